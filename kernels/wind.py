"""Wind: aerodynamic drag and lift on each face of the cloth, from the air's velocity relative to it.

A face (a triangle, or a quad as its two fan triangles) of area A and unit normal n, in air of density rho
moving at ``u`` relative to the face's mean velocity, feels
  drag  = 1/2 rho C_D A (u . n) |u . n| n                      (the pressure on it, along its normal)
  lift  = 1/2 rho C_L A |u|^2 cos(t) sin(t) l                  (across the flow)
where t is the angle between u and the normal turned to face downstream, and l the unit vector across u
towards that normal (a plate tilted in a horizontal wind is lifted). Each face's force is shared equally
among its vertices, so that a flat sheet whose masses are lumped the same way moves as one. The wind's
velocity is ``velocity`` plus, with ``turbulence``, Perlin noise of that fraction of its speed, varying
over ``scale`` metres and seconds. Particles gather their faces' shares (one thread each, no atomics: the
same sums on every run and device) of the shares one thread a face computed; the result is an acceleration
the integrators read as an external force (forces.py).
"""

import warp as wp

from .motion import keyed_value

wp.set_module_options({"fast_math": True})


@wp.struct
class Wind:
    key_time: wp.array(dtype=float)  # the velocity's keys (one, at 0, for a steady wind)
    key_velocity: wp.array(dtype=wp.vec3)
    turbulence: float  # noise amplitude as a fraction of |velocity|
    scale: float  # metres and seconds over which the noise varies
    air_density: float
    drag: float  # C_D
    lift: float  # C_L
    faces: wp.array(dtype=wp.vec4i)  # each face's particles, -1 as a triangle's fourth
    offsets: wp.array(dtype=int)  # (n + 1,) each particle's faces (CSR)
    incident: wp.array(dtype=int)


@wp.func
def air_velocity(wind: Wind, p: wp.vec3, t: float) -> wp.vec3:
    velocity = keyed_value(t, wind.key_time, wind.key_velocity, 0, wind.key_time.shape[0] - 1)
    if wind.turbulence <= 0.0:
        return velocity
    q = wp.vec4(p[0] / wind.scale, p[1] / wind.scale, p[2] / wind.scale, t / wind.scale)
    noise = wp.vec3(wp.noise(wp.uint32(11), q), wp.noise(wp.uint32(23), q), wp.noise(wp.uint32(37), q))
    return velocity + (wind.turbulence * wp.length(velocity)) * noise


@wp.func
def triangle_force(wind: Wind, a: wp.vec3, b: wp.vec3, c: wp.vec3, v: wp.vec3, t: float) -> wp.vec3:
    """The drag and lift on triangle a b c moving at v."""
    cross = wp.cross(b - a, c - a)
    twice_area = wp.length(cross)
    if twice_area <= 0.0:
        return wp.vec3(0.0)
    n = cross / twice_area
    u = air_velocity(wind, (a + b + c) / 3.0, t) - v
    un = wp.dot(u, n)
    pressure = 0.25 * wind.air_density * twice_area  # 1/2 rho A
    force = (pressure * wind.drag * un * wp.abs(un)) * n
    speed = wp.length(u)
    if wind.lift != 0.0 and speed > 0.0:
        downstream = n
        if un < 0.0:
            downstream = -n
        across = downstream - wp.dot(downstream, u / speed) * (u / speed)  # |across| = sin(t)
        cos_t = wp.abs(un) / speed
        force = force + (pressure * wind.lift * speed * speed * cos_t) * across
    return force


@wp.kernel
def face_forces(wind: Wind, clock: wp.array(dtype=int), h: float, x: wp.array(dtype=wp.vec3),
                v: wp.array(dtype=wp.vec3), force: wp.array(dtype=wp.vec3)):
    """Each face's wind force over its vertex count (a vertex's share), at the start of the substep (the
    clock counts finished substeps)."""
    k = wp.tid()
    f = wind.faces[k]
    t = float(clock[0]) * h
    if f[3] < 0:
        mean_v = (v[f[0]] + v[f[1]] + v[f[2]]) / 3.0
        force[k] = triangle_force(wind, x[f[0]], x[f[1]], x[f[2]], mean_v, t) / 3.0
    else:
        mean_v = (v[f[0]] + v[f[1]] + v[f[2]] + v[f[3]]) / 4.0
        force[k] = (triangle_force(wind, x[f[0]], x[f[1]], x[f[2]], mean_v, t)
                    + triangle_force(wind, x[f[0]], x[f[2]], x[f[3]], mean_v, t)) / 4.0


@wp.kernel
def wind_accelerations(wind: Wind, share: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float),
                       acceleration: wp.array(dtype=wp.vec3)):
    """Each particle's shares of its faces' forces, over its mass (zero for a pinned particle)."""
    i = wp.tid()
    total = wp.vec3(0.0)
    for k in range(wind.offsets[i], wind.offsets[i + 1]):
        total = total + share[wind.incident[k]]
    acceleration[i] = total * inv_mass[i]
