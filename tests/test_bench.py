"""The benchmark reports, beside each case's speed, how far its cloth stretched or compressed over the run."""

import re

import numpy as np
import pytest

import warp_cloth as wc
from warp_cloth.lab.bench import Case, format_table, matrix_scene, time_case
from warp_cloth.lab.newton_compare import SIZE, grid_strain


def test_grid_strain_reads_every_structural_and_shear_edge():
    n = 5
    cell = SIZE / (n - 1)
    rows, columns = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    flat = np.stack([1.2 * cell * columns, 0.9 * cell * rows, np.zeros_like(rows)], axis=-1).reshape(-1, 3)
    assert grid_strain(flat, n) == pytest.approx((0.2, 0.1))  # rows 20% long, columns 10% short
    assert grid_strain(np.concatenate([flat, flat / 1.2]), n) == pytest.approx((0.2, 0.25))  # two cloths
    bent = flat.reshape(n, n, 3).copy()
    bent[2, 2] += (0.0, 0.0, 0.5 * cell)
    stretch, _ = grid_strain(bent.reshape(-1, 3), n)
    diagonal = np.hypot(np.hypot(1.2 * cell, 0.9 * cell), 0.5 * cell) / (cell * 2**0.5) - 1.0
    assert stretch == pytest.approx(max(0.2, np.hypot(1.2 * cell, 0.5 * cell) / cell - 1.0, diagonal))


def test_case_reports_the_worst_edge_strain_over_every_frame_of_its_run():
    n = 8
    scene = matrix_scene("hanging", n, "symplectic")
    result = time_case(Case("hanging 8^2 symplectic", scene, frames=4, fresh=False), "cpu", repeats=1)
    same = wc.Simulator(scene, device="cpu")
    stretch = compression = 0.0
    for _ in range(2 + 4):  # the warm-up frames, then the timed ones, on one simulator as the case runs them
        same.step()
        frame_stretch, frame_compression = grid_strain(same.positions(), n)
        stretch, compression = max(stretch, frame_stretch), max(compression, frame_compression)
    assert result.strain["frames"] == 2 + 4 + 1  # frame 0 too
    assert result.max_strain == max(result.strain["stretch"], result.strain["compression"])
    # Newton's rows are measured by grid_strain: the same edges, the same figures
    assert result.strain["stretch"] == pytest.approx(stretch, abs=1e-5)
    assert result.strain["compression"] == pytest.approx(compression, abs=1e-5)
    assert result.strain["stretch"] <= 0.1 + 1e-5  # the attachments hold the cloth
    table = format_table([result])
    assert "worst strain" in table.splitlines()[0]
    assert f"{100 * result.max_strain:.1f}%" in table.splitlines()[2]


def test_bench_off_a_terminal_says_each_case_as_it_starts(tmp_path, capsys):
    """A suite's cases take minutes in all: a log (stderr not a terminal) gets a line as each one starts."""
    from warp_cloth.lab.bench import main

    code = main(["--suite", "matrix", "--device", "cpu", "--repeats", "1", "--no-newton", "--json",
                 str(tmp_path / "bench.json"), "--match", "hanging 64^2"])
    assert code == 0
    lines = capsys.readouterr().err.splitlines()
    said = ["bench matrix on cpu, timing hanging 64^2 symplectic: 0/2, ",
            "bench matrix on cpu, timing hanging 64^2 implicit: 1/2, ", "bench matrix on cpu: 2/2, "]
    assert len(lines) == 3 and all(line.startswith(start) for line, start in zip(lines, said)), lines
    assert lines[-1].endswith(" s"), lines  # what is left of a finished suite goes without saying


def test_a_case_that_blew_up_says_so_with_no_time_or_strain_as_results(tmp_path, capsys):
    """The seed's explicit step at 0.0104 s blows up: its row says where, and gives no time, speed or strain;
    a suite whose cases all blew up still ends with its summary."""
    import json

    from warp_cloth.lab.bench import main

    case = "seed_20x20+self explicit dt=0.0104"
    code = main(["--suite", "integrators", "--device", "cpu", "--repeats", "1", "--json", str(tmp_path / "b.json"),
                 "--match", case])
    assert code == 0
    (result,) = json.loads((tmp_path / "b.json").read_text())["results"]
    assert not result["stable"] and result["seconds"] == [] and result["max_strain"] is None
    assert isinstance(result["unstable_frame"], int) and result["unstable_frame"] >= 1
    out = capsys.readouterr().out.splitlines()
    row = next(line for line in out if line.startswith(case))
    assert f"blew up at frame {result['unstable_frame']}" in row
    assert "%" not in row and not re.search(r"\d\.\d{3}\b", row), row
    assert out[-1].startswith("bench integrators: 1 case on CPU, 1 blew up; wrote "), out[-1]
