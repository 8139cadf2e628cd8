"""Candidate lists of a fixed length (the particles', the contact edges', the face pairs'): an entry is appended
while its list has room; a full list keeps the nearer of it and its farthest entry, counting the other dropped
in ``overflow`` (spatial_hash.count_dropped), so that what a list leaves out is farther than all it holds and
a pair in contact is not left out for farther candidates found first (in the pile with the particle lists'
reach at 3 contact distances, lists filled in the order found left out touching pairs, which no pass then
separated and every solve ran to its cap). Each kind of list says how far an entry lies from the list's owner
(``gap_of``)."""

import functools
from typing import Any

import warp as wp

from .spatial_hash import count_dropped

wp.set_module_options({"fast_math": True})  # as the gathering kernels (see gathering.py)


@functools.cache
def keeping_nearest(gap_of: wp.Function) -> wp.Function:
    """The insert of lists whose entries lie ``gap_of(owner, entry)`` from their owner (any measure that
    grows with the distance): ``insert(listed, start, count, most, entry, gap, overflow, owner)`` puts
    ``entry``, ``gap`` from ``owner``, into the list of ``count`` from ``start`` that holds ``most`` (full, it
    keeps the nearest, and does not add an entry it holds already) and returns the list's new
    count."""

    @wp.func
    def insert_keeping_nearest(listed: wp.array(dtype=int), start: int, count: int, most: int, entry: int,
                               gap: float, overflow: wp.array(dtype=int), owner: Any) -> int:
        if count < most:
            listed[start + count] = entry
            return count + 1
        farthest = int(-1)
        farthest_gap = gap
        for k in range(count):
            held = listed[start + k]
            if held == entry:
                return count
            held_gap = gap_of(owner, held)
            if held_gap > farthest_gap:
                farthest, farthest_gap = k, held_gap
        count_dropped(overflow)  # the farthest entry, or the candidate itself
        if farthest >= 0:
            listed[start + farthest] = entry
        return count

    return insert_keeping_nearest
