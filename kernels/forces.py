"""External forces: what acts on each particle from outside the cloth, per unit mass: gravity, drag, the
wind's accelerations and soft pins' springs.

Both integrators read them through ``external_acceleration`` (the explicit step adds it to the springs'
f / m, the implicit step's right-hand side adds m times it), and the implicit step's matrix reads their
velocity and position derivatives through ``external_damping`` and ``external_stiffness``. A new force is
a field of ``ExternalForces``, its term in these functions, and its scene entry (warp_cloth/device_model.py
fills the struct).
"""

import warp as wp


@wp.struct
class ExternalForces:
    gravity: wp.array(dtype=wp.vec3)  # (worlds,) m/s^2
    world: wp.array(dtype=int)  # (n,) each particle's world
    drag: float  # 1/s: air drag on the particle's velocity
    wind: wp.array(dtype=wp.vec3)  # (n,) each particle's wind acceleration this substep (wind.py); empty: none
    # soft pins, per particle (empty: none): a spring of zero rest length to where the pin puts the particle
    pin_rate: wp.array(dtype=float)  # (n,) its stiffness / the particle's mass, 1/s^2; 0: no soft pin
    pin_damping: wp.array(dtype=float)  # (n,) its damping / the particle's mass, 1/s
    pin_x: wp.array(dtype=wp.vec3)  # (n,) where it pulls the particle this substep
    pin_v: wp.array(dtype=wp.vec3)  # (n,) the velocity there


@wp.func
def external_acceleration(forces: ExternalForces, i: int, x: wp.vec3, v: wp.vec3) -> wp.vec3:
    """The acceleration of particle i, at x with velocity v, from the external forces (the wind's taken
    as it was at the substep's start: explicit in both integrators)."""
    a = forces.gravity[forces.world[i]] - forces.drag * v
    if forces.wind.shape[0] > 0:
        a = a + forces.wind[i]
    if forces.pin_rate.shape[0] > 0:
        a = a + forces.pin_rate[i] * (forces.pin_x[i] - x) + forces.pin_damping[i] * (forces.pin_v[i] - v)
    return a


@wp.func
def external_damping(forces: ExternalForces, i: int) -> float:
    """-d(acceleration)/dv of the external forces on particle i (a multiple of the identity), for the
    implicit matrix."""
    if forces.pin_rate.shape[0] > 0:
        return forces.drag + forces.pin_damping[i]
    return forces.drag


@wp.func
def external_stiffness(forces: ExternalForces, i: int) -> float:
    """-d(acceleration)/dx of the external forces on particle i (a multiple of the identity: a soft pin's),
    for the implicit matrix."""
    if forces.pin_rate.shape[0] > 0:
        return forces.pin_rate[i]
    return 0.0
