"""The kernels' several-threads-per-particle forms (kernels/lanes.py), run here with one thread a particle
in blocks of one, the only form a CPU can run, must give exactly what the one-thread kernels give; their
agreement with several threads a particle is tested on a GPU (test_cuda.py, test_collision.py)."""

import dataclasses

import numpy as np
import pytest
import warp as wp

import warp_cloth as wc
from warp_cloth.kernels import integration, limits, particle_collision, projection
from warp_cloth.stages import ParticleCollision

LANES_FORMS = {"euler_step": integration.euler_step_lanes, "project_strain_limits": limits.project_strain_limits_lanes,
               "separate_particles": particle_collision.separate_particles_lanes,
               "project_limits_and_separation": projection.project_limits_and_separation_lanes,
               "resolve_contact_velocities": particle_collision.resolve_contact_velocities_lanes,
               "gather_neighbors": particle_collision.gather_neighbors_lanes}


def copies(args):
    return [wp.clone(a) if isinstance(a, wp.array) else a for a in args]


def assert_same_lists(loop_outputs, lanes_outputs):
    (neighbors_a, counts_a, *_), (neighbors_b, counts_b, *_) = loop_outputs, lanes_outputs
    counts = counts_a.numpy()
    np.testing.assert_array_equal(counts, counts_b.numpy())
    a, b = (n.numpy().reshape(len(counts), -1) for n in (neighbors_a, neighbors_b))
    for i, count in enumerate(counts):
        np.testing.assert_array_equal(a[i, :count], b[i, :count])
    return int(counts.sum())


# pile separates in 8 passes; with 4 limit passes the limit runs only together with the separation, with
# 10 the separation runs only together with the limit
@pytest.mark.parametrize("limit_iterations, unused", [(4, "project_strain_limits"), (10, "separate_particles")])
def test_lanes_forms_with_one_thread_give_the_one_thread_kernels_results(monkeypatch, limit_iterations, unused):
    scene = wc.load_scene("pile")
    assert scene.collision.iterations == 8
    scene = dataclasses.replace(scene, collision=dataclasses.replace(scene.collision, broad_phase="hash_grid"),
                                simulation=dataclasses.replace(scene.simulation, limit_iterations=limit_iterations))
    sim = wc.Simulator(scene, device="cpu", graph=False)
    sim.run(30)  # the layers have landed: lists, contacts, resting particles
    stage = next(s for s in sim.stages if isinstance(s, ParticleCollision))
    stage.remake_every_substep = True
    real_launch = wp.launch
    checked, listed = set(), []

    def compare_then_launch(kernel, dim, inputs=(), outputs=(), device=None, **kwargs):
        if kernel.key in LANES_FORMS:
            loop_in, loop_out = copies(inputs), copies(outputs)
            real_launch(kernel, dim=dim, inputs=loop_in, outputs=loop_out, device=device)
            lanes_in, lanes_out = copies(inputs), copies(outputs)
            if kernel.key == "gather_neighbors":  # its unsorted lists and their lengths
                lanes_in += [wp.zeros_like(lanes_out[0]), wp.zeros_like(lanes_out[1])]
            wp.launch_tiled(LANES_FORMS[kernel.key](1, 1), dim=[dim], inputs=lanes_in, outputs=lanes_out, block_dim=1,
                            device=device)
            if kernel.key == "gather_neighbors":
                listed.append(assert_same_lists(loop_out, lanes_out))
                for a, b in zip(loop_out[2:], lanes_out[2:]):  # overflow, list positions, remake flag
                    np.testing.assert_array_equal(a.numpy(), b.numpy())
                assert not lanes_in[-1].numpy().any(), "the append counts are left zero"
            else:
                for a, b in zip(loop_in + loop_out, lanes_in + lanes_out):
                    if isinstance(a, wp.array):
                        np.testing.assert_array_equal(a.numpy(), b.numpy())
            checked.add(kernel.key)
        return real_launch(kernel, dim=dim, inputs=inputs, outputs=outputs, device=device, **kwargs)

    monkeypatch.setattr(wp, "launch", compare_then_launch)
    sim.step()
    assert checked == set(LANES_FORMS) - {unused}
    assert min(listed) > sim.model.particle_count  # more than one candidate a particle
