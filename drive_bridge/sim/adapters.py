"""The simulator's reliance on internals of python-can and canopen (the master's are its BLF trace
writer, :mod:`drive_bridge.master.blf`, pinned by ``tests/master/test_blf.py``, and the echo-free
multicast bus, :mod:`drive_bridge.cia.multicast`).

Each behaviour relied on is pinned by ``tests/sim/test_adapters.py``, and
pyproject.toml bounds both libraries above by the versions that test passed on.

:class:`FastVirtualBus` -- python-can's virtual bus without its per-frame cost.
``VirtualBus.send`` deep-copies the frame for every receiver (the largest
single cost of a lockstep cycle).  This subclass shares the same channels and
queues, so it talks to any other VirtualBus on the channel, but builds each
receiver's copy directly, and :meth:`drain` empties the receive queue without
the generic ``recv`` bookkeeping.

With ``direct = True`` (lockstep: every bus on the channel lives in one thread
and nobody blocks in ``recv``) a frame is handed over as the sender's own
``Message`` object, marked received, appended to the receivers' queues
without the queue's locks and wake-ups.  Senders must not touch a frame after
sending it.  Relies on: ``VirtualBus.channel`` (the receivers' queues of the
channel), ``.queue`` (its own, a ``queue.Queue``), ``.channel_id``,
``._check_if_open()``.

:func:`local_node` -- canopen's ``LocalNode`` (the SDO server and object
store of a simulated drive) without canopen's heartbeat timer, attached to a
drive's own way of sending.  Relies on ``LocalNode.__init__`` registering
``nmt.on_write`` through ``add_write_callback`` and on ``sdo.network`` being
what the SDO server sends its replies through.  Its SDO server's ``abort`` answers a request that came
before any transfer (canopen's relies on ``_index``/``_subindex``, None until one began).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator

import can
import canopen
from can.interfaces.virtual import VirtualBus
from canopen.sdo import SdoServer


class FastVirtualBus(VirtualBus):
    """python-can's virtual bus without its per-frame cost (see the module); ``direct``: frames
    handed over as the sender's own objects (lockstep)."""

    direct = False

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self._check_if_open()
        if self.direct:
            msg.is_rx = True
            for bus_queue in self.channel:
                if bus_queue is not self.queue:
                    bus_queue.queue.append(msg)
            return
        timestamp = msg.timestamp if self.preserve_timestamps else time.time()
        for bus_queue in self.channel:
            if bus_queue is self.queue and not self.receive_own_messages:
                continue
            bus_queue.put_nowait(
                can.Message(
                    timestamp=timestamp,
                    arbitration_id=msg.arbitration_id,
                    is_extended_id=msg.is_extended_id,
                    is_remote_frame=msg.is_remote_frame,
                    dlc=msg.dlc,
                    data=bytes(msg.data),
                    channel=self.channel_id,
                    is_rx=bus_queue is not self.queue,
                    check=False,
                )
            )

    def drain(self) -> Iterator[can.Message]:
        """Yield every frame waiting in the receive queue, oldest first."""
        pending = self.queue.queue  # the Queue's deque: popleft is atomic, no lock needed
        popleft = pending.popleft
        while pending:
            yield popleft()


class _LocalNodeWithoutNmtTimer(canopen.LocalNode):
    """canopen's LocalNode whose NMT service does not handle writes to 0x1017 (it would start
    canopen's heartbeat timer thread; a simulated drive sends its heartbeat in simulation time)."""

    def add_write_callback(self, callback: Callable[..., None]) -> None:
        nmt = getattr(self, "nmt", None)
        if nmt is not None and callback == nmt.on_write:
            return
        super().add_write_callback(callback)


class _Replies(canopen.Network):
    """What canopen's SDO server sends its replies through: the drive's own ``send``."""

    def __init__(self, send: Callable[[int, bytes], None]):
        super().__init__()
        self._send = send

    def send_message(self, can_id: int, data: bytes, remote: bool = False) -> None:
        self._send(can_id, bytes(data))


class _SdoServerThatAnswers(SdoServer):
    """canopen's SDO server, whose abort answers a request that came before any transfer too
    (canopen's packs the transfer's object, None until one began: a segment request out of the
    blue made the abort itself raise, out of the server)."""

    def abort(self, abort_code: int = 0x08000000) -> None:
        if self._index is None or self._subindex is None:
            self._index, self._subindex = 0, 0
        super().abort(abort_code)

    def block_upload(self, data: bytes) -> None:
        """A block upload, which this server does not have: canopen's switches to a segmented
        upload, which CiA 301 allows only where the request's protocol switch threshold (byte 5)
        lets it; with 0, abort 0x05040001 (command specifier not valid)."""
        if data[5] == 0:
            self._index, self._subindex = data[1] | data[2] << 8, data[3]
            self.abort(0x05040001)
            return
        super().block_upload(data)


def local_node(
    node_id: int, od: canopen.ObjectDictionary, send: Callable[[int, bytes], None]
) -> canopen.LocalNode:
    """A LocalNode (SDO server, object store) for a simulated drive that sends with ``send``.

    Its SDO server is fed by the drive (``node.sdo.on_request``); heartbeat, NMT, PDOs and
    EMCY are the drive's own.

    Parameters
    ----------
    node_id : int
        The node.
    od : canopen.ObjectDictionary
        The drive's object dictionary.
    send : callable
        ``send(cob_id, data)``.

    Returns
    -------
    canopen.LocalNode
        The node.
    """
    node = _LocalNodeWithoutNmtTimer(node_id, od)
    node.sdo = _SdoServerThatAnswers(0x600 + node_id, 0x580 + node_id, node)
    node.sdo.network = _Replies(send)
    return node
