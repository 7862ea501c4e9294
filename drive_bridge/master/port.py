"""How the cyclic engine (:mod:`.engine`) reaches the bus.

* :class:`BusPort`: a python-can bus of the engine's own, on the wall clock.  The engine waits
  for its deadlines inside the bus's ``recv``, so frames are taken the moment they arrive, each
  with the time stamp the interface gave it (the kernel's on socketcan and udp_multicast).  Every
  frame sent and received goes into a :class:`TraceRing` that the master's process drains into
  the trace file.

The schedule is absolute and monotonic: a port's ``now`` is ``time.monotonic()`` moved once onto
the wall clock's epoch (the epoch frame time stamps are in), so a step of the system clock during
a run moves no deadline.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import can
import numpy as np

from ..cia.p301 import SYNC_COB_ID
from .engine import Handler

#: flag bits of a frame in the ring
RX, ERROR, REMOTE, EXTENDED = 1, 2, 4, 8
HEAD, TAIL, DROPPED = range(3)


class TraceRing:
    """Frames from the engine to the trace writer: one producer, one consumer, fixed size.

    The producer writes a frame, then moves the head; the consumer reads up to the head, then moves
    the tail.  A frame that finds the ring full is counted in ``DROPPED`` instead (the engine never
    waits for the trace).

    Parameters
    ----------
    capacity : int
        Frames it holds.
    allocate : callable
        ``allocate(shape, dtype)``: plain memory, or a shared mapping.
    """

    def __init__(self, capacity: int, allocate: Callable[[tuple[int, ...], type], np.ndarray]):
        self.capacity = capacity
        for name, shape, dtype in self.layout(capacity):
            setattr(self, name, allocate(shape, dtype))

    stamp: np.ndarray
    cob_id: np.ndarray
    flags: np.ndarray
    dlc: np.ndarray
    data: np.ndarray
    counters: np.ndarray

    @staticmethod
    def layout(capacity: int) -> list[tuple[str, tuple[int, ...], type]]:
        """(name, shape, type) of each array, in the order they are allocated.

        Parameters
        ----------
        capacity : int
            Frames it holds.

        Returns
        -------
        list of (str, tuple of int, type)
            The layout.
        """
        return [
            ("stamp", (capacity,), np.float64),
            ("cob_id", (capacity,), np.uint32),
            ("flags", (capacity,), np.uint8),
            ("dlc", (capacity,), np.uint8),
            ("data", (capacity, 8), np.uint8),
            ("counters", (3,), np.int64),
        ]

    def put(self, stamp: float, cob_id: int, flags: int, data: bytes | bytearray) -> None:
        """One frame (the producer's side; counted dropped where the ring is full).

        Parameters
        ----------
        stamp : float
            Its time stamp [s].
        cob_id : int
            Its COB-ID.
        flags : int
            ``RX``, ``ERROR``, ``REMOTE``, ``EXTENDED`` bits.
        data : bytes or bytearray
            Its data.
        """
        counters = self.counters
        head = int(counters[HEAD])
        if head - int(counters[TAIL]) >= self.capacity:
            counters[DROPPED] += 1
            return
        i = head % self.capacity
        self.stamp[i] = stamp
        self.cob_id[i] = cob_id
        self.flags[i] = flags
        n = len(data)
        self.dlc[i] = n
        if n:
            self.data[i, :n] = memoryview(data)
        counters[HEAD] = head + 1

    def take(self) -> list[can.Message]:
        """Every frame put since the last take, as python-can messages.

        Returns
        -------
        list of can.Message
            In the order they were put.
        """
        counters = self.counters
        head, tail = int(counters[HEAD]), int(counters[TAIL])
        out = []
        for j in range(tail, head):
            i = j % self.capacity
            flags, n = int(self.flags[i]), int(self.dlc[i])
            out.append(
                can.Message(
                    timestamp=float(self.stamp[i]),
                    arbitration_id=int(self.cob_id[i]),
                    is_extended_id=bool(flags & EXTENDED),
                    is_remote_frame=bool(flags & REMOTE),
                    is_error_frame=bool(flags & ERROR),
                    is_rx=bool(flags & RX),
                    dlc=n,
                    data=bytes(self.data[i, :n]),
                    check=False,
                )
            )
        counters[TAIL] = head
        return out

    @property
    def dropped(self) -> int:
        """Frames that found the ring full (the trace misses them)."""
        return int(self.counters[DROPPED])


def periodic_send_of(bus: can.BusABC) -> str | None:
    """What sends a periodic frame on ``bus`` where its interface does so itself (the kernel's broadcast
    manager on socketcan, an adapter's own periodic send), else None (python-can's thread).

    Parameters
    ----------
    bus : can.BusABC
        The bus.

    Returns
    -------
    str or None
        What sends it, in words.
    """
    if type(bus)._send_periodic_internal is can.BusABC._send_periodic_internal:
        return None
    if "socketcan" in type(bus).__module__:
        return "the kernel's broadcast manager (socketcan BCM)"
    return f"the interface's own periodic send ({type(bus).__name__})"


class BusPort:
    """The engine on a python-can bus of its own, on the wall clock; every frame into ``ring``.

    Where the interface sends periodic frames itself (:func:`periodic_send_of`), SYNC is left to it:
    it leaves on time whatever the interpreter does, and the engine takes each SYNC as the bus shows
    it (its receive stamp) and sends the RPDOs of the next period right after it.  Should the first
    SYNC not come back within a few periods, the engine's own loop sends SYNC instead (said in
    :attr:`sync_source`).

    Where a drive produces SYNC (``sync_from``), the engine likewise answers each SYNC as the bus shows
    it; should none come within :attr:`FIRST_SYNC_S`, the run ends (the engine never sends SYNC beside
    another producer).

    Parameters
    ----------
    bus : can.BusABC
        The engine's own handle on the bus.
    ring : TraceRing
        Where every frame goes.
    sync_from : str, optional
        The drive that produces SYNC, in words (None: the interface or the engine sends it).
    """

    ECHO_PERIODS = 5  # periods to wait for the interface's first SYNC before taking over
    FIRST_SYNC_S = 0.5  # how long a drive's first SYNC is waited for

    def __init__(self, bus: can.BusABC, ring: TraceRing, sync_from: str | None = None):
        self.bus = bus
        self.ring = ring
        native = None if sync_from else periodic_send_of(bus)
        self.periodic_sync = bool(sync_from) or native is not None
        self._drive_sync = bool(sync_from)
        self.sync_source = sync_from or native or "the engine's own loop"
        self._task: can.broadcastmanager.CyclicSendTaskABC | None = None
        self._offset = time.time() - time.monotonic()
        self._handlers: dict[int, Handler] = {}
        self._on_error: Callable[[], None] | None = None
        self._messages: dict[int, can.Message] = {}  # one per COB-ID sent, its data filled in place
        while bus.recv(0.0) is not None:  # what queued since the last run (the master's trace has it)
            pass

    def now(self) -> float:
        """:meth:`Port.now`: the monotonic clock moved once onto the wall clock's epoch.

        Returns
        -------
        float
            [s].
        """
        return time.monotonic() + self._offset

    def wait_until(self, deadline: float) -> None:
        """:meth:`Port.wait_until`, inside the bus's ``recv``.

        Parameters
        ----------
        deadline : float
            [s, :meth:`now`'s].
        """
        self._receive_until(deadline, sync=False)

    def _receive_until(self, deadline: float, sync: bool) -> None:
        """Hand over every frame that arrives until ``deadline`` (``sync``: or until a SYNC came, and
        every frame queued behind it -- SYNCs handed over late come together, and the engine answers
        the last of them only, rather than a burst of a period's RPDOs for each)."""
        recv, monotonic, offset = self.bus.recv, time.monotonic, self._offset
        while True:
            left = deadline - monotonic() - offset
            msg = recv(left if left > 0 else 0.0)
            if msg is None:
                if left <= 0:
                    return
                continue
            self._dispatch(msg)
            if sync and msg.arbitration_id == SYNC_COB_ID and not msg.is_error_frame:
                deadline = -math.inf

    def start_sync(self, period: float, counter: int = 0) -> None:
        """:meth:`Port.start_sync`: the interface's periodic send (with the counter: one job of
        ``counter`` frames carrying 1..``counter``, sent one a period: python-can's sequence, the
        kernel's broadcast manager on socketcan); a producing drive's first SYNC waited for.

        Parameters
        ----------
        period : float
            The SYNC period [s].
        counter : int
            The counter's overflow value (0: none).
        """
        if self._drive_sync:
            if not self._first_sync(self.FIRST_SYNC_S):
                raise RuntimeError(f"no SYNC within {self.FIRST_SYNC_S} s from the {self.sync_source}")
            return
        frames = [
            can.Message(arbitration_id=SYNC_COB_ID, data=data, is_extended_id=False)
            for data in ([bytes([k]) for k in range(1, counter + 1)] or [b""])
        ]
        self._task = self.bus.send_periodic(frames, period)
        if not self._first_sync(self.ECHO_PERIODS * period):  # it does not show its own frames
            self.stop_sync()
            self.periodic_sync = False
            self.sync_source = (
                f"the engine's own loop ({self.sync_source} did not show its SYNC within "
                f"{self.ECHO_PERIODS} periods)"
            )

    def _first_sync(self, timeout: float) -> bool:
        """Whether a SYNC came within ``timeout`` [s] (handed to the engine as any other)."""
        handler = self._handlers.get(SYNC_COB_ID)
        seen: list[float] = []

        def first(data: bytes | bytearray, stamp: float) -> None:
            seen.append(stamp)
            if handler is not None:
                handler(data, stamp)

        self._handlers[SYNC_COB_ID] = first
        try:
            self.wait_sync(self.now() + timeout)
        finally:
            if handler is not None:
                self._handlers[SYNC_COB_ID] = handler
        return bool(seen)

    def wait_sync(self, timeout_at: float) -> None:
        """:meth:`Port.wait_sync`.

        Parameters
        ----------
        timeout_at : float
            The latest time [s, :meth:`now`'s].
        """
        self._receive_until(timeout_at, sync=True)

    def stop_sync(self) -> None:
        """:meth:`Port.stop_sync`."""
        if self._task is not None:
            self._task.stop()
            self._task = None

    def _dispatch(self, msg: can.Message) -> None:
        stamp = msg.timestamp or self.now()
        # (the interface's SYNC is the master's own frame, not a received one)
        own = (
            self.periodic_sync
            and not self._drive_sync
            and msg.arbitration_id == SYNC_COB_ID
            and not msg.is_error_frame
        )
        flags = (
            (0 if own else RX)
            | (ERROR if msg.is_error_frame else 0)
            | (REMOTE if msg.is_remote_frame else 0)
            | (EXTENDED if msg.is_extended_id else 0)
        )
        self.ring.put(stamp, msg.arbitration_id, flags, msg.data)
        if msg.is_error_frame:
            if self._on_error is not None:
                self._on_error()
            return
        handler = self._handlers.get(msg.arbitration_id)
        if handler is not None and not msg.is_remote_frame:
            handler(msg.data, stamp)

    def send(self, cob_id: int, data: bytes | bytearray, stamp: float) -> None:
        """:meth:`Port.send` (one message object per COB-ID, reused: nothing allocated per frame).

        Parameters
        ----------
        cob_id : int
            Its COB-ID.
        data : bytes or bytearray
            Its data.
        stamp : float
            Its time stamp [s].
        """
        msg = self._messages.get(cob_id)
        if msg is None or len(msg.data) != len(data):
            msg = self._messages[cob_id] = can.Message(
                arbitration_id=cob_id, data=bytes(data), is_extended_id=cob_id > 0x7FF
            )
        else:
            msg.data[:] = data
        msg.timestamp = stamp
        self.ring.put(stamp, cob_id, EXTENDED if cob_id > 0x7FF else 0, data)
        self.bus.send(msg)

    def receive(self, handlers: dict[int, Handler], on_error_frame: Callable[[], None]) -> None:
        """:meth:`Port.receive`.

        Parameters
        ----------
        handlers : dict of int to Handler
            COB-ID -> ``handler(data, timestamp)``.
        on_error_frame : callable
            Called for each error frame.
        """
        self._handlers = dict(handlers)
        self._on_error = on_error_frame

    def release(self) -> None:
        """:meth:`Port.release`."""
        self._handlers = {}
        self._on_error = None
