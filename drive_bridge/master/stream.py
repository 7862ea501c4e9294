"""Cyclic streaming: one setpoint per SYNC (cyclic synchronous or interpolated position, with the
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

The sending loop does only light work: pack the RPDOs, send them and the SYNC,
check the previous cycle's feedback.  Samples stay in device units in
preallocated arrays; conversion to SI happens once, afterwards, in
:mod:`drive_bridge.logs`.
"""
from __future__ import annotations

import gc
import logging
from dataclasses import dataclass
from typing import Callable

import canopen
import numpy as np

from ..errors import GuardStop, Interrupted, MotionAborted, UserError
from ..signals import signal_name
from ..pdo import PdoCodec
from ..setpoint import CSP as CSP_MODE, CW_ENABLE_IP, IP, PVT, SETPOINT_OBJECTS, SW_FOLLOWING, pack_pvt, position_of
from .bringup import QUICK_STOP_RAMP_AND_HOLD, AxisLink, emcy_text
from .campaign import Plan
from .cia402 import CW_ENABLE, CW_SHUTDOWN, CW_SWITCH_ON, SW_FAULT, state_name
from .link import Link
from .timing import Timing, TimingLimits, measure, raise_priority, restore_priority

log = logging.getLogger(__name__)

CW_QUICK_STOP_CMD = 0x000B          # enable voltage + switch on + enable operation, quick stop bit low
CW_DISABLE_VOLTAGE = 0x0000
CW_HALT = 0x010F                    # enable operation with halt (bit 8): a profile position drive holds
PP = 1
#: the controlword that takes a drive one step nearer OPERATION ENABLED from the state it shows
ENABLE_STEP = {"SWITCH ON DISABLED": CW_SHUTDOWN, "READY TO SWITCH ON": CW_SWITCH_ON,
               "SWITCHED ON": CW_ENABLE, "OPERATION ENABLED": CW_ENABLE, "QUICK STOP ACTIVE": CW_ENABLE}
STANDSTILL = 0.002                  # quick stop complete below this fraction of the axis's max velocity ...
STANDSTILL_MIN_RAD_S = 0.05         # ... or below this, whichever is larger (encoder differencing noise)
SYNC_COB_ID = 0x080
#: a cycle's feedback is checked this many SYNC periods after it was due, so that a
#: reply the receiving thread hands over late still counts (and is in the log)
FEEDBACK_LAG = 1
#: rows after the first setpoint by which the drive must show statusword bit 12 (following / IP active)
FOLLOW_GRACE_ROWS = 2
INT16, INT32 = (-2**15, 2**15 - 1), (-2**31, 2**31 - 1)


class Recording:
    """Samples in device units, one row per SYNC cycle.

    ``raw`` holds the TPDO objects of every axis side by side (``columns``
    names them as (axis, index)); ``got`` says which TPDO of which row arrived;
    ``demand`` is the target position sent before each SYNC; ``sync_time``
    the SYNC's time stamp.  :meth:`handlers` gives the per-COB-ID callbacks
    that fill it, used live on the bus and when decoding a trace.

    A TPDO belongs to the last SYNC sent before it; when the receiving thread
    hands it over after the next SYNC went out, its frame time stamp (taken
    when it reached the bus, before that SYNC) still places it in its own row.
    """

    def __init__(self, tpdos: dict[str, list[PdoCodec]], rpdos: dict[str, list[PdoCodec]], n_cycles: int):
        self.axes = list(tpdos)
        self.columns: list[tuple[str, int]] = []
        self._tpdo_slots: list[tuple[int, PdoCodec, int, int]] = []   # (cob, codec, first column, got column)
        for axis, codecs in tpdos.items():
            for codec in codecs:
                self._tpdo_slots.append((codec.cob_id, codec, len(self.columns), len(self._tpdo_slots)))
                self.columns.extend((axis, index) for index in codec.objects)
        self._rpdo_slots = []
        for ai, (axis, codecs) in enumerate(rpdos.items()):
            for codec in codecs:
                for pos, entry in enumerate(codec.entries):
                    if entry in SETPOINT_OBJECTS:
                        self._rpdo_slots.append((codec.cob_id, codec, pos, ai, entry))
        #: per axis, the columns of ``got`` (its TPDOs): a row is complete when all of them arrived
        self.slots = {axis: [slot for _, _, first, slot in self._tpdo_slots if self.columns[first][0] == axis]
                      for axis in self.axes}
        self.raw = np.zeros((n_cycles, len(self.columns)), dtype=np.int64)
        self.got = np.zeros((n_cycles, len(self._tpdo_slots)), dtype=bool)
        self.demand = np.zeros((n_cycles, len(self.axes)), dtype=np.int64)
        self.sync_time = np.full(n_cycles, np.nan)
        self.sync_index = -1          # row of the last SYNC sent (TPDOs after it belong to it)
        self.last_sync_time = -np.inf
        self.rows = 0                 # rows that have a SYNC
        #: SYNCs still to come before the plan's first (decode: those that enabled the drives)
        self.skip_syncs = 0

    def column(self, axis: str, index: int) -> int:
        return self.columns.index((axis, index))

    def handlers(self) -> dict[int, Callable]:
        """COB-ID -> callback(can_id, data, timestamp) for every TPDO and RPDO of the plan."""
        out: dict[int, Callable[..., None]] = {}
        raw, got, sync_time = self.raw, self.got, self.sync_time
        for cob, codec, first, slot in self._tpdo_slots:
            def on_tpdo(can_id: int, data: bytearray, ts: float, first: int = first,
                        last: int = first + len(codec.objects), unpack: Callable = codec.struct.unpack_from,
                        size: int = codec.struct.size, slot: int = slot) -> None:
                row = back = self.sync_index
                if ts < self.last_sync_time and row < len(raw):   # reached the bus before that SYNC
                    while back > 0 and back >= row - FEEDBACK_LAG and ts < sync_time[back]:
                        back -= 1
                    if sync_time[back] <= ts:
                        row = back
                if 0 <= row < len(raw) and len(data) >= size:
                    raw[row, first:last] = unpack(data)
                    got[row, slot] = True
            out[cob] = on_tpdo
        for cob, codec, pos, ai, entry in self._rpdo_slots:
            def on_rpdo(can_id: int, data: bytearray, ts: float, unpack: Callable = codec.struct.unpack_from,
                        pos: int = pos, ai: int = ai, entry: tuple[int, int] = entry) -> None:
                row = self.sync_index + 1
                if row < len(raw):
                    self.demand[row, ai] = position_of(entry, unpack(data)[pos])
            out[cob] = on_rpdo
        return out

    def on_sync(self, timestamp: float) -> None:
        if self.skip_syncs > 0:
            self.skip_syncs -= 1
            return
        self.last_sync_time = timestamp
        self.sync_index += 1
        if self.sync_index < len(self.raw):
            self.sync_time[self.sync_index] = timestamp
            self.rows = self.sync_index + 1

    def valid(self, axis: str) -> np.ndarray:
        """Per row: every TPDO of ``axis`` arrived (a complete sample)."""
        return np.asarray(self.got[:, self.slots[axis]].all(axis=1))

    def missing(self) -> dict[str, int]:
        """Rows without a complete sample, per axis."""
        return {axis: int(np.count_nonzero(~self.valid(axis)[:self.rows])) for axis in self.axes}

    def truncate(self) -> None:
        """Drop rows after the last SYNC (the plan was not finished)."""
        n = self.rows
        self.raw, self.got, self.demand, self.sync_time = (self.raw[:n], self.got[:n],
                                                           self.demand[:n], self.sync_time[:n])


@dataclass
class StreamResult:
    recording: Recording
    cycles_sent: int
    aborted: MotionAborted | None
    missing: dict[str, int]           # samples (rows) missing per axis
    timing: Timing
    #: per axis, how it is held now that the motion is over (for the command's last line)
    holding: dict[str, str] | None = None
    sync_before_plan: int = 0         # SYNC cycles that enabled the drives before the plan's first


class _Feedback:
    """The newest statusword and velocity actual of each axis from its TPDOs, and how many SYNC
    cycles ago each arrived: what the cycles before and after the plan decide on."""

    def __init__(self, axes: dict[str, AxisLink], names: list[str]):
        self.status: dict[str, int | None] = dict.fromkeys(names)
        self.velocity: dict[str, int | None] = dict.fromkeys(names)
        self.age = dict.fromkeys(names, 0)        # SYNCs since the last statusword
        self.handlers = []                          # (COB-ID, callback), for subscribe / unsubscribe
        for a in names:
            for codec in axes[a].tpdos:
                picks = [(i, kind) for i, kind in ((0x6041, "status"), (0x606C, "velocity")) if i in codec.objects]
                if picks:
                    cols = [(codec.objects.index(i), kind) for i, kind in picks]
                    self.handlers.append((codec.cob_id, self._handler(a, codec, cols)))

    def _handler(self, axis: str, codec: PdoCodec, cols: list[tuple[int, str]]
                 ) -> Callable[[int, bytearray, float], None]:
        unpack, size = codec.struct.unpack_from, codec.struct.size

        def on_tpdo(can_id: int, data: bytearray, ts: float) -> None:
            if len(data) >= size:
                values = unpack(data)
                for col, kind in cols:
                    getattr(self, kind)[axis] = values[col]
                    if kind == "status":
                        self.age[axis] = 0
        return on_tpdo

    def subscribe(self, net: canopen.Network) -> None:
        for cob, handler in self.handlers:
            net.subscribe(cob, handler)

    def unsubscribe(self, net: canopen.Network) -> None:
        for cob, handler in self.handlers:
            net.unsubscribe(cob, handler)

    def on_sync(self) -> None:
        for a in self.age:
            self.age[a] += 1

    def state(self, axis: str) -> str | None:
        sw = self.status[axis]
        return None if sw is None else state_name(sw)


class _TorqueOffset:
    """The plan's torque offsets of one axis [0x60B2 units] less the torque its velocity loop held
    at rest when the current move started (``bias``, set by :class:`_Unloader`)."""

    def __init__(self, values: np.ndarray):
        self.values = values
        self.bias = 0

    def at(self, k: int) -> int:
        return max(INT16[0], min(INT16[1], self.values.item(k) - self.bias))


class _Unloader:
    """Where the master sends the model torque, the drive's velocity integrator still holds the
    torque it wound up at rest (against stiction, or the friction of the last move) and adds it to
    the next move; the project's drive restarts its integrator when a move starts instead.  At
    each move start the master measures what the loop holds (torque actual less the offset it
    sends) and sends that much less with the move: the model alone carries it."""

    def __init__(self, rec: Recording, axes: dict[str, AxisLink], plan: Plan, offsets: dict[str, _TorqueOffset]):
        self.jobs = []               # (move-start cycles, offset column, torque column, scaling, TPDO slots)
        for ai, a in enumerate(plan.axes):
            if a not in offsets:
                continue
            moving = np.abs(np.diff(plan.demand[:, ai], prepend=plan.demand[0, ai])) > 0
            starts = set(np.flatnonzero(moving & ~np.concatenate([[False], moving[:-1]])).tolist())
            self.jobs.append((starts, offsets[a], rec.column(a, axes[a].cfg.scaling.torque_object),
                              axes[a].cfg.scaling, rec.slots[a]))
        self.rec = rec

    def at(self, k: int) -> None:
        row = k - 1 - FEEDBACK_LAG           # the newest row checked; at rest its torque is steady
        for starts, offset, col, sc, slots in self.jobs:
            if k in starts and row >= 1 and self.rec.got[row, slots].all():
                raw = self.rec.raw[row, col]
                offset.bias = int(sc.torque_to_device(sc.torque_from_feedback(raw))) - offset.at(row - 1)


def _constant(value: int) -> Callable[[int], int]:
    return lambda k: value


def _packer(ax: AxisLink, codec: PdoCodec, plan: Plan, ai: int, send: Callable[[int, bytes], None],
            offsets: dict[str, _TorqueOffset]) -> Callable[[int, int], None]:
    """Send function of one RPDO for cycle k: the controlword, the setpoint from the plan (target
    position or interpolation data record), the plan's feed-forward offsets (zero without; the
    torque offset through ``offsets``, which may hold back what the velocity loop already holds)."""
    sc = ax.cfg.scaling
    demand = plan.demand[:, ai]
    pos = sc.position_to_device(demand)
    # per mapped object: its value at cycle k (None: the controlword), as a Python int -- read from a
    # numpy column at each cycle (a list of a campaign's Python ints would take ~17 MB per column)
    values: list[Callable[[int], int] | None] = []
    for entry in codec.entries:
        index = entry[0]
        if index == 0x6040:
            values.append(None)
        elif entry == PVT:       # position, velocity at that position, time to reach it [ms]
            vel = np.clip(sc.velocity_to_device(np.gradient(demand, plan.period)), -2**23, 2**23 - 1)
            ms = round(plan.period * 1000)
            values.append(np.array([pack_pvt(p, v, ms) for p, v in zip(pos.tolist(), vel.tolist())],
                                   dtype=np.uint64).item)
        elif entry in SETPOINT_OBJECTS:
            values.append(np.asarray(pos, dtype=np.int64).item)
        elif index == 0x60B2 and plan.torque_ff_Nm is not None:
            offsets[ax.name] = _TorqueOffset(np.asarray(sc.torque_to_device(plan.torque_ff_Nm[:, ai]), dtype=np.int64))
            values.append(offsets[ax.name].at)
        elif index == 0x6060:                               # modes of operation, where an RPDO maps it
            values.append(_constant(ax.mode))
        elif index == 0x60B1 and plan.velocity_ff_rad_s is not None:
            values.append(np.asarray(np.clip(sc.velocity_to_device(plan.velocity_ff_rad_s[:, ai]), *INT32),
                                     dtype=np.int64).item)
        else:
            values.append(_constant(0))
    pack = codec.struct.pack
    cob = codec.cob_id

    def send_cycle(k: int, cw: int) -> None:
        send(cob, pack(*[cw if value is None else value(k) for value in values]))
    return send_cycle


def _at_rest(ax: AxisLink, statusword: int, velocity: int) -> bool:
    """Out of OPERATION ENABLED (quick stop active, switched off or faulted) and its measured
    velocity [device units] within ``STANDSTILL`` of its limit (or ``STANDSTILL_MIN_RAD_S``)."""
    speed = abs(float(ax.cfg.scaling.velocity_from_device(velocity)))
    return state_name(statusword) != "OPERATION ENABLED" and \
        speed <= max(STANDSTILL * ax.cfg.limits.max_velocity, STANDSTILL_MIN_RAD_S)


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
            ax.node.sdo[0x6040].raw = CW_QUICK_STOP_CMD
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
    problems.extend(f"axis {n}: still moving ({speed.get(n, float('nan')):.3g} rad/s) {timeout} s after quick stop"
                    for n in sorted(pending))
    return problems


def stream(link: Link, axes: dict[str, AxisLink], plan: Plan, *, heartbeat_timeout: float, miss_limit: int,
           state_timeout: float, progress: Callable[[int], None] | None = None,
           guard: Callable[[dict[str, int]], str | None] | None = None,
           timing_limits: TimingLimits = TimingLimits(),
           on_start: Callable[[int], None] | None = None) -> StreamResult:
    """Enable the axes without a jump, stream ``plan`` one setpoint per SYNC, hold, return the recording.

    A fault (EMCY, fault bit, heartbeat loss, missing TPDOs, a CAN error frame) or Ctrl-C
    quick-stops every axis; the recording up to that point is kept and the cause is in
    ``aborted``.  ``guard`` sees each checked cycle's actual velocity per axis (device units) and
    stops the run by returning a reason.  ``on_start`` is told how many SYNC cycles enabling took,
    once the plan's first goes out.
    """
    net, clock = link.network, link.clock
    n = len(plan.demand)
    rec = Recording({a: axes[a].tpdos for a in plan.axes}, {a: axes[a].rpdos for a in plan.axes}, n)
    for i, a in enumerate(plan.axes):        # what the RPDOs carry (decode reads it from the trace)
        rec.demand[:, i] = axes[a].cfg.scaling.position_to_device(plan.demand[:, i])
        _inside_drive_limits(axes[a], rec.demand[:, i])
    tpdo_cobs = {c.cob_id for a in plan.axes for c in axes[a].tpdos}
    handlers = {cob: h for cob, h in rec.handlers().items() if cob in tpdo_cobs}
    for cob, handler in handlers.items():
        if net.subscribers.get(cob):
            net.unsubscribe(cob)            # canopen's own PdoMap decoding is not needed here
        net.subscribe(cob, handler)
    feedback = _Feedback(axes, plan.axes)
    feedback.subscribe(net)
    send = net.send_message
    offsets: dict[str, _TorqueOffset] = {}
    codecs = [c for a in plan.axes for c in axes[a].rpdos]
    packers = [(a, _packer(axes[a], c, plan, i, send, offsets), CW_ENABLE_IP if axes[a].mode == IP else CW_ENABLE)
               for i, a in enumerate(plan.axes) for c in axes[a].rpdos]
    unloader = _Unloader(rec, axes, plan, offsets) if offsets else None
    sw_cols = [(a, rec.column(a, 0x6041)) for a in plan.axes]
    buffer_cols = {a: rec.column(a, 0x20C4) for a in plan.axes if (a, 0x20C4) in rec.columns}
    vel_cols = [(a, rec.column(a, 0x606C)) for a in plan.axes] if guard is not None else []
    misses = dict.fromkeys(plan.axes, 0)
    # around the plan, an interpolating drive's setpoint records stay off the bus: a FIFO (maxon's
    # PVT) would keep them and play them when interpolation starts
    cycles = _Cycles(link, [p for p, codec in zip(packers, codecs) if not _records_only(axes[p[0]], codec)],
                     feedback, plan.period)
    aborted = None
    k = sent = 0
    errors_at_start = link.bus_errors.count
    # The cycle collector stops every thread while it walks the heap (gen 2: tens of ms with
    # the object dictionaries loaded). Streaming frees its frames by reference counting, so
    # the collector is off while it runs (on the wall clock after one collection beforehand, in
    # lockstep, where no deadline waits, without: a full collection costs 0.1-0.3 s there).
    if link.threaded:
        gc.collect()
    gc.disable()
    priority, undo = raise_priority() if link.threaded else ("lockstep (no wall clock)", None)
    try:
        emcy_from = {a: len(axes[a].emcy) for a in plan.axes}
        for i, a in enumerate(plan.axes):
            _prepare(axes[a], int(rec.demand[0, i]))
            feedback.status[a] = axes[a].drive.statusword()      # where each starts from, read now
        for a in plan.axes:
            axes[a].node.nmt.send_command(0x01)              # operational: PDOs flow
        aborted = cycles.enable(state_timeout)
        log.info("enabled in the controlword in %d SYNC cycles%s", cycles.count,
                 f"; not: {aborted}" if aborted else "")
        if aborted is None and on_start is not None:
            on_start(cycles.enable_count)
        t0 = clock.now()
        for a in plan.axes:                                  # heartbeat supervision starts now
            if axes[a].last_heartbeat is None:
                axes[a].last_heartbeat = t0
        period = plan.period
        check_every = max(1, round(0.05 / period))
        for k in range(n if aborted is None else 0):
            clock.wait_until(t0 + k * period)
            if k >= FEEDBACK_LAG + 1:
                row = k - 1 - FEEDBACK_LAG
                aborted = _check_buffer(rec, row, buffer_cols) or \
                    _check_row(rec, row, axes, sw_cols, plan.axes, misses, miss_limit, emcy_from)
                if aborted is None and guard is not None and rec.got[row].all():
                    reason = guard({a: int(rec.raw[row, c]) for a, c in vel_cols})
                    if reason:
                        aborted = GuardStop(reason)
                if aborted is None and k % check_every == 0:
                    aborted = check_heartbeats(axes, plan.axes, clock.now(), heartbeat_timeout) or \
                        _check_bus(link, errors_at_start)
                if aborted is not None:
                    if aborted.axis in buffer_cols and aborted.emcy:   # the buffer status names what a vendor's
                        aborted = _buffer_cause(axes[aborted.axis]) or aborted   # EMCY code may not
                    break
                if progress is not None and k % 50 == 0:
                    progress(k)
            if unloader is not None:
                unloader.at(k)
            for _, packer, cw in packers:
                packer(k, cw)
            stamp = clock.now()
            rec.on_sync(stamp)
            feedback.on_sync()
            send(SYNC_COB_ID, b"", False, stamp)
            sent = k + 1
            if stamp - (t0 + k * period) > period / 2:
                t0 = stamp - k * period          # late: restart the schedule here, never burst SYNCs
        else:
            if aborted is None:
                k = n
                clock.sleep((FEEDBACK_LAG + 1) * period)
                for row in range(max(0, n - 1 - FEEDBACK_LAG), n):
                    aborted = aborted or _check_row(rec, row, axes, sw_cols, plan.axes, misses, miss_limit,
                                                    emcy_from)
    except KeyboardInterrupt as exc:
        aborted = Interrupted(signal=signal_name(exc))
    except MotionAborted as exc:
        aborted = exc
    except Exception as exc:          # a bus error mid-motion: still stop the axes
        aborted = MotionAborted(f"{type(exc).__name__}: {exc}")
    finally:
        for cob, handler in handlers.items():
            net.unsubscribe(cob, handler)
    rec.rows = min(rec.rows, sent)           # a row whose SYNC an interrupt kept from the bus is not one
    rec.truncate()
    missing = rec.missing()
    try:
        last = max(0, min(sent, n) - 1)
        log.info("%d of %d plan cycles sent; %s", sent, n, f"stopping: {aborted}" if aborted else "holding")
        if aborted is None:
            holding, problems = cycles.hold(axes, last, state_timeout)
        else:
            holding, problems = cycles.stop(axes, last, max(state_timeout, 2.0), miss_limit)
    finally:
        feedback.unsubscribe(net)
        restore_priority(undo)
        gc.enable()
    if problems:
        text = "; ".join(problems)
        if aborted is None:
            aborted = MotionAborted(text)
        elif isinstance(aborted, Interrupted):           # its reason says it was interrupted already
            aborted = Interrupted(text, aborted.signal)
        else:
            aborted = MotionAborted(f"{aborted.reason}; {text}", aborted.axis, aborted.emcy)
    timing = measure(rec.sync_time, plan.period, missing, wall=link.threaded, priority=priority, limits=timing_limits)
    return StreamResult(rec, sent, aborted, missing, timing, holding, cycles.enable_count)


def _inside_drive_limits(ax: AxisLink, demand: np.ndarray) -> None:
    """UserError before the first setpoint where the plan [device units] leaves the software
    position limits the drive holds (0x607D, as bring-up read it back)."""
    lo, hi = ax.drive_limits.get("0x607D:1"), ax.drive_limits.get("0x607D:2")
    if lo is None or hi is None or lo >= hi or not len(demand):
        return
    if demand.min() < lo or demand.max() > hi:
        sc = ax.cfg.scaling
        raise UserError(f"axis {ax.name}: the motion spans {float(sc.position_from_device(demand.min())):.4f} .. "
                        f"{float(sc.position_from_device(demand.max())):.4f} rad, outside the software position "
                        f"limits the drive holds (0x607D: {float(sc.position_from_device(lo)):.4f} .. "
                        f"{float(sc.position_from_device(hi)):.4f} rad); nothing was enabled or moved")


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
            raise MotionAborted(f"clearing the interpolation buffer (0x60C4:6) failed ({exc}); nothing was "
                                f"enabled", ax.name) from exc
    if ax.mode == CSP_MODE:
        try:
            actual = ax.node.sdo[0x6064].raw
            tolerance = max(1, round(ax.cfg.following_error_window_rad * ax.cfg.scaling.inc_per_rad / 2))
            if abs(actual - target) > tolerance:
                raise MotionAborted(f"the axis stands at {actual} (0x6064), not at the plan's start {target}: it "
                                    f"moved since the plan was made; nothing was enabled", ax.name)
            ax.node.sdo[0x607A].raw = actual
        except (canopen.SdoCommunicationError, canopen.SdoAbortedError) as exc:
            raise MotionAborted(f"setting the target position 0x607A to the actual position before enabling "
                                f"failed ({exc}); nothing was enabled", ax.name) from exc
    ax.drive.set_mode(ax.mode)


class _Cycles:
    """SYNC cycles outside the plan: the RPDOs carry one plan row (where the axis is to stand) and a
    controlword per axis, while the feedback decides when the drives are where they should be."""

    def __init__(self, link: Link, packers: list[tuple[str, Callable[[int, int], None], int]], feedback: _Feedback,
                 period: float):
        self.link, self.packers, self.feedback, self.period = link, packers, feedback, period
        self.count = 0                  # SYNCs sent so far outside the plan
        self.enable_count = 0

    def run(self, row: int, controlword: Callable[[str], int], done: Callable[[], bool], timeout: float) -> bool:
        """Cycle until ``done()`` (True) or ``timeout`` [s] (False)."""
        clock = self.link.clock
        t0 = clock.now()
        k = 0
        while not done():
            if clock.now() - t0 > timeout:
                return False
            clock.wait_until(t0 + k * self.period)
            for axis, packer, _ in self.packers:
                packer(row, controlword(axis))
            self.feedback.on_sync()
            self.link.network.send_message(SYNC_COB_ID, b"", False, clock.now())
            self.count += 1
            k += 1
        return True

    def enable(self, timeout: float) -> MotionAborted | None:
        """Shutdown, switch on, enable operation (from QUICK STOP ACTIVE: enable operation) in the
        controlword, a step each time the feedback shows the state before it."""
        fb = self.feedback
        axes = list(fb.status)
        ok = self.run(0, lambda a: ENABLE_STEP.get(fb.state(a) or "", CW_SHUTDOWN),
                      lambda: all(fb.state(a) == "OPERATION ENABLED" and fb.age[a] <= 1 for a in axes), timeout)
        self.enable_count = self.count
        if ok:
            return None
        late = next(a for a in axes if fb.state(a) != "OPERATION ENABLED")
        sw = fb.status[late]
        return MotionAborted(f"did not reach OPERATION ENABLED within {timeout} s of enabling in the controlword "
                             f"(it shows {fb.state(late) or 'no statusword'}" +
                             (f", statusword 0x{sw:04X})" if sw is not None else ")"), late)

    def _standing(self, ax: AxisLink, still: dict) -> bool:
        fb, a = self.feedback, ax.name
        status, velocity = fb.status[a], fb.velocity[a]
        stopped = fb.age[a] <= 1 and status is not None and velocity is not None and _at_rest(ax, status, velocity)
        still[a] = still[a] + 1 if stopped else 0
        return still[a] >= 2

    def stop(self, axes: dict[str, AxisLink], row: int, timeout: float, miss_limit: int
             ) -> tuple[dict[str, str], list[str]]:
        """Quick stop in every axis's controlword at once, SYNC until each stands still; then an axis
        that holds on its brake has its voltage disabled, one that holds ``enabled`` stays in QUICK STOP
        ACTIVE.  An axis whose feedback has stopped gets its quick stop by SDO."""
        fb = self.feedback
        names = list(fb.status)
        still = dict.fromkeys(names, 0)
        lost: set[str] = set()
        problems: list[str] = []
        start = self.count

        def done() -> bool:
            lost.update(a for a in names if fb.age[a] > miss_limit + FEEDBACK_LAG and self.count - start >= miss_limit)
            return all(a in lost or self._standing(axes[a], still) for a in names)
        try:
            if not self.run(row, lambda a: CW_QUICK_STOP_CMD, done, timeout):
                problems += [f"axis {a}: still moving {timeout} s after quick stop" for a in names
                             if a not in lost and still[a] < 2]
        except Exception:                            # the bus itself failed: SDO for every axis
            lost.update(names)
        if self.count == start:
            lost.update(names)
        if lost:
            problems += quick_stop(self.link, {a: axes[a] for a in sorted(lost)}, timeout)
        brake = [a for a in names if _on_brake(axes[a]) and a not in lost]
        if brake:
            try:
                self.run(row, lambda a: CW_DISABLE_VOLTAGE if a in brake else CW_QUICK_STOP_CMD,
                         lambda: all(fb.state(a) in ("SWITCH ON DISABLED", "FAULT") and fb.age[a] <= 1 for a in brake),
                         timeout)
            except Exception:
                pass
        return {a: holding_of(axes[a], fb.state(a)) for a in names}, problems

    def hold(self, axes: dict[str, AxisLink], row: int, timeout: float) -> tuple[dict[str, str], list[str]]:
        """After the plan: ``brake`` axes switched off (shutdown) onto their brake; ``enabled`` axes
        kept powered at their position, in profile position with halt where the drive has that mode
        (else in QUICK STOP ACTIVE, or interpolation off).  A CSP drive leaves the setpoint stream
        through a quick stop that holds where bring-up set one (0x605A = 6: no setpoint watchdog runs
        there, however long the SDOs that follow take), else its mode is switched by SDO right after
        the last SYNC; an interpolating one stops interpolating.  Then SYNC stops and profile position
        with halt is set by SDO (QUICK STOP ACTIVE → OPERATION ENABLED after a quick stop).  A CSP
        drive with neither is not held once the master is gone, and that is said."""
        fb = self.feedback
        names = list(fb.status)
        brake = [a for a in names if _on_brake(axes[a])]
        powered = [a for a in names if a not in brake]
        # a quick stop that holds (0x605A = 6, as bring-up wrote it) leaves CSP with no setpoint
        # watchdog left to run out; elsewhere halt, interpolation off, and (CSP) the mode switched fast
        qs_hold = {a for a in powered if axes[a].drive_limits.get("0x605A:0") == QUICK_STOP_RAMP_AND_HOLD}
        cw = {**{a: CW_SHUTDOWN for a in brake},
              **{a: CW_QUICK_STOP_CMD if a in qs_hold and axes[a].mode == CSP_MODE else CW_HALT for a in powered}}
        pp = [a for a in powered if PP in axes[a].modes]
        wanted = {a: ("READY TO SWITCH ON", "SWITCH ON DISABLED") if a in brake else
                  ("OPERATION ENABLED",) if cw[a] == CW_HALT else ("QUICK STOP ACTIVE",) for a in names}
        problems = []
        if not self.run(row, cw.__getitem__, lambda: all(fb.state(a) in wanted[a] and fb.age[a] <= 1 for a in names),
                        timeout):
            problems += [f"axis {a}: not held ({fb.state(a) or 'no statusword'} {timeout} s after the motion)"
                         for a in names if fb.state(a) not in wanted[a]]
        state = {a: fb.state(a) for a in names}
        for a in pp:                                 # SYNC has stopped
            drive = axes[a].drive
            try:
                drive.set_mode(PP)
                axes[a].node.sdo[0x6040].raw = CW_HALT
                state[a] = drive.state()
            except Exception as exc:                 # noqa: BLE001 - any failure: it holds as it is
                problems.append(f"axis {a}: could not hold it in profile position ({exc})")
                state[a] = drive.state()
        problems += [f"axis {a}: its drive has neither profile position nor a quick stop that holds: without the "
                     f"master's setpoints it is not held (give it holding: brake)" for a in powered
                     if a not in pp and cw[a] == CW_HALT and axes[a].mode == CSP_MODE]
        return {a: holding_of(axes[a], state[a]) for a in names}, problems


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
BUFFER_ERRORS = {0x0100: "its interpolation buffer ran empty (underflow: a record came late or not at all)",
                 0x0200: "its interpolation buffer overflowed (more records than it takes)",
                 0x0400: "an interpolated velocity above its maximal profile velocity 0x607F",
                 0x0800: "an interpolated acceleration above its maximal profile acceleration 0x60C5"}


def _check_buffer(rec: Recording, row: int, columns: dict[str, int]) -> MotionAborted | None:
    """The drive's interpolation buffer status, where a TPDO maps it: an error bit stops the run."""
    for axis, col in columns.items():
        if rec.got[row, rec.slots[axis]].all() and (error := _buffer_status_error(axis, int(rec.raw[row, col]))):
            return error
    return None


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


def _check_bus(link: Link, errors_at_start: int) -> MotionAborted | None:
    errors = link.bus_errors
    if errors.count > errors_at_start:
        return MotionAborted(f"the CAN interface reported {errors.count - errors_at_start} error frame(s) "
                             f"(bus errors, error passive or bus-off: check wiring, termination and bitrate)")
    return None


def _check_row(rec: Recording, row: int, axes: dict[str, AxisLink], sw_cols: list[tuple[str, int]], names: list[str],
               misses: dict[str, int], miss_limit: int, emcy_from: dict[str, int]) -> MotionAborted | None:
    got = rec.got[row].tolist()                            # a few Python bools: cheaper than numpy's
    for ai, name in enumerate(names):
        ax = axes[name]
        if len(ax.emcy) > emcy_from[name]:                 # an EMCY of this run (not of an earlier one)
            code = ax.emcy[-1][1]
            return MotionAborted(f"drive sent {emcy_text(code)} (EMCY 0x{code:04X})", name, code)
        if not all(got[slot] for slot in rec.slots[name]):
            misses[name] += 1
            if misses[name] >= miss_limit:
                return MotionAborted(f"no TPDO for {misses[name]} consecutive SYNC cycles", name)
            continue
        misses[name] = 0
        sw = int(rec.raw[row, sw_cols[ai][1]])
        if sw & SW_FAULT:
            return MotionAborted(f"drive reports {state_name(sw)} (statusword 0x{sw:04X})", name)
        if row >= FOLLOW_GRACE_ROWS and not sw & SW_FOLLOWING:
            what = ("interpolation is not active" if ax.mode == IP else "the drive does not follow the setpoints")
            return MotionAborted(f"{what} (statusword 0x{sw:04X}, bit 12 clear, in {state_name(sw)})", name)
    return None


def check_heartbeats(axes: dict[str, AxisLink], names: list[str], now: float, timeout: float) -> MotionAborted | None:
    """The first of ``names`` whose drive's heartbeat has been silent longer than ``timeout`` [s]."""
    for name in names:
        last = axes[name].last_heartbeat
        if last is not None and now - last > timeout:
            return MotionAborted(f"heartbeat lost (none for {now - last:.3f} s)", name)
    return None
