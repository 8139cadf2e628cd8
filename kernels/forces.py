"""External forces: what acts on each particle from outside the cloth, per unit mass.

Both integrators read them through ``external_acceleration`` (the explicit step adds it to the springs'
f / m, the implicit step's right-hand side adds m times it), and the implicit step's matrix reads their
velocity derivative through ``external_damping``. A new force is a field of ``ExternalForces``, its term
in these two functions, and its scene entry (warp_cloth/device_model.py fills the struct).
"""

import warp as wp


@wp.struct
class ExternalForces:
    gravity: wp.array(dtype=wp.vec3)  # (worlds,) m/s^2
    world: wp.array(dtype=int)  # (n,) each particle's world
    drag: float  # 1/s: air drag on the particle's velocity
    wind: wp.array(dtype=wp.vec3)  # (n,) each particle's wind acceleration this substep (wind.py); empty: none


@wp.func
def external_acceleration(forces: ExternalForces, i: int, x: wp.vec3, v: wp.vec3) -> wp.vec3:
    """The acceleration of particle i, at x with velocity v, from the external forces (the wind's taken
    as it was at the substep's start: explicit in both integrators)."""
    a = forces.gravity[forces.world[i]] - forces.drag * v
    if forces.wind.shape[0] > 0:
        a = a + forces.wind[i]
    return a


@wp.func
def external_damping(forces: ExternalForces) -> float:
    """-d(acceleration)/dv of the external forces (a multiple of the identity), for the implicit matrix."""
    return forces.drag
