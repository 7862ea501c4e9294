"""Progress for a person at the machine: a bar with axis, level and time left."""

from __future__ import annotations

import bisect
import sys
import time
from typing import TextIO

from .master.campaign import Plan


class CampaignProgress:
    """Callable(k) for the streaming loop; draws on a terminal, prints a line per segment otherwise.

    Parameters
    ----------
    plan : Plan
        The motion streamed (its segments name what runs).
    stream : file-like, optional
        Where it draws; default standard error.
    width : int
        The bar's width [characters].
    """

    def __init__(self, plan: Plan, stream: TextIO | None = None, width: int = 28):
        self.plan = plan
        self.stream = stream or sys.stderr
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.width = width
        self._starts = [s.start for s in plan.segments]
        self._last_segment = -1
        self._t0 = time.monotonic()

    def __call__(self, k: int) -> None:
        plan = self.plan
        i = max(0, bisect.bisect_right(self._starts, k) - 1)
        seg = plan.segments[i]
        what = (
            f"{','.join(seg.axes):<5} {seg.kind:<8} v {seg.velocity_fraction:>4.0%} "
            f"a {seg.acceleration_fraction:>4.0%}"
        )
        n = len(plan.demand)
        frac = k / n if n else 1.0
        if self.tty:
            elapsed = time.monotonic() - self._t0
            left = elapsed / frac * (1 - frac) if frac > 0 else 0.0
            bar = "#" * round(frac * self.width)
            self.stream.write(
                f"\r  {what} [{bar:<{self.width}}] {frac:4.0%}  "
                f"{(n - k) * plan.period:6.1f} s of motion, ~{left:5.1f} s left "
            )
            self.stream.flush()
        elif i != self._last_segment:
            self.stream.write(f"  {what}  at {k * plan.period:7.2f} s of {n * plan.period:.2f} s\n")
            self.stream.flush()
        self._last_segment = i

    def close(self) -> None:
        """End the bar's line (on a terminal)."""
        if self.tty:
            self.stream.write("\n")
            self.stream.flush()


class StepReporter:
    """Progress of a multi-step run: a line when a step starts and when it ends, a
    :class:`CampaignProgress` bar for each motion inside a step, and notes in between.

    Parameters
    ----------
    steps : list of str
        The run's steps, in order (``[k/n]`` counts them).
    stream : file-like, optional
        Where the lines go; default standard error.
    """

    def __init__(self, steps: list[str], stream: TextIO | None = None):
        self.steps = steps
        self.stream = stream or sys.stderr
        self.bar: CampaignProgress | None = None

    def _print(self, text: str) -> None:
        self.stream.write(text + "\n")
        self.stream.flush()

    def start(self, step: str, what: str) -> None:
        """A step starts: ``[k/n] step: what``.

        Parameters
        ----------
        step : str
            One of the run's steps.
        what : str
            What it does, in words.
        """
        self._print(f"[{self.steps.index(step) + 1}/{len(self.steps)}] {step}: {what}")

    def done(self, step: str, seconds: float, line: str) -> None:
        """A step ended well.

        Parameters
        ----------
        step : str
            The step.
        seconds : float
            How long it took [s].
        line : str
            What it found, in one line.
        """
        self.end_motion()
        self._print(f"  done: {step} in {seconds:.1f} s: {line}")

    def failed(self, step: str, seconds: float, reason: str) -> None:
        """A step failed.

        Parameters
        ----------
        step : str
            The step.
        seconds : float
            How long it ran [s].
        reason : str
            Why it failed, and what to do.
        """
        self.end_motion()
        self._print(f"  FAILED: {step} after {seconds:.1f} s: {reason}")

    def note(self, text: str) -> None:
        """A line inside a step (a motion's bar ends first).

        Parameters
        ----------
        text : str
            The note.
        """
        self.end_motion()
        self._print(f"  {text}")

    def motion(self, plan: Plan) -> CampaignProgress:
        """``on_plan`` for record / motion.run: a fresh bar for this motion.

        Parameters
        ----------
        plan : Plan
            The motion about to run.

        Returns
        -------
        CampaignProgress
            Its progress bar (the previous one closed).
        """
        self.end_motion()
        self.bar = CampaignProgress(plan, self.stream)
        return self.bar

    def end_motion(self) -> None:
        """Close the motion's bar, where one is shown."""
        if self.bar is not None:
            self.bar.close()
            self.bar = None
