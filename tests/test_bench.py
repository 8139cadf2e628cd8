"""The benchmark reports, beside each case's speed, how far its cloth stretched or compressed over the run."""

import warp_cloth as wc
from warp_cloth.bench import Case, format_table, matrix_scene, time_case
from warp_cloth.newton_compare import max_edge_strain


def test_case_reports_the_worst_edge_strain_over_every_frame_of_its_run():
    n = 8
    scene = matrix_scene("hanging", n, "symplectic")
    result = time_case(Case("hanging 8^2 symplectic", scene, frames=4, fresh=False), "cpu", repeats=1)
    same = wc.Simulator(scene, device="cpu")
    worst_structural = 0.0
    for _ in range(2 + 4):  # the warm-up frames, then the timed ones, on one simulator as the case runs them
        same.step()
        worst_structural = max(worst_structural, max_edge_strain(same.positions(), n))
    assert result.strain["frames"] == 2 + 4 + 1  # frame 0 too
    assert result.max_strain == max(result.strain["stretch"], result.strain["compression"])
    assert worst_structural - 1e-6 <= result.strain["stretch"] <= 0.1 + 1e-5  # the attachments hold the cloth
    table = format_table([result])
    assert "worst strain" in table.splitlines()[0]
    assert f"{100 * result.max_strain:.1f}%" in table.splitlines()[2]
