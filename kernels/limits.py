"""Provot-style strain limits, projected in parallel as Jacobi iterations with averaging.

Each particle gathers the corrections of its limited springs that are out of range, weighted by inverse
mass (a pinned end does not move), and moves by their average. Reading one buffer and writing another
keeps the pass free of races and deterministic. The velocity gets the same correction divided by h, so
that it stays consistent with the positions (as the seed's velocity fix does).
"""

import warp as wp


@wp.kernel
def project_strain_limits(x: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float),
                          offsets: wp.array(dtype=int), other: wp.array(dtype=int),
                          min_length: wp.array(dtype=float), max_length: wp.array(dtype=float), h: float,
                          x_out: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    xi = x[i]
    wi = inv_mass[i]
    if wi == 0.0:
        x_out[i] = xi
        return
    correction = wp.vec3(0.0)
    violated = int(0)
    for k in range(offsets[i], offsets[i + 1]):
        j = other[k]
        d = xi - x[j]
        length = wp.length(d)
        target = wp.clamp(length, min_length[k], max_length[k])
        if target != length and length > 1.0e-12:
            share = wi / (wi + inv_mass[j])
            correction = correction + share * (target - length) * (d / length)
            violated += 1
    if violated > 0:
        correction = correction / float(violated)
        v[i] = v[i] + correction / h
    x_out[i] = xi + correction
