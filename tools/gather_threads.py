"""What several threads per particle and fast math each give on the speed matrix's cloths (symplectic). For
the configurations of whole frames, ms per frame and worst edge strain, timed as ``warp-cloth bench
--suite matrix`` times them (``Simulator(scene, threads_per_particle=...)``):

* ``by_size``: threads per particle chosen by size (the product's default);
* ``one_thread``: one thread per particle;
* ``threads_K``: K threads per particle in every gathering pass and the list remake.

All of these run the product's kernels, with fast math. ``precise`` is measured per pass instead: every
gathering pass of the cloth's substep (threads chosen by size, the state after the case's frames: 48 on
a GPU) launched on its own with ``launch_gathering`` in a graph of 100 launches, from the same positions
and velocities to scratch arrays, the product's kernel (fast math) against the same kernel built without
fast math (``gathering_kernel(..., options={"fast_math": False})`` from its gather and finish functions in
its kernels/ module); microseconds per launch by pass, and their sums over the substep's gathering passes.
The kernels that are not gathering kernels (the list remake, the hash insert, the contacts' start alone,
the colliders alone) have no precise form here. A whole frame without fast math cannot be built through
the simulator's public interface, so ``precise`` has no ms per frame and no strain.

One JSON line per row, written as it goes.

    [CONFIGS=by_size,precise] [DEVICE=cpu] python tools/gather_threads.py OUT.jsonl [SIZE ...]

(DEVICE=cpu: a check that it runs; threads per particle other than one need a GPU.)
docs/results/gather-threads-h200.jsonl is the H200 output of its earlier version, whose ``precise`` rows
were whole frames with every fast-math kernel module rebuilt without it.
"""

import dataclasses
import functools
import json
import os
import sys

import warp as wp

from lanes_probe import per_launch_us
from warp_cloth.lab.bench import MATRIX_VARIANTS, SPRINGS_ONLY, Case, environment, matrix_frames, matrix_scene, time_case
from warp_cloth.kernels import contact_velocities, explicit_step, projection_passes
from warp_cloth.kernels.gathering import gathering_kernel, launch_gathering, load_gathering
from warp_cloth.passes import GatheringPass
from warp_cloth.simulator import Simulator

wp.config.log_level = wp.LOG_ERROR

# The product's gathering-kernel factories, and what each builds its kernel from: args struct, gather, finish.
GATHERING = {
    explicit_step.explicit_step_kernel: (explicit_step.ExplicitStepArgs, explicit_step.gather_spring_forces,
                                         explicit_step.finish_explicit_step),
    explicit_step.explicit_step_and_contact_start_kernel: (explicit_step.ExplicitStepAndContactStartArgs,
                                                           explicit_step.gather_step_of,
                                                           explicit_step.finish_explicit_step_and_contact_start),
    projection_passes.limit_pass_kernel: (projection_passes.LimitPassArgs, projection_passes.gather_limits,
                                          projection_passes.finish_limit_pass),
    projection_passes.separation_pass_kernel: (projection_passes.SeparationPassArgs, projection_passes.gather_pushes,
                                               projection_passes.finish_separation_pass),
    projection_passes.limit_and_separation_pass_kernel: (projection_passes.LimitAndSeparationPassArgs,
                                                         projection_passes.gather_limits_and_pushes,
                                                         projection_passes.finish_limit_and_separation_pass),
    contact_velocities.contact_velocities_kernel: (contact_velocities.ContactVelocitiesArgs,
                                                   contact_velocities.gather_velocity_changes,
                                                   contact_velocities.finish_contact_velocities),
}


@functools.cache
def precise_kernel(factory, threads: int) -> wp.Kernel:
    """``factory(threads)``'s kernel compiled without fast math."""
    args_type, gather, finish = GATHERING[factory]
    name = factory.__name__.removesuffix("_kernel") + "_precise"
    return gathering_kernel(name, args_type, gather, finish, threads, options={"fast_math": False})


def precise_twin(step: GatheringPass) -> wp.Kernel:
    factory = next((f for f in GATHERING if f(step.threads) is step.kernel), None)
    if factory is None:
        raise LookupError(f"pass {step.name!r}: its kernel is none of the kernels/ factories listed here")
    return precise_kernel(factory, step.threads)


def precise_row(variant: str, n: int, device: str) -> dict:
    """Each gathering pass of the cloth's substep, with and without fast math, per launch."""
    sim = Simulator(matrix_scene(variant, n, "symplectic"), device=device)
    sim.run(matrix_frames(n, device))
    x, v = sim.state.x, sim.state.v
    x_out, v_out = wp.clone(x), wp.clone(v)  # scratch: the simulator's state is left as it was

    def us(kernel: wp.Kernel, step: GatheringPass) -> float:
        load_gathering(kernel, step.threads, sim.device)
        return per_launch_us(lambda: launch_gathering(kernel, step.threads, x.shape[0], x, v, x_out, v_out,
                                                      step.args), sim.device)

    passes = [{"pass": step.name, "threads": step.threads, "fast_math_us": us(step.kernel, step),
               "precise_us": us(precise_twin(step), step)}
              for step in sim.plan.passes if isinstance(step, GatheringPass)]
    return {"config": "precise", "variant": variant, "n": n, "threads_per_particle": sim.plan.threads,
            "substep_passes": sim.plan.pass_names, "gathering_passes": passes,
            "gathering_fast_math_us": sum(p["fast_math_us"] for p in passes),
            "gathering_precise_us": sum(p["precise_us"] for p in passes)}


def main() -> None:
    device = os.environ.get("DEVICE", "cuda")
    out = open(sys.argv[1], "a")
    sizes = [int(n) for n in sys.argv[2:]] or [64, 256, 1024]
    print(json.dumps({"environment": environment(device)}), file=out, flush=True)
    fixed = {"by_size": None, "one_thread": 1}
    for config in os.environ.get("CONFIGS", "by_size,one_thread,precise").split(","):
        threads = None if config == "precise" else fixed[config] if config in fixed else \
            int(config.removeprefix("threads_"))
        for n in sizes:
            for variant in (*MATRIX_VARIANTS, SPRINGS_ONLY):
                if config == "precise":
                    row = precise_row(variant, n, device)
                    print(json.dumps(row), file=out, flush=True)
                    print(f"{config:10s} {variant:12s} {n:5d}^2 gathering passes "
                          f"{row['gathering_fast_math_us']:8.1f} us a substep with fast math, "
                          f"{row['gathering_precise_us']:8.1f} without", flush=True)
                    continue
                case = Case(f"{variant} {n}^2 symplectic", matrix_scene(variant, n, "symplectic"),
                            matrix_frames(n, device), fresh=False, threads_per_particle=threads)
                result = time_case(case, device, 3)
                row = dict(dataclasses.asdict(result), config=config, variant=variant, n=n,
                           ms_per_frame=result.ms_per_frame)
                print(json.dumps(row), file=out, flush=True)
                print(f"{config:10s} {variant:12s} {n:5d}^2 {result.ms_per_frame:8.3f} ms/frame  "
                      f"strain {result.max_strain}", flush=True)


if __name__ == "__main__":
    main()
