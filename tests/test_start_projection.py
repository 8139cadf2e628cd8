"""A run that starts fresh starts from its cloths projected onto their strain limits
(warp_cloth/start_projection.py): a cloth past them is moved onto them before the first substep, at the
velocities the scene gives, and the run says so; a cloth within them starts exactly as given; a run
restored from a checkpoint is not projected again."""

import numpy as np

import warp_cloth as wc
from conftest import assert_restored_run_continues, run_cli_in_process, spring_strains

LIMIT = 0.1
TOLERANCE = 0.005  # the scene's limit_tolerance (its default)


def twisted(name: str = "twisted", origin_x: float = -1.0) -> wc.Cloth:
    """A grid twisted a quarter turn, its rest lengths the flat grid's: 15.6% past its 10% limit."""
    return wc.Cloth(name=name, resolution=(12, 12), size=(2.0, 2.0), orientation="vertical",
                    origin=(origin_x, 0.5, 0.0), twist=90.0, density=0.2,
                    limit=wc.Limit(stretch=LIMIT, compression=LIMIT))


def flat(name: str = "flat", origin_x: float = 2.0) -> wc.Cloth:
    return wc.Cloth(name=name, resolution=(12, 12), size=(2.0, 2.0), orientation="vertical",
                    origin=(origin_x, 0.5, 0.0), density=0.2, limit=wc.Limit(stretch=LIMIT, compression=LIMIT))


def scene(*cloths: wc.Cloth, **simulation) -> wc.Scene:
    return wc.Scene(name="start", cloths=cloths, ground=wc.Ground(), simulation=wc.Simulation(frames=4, **simulation))


def limited_strains(sim: wc.Simulator, positions: np.ndarray) -> np.ndarray:
    return spring_strains(sim, positions)[np.isfinite(sim.model.springs.limit_max)]


class StartFrame:
    """A writer that keeps the first frame it is given."""

    def begin(self, sim) -> None:
        self.first = None

    def write_frame(self, sim, frame: int) -> None:
        if self.first is None:
            self.first = sim.positions()

    def finish(self, sim, frames_written: int) -> None:
        pass


def test_a_cloth_past_its_limit_starts_projected_onto_it_at_the_velocities_the_scene_gives():
    sim = wc.Simulator(scene(twisted()), device="cpu")
    given = limited_strains(sim, sim.model.positions)
    assert given.max() > 1.15 * (1.0 + LIMIT) - 1.0  # the twist stretches it past its limit
    report = sim.start_projection
    assert [c.name for c in report.cloths] == ["twisted"] and report.residual <= 1.0
    assert abs(report.cloths[0].past - ((1.0 + given.max()) / (1.0 + LIMIT) - 1.0)) < 1e-4
    assert "cloth 'twisted' starts 15." in report.describe() and "projected onto it" in report.describe()
    start = sim.positions()
    assert limited_strains(sim, start).max() <= (1.0 + LIMIT) * (1.0 + TOLERANCE) - 1.0
    np.testing.assert_array_equal(sim.velocities(), sim.model.velocities)
    frame = StartFrame()
    sim.run(2, writers=[frame])
    np.testing.assert_array_equal(frame.first, start)  # frame 0 is the state the run starts from


def test_a_cloth_within_its_limits_starts_exactly_as_given_and_beside_one_past_them_too():
    alone = wc.Simulator(scene(flat()), device="cpu")
    assert alone.start_projection is None
    np.testing.assert_array_equal(alone.positions(), alone.model.positions)
    both = wc.Simulator(scene(twisted(), flat()), device="cpu")
    assert [(c.cloth, c.name) for c in both.start_projection.cloths] == [(0, "twisted")]
    np.testing.assert_array_equal(both.cloth_positions(1), both.model.positions[both.model.cloth_slice(1)])
    assert not np.array_equal(both.cloth_positions(0), both.model.positions[both.model.cloth_slice(0)])


def test_a_batch_projects_the_cloths_that_start_past_their_limits_only():
    scenes = [scene(flat()), scene(twisted("a"), flat("b"))]
    batch = wc.Batch(scenes, device="cpu")
    reports = batch.start_projections
    assert list(reports) == [1] and [(c.cloth, c.name) for c in reports[1].cloths] == [(0, "a")]
    alone = [wc.Simulator(s, device="cpu") for s in scenes]
    np.testing.assert_array_equal(batch.positions(0), alone[0].model.positions)
    b = alone[1].model.cloth_slice(1)
    np.testing.assert_array_equal(batch.positions(1)[b], alone[1].model.positions[b])
    assert limited_strains(alone[1], batch.positions(1)).max() <= (1.0 + LIMIT) * (1.0 + TOLERANCE) - 1.0


def test_a_run_restored_from_a_checkpoint_is_not_projected_again(tmp_path):
    sim = wc.Simulator(scene(twisted()), device="cpu")
    sim.step()
    restored = wc.Simulator(scene(twisted()), device="cpu")
    assert restored.start_projection is not None
    assert_restored_run_continues(sim, restored, tmp_path / "state.npz")
    assert restored.start_projection is None


def test_the_run_says_which_cloth_started_past_its_limit_and_the_plan_says_what_the_simulator_does(tmp_path):
    scene_file = tmp_path / "twisted.toml"
    scene_file.write_text('[simulation]\nframes = 2\n\n[ground]\n\n[[cloth]]\nname = "twisted"\nresolution = [12, 12]\n'
                          'size = [2.0, 2.0]\norientation = "vertical"\norigin = [-1.0, 0.5, 0.0]\ntwist = 90.0\n'
                          'limit = { stretch = 0.1, compression = 0.1 }\n')
    code, out, err = run_cli_in_process("run", str(scene_file), "--out", str(tmp_path), "--quiet", "--device", "cpu",
                                        cwd=tmp_path)
    assert code == 0, err
    line = next(line for line in out.splitlines() if "past its strain limit" in line)
    assert line.startswith("twisted: cloth 'twisted' starts 15.") and "projected onto it in" in line
    code, out, err = run_cli_in_process("run", "hanging", "--frames", "2", "--out", str(tmp_path), "--quiet",
                                        "--device", "cpu", cwd=tmp_path)
    assert code == 0 and "strain limit" not in out, err
    code, out, err = run_cli_in_process("plan", str(scene_file), "--device", "cpu", cwd=tmp_path)
    assert code == 0 and "projects the cloths that start past their strain limits onto them" in out, err
