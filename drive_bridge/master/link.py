"""How the master reaches the bus: a canopen Network, its clock, and the raw trace.

:class:`Link` is the contract every master function takes.  :class:`BusLink`
is the real thing: a python-can bus (socketcan, pcan, kvaser, virtual, or the
simulator's process on udp_multicast), canopen's Notifier thread receiving,
and the wall clock.  The simulator's lockstep link fulfils the same contract;
nothing in the master knows which one it has (``tests/master/test_link.py``
runs one scenario over both).
"""
from __future__ import annotations

import os
import sys
import threading
import time
from collections import deque
from typing import Protocol, runtime_checkable

import can
import canopen

from .timing import raise_priority


class Clock(Protocol):
    def now(self) -> float:
        """Time stamp [s] used for frames and logs."""

    def sleep(self, seconds: float) -> None:
        """Let ``seconds`` pass (the link keeps receiving meanwhile)."""

    def wait_until(self, deadline: float) -> None:
        """Return when ``now() >= deadline``, yielding the CPU meanwhile."""


class WallClock:
    """Real time: ``now`` is Unix time, like hardware frame time stamps."""

    now = staticmethod(time.time)

    @staticmethod
    def sleep(seconds: float) -> None:
        time.sleep(max(0.0, seconds))

    def wait_until(self, deadline: float) -> None:
        # One sleep, no spinning: a thread that polls with sleep(0) hands the GIL to the
        # others and then waits a switch interval to get it back. Linux wakes within ~0.1 ms.
        left = deadline - time.time()
        if left > 0:
            time.sleep(left)


TRACE_PRIORITY = 10           # SCHED_FIFO priority of the trace writer (the streaming threads: 50)


class TraceRecorder(can.Listener):
    """Recorder of every frame sent and received, in a python-can log format.

    With ``background`` (frames come from several threads) a frame is only
    queued where it is seen, and a writer thread of its own formats and
    compresses: the thread that sends setpoints never waits for the file.
    """

    def __init__(self, path, *, background: bool = False, flush_every_s: float = 0.05):
        self.writer = can.Logger(str(path))
        self._background = background
        if background:
            self._pending: deque[can.Message] = deque()
            self._stopping = threading.Event()
            self._flush_every_s = flush_every_s
            self._thread = threading.Thread(target=self._write_loop, name="trace-writer", daemon=True)
            self._thread.start()

    def on_message_received(self, msg: can.Message) -> None:
        if self._background:
            self._pending.append(msg)          # atomic: no lock shared with the sending thread
        else:
            self.writer.on_message_received(msg)

    def _write_loop(self) -> None:
        # Below the threads that send setpoints and receive feedback, but above every ordinary
        # process: a writer preempted by other load while it holds the GIL would hold them up too.
        if not raise_priority(TRACE_PRIORITY)[1]:
            try:
                os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), 10)
            except (AttributeError, OSError):
                pass          # not on this platform: the writer still only runs every flush period
        while not self._stopping.wait(self._flush_every_s):
            self._write_pending()
        self._write_pending()

    def _write_pending(self) -> None:
        pending, write = self._pending, self.writer.on_message_received
        while pending:
            write(pending.popleft())

    def stop(self) -> None:
        if self._background:
            self._stopping.set()
            self._thread.join()
        self.writer.stop()


class MasterNetwork(canopen.Network):
    """canopen Network that stamps sent frames with the link clock, records them
    to the trace, and lets a lockstep link run the other side after each send."""

    def __init__(self, bus: can.BusABC, clock: Clock):
        super().__init__(bus)
        self.clock = clock
        self.trace: TraceRecorder | None = None
        self.after_send = None

    def send_message(self, can_id: int, data: bytes, remote: bool = False,
                     timestamp: float | None = None) -> None:
        """Send one frame stamped ``timestamp`` (default: now); it is traced before it
        goes on the bus, so the trace never shows a reply before its request."""
        msg = can.Message(arbitration_id=can_id, data=data, is_extended_id=can_id > 0x7FF,
                          is_remote_frame=remote, is_rx=False,
                          timestamp=self.clock.now() if timestamp is None else timestamp)
        if self.trace is not None:
            self.trace.on_message_received(msg)
        with self.send_lock:
            self.bus.send(msg)
        if self.after_send is not None:
            self.after_send()


@runtime_checkable
class Link(Protocol):
    """What the master needs of its way to the drives.

    ``network`` is the canopen Network the master's nodes live on (every frame it sends is
    stamped with ``clock`` and traced); ``clock`` is the time the master waits on and stamps
    with; ``threaded`` says whether frames arrive on another thread (a trace must then be
    written in the background).
    """

    network: MasterNetwork
    clock: Clock
    threaded: bool

    def record(self, trace: TraceRecorder | None) -> None:
        """Send every frame from now on, sent and received, to ``trace`` (None stops)."""

    def close(self) -> None:
        """Close the bus (and whatever runs behind it)."""


class _ReceiverPriority(can.Listener):
    """Asks, from the receiving thread itself on its first frame, for the priority the sending
    thread gets while it streams (see :mod:`drive_bridge.master.timing`)."""

    def __init__(self):
        self.granted: str | None = None

    def on_message_received(self, msg: can.Message) -> None:
        if self.granted is None:
            self.granted = raise_priority()[0]


class BusLink:
    """A python-can bus with canopen's Notifier thread and the wall clock."""

    threaded = True           # frames arrive on the Notifier thread

    def __init__(self, bus: can.BusABC):
        self.clock = WallClock()
        # CPython hands the GIL over every 5 ms by default: longer than a SYNC period. The
        # receiving thread must get it within a fraction of a period.
        sys.setswitchinterval(min(sys.getswitchinterval(), 0.001))
        self.bus = bus
        self.network = MasterNetwork(self.bus, self.clock)
        self.network.connect()
        self.network.notifier.add_listener(_ReceiverPriority())
        self.on_close = []                # callbacks after the bus is closed

    @classmethod
    def open(cls, interface: str, channel: str, bitrate: int | None = None) -> "BusLink":
        """Open a python-can bus (``bitrate`` where the interface takes one)."""
        kwargs = {"interface": interface, "channel": channel}
        if bitrate and interface != "virtual":
            kwargs["bitrate"] = bitrate
        if interface == "virtual":
            kwargs["preserve_timestamps"] = False
        return cls(can.Bus(**kwargs))

    def record(self, trace: TraceRecorder | None) -> None:
        """Send every frame from now on to ``trace`` (None stops)."""
        if self.network.trace is not None:
            self.network.notifier.remove_listener(self.network.trace)
        self.network.trace = trace
        if trace is not None:
            self.network.notifier.add_listener(trace)

    def close(self) -> None:
        self.network.disconnect()
        for callback in self.on_close:
            callback()
