"""Probe: the spring gather with K threads ("lanes") per particle and P = B / K particles per block of B
threads, the lanes' partial forces summed by a tile reduction along the lane axis; against the product's
kernel (one thread per particle), and against it compiled with fast math. A graph of 100 launches of each
on the hanging matrix cloth; microseconds per launch and the largest position difference from the
product's kernel. Not used by the package. Run before fast math became the product's default
(docs/results/lanes-probe-h200.json); since then "loop" is compiled with fast math as well.

    python tools/lanes_probe.py OUT.json [cuda|cpu]
"""
import json
import statistics
import sys
import time

import warp as wp

wp.config.log_level = wp.LOG_ERROR
from warp_cloth.bench import matrix_scene  # noqa: E402
from warp_cloth.kernels import integration  # noqa: E402
from warp_cloth.kernels.springs import gather_spring_forces, spring_force  # noqa: E402
from warp_cloth.simulator import Simulator  # noqa: E402
from warp_cloth.stages import upload_springs  # noqa: E402


def lanes_kernel(K: int, B: int):
    P = B // K

    @wp.kernel(module="unique")
    def euler_step_lanes(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float),
                         gravity: wp.vec3, drag: float, h: float, semi_implicit: int, offsets: wp.array(dtype=int),
                         other: wp.array(dtype=int), spring: wp.array(dtype=int), rest: wp.array(dtype=float),
                         stiffness: wp.array(dtype=float), damping: wp.array(dtype=float), flags: wp.array(dtype=int),
                         x_out: wp.array(dtype=wp.vec3), v_out: wp.array(dtype=wp.vec3)):
        block, lane = wp.tid()
        i = block * wp.static(P) + lane / wp.static(K)
        slot = lane % wp.static(K)
        f = wp.vec3(0.0)
        xi = wp.vec3(0.0)
        vi = wp.vec3(0.0)
        if i < x.shape[0]:
            xi = x[i]
            vi = v[i]
            for e in range(offsets[i] + slot, offsets[i + 1], wp.static(K)):
                j = other[e]
                s = spring[e]
                f = f + spring_force(xi, x[j], vi, v[j], rest[s], stiffness[s], damping[s], flags[s])
        sums = wp.tile_sum(wp.tile_reshape(wp.tile(f, preserve_type=True), shape=(wp.static(P), wp.static(K))), axis=1)
        total = sums[lane / wp.static(K)]
        if slot == 0 and i < x.shape[0]:
            w = inv_mass[i]
            if w == 0.0:
                x_out[i] = xi
                v_out[i] = vi
            else:
                v_new = vi + h * (gravity - drag * vi + w * total)
                v_out[i] = v_new
                if semi_implicit != 0:
                    x_out[i] = xi + h * v_new
                else:
                    x_out[i] = xi + h * vi

    return euler_step_lanes


@wp.kernel(module="unique")
def euler_step_fast(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float),
                    gravity: wp.vec3, drag: float, h: float, semi_implicit: int, offsets: wp.array(dtype=int),
                    other: wp.array(dtype=int), spring: wp.array(dtype=int), rest: wp.array(dtype=float),
                    stiffness: wp.array(dtype=float), damping: wp.array(dtype=float), flags: wp.array(dtype=int),
                    x_out: wp.array(dtype=wp.vec3), v_out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    w = inv_mass[i]
    if w == 0.0:
        x_out[i] = x[i]
        v_out[i] = v[i]
        return
    f = gather_spring_forces(i, x, v, offsets, other, spring, rest, stiffness, damping, flags)
    v_new = v[i] + h * (gravity - drag * v[i] + w * f)
    v_out[i] = v_new
    if semi_implicit != 0:
        x_out[i] = x[i] + h * v_new
    else:
        x_out[i] = x[i] + h * v[i]


euler_step_fast.module.options["fast_math"] = True


def per_launch_us(launch, device):
    launch()
    wp.synchronize_device(device)
    with wp.ScopedCapture(device=device) as cap:
        for _ in range(100):
            launch()
    t = []
    for _ in range(5):
        wp.synchronize_device(device)
        s = time.perf_counter()
        for _ in range(10):
            wp.capture_launch(cap.graph)
        wp.synchronize_device(device)
        t.append((time.perf_counter() - s) / 1000 * 1e6)
    return statistics.median(t)


device = sys.argv[2] if len(sys.argv) > 2 else "cuda"
sizes = (64, 128, 256, 1024) if device == "cuda" else (8,)
shapes = [(K, B) for B in (64, 128, 256) for K in (1, 2, 4, 8, 16)] if device == "cuda" else [(1, 1)]
kernels = {shape: lanes_kernel(*shape) for shape in shapes}
res = {}
for n in sizes:
    sim = Simulator(matrix_scene("hanging", n, "symplectic"), device=device)
    sim.run(2)
    st = sim.state
    model = sim.model
    inv_mass = wp.array(model.inv_mass, dtype=float, device=device)
    args = [st.x, st.v, inv_mass, wp.vec3(0.0, -9.81, 0.0), 0.0, 1.0 / 240, 1, *upload_springs(model, device)]
    xo = wp.empty_like(st.x)
    vo = wp.empty_like(st.v)
    N = model.particle_count
    row = {}
    for name, kernel in (("loop", integration.euler_step), ("loop_fast_math", euler_step_fast)):
        row[name] = per_launch_us(lambda: wp.launch(kernel, N, inputs=args, outputs=[xo, vo], device=device), device)
        if name == "loop":
            ref = xo.numpy().copy()
        else:
            row[name + "_max_diff"] = float(abs(xo.numpy() - ref).max())
    for (K, B), kernel in kernels.items():
        blocks = (N + B // K - 1) // (B // K)
        key = f"K{K}_B{B}"
        row[key] = per_launch_us(lambda: wp.launch_tiled(kernel, dim=[blocks], inputs=args, outputs=[xo, vo],
                                                         block_dim=B, device=device), device)
        row[key + "_max_diff"] = float(abs(xo.numpy() - ref).max())
    res[n] = row
    print(n, {k: round(v, 2) for k, v in row.items() if not k.endswith("diff")},
          "max diff", max(v for k, v in row.items() if k.endswith("diff")), flush=True)
json.dump({"device": str(wp.get_device(device).name), "warp": wp.config.version, "per_launch_us": res},
          open(sys.argv[1], "w"), indent=1)
