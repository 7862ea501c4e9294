"""Pins every behaviour of python-can and canopen that drive_bridge.sim.adapters relies on
(their internals, not their documented API): run this after raising a bound in pyproject.toml."""

from __future__ import annotations

import struct

import can
import canopen
import pytest
from can.interfaces.virtual import VirtualBus

from drive_bridge.cia.od import load_od
from drive_bridge.resources import PROJECT_EDS
from drive_bridge.sim.adapters import FastVirtualBus, local_node


def frame(cob_id: int, data: bytes, t: float) -> can.Message:
    return can.Message(arbitration_id=cob_id, data=data, is_extended_id=False, timestamp=t)


@pytest.mark.parametrize("direct", [False, True])
def test_fast_virtual_bus_talks_to_pythoncan_virtual_buses_on_its_channel(direct):
    channel = f"pin-{direct}"
    fast = FastVirtualBus(channel=channel, preserve_timestamps=True)
    stock = VirtualBus(channel=channel, preserve_timestamps=True)
    other = FastVirtualBus(channel=channel, preserve_timestamps=True)
    fast.direct = direct
    try:
        sent = [frame(0x181, b"\x01\x02", 1.5), frame(0x281, b"", 2.25)]
        for msg in sent:
            fast.send(msg)
        got = [stock.recv(0), stock.recv(0)]
        assert [(m.arbitration_id, bytes(m.data), m.timestamp) for m in got] == [
            (0x181, b"\x01\x02", 1.5),
            (0x281, b"", 2.25),
        ]
        assert all(m.is_rx for m in got) and stock.recv(0) is None
        drained = list(other.drain())
        assert [(m.arbitration_id, m.timestamp) for m in drained] == [(0x181, 1.5), (0x281, 2.25)]
        if direct:  # the sender's own objects, no copy
            assert drained[0] is sent[0]
        assert list(fast.drain()) == []  # never its own frames
        stock.send(frame(0x701, b"\x05", 3.0))
        assert [(m.arbitration_id, bytes(m.data)) for m in fast.drain()] == [(0x701, b"\x05")]
    finally:
        for bus in (fast, stock, other):
            bus.shutdown()


def test_canopen_local_node_registers_its_nmt_write_handler_through_add_write_callback():
    registered = []

    class Spy(canopen.LocalNode):
        def add_write_callback(self, callback):
            registered.append(callback)
            super().add_write_callback(callback)

    node = Spy(5, load_od(PROJECT_EDS, 5))
    assert node.nmt.on_write in registered


def test_local_node_answers_sdo_through_the_drive_and_leaves_heartbeats_to_it():
    sent = []
    node = local_node(5, load_od(PROJECT_EDS, 5), lambda cob, data: sent.append((cob, data)))
    node.set_data(0x1017, 0, struct.pack("<H", 100))  # canopen's NMT would start a timer thread here
    node.sdo.on_request(0x605, bytes([0x40, 0x17, 0x10, 0x00, 0, 0, 0, 0]), 0.0)  # upload 0x1017
    assert len(sent) == 1 and sent[0][0] == 0x585
    assert sent[0][1][0] & 0xE0 == 0x40 and struct.unpack_from("<H", sent[0][1], 4)[0] == 100


def test_an_sdo_segment_request_before_any_transfer_is_answered_with_an_abort():
    """canopen's SdoServer.abort packs the transfer's index, None before any transfer (its
    ``_index``/``_subindex``): the simulated drive's server answers such a request with an abort
    instead of raising out of it."""
    sent = []
    node = local_node(5, load_od(PROJECT_EDS, 5), lambda cob, data: sent.append((cob, bytes(data))))
    node.sdo.on_request(0x605, bytes(8), 0.0)  # a download segment, no transfer begun
    assert len(sent) == 1 and sent[0][0] == 0x585 and sent[0][1][0] == 0x80  # an abort
    assert node.sdo._index is not None  # the attribute the adapter relies on
