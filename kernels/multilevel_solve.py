"""The strain limits as stiff springs, solved by conjugate gradients with a multilevel preconditioner (issue 33,
the lab's trial; warp_cloth/multilevel_solve.py). Every limited spring is held, the violated ones at their
limit and the others at their current length: a step dx minimises 1/2 |dx|_M^2 + k/2 |J dx + C|^2, that is
(M + k J^T J) dx = -k J^T C over the free particles. The matrix is kept as 3x3 blocks, a diagonal block a node
and an off-diagonal block an edge (on the finest level a node is a particle and an edge a spring); a coarser
level's nodes are aggregates of the finer's and its blocks their Galerkin sums (a piecewise-constant
prolongation). The preconditioner is a V-cycle of damped block-Jacobi smoothing. Every sum is a gather over
lists the host made (no atomics but the dot products')."""

import warp as wp


@wp.struct
class BlockLevel:
    """A level's matrix: its diagonal blocks and their inverses, its edges' blocks (the block of the edge's
    first node's row and second node's column; the other is its transpose), and each node's incident edges."""
    diagonal: wp.array(dtype=wp.mat33)
    inverse: wp.array(dtype=wp.mat33)
    edge_block: wp.array(dtype=wp.mat33)
    incident_start: wp.array(dtype=int)  # (nodes + 1,) node i's incident edges are start[i] .. start[i + 1] - 1
    incident_edge: wp.array(dtype=int)
    incident_node: wp.array(dtype=int)  # the edge's other node
    incident_first: wp.array(dtype=int)  # 1: the node is the edge's first (its block as stored), 0: the transpose
    free: wp.array(dtype=int)  # 0: a node nothing moves (a pinned particle)


@wp.struct
class Aggregation:
    """How a coarse level's blocks are summed from the finer level's, per coarse node and per coarse edge."""
    member_start: wp.array(dtype=int)  # a coarse node's fine nodes
    member: wp.array(dtype=int)
    inner_start: wp.array(dtype=int)  # the fine edges within a coarse node
    inner: wp.array(dtype=int)
    source_start: wp.array(dtype=int)  # the fine edges of a coarse edge
    source: wp.array(dtype=int)
    source_flip: wp.array(dtype=int)  # 1: the fine edge runs the other way (its transpose)
    aggregate: wp.array(dtype=int)  # each fine node's coarse node


@wp.kernel
def spring_blocks(x: wp.array(dtype=wp.vec3), first: wp.array(dtype=int), second: wp.array(dtype=int),
                  min_length: wp.array(dtype=float), max_length: wp.array(dtype=float),
                  inv_mass: wp.array(dtype=float), stiffness: float,
                  normal: wp.array(dtype=wp.vec3), excess: wp.array(dtype=float),
                  edge_block: wp.array(dtype=wp.mat33)):
    """Spring e's direction, how far it is past its range (its C), and its off-diagonal block -k n n^T
    (0 where either end is pinned: a pinned particle's row is left out)."""
    e = wp.tid()
    a = first[e]
    b = second[e]
    d = x[b] - x[a]
    length = wp.length(d)
    n = wp.vec3(0.0)
    if length > 1.0e-12:
        n = d / length
    normal[e] = n
    excess[e] = length - wp.clamp(length, min_length[e], max_length[e])
    block = wp.mat33(0.0)
    if inv_mass[a] > 0.0 and inv_mass[b] > 0.0:
        block = -stiffness * wp.outer(n, n)
    edge_block[e] = block


@wp.kernel
def particle_rows(level: BlockLevel, normal: wp.array(dtype=wp.vec3), excess: wp.array(dtype=float),
                  inv_mass: wp.array(dtype=float), stiffness: float, right: wp.array(dtype=wp.vec3)):
    """Particle i's diagonal block m I + k sum n n^T over its springs and its right side -k (J^T C)_i (a pinned
    particle: the identity and 0)."""
    i = wp.tid()
    w = inv_mass[i]
    if w == 0.0:
        level.diagonal[i] = wp.identity(n=3, dtype=float)
        right[i] = wp.vec3(0.0)
        return
    block = wp.identity(n=3, dtype=float) / w
    side = wp.vec3(0.0)
    for k in range(level.incident_start[i], level.incident_start[i + 1]):
        e = level.incident_edge[k]
        n = normal[e]
        block = block + stiffness * wp.outer(n, n)
        if level.incident_first[k] == 1:
            side = side + stiffness * excess[e] * n  # too long pulls the first end toward the second
        else:
            side = side - stiffness * excess[e] * n
    level.diagonal[i] = block
    right[i] = side


@wp.kernel
def coarse_diagonal(fine: BlockLevel, aggregation: Aggregation, coarse: BlockLevel):
    """A coarse node's diagonal block: its free fine nodes' diagonal blocks and both blocks of each fine edge
    within it."""
    c = wp.tid()
    block = wp.mat33(0.0)
    for k in range(aggregation.member_start[c], aggregation.member_start[c + 1]):
        i = aggregation.member[k]
        if fine.free[i] != 0:
            block = block + fine.diagonal[i]
    for k in range(aggregation.inner_start[c], aggregation.inner_start[c + 1]):
        e = fine.edge_block[aggregation.inner[k]]
        block = block + e + wp.transpose(e)
    coarse.diagonal[c] = block


@wp.kernel
def coarse_edges(fine: BlockLevel, aggregation: Aggregation, coarse: BlockLevel):
    """A coarse edge's block: the sum of its fine edges' blocks, each turned to the coarse edge's way."""
    c = wp.tid()
    block = wp.mat33(0.0)
    for k in range(aggregation.source_start[c], aggregation.source_start[c + 1]):
        e = fine.edge_block[aggregation.source[k]]
        if aggregation.source_flip[k] == 1:
            e = wp.transpose(e)
        block = block + e
    coarse.edge_block[c] = block


@wp.kernel
def invert_diagonal(level: BlockLevel):
    """Each free node's inverse diagonal block (0 for a pinned node, or a block nothing couples)."""
    i = wp.tid()
    block = level.diagonal[i]
    scale = wp.trace(block) / 3.0
    inverse = wp.mat33(0.0)
    if level.free[i] != 0 and scale > 0.0:
        if wp.abs(wp.determinant(block)) > 1.0e-9 * scale * scale * scale:
            inverse = wp.inverse(block)
    level.inverse[i] = inverse


@wp.func
def times_matrix(level: BlockLevel, x: wp.array(dtype=wp.vec3), i: int):
    """Row i of the level's matrix times x."""
    y = level.diagonal[i] * x[i]
    for k in range(level.incident_start[i], level.incident_start[i + 1]):
        block = level.edge_block[level.incident_edge[k]]
        if level.incident_first[k] == 0:
            block = wp.transpose(block)
        y = y + block * x[level.incident_node[k]]
    return y


@wp.kernel
def multiply(level: BlockLevel, x: wp.array(dtype=wp.vec3), y: wp.array(dtype=wp.vec3)):
    """y = A x on the free nodes (0 on the others)."""
    i = wp.tid()
    out = wp.vec3(0.0)
    if level.free[i] != 0:
        out = times_matrix(level, x, i)
    y[i] = out


@wp.kernel
def smooth_from_zero(level: BlockLevel, right: wp.array(dtype=wp.vec3), weight: float, x: wp.array(dtype=wp.vec3)):
    """A damped block-Jacobi step from x = 0."""
    i = wp.tid()
    x[i] = weight * (level.inverse[i] * right[i])


@wp.kernel
def smooth(level: BlockLevel, right: wp.array(dtype=wp.vec3), x: wp.array(dtype=wp.vec3), weight: float,
           smoothed: wp.array(dtype=wp.vec3)):
    """A damped block-Jacobi step from x, into ``smoothed``."""
    i = wp.tid()
    out = x[i]
    if level.free[i] != 0:
        out = out + weight * (level.inverse[i] * (right[i] - times_matrix(level, x, i)))
    smoothed[i] = out


@wp.kernel
def residual(level: BlockLevel, right: wp.array(dtype=wp.vec3), x: wp.array(dtype=wp.vec3),
             out: wp.array(dtype=wp.vec3)):
    """r - A x on the free nodes (0 on the others)."""
    i = wp.tid()
    value = wp.vec3(0.0)
    if level.free[i] != 0:
        value = right[i] - times_matrix(level, x, i)
    out[i] = value


@wp.kernel
def restrict(aggregation: Aggregation, fine: wp.array(dtype=wp.vec3), coarse: wp.array(dtype=wp.vec3)):
    """A coarse node's value: the sum of its fine nodes'."""
    c = wp.tid()
    total = wp.vec3(0.0)
    for k in range(aggregation.member_start[c], aggregation.member_start[c + 1]):
        total = total + fine[aggregation.member[k]]
    coarse[c] = total


@wp.kernel
def prolong(fine: BlockLevel, aggregation: Aggregation, coarse_x: wp.array(dtype=wp.vec3),
            x: wp.array(dtype=wp.vec3)):
    """The coarse correction added to each free fine node of its aggregate."""
    i = wp.tid()
    if fine.free[i] != 0:
        x[i] = x[i] + coarse_x[aggregation.aggregate[i]]


@wp.kernel
def dot(a: wp.array(dtype=wp.vec3), b: wp.array(dtype=wp.vec3), count: int, threads: int,
        out: wp.array(dtype=wp.float64), slot: int):
    """out[slot] += a . b, each thread summing every ``threads``-th element (out[slot] zeroed before)."""
    t = wp.tid()
    total = wp.float64(0.0)
    for i in range(t, count, threads):
        total = total + wp.float64(wp.dot(a[i], b[i]))
    wp.atomic_add(out, slot, total)


# The conjugate gradients' scalars, in one float64 array: r.z, p.Ap, and the next r.z
RZ = wp.constant(0)
P_AP = wp.constant(1)
RZ_NEXT = wp.constant(2)


@wp.kernel
def start_directions(z: wp.array(dtype=wp.vec3), x: wp.array(dtype=wp.vec3), p: wp.array(dtype=wp.vec3)):
    """x = 0 and p = z at the start."""
    i = wp.tid()
    x[i] = wp.vec3(0.0)
    p[i] = z[i]


@wp.kernel
def step_solution(scalars: wp.array(dtype=wp.float64), p: wp.array(dtype=wp.vec3), a_p: wp.array(dtype=wp.vec3),
                  x: wp.array(dtype=wp.vec3), r: wp.array(dtype=wp.vec3)):
    """x += alpha p, r -= alpha A p, alpha = r.z / p.Ap (no step where p.Ap is not positive)."""
    i = wp.tid()
    alpha = wp.float64(0.0)
    if scalars[P_AP] > wp.float64(0.0):
        alpha = scalars[RZ] / scalars[P_AP]
    step = float(alpha)
    x[i] = x[i] + step * p[i]
    r[i] = r[i] - step * a_p[i]


@wp.kernel
def step_direction(scalars: wp.array(dtype=wp.float64), z: wp.array(dtype=wp.vec3), p: wp.array(dtype=wp.vec3)):
    """p = z + beta p, beta = the next r.z over r.z."""
    i = wp.tid()
    beta = wp.float64(0.0)
    if scalars[RZ] > wp.float64(0.0):
        beta = scalars[RZ_NEXT] / scalars[RZ]
    p[i] = z[i] + float(beta) * p[i]


@wp.kernel
def next_scalars(scalars: wp.array(dtype=wp.float64)):
    """The next iteration's r.z; its sums zeroed."""
    scalars[RZ] = scalars[RZ_NEXT]
    scalars[P_AP] = wp.float64(0.0)
    scalars[RZ_NEXT] = wp.float64(0.0)


@wp.kernel
def move_particles(dx: wp.array(dtype=wp.vec3), inv_mass: wp.array(dtype=float), h: float,
                   x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3)):
    """The free particles moved by dx, their velocities by dx over h."""
    i = wp.tid()
    if inv_mass[i] > 0.0:
        x[i] = x[i] + dx[i]
        v[i] = v[i] + dx[i] / h
