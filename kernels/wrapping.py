"""The shortest way between two points that stays outside a world's spheres: how far a particle is from its
pin across whatever cloth may lie between them, for long-range attachments that run over a sphere.

The cloth between a pin and a particle is a path of limited springs whose particles the colliders keep
outside each sphere; a spring's chord of length L between two such particles stays outside the sphere
shrunk to sqrt(r^2 - (L/2)^2). The shortest way around that shrunk sphere is then no longer than the cloth's
path, so holding it within (1 + stretch) times the rest distance asks nothing the springs' own limits do
not. Where the straight line misses a sphere, or an end lies inside it, the straight distance is that
bound; a sphere the line passes through makes it the way around: the tangent from the pin, the great
circle's arc, the tangent to the particle.
"""

import warp as wp

from .colliders import RigidColliders


@wp.func
def perpendicular_to(u: wp.vec3) -> wp.vec3:
    """Some unit vector perpendicular to unit vector u."""
    axis = wp.vec3(1.0, 0.0, 0.0)
    if wp.abs(u[0]) > 0.9:
        axis = wp.vec3(0.0, 1.0, 0.0)
    return wp.normalize(wp.cross(u, axis))


@wp.func
def way_around_sphere(a: wp.vec3, p: wp.vec3, centre: wp.vec3, radius: float):
    """The length of the shortest way from a to p outside the ball (centre, radius), and the unit direction
    in which that length grows fastest as p moves (along the way's last straight piece)."""
    d = p - a
    straight = wp.length(d)
    direction = d / wp.max(straight, 1.0e-12)
    ca = a - centre
    cp = p - centre
    da = wp.length(ca)
    dp = wp.length(cp)
    if da <= radius or dp <= radius:
        return straight, direction
    u = cp / dp
    angle = wp.acos(wp.clamp(wp.dot(ca, cp) / (da * dp), -1.0, 1.0))
    arc = angle - wp.acos(radius / da) - wp.acos(radius / dp)
    if arc <= 0.0:
        return straight, direction
    to_a = ca - wp.dot(ca, u) * u  # towards a, across p's radius
    across = perpendicular_to(u)
    if wp.length(to_a) > 1.0e-9 * da:
        across = wp.normalize(to_a)
    tangent_a = wp.sqrt(da * da - radius * radius)
    tangent_p = wp.sqrt(dp * dp - radius * radius)
    return tangent_a + tangent_p + radius * arc, (tangent_p * u - radius * across) / dp


@wp.func
def distance_to_pin(colliders: RigidColliders, i: int, a: wp.vec3, p: wp.vec3, chord_half: float):
    """How far particle i at p is from its pin at a across any cloth between them (the longest of the ways
    around each of its world's spheres, each shrunk by the chord of its longest spring, ``chord_half`` half
    of it), and the direction in which that grows as p moves."""
    d = p - a
    length = wp.length(d)
    direction = d / wp.max(length, 1.0e-12)
    if colliders.world.shape[0] == 0:
        return length, direction
    w = colliders.world[i]
    for s in range(colliders.sphere_start[w], colliders.sphere_start[w + 1]):
        r = colliders.radius[s]
        shrunk = wp.sqrt(wp.max(r * r - chord_half * chord_half, 0.0))
        around, towards = way_around_sphere(a, p, colliders.center[s], shrunk)
        if around > length:
            length = around
            direction = towards
    return length, direction
