"""Prescribed motion: the simulation clock, and oscillations x0 + A sin(2 pi f t + phase) along an axis that
drive pins and move spheres. (A fixed pin needs no kernel: its particle has inverse mass 0, starts at rest
at its anchor, and nothing moves it.)"""

import warp as wp


@wp.func
def oscillation_offset(t: float, amplitude: wp.vec3, frequency: float, phase: float) -> wp.vec3:
    return amplitude * wp.sin(2.0 * wp.pi * frequency * t + phase)


@wp.func
def oscillation_velocity(t: float, amplitude: wp.vec3, frequency: float, phase: float) -> wp.vec3:
    omega = 2.0 * wp.pi * frequency
    return amplitude * (omega * wp.cos(omega * t + phase))


@wp.func
def clock_time(clock: wp.array(dtype=int), h: float) -> float:
    """Time at the end of the current substep (the clock counts finished substeps)."""
    return float(clock[0] + 1) * h


@wp.kernel
def advance_clock(clock: wp.array(dtype=int)):
    clock[0] = clock[0] + 1


@wp.func
def key_segment(t: float, times: wp.array(dtype=float), first: int, last: int) -> int:
    """The key a linear path through keys ``first`` to ``last`` (inclusive) leaves from at ``t``: the last
    key not after ``t``, ``first`` before it and ``last`` after the last."""
    k = first
    while k < last and times[k + 1] <= t:
        k += 1
    return k


@wp.func
def keyed_slope(t: float, times: wp.array(dtype=float), values: wp.array(dtype=wp.vec3), first: int,
                last: int) -> wp.vec3:
    """The rate of change at ``t`` of the path through keys ``first`` to ``last``: zero where it is held,
    before the first key and after the last."""
    k = key_segment(t, times, first, last)
    if k == last or t <= times[first]:
        return wp.vec3(0.0)
    return (values[k + 1] - values[k]) / (times[k + 1] - times[k])


@wp.func
def keyed_value(t: float, times: wp.array(dtype=float), values: wp.array(dtype=wp.vec3), first: int,
                last: int) -> wp.vec3:
    """The value at ``t`` of the path through keys ``first`` to ``last``, linear between two keys."""
    k = key_segment(t, times, first, last)
    return values[k] + wp.max(t - times[k], 0.0) * keyed_slope(t, times, values, first, last)


@wp.kernel
def move_spheres(clock: wp.array(dtype=int), h: float, base: wp.array(dtype=wp.vec3),
                 key_start: wp.array(dtype=int), key_time: wp.array(dtype=float),
                 key_offset: wp.array(dtype=wp.vec3), amplitude: wp.array(dtype=wp.vec3),
                 frequency: wp.array(dtype=float), phase: wp.array(dtype=float), center: wp.array(dtype=wp.vec3),
                 velocity: wp.array(dtype=wp.vec3)):
    """Each sphere along its keys (linearly between them, held before the first and after the last) plus
    its oscillation, at the end of the substep, with the velocity of both."""
    s = wp.tid()
    t = clock_time(clock, h)
    first, last = key_start[s], key_start[s + 1] - 1
    center[s] = base[s] + keyed_value(t, key_time, key_offset, first, last) + \
        oscillation_offset(t, amplitude[s], frequency[s], phase[s])
    velocity[s] = keyed_slope(t, key_time, key_offset, first, last) + \
        oscillation_velocity(t, amplitude[s], frequency[s], phase[s])


@wp.kernel
def drive_pins(index: wp.array(dtype=int), anchor: wp.array(dtype=wp.vec3), amplitude: wp.array(dtype=wp.vec3),
               frequency: wp.array(dtype=float), phase: wp.array(dtype=float), clock: wp.array(dtype=int),
               h: float, x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)):
    p = wp.tid()
    i = index[p]
    t = clock_time(clock, h)
    x[i] = anchor[p] + oscillation_offset(t, amplitude[p], frequency[p], phase[p])
    v[i] = oscillation_velocity(t, amplitude[p], frequency[p], phase[p])


@wp.kernel
def pinned_velocity_change(index: wp.array(dtype=int), amplitude: wp.array(dtype=wp.vec3),
                           frequency: wp.array(dtype=float), phase: wp.array(dtype=float), clock: wp.array(dtype=int),
                           h: float, v: wp.array(dtype=wp.vec3), dv: wp.array(dtype=wp.vec3)):
    """For an implicit solve: the change that brings each pinned particle to its prescribed velocity at the
    end of the substep (zero for fixed pins)."""
    p = wp.tid()
    i = index[p]
    dv[i] = oscillation_velocity(clock_time(clock, h), amplitude[p], frequency[p], phase[p]) - v[i]


@wp.func
def keyed_point_velocity(t: float, key_times: wp.array(dtype=float), keys: wp.array2d(dtype=wp.vec3),
                         j: int) -> wp.vec3:
    """The velocity of point ``j`` of a keyed point set at ``t``: between the two keys around it, zero before
    the first key and after the last."""
    last = key_times.shape[0] - 1
    k = key_segment(t, key_times, 0, last)
    if k == last or t <= key_times[0]:
        return wp.vec3(0.0)
    return (keys[k + 1, j] - keys[k, j]) / (key_times[k + 1] - key_times[k])


@wp.func
def keyed_point(t: float, key_times: wp.array(dtype=float), keys: wp.array2d(dtype=wp.vec3), j: int) -> wp.vec3:
    """Point ``j`` of a keyed point set at ``t``: linearly between the two keys around it, held at the first
    before it and at the last after it."""
    k = key_segment(t, key_times, 0, key_times.shape[0] - 1)
    return keys[k, j] + wp.max(t - key_times[k], 0.0) * keyed_point_velocity(t, key_times, keys, j)


@wp.kernel
def place_keyed_points(clock: wp.array(dtype=int), h: float, key_times: wp.array(dtype=float),
                       keys: wp.array2d(dtype=wp.vec3), points: wp.array(dtype=wp.vec3),
                       velocities: wp.array(dtype=wp.vec3)):
    """An animated mesh's vertex where its keys put it at the end of the substep, with its velocity."""
    j = wp.tid()
    t = clock_time(clock, h)
    points[j] = keyed_point(t, key_times, keys, j)
    velocities[j] = keyed_point_velocity(t, key_times, keys, j)


@wp.kernel
def place_keyed_particles(clock: wp.array(dtype=int), h: float, key_times: wp.array(dtype=float),
                          keys: wp.array2d(dtype=wp.vec3), index: wp.array(dtype=int), x: wp.array(dtype=wp.vec3),
                          v: wp.array(dtype=wp.vec3)):
    """Keyed pinned particles where their keys put them at the end of the substep, with their velocity."""
    j = wp.tid()
    t = clock_time(clock, h)
    x[index[j]] = keyed_point(t, key_times, keys, j)
    v[index[j]] = keyed_point_velocity(t, key_times, keys, j)


@wp.func
def face_frame(mesh: wp.uint64, face: int) -> wp.mat33:
    """An orthonormal frame of a mesh face as it is now: its first edge, across it, its normal (columns)."""
    a = wp.mesh_eval_position(mesh, face, 1.0, 0.0)
    b = wp.mesh_eval_position(mesh, face, 0.0, 1.0)
    n = wp.mesh_eval_face_normal(mesh, face)
    e1 = wp.normalize(b - a)
    return wp.matrix_from_cols(e1, wp.cross(n, e1), n)


@wp.kernel
def attach_to_mesh(mesh: wp.uint64, index: wp.array(dtype=int), x: wp.array(dtype=wp.vec3),
                   face: wp.array(dtype=int), bary: wp.array(dtype=wp.vec2), offset: wp.array(dtype=wp.vec3)):
    """Each particle's nearest point on the mesh (face and barycentric coordinates) and where the particle
    is from it in that face's frame, once, for pins that follow the mesh."""
    k = wp.tid()
    p = x[index[k]]
    query = wp.mesh_query_point_no_sign(mesh, p, 1.0e7)
    face[k] = query.face
    bary[k] = wp.vec2(query.u, query.v)
    on_face = wp.mesh_eval_position(mesh, query.face, query.u, query.v)
    offset[k] = wp.transpose(face_frame(mesh, query.face)) * (p - on_face)


@wp.kernel
def follow_mesh(mesh: wp.uint64, index: wp.array(dtype=int), face: wp.array(dtype=int),
                bary: wp.array(dtype=wp.vec2), offset: wp.array(dtype=wp.vec3), x: wp.array(dtype=wp.vec3),
                v: wp.array(dtype=wp.vec3)):
    """Pinned particles where their attachment to the mesh, as it is now, puts them, with the surface's
    velocity there."""
    k = wp.tid()
    f = face[k]
    u = bary[k][0]
    w = bary[k][1]
    i = index[k]
    x[i] = wp.mesh_eval_position(mesh, f, u, w) + face_frame(mesh, f) * offset[k]
    v[i] = wp.mesh_eval_velocity(mesh, f, u, w)


@wp.kernel
def follow_control(clock: wp.array(dtype=int), substeps: int, frame_time: float, index: wp.array(dtype=int),
                   start: wp.array(dtype=wp.vec3), goal: wp.array(dtype=wp.vec3), first_frame: wp.array(dtype=int),
                   x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)):
    """Points sent from Python (warp_cloth/control.py): row r, sent before frame ``first_frame[r]`` (-1: not
    sent), goes from ``start`` to ``goal`` in a straight line over that frame, at the end of each substep,
    with its speed, and then stays at ``goal`` at rest."""
    r = wp.tid()
    if first_frame[r] < 0:
        return
    i = index[r]
    done = clock[0] - first_frame[r] * substeps  # the frame's substeps finished before this one
    if done >= substeps:
        x[i] = goal[r]
        v[i] = wp.vec3(0.0)
        return
    w = float(done + 1) / float(substeps)
    x[i] = (1.0 - w) * start[r] + w * goal[r]
    v[i] = (goal[r] - start[r]) / frame_time
