"""How the master reaches the bus: a canopen Network, its clock, and the raw trace.

:class:`Link` is the contract every master function takes.  :class:`BusLink`
is the real thing: a python-can bus (socketcan, pcan, kvaser, virtual, or the
simulator's process on udp_multicast), canopen's Notifier thread receiving,
and the wall clock.  The simulator's lockstep link fulfils the same contract;
nothing in the master knows which one it has (``tests/master/test_link.py``
runs one scenario over both).
"""

from __future__ import annotations

import bisect
import logging
import math
import os
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import replace
from typing import Protocol, runtime_checkable

import can
import canopen

from ..cia.buses import BusSpec
from ..errors import BusError
from ..interrupts import signal_name
from .blf import BatchedBLFWriter
from .coprocess import EngineError, EngineProcess, EngineThread, engine_for
from .engine import ROWS_SENT, STOP_REQUEST, Arrays, Job, Outcome, reporter, stop_code
from .timing import Clock, raise_priority

log = logging.getLogger(__name__)


class WallClock:
    """Real time: ``now`` is Unix time, like hardware frame time stamps."""

    now = staticmethod(time.time)

    @staticmethod
    def sleep(seconds: float) -> None:
        """Sleep.

        Parameters
        ----------
        seconds : float
            How long [s] (nothing for a negative time).
        """
        time.sleep(max(0.0, seconds))

    def wait_until(self, deadline: float) -> None:
        """Sleep until a time: one sleep, no spinning (a thread that polls with sleep(0) hands the
        GIL to the others and then waits a switch interval to get it back; Linux wakes within
        ~0.1 ms).

        Parameters
        ----------
        deadline : float
            Unix time [s].
        """
        left = deadline - time.time()
        if left > 0:
            time.sleep(left)


TRACE_PRIORITY = 10  # SCHED_FIFO priority of the trace writer (the streaming threads: 50)

#: zlib level of a BLF trace's containers: the fastest. A campaign's frames (48 bytes of BLF each,
#: mostly the same from one SYNC to the next) take a quarter of the CPU python-can's default (6)
#: takes, for a file 5 % larger -- CPU the drives and the master have on the wall clock
#: (docs/benchmarks.md)
TRACE_COMPRESSION = 1


REORDER_S = 0.5  # a background trace writes a frame once none older can still arrive: a
#                              simulated drive held up (its process stalled) stamps its replies up to its
#                              heartbeat consumer time in the past, and the master may drain the engine late


class TraceRecorder(can.Listener):
    """Recorder of every frame sent and received, in a python-can log format.

    Frames are written in time order with their time stamps plus ``epoch`` [s] (a lockstep
    link's clock starts at 0: the trace then reads as captured at the run's wall-clock start).
    With ``background`` (frames come from several threads) a frame is only queued where it is
    seen, and a writer thread of its own sorts, formats and compresses: the thread that sends
    setpoints never waits for the file.

    Parameters
    ----------
    path : str or os.PathLike
        The file; its suffix names the format (``.blf``, ``.asc``, ...).
    background : bool
        Frames come from several threads: a writer thread of its own writes them.
    flush_every_s : float
        How often that thread writes [s].
    epoch : float
        Added to every time stamp [s] (a lockstep link's start on the wall clock).
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        background: bool = False,
        flush_every_s: float = 0.05,
        epoch: float = 0.0,
    ):
        if background and epoch:
            raise ValueError("a background trace takes frames stamped with the wall clock (epoch 0)")
        blf = str(path).lower().endswith(".blf")
        self.writer = (
            BatchedBLFWriter(
                path, epoch=epoch, container_thread=not background, compression_level=TRACE_COMPRESSION
            )
            if blf
            else can.Logger(str(path))
        )
        self._background = background
        self._epoch = 0.0 if blf else epoch  # the BLF writer adds it itself
        #: frames stamped up to this came already from elsewhere (the cyclic engine's ring): not again
        self.seen_until = -math.inf
        if not background and not self._epoch:
            self.on_message_received = self.writer.on_message_received  # type: ignore[method-assign]
        if background:
            self._pending: deque[can.Message] = deque()
            self._held: list[can.Message] = []
            self._stopping = threading.Event()
            self._flush_every_s = flush_every_s
            self._thread = threading.Thread(target=self._write_loop, name="trace-writer", daemon=True)
            self._thread.start()

    def on_message_received(self, msg: can.Message) -> None:
        if self._background:
            if msg.timestamp > self.seen_until:
                self._pending.append(msg)  # atomic: no lock shared with the sending thread
        else:
            self._write(msg)

    def _write(self, msg: can.Message) -> None:
        if not self._epoch:
            self.writer.on_message_received(msg)
            return
        # on the one thread that holds the frame (a lockstep link): stamped for the file and back,
        # cheaper than a copy of each of a campaign's millions of frames
        stamp = msg.timestamp
        msg.timestamp = stamp + self._epoch
        try:
            self.writer.on_message_received(msg)
        finally:
            msg.timestamp = stamp

    def _write_loop(self) -> None:
        # Below the threads that send setpoints and receive feedback, but above every ordinary
        # process: a writer preempted by other load while it holds the GIL would hold them up too.
        if not raise_priority(TRACE_PRIORITY)[1]:
            try:
                os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), 10)
            except (AttributeError, OSError):
                pass  # not on this platform: the writer still only runs every flush period
        while not self._stopping.wait(self._flush_every_s):
            self._write_pending(final=False)
        self._write_pending(final=True)

    def _write_pending(self, final: bool) -> None:
        """Frames reach the queue from the sending and the receiving thread, not always in the
        order of their stamps: they are held until ``REORDER_S`` past the newest, then written
        sorted (all of them at the end)."""
        pending, held = self._pending, self._held
        while pending:
            held.append(pending.popleft())
        if not held:
            return
        held.sort(key=lambda m: m.timestamp)
        cut = (
            len(held)
            if final
            else bisect.bisect_right(held, held[-1].timestamp - REORDER_S, key=lambda m: m.timestamp)
        )
        for msg in held[:cut]:
            self._write(msg)
        del held[:cut]

    def stop(self) -> None:
        if self._background:
            self._stopping.set()
            self._thread.join()
        self.writer.stop()


class MasterNetwork(canopen.Network):
    """canopen Network that stamps sent frames with the link clock, records them
    to the trace, and lets a lockstep link run the other side after each send.

    Parameters
    ----------
    bus : can.BusABC
        The bus.
    clock : Clock
        The link's clock (frames are stamped with it).
    """

    #: [s] how long canopen's notifier thread waits in one ``recv`` (a frame ends the wait at
    #: once): closing the network joins the thread, which with canopen's 1 s held every
    #: command on a bus up to a second at its end (0.38 s on average, measured)
    NOTIFIER_CYCLE = 0.1

    def __init__(self, bus: can.BusABC, clock: Clock):
        super().__init__(bus)
        self.clock = clock
        self.traces: tuple[TraceRecorder, ...] = ()
        #: called with each frame's COB-ID once it is on the bus (a lockstep link runs the drives)
        self.after_send: Callable[[int], None] | None = None

    def send_message(
        self, can_id: int, data: bytes, remote: bool = False, timestamp: float | None = None
    ) -> None:
        """Send one frame stamped ``timestamp`` (default: now); it is traced before it
        goes on the bus, so the trace never shows a reply before its request."""
        msg = can.Message(
            arbitration_id=can_id,
            data=data,
            is_extended_id=can_id > 0x7FF,
            is_remote_frame=remote,
            is_rx=False,
            timestamp=self.clock.now() if timestamp is None else timestamp,
        )
        if self.bus is None:
            raise BusError("the CANopen network has no bus (not connected)")
        for trace in self.traces:
            trace.on_message_received(msg)
        with self.send_lock:
            self.bus.send(msg)
        if self.after_send is not None:
            self.after_send(can_id)


@runtime_checkable
class Link(Protocol):
    """What the master needs of its way to the drives.

    ``network`` is the canopen Network the master's nodes live on (every frame it sends is
    stamped with ``clock`` and traced); ``clock`` is the time the master waits on and stamps
    with; ``threaded`` says whether frames arrive on another thread (a trace must then be
    written in the background); ``epoch`` [s] is what makes the clock's time a wall-clock
    time (0 where the clock is the wall clock).
    """

    network: MasterNetwork
    threaded: bool
    epoch: float
    bus_errors: BusErrors

    @property
    def clock(self) -> Clock:
        """The time the master waits on and stamps with."""

    def add_trace(self, trace: TraceRecorder) -> None:
        """Send every frame from now on, sent and received, to a trace too.

        Parameters
        ----------
        trace : TraceRecorder
            The recorder (a python-can log file: BLF, ASC, ...).
        """

    def remove_trace(self, trace: TraceRecorder) -> None:
        """Stop sending frames to a trace.

        Parameters
        ----------
        trace : TraceRecorder
            A recorder :meth:`add_trace` was given.
        """

    def start_heartbeat(self, node_id: int, period: float) -> None:
        """Produce the master's heartbeat until the link closes, independent of what the master is
        busy with: the drives' heartbeat consumers stop the axes when it falls silent.

        Parameters
        ----------
        node_id : int
            The master's node id: the heartbeat's COB-ID is 0x700 + ``node_id`` (NMT state
            operational).
        period : float
            Its period [s].
        """

    def stop_heartbeat(self) -> None:
        """Stop the master's heartbeat (the drives then stop as if the master had died)."""

    def run_cycles(
        self,
        job: Job,
        fill: Callable[[Arrays], None],
        progress: Callable[[int], None] | None,
        on_start: Callable[[int], None] | None,
    ) -> tuple[Outcome, Arrays, str]:
        """Run the cyclic engine on a job: SYNC, setpoints and actual values every period.

        Parameters
        ----------
        job : Job
            The streamed motion as plain data: the axes, their PDOs, the plan's rows (one SYNC
            each) and what the engine supervises.
        fill : callable
            Writes the setpoint table into the engine's arrays before it starts.
        progress : callable or None
            Called with the plan's rows sent so far, now and then while the engine runs.
        on_start : callable or None
            Called once, with the SYNC cycles enabling took, when the plan's first row has gone
            out.

        Returns
        -------
        outcome : Outcome
            How the run ended: the rows sent, why it stopped, each axis's last statusword, the
            run's timing.
        arrays : Arrays
            The setpoints sent and the actual values received, per cycle.
        where : str
            Where it ran and what was granted it (a process of its own, SCHED_FIFO, ...).
        """

    def close(self) -> None:
        """Close the bus (and whatever runs behind it)."""


def heartbeat_frame(node_id: int, timestamp: float = 0.0) -> can.Message:
    """The master's heartbeat: NMT state operational (0x05).

    Parameters
    ----------
    node_id : int
        The master's node id.
    timestamp : float
        The frame's time stamp [s].

    Returns
    -------
    can.Message
        The frame (COB-ID 0x700 + node id).
    """
    return can.Message(
        arbitration_id=0x700 + node_id, data=b"\x05", is_extended_id=False, timestamp=timestamp
    )


class BusErrors(can.Listener):
    """Counts error frames the interface reports (bus errors, error passive, bus-off where it
    reports them as frames); the streaming loop stops the motion on the first."""

    def __init__(self) -> None:
        self.count = 0

    def on_message_received(self, msg: can.Message) -> None:
        if msg.is_error_frame:
            self.count += 1


class BusLink:
    """A python-can bus with canopen's Notifier thread and the wall clock; the cyclic engine on a
    handle of its own on the same bus (``spec``), in a process of its own where it can be.

    Parameters
    ----------
    bus : can.BusABC
        The master's bus (canopen's notifier reads it).
    spec : BusSpec
        How the engine opens a handle of its own on the same bus.
    """

    threaded = True  # frames arrive on the Notifier thread
    epoch = 0.0  # the clock is the wall clock
    POLL_S = 0.05  # how often the master drains the engine's trace ring and shows progress

    def __init__(self, bus: can.BusABC, spec: BusSpec):
        self.clock = WallClock()
        # CPython hands the GIL over every 5 ms by default: longer than a SYNC period. The
        # receiving thread must get it within a fraction of a period.
        sys.setswitchinterval(min(sys.getswitchinterval(), 0.001))
        self.bus = bus
        self.spec = spec
        self.network = MasterNetwork(self.bus, self.clock)
        self.network.connect()
        if self.network.notifier is None:
            raise BusError("canopen's network started no notifier")
        self.notifier: can.Notifier = self.network.notifier
        self.bus_errors = BusErrors()
        self.notifier.add_listener(self.bus_errors)
        self.on_close: list[Callable[[], None]] = []  # callbacks after the bus is closed
        self._heartbeat: can.broadcastmanager.CyclicSendTaskABC | None = None
        self._beat: tuple[int, float] | None = None  # the master's heartbeat: node id, period [s]
        #: the cyclic engine's host, started with the first stream and kept for the link's life
        self.engine: EngineProcess | EngineThread | None = None
        #: what runs the drives behind the bus, where the link started it (the simulated drives' process)
        self.simulator: object | None = None

    @classmethod
    def open(
        cls,
        interface: str,
        channel: str | int | None,
        bitrate: int | None = None,
        options: dict | None = None,
    ) -> BusLink:
        """A link on :func:`~drive_bridge.cia.buses.open_bus`.

        Parameters
        ----------
        interface : str
            python-can's interface name.
        channel : str or int, optional
            Its channel.
        bitrate : int, optional
            [bit/s].
        options : dict, optional
            The interface's own arguments.

        Returns
        -------
        BusLink
            The link, its network connected.
        """
        spec = BusSpec(interface, channel, bitrate, dict(options or {}))
        return cls(spec.open(), spec)

    def run_cycles(
        self,
        job: Job,
        fill: Callable[[Arrays], None],
        progress: Callable[[int], None] | None,
        on_start: Callable[[int], None] | None,
    ) -> tuple[Outcome, Arrays, str]:
        """:meth:`Link.run_cycles`: the engine in a process of its own where it can be (else a
        thread of this one), its trace ring drained into the traces every ``POLL_S``.

        Parameters
        ----------
        job : Job
            The streamed motion as plain data.
        fill : callable
            Writes the setpoint table into the engine's arrays.
        progress : callable or None
            Called with the plan's rows sent so far.
        on_start : callable or None
            Called once when the plan's first row has gone out.

        Returns
        -------
        outcome : Outcome
            How the run ended.
        arrays : Arrays
            The setpoints and actual values per cycle.
        where : str
            Where it ran and what was granted it.
        """
        if self.engine is None:
            self.engine = engine_for(self.spec)
        engine = self.engine
        beat = self._beat
        if beat is not None and isinstance(self._heartbeat, can.broadcastmanager.ThreadBasedCyclicSendTask):
            # a thread of this process that the master's other work can hold up (300 ms once: every drive
            # stopped): the engine beats while it runs
            self.stop_heartbeat()
            job = replace(job, heartbeat=(0x700 + beat[0], beat[1]))
        traces = self.network.traces
        for trace in traces:  # the engine's ring carries every frame while it runs
            self.notifier.remove_listener(trace)
        last = -math.inf  # the newest stamp the ring handed over
        try:
            arrays, ring = engine.start(job, fill)
            report = reporter(arrays, progress, on_start)
            outcome = None
            while outcome is None:
                try:
                    try:
                        outcome = engine.result(self.POLL_S)
                    finally:
                        for msg in ring.take():
                            last = max(last, msg.timestamp)
                            for trace in traces:
                                trace.on_message_received(msg)
                    report()
                except KeyboardInterrupt as exc:  # the engine stops the axes; wait for it to say so
                    arrays.control[STOP_REQUEST] = stop_code(signal_name(exc))
                except EngineError as exc:  # it is gone: the axes are stopped by SDO
                    log.error("%s", exc)
                    self.engine = None
                    engine.close()
                    outcome = Outcome(
                        abort=("error", None, str(exc), None),
                        lost=[a.name for a in job.axes],
                        rows_sent=int(arrays.control[ROWS_SENT]),
                    )
            if ring.dropped:
                log.warning(
                    "%d frames did not fit the engine's trace ring: the trace misses them", ring.dropped
                )
            return outcome, arrays, engine.description
        finally:
            if job.heartbeat is not None and beat is not None:
                self.start_heartbeat(*beat)
            for trace in traces:  # what this bus still holds of the engine's run is in the trace
                trace.seen_until = max(trace.seen_until, last)
                self.notifier.add_listener(trace)

    def add_trace(self, trace: TraceRecorder) -> None:
        """:meth:`Link.add_trace`.

        Parameters
        ----------
        trace : TraceRecorder
            The recorder.
        """
        self.network.traces += (trace,)
        self.notifier.add_listener(trace)

    def remove_trace(self, trace: TraceRecorder) -> None:
        """:meth:`Link.remove_trace`.

        Parameters
        ----------
        trace : TraceRecorder
            A recorder :meth:`add_trace` was given.
        """
        self.notifier.remove_listener(trace)
        self.network.traces = tuple(t for t in self.network.traces if t is not trace)

    def start_heartbeat(self, node_id: int, period: float) -> None:
        """:meth:`Link.start_heartbeat` by python-can's periodic send: the kernel's broadcast manager
        on socketcan, a thread of its own elsewhere (SCHED_FIFO where granted); either way it ends
        with this process, as a master's heartbeat must.

        Parameters
        ----------
        node_id : int
            The master's node id.
        period : float
            The heartbeat's period [s].
        """
        self.stop_heartbeat()
        self._beat = (node_id, period)
        self._heartbeat = self.bus.send_periodic(heartbeat_frame(node_id), period)
        thread = getattr(self._heartbeat, "thread", None)
        if thread is not None and thread.native_id is not None:
            # python-can's own thread: above ordinary processes, as the trace writer, or a load that
            # preempts it while it holds the GIL holds up the thread that streams the setpoints
            try:
                os.sched_setscheduler(thread.native_id, os.SCHED_FIFO, os.sched_param(TRACE_PRIORITY))
            except (AttributeError, OSError) as exc:  # not allowed here: it sends ten short frames a second
                log.debug("the heartbeat thread keeps its ordinary priority (%s)", exc)

    def stop_heartbeat(self) -> None:
        """:meth:`Link.stop_heartbeat`."""
        self._beat = None
        if self._heartbeat is not None:
            self._heartbeat.stop()
            self._heartbeat = None

    def close(self) -> None:
        """:meth:`Link.close`: the engine, the heartbeat, the network, then the callbacks."""
        if self.engine is not None:
            self.engine.close()
            self.engine = None
        self.stop_heartbeat()
        self.network.disconnect()
        for callback in self.on_close:
            callback()
