"""Measuring edge strain: each edge's l / L - 1, the frame's worst stretch and compression, and a histogram
of every edge's strain for percentiles. A diagnostic: it reads positions and writes only its own arrays."""

import warp as wp


@wp.kernel
def measure_edges(x: wp.array(dtype=wp.vec3), edges: wp.array(dtype=wp.vec2i), rest: wp.array(dtype=float),
                  slot: int, low: float, bins_per_unit: float, worst: wp.array2d(dtype=float),
                  histogram: wp.array(dtype=int)):
    """worst[slot] becomes (largest stretch, largest compression) over the edges, both as positive
    fractions, and each edge's strain is counted in its bin of ``histogram`` (from ``low``, the first and
    last bins also taking what lies beyond them)."""
    e = wp.tid()
    pair = edges[e]
    strain = wp.length(x[pair[0]] - x[pair[1]]) / rest[e] - 1.0
    if strain > 0.0:
        wp.atomic_max(worst, slot, 0, strain)
    else:
        wp.atomic_max(worst, slot, 1, -strain)
    bin = wp.clamp(int(wp.floor((strain - low) * bins_per_unit)), 0, histogram.shape[0] - 1)
    wp.atomic_add(histogram, bin, 1)


@wp.kernel
def worst_by_world(x: wp.array(dtype=wp.vec3), edges: wp.array(dtype=wp.vec2i), rest: wp.array(dtype=float),
                   edge_world: wp.array(dtype=int), worst: wp.array2d(dtype=float)):
    """worst[w] becomes the largest (stretch, compression) of world w's edges so far, both as positive
    fractions (kept over every frame measured: the caller never clears it)."""
    e = wp.tid()
    pair = edges[e]
    strain = wp.length(x[pair[0]] - x[pair[1]]) / rest[e] - 1.0
    if strain > 0.0:
        wp.atomic_max(worst, edge_world[e], 0, strain)
    else:
        wp.atomic_max(worst, edge_world[e], 1, -strain)
