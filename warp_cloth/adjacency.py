"""Incidence lists of a graph given as index pairs."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Adjacency:
    """Per-particle incidence lists (CSR): particle i's entries are ``offsets[i]:offsets[i+1]``."""

    offsets: np.ndarray  # (n + 1,) int32
    other: np.ndarray  # (2 s,) int32: the particle at the other end
    spring: np.ndarray  # (2 s,) int32: the spring's index

    @staticmethod
    def of(pairs: np.ndarray, particle_count: int) -> "Adjacency":
        s = len(pairs)
        owner = np.concatenate([pairs[:, 0], pairs[:, 1]])
        other = np.concatenate([pairs[:, 1], pairs[:, 0]])
        spring = np.concatenate([np.arange(s), np.arange(s)])
        order = np.argsort(owner.astype(np.int64) * particle_count + other, kind="stable")  # by owner, then other
        counts = np.bincount(owner, minlength=particle_count)
        offsets = np.zeros(particle_count + 1, dtype=np.int32)
        np.cumsum(counts, out=offsets[1:])
        return Adjacency(offsets, other[order].astype(np.int32), spring[order].astype(np.int32))
