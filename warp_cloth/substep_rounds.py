"""A frame's substeps as the simulator launches them, each followed by the blow-up guard's check
(kernels/guard.py). Captured in a graph, a frame of at least ``LOOPED_FROM`` substeps loops on the device over
rounds of ``ROUND`` substeps, captured once, and captures the rest after the loop: a frame's graph then holds
fewer than ``2 * ROUND`` substeps at any count. A graph of every substep cost its capture and upload in
proportion to the count: a cotton cloth of 128^2 at its stable 955 substeps a frame took 2.2 s to capture on
an H200 (each of a run's four graphs: two buffer parities by two guard slots), 0.05 s looped. A round costs
the loop's condition, a few microseconds (docs/notebook/benchmarks.md): a frame of fewer substeps, whose graph
is quick to capture, does not loop. Nor does a scene whose mesh colliders move (the scene's or the control's):
their BVH refit allocates memory, which a loop's body may not.

``ROUND`` is even: a substep swaps the same buffers each time, so two leave them where they were, and the
loop's body may replay from where it ends."""

from __future__ import annotations

from typing import Callable

import warp as wp

from warp_cloth.kernels import substep_rounds

from .state import DeviceState

ROUND = 16  # substeps a round of the device's loop
LOOPED_FROM = 4 * ROUND  # the fewest substeps a frame loops over


class SubstepRounds:
    """The loop's counters on the device, made once per simulator."""

    def __init__(self, device, loops: bool) -> None:
        self.device = device
        self.loops = loops  # whether a captured frame may loop (no allocation in a substep)
        self.done = wp.zeros(1, dtype=int, device=device)  # the frame's substeps before the round in progress
        self.rounds_left = wp.zeros(1, dtype=int, device=device)  # the loop's condition
        self.none_done = wp.zeros(1, dtype=int, device=device)  # a frame that does not loop counts from here: 0

    def launch(self, substeps: int, captured: bool, state: DeviceState, substep: Callable[[], None],
               check: Callable[[wp.array, int], None]) -> None:
        """``substeps`` calls of ``substep``, each followed by ``check(done, offset)`` (the substep's index is
        ``done[0] + offset``), looped on the device in rounds where ``captured`` (in a graph's capture), the
        scene ``loops`` and there are ``LOOPED_FROM`` substeps; the substeps left after the rounds, or all of
        them, one after another."""
        rounds = substeps // ROUND if captured and self.loops and substeps >= LOOPED_FROM else 0
        done = self.none_done
        if rounds:
            done = self.done
            wp.launch(substep_rounds.start_rounds, dim=1, inputs=[rounds], outputs=[self.done, self.rounds_left],
                      device=self.device)
            parity = state.parity

            def one_round() -> None:
                for offset in range(ROUND):
                    substep()
                    check(self.done, offset)
                wp.launch(substep_rounds.next_round, dim=1, inputs=[ROUND], outputs=[self.done, self.rounds_left],
                          device=self.device)

            wp.capture_while(self.rounds_left, one_round)
            assert state.parity == parity, "a round of substeps must leave the buffers where it found them"
        for offset in range(substeps - rounds * ROUND):
            substep()
            check(done, offset)
