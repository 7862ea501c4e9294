"""The cyclic engine: SYNC, the RPDOs of each period, TPDO capture and the supervision decisions of
a streamed motion, from enabling the drives to holding or stopping them.

The engine knows nothing of canopen's objects, the configuration or the files: it runs a
:class:`Job` (plain data: the PDO layouts, what each RPDO field carries, per-axis constants in
device units, the limits written to the drives) over a :class:`Port` (how frames leave and
arrive, and the time), writing into arrays made before motion (:class:`Arrays`).  The same code
runs in lockstep (in the master's thread, simulated time) and on the wall clock (in a process of
its own: :mod:`.coprocess`).

Schedule.  Period ``k`` starts at ``t0 + k * period`` (an absolute monotonic schedule).  At its
start the SYNC goes out, then, inside the synchronous window, the RPDOs the drives take at the
next SYNC.  A SYNC goes out within half a period of its period's start or not at all: a cycle
that starts later sends the SYNC of the period whose start is within half a period (waiting for
the next one's), never the ones it missed, so no two SYNCs are closer than half a period (a
drive's answer to one would reach the bus after the next, and its interpolation would see a
period of a few microseconds).  The plan rows of missed periods get no SYNC (``sync_time`` NaN),
and the setpoints that follow are those of their own time.  Where the interface sends SYNC itself
(the kernel's broadcast manager), the engine answers each SYNC as the bus hands it over; SYNCs handed
over together are answered once, the last (the others are counted ``setpoints_late``), and one that
does not come is waited for as long as the drives wait for setpoints.

Supervision is judged in time.  A drive must answer a SYNC within the synchronous window
(0x1007, or the period where none is written).  A row's feedback is judged once the bus shows
that window has passed: a frame from the drives stamped later, or, where none comes, the
engine's own clock past the heartbeat consumer time (then nothing is heard at all).  A drive
whose feedback stays missing for longer than ``feedback_timeout_s`` stops the run; a late master
(a cycle that did not start on time) is never counted as a drive's silence, and where the drives
stop because the master's setpoints stopped longer than their own timeout, the run says the
master was late.

The cyclic path does not grow: every array is allocated before motion, no container is appended
to, and it neither logs nor writes files (the host turns the outcome into words and files).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from ..cia.p301 import SYNC_COB_ID
from ..cia.p402 import (
    CW_DISABLE_VOLTAGE,
    CW_ENABLE,
    CW_HALT,
    CW_QUICK_STOP,
    CW_SHUTDOWN,
    CW_SWITCH_ON,
    SW_FAULT,
    SW_FOLLOWING,
    state_name,
)

#: the controlword that takes a drive one step nearer OPERATION ENABLED from the state it shows
ENABLE_STEP = {
    "SWITCH ON DISABLED": CW_SHUTDOWN,
    "READY TO SWITCH ON": CW_SWITCH_ON,
    "SWITCHED ON": CW_ENABLE,
    "OPERATION ENABLED": CW_ENABLE,
    "QUICK STOP ACTIVE": CW_ENABLE,
}
HEARTBEAT_OPERATIONAL = b"\x05"  # the master's heartbeat: NMT state operational
#: SYNCs of the plan after its first by which the drive must show statusword bit 12 (following / IP
#: active): SYNCs, not rows -- where the master woke late at the plan's start, its first rows passed
#: without one, and the drive was told nothing in them
FOLLOW_GRACE_SYNCS = 2
#: how often [s] the engine checks the drives' heartbeats, the bus's error frames and its stop request
CHECK_EVERY_S = 0.05
#: a gap this long between two turns of the engine's loop (which waits CHECK_EVERY_S at most) is
#: the host holding the engine up: the time is not the drives' silence [s]
AWAY_S = 0.1
INT16 = (-(2**15), 2**15 - 1)
#: kinds of an RPDO field: the controlword, a column of the setpoint table, a constant, a column of
#: the torque offsets (less what the velocity loop holds at rest, see :attr:`AxisJob.torque_Nm_per_raw`)
FIELD_CONTROLWORD, FIELD_TABLE, FIELD_CONSTANT, FIELD_TORQUE_OFFSET = range(4)
#: the engine's phases (shared with the host through ``Arrays.control``)
ENABLING, STREAMING, HOLDING, STOPPING, SWITCHING_OFF, ENDED = range(6)
#: slots of ``Arrays.control`` (int64): what the host reads while the engine runs, and its stop request
PHASE, ROWS_SENT, STOP_REQUEST, ENABLE_CYCLES, CONTROL_SLOTS = range(5)
#: stop requests in ``STOP_REQUEST``: none, or the signal that asked for it
STOP_SIGNALS = ("", "Ctrl-C", "SIGTERM", "SIGHUP")
AGE_BIN_S, AGE_BINS = 1e-4, 1000  # histogram of feedback age: 0.1 ms bins up to 100 ms
PROGRESS_ROWS = 50  # the host's progress is told the plan row in steps of this many
#: records a period and axis fed into a drive's FIFO at most (one is taken a period): a refill
#: after a stall comes back two records a period faster than the drive takes them, never a flood
FEED_PER_PERIOD = 3
#: the plan's last rows in which a FIFO found empty, every record fed, is the plan's end (a drive
#: whose interpolation began a SYNC before the engine's row 0 takes its last record a row early)
PLAN_END_ROWS = 2
#: what a port hands each received frame to: (data, time stamp [s])
Handler = Callable[[bytes | bytearray, float], None]


# ---------------------------------------------------------------------------------------- the job
@dataclass(frozen=True)
class RpdoJob:
    """One RPDO.

    Parameters
    ----------
    cob_id : int
        Its COB-ID.
    format : str
        Its struct format.
    fields : tuple of (int, int)
        What each field carries: ``(kind, argument)``.
    axis : int
        Its axis, an index into :attr:`Job.axes`.
    around_plan : bool
        Also sent while enabling, holding and stopping (not: interpolation data records).
    ahead : bool
        Records fed ahead into the drive's FIFO (:attr:`AxisJob.ahead`), not one per SYNC.
    """

    cob_id: int
    format: str
    fields: tuple[tuple[int, int], ...]
    axis: int
    around_plan: bool = True
    ahead: bool = False


@dataclass(frozen=True)
class TpdoJob:
    """One TPDO: its values go to ``raw[row, first:first + count]``, its arrival to ``got[row, slot]``.

    Parameters
    ----------
    cob_id : int
        Its COB-ID.
    format : str
        Its struct format.
    first : int
        Its first column of ``raw``.
    slot : int
        Its column of ``got``.
    axis : int
        Its axis, an index into :attr:`Job.axes`.
    """

    cob_id: int
    format: str
    first: int
    slot: int
    axis: int


@dataclass(frozen=True)
class AxisJob:
    """What the engine needs of one axis, in the drive's units.

    Parameters
    ----------
    name : str
        The axis.
    node_id : int
        Its node id.
    slots : tuple of int
        Its TPDOs' columns of ``got``: a row is complete when all arrived.
    statusword : int
        Its statusword's column of ``raw``.
    velocity : int
        Its velocity actual's column of ``raw`` (-1: not mapped).
    torque : int
        Its torque feedback's column of ``raw`` (-1: not mapped).
    buffer_status : int
        The column of maxon's interpolation buffer status 0x20C4:1 (-1: none).
    position_column : int
        The column of the setpoint table that holds its position [increments].
    enable_controlword : int
        The controlword during the plan (interpolated position: + bit 4).
    interpolating : bool
        Streamed in interpolated position mode.
    standstill : float
        |velocity actual| at or below this is standing [velocity units].
    on_brake : bool
        Held switched off onto its brake.
    quick_stop_holds : bool
        0x605A = 6: a quick stop holds the axis powered (leaves CSP safely).
    csp : bool
        Streamed in cyclic synchronous position mode.
    torque_Nm_per_raw : float
        Where the master sends a torque offset: at each move start the torque the velocity loop
        holds at rest (feedback [raw] × Nm per raw unit, in per mille of the rated torque) is taken
        out of the offsets (0: not done).
    rated_torque_Nm : float
        The drive's rated torque [Nm].
    move_starts : tuple of int
        The plan rows where moves start.
    velocity_guard : float
        |velocity actual| beyond this stops the run [velocity units].
    ahead : int
        Records kept ahead in the drive's interpolation FIFO (0: one setpoint per SYNC): the plan's
        rows go out ahead of the SYNCs that take them, at most ``FEED_PER_PERIOD`` a period.
    fill : int
        The column of the FIFO's fill 0x60C4:2 in ``raw`` (-1: not mapped).
    stride : int
        Plan rows one record fed ahead spans (a PVT record's own time; the record of its last row
        goes out, carrying that time).
    tail : (int, int)
        Records fed after the plan's last, and the record (a drive that faults on an empty buffer,
        maxon's PVT: the plan's end held for longer than a stall at the end lasts, until the
        master's hold words end interpolation); (0, 0): none.
    """

    name: str
    node_id: int
    slots: tuple[int, ...]
    statusword: int
    velocity: int
    torque: int = -1
    buffer_status: int = -1
    position_column: int = -1
    enable_controlword: int = CW_ENABLE
    interpolating: bool = False
    standstill: float = 0.0
    on_brake: bool = False
    quick_stop_holds: bool = False
    csp: bool = True
    torque_Nm_per_raw: float = 0.0
    rated_torque_Nm: float = 1.0
    move_starts: tuple[int, ...] = ()
    velocity_guard: float = math.inf
    ahead: int = 0
    fill: int = -1
    stride: int = 1
    tail: tuple[int, int] = (0, 0)


@dataclass(frozen=True)
class Supervision:
    """The time limits the engine judges by, and what they come from (written into the drives at
    bring-up, or the drive profile's own).

    Parameters
    ----------
    period_s : float
        The SYNC period = 0x1006 [s].
    window_s : float
        The synchronous window 0x1007 [s] (the period where none is written).
    feedback_timeout_s : float
        A drive's feedback missing this long stops the run [s].
    setpoint_timeout_s : float
        The drives stop on their own after this long without setpoints [s].
    heartbeat_timeout_s : float
        A node silent this long is lost [s] (the wall-clock backstop).
    state_timeout_s : float
        Enabling, holding [s].
    stop_timeout_s : float
        Quick stop until standing still [s].
    sources : dict of str to str
        Where each limit comes from.
    """

    period_s: float
    window_s: float
    feedback_timeout_s: float
    setpoint_timeout_s: float
    heartbeat_timeout_s: float
    state_timeout_s: float
    stop_timeout_s: float
    sources: dict[str, str] = field(default_factory=dict)

    def as_dict(self) -> dict:
        """meta.yaml's ``supervision``.

        Returns
        -------
        dict
            Each limit in ms, and where it comes from (``sources``).
        """
        out: dict = {
            k: round(getattr(self, k) * 1e3, 3)
            for k in (
                "period_s",
                "window_s",
                "feedback_timeout_s",
                "setpoint_timeout_s",
                "heartbeat_timeout_s",
            )
        }
        out = {k.replace("_s", "_ms"): v for k, v in out.items()}
        out["sources"] = dict(self.sources)
        return out


@dataclass(frozen=True)
class Job:
    """A streamed motion as plain data: what :class:`Engine` runs.

    Parameters
    ----------
    axes : tuple of AxisJob
        The axes.
    rpdos, tpdos : tuple of RpdoJob, TpdoJob
        Their PDOs.
    rows : int
        The plan's rows (one SYNC each, on time).
    columns : int
        Of ``raw``.
    table_columns : int
        Of the setpoint table.
    supervision : Supervision
        The time limits the engine judges by.
    heartbeat : (int, float), optional
        The master's heartbeat the engine sends while it runs: COB-ID, period [s].
    sync_from : str, optional
        The drive that produces SYNC while the engine runs, in words (None: the interface or the
        engine sends it).
    sync_counter : int
        The SYNC counter's overflow value every node holds (0x1019; 0: SYNC without a counter): each
        SYNC carries its count 1..``sync_counter``, and a gap in those received is SYNCs lost.
    """

    axes: tuple[AxisJob, ...]
    rpdos: tuple[RpdoJob, ...]
    tpdos: tuple[TpdoJob, ...]
    rows: int
    columns: int
    table_columns: int
    supervision: Supervision
    #: the master's heartbeat (COB-ID, period [s]) where the engine is to produce it while it runs (the
    #: link's own is a thread of the master's process there, which the master's other work can hold up)
    heartbeat: tuple[int, float] | None = None
    sync_from: str | None = None
    sync_counter: int = 0


class Arrays:
    """Every array the engine writes or reads, made before motion by the host (plain memory in
    lockstep, one shared mapping for an engine in its own process): the setpoint table (what the
    RPDOs carry per plan row), the TPDO values and arrivals per row, the position each drive took at
    each SYNC, the SYNC time stamps (NaN: no SYNC in that period), the torque held back per axis, the
    feedback age histogram and the control slots the host reads and writes while the engine runs.

    Parameters
    ----------
    job : Job
        The job (the arrays' sizes).
    allocate : callable
        ``allocate(shape, dtype)``: plain memory, or a shared mapping.
    """

    table: np.ndarray
    raw: np.ndarray
    got: np.ndarray
    demand: np.ndarray
    sync_time: np.ndarray
    torque_offset: np.ndarray
    ages: np.ndarray
    control: np.ndarray

    def __init__(self, job: Job, allocate: Callable[[tuple[int, ...], type], np.ndarray]):
        for name, shape, dtype in self.layout(job):
            setattr(self, name, allocate(shape, dtype))
        self.sync_time[:] = np.nan

    @staticmethod
    def layout(job: Job) -> list[tuple[str, tuple[int, ...], type]]:
        """(name, shape, type) of each array, in the order they are allocated.

        Parameters
        ----------
        job : Job
            The job.

        Returns
        -------
        list of (str, tuple of int, type)
            The layout.
        """
        n = job.rows
        return [
            ("table", (n, max(1, job.table_columns)), np.int64),
            ("raw", (n, max(1, job.columns)), np.int64),
            ("got", (n, max(1, len(job.tpdos))), np.bool_),
            ("demand", (n, len(job.axes)), np.int64),
            ("sync_time", (n,), np.float64),
            ("torque_offset", (len(job.axes),), np.int64),
            ("ages", (AGE_BINS + 1,), np.int64),
            ("control", (CONTROL_SLOTS,), np.int64),
        ]


@dataclass
class Outcome:
    """How a run ended, for the host to turn into words: the rows sent, why it stopped (``abort``:
    kind, axis, detail, EMCY code), each axis's last statusword, the axes whose feedback was gone
    (the host stops those by SDO), problems while stopping or holding, and the run's timing.

    Parameters
    ----------
    rows_sent : int
        The plan's rows sent.
    enable_cycles : int
        The SYNC cycles enabling took.
    abort : (str, str or None, str, int or None), optional
        Why it stopped: kind, axis, detail, EMCY code.
    statuswords : dict of str to int or None
        Each axis's last statusword.
    lost : list of str
        The axes whose feedback was gone.
    problems : list of str
        Problems while stopping or holding.
    late_cycles : int
        Cycles that started more than half a period late.
    periods_skipped : int
        Periods that got no SYNC (a late cycle sends the one whose start is within half a period).
    setpoints_late : int
        Interface-sent SYNCs the engine had sent no new setpoints before.
    syncs_lost : int
        SYNCs the counter says were sent and never reached the engine.
    worst_wake_ms : float
        The latest a cycle started after its deadline [ms].
    largest_sync_gap_ms : float
        The largest gap between two SYNCs [ms].
    sync_source : str
        What sent SYNC, in words.
    """

    rows_sent: int = 0
    enable_cycles: int = 0
    abort: tuple[str, str | None, str, int | None] | None = None
    statuswords: dict[str, int | None] = field(default_factory=dict)
    lost: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    late_cycles: int = 0
    periods_skipped: int = 0
    setpoints_late: int = 0
    syncs_lost: int = 0
    worst_wake_ms: float = 0.0
    largest_sync_gap_ms: float = 0.0
    sync_source: str = ""


def stop_code(signal_name: str) -> int:
    """The ``STOP_REQUEST`` value of a stop asked for by ``signal_name`` (Ctrl-C, SIGTERM, SIGHUP).

    Parameters
    ----------
    signal_name : str
        Ctrl-C, SIGTERM or SIGHUP.

    Returns
    -------
    int
        The value (1 for another name).
    """
    return STOP_SIGNALS.index(signal_name) if signal_name in STOP_SIGNALS else 1


def reporter(
    arrays: Arrays, progress: Callable[[int], None] | None, on_start: Callable[[int], None] | None
) -> Callable[[], None]:
    """What the host calls now and then while the engine runs: ``on_start`` (once, with the SYNC
    cycles enabling took) when the plan's first row has gone out, ``progress`` with the rows sent.

    Parameters
    ----------
    arrays : Arrays
        The engine's arrays (its control slots are read).
    progress : callable or None
        Called with the rows sent.
    on_start : callable or None
        Called once with the SYNC cycles enabling took.

    Returns
    -------
    callable
        What the host calls.
    """
    started = [on_start is None]
    shown = [-1]
    control = arrays.control

    def report() -> None:
        if control[PHASE] != STREAMING:
            return
        rows = int(control[ROWS_SENT])
        if not started[0] and rows > 0:
            started[0] = True
            on_start(int(control[ENABLE_CYCLES]))  # type: ignore[misc]
        row = (rows - 1) // PROGRESS_ROWS * PROGRESS_ROWS
        if progress is not None and row > shown[0]:
            shown[0] = row
            progress(row)

    return report


# ---------------------------------------------------------------------------------------- the port
class Port(Protocol):
    """How the engine reaches the bus.  ``receive`` is given the handler table once; frames that
    arrive are handed to ``handlers[cob_id](data, timestamp)`` while the engine waits (``wait_until``)
    or, in lockstep, as soon as the frame that caused them was sent."""

    sync_source: str
    #: the interface sends SYNC itself (the kernel's broadcast manager, an adapter's periodic send): the
    #: engine takes each SYNC as the bus shows it and sends the RPDOs after it
    periodic_sync: bool

    def now(self) -> float:
        """The time [s] frames are stamped in."""

    def start_sync(self, period: float, counter: int = 0) -> None:
        """Let the interface send SYNC every ``period`` [s] (``periodic_sync`` only), with the counter
        1..``counter`` where it is not 0.

        Parameters
        ----------
        period : float
            The SYNC period [s].
        counter : int
            The counter's overflow value (0: none).
        """

    def wait_sync(self, timeout_at: float) -> None:
        """Hand over frames until a SYNC has been seen, and every frame queued behind it (SYNCs handed
        over late come in one call), or until ``timeout_at`` (``periodic_sync`` only).

        Parameters
        ----------
        timeout_at : float
            The latest time [s, :meth:`now`'s].
        """

    def stop_sync(self) -> None:
        """Stop the interface's SYNC, where it was started (a no-op otherwise)."""

    def wait_until(self, deadline: float) -> None:
        """Return at ``deadline``, handing over every frame that arrives meanwhile.

        Parameters
        ----------
        deadline : float
            [s, :meth:`now`'s].
        """

    def send(self, cob_id: int, data: bytes | bytearray, stamp: float) -> None:
        """Send one frame stamped ``stamp`` [s] (taken just before, from :meth:`now`).

        Parameters
        ----------
        cob_id : int
            Its COB-ID.
        data : bytes or bytearray
            Its data.
        stamp : float
            Its time stamp [s].
        """

    def receive(self, handlers: dict[int, Handler], on_error_frame: Callable[[], None]) -> None:
        """From now on, hand received frames to ``handlers`` by COB-ID, error frames to ``on_error_frame``.

        Parameters
        ----------
        handlers : dict of int to Handler
            COB-ID -> ``handler(data, timestamp)``.
        on_error_frame : callable
            Called for each error frame.
        """

    def release(self) -> None:
        """Hand no more frames to the handlers."""


# ---------------------------------------------------------------------------------------- the engine
class Engine:
    """Runs one :class:`Job` over ``port``: enable, stream, then hold, or stop on the first fault.

    Parameters
    ----------
    job : Job
        The job.
    arrays : Arrays
        Its arrays.
    port : Port
        How it reaches the bus.
    on_check : callable, optional
        Called after a period's frames are out whenever the engine checks its watches (about every
        ``CHECK_EVERY_S``): the host's own checks in lockstep.
    """

    def __init__(self, job: Job, arrays: Arrays, port: Port, on_check: Callable[[], None] | None = None):
        self.job, self.arrays, self.port = job, arrays, port
        #: called every ``CHECK_EVERY_S`` of the engine's time (lockstep: the host's progress, on this thread)
        self.on_check = on_check
        sup = job.supervision
        self.period = sup.period_s
        n_axes = len(job.axes)
        self.status: list[int | None] = [None] * n_axes
        self.velocity: list[int | None] = [None] * n_axes
        self.age = [0] * n_axes  # SYNCs since each axis's last statusword
        self.heard = [0.0] * n_axes  # engine time of each drive's last frame (any)
        self.sync_read = -math.inf  # engine time the last SYNC was read (or sent)
        self.turned = -math.inf  # engine time of the loop's last turn (:meth:`_turn`)
        self.beat = [0.0] * n_axes  # engine time of each drive's last heartbeat
        self.last_complete = [math.inf] * n_axes  # SYNC time of each axis's last complete row
        self.emcy: tuple[int, int] | None = None  # (axis, code) of the first EMCY of this run
        self.bus_errors = 0
        self.evidence = -math.inf  # newest time stamp of a frame from the drives
        self.judged = 0  # rows before this are judged
        self.judged_syncs = 0  # SYNCs of the plan among them
        self.row = -1  # plan row of the last SYNC (-1: none yet)
        self.pending = [0] * n_axes  # position the last RPDO carried, per axis
        self.outcome = Outcome(sync_source=port.sync_source)
        self.phase = ENABLING
        self.start = self.phase_start = self.next_check = self.t0 = 0.0
        self.slot = 0  # periods since the first SYNC
        self.plan_slot = 0  # the period of plan row 0
        self.last_sync = -math.inf
        self.enable_cycles = 0
        self.still = [0] * n_axes  # fresh standstill readings in a row, per axis
        self.check_due = False
        self.fence = math.inf  # time stamp of the first SYNC after the plan's rows
        self.syncs_seen = 0
        #: the SYNC frames' data in turn (the counter 1..N, or none) and the count of the last one
        self._sync_data = [bytes([k]) for k in range(1, job.sync_counter + 1)] or [b""]
        self.count = 0
        self.next_beat = -math.inf  # when the master's heartbeat is due (job.heartbeat)
        self._rpdos = [
            (r, struct.Struct(r.format), bytearray(struct.calcsize(r.format)), [0] * len(r.fields))
            for r in job.rpdos
        ]
        self._ahead = [entry for entry in self._rpdos if entry[0].ahead]
        self.fed = [0] * n_axes  # plan rows written into each axis's FIFO
        self._starts = [set(a.move_starts) for a in job.axes]
        #: per axis, the setpoint table's column of the torque offsets it is sent (-1: none)
        self._offset_columns = [
            next(
                (
                    arg
                    for r in job.rpdos
                    if r.axis == axis
                    for kind, arg in r.fields
                    if kind == FIELD_TORQUE_OFFSET
                ),
                -1,
            )
            for axis in range(n_axes)
        ]

    # ------------------------------------------------------------------ receiving
    def handlers(self) -> dict[int, Handler]:
        """COB-ID -> handler of every frame the engine listens to.

        Returns
        -------
        dict of int to Handler
            COB-ID -> ``handler(data, timestamp)``.
        """
        out: dict[int, Handler] = {}
        for tpdo in self.job.tpdos:
            out[tpdo.cob_id] = self._tpdo_handler(tpdo)
        for i, ax in enumerate(self.job.axes):
            out[0x080 + ax.node_id] = self._emcy_handler(i)
            out[0x700 + ax.node_id] = self._heartbeat_handler(i)
        if self.port.periodic_sync:
            out[SYNC_COB_ID] = self._on_sync_frame
        return out

    def _tpdo_handler(self, tpdo: TpdoJob) -> Handler:
        unpack, size = struct.Struct(tpdo.format).unpack_from, struct.calcsize(tpdo.format)
        first, slot, axis = tpdo.first, tpdo.slot, tpdo.axis
        ax = self.job.axes[axis]
        last = first + len(struct.Struct(tpdo.format).unpack(bytes(size)))
        sw_at = ax.statusword - first if first <= ax.statusword < last else -1
        vel_at = ax.velocity - first if first <= ax.velocity < last else -1
        raw, got, sync_time, ages = self.arrays.raw, self.arrays.got, self.arrays.sync_time, self.arrays.ages
        port = self.port

        def on_tpdo(data: bytes | bytearray, stamp: float) -> None:
            if len(data) < size:
                return
            values = unpack(data)
            self.heard[axis] = port.now()
            if stamp > self.evidence:
                self.evidence = stamp
            if sw_at >= 0:
                self.status[axis] = values[sw_at]
                self.age[axis] = 0
            if vel_at >= 0:
                self.velocity[axis] = values[vel_at]
            if stamp >= self.fence:  # it answers a SYNC after the plan's last
                return
            row = self.row
            # the row of the newest SYNC before the frame reached the bus, among rows not judged yet
            while row >= self.judged and (sync_time[row] != sync_time[row] or stamp < sync_time[row]):
                row -= 1
            if row >= self.judged:
                raw[row, first:last] = values
                got[row, slot] = True
                age = port.now() - stamp
                ages[min(AGE_BINS, max(0, int(age / AGE_BIN_S)))] += 1

        return on_tpdo

    def _emcy_handler(self, axis: int) -> Handler:
        def on_emcy(data: bytes | bytearray, stamp: float) -> None:
            self.heard[axis] = self.port.now()
            code = int.from_bytes(data[:2], "little") if len(data) >= 2 else 0
            if code and self.emcy is None:  # code 0: error reset, no error
                self.emcy = (axis, code)

        return on_emcy

    def _heartbeat_handler(self, axis: int) -> Handler:
        def on_heartbeat(data: bytes | bytearray, stamp: float) -> None:
            self.heard[axis] = self.beat[axis] = self.port.now()
            if stamp > self.evidence:
                self.evidence = stamp

        return on_heartbeat

    def _on_error_frame(self) -> None:
        self.bus_errors += 1

    # ------------------------------------------------------------------ sending
    def _send_rpdos(
        self, row: int, controlwords: list[int], records: bool, stamp: float | None = None
    ) -> None:
        """The RPDOs the drives take at the next SYNC: ``row`` of the setpoint table, a controlword
        per axis (``records``: also interpolation records, which a drive's FIFO would otherwise keep),
        stamped ``stamp`` where given (else when each goes)."""
        table, offsets = self.arrays.table, self.arrays.torque_offset
        send = self.port.send
        now = self.port.now if stamp is None else lambda: stamp
        for rpdo, codec, buffer, values in self._rpdos:
            if rpdo.ahead or not (records or rpdo.around_plan):
                continue
            axis = rpdo.axis
            for i, (kind, arg) in enumerate(rpdo.fields):
                if kind == FIELD_CONTROLWORD:
                    values[i] = controlwords[axis]
                elif kind == FIELD_TABLE:
                    values[i] = int(table[row, arg])
                elif kind == FIELD_TORQUE_OFFSET:
                    values[i] = max(INT16[0], min(INT16[1], int(table[row, arg]) - int(offsets[axis])))
                else:
                    values[i] = arg
            codec.pack_into(buffer, 0, *values)
            send(rpdo.cob_id, buffer, now())
        for axis, ax in enumerate(self.job.axes):
            if ax.position_column >= 0:
                self.pending[axis] = int(table[row, ax.position_column])

    def _feed(self, taken: int) -> bool:
        """Each buffered axis's buffer topped up to its ``ahead`` rows past the ``taken`` plan rows
        (at most :data:`FEED_PER_PERIOD` records this period, each the record of the last row it
        spans); True when every one holds them."""
        job, table, send, now = self.job, self.arrays.table, self.port.send, self.port.now
        for rpdo, codec, buffer, values in self._ahead:
            axis = rpdo.axis
            ax = job.axes[axis]
            wanted = min(job.rows, taken + ax.ahead)
            if wanted == job.rows:  # the plan's last record is due: the tail after it
                wanted += ax.tail[0]
            for _ in range(FEED_PER_PERIOD):
                row = self.fed[axis]
                if row >= wanted:
                    break
                if row < job.rows:  # a record of the plan: its last row's (past it, the tail's)
                    row = min(job.rows, row + ax.stride) - 1
                for i, (kind, arg) in enumerate(rpdo.fields):
                    if kind != FIELD_TABLE:
                        values[i] = arg
                    else:
                        values[i] = int(table[row, arg]) if row < job.rows else ax.tail[1]
                codec.pack_into(buffer, 0, *values)
                send(rpdo.cob_id, buffer, now())
                self.fed[axis] = row + 1
        return all(
            self.fed[rpdo.axis] >= min(job.rows, taken + job.axes[rpdo.axis].ahead)
            for rpdo, *_ in self._ahead
        )

    def _unload(self, row: int) -> None:
        """Before the RPDOs of plan ``row``: at a move start, what the velocity loop holds at rest (the
        torque actual less the offset sent, on the newest judged row) is taken out of the offsets."""
        job, arrays = self.job, self.arrays
        ref = row - 2  # the newest row whose feedback has arrived (in lockstep, always)
        if ref < 1:
            return
        for axis, ax in enumerate(job.axes):
            if (
                ax.torque_Nm_per_raw
                and row in self._starts[axis]
                and all(arrays.got[ref, s] for s in ax.slots)
            ):
                sent = self._offset_columns[axis]
                held = round(
                    float(arrays.raw[ref, ax.torque]) * ax.torque_Nm_per_raw / ax.rated_torque_Nm * 1000
                )
                before = max(
                    INT16[0],
                    min(INT16[1], int(arrays.table[ref - 1, sent]) - int(arrays.torque_offset[axis])),
                )
                arrays.torque_offset[axis] = held - before

    # ------------------------------------------------------------------ judging
    def _judge(self, now: float) -> tuple[str, str | None, str, int | None] | None:
        """Judge every row whose synchronous window the bus has passed; the first fault found.

        The bus's own time says so: a frame from the drives stamped past the row's window.  Only
        where nothing at all came for longer than the heartbeat timeout does the engine's clock
        stand in (the drives gone quiet): a burst of frames stamped in the past -- a drive held up
        and sending what it owes, a receive buffer drained after a stall -- is judged by its
        stamps, each row once the frames after it are in, never before its own TPDOs are read."""
        job, arrays, sup = self.job, self.arrays, self.job.supervision
        sync_time, got, raw = arrays.sync_time, arrays.got, arrays.raw
        evidence = self.evidence
        drive_sync = self.sync_read if job.sync_from is not None else -math.inf  # (not the kernel's)
        if now - max(*self.heard, drive_sync) > sup.heartbeat_timeout_s:
            evidence = max(evidence, now - sup.heartbeat_timeout_s)
        while self.judged <= self.row:
            r = self.judged
            t = sync_time[r]
            if t != t:  # no SYNC in that period: nothing was asked of the drives
                self.judged += 1
                continue
            if evidence < t + sup.window_s:
                break
            self.judged += 1
            self.judged_syncs += 1
            for axis, ax in enumerate(job.axes):
                if not all(got[r, s] for s in ax.slots):
                    silent = t - self.last_complete[axis]
                    if silent > sup.feedback_timeout_s:
                        return (
                            "silent",
                            ax.name,
                            f"no feedback for {silent * 1e3:.0f} ms (its TPDOs missing "
                            f"since the SYNC at row {r}; the limit is {sup.feedback_timeout_s * 1e3:.0f} ms)",
                            None,
                        )
                    continue
                self.last_complete[axis] = t
                sw = int(raw[r, ax.statusword])
                if sw & SW_FAULT:
                    return ("fault", ax.name, f"drive reports {state_name(sw)} (statusword 0x{sw:04X})", None)
                if (
                    self.judged_syncs > FOLLOW_GRACE_SYNCS
                    and not sw & SW_FOLLOWING
                    and not self._taken_all(axis, r)
                ):
                    left = int(raw[r, ax.fill]) if ax.ahead and ax.fill >= 0 else -1
                    if left == 0:  # its FIFO ran dry: a planned stop
                        return ("dry", ax.name, str(r), None)
                    what = (
                        "interpolation is not active"
                        if ax.interpolating
                        else "the drive does not follow the setpoints"
                    )
                    if left > 0:  # records waiting: the drive did not take interpolation up
                        what += f" with {left} records in its FIFO"
                    return (
                        "following",
                        ax.name,
                        f"{what} (statusword 0x{sw:04X}, bit 12 clear, in {state_name(sw)})",
                        None,
                    )
                if ax.buffer_status >= 0 and int(raw[r, ax.buffer_status]) & 0x0F00:
                    return ("buffer", ax.name, f"0x{int(raw[r, ax.buffer_status]):04X}", None)
                if ax.velocity >= 0 and abs(int(raw[r, ax.velocity])) > ax.velocity_guard:
                    return ("guard", ax.name, str(int(raw[r, ax.velocity])), None)
        return None

    def _taken_all(self, axis: int, row: int) -> bool:
        """The axis, fed ahead, was fed every record of the plan and ``row`` is one of its last
        :data:`PLAN_END_ROWS`: a FIFO empty there is the plan's end (it ends at rest, where the
        drive's planned stop holds it), not a master that was away."""
        ax = self.job.axes[axis]
        return bool(ax.ahead) and self.fed[axis] >= self.job.rows and row >= self.job.rows - PLAN_END_ROWS

    def _watch(self, now: float, stop_request: int) -> tuple[str, str | None, str, int | None] | None:
        """What is judged in time rather than per row: EMCY, a node's heartbeat, error frames, a stop."""
        if self.emcy is not None:
            axis, code = self.emcy
            return ("emcy", self.job.axes[axis].name, "", code)
        if stop_request:
            return ("interrupt", None, STOP_SIGNALS[min(stop_request, len(STOP_SIGNALS) - 1)], None)
        if self.bus_errors:
            return ("bus", None, str(self.bus_errors), None)
        limit = self.job.supervision.heartbeat_timeout_s
        for axis, ax in enumerate(self.job.axes):
            if now - self.beat[axis] > limit:
                return ("heartbeat", ax.name, f"{now - self.beat[axis]:.3f}", None)
        return None

    # ------------------------------------------------------------------ the loop
    def run(self) -> Outcome:
        """Enable, stream every row, hold; on a fault, a stop request (a signal included) or any
        failure, quick-stop every axis in the controlword and cycle until each stands still (where
        the cyclic path itself failed, every axis is left to the host to stop by SDO).

        Returns
        -------
        Outcome
            How the run ended.
        """
        job, port, out, control = self.job, self.port, self.outcome, self.arrays.control
        port.receive(self.handlers(), self._on_error_frame)
        try:
            self.start = self.phase_start = self.next_check = port.now()
            self.heard = [self.start] * len(job.axes)
            self.beat = [self.start] * len(job.axes)
            self.turned = self.start
            self._enter(ENABLING, self.start)
            # the first RPDOs: the run's SYNCs are those stamped after them (a SYNC the bus had
            # before, read only now, is not one -- nor is it in the trace, where decode counts them)
            self._send_rpdos(0, self._enable_words(), records=False, stamp=self.start)
            self.t0 = port.now()
            if port.periodic_sync:
                port.start_sync(self.period, job.sync_counter)
            while True:
                try:
                    done = self._cycle()
                    if self.check_due:  # after the period's frames are out
                        self.check_due = False
                        self.on_check()  # type: ignore[misc]
                    if done:
                        break
                except KeyboardInterrupt as exc:  # lockstep: the signal arrives on this thread
                    control[STOP_REQUEST] = stop_code(getattr(exc, "name", "Ctrl-C"))
        except Exception as exc:  # noqa: BLE001 - stop the axes, say why
            out.abort = out.abort or ("error", None, f"{type(exc).__name__}: {exc}", None)
            out.lost = [a.name for a in job.axes]
        finally:
            port.stop_sync()
            port.release()
            control[PHASE] = ENDED
        out.statuswords = {a.name: self.status[i] for i, a in enumerate(job.axes)}
        return out

    def _enter(self, phase: int, now: float) -> None:
        self.phase = phase
        self.phase_start = now
        self.arrays.control[PHASE] = phase

    def _cycle(self) -> bool:
        """One period: its SYNC (sent at its start, or seen on the bus where the interface sends it), judge,
        send the RPDOs of the next; True when done."""
        job, arrays, port, out = self.job, self.arrays, self.port, self.outcome
        period, control = self.period, arrays.control
        if port.periodic_sync:
            seen = self.syncs_seen
            now = self._await_sync()  # (each of its turns taken)
            late = now - self.last_sync  # the RPDOs that follow go out this long after their SYNC
            out.worst_wake_ms = max(out.worst_wake_ms, late * 1e3)
            if late > job.supervision.window_s:
                out.late_cycles += 1  # past the window: the drives keep the setpoints they have
            if not self._ahead or len(self._ahead) < len(job.axes):
                out.setpoints_late += self.syncs_seen - seen - 1  # SYNCs that came before their setpoints
        else:
            now, late = self._wake()
            self._turn(now)
            out.worst_wake_ms = max(out.worst_wake_ms, late * 1e3)
            if late > period / 2:
                out.late_cycles += 1
            while late > period / 2:  # the period whose start is within half a period (passed, or
                # the next one's, waited for -- and again if held up meanwhile): the missed ones get
                # no SYNC, and no two SYNCs come closer than half a period
                behind = max(1, round(late / period))
                self.slot += behind
                out.periods_skipped += behind
                now, late = self._wake()
            stamp = port.now()
            self._on_sync(stamp)  # (before it goes: in lockstep the replies come at once)
            port.send(SYNC_COB_ID, self._sync_data[self.count], stamp)
            self.count = (self.count + 1) % len(self._sync_data)
        if job.heartbeat is not None and now >= self.next_beat:  # the master's heartbeat, no burst when late
            cob_id, beat = job.heartbeat
            port.send(cob_id, HEARTBEAT_OPERATIONAL, port.now())
            self.next_beat = max(self.next_beat + beat, now)
        # ---- judge, then decide the next period
        abort = None
        if self.emcy is not None:  # an EMCY names the cause the statusword shows after it
            abort = self._watch(now, 0)
        if abort is None and self.phase in (STREAMING, HOLDING):
            abort = self._judge(now)
        if abort is None and (control[STOP_REQUEST] or now >= self.next_check):
            self.next_check = now + CHECK_EVERY_S
            abort = self._watch(now, int(control[STOP_REQUEST]))
            self.check_due = self.on_check is not None
        if abort is not None and self.phase in (ENABLING, STREAMING, HOLDING):
            out.abort = abort
            self._enter(STOPPING, now)
        if self.phase == ENABLING:
            return self._enabling(now)
        if self.phase == STREAMING:
            nxt = self.slot - self.plan_slot
            if nxt < job.rows:
                self._unload(nxt)
                self._send_rpdos(nxt, [a.enable_controlword for a in job.axes], records=True)
                self._feed(nxt)
                return False
            self._enter(HOLDING, now)  # the plan's last SYNC went out: hold from the next
        if self.phase == HOLDING:
            return self._holding(now)
        if self.phase == STOPPING:
            return self._stopping(now)
        return self._switching_off(now)

    def _await_sync(self) -> float:
        """Wait for the interface's next SYNC (``periodic_sync``); the time it was handed over [s].

        A SYNC may come late -- the interface or the producing drive held up, or its frame handed
        over late (the kernel's softirqs behind a real-time task, an emulated vCPU): the drives then
        keep the setpoints they have and wait for new ones as long as their setpoint-loss timeout,
        or take the records fed ahead.  So the engine waits as long as the longer of these (the gap
        is judged with the timing).
        Meanwhile it looks every :data:`CHECK_EVERY_S` for what :meth:`_watch` judges: where that
        asks for a stop, or where no SYNC came for longer, the cyclic path cannot act (its RPDOs take
        effect at a SYNC) and ends, leaving every axis to the host to stop by SDO.
        """
        port, control, out = self.port, self.arrays.control, self.outcome
        seen = self.syncs_seen
        first = self.last_sync == -math.inf  # (where start_sync did not see one)
        # since the last SYNC came: its stamp, or later where it was read later (a burst a drive
        # sends of SYNCs it owes after being held up is read over some ms, stamped in the past)
        since = port.now() if first else max(self.last_sync, self.sync_read)
        sup = self.job.supervision
        # (a SYNC from elsewhere may come late, and the ones it owes then: the drives stop on their own
        # after their setpoint timeout, or once the records fed ahead run out)
        ahead = max((a.ahead for a in self.job.axes), default=0) * self.period
        limit = 1.0 if first else max(3 * self.period, sup.setpoint_timeout_s, ahead)
        while True:
            port.wait_sync(min(since + limit, port.now() + CHECK_EVERY_S))
            now = port.now()
            since += self._turn(now)  # (the engine held up: no SYNC's absence)
            if self.syncs_seen != seen:
                return now
            out.abort = out.abort or self._watch(now, int(control[STOP_REQUEST]))
            if out.abort is not None:
                raise RuntimeError("a stop while the interface sent no SYNC")  # (the abort says why)
            if now >= since + limit:
                raise RuntimeError(
                    f"no SYNC from {port.sync_source} for {(now - since) * 1e3:.0f} ms"
                    + ("" if first else f", longer than the drives wait for setpoints ({limit * 1e3:.0f} ms)")
                )

    def _turn(self, now: float) -> float:
        """A turn of the engine's loop at ``now``: where the host held the engine up since the last
        (a gap over :data:`AWAY_S`), the time it was away is not the drives' silence nor their
        slowness -- when each was last heard, its last heartbeat, the last SYNC read and the
        phase's start move on by it (a host that stops every process, the drives' stand-ins among
        them, leaves them nothing to send until it lets them go); that time [s], else 0."""
        gap, self.turned = now - self.turned, now
        if gap <= AWAY_S:
            return 0.0
        # (never past now: what was read as the engine ran again is news, not old)
        self.heard = [min(t + gap, now) for t in self.heard]
        self.beat = [min(t + gap, now) for t in self.beat]
        self.sync_read = min(self.sync_read + gap, now)
        self.phase_start = min(
            self.phase_start + gap, now
        )  # (nor the drives' slowness to enable, hold or stop)
        return gap

    def _wake(self) -> tuple[float, float]:
        """Wait for the start of period ``slot`` on the absolute schedule: the time then, and how
        late that is [s]."""
        deadline = self.t0 + self.slot * self.period
        self.port.wait_until(deadline)
        now = self.port.now()
        return now, now - deadline

    def _on_sync(self, stamp: float) -> None:
        """A SYNC at ``stamp``: the row of the period (while streaming), the feedback's age."""
        job, arrays, out = self.job, self.arrays, self.outcome
        if self.phase == STREAMING and self.slot - self.plan_slot >= job.rows:
            # a late cycle past the plan's end: the plan's last periods had no SYNC -- rows of the
            # recording like any period skipped (no sample, counted missing), not rows it never had
            out.rows_sent = job.rows
            arrays.control[ROWS_SENT] = job.rows
            self._enter(HOLDING, stamp)
        row = self.slot - self.plan_slot if self.phase == STREAMING else -1
        for axis in range(len(job.axes)):
            self.age[axis] += 1
        if self.last_sync > -math.inf:
            out.largest_sync_gap_ms = max(out.largest_sync_gap_ms, (stamp - self.last_sync) * 1e3)
        self.last_sync = stamp
        self.sync_read = self.port.now()
        self.syncs_seen += 1
        if row >= 0:
            if self.row < 0:  # a drive's silence counts from the plan's first SYNC (row 0, or a
                # later one where the master woke late at the plan's start)
                self.last_complete = [stamp] * len(job.axes)
            arrays.sync_time[row] = stamp
            arrays.demand[row] = self.pending
            for axis, ax in enumerate(job.axes):
                if ax.ahead and row < self.fed[axis]:  # its FIFO's record of this SYNC, fed in order
                    arrays.demand[row, axis] = arrays.table[row, ax.position_column]
            self.row = row
            out.rows_sent = row + 1
            arrays.control[ROWS_SENT] = row + 1
        elif self.phase == ENABLING:
            self.enable_cycles += 1
        elif self.row >= 0 and self.fence == math.inf:
            self.fence = stamp  # feedback from here on belongs to no plan row
        self.slot += 1

    def _on_sync_frame(self, data: bytes | bytearray, stamp: float) -> None:
        """The SYNC the interface or a drive sent, as the bus shows it (its stamp); where it carries
        the counter, the SYNCs its count skipped are lost ones: their periods pass without a row."""
        if stamp < self.start:  # before the first RPDO: not a SYNC of this run
            return
        overflow = self.job.sync_counter
        if overflow and data:
            if self.count:
                lost = (data[0] - self.count - 1) % overflow
                self.slot += lost
                self.outcome.syncs_lost += lost
            self.count = data[0]
        self._on_sync(stamp)

    def _enabling(self, now: float) -> bool:
        job, out, sup = self.job, self.outcome, self.job.supervision
        if self._all(lambda a: self._state(a) == "OPERATION ENABLED" and self.age[a] <= 1):
            # the FIFOs filled before interpolation starts; and where a drive keeps time, started in a
            # period the engine answers early in (bit 4 sent late would be taken a SYNC after row 0's:
            # every row's record a period off) -- for half the state timeout at most
            answer_late = (
                now - self.last_sync > self.period / 2 and now - self.phase_start < sup.state_timeout_s / 2
            )
            if not self._feed(0) or (self._ahead and self.port.periodic_sync and answer_late):
                self._send_rpdos(0, self._enable_words(), records=False)
                return False
            out.enable_cycles = self.enable_cycles
            self.arrays.control[ENABLE_CYCLES] = self.enable_cycles
            self._enter(STREAMING, now)
            self.plan_slot = self.slot
            self._unload(0)
            self._send_rpdos(0, [a.enable_controlword for a in job.axes], records=True)
        elif now - self.phase_start > sup.state_timeout_s:
            late = next(a for a in range(len(job.axes)) if self._state(a) != "OPERATION ENABLED")
            sw = self.status[late]
            out.abort = (
                "enable",
                job.axes[late].name,
                f"did not reach OPERATION ENABLED within "
                f"{sup.state_timeout_s} s of enabling in the controlword (it shows "
                f"{self._state(late) or 'no statusword'}"
                + (f", statusword 0x{sw:04X})" if sw is not None else ")"),
                None,
            )
            self._enter(STOPPING, now)
            return self._stopping(now)
        else:
            self._send_rpdos(0, self._enable_words(), records=False)
        return False

    def _holding(self, now: float) -> bool:
        job, out, sup = self.job, self.outcome, self.job.supervision
        wanted = self._hold_words()
        if self.judged > self.row and self._all(
            lambda a: self._state(a) in _HELD[wanted[a]] and self.age[a] <= 1
        ):
            return True
        if now - self.phase_start > sup.state_timeout_s:
            out.problems += [
                f"axis {ax.name}: not held ({self._state(a) or 'no statusword'} {sup.state_timeout_s} s "
                f"after the motion)"
                for a, ax in enumerate(job.axes)
                if self._state(a) not in _HELD[wanted[a]]
            ]
            return True
        self._send_rpdos(max(0, self.row), wanted, records=False)
        return False

    def _stopping(self, now: float) -> bool:
        job, out, sup = self.job, self.outcome, self.job.supervision
        if self._stopped(now - self.phase_start):
            if not any(ax.on_brake and ax.name not in out.lost for ax in job.axes):
                return True
            self._enter(SWITCHING_OFF, now)
            return self._switching_off(now)
        if now - self.phase_start > sup.stop_timeout_s:
            out.problems += [
                f"axis {ax.name}: still moving {sup.stop_timeout_s} s after quick stop"
                for a, ax in enumerate(job.axes)
                if ax.name not in out.lost and self.still[a] < 2
            ]
            return True
        self._send_rpdos(max(0, self.row), [CW_QUICK_STOP] * len(job.axes), records=False)
        return False

    def _switching_off(self, now: float) -> bool:
        """After a quick stop: an axis that holds on its brake has its voltage disabled."""
        job, sup = self.job, self.job.supervision
        brake = [a for a, ax in enumerate(job.axes) if ax.on_brake and ax.name not in self.outcome.lost]
        if (
            all(self._state(a) in ("SWITCH ON DISABLED", "FAULT") and self.age[a] <= 1 for a in brake)
            or now - self.phase_start > sup.state_timeout_s
        ):
            return True
        self._send_rpdos(
            max(0, self.row),
            [CW_DISABLE_VOLTAGE if a in brake else CW_QUICK_STOP for a in range(len(job.axes))],
            records=False,
        )
        return False

    # ------------------------------------------------------------------ helpers
    def _state(self, axis: int) -> str | None:
        sw = self.status[axis]
        return None if sw is None else state_name(sw)

    def _all(self, test: Callable[[int], bool]) -> bool:
        return all(test(a) for a in range(len(self.job.axes)))

    def _enable_words(self) -> list[int]:
        """Shutdown, switch on, enable operation: a step each time the feedback shows the state before."""
        return [ENABLE_STEP.get(self._state(a) or "", CW_SHUTDOWN) for a in range(len(self.job.axes))]

    def _hold_words(self) -> list[int]:
        """After the plan: a brake axis shut down; a powered CSP axis whose quick stop holds leaves the
        stream through it; any other halts (profile position with halt follows by SDO)."""
        return [
            CW_SHUTDOWN if ax.on_brake else CW_QUICK_STOP if ax.quick_stop_holds and ax.csp else CW_HALT
            for ax in self.job.axes
        ]

    def _stopped(self, elapsed: float) -> bool:
        """Each axis standing still on two fresh statuswords in a row, or lost (its feedback gone longer
        than the feedback timeout, judged after that long in the stop)."""
        sup, out, still = self.job.supervision, self.outcome, self.still
        for axis, ax in enumerate(self.job.axes):
            if ax.name in out.lost:
                continue
            gone = self.port.now() - self.heard[axis] > sup.feedback_timeout_s or (
                self.status[axis] is None and elapsed > sup.feedback_timeout_s
            )
            if gone and elapsed > sup.feedback_timeout_s:
                out.lost.append(ax.name)
                continue
            sw, v = self.status[axis], self.velocity[axis]
            at_rest = (
                self.age[axis] <= 1
                and sw is not None
                and state_name(sw) != "OPERATION ENABLED"
                and (v is None or abs(v) <= ax.standstill)
            )
            still[axis] = still[axis] + 1 if at_rest else 0
        return all(ax.name in out.lost or still[a] >= 2 for a, ax in enumerate(self.job.axes))


#: the states each hold controlword leaves an axis in
_HELD = {
    CW_SHUTDOWN: ("READY TO SWITCH ON", "SWITCH ON DISABLED"),
    CW_HALT: ("OPERATION ENABLED",),
    CW_QUICK_STOP: ("QUICK STOP ACTIVE",),
}
