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
STOP ACTIVE, powered (:mod:`.hold`).

This module lays the plan out as a :class:`~.engine.Job` (what each RPDO field carries, per axis
its constants in device units, the time limits the drives were given) and a setpoint table, hands
them to the link's cyclic engine (:mod:`.engine`; on the wall clock in a process of its own,
:mod:`.coprocess`), and turns the engine's outcome into the :class:`StreamResult`: the recording
in device units (:class:`~.recording.Recording`; SI once, afterwards, in :mod:`drive_bridge.logs`),
why it stopped (:mod:`.supervision`), how each axis is held, the run's timing.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from ..cia.objects import (
    CONTROLWORD,
    INTERPOLATION_DATA_CONFIGURATION,
    MODES_OF_OPERATION,
    STATUSWORD,
    SYNC_COUNTER_OVERFLOW,
    TORQUE_OFFSET,
    VELOCITY_ACTUAL,
    VELOCITY_OFFSET,
    torque_object,
)
from ..cia.p402 import (
    CSP,
    CW_ENABLE,
    CW_ENABLE_IP,
    CW_HALT,
    IP,
    PP,
    QUICK_STOP_RAMP_AND_HOLD,
    state_name,
)
from ..cia.pdo import PdoCodec
from ..cia.setpoint import PVT, PVT_BUFFER_STATUS, PVT_RECORD_MAX_S, SETPOINT_OBJECTS, pack_pvt
from ..config import TimingLimits
from ..errors import Interrupted, MotionAborted, UserError
from ..outputs import hex_object
from .bringup import AxisLink
from .campaign import Plan
from .engine import (
    AGE_BIN_S,
    FIELD_CONSTANT,
    FIELD_CONTROLWORD,
    FIELD_TABLE,
    FIELD_TORQUE_OFFSET,
    Arrays,
    AxisJob,
    Job,
    Outcome,
    RpdoJob,
    Supervision,
    TpdoJob,
)
from .hold import STANDSTILL, STANDSTILL_MIN_RAD_S, holding_of, on_brake, prepare_enable, quick_stop
from .link import Link
from .recording import Recording
from .supervision import VelocityGuard, stop_reason
from .timekeeper import choose_producer, described, producing
from .timing import Timing, measure

log = logging.getLogger(__name__)

INT32 = (-(2**31), 2**31 - 1)


@dataclass
class StreamResult:
    """A plan streamed (:func:`stream`).

    Parameters
    ----------
    recording : Recording
        What was recorded.
    cycles_sent : int
        The plan's rows sent.
    aborted : MotionAborted or None
        What stopped the motion, where something did.
    missing : dict of str to int
        Per axis, rows without a complete sample.
    timing : Timing
        The run's timing.
    holding : dict of str to str, optional
        Per axis, how it is held now that the motion is over (for the command's last line).
    sync_before_plan : int
        SYNC cycles that enabled the drives before the plan's first.
    """

    recording: Recording
    cycles_sent: int
    aborted: MotionAborted | None
    missing: dict[str, int]
    timing: Timing
    holding: dict[str, str] | None = None
    sync_before_plan: int = 0


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
                if index == CONTROLWORD:
                    fields.append((FIELD_CONTROLWORD, 0))
                elif entry == PVT:  # position, velocity at that position, time to reach it [ms]
                    columns.append(
                        _pvt_records(
                            positions,
                            sc.velocity_to_device(np.gradient(demand, plan.period)),
                            plan.period,
                            ax.streaming.stride,
                        )
                    )
                    fields.append((FIELD_TABLE, len(columns) - 1))
                elif entry in SETPOINT_OBJECTS:
                    fields.append((FIELD_TABLE, position_column))
                elif index == TORQUE_OFFSET and plan.torque_ff_Nm is not None:
                    columns.append(np.asarray(sc.torque_to_device(plan.torque_ff_Nm[:, ai]), dtype=np.int64))
                    fields.append((FIELD_TORQUE_OFFSET, len(columns) - 1))
                    torque_gain = sc.feedback_Nm_per_unit
                elif index == MODES_OF_OPERATION:  # modes of operation, where an RPDO maps it
                    fields.append((FIELD_CONSTANT, ax.mode))
                elif index == VELOCITY_OFFSET and plan.velocity_ff_rad_s is not None:
                    columns.append(
                        np.asarray(
                            np.clip(sc.velocity_to_device(plan.velocity_ff_rad_s[:, ai]), *INT32),
                            dtype=np.int64,
                        )
                    )
                    fields.append((FIELD_TABLE, len(columns) - 1))
                else:
                    fields.append((FIELD_CONSTANT, 0))
            # around the plan, an interpolating drive's setpoint records stay off the bus: a FIFO (maxon's
            # PVT) would keep them and play them when interpolation starts
            records_only = _records_only(ax, codec)
            rpdos.append(
                RpdoJob(
                    codec.cob_id,
                    # a 64-bit field packed signed: the table holds a PVT record as int64 (same bytes)
                    codec.struct.format.replace("Q", "q"),
                    tuple(fields),
                    ai,
                    not records_only,
                    records_only and ax.streaming.buffered,
                )
            )
        moving = np.abs(np.diff(demand, prepend=demand[0])) > 0
        starts = (
            np.flatnonzero(moving & ~np.concatenate([[False], moving[:-1]]))
            if torque_gain
            else np.empty(0, int)
        )
        cols = {
            index: rec.column(a, index)
            for index in (
                STATUSWORD,
                VELOCITY_ACTUAL,
                torque_object(sc.torque_feedback, sc.torque_index),
                PVT_BUFFER_STATUS[0],
                INTERPOLATION_DATA_CONFIGURATION,
            )
            if (a, index) in rec.columns
        }
        powered = not on_brake(ax)
        standstill = (
            max(STANDSTILL * ax.cfg.limits.max_velocity, STANDSTILL_MIN_RAD_S) * sc.velocity_per_rad_s
        )
        axis_jobs.append(
            AxisJob(
                a,
                ax.cfg.node_id,
                tuple(rec.slots[a]),
                cols[STATUSWORD],
                cols.get(VELOCITY_ACTUAL, -1),
                cols.get(torque_object(sc.torque_feedback, sc.torque_index), -1),
                cols.get(PVT_BUFFER_STATUS[0], -1),
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
                ax.streaming.depth,
                cols.get(INTERPOLATION_DATA_CONFIGURATION, -1),
                ax.streaming.stride,
                _pvt_tail(ax, positions, plan.period),
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
    sync_producer: str = "auto",
) -> StreamResult:
    """Enable the axes without a jump, stream ``plan`` (a setpoint per SYNC, or records fed ahead into
    each drive's FIFO: :mod:`.buffered`), hold, return the recording.

    A fault (EMCY, fault bit, heartbeat loss, feedback missing longer than ``supervision`` allows, a
    CAN error frame), the ``guard`` or Ctrl-C quick-stops every axis; the recording up to that point
    is kept and the cause is in ``aborted``.  ``on_start`` is told how many SYNC cycles enabling
    took, once the plan's first goes out.

    Parameters
    ----------
    link : Link
        The link to the drives.
    axes : dict of str to AxisLink
        The brought-up axes.
    plan : Plan
        The plan.
    supervision : Supervision
        The limits it is judged by.
    progress : callable, optional
        Called with the rows sent.
    guard : VelocityGuard, optional
        The run's velocity guard.
    timing_limits : TimingLimits
        The limits of a wall-clock run.
    on_start : callable, optional
        Told how many SYNC cycles enabling took.
    sync_producer : {"auto", "interface"}
        Who sends SYNC on the wall clock (bus.yml ``master.sync_producer``, :mod:`.timekeeper`).

    Returns
    -------
    StreamResult
        The recording, how it ended, the timing.
    """
    net = link.network
    n = len(plan.demand)
    rec = Recording({a: axes[a].tpdos for a in plan.axes}, {a: axes[a].rpdos for a in plan.axes}, 0)
    job, columns = _job(axes, plan, rec, supervision, guard)
    counters = {ax.drive_limits.get(hex_object(SYNC_COUNTER_OVERFLOW, 0), 0) for ax in axes.values()}
    if len(counters) == 1:  # (every node holds the same: each SYNC carries its count)
        job = replace(job, sync_counter=int(counters.pop()))
    producer = choose_producer(axes, link.threaded, sync_producer)
    if producer is not None:
        job = replace(job, sync_from=described(producer))
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
            prepare_enable(axes[a], int(columns[job.axes[i].position_column][0]) if n else 0)
        for a in plan.axes:
            axes[a].node.nmt.send_command(0x01)  # operational: PDOs flow
        with producing(producer) as produces:
            if not produces:
                job = replace(job, sync_from=None)  # the engine sends SYNC
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
    aborted = refused or stop_reason(outcome, axes, supervision, guard)
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
        setpoints_late=outcome.setpoints_late,
    )
    timing.engine = {
        "host": host or "lockstep",
        "sync_source": outcome.sync_source,
        "streaming": {a: axes[a].streaming.why for a in plan.axes},
        "late_cycles": outcome.late_cycles,
        "periods_skipped": outcome.periods_skipped,
        "setpoints_late": outcome.setpoints_late,
        "syncs_lost": outcome.syncs_lost,
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
            if on_brake(ax) or PP not in ax.modes:
                continue
            try:
                ax.drive.set_mode(PP)
                ax.node.sdo[CONTROLWORD].raw = CW_HALT
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
            if not on_brake(axes[a])
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


def _pvt_records(positions: np.ndarray, velocities: np.ndarray, period_s: float, stride: int) -> np.ndarray:
    """maxon's PVT records (0x20C1 as int64), one a row: each row's position and velocity [device
    units], and the time to reach it from the record before, where records end every ``stride`` rows
    and at the last (the rows between are never sent)."""
    n = len(positions)
    ends = np.unique(np.append(np.arange(stride - 1, n, stride), n - 1))
    ms = np.full(n, round(stride * period_s * 1e3), dtype=np.int64)
    ms[ends] = np.diff(ends, prepend=-1) * round(period_s * 1e3)
    velocities = np.clip(velocities, -(2**23), 2**23 - 1)
    records = [pack_pvt(p, v, t) for p, v, t in zip(positions.tolist(), velocities.tolist(), ms.tolist())]
    return np.array(records, dtype=np.uint64).view(np.int64)


def _pvt_tail(ax: AxisLink, positions: np.ndarray, period_s: float) -> tuple[int, int]:
    """PVT records fed ahead: records of the longest time holding the plan's last position, as many
    as outlast the records kept ahead and one more, fed after the plan's last (maxon's drive faults
    on an empty buffer; the master's hold words end interpolation before they run out)."""
    if not (ax.streaming.buffered and ax.streaming.record == PVT):
        return (0, 0)
    count = math.ceil(ax.streaming.depth * period_s / PVT_RECORD_MAX_S) + 1
    hold = pack_pvt(int(positions[-1]), 0, round(PVT_RECORD_MAX_S * 1e3))
    return (count, int(np.array([hold], dtype=np.uint64).view(np.int64)[0]))


def _records_only(ax: AxisLink, codec: PdoCodec) -> bool:
    """An RPDO of an interpolating axis that carries setpoint records and no controlword."""
    return (
        ax.mode == IP
        and CONTROLWORD not in codec.objects
        and any(e in SETPOINT_OBJECTS for e in codec.entries)
    )
