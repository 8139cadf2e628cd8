"""Rigid colliders: the ground plane and spheres.

A particle inside is put back on the surface, and, as for every position correction here, its velocity
changes by that correction over h (so a particle that sank in during the substep stops, and one hit by a
moving sphere takes the sphere's normal speed). What is still approaching the collider after that is
removed, and friction takes tangential speed relative to the collider in proportion to the normal speed
taken away (Coulomb), so a cloth sliding on the ground decelerates at mu g.
"""

import warp as wp


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


@wp.kernel
def collide_ground(height: float, friction: float, h: float, inv_mass: wp.array(dtype=float),
                   x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), resting: wp.array(dtype=int)):
    """``resting`` (empty without particle collision) marks the particles a collider holds up."""
    i = wp.tid()
    p = x[i]
    if p[1] >= height or inv_mass[i] == 0.0:
        return
    if resting.shape[0] > 0:
        resting[i] = 1
    depth = height - p[1]
    x[i] = wp.vec3(p[0], height, p[2])
    normal = wp.vec3(0.0, 1.0, 0.0)
    v[i] = contact_velocity(v[i] + normal * (depth / h), wp.vec3(0.0), normal, depth / h, friction)


@wp.kernel
def collide_spheres(center: wp.array(dtype=wp.vec3), sphere_velocity: wp.array(dtype=wp.vec3),
                    radius: wp.array(dtype=float), friction: wp.array(dtype=float), h: float,
                    inv_mass: wp.array(dtype=float), x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3),
                    resting: wp.array(dtype=int)):
    i = wp.tid()
    if inv_mass[i] == 0.0:
        return
    p = x[i]
    vel = v[i]
    for s in range(center.shape[0]):
        d = p - center[s]
        dist = wp.length(d)
        if dist < radius[s]:
            normal = wp.vec3(0.0, 1.0, 0.0)
            if dist > 1.0e-12:
                normal = d / dist
            depth = radius[s] - dist
            if resting.shape[0] > 0:
                resting[i] = 1
            p = center[s] + radius[s] * normal
            vel = contact_velocity(vel + normal * (depth / h), sphere_velocity[s], normal, depth / h, friction[s])
    x[i] = p
    v[i] = vel
