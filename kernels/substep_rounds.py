"""A frame's substeps looped on the device in rounds (warp_cloth/substep_rounds.py): the substeps done
before the round in progress, which index the blow-up guard's flags, and the rounds left, the loop's
condition."""

import warp as wp


@wp.kernel
def start_rounds(rounds: int, done: wp.array(dtype=int), rounds_left: wp.array(dtype=int)):
    done[0] = 0
    rounds_left[0] = rounds


@wp.kernel
def next_round(substeps: int, done: wp.array(dtype=int), rounds_left: wp.array(dtype=int)):
    done[0] = done[0] + substeps
    rounds_left[0] = rounds_left[0] - 1
