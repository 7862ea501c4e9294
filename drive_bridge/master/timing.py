"""How well a wall-clock run kept its SYNC period, and the thread priority it asked for.

Every run reports its timing: late cycles (a SYNC more than ``LATE_FACTOR`` periods after the
one before), the largest SYNC gap, the samples missing and, where the interface sends SYNC
itself, the SYNCs that came before their setpoints.  A run past its limits is
``degraded``: its data are kept and usable with care, and the command ends with exit code 5.
The cyclic engine's process (:mod:`.coprocess`) asks the OS for a real-time (SCHED_FIFO)
priority and locked memory where it allows them; the report says what it got.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, field
from typing import Protocol

import numpy as np

from ..config import TimingLimits

LATE_FACTOR = 1.5
RT_PRIORITY = 50  # SCHED_FIFO priority asked for (1..99); below kernel threads
MCL_CURRENT, MCL_FUTURE = 1, 2


class Clock(Protocol):
    """The time a link waits on and stamps with (the wall clock, or a lockstep link's)."""

    def now(self) -> float:
        """Time stamp [s] used for frames and logs."""

    def sleep(self, seconds: float) -> None:
        """Let ``seconds`` pass (the link keeps receiving meanwhile).

        Parameters
        ----------
        seconds : float
            [s].
        """

    def wait_until(self, deadline: float) -> None:
        """Return when ``now() >= deadline``, yielding the CPU meanwhile.

        Parameters
        ----------
        deadline : float
            [s, :meth:`now`'s].
        """


@dataclass
class Timing:
    """How a run kept its time (:func:`measure`).

    Parameters
    ----------
    clock : {"wall", "lockstep"}
        The wall clock, or simulation time (always on time).
    cycles : int
        SYNC cycles.
    late_cycles_pct : float
        SYNC gaps over 1.5 periods [% of all].
    max_sync_gap_ms : float
        The largest SYNC gap [ms].
    mean_sync_period_ms : float
        [ms].
    samples_missing : dict of str to int
        Per axis, rows without a complete sample.
    priority : str
        What the OS granted the sending thread.
    degraded : bool
        Past the timing limits.
    reasons : list of str
        Which, and by how much.
    engine : dict
        How the cyclic engine ran: its host (a process of its own, a thread, lockstep), where SYNC
        came from, late cycles and skipped periods as it counted them, its worst wake-up, the
        feedback's age when it had it, and the supervision limits it judged by.
    """

    clock: str
    cycles: int
    late_cycles_pct: float
    max_sync_gap_ms: float
    mean_sync_period_ms: float
    samples_missing: dict[str, int]
    priority: str
    degraded: bool = False
    reasons: list[str] = field(default_factory=list)
    engine: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        """The timing as meta.yaml and ``--json`` hold it.

        Returns
        -------
        dict
            Every field.
        """
        return asdict(self)


def measure(
    sync_time: np.ndarray,
    period: float,
    missing: dict[str, int],
    *,
    wall: bool,
    priority: str,
    limits: TimingLimits,
    setpoints_late: int = 0,
    joins: tuple[int, ...] = (),
) -> Timing:
    """The timing of a run from its SYNC time stamps [s], missing samples per axis and the SYNCs that
    came before their setpoints.

    Parameters
    ----------
    sync_time : numpy.ndarray
        Per plan row, its SYNC's time stamp [s] (NaN: none).
    period : float
        The SYNC period [s].
    missing : dict of str to int
        Per axis, rows without a complete sample.
    wall : bool
        On the wall clock (else lockstep: always on time).
    priority : str
        What the OS granted.
    limits : TimingLimits
        The limits a wall-clock run is judged by.
    setpoints_late : int
        SYNCs the interface sent (on time) that the engine answered with no setpoints, as they were
        handed over together, late: judged as late cycles are.
    joins : tuple of int
        Rows a repeated segment's stream starts at: the time before them is no SYNC gap.

    Returns
    -------
    Timing
        The timing, and whether it is degraded.
    """
    pieces = np.split(sync_time, sorted(joins))
    gaps = np.concatenate([np.diff(piece[np.isfinite(piece)]) for piece in pieces])
    n = len(sync_time)
    late = float(np.count_nonzero(gaps > LATE_FACTOR * period) / len(gaps) * 100) if len(gaps) else 0.0
    t = Timing(
        "wall" if wall else "lockstep",
        n,
        round(late, 3),
        round(float(gaps.max()) * 1e3, 3) if len(gaps) else 0.0,
        round(float(gaps.mean()) * 1e3, 4) if len(gaps) else 0.0,
        dict(missing),
        priority,
    )
    if wall and n:
        worst = max(missing.values(), default=0) / n * 100
        for what, value, limit in (
            ("late cycles", t.late_cycles_pct, limits.max_late_pct),
            ("SYNCs before their setpoints", setpoints_late / n * 100, limits.max_late_pct),
            ("largest SYNC gap", t.max_sync_gap_ms / (period * 1e3), limits.max_gap_periods),
            ("samples missing", worst, limits.max_missing_pct),
        ):
            if value > limit:
                unit = "periods" if what == "largest SYNC gap" else "%"
                t.reasons.append(f"{what} {value:.3g} {unit} > {limit:g} {unit}")
        t.degraded = bool(t.reasons)
    return t


def raise_priority(priority: int = RT_PRIORITY) -> tuple[str, tuple[int, os.sched_param] | None]:
    """Ask for SCHED_FIFO ``priority`` for the calling thread; (what was granted, how to undo it:
    None when nothing was granted).

    Parameters
    ----------
    priority : int
        The SCHED_FIFO priority.

    Returns
    -------
    granted : str
        What was granted, in words.
    undo : (int, os.sched_param) or None
        The policy and parameters to put back.
    """
    if not hasattr(os, "sched_setscheduler"):
        return "normal (this OS has no SCHED_FIFO)", None
    try:
        before = (os.sched_getscheduler(0), os.sched_getparam(0))
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        return f"SCHED_FIFO {priority}", before
    except OSError as exc:
        return (
            f"normal (SCHED_FIFO not granted: {exc.strerror}; run with CAP_SYS_NICE or as root for it)",
            None,
        )


def lock_memory() -> str:
    """Lock the process's memory, now and to come (mlockall), where the OS allows; what was granted.

    Returns
    -------
    str
        What was granted, in words.
    """
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.mlockall(MCL_CURRENT | MCL_FUTURE) != 0:
            raise OSError(ctypes.get_errno(), os.strerror(ctypes.get_errno()))
        return "memory locked"
    except (AttributeError, OSError) as exc:
        return f"memory not locked ({getattr(exc, 'strerror', exc)}; raise RLIMIT_MEMLOCK or run as root)"
