"""Pins the behaviour of python-can's udp_multicast bus that drive_bridge.cia.multicast relies on
(its internals: run this after raising python-can's bound in pyproject.toml), and that python-can
opens the echo-free bus by its registered name."""

from __future__ import annotations

import socket
import time

import can
import pytest

from drive_bridge.cia.buses import open_bus
from drive_bridge.cia.multicast import INTERFACE, LoopbackMulticastBus
from drive_bridge.cia.multicast import UDP_GROUP as GROUP
from drive_bridge.sim.process import free_port


def frame(cob_id: int, data: bytes, t: float) -> can.Message:
    return can.Message(arbitration_id=cob_id, data=data, is_extended_id=False, timestamp=t)


def test_loopback_multicast_bus_drops_its_echo_and_keeps_the_senders_time():
    port = free_port()
    a, b = LoopbackMulticastBus(GROUP, port), LoopbackMulticastBus(GROUP, port)
    try:
        a.send(frame(0x080, b"", 123.456))
        msg = b.recv(timeout=2.0)
        assert msg is not None and msg.arbitration_id == 0x080 and msg.timestamp == pytest.approx(123.456)
        deadline = time.monotonic() + 0.3
        while time.monotonic() < deadline:
            assert a.recv(timeout=0.05) is None  # its own frame looped back: dropped
    finally:
        a.shutdown()
        b.shutdown()


def test_python_can_opens_the_echo_free_bus_by_its_name_as_bus_yml_names_udp_multicast():
    port = free_port()
    named = can.Bus(interface=INTERFACE, channel=GROUP, port=port)
    configured = open_bus("udp_multicast", GROUP, None, {"port": port})
    try:
        assert isinstance(named, LoopbackMulticastBus) and isinstance(configured, LoopbackMulticastBus)
        configured.send(frame(0x181, b"\x01", 1.0))
        msg = named.recv(timeout=2.0)
        assert msg is not None and msg.arbitration_id == 0x181
        assert configured.recv(timeout=0.1) is None  # not its own echo
    finally:
        named.shutdown()
        configured.shutdown()


def test_a_listener_asks_for_a_receive_buffer_that_holds_a_whole_stream_it_falls_behind_on():
    """20 000 frames sent while the listener reads none (a listener held up for seconds beside a
    master and drives first in line for the CPU): every one is there when it reads them, with the
    buffer it asked for (the default holds about half as many)."""
    port = free_port()
    listener = LoopbackMulticastBus(GROUP, port, receive_buffer=32 << 20)
    sender = LoopbackMulticastBus(GROUP, port)
    try:
        granted = listener._multicast._socket.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
        if granted < 32 << 20:
            pytest.skip(f"the OS granted {granted} bytes (SO_RCVBUFFORCE needs CAP_NET_ADMIN)")
        for index in range(20_000):
            sender.send(frame(0x080, index.to_bytes(2, "little"), float(index)))
        held = []
        while (msg := listener.recv(timeout=0.5)) is not None:
            held.append(int.from_bytes(msg.data, "little"))
        assert held == list(range(20_000))
    finally:
        listener.shutdown()
        sender.shutdown()
