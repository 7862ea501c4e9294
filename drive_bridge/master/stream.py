"""Streaming a plan: one setpoint per SYNC (cyclic synchronous or interpolated position, with the
master's feed-forward offsets where the plan has them), feedback recorded per SYNC, safety on
every cycle.

Around the plan SYNC runs too.  Before it, the drives are enabled in the mapped controlword while
the RPDOs already carry the plan's first setpoint, which is where each axis stands (its target
0x607A was set to that by SDO first, so a CSP drive that takes its target on enable does not
jump).  After it, each axis is left held (``holding: enabled``: powered at its position,
profile position with halt; ``brake``: switched off onto its brake); after a fault or a signal,
every axis gets a quick stop in the next cycle's controlword and SYNC runs until each stands
still (SDO only where its feedback is gone), and an axis that holds ``enabled`` stays in QUICK
STOP ACTIVE, powered.

This module lays the plan out as a :class:`~.engine.Job` (what each RPDO field carries, per axis
its constants in device units, the time limits the drives were given) and a setpoint table, hands
them to the link's cyclic engine (:mod:`.engine`; on the wall clock in a process of its own,
:mod:`.coprocess`), and turns the engine's outcome into the :class:`StreamResult`: the recording
in device units (:class:`Recording`; SI once, afterwards, in :mod:`drive_bridge.logs`), why it
stopped, how each axis is held, the run's timing.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass

import canopen
import numpy as np

from ..cia.p301 import MASTER_LOSS, emcy_text
from ..cia.p402 import (
    CSP,
    CW_ENABLE,
    CW_ENABLE_IP,
    CW_HALT,
    CW_QUICK_STOP,
    IP,
    PP,
    QUICK_STOP_RAMP_AND_HOLD,
    state_name,
)
from ..config import TimingLimits
from ..errors import GuardStop, Interrupted, MotionAborted, UserError
from ..pdo import PdoCodec
from ..setpoint import PVT, SETPOINT_OBJECTS, pack_pvt, position_of
from .bringup import AxisLink
from .campaign import Plan
from .engine import (
    AGE_BIN_S,
    CONSTANT,
    CONTROLWORD,
    TABLE,
    TORQUE_OFFSET,
    Arrays,
    AxisJob,
    Job,
    Outcome,
    RpdoJob,
    Supervision,
    TpdoJob,
)
from .link import Link
from .timing import Timing, measure

log = logging.getLogger(__name__)

STANDSTILL = 0.002  # quick stop complete below this fraction of the axis's max velocity ...
STANDSTILL_MIN_RAD_S = 0.05  # ... or below this, whichever is larger (encoder differencing noise)
#: decoding a trace: a TPDO is placed in the row of the newest SYNC before its time stamp, looking
#: back at most this many rows (a reply the master took in after the next SYNC went out)
FEEDBACK_LAG = 1
INT32 = (-(2**31), 2**31 - 1)
#: EMCY codes a drive sends when the master's stream stopped reaching it (loss of setpoints, the
#: master's heartbeat): where the master's own SYNCs were late by more than the drive allows, the
#: master was late, and the run says so
#: the drive profile's setpoint-loss timeout is unknown: a drive is taken to stop on the master's
#: heartbeat alone, within the consumer time bring-up wrote (0x1016:1)
NO_TIMEOUT = None


class Recording:
    """Samples in device units, one row per SYNC period of the plan.

    ``raw`` holds the TPDO objects of every axis side by side (``columns``
    names them as (axis, index)); ``got`` says which TPDO of which row arrived;
    ``demand`` is the position each drive took at the row's SYNC (what the last
    RPDO before it carried); ``sync_time`` the SYNC's time stamp, NaN for a period
    a late master sent no SYNC in (``skipped``).  :meth:`handlers` gives the
    per-COB-ID callbacks that rebuild it from a trace (:mod:`drive_bridge.logs`);
    live, the cyclic engine writes the same arrays (``arrays``, its own).

    A TPDO belongs to the last SYNC sent before it; when it is read after the
    next SYNC went out, its frame time stamp (taken when it reached the bus,
    before that SYNC) still places it in its own row.
    """

    def __init__(
        self,
        tpdos: dict[str, list[PdoCodec]],
        rpdos: dict[str, list[PdoCodec]],
        n_cycles: int,
        arrays: Arrays | None = None,
    ):
        self.axes = list(tpdos)
        self.columns: list[tuple[str, int]] = []
        self._tpdo_slots: list[tuple[int, PdoCodec, int, int]] = []  # (cob, codec, first column, got column)
        for axis, codecs in tpdos.items():
            for codec in codecs:
                self._tpdo_slots.append((codec.cob_id, codec, len(self.columns), len(self._tpdo_slots)))
                self.columns.extend((axis, index) for index in codec.objects)
        self._rpdo_slots = []
        for ai, codecs in enumerate(rpdos.values()):
            for codec in codecs:
                for pos, entry in enumerate(codec.entries):
                    if entry in SETPOINT_OBJECTS:
                        self._rpdo_slots.append((codec.cob_id, codec, pos, ai, entry))
        #: per axis, the columns of ``got`` (its TPDOs): a row is complete when all of them arrived
        self.slots = {
            axis: [slot for _, _, first, slot in self._tpdo_slots if self.columns[first][0] == axis]
            for axis in self.axes
        }
        if arrays is not None:
            self.raw, self.got, self.demand, self.sync_time = (
                arrays.raw,
                arrays.got,
                arrays.demand,
                arrays.sync_time,
            )
        else:
            self.raw = np.zeros((n_cycles, len(self.columns)), dtype=np.int64)
            self.got = np.zeros((n_cycles, len(self._tpdo_slots)), dtype=bool)
            self.demand = np.zeros((n_cycles, len(self.axes)), dtype=np.int64)
            self.sync_time = np.full(n_cycles, np.nan)
        self.pending = [0] * len(self.axes)  # position the last RPDO carried, per axis (decode)
        self.sync_index = -1  # row of the last SYNC sent (TPDOs after it belong to it)
        self.last_sync_time = -np.inf
        self.rows = 0  # rows up to the last one with a SYNC
        #: SYNCs still to come before the plan's first (decode: those that enabled the drives)
        self.skip_syncs = 0
        #: rows whose period got no SYNC (a late master sends the SYNC of the period it is in)
        self.skipped: set[int] = set()

    def column(self, axis: str, index: int) -> int:
        return self.columns.index((axis, index))

    def handlers(self) -> dict[int, Callable]:
        """COB-ID -> callback(can_id, data, timestamp) for every TPDO and RPDO of the plan."""
        out: dict[int, Callable[..., None]] = {}
        raw, got, sync_time = self.raw, self.got, self.sync_time
        for cob, codec, first, slot in self._tpdo_slots:

            def on_tpdo(
                can_id: int,
                data: bytearray,
                ts: float,
                first: int = first,
                last: int = first + len(codec.objects),
                unpack: Callable = codec.struct.unpack_from,
                size: int = codec.struct.size,
                slot: int = slot,
            ) -> None:
                row = back = self.sync_index
                if ts < self.last_sync_time and row < len(raw):  # reached the bus before that SYNC
                    while back > 0 and back >= row - FEEDBACK_LAG and not sync_time[back] <= ts:
                        back -= 1
                    if sync_time[back] <= ts:
                        row = back
                if 0 <= row < len(raw) and len(data) >= size:
                    raw[row, first:last] = unpack(data)
                    got[row, slot] = True

            out[cob] = on_tpdo
        for cob, codec, pos, ai, entry in self._rpdo_slots:

            def on_rpdo(
                can_id: int,
                data: bytearray,
                ts: float,
                unpack: Callable = codec.struct.unpack_from,
                pos: int = pos,
                ai: int = ai,
                entry: tuple[int, int] = entry,
            ) -> None:
                self.pending[ai] = position_of(entry, unpack(data)[pos])

            out[cob] = on_rpdo
        return out

    def on_sync(self, timestamp: float) -> None:
        if self.skip_syncs > 0:
            self.skip_syncs -= 1
            return
        self.last_sync_time = timestamp
        self.sync_index += 1
        while self.sync_index in self.skipped:
            self.sync_index += 1
        if self.sync_index < len(self.raw):
            self.sync_time[self.sync_index] = timestamp
            self.demand[self.sync_index] = self.pending
            self.rows = self.sync_index + 1

    def valid(self, axis: str) -> np.ndarray:
        """Per row: every TPDO of ``axis`` arrived (a complete sample)."""
        return np.asarray(self.got[:, self.slots[axis]].all(axis=1))

    def missing(self) -> dict[str, int]:
        """Rows without a complete sample, per axis (rows of periods without a SYNC included)."""
        return {axis: int(np.count_nonzero(~self.valid(axis)[: self.rows])) for axis in self.axes}

    def truncate(self) -> None:
        """Drop rows after the last SYNC (the plan was not finished)."""
        n = self.rows
        self.raw, self.got, self.demand, self.sync_time = (
            self.raw[:n],
            self.got[:n],
            self.demand[:n],
            self.sync_time[:n],
        )


@dataclass
class StreamResult:
    recording: Recording
    cycles_sent: int
    aborted: MotionAborted | None
    missing: dict[str, int]  # samples (rows) missing per axis
    timing: Timing
    #: per axis, how it is held now that the motion is over (for the command's last line)
    holding: dict[str, str] | None = None
    sync_before_plan: int = 0  # SYNC cycles that enabled the drives before the plan's first


def _at_rest(ax: AxisLink, statusword: int, velocity: int) -> bool:
    """Out of OPERATION ENABLED (quick stop active, switched off or faulted) and its measured
    velocity [device units] within ``STANDSTILL`` of its limit (or ``STANDSTILL_MIN_RAD_S``)."""
    speed = abs(float(ax.cfg.scaling.velocity_from_device(velocity)))
    return state_name(statusword) != "OPERATION ENABLED" and speed <= max(
        STANDSTILL * ax.cfg.limits.max_velocity, STANDSTILL_MIN_RAD_S
    )


def _on_brake(ax: AxisLink) -> bool:
    """Whether the axis is held by its brake (``holding: brake``) rather than powered."""
    return ax.cfg.drive_limits is not None and ax.cfg.drive_limits.holding == "brake"


def quick_stop(link: Link, axes: dict[str, AxisLink], timeout: float) -> list[str]:
    """Quick stop every axis by SDO, then wait until each stands still (the fallback where an axis's
    cyclic feedback is gone, and for a master that no longer streams). Returns problems seen.

    An axis stands still when a fresh read shows it out of OPERATION ENABLED (quick stop active,
    switched off or faulted) and its measured velocity (0x606C) within ``STANDSTILL`` of its
    limit on two reads in a row: never a statusword bit left from an earlier stop, and a drive
    that switched off while its axis coasts is waited for too."""
    problems = []
    for name, ax in axes.items():
        try:
            ax.node.sdo[0x6040].raw = CW_QUICK_STOP
        except (canopen.SdoCommunicationError, canopen.SdoAbortedError) as exc:
            problems.append(f"axis {name}: quick stop not confirmed ({exc})")
    deadline = link.clock.now() + timeout
    pending = {n for n in axes if not any(p.startswith(f"axis {n}:") for p in problems)}
    still = dict.fromkeys(pending, 0)
    speed = {}
    while pending and link.clock.now() < deadline:
        for name in list(pending):
            ax = axes[name]
            try:
                sw, velocity = ax.node.sdo[0x6041].raw, ax.node.sdo[0x606C].raw
            except (canopen.SdoCommunicationError, canopen.SdoAbortedError):
                continue
            speed[name] = abs(float(ax.cfg.scaling.velocity_from_device(velocity)))
            still[name] = still[name] + 1 if _at_rest(ax, sw, velocity) else 0
            if still[name] >= 2:
                pending.discard(name)
        if pending:
            link.clock.sleep(0.01)
    problems.extend(
        f"axis {n}: still moving ({speed.get(n, float('nan')):.3g} rad/s) {timeout} s after quick stop"
        for n in sorted(pending)
    )
    return problems


@dataclass(frozen=True)
class VelocityGuard:
    """A run's own limit on each axis's measured velocity [rad/s]: beyond it the run stops."""

    limits: dict[str, float]

    def reason(self, axis: str, velocity: float) -> str:
        return f"axis {axis}: velocity {velocity:.3g} rad/s beyond the guard {self.limits[axis]:.3g} rad/s: stopped"


def supervision_for(
    axes: dict[str, AxisLink],
    period: float,
    *,
    heartbeat_timeout: float,
    state_timeout: float,
    setpoint_timeout: float | None = NO_TIMEOUT,
    miss_limit: int | None = None,
    setpoint_source: str = "",
) -> Supervision:
    """The time limits a stream is judged by, from what bring-up wrote into the drives and read back:
    the SYNC period (0x1006), the synchronous window (0x1007, else the period), the master's
    heartbeat consumer time (0x1016:1); and the drives' own setpoint-loss timeout where their
    profile names one (``setpoint_timeout`` [s]).  A drive's feedback may be missing as long as a
    drive waits for the master's setpoints before it stops on its own: the setpoint-loss timeout,
    else the heartbeat consumer time.  ``miss_limit`` (bus.yml ``master.tpdo_miss_limit``) sets it
    to that many periods instead."""
    sources = {"period": "master.sync_period (0x1006 written)"}
    windows = [ax.drive_limits.get("0x1007:0") for ax in axes.values()]
    window = min((w for w in windows if w), default=None)
    if window:
        sources["window"] = "0x1007, as the drives hold it"
    else:
        sources["window"] = "the SYNC period (no synchronous window 0x1007 written)"
    consumers = [ax.drive_limits.get("0x1016:1") for ax in axes.values()]
    consumer_ms = min((c & 0xFFFF for c in consumers if c), default=None)
    drive_stops = setpoint_timeout
    if drive_stops is None:
        drive_stops = (consumer_ms / 1000.0) if consumer_ms else heartbeat_timeout
        sources["setpoint_timeout"] = (
            (
                "the master's heartbeat consumer time the drives hold (0x1016:1): their "
                "profile names no setpoint-loss timeout"
            )
            if consumer_ms
            else "master.heartbeat_consumer_ms (no consumer time written, no setpoint-loss timeout in the profile)"
        )
    else:
        sources["setpoint_timeout"] = setpoint_source or "the drive profile's setpoint-loss timeout"
    if miss_limit is not None:
        feedback = miss_limit * period
        sources["feedback_timeout"] = f"master.tpdo_miss_limit: {miss_limit} periods"
    else:
        feedback = drive_stops
        sources["feedback_timeout"] = "as long as the drives wait for setpoints (setpoint timeout)"
    sources["heartbeat_timeout"] = "master.heartbeat_consumer_ms"
    return Supervision(
        period,
        (window / 1e6) if window else period,
        feedback,
        drive_stops,
        heartbeat_timeout,
        state_timeout,
        max(state_timeout, 2.0),
        sources,
    )


def _job(
    axes: dict[str, AxisLink],
    plan: Plan,
    rec: Recording,
    supervision: Supervision,
    guard: VelocityGuard | None,
) -> tuple[Job, list[np.ndarray]]:
    """The plan as the engine runs it, and the setpoint table's columns."""
    names = plan.axes
    columns: list[np.ndarray] = []
    rpdos: list[RpdoJob] = []
    axis_jobs: list[AxisJob] = []
    for ai, a in enumerate(names):
        ax = axes[a]
        sc = ax.cfg.scaling
        demand = plan.demand[:, ai]
        positions = sc.position_to_device(demand)
        columns.append(np.asarray(positions, dtype=np.int64))
        position_column = len(columns) - 1
        torque_gain = 0.0
        for codec in ax.rpdos:
            fields: list[tuple[int, int]] = []
            for entry in codec.entries:
                index = entry[0]
                if index == 0x6040:
                    fields.append((CONTROLWORD, 0))
                elif entry == PVT:  # position, velocity at that position, time to reach it [ms]
                    vel = np.clip(
                        sc.velocity_to_device(np.gradient(demand, plan.period)), -(2**23), 2**23 - 1
                    )
                    ms = round(plan.period * 1000)
                    records = np.array(
                        [pack_pvt(p, v, ms) for p, v in zip(positions.tolist(), vel.tolist())],
                        dtype=np.uint64,
                    )
                    columns.append(records.view(np.int64))
                    fields.append((TABLE, len(columns) - 1))
                elif entry in SETPOINT_OBJECTS:
                    fields.append((TABLE, position_column))
                elif index == 0x60B2 and plan.torque_ff_Nm is not None:
                    columns.append(np.asarray(sc.torque_to_device(plan.torque_ff_Nm[:, ai]), dtype=np.int64))
                    fields.append((TORQUE_OFFSET, len(columns) - 1))
                    torque_gain = sc.feedback_Nm_per_unit
                elif index == 0x6060:  # modes of operation, where an RPDO maps it
                    fields.append((CONSTANT, ax.mode))
                elif index == 0x60B1 and plan.velocity_ff_rad_s is not None:
                    columns.append(
                        np.asarray(
                            np.clip(sc.velocity_to_device(plan.velocity_ff_rad_s[:, ai]), *INT32),
                            dtype=np.int64,
                        )
                    )
                    fields.append((TABLE, len(columns) - 1))
                else:
                    fields.append((CONSTANT, 0))
            # around the plan, an interpolating drive's setpoint records stay off the bus: a FIFO (maxon's
            # PVT) would keep them and play them when interpolation starts
            rpdos.append(
                RpdoJob(codec.cob_id, codec.struct.format, tuple(fields), ai, not _records_only(ax, codec))
            )
        moving = np.abs(np.diff(demand, prepend=demand[0])) > 0
        starts = (
            np.flatnonzero(moving & ~np.concatenate([[False], moving[:-1]]))
            if torque_gain
            else np.empty(0, int)
        )
        cols = {
            index: rec.column(a, index)
            for index in (0x6041, 0x606C, sc.torque_object, 0x20C4)
            if (a, index) in rec.columns
        }
        powered = not _on_brake(ax)
        standstill = (
            max(STANDSTILL * ax.cfg.limits.max_velocity, STANDSTILL_MIN_RAD_S) * sc.velocity_per_rad_s
        )
        axis_jobs.append(
            AxisJob(
                a,
                ax.cfg.node_id,
                tuple(rec.slots[a]),
                cols[0x6041],
                cols.get(0x606C, -1),
                cols.get(sc.torque_object, -1),
                cols.get(0x20C4, -1),
                position_column,
                CW_ENABLE_IP if ax.mode == IP else CW_ENABLE,
                ax.mode == IP,
                float(standstill),
                not powered,
                powered and ax.drive_limits.get("0x605A:0") == QUICK_STOP_RAMP_AND_HOLD,
                ax.mode == CSP,
                float(torque_gain),
                float(sc.rated_torque_Nm),
                tuple(int(k) for k in starts),
                math.inf
                if guard is None or a not in guard.limits
                else guard.limits[a] * sc.velocity_per_rad_s,
            )
        )
    tpdos = [
        TpdoJob(cob, codec.struct.format, first, slot, names.index(rec.columns[first][0]))
        for cob, codec, first, slot in rec._tpdo_slots
    ]
    job = Job(
        tuple(axis_jobs),
        tuple(rpdos),
        tuple(tpdos),
        len(plan.demand),
        len(rec.columns),
        len(columns),
        supervision,
    )
    return job, columns


def stream(
    link: Link,
    axes: dict[str, AxisLink],
    plan: Plan,
    *,
    supervision: Supervision,
    progress: Callable[[int], None] | None = None,
    guard: VelocityGuard | None = None,
    timing_limits: TimingLimits = TimingLimits(),
    on_start: Callable[[int], None] | None = None,
) -> StreamResult:
    """Enable the axes without a jump, stream ``plan`` one setpoint per SYNC, hold, return the recording.

    A fault (EMCY, fault bit, heartbeat loss, feedback missing longer than ``supervision`` allows, a
    CAN error frame), the ``guard`` or Ctrl-C quick-stops every axis; the recording up to that point
    is kept and the cause is in ``aborted``.  ``on_start`` is told how many SYNC cycles enabling
    took, once the plan's first goes out.
    """
    net = link.network
    n = len(plan.demand)
    rec = Recording({a: axes[a].tpdos for a in plan.axes}, {a: axes[a].rpdos for a in plan.axes}, 0)
    job, columns = _job(axes, plan, rec, supervision, guard)
    for i, a in enumerate(plan.axes):
        _inside_drive_limits(axes[a], columns[job.axes[i].position_column])
    for cob in {c.cob_id for a in plan.axes for c in axes[a].tpdos}:
        if net.subscribers.get(cob):
            net.unsubscribe(cob)  # canopen's own PdoMap decoding is not needed here

    def fill(arrays: Arrays) -> None:
        for j, column in enumerate(columns):
            arrays.table[:, j] = column

    arrays: Arrays | None = None
    host = ""
    refused: MotionAborted | None = None
    try:
        for i, a in enumerate(plan.axes):
            _prepare(axes[a], int(columns[job.axes[i].position_column][0]) if n else 0)
        for a in plan.axes:
            axes[a].node.nmt.send_command(0x01)  # operational: PDOs flow
        outcome, arrays, host = link.run_cycles(job, fill, progress, on_start)
    except KeyboardInterrupt as exc:  # before the engine ran: stop by SDO
        outcome = Outcome(
            abort=("interrupt", None, getattr(exc, "name", "Ctrl-C"), None), lost=list(plan.axes)
        )
    except MotionAborted as exc:  # preparing a drive failed: nothing was enabled
        refused = exc
        outcome = Outcome(abort=("refused", exc.axis, exc.reason, None), lost=list(plan.axes))
    except Exception as exc:  # a bus error before or around the motion: still stop the axes
        outcome = Outcome(abort=("error", None, f"{type(exc).__name__}: {exc}", None), lost=list(plan.axes))
    rec = Recording({a: axes[a].tpdos for a in plan.axes}, {a: axes[a].rpdos for a in plan.axes}, n, arrays)
    rec.rows = outcome.rows_sent
    if arrays is not None:
        rec.skipped = set(np.flatnonzero(np.isnan(arrays.sync_time[: outcome.rows_sent])).tolist())
    rec.truncate()
    missing = rec.missing()
    aborted = refused or _aborted(outcome, axes, supervision, guard)
    log.info(
        "%d of %d plan cycles sent; %s",
        outcome.rows_sent,
        n,
        f"stopping: {aborted}" if aborted else "holding",
    )
    holding, problems = _after(link, axes, plan.axes, outcome, aborted is None, supervision)
    if problems:
        text = "; ".join(problems)
        if aborted is None:
            aborted = MotionAborted(text)
        elif isinstance(aborted, Interrupted):  # its reason says it was interrupted already
            aborted = Interrupted(text, aborted.signal)
        else:
            aborted = MotionAborted(f"{aborted.reason}; {text}", aborted.axis, aborted.emcy)
    timing = measure(
        rec.sync_time,
        plan.period,
        missing,
        wall=link.threaded,
        priority=host or "lockstep (no wall clock)",
        limits=timing_limits,
    )
    timing.engine = {
        "host": host or "lockstep",
        "sync_source": outcome.sync_source,
        "late_cycles": outcome.late_cycles,
        "periods_skipped": outcome.periods_skipped,
        "setpoints_late": outcome.setpoints_late,
        "rows_skipped": sorted(rec.skipped),
        "worst_wake_ms": round(outcome.worst_wake_ms, 3),
        "feedback_age_ms": _ages(arrays),
        "supervision": supervision.as_dict(),
    }
    return StreamResult(rec, outcome.rows_sent, aborted, missing, timing, holding, outcome.enable_cycles)


def _ages(arrays: Arrays | None) -> dict[str, float]:
    """How long after it reached the bus the engine had each TPDO: p50, p99 and max [ms]."""
    if arrays is None or not arrays.ages.sum():
        return {}
    counts = arrays.ages
    cumulative = np.cumsum(counts) / counts.sum()
    edges = (np.arange(len(counts)) + 1) * AGE_BIN_S * 1e3
    return {
        "p50": round(float(edges[np.searchsorted(cumulative, 0.5)]), 2),
        "p99": round(float(edges[np.searchsorted(cumulative, 0.99)]), 2),
        "max": round(float(edges[np.flatnonzero(counts)[-1]]), 2),
    }


def _aborted(
    outcome: Outcome, axes: dict[str, AxisLink], supervision: Supervision, guard: VelocityGuard | None
) -> MotionAborted | None:
    """Why the engine stopped, in words (None: it did not)."""
    if outcome.abort is None:
        return None
    kind, axis, detail, code = outcome.abort
    if kind == "interrupt":
        return Interrupted(signal=detail or "Ctrl-C")
    if kind == "emcy" and axis is not None and code is not None:
        gap = outcome.largest_sync_gap_ms
        if code in MASTER_LOSS and gap >= supervision.setpoint_timeout_s * 1e3:
            return MotionAborted(
                f"the master was late: its SYNCs stopped for {gap:.0f} ms, longer than the drives wait for "
                f"setpoints ({supervision.setpoint_timeout_s * 1e3:.0f} ms); the drive stopped on its own "
                f"({emcy_text(code)}, EMCY 0x{code:04X})",
                axis,
                code,
            )
        buffer = (
            _buffer_cause(axes[axis])
            if any(i == 0x20C4 for c in axes[axis].tpdos for i in c.objects)
            else None
        )
        return buffer or MotionAborted(f"drive sent {emcy_text(code)} (EMCY 0x{code:04X})", axis, code)
    if kind == "silent":
        return MotionAborted(f"no TPDO: {detail}", axis)
    if kind == "guard" and axis is not None and guard is not None:
        return GuardStop(guard.reason(axis, float(axes[axis].cfg.scaling.velocity_from_device(int(detail)))))
    if kind == "buffer" and axis is not None:
        return _buffer_status_error(axis, int(detail, 16)) or MotionAborted(detail, axis)
    if kind == "heartbeat":
        return MotionAborted(f"heartbeat lost (none for {detail} s)", axis)
    if kind == "bus":
        return MotionAborted(
            f"the CAN interface reported {detail} error frame(s) (bus errors, error passive or "
            f"bus-off: check wiring, termination and bitrate)"
        )
    return MotionAborted(detail, axis)


def _after(
    link: Link,
    axes: dict[str, AxisLink],
    names: list[str],
    outcome: Outcome,
    completed: bool,
    supervision: Supervision,
) -> tuple[dict[str, str], list[str]]:
    """Once SYNC has stopped: an axis whose feedback was gone gets its quick stop by SDO; after a
    completed plan, a powered axis is held in profile position with halt where its drive has that
    mode, and a CSP axis that has neither that nor a quick stop that holds is said not to be held."""
    problems = list(outcome.problems)
    state = {a: None if (sw := outcome.statuswords.get(a)) is None else state_name(sw) for a in names}
    if outcome.lost:
        problems += quick_stop(link, {a: axes[a] for a in sorted(outcome.lost)}, supervision.stop_timeout_s)
        for a in outcome.lost:
            try:
                state[a] = axes[a].drive.state()
            except Exception:  # noqa: BLE001 - it is said as it is
                pass
    if completed and not outcome.lost:
        for a in names:
            ax = axes[a]
            if _on_brake(ax) or PP not in ax.modes:
                continue
            try:
                ax.drive.set_mode(PP)
                ax.node.sdo[0x6040].raw = CW_HALT
                state[a] = ax.drive.state()
            except Exception as exc:  # noqa: BLE001 - any failure: it holds as it is
                problems.append(f"axis {a}: could not hold it in profile position ({exc})")
                try:
                    state[a] = ax.drive.state()
                except Exception:  # noqa: BLE001
                    pass
        problems += [
            f"axis {a}: its drive has neither profile position nor a quick stop that holds: without the "
            f"master's setpoints it is not held (give it holding: brake)"
            for a in names
            if not _on_brake(axes[a])
            and PP not in axes[a].modes
            and axes[a].mode == CSP
            and axes[a].drive_limits.get("0x605A:0") != QUICK_STOP_RAMP_AND_HOLD
        ]
    return {a: holding_of(axes[a], state[a]) for a in names}, problems


def _inside_drive_limits(ax: AxisLink, demand: np.ndarray) -> None:
    """UserError before the first setpoint where the plan [device units] leaves the software
    position limits the drive holds (0x607D, as bring-up read it back)."""
    lo, hi = ax.drive_limits.get("0x607D:1"), ax.drive_limits.get("0x607D:2")
    if lo is None or hi is None or lo >= hi or not len(demand):
        return
    if demand.min() < lo or demand.max() > hi:
        sc = ax.cfg.scaling
        raise UserError(
            f"axis {ax.name}: the motion spans {float(sc.position_from_device(demand.min())):.4f} .. "
            f"{float(sc.position_from_device(demand.max())):.4f} rad, outside the software position "
            f"limits the drive holds (0x607D: {float(sc.position_from_device(lo)):.4f} .. "
            f"{float(sc.position_from_device(hi)):.4f} rad); nothing was enabled or moved"
        )


def _records_only(ax: AxisLink, codec: PdoCodec) -> bool:
    """An RPDO of an interpolating axis that carries setpoint records and no controlword."""
    return ax.mode == IP and 0x6040 not in codec.objects and any(e in SETPOINT_OBJECTS for e in codec.entries)


def _prepare(ax: AxisLink, target: int) -> None:
    """Before SYNC starts: a fault reset (SDO), the target position set to where the axis stands
    (CSP: a drive that takes 0x607A on enable must not jump), a record buffer emptied of whatever
    an earlier run left in it (IP with 0x60C4), then the operating mode."""
    ax.drive.reset_fault()
    if ax.mode == IP and ax.setpoint == PVT and 0x60C4 in ax.node.object_dictionary:
        try:
            ax.node.sdo[0x60C4][6].raw = 0
            ax.node.sdo[0x60C4][6].raw = 1
        except (canopen.SdoCommunicationError, canopen.SdoAbortedError) as exc:
            raise MotionAborted(
                f"clearing the interpolation buffer (0x60C4:6) failed ({exc}); nothing was enabled", ax.name
            ) from exc
    if ax.mode == CSP:
        try:
            actual = ax.node.sdo[0x6064].raw
            tolerance = max(1, round(ax.cfg.following_error_window_rad * ax.cfg.scaling.inc_per_rad / 2))
            if abs(actual - target) > tolerance:
                raise MotionAborted(
                    f"the axis stands at {actual} (0x6064), not at the plan's start {target}: it "
                    f"moved since the plan was made; nothing was enabled",
                    ax.name,
                )
            ax.node.sdo[0x607A].raw = actual
        except (canopen.SdoCommunicationError, canopen.SdoAbortedError) as exc:
            raise MotionAborted(
                f"setting the target position 0x607A to the actual position before enabling "
                f"failed ({exc}); nothing was enabled",
                ax.name,
            ) from exc
    ax.drive.set_mode(ax.mode)


def holding_of(ax: AxisLink, state: str | None) -> str:
    """How an axis in CiA 402 ``state`` is held, in words, for the command's last lines."""
    if state in ("SWITCH ON DISABLED", "READY TO SWITCH ON", "SWITCHED ON"):
        return "switched off, on its brake" if _on_brake(ax) else "switched off: NOT HELD"
    if state == "OPERATION ENABLED":
        return "powered, holding its position (profile position, halt)"
    if state == "QUICK STOP ACTIVE":
        return "powered, holding its position (quick stop active)"
    return f"in {state or 'an unknown state'}"


#: maxon's interpolation buffer status 0x20C4:1: error bits (each aborts the drive's trajectory)
#: (EPOS Application Note "Interpolation Position Mode", Dec 2008, p. 13)
BUFFER_ERRORS = {
    0x0100: "its interpolation buffer ran empty (underflow: a record came late or not at all)",
    0x0200: "its interpolation buffer overflowed (more records than it takes)",
    0x0400: "an interpolated velocity above its maximal profile velocity 0x607F",
    0x0800: "an interpolated acceleration above its maximal profile acceleration 0x60C5",
}


def _buffer_status_error(axis: str, status: int) -> MotionAborted | None:
    for bit, what in BUFFER_ERRORS.items():
        if status & bit:
            return MotionAborted(f"the drive reports {what} (0x20C4:1 = 0x{status:04X})", axis)
    return None


def _buffer_cause(ax: AxisLink) -> MotionAborted | None:
    """After an EMCY, the interpolation buffer status read by SDO: an error there is the cause."""
    try:
        return _buffer_status_error(ax.name, ax.node.sdo[0x20C4][1].raw)
    except (canopen.SdoCommunicationError, canopen.SdoAbortedError):
        return None


def check_heartbeats(
    axes: dict[str, AxisLink], names: list[str], now: float, timeout: float
) -> MotionAborted | None:
    """The first of ``names`` whose drive's heartbeat has been silent longer than ``timeout`` [s]."""
    for name in names:
        last = axes[name].last_heartbeat
        if last is not None and now - last > timeout:
            return MotionAborted(f"heartbeat lost (none for {now - last:.3f} s)", name)
    return None
