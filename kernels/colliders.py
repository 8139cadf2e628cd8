"""Rigid colliders: the ground plane, spheres and the user's meshes.

A particle inside is put back on the surface, and, as for every position correction here, its velocity
changes by that correction over h (so a particle that sank in during the substep stops, and one hit by a
moving sphere takes the sphere's normal speed). What is still approaching the collider after that is
removed, and friction takes tangential speed relative to the collider in proportion to the normal speed
taken away (Coulomb), so a cloth sliding on the ground decelerates at mu g. The coefficient is the
collider's, or the particle's cloth's (its material's) where that is larger.

All of a scene's colliders travel in one ``RigidColliders`` and act through ``collide_particle``, which
runs each kind of the particle's world (see warp_cloth/model.py's ``Worlds``) in turn on one particle alone, so that the passes that move particles can end with them
instead of launching another kernel. A new collider kind is its fields here (filled in by its entry in
warp_cloth/collider_kinds.py), one ``collide_<kind>`` function of the form below, and its line in
``collide_particle``.

With particle collision, the colliders also mark the particles they hold up (``resting``), which the
collision passes read. A pass reads one bit of it (``read_bit``, 1 or 2) and its colliders write the
other, so a kernel that reads its neighbours' flags never sees them change under it; the passes
alternate the bits.
"""

import warp as wp

wp.set_module_options({"fast_math": True})  # as the gathering kernels (see gathering.py)


@wp.struct
class RigidColliders:
    world: wp.array(dtype=int)  # (n,) each particle's world
    ground: wp.array(dtype=int)  # (worlds,) 1 where the world has a ground plane
    ground_height: wp.array(dtype=float)
    ground_friction: wp.array(dtype=float)
    sphere_start: wp.array(dtype=int)  # (worlds + 1,) world w's spheres are sphere_start[w] to [w + 1] - 1
    mesh_start: wp.array(dtype=int)  # (worlds + 1,) likewise its meshes
    center: wp.array(dtype=wp.vec3)  # spheres (none: empty arrays); centres and velocities are state
    velocity: wp.array(dtype=wp.vec3)
    radius: wp.array(dtype=float)
    friction: wp.array(dtype=float)
    angular_velocity: wp.array(dtype=wp.vec3)  # radians a second about each centre
    meshes: wp.array(dtype=wp.uint64)  # mesh colliders' BVHs (wp.Mesh ids; none: empty)
    mesh_thickness: wp.array(dtype=float)
    mesh_friction: wp.array(dtype=float)
    mesh_reach: float  # how far past its thickness a mesh looks for particles (behind its faces too)
    cloth_friction: wp.array(dtype=float)  # (n,) each particle's cloth's coefficient, or empty: none


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
def collide_ground(w: int, p: wp.vec3, vel: wp.vec3, hit: int, colliders: RigidColliders, h: float,
                   cloth_friction: float):
    height = colliders.ground_height[w]
    if colliders.ground[w] != 0 and p[1] < height:
        depth = height - p[1]
        p = wp.vec3(p[0], height, p[2])
        up = wp.vec3(0.0, 1.0, 0.0)
        vel = contact_velocity(vel + up * (depth / h), wp.vec3(0.0), up, depth / h,
                               wp.max(colliders.ground_friction[w], cloth_friction))
        hit = 1
    return p, vel, hit


@wp.func
def collide_spheres(w: int, p: wp.vec3, vel: wp.vec3, hit: int, colliders: RigidColliders, h: float,
                    cloth_friction: float):
    for s in range(colliders.sphere_start[w], colliders.sphere_start[w + 1]):
        d = p - colliders.center[s]
        dist = wp.length(d)
        if dist < colliders.radius[s]:
            normal = wp.vec3(0.0, 1.0, 0.0)
            if dist > 1.0e-12:
                normal = d / dist
            depth = colliders.radius[s] - dist
            p = colliders.center[s] + colliders.radius[s] * normal
            surface_velocity = colliders.velocity[s] + wp.cross(colliders.angular_velocity[s],
                                                                colliders.radius[s] * normal)
            vel = contact_velocity(vel + normal * (depth / h), surface_velocity, normal, depth / h,
                                   wp.max(colliders.friction[s], cloth_friction))
            hit = 1
    return p, vel, hit


@wp.func
def collide_meshes(w: int, p: wp.vec3, vel: wp.vec3, hit: int, colliders: RigidColliders, h: float,
                   cloth_friction: float):
    """Each mesh keeps the particle ``thickness`` off the side its nearest face faces: a particle closer,
    or behind that face (inside a closed mesh), is put at that distance along the direction from the
    nearest surface point (a face's normal, or out from an edge or corner); friction acts against the
    speed relative to the surface there (its vertices' velocities, zero for a static mesh)."""
    for m in range(colliders.mesh_start[w], colliders.mesh_start[w + 1]):
        mesh = colliders.meshes[m]
        thickness = colliders.mesh_thickness[m]
        query = wp.mesh_query_point_sign_normal(mesh, p, thickness + colliders.mesh_reach)
        if query.result:
            closest = wp.mesh_eval_position(mesh, query.face, query.u, query.v)
            d = p - closest
            dist = wp.length(d)
            normal = d * (query.sign / wp.max(dist, 1.0e-9))
            if dist <= 1.0e-9:  # on the surface itself: the face's normal
                normal = wp.mesh_eval_face_normal(mesh, query.face)
            depth = thickness - query.sign * dist
            if depth > 0.0:
                p = closest + thickness * normal
                surface_velocity = wp.mesh_eval_velocity(mesh, query.face, query.u, query.v)
                vel = contact_velocity(vel + normal * (depth / h), surface_velocity, normal, depth / h,
                                       wp.max(colliders.mesh_friction[m], cloth_friction))
                hit = 1
    return p, vel, hit


@wp.func
def collide_particle(i: int, p: wp.vec3, vel: wp.vec3, colliders: RigidColliders, h: float):
    """Free particle i's position and velocity after every collider kind of its world in turn; and 1 if
    any of them touched it."""
    hit = int(0)
    if colliders.world.shape[0] == 0:  # no colliders
        return p, vel, hit
    w = colliders.world[i]
    cloth_friction = float(0.0)
    if colliders.cloth_friction.shape[0] > 0:
        cloth_friction = colliders.cloth_friction[i]
    p, vel, hit = collide_ground(w, p, vel, hit, colliders, h, cloth_friction)
    p, vel, hit = collide_spheres(w, p, vel, hit, colliders, h, cloth_friction)
    p, vel, hit = collide_meshes(w, p, vel, hit, colliders, h, cloth_friction)
    return p, vel, hit


@wp.func
def mark_resting(i: int, hit: int, resting: wp.array(dtype=int), read_bit: int):
    """Particle i is marked resting for the next pass if it was for this one or a collider touched it now
    (``resting`` empty: no marks)."""
    if resting.shape[0] > 0:
        seen = resting[i] & read_bit
        if seen != 0 or hit != 0:
            resting[i] = seen | (3 - read_bit)
        else:
            resting[i] = 0


@wp.func
def collide_and_mark(i: int, p: wp.vec3, vel: wp.vec3, colliders: RigidColliders, h: float,
                     resting: wp.array(dtype=int), read_bit: int):
    """``collide_particle``, then ``mark_resting``."""
    p, vel, hit = collide_particle(i, p, vel, colliders, h)
    mark_resting(i, hit, resting, read_bit)
    return p, vel


@wp.kernel
def collide(colliders: RigidColliders, h: float, inv_mass: wp.array(dtype=float), x: wp.array(dtype=wp.vec3),
            v: wp.array(dtype=wp.vec3)):
    """The colliders alone, where no other pass moves particles after integration."""
    i = wp.tid()
    if inv_mass[i] == 0.0:
        return
    p, vel, hit = collide_particle(i, x[i], v[i], colliders, h)
    x[i] = p
    v[i] = vel


@wp.kernel
def depth_in_mesh(mesh: wp.uint64, thickness: float, reach: float, x: wp.array(dtype=wp.vec3),
                  depth: wp.array(dtype=float)):
    """How far each point is inside the mesh's thickness (behind its nearest face counts as inside; points
    farther than ``reach`` from the surface: 0), for the check of where cloths start."""
    i = wp.tid()
    query = wp.mesh_query_point_sign_normal(mesh, x[i], reach)
    depth[i] = 0.0
    if query.result:
        closest = wp.mesh_eval_position(mesh, query.face, query.u, query.v)
        depth[i] = wp.max(0.0, thickness - query.sign * wp.length(x[i] - closest))
