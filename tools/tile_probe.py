"""Probe for the next step on small cloths: spring forces and integration with one thread per particle (the
product's kernel) against a block of 16 or 32 threads per particle whose forces a tile sum reduces. A graph
of 100 launches of each on the hanging matrix cloth; microseconds per launch, and the largest position
difference (the sums' order differs). Not used by the package.

    python tools/tile_probe.py OUT.json [cuda|cpu]

docs/results/tile-probe-h200.json is its output on the H200.
"""
import json, sys, time, statistics
import warp as wp
wp.config.log_level = wp.LOG_ERROR
from warp_cloth.kernels.springs import spring_force
from warp_cloth.kernels import integration
from warp_cloth.bench import matrix_scene
from warp_cloth.simulator import Simulator
from warp_cloth.stages import upload_springs

@wp.kernel
def euler_step_tiled(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float),
                     gravity: wp.vec3, drag: float, h: float, semi_implicit: int, offsets: wp.array(dtype=int),
                     other: wp.array(dtype=int), spring: wp.array(dtype=int), rest: wp.array(dtype=float),
                     stiffness: wp.array(dtype=float), damping: wp.array(dtype=float), flags: wp.array(dtype=int),
                     x_out: wp.array(dtype=wp.vec3), v_out: wp.array(dtype=wp.vec3)):
    i, lane = wp.tid()
    start = offsets[i]
    count = offsets[i + 1] - start
    xi = x[i]
    vi = v[i]
    f = wp.vec3(0.0)
    for k in range(lane, count, wp.block_dim()):
        e = start + k
        j = other[e]
        s = spring[e]
        f = f + spring_force(xi, x[j], vi, v[j], rest[s], stiffness[s], damping[s], flags[s])
    total = wp.tile_extract(wp.tile_sum(wp.tile(f, preserve_type=True)), 0)
    if lane == 0:
        w = inv_mass[i]
        if w == 0.0:
            x_out[i] = xi
            v_out[i] = vi
        else:
            v_new = vi + h * (gravity - drag * vi + w * total)  # as integration.euler_step
            v_out[i] = v_new
            if semi_implicit != 0:
                x_out[i] = xi + h * v_new
            else:
                x_out[i] = xi + h * vi

def per_launch_us(launch, device):
    launch(); wp.synchronize_device(device)
    with wp.ScopedCapture(device=device) as cap:
        for _ in range(100):
            launch()
    t = []
    for _ in range(5):
        wp.synchronize_device(device); s = time.perf_counter()
        for _ in range(10):
            wp.capture_launch(cap.graph)
        wp.synchronize_device(device); t.append((time.perf_counter() - s) / 1000 * 1e6)
    return statistics.median(t)

device = sys.argv[2] if len(sys.argv) > 2 else "cuda"
res = {}
for n in ((64, 256, 1024) if device == "cuda" else (16,)):
    sim = Simulator(matrix_scene("hanging", n, "symplectic"), device=device); sim.run(2)
    st = sim.state; model = sim.model
    inv_mass = wp.array(model.inv_mass, dtype=float, device=device)
    springs = upload_springs(model, device)
    args = [st.x, st.v, inv_mass, wp.vec3(0.0, -9.81, 0.0), 0.0, 1.0 / 240, 1, *springs]
    xo = wp.empty_like(st.x); vo = wp.empty_like(st.v)
    N = model.particle_count
    row = {"loop": per_launch_us(lambda: wp.launch(integration.euler_step, N, inputs=args, outputs=[xo, vo], device=device), device)}
    wp.launch(integration.euler_step, N, inputs=args, outputs=[xo, vo], device=device); ref = xo.numpy().copy()
    for bd in (16, 32):
        row[f"tile{bd}"] = per_launch_us(lambda: wp.launch_tiled(euler_step_tiled, dim=[N], inputs=args, outputs=[xo, vo], block_dim=bd, device=device), device)
        wp.launch_tiled(euler_step_tiled, dim=[N], inputs=args, outputs=[xo, vo], block_dim=bd, device=device)
        row[f"tile{bd}_max_diff"] = float(abs(xo.numpy() - ref).max())
    res[n] = row
    print(n, row, flush=True)
json.dump(res, open(sys.argv[1], "w"), indent=1)
