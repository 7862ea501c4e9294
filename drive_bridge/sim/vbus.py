"""python-can's virtual bus without its per-frame cost, for the simulator and the lockstep link.

``VirtualBus.send`` deep-copies the frame for every receiver (the largest
single cost of a lockstep cycle).  This subclass shares the same channels and
queues, so it talks to any other VirtualBus on the channel, but builds each
receiver's copy directly, and :meth:`drain` empties the receive queue without
the generic ``recv`` bookkeeping.
"""
from __future__ import annotations

import time

import can
from can.interfaces.virtual import VirtualBus


class FastVirtualBus(VirtualBus):
    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self._check_if_open()
        timestamp = msg.timestamp if self.preserve_timestamps else time.time()
        for bus_queue in self.channel:
            if bus_queue is self.queue and not self.receive_own_messages:
                continue
            bus_queue.put_nowait(can.Message(
                timestamp=timestamp, arbitration_id=msg.arbitration_id, is_extended_id=msg.is_extended_id,
                is_remote_frame=msg.is_remote_frame, dlc=msg.dlc, data=bytes(msg.data),
                channel=self.channel_id, is_rx=bus_queue is not self.queue, check=False))

    def drain(self):
        """Yield every frame waiting in the receive queue, oldest first."""
        pending, get = self.queue.queue, self.queue.get_nowait    # the Queue's deque: a lock-free peek
        while pending:
            yield get()
