"""``drive-bridge sim`` against a master the project did not write: python canopen's own services
(NMT, SDO, PDO, EMCY, SYNC) and its CiA 402 node, over python-can's stock udp_multicast bus, as a
user testing their own master would start it."""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Iterator

import canopen
import numpy as np
import pytest

from drive_bridge.cia.multicast import UDP_GROUP
from drive_bridge.cia.p301 import ERR_PARAMETER
from drive_bridge.master.campaign import trapezoid
from drive_bridge.resources import PROJECT_EDS
from harness.support import start_sim

pytestmark = [pytest.mark.slow, pytest.mark.realtime]

NODES = (1, 2, 3)


@pytest.fixture(scope="module")
def drives(tmp_path_factory) -> Iterator[canopen.Network]:
    """``drive-bridge sim`` in a process of its own, and a canopen network on its bus (python-can's
    udp_multicast as it comes: it hands the network its own frames back too)."""
    process, _, port = start_sim(tmp_path_factory.mktemp("sim"))
    network = canopen.Network()
    try:
        network.connect(interface="udp_multicast", channel=UDP_GROUP, port=port)
        yield network
    finally:
        network.disconnect()
        process.terminate()
        process.wait(10)


def test_a_value_a_drive_cannot_take_by_rpdo_is_answered_with_an_emcy_and_every_drive_serves_on(drives):
    """0x6060 = 2 (a mode not in 0x6502) by RPDO: EMCY 0x6320 from that drive, its mode unchanged,
    and every drive still answers SDO and sends its heartbeat (the same write by SDO is refused)."""
    network = drives
    nodes = {n: network.add_node(n, str(PROJECT_EDS)) for n in NODES}
    emcy: list[tuple[int, int]] = []
    beats: list[int] = []
    for n in NODES:
        network.subscribe(0x80 + n, lambda cob, data, ts: emcy.append((cob - 0x80, data[0] | data[1] << 8)))
        network.subscribe(0x700 + n, lambda cob, data, ts: beats.append(cob - 0x700))
    node = nodes[1]
    node.nmt.state = "PRE-OPERATIONAL"
    for n in NODES:
        nodes[n].sdo[0x1017].raw = 50  # heartbeat producer, 50 ms
    with pytest.raises(canopen.SdoAbortedError):
        node.sdo[0x6060].raw = 2
    node.rpdo.read()
    pdo = node.rpdo[2]
    pdo.clear()
    pdo.add_variable(0x6060)
    pdo.cob_id = 0x300 + 1
    pdo.trans_type = 255  # event-driven: taken as it comes
    pdo.enabled = True
    node.rpdo.save()
    node.nmt.state = "OPERATIONAL"
    time.sleep(0.1)
    before = node.sdo[0x6061].raw
    pdo[0].raw = 2
    pdo.transmit()
    deadline = time.monotonic() + 5.0
    while (1, ERR_PARAMETER) not in emcy and time.monotonic() < deadline:
        time.sleep(0.02)
    assert (1, ERR_PARAMETER) in emcy, emcy
    assert node.sdo[0x6061].raw == before  # not taken
    beats.clear()
    time.sleep(0.5)
    assert set(beats) == set(NODES), beats  # every drive's heartbeat goes on
    for n in NODES:
        assert nodes[n].sdo[0x6041].raw is not None  # and each answers SDO
    pdo[0].raw = 1  # a value it can take, by the same PDO
    pdo.transmit()
    deadline = time.monotonic() + 5.0
    while node.sdo[0x6061].raw != 1 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert node.sdo[0x6061].raw == 1


def test_profile_position_takes_the_target_of_the_same_rpdo_as_its_new_set_point(drives):
    """canopen's CiA 402 node, the EDS's own RPDO1 (controlword and target 0x607A, synchronous, sent
    every SYNC as canopen's periodic PDO does): a new set-point (bit 4 rising) sent in one PDO with
    its target moves the axis there -- the drive takes the whole PDO before it acts on any of it."""
    network = drives
    node = canopen.BaseNode402(2, str(PROJECT_EDS))
    network.add_node(node)
    node.nmt.state = "PRE-OPERATIONAL"
    node.setup_402_state_machine()  # reads the PDO mappings
    node.nmt.state = "OPERATIONAL"
    node.op_mode = "PROFILED POSITION"
    pdo = node.rpdo[1]
    start = node.sdo[0x6064].raw
    pdo[1].raw = start  # the target where the axis stands
    network.sync.start(0.01)  # the master's SYNC, 10 ms, and RPDO1 with each
    pdo.start(0.01)
    try:
        node.state = "OPERATION ENABLED"
        target = start + 1048576 // 2  # half a turn
        pdo.stop()
        pdo[1].raw = target
        pdo[0].raw = 0x1F  # enable operation + new set-point, in the same PDO as the target
        pdo.start(0.01)
        deadline = time.monotonic() + 10.0
        while abs(node.sdo[0x6064].raw - target) > 1000 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert abs(node.sdo[0x6064].raw - target) <= 1000, (start, target, node.sdo[0x6064].raw)
        node.state = "SWITCH ON DISABLED"
    finally:
        pdo.stop()
        network.sync.stop()


def test_what_a_tool_reads_and_writes_by_sdo_is_what_cia_301_and_402_define(drives):
    """An SDO block upload a drive does not have is refused as CiA 301 says (abort 0x05040001:
    protocol switch threshold 0 forbids a segmented answer); a TPDO's communication record counts its
    event timer (sub 5) in sub 0; option codes refuse the values CiA 402 reserves."""
    network = drives
    node = network.add_node(3, str(PROJECT_EDS))
    with pytest.raises(canopen.SdoAbortedError) as refused:
        with node.sdo.open(0x1018, 1, "rb", block_transfer=True) as stream:
            stream.read()
    assert refused.value.code == 0x05040001
    assert node.sdo[0x1018][1].raw is not None  # and it serves on
    for tpdo in range(0x1800, 0x1804):
        assert node.sdo[tpdo][0].raw == 5
        assert node.sdo[tpdo][5].raw is not None  # the event timer, within 1..sub 0
    for index, reserved, defined in ((0x605A, 99, 2), (0x6007, 99, 1)):
        with pytest.raises(canopen.SdoAbortedError) as refused:
            node.sdo[index].raw = reserved
        assert refused.value.code == 0x06090030, hex(index)
        node.sdo[index].raw = defined
        assert node.sdo[index].raw == defined


def test_csp_at_a_10_ms_sync_moves_as_0x60c2_says_not_stop_and_go(drives):
    """A master of its own at a 10 ms SYNC (the simulator started at its default 2 ms), 0x1006 and
    0x60C2 = 10 ms written, cyclic synchronous position with controlword and target in the EDS's
    RPDO1 after each SYNC: the drive interpolates each setpoint over 10 ms -- its velocity, read at
    any moment of the cruise, is the commanded one (not 2 ms of motion and 8 of standstill) -- and
    the axis arrives when the profile ends."""
    network = drives
    node = canopen.BaseNode402(3, str(PROJECT_EDS))
    network.add_node(node)
    node.nmt.state = "PRE-OPERATIONAL"
    node.sdo[0x1006].raw = 10_000  # [µs]
    node.sdo[0x60C2][1].raw, node.sdo[0x60C2][2].raw = 10, -3  # 10 × 10⁻³ s
    node.setup_402_state_machine()
    node.nmt.state = "OPERATIONAL"
    node.op_mode = "CYCLIC SYNCHRONOUS POSITION"
    pdo = node.rpdo[1]  # 0x6040 + 0x607A, synchronous
    start = node.sdo[0x6064].raw
    per_rad = 1048576 / (2 * math.pi)
    speed, accel, period = 2.0 * per_rad, 10.0 * per_rad, 0.010  # [inc/s], [inc/s²], [s]
    ramp, cruise = speed / accel, 1.0  # [s]
    # the setpoints of a trapezoid: ramp, 1 s at speed, ramp
    target = np.round(trapezoid(start, start + speed * (ramp + cruise), speed, accel, period)).astype(int)
    sampled: list[float] = []
    controlword = [0x06]

    def master() -> None:  # SYNC, then the setpoint for the period it opens, on an absolute schedule
        t0 = time.monotonic()
        for k, setpoint in enumerate([start] * 50 + list(target) + [int(target[-1])] * 100):
            time.sleep(max(0.0, t0 + k * period - time.monotonic()))
            network.sync.transmit()
            pdo[0].raw, pdo[1].raw = controlword[0], setpoint
            pdo.transmit()

    pdo[0].raw, pdo[1].raw = 0x06, start
    thread = threading.Thread(target=master)
    thread.start()
    try:
        for word in (0x06, 0x07, 0x0F):  # shutdown, switch on, enable operation
            controlword[0] = word
            time.sleep(0.1)
        assert node.state == "OPERATION ENABLED"
        time.sleep(0.5 - 0.3 + ramp + 0.1)  # into the cruise (the profile starts 0.5 s after the master)
        t_end = time.monotonic() + cruise - 0.2
        while time.monotonic() < t_end:
            sampled.append(node.sdo[0x606C].raw)
            time.sleep(0.007)
        thread.join()
        arrived = node.sdo[0x6064].raw
    finally:
        thread.join()
        controlword[0] = 0x06
        node.sdo[0x6040].raw = 0x06
    velocity = np.array(sampled)
    assert len(velocity) > 30
    assert np.median(velocity) == pytest.approx(speed, rel=0.1)  # moving at the commanded speed ...
    assert (
        np.percentile(velocity, 5) > 0.7 * speed and np.percentile(velocity, 95) < 1.3 * speed
    )  # ... steadily
    assert abs(arrived - target[-1]) < 0.01 * per_rad  # and there when the profile ended (+1 s)
