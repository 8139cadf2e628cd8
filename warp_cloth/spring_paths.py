"""Shortest paths along a cloth's edges from a set of its particles (its pins): how far across the cloth at
rest each particle is from the nearest of them, for long-range attachments on any mesh.

A path of edges is at least as long as the shortest way across the surface, so a limit of (1 + stretch)
times it is implied by the edges' own limits and never asks for what the cloth cannot give.
"""

from __future__ import annotations

import numpy as np


def nearest_along_edges(n: int, pairs: np.ndarray, lengths: np.ndarray,
                        sources: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each of ``n`` particles, the source at the end of its shortest path along the edges ``pairs``
    (of ``lengths``), and that path's length (-1 and inf where no path leads to a source).

    Dijkstra's order, settled a band at a time: every particle within the shortest edge of the nearest
    unsettled one is final (no path through another unsettled particle can be shorter), so each band is
    settled by one vectorised relaxation of its edges, and a grid of k rows takes about k bands."""
    both = np.concatenate([pairs, pairs[:, ::-1]]).astype(np.int64)
    weights = np.concatenate([lengths, lengths]).astype(np.float64)
    order = np.argsort(both[:, 0], kind="stable")
    neighbour, weights = both[order, 1], weights[order]
    start = np.searchsorted(both[order, 0], np.arange(n + 1))
    shortest = float(weights.min()) if len(weights) else np.inf
    distance = np.full(n, np.inf)
    nearest = np.full(n, -1, dtype=np.int64)
    sources = np.unique(np.asarray(sources, dtype=np.int64))
    distance[sources], nearest[sources] = 0.0, sources
    settled = np.zeros(n, dtype=bool)
    reached = sources
    while reached.size:
        band = reached[distance[reached] < distance[reached].min() + shortest]
        settled[band] = True
        counts = start[band + 1] - start[band]
        edge = np.repeat(start[band] - np.cumsum(counts) + counts, counts) + np.arange(counts.sum())
        near, far = np.repeat(band, counts), neighbour[edge]
        through = distance[near] + weights[edge]
        better = ~settled[far] & (through < distance[far])
        near, far, through = near[better], far[better], through[better]
        first = np.lexsort((through, far))  # each far particle's shortest offer first
        keep = first[np.diff(far[first], prepend=-1) != 0]
        distance[far[keep]], nearest[far[keep]] = through[keep], nearest[near[keep]]
        reached = np.unique(np.concatenate([reached[~settled[reached]], far[keep]]))
    return nearest, distance
