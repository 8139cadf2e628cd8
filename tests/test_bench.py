"""The benchmark reports, beside each matrix cloth's speed, how far the cloth stretched."""

import warp_cloth as wc
from warp_cloth.bench import Case, format_table, matrix_scene, time_case
from warp_cloth.newton_compare import max_edge_strain


def test_matrix_case_reports_the_worst_edge_strain_of_its_run():
    n = 8
    scene = matrix_scene("hanging", n, "symplectic")
    result = time_case(Case("hanging 8^2 symplectic", scene, frames=4, fresh=False, grid=n), "cpu", repeats=1)
    same = wc.Simulator(scene, device="cpu")
    same.run(2 + 4)  # the warm-up frames, then the timed ones, on one simulator as the case runs them
    assert result.max_strain == max_edge_strain(same.positions(), n)
    assert 0.0 < result.max_strain <= 0.1 + 1e-5  # the attachments hold the hanging cloth
    table = format_table([result])
    assert "worst strain" in table.splitlines()[0]
    assert f"{100 * result.max_strain:.1f}%" in table.splitlines()[2]
