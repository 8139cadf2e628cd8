"""The lines of a scene's cloths for the line solve (issue 33; line_solve.py): chains of limited springs
cut at pins, grouped into families whose lines share no free particle, so that one launch solves a family.

A grid cloth's families are its rows, columns and the two diagonal families of its shear springs, found from
its layout. A cloth from a mesh has no layout to read: its limited springs (structural and shear) are joined
into chains at each vertex, the incident springs that continue each other most nearly paired first, and the
chains' pieces between pins coloured greedily so that the pieces of one colour share no free particle. On a
mesh made from a grid the chains are the grid's lines again (rows, columns, and one diagonal family a
triangulated quad or two a quad)."""

from __future__ import annotations

import numpy as np

from .mesh_io import pair_keys
from .model import Model
from .scene import Scene

# Two springs at a vertex continue each other when the angle between them at rest is at least 120 degrees:
# a grid's straight lines, not the turn from a boundary's column into its diagonal.
CONTINUING_COSINE = -0.5

# A family: its lines' starts, their particles, and each slot's allowed length range (the spring from that
# particle to the next; 0 at a line's last particle).
Family = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def grid_chains(nx: int, ny: int) -> dict[str, list[np.ndarray]]:
    """The particle chains of a grid of nx x ny cells (particle (x, y) is x + (nx + 1) y) along its
    structural springs (rows, columns) and its shear springs ((x, y)-(x+1, y+1) and (x+1, y)-(x, y+1))."""
    idx = lambda x, y: x + (nx + 1) * y  # noqa: E731
    rows = [idx(np.arange(nx + 1), y) for y in range(ny + 1)]
    columns = [idx(x, np.arange(ny + 1)) for x in range(nx + 1)]
    diagonals, antidiagonals = [], []
    for x0, y0 in [(x, 0) for x in range(nx)] + [(0, y) for y in range(1, ny)]:
        t = np.arange(min(nx - x0, ny - y0) + 1)
        diagonals.append(idx(x0 + t, y0 + t))
    for s in range(1, nx + ny):
        x0, y0 = min(s, nx), s - min(s, nx)
        t = np.arange(min(x0, ny - y0) + 1)
        antidiagonals.append(idx(x0 - t, y0 + t))
    return dict(rows=rows, columns=columns, diagonals=diagonals, antidiagonals=antidiagonals)


def mesh_chains(pairs: np.ndarray, points: np.ndarray) -> list[np.ndarray]:
    """Chains of particles covering every spring of ``pairs`` (s, 2) once: at each vertex its springs paired
    greedily, the most nearly opposite at rest (``points``) first, while they continue each other
    (CONTINUING_COSINE); a chain runs through paired springs and ends at an unpaired one. A closed chain is
    opened at one of its vertices, which is then its first particle and its last."""
    ends = pairs.ravel()  # half h: spring h // 2 at its end h % 2
    direction = points[pairs[:, 1]] - points[pairs[:, 0]]
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    outward = np.stack([direction, -direction], axis=1).reshape(-1, 3)  # from the half's vertex along its spring
    link = np.full(len(ends), -1, dtype=np.int64)
    order = np.argsort(ends, kind="stable")
    bounds = np.searchsorted(ends[order], np.arange(len(points) + 1))
    degree = np.diff(bounds)
    for d in np.unique(degree[degree >= 2]).tolist():  # the vertices of each degree together
        at = bounds[:-1][degree == d]
        halves = order[at[:, None] + np.arange(d)]  # (vertices, d)
        cosines = np.einsum("vik,vjk->vij", outward[halves], outward[halves])
        i, j = np.triu_indices(d, 1)
        pair_cosines = cosines[:, i, j]
        rows = np.arange(len(at))
        for k in np.argsort(pair_cosines, axis=1, kind="stable").T:  # each vertex's k-th most opposite pair
            a, b = halves[rows, i[k]], halves[rows, j[k]]
            joined = (pair_cosines[rows, k] < CONTINUING_COSINE) & (link[a] < 0) & (link[b] < 0)
            link[a[joined]], link[b[joined]] = b[joined], a[joined]
    done = np.zeros(len(pairs), dtype=bool)
    chains = []
    # open chains from their unpaired ends, then what is left, the closed ones
    for start in list(np.nonzero(link < 0)[0]) + list(range(0, len(ends), 2)):
        if done[start // 2]:
            continue
        chain, half = [ends[start]], start
        while True:
            done[half // 2] = True
            far = half ^ 1
            chain.append(ends[far])
            half = link[far]
            if half < 0 or done[half // 2]:
                break
        chains.append(np.asarray(chain, dtype=np.int64))
    return chains


def chain_lines(chains: list[np.ndarray], free: np.ndarray, keys: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """The lines of ``chains`` (particle indices), all at once: each chain cut at its pinned particles (a cut
    particle ends one piece and starts the next) and at its springs that are not limited (not among ``keys``,
    the limited springs' sorted pair keys), the pieces with no free particle left out; per line its particles
    and its springs' indices into ``keys``."""
    lengths = np.array([len(chain) for chain in chains], dtype=np.int64)
    particles = np.concatenate(chains)
    first = np.cumsum(lengths) - lengths  # each chain's first particle in ``particles``
    end = first + lengths
    inner = np.ones(len(particles), dtype=bool)  # a spring from particle g to g + 1 of the same chain
    inner[end - 1] = False
    after = np.flatnonzero(inner)
    wanted = pair_keys(np.stack([particles[after], particles[after + 1]], axis=1), len(free))
    at = np.zeros(len(particles), dtype=np.int64)
    at[after] = np.minimum(np.searchsorted(keys, wanted), len(keys) - 1)
    limited = np.zeros(len(particles), dtype=bool)
    limited[after] = keys[at[after]] == wanted
    within = np.ones(len(particles), dtype=bool)  # every particle but a chain's first can cut
    within[first] = False
    cut_unlimited = np.flatnonzero(within & ~np.roll(limited, 1))  # the spring before it is not limited
    cut_pinned = np.flatnonzero(within & np.roll(limited, 1) & ~free[particles])
    cuts = np.concatenate([cut_unlimited, cut_pinned])
    stop_at_cut = np.concatenate([cut_unlimited, cut_pinned + 1])  # where the piece before a cut stops
    order = np.argsort(cuts)
    cuts, stop_at_cut = cuts[order], stop_at_cut[order]
    starts = np.concatenate([first, cuts])
    stops = np.concatenate([end, stop_at_cut])
    chain_of = np.repeat(np.arange(len(chains)), lengths)
    by_start = np.argsort(starts, kind="stable")
    starts = starts[by_start]
    # a piece stops at the next cut of its chain, or at its chain's end
    next_stop = np.append(stops[by_start][1:], 0)
    same_chain = np.append(chain_of[starts[1:]] == chain_of[starts[:-1]], False)
    piece_stop = np.where(same_chain, next_stop, end[chain_of[starts]])
    free_before = np.concatenate([[0], np.cumsum(free[particles])])
    kept = (piece_stop - starts >= 2) & (free_before[piece_stop] > free_before[starts])
    return [(particles[a:b], at[a:b - 1]) for a, b in zip(starts[kept].tolist(), piece_stop[kept].tolist())]


def colour_lines(lines: list[np.ndarray], free: np.ndarray) -> np.ndarray:
    """Per line, its colour: lines sharing a free particle differ, the longest coloured first, each the
    smallest colour none of its coloured neighbours has."""
    on = {}  # free particle -> the lines through it
    for l, line in enumerate(lines):
        for p in np.unique(line[free[line]]).tolist():
            on.setdefault(p, []).append(l)
    colour = np.full(len(lines), -1, dtype=np.int64)
    for l in sorted(range(len(lines)), key=lambda l: -len(lines[l])):
        taken = {colour[m] for p in np.unique(lines[l][free[lines[l]]]).tolist() for m in on[p]}
        colour[l] = next(c for c in range(len(lines) + 1) if c not in taken)
    return colour


def cloth_lines(model: Model, scene: Scene) -> list[Family]:
    """The scene's families of lines: a grid cloth's rows, columns, diagonals and antidiagonals, a mesh
    cloth's coloured chains; the cloths' k-th families solved as one (none where no cloth is limited)."""
    springs = model.springs
    n = model.particle_count
    limited = np.isfinite(springs.limit_max)
    pairs = np.sort(springs.pairs[limited], axis=1).astype(np.int64)
    keys = pair_keys(pairs, n)
    order = np.argsort(keys)
    keys, lo, hi = keys[order], springs.limit_min[limited][order], springs.limit_max[limited][order]
    free = model.inv_mass > 0

    families: list[list[tuple[np.ndarray, np.ndarray]]] = []  # per family its lines: particles, slots
    for c, cloth in enumerate(scene.cloths):
        if cloth.limit is None:  # its springs are not limited (a seam's may be: they are no line)
            continue
        offset = model.offsets[c]
        if cloth.mesh is None:
            grouped = [list(chains) for chains in grid_chains(*cloth.resolution).values()]
        else:
            inside = (pairs[:, 0] >= offset) & (pairs[:, 0] < model.offsets[c + 1])
            grouped = [mesh_chains(pairs[inside] - offset, model.cloths[c].positions)]
        for g, chains in enumerate(grouped):
            lines = chain_lines([chain + offset for chain in chains], free, keys)
            if cloth.mesh is None:
                colours = np.full(len(lines), g)
            else:
                colours = colour_lines([particles for particles, _ in lines], free)
            for line, f in zip(lines, colours.tolist()):
                families += [[] for _ in range(f + 1 - len(families))]
                families[f].append(line)
    out = []
    for lines in filter(None, families):
        starts = np.cumsum([0] + [len(particles) for particles, _ in lines])
        slot_lo = [np.append(lo[slots], 0.0) for _, slots in lines]
        slot_hi = [np.append(hi[slots], 0.0) for _, slots in lines]
        out.append((starts.astype(np.int32), np.concatenate([p for p, _ in lines]).astype(np.int32),
                    np.concatenate(slot_lo).astype(np.float32), np.concatenate(slot_hi).astype(np.float32)))
    return out
