"""How far the surface contacts' candidate lists reach (face and edge pairs, with a surface thickness): each
particle's allowance, how far it may move from where the lists were made before a pair they leave out could
come within the thickness.

The lists are made where a substep started, after the query radius r was chosen (displacement_bounds.py):
every iterate of the solve and the step's end keep a free particle within its bound
of the start, at most gamma r, and a pinned one goes where its pass put it. A particle's allowance at the
remake is its reach this substep (gamma r, or a pin's move), and a pair is listed where it lies within the
thickness plus both sides' allowances (a triangle's or an edge's the largest of its vertices'). A later
substep may keep the lists while every particle's move from where they were made plus its reach then stays
within its allowance: a pair left out then lies farther apart than the thickness plus both reaches where the
substep starts, so stays farther apart than the thickness in every iterate, and needs no bound of its own
(the bounds are read off the lists, listed_distances.py). (Lists made where the step predicted, with a skin
alone, left out pairs that the solve then carried 3 to 16 mm: docs/notebook/layers.md.)

The allowances hold no skin beyond the reach, so the lists are remade in every substep in which a particle
moves: a skin (the particle lists' rebuild distance, 2.1 mm at a 4 mm radius) kept them a substep or two on
the stacked drape at the price of longer lists and wider cells, and its 100 frames took 92.0 s on an H200
against 51.7 s without (docs/notebook/layers.md, "The bounds read off the lists, and no skin")."""

import warp as wp


@wp.func
def reach_of(i: int, start: wp.array(dtype=wp.vec3), x: wp.array(dtype=wp.vec3), query: wp.array(dtype=float),
             gamma: float, inv_mass: wp.array(dtype=float)) -> float:
    """How far particle i may get from ``start`` this substep: the largest bound, gamma times the query radius
    (``query[0]``), or, pinned, its move to ``x``."""
    if inv_mass[i] == 0.0:
        return wp.length(x[i] - start[i])
    return gamma * query[0]


@wp.kernel
def ask_if_beyond_allowance(start: wp.array(dtype=wp.vec3), x: wp.array(dtype=wp.vec3),
                            query: wp.array(dtype=float), gamma: float, inv_mass: wp.array(dtype=float),
                            built: wp.array(dtype=wp.vec3), allowance: wp.array(dtype=float),
                            rebuild: wp.array(dtype=int)):
    """Asks for a remake (``rebuild[0]``) where a particle's move since the lists were made (``built``) plus
    its reach this substep passes its allowance."""
    i = wp.tid()
    if rebuild[0] != 0:
        return
    if wp.length(start[i] - built[i]) + reach_of(i, start, x, query, gamma, inv_mass) > allowance[i]:
        rebuild[0] = 1


@wp.kernel
def start_allowances(rebuild: wp.array(dtype=int), widest: wp.array(dtype=float)):
    """Where ``rebuild`` is set (one thread): the largest allowance reset, before ``allow``."""
    if rebuild[0] != 0:
        widest[0] = 0.0


@wp.kernel
def allow(start: wp.array(dtype=wp.vec3), x: wp.array(dtype=wp.vec3), query: wp.array(dtype=float), gamma: float,
          inv_mass: wp.array(dtype=float), rebuild: wp.array(dtype=int), built: wp.array(dtype=wp.vec3),
          allowance: wp.array(dtype=float), widest: wp.array(dtype=float)):
    """Where ``rebuild`` is set: each particle's allowance (its reach) and where the lists are made
    (``start``), and the largest allowance (``widest[0]``), which the hashes' cells widen for."""
    if rebuild[0] == 0:
        return
    i = wp.tid()
    built[i] = start[i]
    a = reach_of(i, start, x, query, gamma, inv_mass)
    allowance[i] = a
    wp.atomic_max(widest, 0, a)


@wp.func
def triangle_allowance(allowance: wp.array(dtype=float), t: wp.vec3i) -> float:
    return wp.max(wp.max(allowance[t[0]], allowance[t[1]]), allowance[t[2]])


@wp.func
def edge_allowance(allowance: wp.array(dtype=float), ends: wp.vec2i) -> float:
    return wp.max(allowance[ends[0]], allowance[ends[1]])
