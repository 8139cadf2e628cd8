"""Rigid colliders: the ground plane and spheres.

A particle inside is put back on the surface, and, as for every position correction here, its velocity
changes by that correction over h (so a particle that sank in during the substep stops, and one hit by a
moving sphere takes the sphere's normal speed). What is still approaching the collider after that is
removed, and friction takes tangential speed relative to the collider in proportion to the normal speed
taken away (Coulomb), so a cloth sliding on the ground decelerates at mu g.

All of a scene's colliders travel in one ``RigidColliders`` and act through ``collide_particle``, so that
the kernels that move particles (the strain limit's and the collision's passes) can end with them
instead of launching another kernel: every collider acts on one particle alone.

With particle collision, the colliders also mark the particles they hold up (``resting``), which the
collision passes read. A pass reads one bit of it (``read_bit``, 1 or 2) and its colliders write the
other, so a kernel that reads its neighbours' flags never sees them change under it; the passes
alternate the bits.
"""

import warp as wp

from .lanes import FAST_MATH

wp.set_module_options(FAST_MATH)


@wp.struct
class RigidColliders:
    ground: int  # 1 when the scene has a ground plane
    ground_height: float
    ground_friction: float
    center: wp.array(dtype=wp.vec3)  # spheres (none: empty arrays)
    velocity: wp.array(dtype=wp.vec3)
    radius: wp.array(dtype=float)
    friction: wp.array(dtype=float)


@wp.func
def contact_velocity(v: wp.vec3, collider_velocity: wp.vec3, normal: wp.vec3, pushed_speed: float,
                     friction: float) -> wp.vec3:
    """Velocity after a contact whose position correction already added ``pushed_speed`` along the normal."""
    relative = v - collider_velocity
    vn = wp.dot(relative, normal)
    stopped = pushed_speed
    if vn < 0.0:
        relative = relative - vn * normal
        stopped = stopped - vn
    tangential = relative - wp.dot(relative, normal) * normal
    speed = wp.length(tangential)
    if speed > 0.0:
        relative = relative - tangential * wp.min(1.0, friction * stopped / speed)
    return collider_velocity + relative


@wp.func
def collide_particle(p: wp.vec3, vel: wp.vec3, colliders: RigidColliders, h: float):
    """A free particle's position and velocity after the ground, then each sphere; and 1 if any of them
    touched it."""
    hit = int(0)
    if colliders.ground != 0 and p[1] < colliders.ground_height:
        depth = colliders.ground_height - p[1]
        p = wp.vec3(p[0], colliders.ground_height, p[2])
        up = wp.vec3(0.0, 1.0, 0.0)
        vel = contact_velocity(vel + up * (depth / h), wp.vec3(0.0), up, depth / h, colliders.ground_friction)
        hit = 1
    for s in range(colliders.center.shape[0]):
        d = p - colliders.center[s]
        dist = wp.length(d)
        if dist < colliders.radius[s]:
            normal = wp.vec3(0.0, 1.0, 0.0)
            if dist > 1.0e-12:
                normal = d / dist
            depth = colliders.radius[s] - dist
            p = colliders.center[s] + colliders.radius[s] * normal
            vel = contact_velocity(vel + normal * (depth / h), colliders.velocity[s], normal, depth / h,
                                   colliders.friction[s])
            hit = 1
    return p, vel, hit


@wp.func
def collide_and_mark(i: int, p: wp.vec3, vel: wp.vec3, colliders: RigidColliders, h: float,
                     resting: wp.array(dtype=int), read_bit: int):
    """``collide_particle``, then particle i is marked resting for the next pass if it was for this one or
    a collider touched it now (``resting`` empty: no marks)."""
    p, vel, hit = collide_particle(p, vel, colliders, h)
    if resting.shape[0] > 0:
        seen = resting[i] & read_bit
        if seen != 0 or hit != 0:
            resting[i] = seen | (3 - read_bit)
        else:
            resting[i] = 0
    return p, vel


@wp.kernel
def collide(colliders: RigidColliders, h: float, inv_mass: wp.array(dtype=float), x: wp.array(dtype=wp.vec3),
            v: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    if inv_mass[i] == 0.0:
        return
    p, vel, hit = collide_particle(x[i], v[i], colliders, h)
    x[i] = p
    v[i] = vel
