"""The moves between the levels of the multilevel limit solve (warp_cloth/hierarchy.py): each level's
nodes start where their particles are; each coarse limit's path is measured and, where it is longer than
its springs allow, the straight distance between its ends given the same proportion as its target; a
finer level's nodes follow their parents in the coarser one, by the weighted mean of the parents'
displacements since the start."""

import warp as wp


@wp.kernel
def start_levels(particle: wp.array(dtype=int), x: wp.array(dtype=wp.vec3), start: wp.array(dtype=wp.vec3),
                 current: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    p = x[particle[i]]
    start[i] = p
    current[i] = p


INACTIVE = wp.constant(1.0e30)  # the longest target of a limit whose path is not too long


@wp.kernel
def measure_springs(ends: wp.array(dtype=wp.vec2i), x: wp.array(dtype=wp.vec3), length: wp.array(dtype=float)):
    """The level-0 limits (the springs'): how long each is now."""
    e = wp.tid()
    length[e] = wp.length(x[ends[e][0]] - x[ends[e][1]])


@wp.kernel
def measure_paths(first: int, ends: wp.array(dtype=wp.vec2i), path: wp.array(dtype=wp.vec3i),
                  shortest: wp.array(dtype=float), longest: wp.array(dtype=float), start: wp.array(dtype=wp.vec3),
                  length: wp.array(dtype=float), target: wp.array(dtype=wp.vec2)):
    """Limit first + tid of a coarse level: its path's length now (the finer limits' along it), and its
    target range: the straight distance between its ends shortened (lengthened) in the proportion the path
    is too long (too short), else unbounded on that side."""
    e = first + wp.tid()
    total = float(0.0)
    for c in range(3):
        part = path[e][c]
        if part >= 0:
            total = total + length[part]
    length[e] = total
    chord = wp.length(start[ends[e][0]] - start[ends[e][1]])
    lo = float(0.0)
    hi = INACTIVE
    if total > longest[e]:
        hi = chord * (longest[e] / total)
    elif total < shortest[e] and total > 0.0:
        lo = chord * (shortest[e] / total)
    target[e] = wp.vec2(lo, hi)


@wp.func
def parents_displacement(i: int, offsets: wp.array(dtype=int), parent: wp.array(dtype=int),
                         weight: wp.array(dtype=float), start: wp.array(dtype=wp.vec3),
                         current: wp.array(dtype=wp.vec3)) -> wp.vec3:
    d = wp.vec3(0.0)
    for e in range(offsets[i], offsets[i + 1]):
        j = parent[e]
        d = d + weight[e] * (current[j] - start[j])
    return d


@wp.kernel
def follow_parents(first: int, offsets: wp.array(dtype=int), parent: wp.array(dtype=int),
                   weight: wp.array(dtype=float), inv_mass: wp.array(dtype=float), start: wp.array(dtype=wp.vec3),
                   current: wp.array(dtype=wp.vec3)):
    """Node first + tid of a level moves to its start plus its parents' displacement (a pinned one stays)."""
    i = first + wp.tid()
    if inv_mass[i] == 0.0:
        return
    current[i] = start[i] + parents_displacement(i, offsets, parent, weight, start, current)


@wp.kernel
def particles_follow_parents(offsets: wp.array(dtype=int), parent: wp.array(dtype=int),
                             weight: wp.array(dtype=float), inv_mass: wp.array(dtype=float),
                             start: wp.array(dtype=wp.vec3), current: wp.array(dtype=wp.vec3), h: float,
                             x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)):
    """Each free particle moves by its parents' displacement in the first level, its velocity changed by
    that move over h, as for every projection here."""
    i = wp.tid()
    if inv_mass[i] == 0.0:
        return
    d = parents_displacement(i, offsets, parent, weight, start, current)
    x[i] = x[i] + d
    v[i] = v[i] + d / h
