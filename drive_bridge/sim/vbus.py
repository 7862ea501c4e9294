"""python-can's virtual bus without its per-frame cost, for the simulator and the lockstep link.

``VirtualBus.send`` deep-copies the frame for every receiver (the largest
single cost of a lockstep cycle).  This subclass shares the same channels and
queues, so it talks to any other VirtualBus on the channel, but builds each
receiver's copy directly, and :meth:`drain` empties the receive queue without
the generic ``recv`` bookkeeping.

With ``direct = True`` (lockstep: every bus on the channel lives in one thread
and nobody blocks in ``recv``) a frame is handed over as the sender's own
``Message`` object, marked received, appended to the receivers' queues
without the queue's locks and wake-ups.  Senders must not touch a frame after
sending it.
"""
from __future__ import annotations

import time

import can
from can.interfaces.virtual import VirtualBus


class FastVirtualBus(VirtualBus):
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
            bus_queue.put_nowait(can.Message(
                timestamp=timestamp, arbitration_id=msg.arbitration_id, is_extended_id=msg.is_extended_id,
                is_remote_frame=msg.is_remote_frame, dlc=msg.dlc, data=bytes(msg.data),
                channel=self.channel_id, is_rx=bus_queue is not self.queue, check=False))

    def drain(self):
        """Yield every frame waiting in the receive queue, oldest first."""
        pending = self.queue.queue           # the Queue's deque: popleft is atomic, no lock needed
        popleft = pending.popleft
        while pending:
            yield popleft()
