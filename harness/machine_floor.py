"""The machine's own floor, measured beside a wall-clock run: a plain Python loop pinned to each CPU
at SCHED_FIFO on a 2 ms absolute schedule (as cyclictest measures: sleep to the next deadline, note
how late it woke), each in a process of its own.  ``tools/bench_realtime.py`` sets each late SYNC of
a campaign against it; the wall-clock tests use it to tell a stall of the machine (the floor held
up as long) from one of ours (it was not)."""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, TypeVar

import numpy as np

from drive_bridge.cia.p301 import MASTER_LOSS

PERIOD_S = 0.002
SLACK_PERIODS = 2.5  # how much longer a SYNC gap is than the stall of the machine behind it, at most

LOOP = """import json, os, signal, sys, time
period = float(sys.argv[1])
os.sched_setaffinity(0, {int(sys.argv[2])})
try:
    os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(50))
    granted = "SCHED_FIFO 50"
except OSError as exc:
    granted = f"normal ({exc.strerror})"
stop = []
signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
offset = time.time() - time.monotonic()
late, held = [], []
t0 = time.monotonic() + period
k = 0
sys.stdout.write("ready\\n")
sys.stdout.flush()
while not stop:
    deadline = t0 + k * period
    left = deadline - time.monotonic()
    if left > 0:
        time.sleep(left)
    woke = time.monotonic() - deadline
    late.append(woke)
    if woke > period / 2:
        held.append((deadline + offset, woke))
    k += 1
print(json.dumps({"granted": granted, "late": late, "held": held}))
"""


@dataclass
class Floor:
    """What the plain loops measured: the scheduling they were granted, their wake-ups [ms]
    (p99, p99.9, max, share over 3 ms [%]) and, per CPU, when a loop was held up: (wall-clock
    time of the deadline [s], how late it woke [ms])."""

    granted: str = ""
    p99: float = 0.0
    p999: float = 0.0
    max: float = 0.0
    over_3ms_pct: float = 0.0
    held: list[list[tuple[float, float]]] = field(default_factory=list)

    def held_ms(self) -> float:
        """The longest any CPU's loop was held up [ms] (0 where none was)."""
        return max((late for cpu in self.held for _, late in cpu), default=0.0)


@contextlib.contextmanager
def floor_during() -> Iterator[Floor]:
    """The floor measured while the block runs, one plain loop pinned to each CPU (a stall of one
    virtual CPU shows in its own); filled in when the block ends."""
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", LOOP, str(PERIOD_S), str(cpu)], stdout=subprocess.PIPE, text=True
        )
        for cpu in sorted(os.sched_getaffinity(0))
    ]
    for proc in procs:
        assert proc.stdout is not None
        proc.stdout.readline()
    result = Floor()
    try:
        yield result
    finally:
        for proc in procs:
            proc.terminate()
        data = [json.loads(proc.communicate()[0]) for proc in procs]
        late = np.concatenate([d["late"] for d in data]) * 1e3
        result.granted = data[0]["granted"]
        result.p99 = float(np.percentile(late, 99))
        result.p999 = float(np.percentile(late, 99.9))
        result.max = float(late.max())
        result.over_3ms_pct = float(np.mean(late > 3.0) * 100)
        result.held = [[(t, w * 1e3) for t, w in d["held"]] for d in data]


Outcome = TypeVar("Outcome")


def machine_explains(gap_ms: float, held_ms: float) -> bool:
    """Whether a plain loop held up ``held_ms`` [ms] explains a SYNC gap of ``gap_ms`` [ms]: the
    machine stopped every task as long.  A gap is up to :data:`SLACK_PERIODS` periods longer than
    the stall that caused it, seen by the loop: when the machine stops, the engine may have sent its
    last SYNC up to a period before, and after it sends the next at the period nearest its wake-up
    (up to half a period on), while the loop, sleeping to a deadline at most a period after the
    stall began, wakes late by the stall less that period at most."""
    return held_ms >= gap_ms - SLACK_PERIODS * PERIOD_S * 1e3


def beside_the_floor(
    run: Callable[[], Outcome], stalled_ms: Callable[[Outcome], float | None], attempts: int = 3
) -> Outcome:
    """``run()`` with the machine's floor measured beside it; run again where it was stopped by a
    stall the machine's floor shows too (:func:`machine_explains`).  ``stalled_ms(outcome)`` says
    how long the run was stalled [ms] where a stall stopped it (None: it was not stopped by one).
    A stall the floor of the same attempt does not explain is ours: the test fails, saying how long
    each was.  After ``attempts`` runs each stopped by the machine, the test fails saying so."""
    held = []
    for _ in range(attempts):
        with floor_during() as floor:
            outcome = run()
        stall = stalled_ms(outcome)
        if stall is None:
            return outcome
        said = f"a {stall:.0f} ms stall, the floor held {floor.held_ms():.0f} ms"
        if not machine_explains(stall, floor.held_ms()):
            raise AssertionError(f"a stall of ours stopped the run: {said}")
        held.append(said)
    raise AssertionError(f"the machine stalled the run in each of {attempts} attempts: " + "; ".join(held))


def stall_ms(abort: str | None, max_sync_gap_ms: float) -> float | None:
    """How long the stall that stopped a wall-clock run lasted [ms] (None: none stopped it), from
    the reason it was stopped for (None: it was not) and its largest SYNC gap [ms]: the drives'
    setpoint watchdog or heartbeat consumer (the SYNCs stopped that long), or the master's TPDO
    watch (3 periods)."""
    if abort is None:
        return None
    if any(f"EMCY 0x{code:04X}" in abort for code in MASTER_LOSS):
        return max_sync_gap_ms
    return 3 * PERIOD_S * 1e3 if "no TPDO" in abort else None


def run_stall_ms(result: Any) -> float | None:
    """:func:`stall_ms` of a run's result (``aborted``: a MotionAborted or None; ``timing``)."""
    return stall_ms(result.aborted and result.aborted.reason, result.timing.max_sync_gap_ms)


def meta_stall_ms(meta: dict) -> float | None:
    """:func:`stall_ms` of a recorded run, from its ``meta.yaml`` (as read)."""
    return stall_ms(meta.get("abort", {}).get("reason"), meta["timing"]["max_sync_gap_ms"])
