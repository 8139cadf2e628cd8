"""Candidate lists of a fixed length (the particles', the contact edges', the face pairs'): an entry is appended
while its list has room; a full list keeps the nearer of it and its farthest entry, counting the other dropped
in ``overflow`` (spatial_hash.count_dropped), so that what a list leaves out is farther than all it holds and
a pair in contact is not left out for farther candidates found first (in the pile with the particle lists'
reach at 3 contact distances, lists filled in the order found left out touching pairs, which no pass then
separated and every solve ran to its cap). Each kind of list says how far an entry in a slot lies from the
list's owner (``gap_of``) and may keep the gap it was listed at (``remember``): the particles' lists work a
distance out again, which costs less than a slot's memory; the surface lists keep their pairs' gaps while
they are made, since working them out again cost a full list 32 segment or triangle distances a candidate
(the stacked drape's lists drop many: 27,600 a substep at 64^2, docs/notebook/layers.md)."""

import functools
from typing import Any

import warp as wp

from .spatial_hash import count_dropped

wp.set_module_options({"fast_math": True})  # as the gathering kernels (see gathering.py)


@functools.cache
def keeping_nearest(gap_of: wp.Function, remember: wp.Function) -> wp.Function:
    """The insert of lists whose entries lie ``gap_of(owner, slot, entry)`` from their owner (any measure that
    grows with the distance; ``slot`` the entry's place in the lists' array) and which keep an entry's gap
    with ``remember(owner, slot, gap)``: ``insert(listed, start, count, most, entry, gap, overflow, owner)``
    puts ``entry``, ``gap`` from ``owner``, into the list of ``count`` from ``start`` that holds ``most``
    (full, it keeps the nearest, and does not add an entry it holds already) and returns the list's new
    count."""

    @wp.func
    def insert_keeping_nearest(listed: wp.array(dtype=int), start: int, count: int, most: int, entry: int,
                               gap: float, overflow: wp.array(dtype=int), owner: Any) -> int:
        if count < most:
            listed[start + count] = entry
            remember(owner, start + count, gap)
            return count + 1
        farthest = int(-1)
        farthest_gap = gap
        for k in range(count):
            held = listed[start + k]
            if held == entry:
                return count
            held_gap = gap_of(owner, start + k, held)
            if held_gap > farthest_gap:
                farthest, farthest_gap = k, held_gap
        count_dropped(overflow)  # the farthest entry, or the candidate itself
        if farthest >= 0:
            listed[start + farthest] = entry
            remember(owner, start + farthest, gap)
        return count

    return insert_keeping_nearest


@wp.func
def stored_gap(gaps: wp.array(dtype=float), slot: int, entry: int) -> float:
    """A list's gap as ``remember_gap`` kept it (for lists whose gaps cost more to work out than to keep)."""
    return gaps[slot]


@wp.func
def remember_gap(gaps: wp.array(dtype=float), slot: int, gap: float):
    gaps[slot] = gap


insert_keeping_gaps = keeping_nearest(stored_gap, remember_gap)  # its owner: the gaps, laid out as the lists
