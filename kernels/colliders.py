"""Rigid colliders: the ground plane and spheres. A particle inside is put back on the surface and loses
the normal component of its velocity relative to the collider if it is approaching; friction then takes
away tangential relative speed in proportion to that normal impulse (Coulomb)."""

import warp as wp


@wp.func
def contact_velocity(v: wp.vec3, collider_velocity: wp.vec3, normal: wp.vec3, friction: float) -> wp.vec3:
    relative = v - collider_velocity
    vn = wp.dot(relative, normal)
    if vn >= 0.0:
        return v
    tangential = relative - vn * normal
    speed = wp.length(tangential)
    if speed > 0.0:
        tangential = tangential * wp.max(0.0, 1.0 - friction * (-vn) / speed)
    return collider_velocity + tangential


@wp.kernel
def collide_ground(height: float, friction: float, inv_mass: wp.array(dtype=float),
                   x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    p = x[i]
    if p[1] >= height or inv_mass[i] == 0.0:
        return
    x[i] = wp.vec3(p[0], height, p[2])
    v[i] = contact_velocity(v[i], wp.vec3(0.0), wp.vec3(0.0, 1.0, 0.0), friction)


@wp.kernel
def collide_spheres(center: wp.array(dtype=wp.vec3), sphere_velocity: wp.array(dtype=wp.vec3),
                    radius: wp.array(dtype=float), friction: wp.array(dtype=float),
                    inv_mass: wp.array(dtype=float), x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)):
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
            p = center[s] + radius[s] * normal
            vel = contact_velocity(vel, sphere_velocity[s], normal, friction[s])
    x[i] = p
    v[i] = vel
