"""Provot-style strain limits, projected in parallel as Jacobi iterations with averaging.

Each particle gathers the corrections of its limited springs that are out of range, weighted by inverse
mass (a pinned end does not move), and moves by their average. Reading one buffer and writing another
keeps the pass free of races and deterministic. The velocity gets the same correction divided by h, so
that it stays consistent with the positions (as the seed's velocity fix does). Long-range attachments to
pins, which a limit pass may also apply, are attachments.py's.
"""

import warp as wp


@wp.struct
class StrainLimits:
    offsets: wp.array(dtype=int)  # (n + 1,) particle i's limited springs are offsets[i]:offsets[i + 1]
    other: wp.array(dtype=int)  # per incidence: the particle at the other end
    min_length: wp.array(dtype=float)  # per incidence: the allowed range of the spring's length
    max_length: wp.array(dtype=float)
    residual_length: wp.array(dtype=float)  # per incidence where some pair is sewn, else empty: the length a
    # violation is a fraction of where it is more than max_length (a seam's allowed length reaches 0)


@wp.func
def limit_correction(xi: wp.vec3, wi: float, xj: wp.vec3, wj: float, min_length: float, max_length: float):
    """Particle i's share of the correction that brings the pair i-j within its limits, and 1 if the pair
    is out of them (else zero and 0)."""
    d = xi - xj
    length = wp.length(d)
    target = wp.clamp(length, min_length, max_length)
    if target != length and length > 1.0e-12:
        return (wi / (wi + wj)) * (target - length) * (d / length), 1
    return wp.vec3(0.0), 0


@wp.func
def limit_corrections(limits: StrainLimits, i: int, first: int, stride: int, xi: wp.vec3, wi: float,
                      x: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float)) -> wp.vec4:
    """Sum of free particle i's (at xi, inverse mass wi) shares of the corrections of its limited springs
    offsets[i] + first, + stride, ... (xyz), and how many of them are out of their limits (w)."""
    total = wp.vec4(0.0)
    for e in range(limits.offsets[i] + first, limits.offsets[i + 1], stride):
        j = limits.other[e]
        c, out = limit_correction(xi, wi, x[j], inv_mass[j], limits.min_length[e], limits.max_length[e])
        total = total + wp.vec4(c[0], c[1], c[2], float(out))
    return total


@wp.func
def mean_of(total: wp.vec4) -> wp.vec3:
    """The mean of the corrections whose sum and count ``total`` holds (zero for none)."""
    correction = wp.vec3(total[0], total[1], total[2])
    if total[3] > 0.0:
        correction = correction / total[3]
    return correction


@wp.func
def limit_violation(limits: StrainLimits, i: int, x: wp.array(dtype=wp.vec3)) -> float:
    """How far particle i's limited springs lie outside their allowed lengths, the worst of them, as a
    fraction of the length it should be within (0 where all hold)."""
    xi = x[i]
    worst = float(0.0)
    sewn = limits.residual_length.shape[0] > 0
    for e in range(limits.offsets[i], limits.offsets[i + 1]):
        length = wp.length(xi - x[limits.other[e]])
        longest = limits.max_length[e]
        shortest = limits.min_length[e]
        if length > longest:
            scale = longest
            if sewn:
                scale = wp.max(longest, limits.residual_length[e])
            worst = wp.max(worst, (length - longest) / scale)
        elif length < shortest:
            worst = wp.max(worst, (shortest - length) / shortest)
    return worst
