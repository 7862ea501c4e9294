"""How the master reaches the bus: a canopen Network, its clock, and the raw trace.

:class:`BusLink` is the real thing: a python-can bus (socketcan, pcan, kvaser,
virtual...), canopen's Notifier thread receiving, and the wall clock.  The
simulator offers a lockstep link with the same attributes; nothing in the
master knows which one it has.
"""
from __future__ import annotations

import sys
import threading
import time
from typing import Protocol

import can
import canopen


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
        # Sleep most of the way, then yield in short slices: never spin without yielding.
        while True:
            left = deadline - time.time()
            if left <= 0:
                return
            time.sleep(left - 0.0003 if left > 0.0008 else 0.0)


class TraceRecorder(can.Listener):
    """Thread-safe recorder of every frame sent and received, in a python-can log format."""

    def __init__(self, path):
        self.writer = can.Logger(str(path))
        self._lock = threading.Lock()

    def on_message_received(self, msg: can.Message) -> None:
        with self._lock:
            self.writer.on_message_received(msg)

    def stop(self) -> None:
        with self._lock:
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


class BusLink:
    """A python-can bus with canopen's Notifier thread and the wall clock."""

    def __init__(self, interface: str, channel: str, bitrate: int | None = None):
        kwargs = {"interface": interface, "channel": channel}
        if bitrate and interface != "virtual":
            kwargs["bitrate"] = bitrate
        if interface == "virtual":
            kwargs["preserve_timestamps"] = False
        self.clock = WallClock()
        # CPython hands the GIL over every 5 ms by default: longer than a SYNC period. The
        # receiving thread must get it within a fraction of a period.
        sys.setswitchinterval(min(sys.getswitchinterval(), 0.001))
        self.bus = can.Bus(**kwargs)
        self.network = MasterNetwork(self.bus, self.clock)
        self.network.connect()

    def record(self, trace: TraceRecorder | None) -> None:
        """Send every frame from now on to ``trace`` (None stops)."""
        if self.network.trace is not None:
            self.network.notifier.remove_listener(self.network.trace)
        self.network.trace = trace
        if trace is not None:
            self.network.notifier.add_listener(trace)

    def pump(self) -> None:
        """Frames are delivered by the Notifier thread; nothing to do."""

    def close(self) -> None:
        self.network.disconnect()
