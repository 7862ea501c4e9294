"""The engine's port on a python-can bus (:class:`drive_bridge.master.port.BusPort`), on python-can's
``virtual`` interface: what it hands the engine while it waits for a SYNC."""

from __future__ import annotations

import can
import numpy as np

from drive_bridge.cia.p301 import SYNC_COB_ID
from drive_bridge.master.port import BusPort, TraceRing


def test_syncs_handed_over_together_come_in_one_wait_with_what_queued_behind_them():
    """Three SYNCs, each with a drive's answer, queued while the engine was held up, are handed over
    in one ``wait_sync`` -- all of them, and the frames behind the last -- so that the engine answers
    the last once rather than each with a period's RPDOs (before: one SYNC a call, the next call
    returning at once with the next queued one); the wait ends once the queue is empty, long before
    its deadline."""
    channel = "drive-bridge-test-port"
    with (
        can.Bus(interface="virtual", channel=channel) as engine_bus,
        can.Bus(interface="virtual", channel=channel) as drives,
    ):
        port = BusPort(engine_bus, TraceRing(64, np.zeros))
        seen: list[int] = []
        port.receive(
            {cob_id: lambda data, stamp, c=cob_id: seen.append(c) for cob_id in (0x80, 0x181)}, lambda: None
        )
        for _ in range(3):
            drives.send(can.Message(arbitration_id=SYNC_COB_ID, data=b"", is_extended_id=False))
            drives.send(can.Message(arbitration_id=0x181, data=bytes(8), is_extended_id=False))
        start = port.now()
        port.wait_sync(start + 5.0)
        assert seen == [0x80, 0x181] * 3
        assert port.now() - start < 1.0
        assert len(port.ring.take()) == 6
