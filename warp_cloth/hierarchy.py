"""Coarser and coarser graphs of a cloth's strain limits, for the multilevel limit solve
(warp_cloth/limit_solve.py, docs/strain-solve.md).

A Jacobi pass moves a correction one spring across the cloth, so local passes need as many of them as the
cloth has rows before a pin or a collider holds its far side. Each level here is a subset of the finer
one's nodes (a maximal independent set of its graph, pinned nodes first), joined by limits along paths of
two or three of the finer level's limits (the shortest such path between them), so that every coarse
limit stands for a path of the cloth's springs. The solve reads how long each path is now, and where it
is longer (or shorter) than its springs allow, asks the straight distance between the path's ends to
shrink (or grow) in the same proportion; the finer level's nodes follow their parents (their coarse neighbours, weighted by
closeness) before their own passes. A correction then crosses a level of m nodes in about sqrt(m) passes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .adjacency import Adjacency

COARSEST_NODES = 64  # stop coarsening below this many nodes
LEAST_REDUCTION = 0.85  # or when a level keeps more than this fraction of the one below


@dataclass(frozen=True)
class Csr:
    offsets: np.ndarray  # (rows + 1,) int32
    index: np.ndarray  # int32, row r's entries at offsets[r]:offsets[r + 1]
    value: np.ndarray  # one per entry


@dataclass(frozen=True)
class Hierarchy:
    """Levels 1..K (coarsest last), their nodes concatenated: level k's are ``first[k-1]:first[k]``; and
    the limits of levels 0 (the springs') to K concatenated: level k's are ``edge_first[k]:edge_first[k+1]``."""

    first: tuple[int, ...]  # (K + 1,) where each level's nodes start (0 first), and the end
    particle: np.ndarray  # (nodes,) the particle each node is
    inv_mass: np.ndarray  # (nodes,) the inverse of its aggregate's mass, 0 where the particle is pinned
    edge_first: tuple[int, ...]  # (K + 2,) where each level's limits start, and the end
    edge_ends: np.ndarray  # (edges, 2) int32: particles at level 0, nodes (concatenated index) above
    edge_longest: np.ndarray  # (edges,) float32: the most the path's springs allow
    edge_shortest: np.ndarray  # (edges,) float32: the least they allow
    edge_path: np.ndarray  # (edges, 3) int32: the finer level's limits the path is made of (-1: none)
    limits: Csr  # per node its coarse limits: the other node, and (value) the limit's index
    parents: Csr  # per node of levels 1..K-1 its parents in the next coarser level, with their weights
    particle_parents: Csr  # per particle its parents in level 1

    @property
    def levels(self) -> int:
        return len(self.first) - 1

    def level_size(self, k: int) -> int:
        return self.first[k] - self.first[k - 1]


def build_hierarchy(pairs: np.ndarray, shortest: np.ndarray, longest: np.ndarray, masses: np.ndarray,
                    inv_mass: np.ndarray, lattice: np.ndarray | None = None) -> Hierarchy | None:
    """The levels above the graph of ``pairs`` (particle index pairs) whose lengths are limited to
    ``shortest``..``longest``; None where the graph is too small to coarsen. ``lattice`` (per particle, optional): the
    level a particle of a grid belongs to (how many times its row and column can both be halved); the sets
    then prefer it, so that a grid's levels are every 2nd, 4th, ... row and column and its coarse limits
    run straight along rows, columns and diagonals."""
    n = len(masses)
    preference = np.zeros(n) if lattice is None else lattice.astype(np.float64)
    nodes, mass, pinned = np.arange(n), masses.astype(np.float64), inv_mass == 0.0
    order = np.argsort(longest, kind="stable")  # where a pair repeats, the shortest longest length wins
    pairs, shortest, longest = pairs[order], shortest[order], longest[order]
    edges, lengths, paths = _undirected(pairs, longest.astype(np.float64), np.full((len(pairs), 3), -1))
    least = _undirected(pairs, longest.astype(np.float64), shortest.astype(np.float64)[:, None])[2][:, 0]
    all_edges, all_lengths, all_paths, edge_first = [edges], [lengths], [paths], [0, len(edges)]
    all_least = [least]
    levels, parent_maps = [], []
    while len(nodes) > COARSEST_NODES and len(edges):
        coarse, parents, coarse_neighbours, aggregate, reach = _coarsen(len(nodes), edges, lengths, pinned,
                                                                        preference[nodes])
        if len(coarse) > LEAST_REDUCTION * len(nodes):
            break
        edges, lengths, paths = _coarse_limits(edges, lengths, coarse_neighbours, aggregate, reach, coarse,
                                               len(nodes), edge_first[-2])
        mass = np.bincount(aggregate, weights=mass, minlength=len(nodes))[coarse]
        pinned = pinned[coarse]
        nodes = nodes[coarse]
        levels.append((nodes, mass, pinned, edges))
        parent_maps.append(parents)
        all_edges.append(edges)
        all_lengths.append(lengths)
        all_paths.append(paths)
        every_least = np.concatenate(all_least)
        all_least.append(np.where(paths >= 0, every_least[np.maximum(paths, 0)], 0.0).sum(axis=1))
        edge_first.append(edge_first[-1] + len(edges))
    if not levels:
        return None
    first = np.concatenate([[0], np.cumsum([len(level[0]) for level in levels])])
    limits = [_csr(len(level[0]), level[3], np.arange(len(level[3])) + edge_first[k + 1], shift=first[k])
              for k, level in enumerate(levels)]
    parents = [_shift(parent_maps[k], first[k]) for k in range(1, len(levels))]
    ends = [all_edges[0]] + [all_edges[k] + first[k - 1] for k in range(1, len(all_edges))]
    return Hierarchy(
        first=tuple(int(f) for f in first),
        particle=np.concatenate([level[0] for level in levels]).astype(np.int32),
        inv_mass=np.concatenate([np.where(level[2], 0.0, 1.0 / level[1]) for level in levels]).astype(np.float32),
        edge_first=tuple(int(f) for f in edge_first),
        edge_ends=np.concatenate(ends).astype(np.int32),
        edge_longest=np.concatenate(all_lengths).astype(np.float32),
        edge_shortest=np.concatenate(all_least).astype(np.float32),
        edge_path=np.concatenate(all_paths).astype(np.int32),
        limits=_concatenate(limits),
        parents=_concatenate(parents) if parents else Csr(np.zeros(1, np.int32), np.zeros(0, np.int32),
                                                          np.zeros(0, np.float32)),
        particle_parents=parent_maps[0])


def _undirected(pairs: np.ndarray, lengths: np.ndarray, paths: np.ndarray):
    """Each pair once (i < j), with the shortest of its lengths and that one's path."""
    lo, hi = np.minimum(pairs[:, 0], pairs[:, 1]), np.maximum(pairs[:, 0], pairs[:, 1])
    keep = lo != hi
    pairs, lengths, paths = np.stack([lo[keep], hi[keep]], axis=1), lengths[keep], paths[keep]
    if not len(pairs):
        return pairs.reshape(0, 2).astype(np.int64), lengths, paths
    order = np.lexsort((lengths, pairs[:, 1], pairs[:, 0]))
    pairs, lengths, paths = pairs[order], lengths[order], paths[order]
    first = np.ones(len(pairs), dtype=bool)
    first[1:] = np.any(pairs[1:] != pairs[:-1], axis=1)
    return pairs[first].astype(np.int64), lengths[first], paths[first]


def _coarsen(n: int, edges: np.ndarray, lengths: np.ndarray, pinned: np.ndarray, preference: np.ndarray):
    """A maximal independent set of the graph (Luby's rounds: pinned nodes first, then by ``preference``,
    then in a fixed pseudo-random order, so that the build is deterministic), each other node's parents (its
    neighbours in the set, weighted by inverse length) and its aggregate (the nearest of them) with the
    distance to it and the limit that spans it (-1 for a node of the set)."""
    priority = (_scramble(np.arange(n)).astype(np.float64) + 2.0 ** 33 * preference
                + np.where(pinned, 2.0 ** 45, 0.0))
    both = np.concatenate([edges, edges[:, ::-1]])
    both_lengths = np.concatenate([lengths, lengths])
    both_ids = np.concatenate([np.arange(len(edges)), np.arange(len(edges))])
    state = np.zeros(n, dtype=np.int8)  # 0 undecided, 1 in the set, -1 next to it
    while (state == 0).any():
        undecided = state == 0
        live = undecided[both[:, 0]] & undecided[both[:, 1]]
        best_neighbour = np.full(n, -np.inf)
        np.maximum.at(best_neighbour, both[live, 0], priority[both[live, 1]])
        chosen = undecided & (priority > best_neighbour)
        state[chosen] = 1
        covered = np.zeros(n, dtype=bool)
        covered[both[chosen[both[:, 0]], 1]] = True
        state[covered & (state == 0)] = -1
    coarse = np.nonzero(state == 1)[0]
    coarse_index = np.full(n, -1, dtype=np.int64)
    coarse_index[coarse] = np.arange(len(coarse))
    # parents: a coarse node is its own; another node's are its coarse neighbours
    to_coarse = (state[both[:, 0]] == -1) & (state[both[:, 1]] == 1)
    child, parent, length = both[to_coarse, 0], both[to_coarse, 1], both_lengths[to_coarse]
    edge_id = both_ids[to_coarse]
    by_child = np.argsort(child, kind="stable")
    coarse_neighbours = (child[by_child], parent[by_child], length[by_child], edge_id[by_child])
    child = np.concatenate([child, coarse])
    parent = np.concatenate([parent, coarse])
    length = np.concatenate([length, np.zeros(len(coarse))])
    edge_id = np.concatenate([edge_id, np.full(len(coarse), -1)])
    order = np.lexsort((length, child))
    child, parent, length, edge_id = child[order], parent[order], length[order], edge_id[order]
    nearest = np.ones(len(child), dtype=bool)
    nearest[1:] = child[1:] != child[:-1]
    aggregate, reach = np.empty(n, dtype=np.int64), (np.empty(n), np.empty(n, dtype=np.int64))
    aggregate[child[nearest]] = parent[nearest]
    reach[0][child[nearest]], reach[1][child[nearest]] = length[nearest], edge_id[nearest]
    closeness = np.ones(len(length))
    np.divide(1.0, length, out=closeness, where=length > 0.0)
    total = np.bincount(child, weights=closeness, minlength=n)
    weight = closeness / total[child]
    offsets = np.zeros(n + 1, dtype=np.int32)
    np.cumsum(np.bincount(child, minlength=n), out=offsets[1:])
    parents = Csr(offsets, coarse_index[parent].astype(np.int32), weight.astype(np.float32))
    return coarse, parents, coarse_neighbours, aggregate, reach


def _coarse_limits(edges: np.ndarray, lengths: np.ndarray, coarse_neighbours: tuple, aggregate: np.ndarray,
                   reach: tuple, coarse: np.ndarray, n: int, first_edge: int):
    """Limits between coarse nodes two steps apart (through a common neighbour) or whose aggregates touch
    (three steps, through each one's aggregate), each as long as the shortest such path, in coarse
    indices, with the finer level's limits along it (as indices of the concatenation from ``first_edge``)."""
    child, parent, length, edge_id = coarse_neighbours  # sorted by child
    rank = np.arange(len(child)) - np.searchsorted(child, child, side="left")  # among the child's entries
    count = np.bincount(child, minlength=n)[child]
    ends_a, ends_b, path_lengths, paths = [], [], [], []
    for k in range(1, count.max(initial=0)):  # each entry with the one k places after it, same child
        i = np.nonzero(rank + k < count)[0]
        j = i + k
        ends_a.append(parent[i])
        ends_b.append(parent[j])
        path_lengths.append(length[i] + length[j])
        paths.append(np.stack([edge_id[i], edge_id[j], np.full(len(i), -1)], axis=1))
    reach_length, reach_edge = reach
    a, b = aggregate[edges[:, 0]], aggregate[edges[:, 1]]
    across = np.nonzero(a != b)[0]
    x, y = edges[across, 0], edges[across, 1]
    ends_a.append(a[across])
    ends_b.append(b[across])
    path_lengths.append(reach_length[x] + lengths[across] + reach_length[y])
    paths.append(np.stack([reach_edge[x], across, reach_edge[y]], axis=1))
    coarse_index = np.full(n, -1, dtype=np.int64)
    coarse_index[coarse] = np.arange(len(coarse))
    pairs = np.stack([coarse_index[np.concatenate(ends_a)], coarse_index[np.concatenate(ends_b)]], axis=1)
    path = np.concatenate(paths)
    path = np.where(path >= 0, path + first_edge, -1)
    return _undirected(pairs, np.concatenate(path_lengths), path)


def _scramble(i: np.ndarray) -> np.ndarray:
    """A fixed bijection of 0..2^32-1 (so that neighbours' priorities are unrelated)."""
    x = i.astype(np.uint64) & np.uint64(0xFFFFFFFF)
    with np.errstate(over="ignore"):
        x = (x * np.uint64(0x9E3779B1)) & np.uint64(0xFFFFFFFF)
        x ^= x >> np.uint64(15)
        x = (x * np.uint64(0x85EBCA77)) & np.uint64(0xFFFFFFFF)
        x ^= x >> np.uint64(13)
    return x


def _csr(rows: int, pairs: np.ndarray, values: np.ndarray, shift: int) -> Csr:
    """Both directions of each pair as rows' entries (with the pair's value), indices shifted by ``shift``."""
    adjacency = Adjacency.of(pairs, rows)
    return Csr(adjacency.offsets, (adjacency.other + shift).astype(np.int32), values[adjacency.spring])


def _shift(csr: Csr, shift: int) -> Csr:
    return Csr(csr.offsets, (csr.index + shift).astype(np.int32), csr.value)


def _concatenate(parts: list[Csr]) -> Csr:
    starts = np.cumsum([0] + [p.offsets[-1] for p in parts[:-1]])
    offsets = np.concatenate([[0]] + [p.offsets[1:] + s for p, s in zip(parts, starts)]).astype(np.int32)
    return Csr(offsets, np.concatenate([p.index for p in parts]), np.concatenate([p.value for p in parts]))
