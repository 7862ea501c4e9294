"""Lockstep link: the master and the simulated drives share one thread.

After each frame the master sends, the drives handle everything on their bus
(a SYNC advances them one period) and the replies are fed to the master's
canopen Network at once, so an SDO request is answered before ``send``
returns.  Time is the simulation's: it moves with SYNC and with
``clock.sleep``, so runs are deterministic and faster than real time.  A trace
reads as captured from the wall-clock time the link was opened (``epoch``; the
``SOURCE_DATE_EPOCH`` convention fixes it, for traces identical run to run).
"""

from __future__ import annotations

import os
import time
from collections import deque
from collections.abc import Callable

import can
import numpy as np

from ..master.engine import Arrays, Engine, Handler, Job, Outcome, reporter
from ..master.link import BusErrors, MasterNetwork, TraceRecorder, heartbeat_frame
from . import kernel
from .adapters import FastVirtualBus
from .robot import SimRobot

SDO_REQUESTS = (0x601, 0x67F)  # COB-IDs of SDO requests to nodes 1-127 (the master's)


class LockstepClock:
    """Simulation time of ``robot``; sleeping lets the drives run without SYNC.

    Parameters
    ----------
    link : LockstepLink
        The link (its robot's time).
    """

    def __init__(self, link: LockstepLink):
        self._link = link

    def now(self) -> float:
        """The robot's time.

        Returns
        -------
        float
            [s].
        """
        return self._link.robot.time

    def sleep(self, seconds: float) -> None:
        """Let the robot run ``seconds`` without SYNC, its frames handed to the master.

        Parameters
        ----------
        seconds : float
            [s].
        """
        self._link.robot.idle(seconds)
        self._link.pump()

    def wait_until(self, deadline: float) -> None:
        """SYNC frames move time in lockstep; there is nothing to wait for.

        Parameters
        ----------
        deadline : float
            [s] (not waited for).
        """


class LinkPort:
    """The cyclic engine on a link's canopen network and clock: in lockstep, the simulated drives
    answer each frame before ``send`` returns (how the engine reaches the bus: :mod:`..master.port`).

    Parameters
    ----------
    link : LockstepLink
        The link.
    """

    sync_source = "lockstep (simulated time)"
    periodic_sync = False

    def __init__(self, link: LockstepLink):
        self.link = link
        self.now = link.clock.now
        self._subscribed: list[tuple[int, Callable[[int, bytearray, float], None]]] = []
        self._errors = link.bus_errors.count
        self._on_error: Callable[[], None] | None = None

    def wait_until(self, deadline: float) -> None:
        """:meth:`~drive_bridge.master.engine.Port.wait_until`: nothing to wait for; an error frame
        seen meanwhile is handed on.

        Parameters
        ----------
        deadline : float
            [s].
        """
        self.link.clock.wait_until(deadline)
        if self._on_error is not None and self.link.bus_errors.count > self._errors:
            self._errors = self.link.bus_errors.count
            self._on_error()

    def send(self, cob_id: int, data: bytes | bytearray, stamp: float) -> None:
        """:meth:`~drive_bridge.master.engine.Port.send`: the drives answer before it returns.

        Parameters
        ----------
        cob_id : int
            Its COB-ID.
        data : bytes or bytearray
            Its data.
        stamp : float
            Its time stamp [s].
        """
        self.link.network.send_message(cob_id, bytes(data), False, stamp)

    def receive(self, handlers: dict[int, Handler], on_error_frame: Callable[[], None]) -> None:
        """:meth:`~drive_bridge.master.engine.Port.receive`: subscribed on the canopen network.

        Parameters
        ----------
        handlers : dict of int to Handler
            COB-ID -> ``handler(data, timestamp)``.
        on_error_frame : callable
            Called for each error frame.
        """
        net = self.link.network
        for cob_id, handler in handlers.items():

            def on_frame(can_id: int, data: bytearray, stamp: float, handler: Handler = handler) -> None:
                handler(data, stamp)

            net.subscribe(cob_id, on_frame)
            self._subscribed.append((cob_id, on_frame))
        self._on_error = on_error_frame

    def start_sync(self, period: float, counter: int = 0) -> None:
        """Not in lockstep: the engine sends SYNC itself (``periodic_sync`` is False).

        Parameters
        ----------
        period : float
            [s].
        counter : int
            The counter's overflow value.

        Raises
        ------
        NotImplementedError
            Always.
        """
        raise NotImplementedError("in lockstep the engine sends SYNC itself")

    def wait_sync(self, timeout_at: float) -> None:
        """Not in lockstep: the engine sends SYNC itself.

        Parameters
        ----------
        timeout_at : float
            [s].

        Raises
        ------
        NotImplementedError
            Always.
        """
        raise NotImplementedError("in lockstep the engine sends SYNC itself")

    def stop_sync(self) -> None:
        """The engine sends SYNC itself: nothing to stop."""

    def release(self) -> None:
        """:meth:`~drive_bridge.master.engine.Port.release`: unsubscribed."""
        for cob_id, callback in self._subscribed:
            self.link.network.unsubscribe(cob_id, callback)
        self._subscribed.clear()
        self._on_error = None


class LockstepLink:
    """Master side of the virtual bus, pumped synchronously with ``robot``.

    Parameters
    ----------
    robot : SimRobot
        The simulated robot, on its own in-process bus.
    channel : str
        The virtual bus's channel.

    Raises
    ------
    ValueError
        A robot not on a FastVirtualBus.
    """

    threaded = False  # every frame is seen on the calling thread

    def __init__(self, robot: SimRobot, channel: str = "drive-bridge"):
        self.epoch = float(os.environ.get("SOURCE_DATE_EPOCH") or time.time())
        self.robot = robot
        self.clock = LockstepClock(self)
        self.bus = FastVirtualBus(channel=channel, preserve_timestamps=True)
        if not isinstance(robot.bus, FastVirtualBus):
            raise ValueError(
                "a lockstep link runs the robot on its own in-process bus (robot.bus a FastVirtualBus)"
            )
        self.bus.direct = robot.bus.direct = True  # one thread: hand frames over as they are
        self.network = MasterNetwork(self.bus, self.clock)
        self.network.after_send = self._after_send
        self._notify = self.network.notify
        self.bus_errors = BusErrors()  # a virtual bus has none; the contract has them
        self._heartbeat: Callable[[float], None] | None = None
        #: the master's heartbeats handed to the drives while the robot advanced, for the trace: written
        #: there in time order with the drives' frames of the same stretch (:meth:`pump`)
        self._beats: deque[can.Message] = deque()
        robot.power_on()
        self.pump()

    def add_trace(self, trace: TraceRecorder) -> None:
        """:meth:`~drive_bridge.master.link.Link.add_trace`.

        Parameters
        ----------
        trace : TraceRecorder
            The recorder.
        """
        self.network.traces += (trace,)

    def remove_trace(self, trace: TraceRecorder) -> None:
        """:meth:`~drive_bridge.master.link.Link.remove_trace` (the heartbeats until now written first).

        Parameters
        ----------
        trace : TraceRecorder
            A recorder :meth:`add_trace` was given.
        """
        self._trace_beats(self.robot.time)
        self.network.traces = tuple(t for t in self.network.traces if t is not trace)

    def _trace_beats(self, until: float) -> None:
        """Trace the master's heartbeats stamped up to ``until`` [s]."""
        beats, traces = self._beats, self.network.traces
        while beats and beats[0].timestamp <= until:
            msg = beats.popleft()
            for trace in traces:
                trace.on_message_received(msg)

    def _after_send(self, cob_id: int) -> None:
        if SDO_REQUESTS[0] <= cob_id <= SDO_REQUESTS[1]:
            # a drive answers an SDO request on one of its loop ticks, not in no time: a trace of
            # the start-up reads as the bus carried it (and a replay keeps its pace)
            self.robot.idle(kernel.VELOCITY_TICK_S)
        self.robot.process()
        self.pump()

    def pump(self) -> None:
        """Deliver every frame waiting for the master to its canopen Network (a frame the
        drives sent without a time stamp gets the time the master sees it)."""
        notify, traces, now = self._notify, self.network.traces, self.robot.time
        for msg in self.bus.drain():
            if not msg.timestamp:
                msg.timestamp = now
            if self._beats:
                self._trace_beats(msg.timestamp)
            for trace in traces:
                trace.on_message_received(msg)
            notify(msg.arbitration_id, msg.data, msg.timestamp)
        self._trace_beats(now)

    def start_heartbeat(self, node_id: int, period: float) -> None:
        """In simulation time: each beat is handed to the drives at the instant it is due while the
        robot advances, however long the master waits (and to the trace in time order, :meth:`pump`).

        Parameters
        ----------
        node_id : int
            The master's node id.
        period : float
            The heartbeat's period [s].
        """
        self.stop_heartbeat()
        due = [self.robot.time]

        def beat(now: float) -> None:
            while now >= due[0] - 1e-9:
                msg = heartbeat_frame(node_id, due[0])
                self._beats.append(msg)
                self.robot.dispatch(msg)
                due[0] += period

        self._heartbeat = beat
        self.robot.timers.append(beat)
        beat(self.robot.time)

    def stop_heartbeat(self) -> None:
        """:meth:`~drive_bridge.master.link.Link.stop_heartbeat`."""
        if self._heartbeat is not None:
            self.robot.timers.remove(self._heartbeat)
            self._heartbeat = None

    def run_cycles(
        self,
        job: Job,
        fill: Callable[[Arrays], None],
        progress: Callable[[int], None] | None,
        on_start: Callable[[int], None] | None,
    ) -> tuple[Outcome, Arrays, str]:
        """The cyclic engine on this thread, in simulation time.

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
            ``lockstep``.
        """
        arrays = Arrays(job, np.zeros)
        fill(arrays)
        outcome = Engine(job, arrays, LinkPort(self), on_check=reporter(arrays, progress, on_start)).run()
        return outcome, arrays, "lockstep (no wall clock)"

    def close(self) -> None:
        """:meth:`~drive_bridge.master.link.Link.close`: the heartbeat, the bus, the robot."""
        self.stop_heartbeat()
        self.bus.shutdown()
        self.robot.shutdown()
