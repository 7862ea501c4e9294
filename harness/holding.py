"""Judging an axis's hold on the wall clock by the plant itself: a commissioning's motions timed as
the master streams them (:class:`MotionSpans`), set against the simulated plant as its drives'
process wrote it (:class:`drive_bridge.sim.process.PlantWatch`): how far an axis strayed while no
motion was commanded, and its power state at the end."""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from drive_bridge.commissioning import STEPS
from drive_bridge.progress import StepReporter

SETTLING_S = 0.3  # after a motion's last set-point: its stop, or the hold taking over, settles


class MotionSpans(StepReporter):
    """A commissioning's progress, each motion's span on the wall clock kept (``time.time()``'s:
    the plant watch's clock); with ``stall`` (``(step, n, seconds, pid)``), the process ``pid()``
    names stopped for ``seconds`` halfway through motion ``n`` (from 0) of ``step``."""

    def __init__(self, stall: tuple[str, int, float, Callable[[], int]] | None = None):
        super().__init__(list(STEPS))
        self.stall = stall
        self.spans: list[list[float]] = []
        self.step = ""
        self.motions = 0  # in the step
        self.stalled: list[int] = []

    def start(self, step: str, what: str) -> None:
        self.step, self.motions = step, 0
        super().start(step, what)

    def motion(self, plan):
        bar = super().motion(plan)
        span = [time.time(), time.time()]
        self.spans.append(span)
        rows, nth = len(plan.demand), self.motions
        self.motions += 1

        def progress(k: int) -> None:
            span[1] = time.time()
            if self.stall and (self.step, nth) == self.stall[:2] and not self.stalled and k >= rows // 2:
                pid = self.stall[3]()
                os.kill(pid, signal.SIGSTOP)
                time.sleep(self.stall[2])
                os.kill(pid, signal.SIGCONT)
                span[1] = time.time()  # (what was fed ahead of the stall ran on through it: commanded)
                self.stalled.append(k)
            bar(k)

        return progress


def uncommanded(watch: Path, spans: list[list[float]], axis: str) -> tuple[float, int]:
    """How far ``axis`` strayed [rad, motor side] while no motion was commanded (each stretch between
    motions on its own, from where it stood at the stretch's start), and its power state at the end
    (:data:`drive_bridge.cia.p402.STATE_BITS`'s keys).

    Parameters
    ----------
    watch : Path
        The plant as the drives' process wrote it.
    spans : list of [float, float]
        The motions' spans [s, ``time.time()``'s].
    axis : str
        The axis.

    Returns
    -------
    (float, int)
        The largest excursion and the last state.
    """
    with watch.open() as f:
        columns = f.readline().split()
    plant = np.loadtxt(watch, skiprows=1, ndmin=2)
    t = plant[:, 0]
    position, state = plant[:, columns.index(f"{axis}_rad")], plant[:, columns.index(f"{axis}_state")]
    free = np.ones(len(t), bool)
    for start, end in spans:
        free &= ~((t >= start) & (t <= end + SETTLING_S))
    index = np.flatnonzero(free)
    worst = 0.0
    for stretch in np.split(index, np.flatnonzero(np.diff(index) > 1) + 1):
        if len(stretch):
            worst = max(worst, float(np.max(np.abs(position[stretch] - position[stretch[0]]))))
    return worst, int(state[-1])
