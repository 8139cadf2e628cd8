"""Bending linear in the curvature: a material's stencils (warp_cloth/materials.py derives them), and
their Jacobians for the implicit solve.

A stencil names its particles and their weights w (1/m^2), which sum to zero and make the curvature
vector d = sum_r w_r x_r vanish at the flat rest state, and grow as the curvature there times the cloth's
normal: three particles p, m, q along a straight row (the second difference over its spacings), or a
particle and up to seven neighbours, the weights that read the curvature along the
warp or the weft from the quadratic fitting them (warp_cloth/bend_fits.py). Its
energy 1/2 k |d|^2 and dashpot 1/2 c |sum_r w_r v_r|^2 give each of its particles
r the force -w_r (k d + c sum_s w_s v_s). Linear in the positions: the stiffness Jacobian is the constant
k w_r w_s I between particles r and s, and the damping one c w_r w_s I.

Each stencil's entries lie in ``particles`` and ``weights`` from ``starts[s]`` to ``starts[s + 1]``, so a
row reads its three and a fit its own. Gathered per particle, as the springs are: ``offsets`` lists each
particle's incidences, each naming a stencil and the particle's entry in it, so every particle sums its own
forces without atomics.
"""

import warp as wp


@wp.struct
class Bending:
    offsets: wp.array(dtype=int)  # (n + 1,) particle i's incidences are offsets[i]:offsets[i + 1]
    stencil: wp.array(dtype=int)  # per incidence: the stencil
    entry: wp.array(dtype=int)  # per incidence: the particle's entry in it, an index of particles and weights
    starts: wp.array(dtype=int)  # (s + 1,) stencil s's entries are starts[s]:starts[s + 1]
    particles: wp.array(dtype=int)  # (e,) each stencil's particles
    weights: wp.array(dtype=float)  # (e,) 1/m^2
    stiffness: wp.array(dtype=float)  # (s,) N m^3: the bending stiffness times the area the stencil stands for
    damping: wp.array(dtype=float)  # (s,) N m^3 s


@wp.func
def stencil_sum(bending: Bending, s: int, u: wp.array(dtype=wp.vec3)) -> wp.vec3:
    """sum_r w_r u_r over stencil s."""
    total = wp.vec3(0.0)
    for e in range(bending.starts[s], bending.starts[s + 1]):
        total = total + bending.weights[e] * u[bending.particles[e]]
    return total


@wp.func
def bending_forces(bending: Bending, i: int, first: int, stride: int, x: wp.array(dtype=wp.vec3),
                   v: wp.array(dtype=wp.vec3)) -> wp.vec3:
    """Sum of the stencils' forces on particle i from its incidences offsets[i] + first, + stride, ..."""
    f = wp.vec3(0.0)
    for k in range(bending.offsets[i] + first, bending.offsets[i + 1], stride):
        s = bending.stencil[k]
        w = bending.weights[bending.entry[k]]
        f = f - w * (bending.stiffness[s] * stencil_sum(bending, s, x) + bending.damping[s] * stencil_sum(bending, s, v))
    return f


@wp.func
def add_bending_times(bending: Bending, i: int, p: wp.array(dtype=wp.vec3), h: float, total: wp.vec3) -> wp.vec3:
    """``total`` plus the stencils' part of particle i's row of the step's matrix (h D + h^2 K) times p."""
    for k in range(bending.offsets[i], bending.offsets[i + 1]):
        s = bending.stencil[k]
        w = bending.weights[bending.entry[k]]
        total = total + (w * (h * bending.damping[s] + h * h * bending.stiffness[s])) * stencil_sum(bending, s, p)
    return total


@wp.func
def add_bending_diagonal(bending: Bending, i: int, h: float, block: wp.mat33) -> wp.mat33:
    """``block`` plus the stencils' part of particle i's 3x3 diagonal block of the step's matrix."""
    scale = float(0.0)
    for k in range(bending.offsets[i], bending.offsets[i + 1]):
        s = bending.stencil[k]
        w = bending.weights[bending.entry[k]]
        scale = scale + w * w * (h * bending.damping[s] + h * h * bending.stiffness[s])
    return block + scale * wp.identity(n=3, dtype=float)


@wp.func
def bending_stiffness_times(bending: Bending, i: int, u: wp.array(dtype=wp.vec3)) -> wp.vec3:
    """Particle i's row of the stencils' K u."""
    total = wp.vec3(0.0)
    for k in range(bending.offsets[i], bending.offsets[i + 1]):
        s = bending.stencil[k]
        w = bending.weights[bending.entry[k]]
        total = total + (w * bending.stiffness[s]) * stencil_sum(bending, s, u)
    return total
