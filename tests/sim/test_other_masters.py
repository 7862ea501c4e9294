"""``drive-bridge sim`` against a master the project did not write: python canopen's own services
(NMT, SDO, PDO, EMCY, SYNC) and its CiA 402 node, over python-can's stock udp_multicast bus, as a
user testing their own master would start it."""

from __future__ import annotations

import contextlib
import math
import subprocess
import sys
import threading
import time
from collections.abc import Iterator

import can
import canopen
import numpy as np
import pytest

from drive_bridge.cia.multicast import UDP_GROUP
from drive_bridge.cia.p301 import ERR_PARAMETER
from drive_bridge.cli import main
from drive_bridge.master.campaign import trapezoid
from drive_bridge.master.timing import raise_priority
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


@pytest.mark.parametrize("period_ms, node_id", [(10, 3), (20, 1)])
def test_csp_at_the_masters_sync_moves_as_0x60c2_says_not_stop_and_go(drives, period_ms, node_id):
    """A master of its own at a 10 or 20 ms SYNC (the simulator started at its default 2 ms),
    writing only 0x60C2 to match (no 0x1006, as ros2_canopen's examples and canopen's own node
    leave it), cyclic synchronous position with controlword and target in the EDS's RPDO1 after
    each SYNC: the drive interpolates each setpoint over the period -- its velocity, read at any
    moment of the cruise, is the commanded one (not 2 ms of motion and the rest standstill) -- and
    the axis arrives when the profile ends.  Before, the drive kept its 2 ms and faulted.  (An axis
    of its own each: switched off at the end, Z falls onto its end stop.)"""
    network = drives
    node = canopen.BaseNode402(node_id, str(PROJECT_EDS))
    network.add_node(node)
    node.nmt.state = "PRE-OPERATIONAL"
    node.sdo[0x60C2][2].raw, node.sdo[0x60C2][1].raw = -3, period_ms  # period_ms × 10⁻³ s
    node.setup_402_state_machine()
    node.nmt.state = "OPERATIONAL"
    node.op_mode = "CYCLIC SYNCHRONOUS POSITION"
    pdo = node.rpdo[1]  # 0x6040 + 0x607A, synchronous
    start = node.sdo[0x6064].raw
    per_rad = 1048576 / (2 * math.pi)
    speed, accel, period = 2.0 * per_rad, 10.0 * per_rad, period_ms / 1e3  # [inc/s], [inc/s²], [s]
    ramp, cruise = speed / accel, 1.0  # [s]
    # the setpoints of a trapezoid: ramp, 1 s at speed, ramp
    target = np.round(trapezoid(start, start + speed * (ramp + cruise), speed, accel, period)).astype(int)
    sampled: list[float] = []
    controlword = [0x06]

    def master() -> None:  # SYNC, then the setpoint for the period it opens, on an absolute schedule
        t0 = time.monotonic()
        hold = round(0.5 / period)  # 0.5 s before the profile, 1 s after it
        for k, setpoint in enumerate([start] * hold + list(target) + [int(target[-1])] * 2 * hold):
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
        time.sleep(3 * period)  # the last RPDO (enable operation) taken first: the drive's grid arms it
        node.sdo[0x6040].raw = 0x06
    velocity = np.array(sampled)
    assert len(velocity) > 30
    assert np.median(velocity) == pytest.approx(speed, rel=0.1)  # moving at the commanded speed ...
    assert (
        np.percentile(velocity, 5) > 0.7 * speed and np.percentile(velocity, 95) < 1.3 * speed
    )  # ... steadily
    assert abs(arrived - target[-1]) < 0.01 * per_rad  # and there when the profile ended (+1 s)
    del network[node_id]


def test_an_interpolation_period_the_loops_cannot_run_is_refused_with_an_sdo_abort(drives):
    """0x60C2 = 3 × 10⁻⁴ s (not a whole number of the 0.5 ms loop tick) is refused with abort
    0x06090030 (value range) a master can read, and the period the drive keeps is the one before;
    a change while the drive is enabled is refused as the device state's (0x08000022)."""
    network = drives
    node = network.add_node(1, str(PROJECT_EDS))
    node.nmt.state = "PRE-OPERATIONAL"
    node.sdo[0x60C2][2].raw, node.sdo[0x60C2][1].raw = -3, 10
    node.sdo[0x60C2][2].raw = -4  # 10 × 10⁻⁴ s = 1 ms: whole ticks
    with pytest.raises(canopen.SdoAbortedError) as refused:
        node.sdo[0x60C2][1].raw = 3  # 0.3 ms
    assert refused.value.code == 0x06090030
    assert (node.sdo[0x60C2][1].raw, node.sdo[0x60C2][2].raw) == (10, -4)
    node.sdo[0x60C2][2].raw, node.sdo[0x60C2][1].raw = -3, 10  # back to the module's 10 ms
    del network[1]


PER_REV = 1048576  # the simulated drives' position unit: encoder increments per motor revolution
#: a replaying master's SYNC gap [ms] past which a drive may rightly stop it (5 periods: half the
#: drives' setpoint watch), and how many replays a stalled player gets
RIDE_MS, REPLAYS = 10.0, 4


class Tpdo1:
    """A node's TPDO1 as the master receives it (the EDS's own mapping: statusword 0x6041,
    position actual 0x6064, sent on each SYNC), with the bus's time stamps."""

    def __init__(self, network: canopen.Network, node_id: int):
        self.rows: list[tuple[float, int, int]] = []
        network.subscribe(0x180 + node_id, self._take)

    def _take(self, _cob: int, data: bytearray, stamp: float) -> None:
        self.rows.append(
            (stamp, int.from_bytes(data[0:2], "little"), int.from_bytes(data[2:6], "little", signed=True))
        )

    def since(self, start: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(time since ``start`` [s], statusword, position [inc]) of the frames received after it."""
        rows = np.array([r for r in self.rows if r[0] >= start], dtype=float)
        return rows[:, 0] - start, rows[:, 1].astype(int), rows[:, 2]

    def wait(self, mask: int, value: int, timeout: float) -> float:
        """The stamp of the first frame from now on whose statusword has ``value`` under ``mask``."""
        seen, deadline = len(self.rows), time.monotonic() + timeout
        while time.monotonic() < deadline:
            for stamp, word, _ in self.rows[seen:]:
                if word & mask == value:
                    return stamp
            time.sleep(0.01)
        raise AssertionError(f"statusword & 0x{mask:04X} never 0x{value:04X}: last 0x{self.rows[-1][1]:04X}")


def velocity(t: np.ndarray, position: np.ndarray) -> np.ndarray:
    """[rev/s] between successive frames."""
    return np.diff(position) / np.diff(t) / PER_REV


@contextlib.contextmanager
def operational(network: canopen.Network, node_id: int) -> Iterator[tuple[canopen.BaseNode402, Tpdo1]]:
    """Node ``node_id`` as canopen's CiA 402 node, OPERATIONAL, SYNC every 10 ms with its RPDO1
    (controlword, target) sent after each as a periodic PDO; left SWITCH ON DISABLED."""
    node = canopen.BaseNode402(node_id, str(PROJECT_EDS))
    # canopen waits 0.2 s for each statusword TPDO while it switches states; the SYNC that brings
    # it comes from a thread of this process, which a machine loaded by the other tests' processes
    # (and two CPU-bound loops) held up for longer once: the drive's punctuality is what the
    # tests below measure, frame by frame, not this process's
    node.TIMEOUT_CHECK_TPDO = 1.0
    network.add_node(node)
    node.nmt.state = "PRE-OPERATIONAL"
    node.sdo[0x60C2][2].raw, node.sdo[0x60C2][1].raw = -3, 10  # the interpolation period: the SYNC's
    node.setup_402_state_machine()
    tpdo = Tpdo1(network, node_id)
    node.nmt.state = "OPERATIONAL"
    node.rpdo[1][0].raw, node.rpdo[1][1].raw = 0x06, node.sdo[0x6064].raw
    network.sync.start(0.01)
    node.rpdo[1].start(0.01)
    try:
        yield node, tpdo
    finally:
        node.state = "SWITCH ON DISABLED"
        node.rpdo[1].stop()
        network.sync.stop()
        del network[node_id]


@pytest.fixture
def node402(drives) -> Iterator[tuple[canopen.BaseNode402, Tpdo1]]:
    """Node 2, :func:`operational`."""
    with operational(drives, 2) as started:
        yield started


def test_profile_velocity_takes_its_ramp_time_and_says_reached_only_at_speed(node402):
    """Profile velocity, 0 -> 4 rev/s at 0x6083 = 4 rev/s²: the axis takes the 1 s its ramp says
    (±10 %); bit 10 (target reached) is clear while it ramps and set at speed, bit 12 (speed = 0)
    is set only while it stands."""
    node, tpdo = node402
    node.op_mode = "PROFILED VELOCITY"
    node.sdo[0x6083].raw = 4 * PER_REV
    node.sdo[0x60FF].raw = 0
    node.state = "OPERATION ENABLED"
    standing = tpdo.wait(0x1000, 0x1000, 2.0)  # enabled, standing: speed = 0
    start = time.time()
    assert start > standing
    node.sdo[0x60FF].raw = 4 * PER_REV
    reached = tpdo.wait(0x0400, 0x0400, 3.0) - start
    time.sleep(0.3)
    t, word, position = tpdo.since(start)
    v = velocity(t, position)
    assert reached == pytest.approx(1.0, rel=0.1), reached
    ramping = (t[1:] > 0.1) & (t[1:] < reached - 0.05)
    assert not np.any(word[1:][ramping] & 0x0400)  # not reached while it ramps ...
    # ... below speed: ramping (the mean of a ramp from 0.1 s to its end; frame by frame the reception
    # stamps of a loaded machine scatter the velocity read from them by several %)
    assert np.mean(v[ramping]) == pytest.approx(0.5 * 4.0 * (0.1 + reached - 0.05), rel=0.15)
    at_speed = t[1:] > reached + 0.02
    assert np.all(word[1:][at_speed] & 0x0400)  # reached ...
    assert np.median(v[at_speed]) == pytest.approx(4.0, rel=0.02)  # ... at the target velocity
    assert not np.any(word[1:][t[1:] > 0.1] & 0x1000)  # moving: speed is not 0
    node.sdo[0x60FF].raw = 0
    tpdo.wait(0x1400, 0x1400, 3.0)  # at rest again: reached, speed = 0


def test_profile_position_takes_the_time_its_trapezoid_says_and_reached_means_there(node402):
    """Half a turn at 0x6081 = 1 rev/s, 0x6083 = 0x6084 = 4 rev/s²: 0.25 s up, 0.25 s at speed,
    0.25 s down -- set-point acknowledged (bit 12) as the profile starts, target reached (bit 10)
    0.75 s later (±10 %) with the axis in the position window, and not before."""
    node, tpdo = node402
    node.op_mode = "PROFILED POSITION"
    for index, value in ((0x6081, PER_REV), (0x6083, 4 * PER_REV), (0x6084, 4 * PER_REV)):
        node.sdo[index].raw = value
    node.state = "OPERATION ENABLED"
    pdo = node.rpdo[1]
    start_position = node.sdo[0x6064].raw
    target = start_position + PER_REV // 2
    time.sleep(0.1)
    start = time.time()
    pdo[1].raw, pdo[0].raw = target, 0x1F  # target and new set-point in one PDO
    acknowledged = tpdo.wait(0x1000, 0x1000, 2.0) - start
    reached = tpdo.wait(0x0400, 0x0400, 3.0) - start
    t, word, position = tpdo.since(start)
    moving = np.flatnonzero(np.abs(position - start_position) > 0.0005 * PER_REV)
    assert t[moving[0]] > acknowledged  # the profile starts with the acknowledgement ...
    assert reached - acknowledged == pytest.approx(0.75, rel=0.1), (
        acknowledged,
        reached,
    )  # ... and ends on time
    before = t < reached - 0.005
    assert not np.any(word[before & (t > acknowledged)] & 0x0400)
    assert np.all(np.abs(position[t >= reached] - target) <= node.sdo[0x6067].raw)
    pdo[0].raw = 0x0F


def test_quick_stop_takes_its_ramp_and_a_fault_is_reset_as_canopens_node_resets_it(drives, node402):
    """At 4 rev/s in profile velocity, quick stop (0x605A = 6: ramp on 0x6085, stay) stops the axis
    in the 0.5 s of 0x6085 = 8 rev/s² (±10 %), says QUICK STOP ACTIVE and target reached only at
    rest; enable operation takes it back. The master's heartbeat then stops with 0x6007 = 1: the
    drive faults (EMCY 0x8130, statusword bit 3), and canopen's fault reset clears it (EMCY 0x0000)."""
    network, (node, tpdo) = drives, node402
    emcy: list[int] = []
    network.subscribe(0x82, lambda cob, data, ts: emcy.append(data[0] | data[1] << 8))
    node.op_mode = "PROFILED VELOCITY"
    node.sdo[0x6083].raw, node.sdo[0x6085].raw, node.sdo[0x605A].raw = 8 * PER_REV, 8 * PER_REV, 6
    node.sdo[0x60FF].raw = 4 * PER_REV
    node.state = "OPERATION ENABLED"
    tpdo.wait(0x0400, 0x0400, 3.0)  # at speed
    start = time.time()
    node.rpdo[1][0].raw = 0x0B  # quick stop
    stopped = tpdo.wait(0x046F, 0x0407, 3.0) - start  # QUICK STOP ACTIVE, target reached
    t, word, position = tpdo.since(start)
    v = velocity(t, position)
    assert stopped == pytest.approx(0.5, rel=0.1), stopped
    assert np.all(np.abs(v[t[1:] > stopped + 0.02]) < 0.01)
    assert not np.any(word[(t > 0.02) & (t < stopped - 0.005)] & 0x0400)
    node.rpdo[1][0].raw = 0x0F  # enable operation: back from QUICK STOP ACTIVE
    tpdo.wait(0x006F, 0x0027, 2.0)
    node.sdo[0x60FF].raw = 0
    node.sdo[0x6007].raw = 1  # the master lost: fault
    node.sdo[0x1016][1].raw = 0x7F << 16 | 100  # watch node 127 every 100 ms
    for _ in range(3):
        network.send_message(0x77F, [0x05])
        time.sleep(0.05)
    deadline = time.monotonic() + 2.0  # (by SDO: the drive fell back to PRE-OPERATIONAL, no TPDO)
    while not node.sdo[0x6041].raw & 0x0008 and time.monotonic() < deadline:
        time.sleep(0.02)
    assert node.sdo[0x6041].raw & 0x0008 and 0x8130 in emcy  # FAULT, once its heartbeats stopped
    node.sdo[0x1016][1].raw = 0  # (watch nothing while the master is away)
    node.nmt.state = "OPERATIONAL"
    tpdo.wait(0x0008, 0x0008, 2.0)  # its TPDOs flow again, saying FAULT: the state canopen starts from
    node.state = "SWITCH ON DISABLED"  # canopen's fault reset (controlword bit 7)
    assert not node.sdo[0x6041].raw & 0x0008 and emcy[-1] == 0x0000


def test_homing_on_the_limit_switch_says_attained_and_reached_as_cia_402_tables_them(drives):
    """Homing method 17 (negative limit switch) on z, which rests on its lower end stop: before
    the start, 'not started' (bit 10 set, 12 clear); while it leaves the switch at the zero speed,
    'in progress' (10 and 12 clear); then 'attained' and, once at rest, 'completed' (10 and 12
    set), the position counted from the switch's edge as home (0x607C = 0), the search moving at
    the zero speed 0x6099:2."""
    with operational(drives, 3) as (node, tpdo):
        node.op_mode = "HOMING"
        zero_speed = PER_REV // 10  # 0.1 rev/s
        node.sdo[0x6098].raw, node.sdo[0x609A].raw, node.sdo[0x607C].raw = 17, 10 * PER_REV, 0
        node.sdo[0x6099][1].raw, node.sdo[0x6099][2].raw = PER_REV, zero_speed  # switch, zero speed
        resting = node.sdo[0x6064].raw + 1000
        while abs(node.sdo[0x6064].raw - resting) > 10:  # at rest (an earlier test may have let it fall)
            resting = node.sdo[0x6064].raw
            time.sleep(0.2)
        node.state = "OPERATION ENABLED"
        tpdo.wait(0x3400, 0x0400, 2.0)  # homing not started
        start = time.time()
        node.rpdo[1][0].raw = 0x1F  # start homing
        attained = tpdo.wait(0x1000, 0x1000, 10.0) - start
        completed = tpdo.wait(0x3400, 0x1400, 3.0) - start
        t, word, position = tpdo.since(start)
        searching = (t > 0.1) & (t < attained - 0.005)
        assert not np.any(word[searching] & 0x3400)  # in progress: bits 10, 12, 13 clear
        assert np.median(velocity(t, position)[searching[1:]]) == pytest.approx(0.1, rel=0.1)  # zero speed
        first = np.flatnonzero(t >= attained)[0]
        assert abs(position[first]) < 0.1 * 0.03 * PER_REV  # attained on the edge (3 periods at the zero
        # speed), counted as home
        assert completed > attained and abs(position[-1]) < 0.01 * PER_REV


def _emcy_code(frame: can.Message) -> int:
    """The error code of an EMCY frame (0: an error reset)."""
    return int.from_bytes(frame.data[:2], "little")


def _is_masters(cob_id: int) -> bool:
    """NMT, SYNC, an SDO request, an RPDO 1-4 or the master's heartbeat (node 127)."""
    return (
        cob_id in (0x000, 0x080, 0x77F)
        or 0x601 <= cob_id <= 0x67F
        or any(base < cob_id <= base + 0x7F for base in (0x200, 0x300, 0x400, 0x500))
    )


def test_a_lockstep_trace_replayed_by_can_player_reaches_the_drives_frame_for_frame(tmp_path):
    """``record --sim`` in lockstep writes trace.blf; its start-up reads as a bus carried it (an SDO
    answer a loop tick after its request, no two requests at one instant), and the master's
    frames of it, replayed by python-can's ``can.player`` at their own time stamps to a fresh
    ``drive-bridge sim``, are each answered as in the trace: every SDO response, a TPDO for every
    SYNC, no EMCY while the replay lasts (its heartbeat consumer times out after it, as it should),
    the axis where the trace left it."""
    assert main(["record", "--sim", "--quick", "--axes", "z", "--out", str(tmp_path / "run")]) == 0
    with can.LogReader(str(tmp_path / "run" / "trace.blf")) as reader:
        frames = list(reader)
    ids = [f.arbitration_id for f in frames]
    startup = frames[: ids.index(0x080)]
    requests = [f.timestamp for f in startup if 0x601 <= f.arbitration_id <= 0x67F]
    assert len(set(requests)) == len(requests) > 100
    for request, answer in zip(startup, startup[1:]):
        if request.arbitration_id == 0x603 and answer.arbitration_id == 0x583:
            assert answer.timestamp - request.timestamp >= 0.0004
    replay = tmp_path / "replay.blf"
    masters = [frame for frame in frames if _is_masters(frame.arbitration_id)]
    with can.Logger(str(replay)) as writer:
        for frame in masters:
            writer.on_message_received(frame)

    def replayed() -> list[can.Message]:
        """The frames a fresh ``drive-bridge sim`` heard while ``can.player`` replayed the master's,
        the player asking for SCHED_FIFO as a master's cyclic process does (where granted)."""
        process, _, port = start_sim(tmp_path)
        heard: list[can.Message] = []
        try:
            # (python-can's udp_multicast_noecho: this project's; every frame stamped when it reached
            # this socket, the master's and the drives' on one clock, so this listener may read them
            # late: at normal priority beside the player and the drives, first in line for the CPU,
            # it can be held up for seconds -- its receive buffer holds the whole replay, and it
            # listens until it has read the last of it)
            with can.Bus(
                interface="udp_multicast_noecho",
                channel=UDP_GROUP,
                port=port,
                stamps="kernel",
                receive_buffer=64 << 20,
            ) as bus:
                notifier = can.Notifier(bus, [heard.append])
                player = [sys.executable, "-m", "can.player", "-i", "udp_multicast", "-c", UDP_GROUP]
                bus_kwargs = ["--bus-kwargs", f"port={port}", "--gap", "0"]  # (an option ends the list)
                subprocess.run(
                    [*player, *bus_kwargs, str(replay)], check=True, timeout=120, preexec_fn=raise_priority
                )
                deadline = time.monotonic() + 60
                while sum(_is_masters(m.arbitration_id) for m in list(heard)) < len(masters):
                    if time.monotonic() > deadline:
                        break  # (what did not come is counted below)
                    time.sleep(0.1)
                time.sleep(0.2)  # the drives' answers to the last
                notifier.stop()
        finally:
            process.terminate()
            process.wait(10)
        return heard

    def player_stalled(heard: list[can.Message]) -> bool:
        """A drive sent an EMCY while the replay lasted, and the player's SYNCs had stopped longer
        than :data:`RIDE_MS` (a master this late drops a drive as it would a real one: its
        setpoint watch, or a following error once setpoints resume after Z's extrapolation)."""
        until = max(m.timestamp for m in heard if _is_masters(m.arbitration_id))
        emcy = [
            m for m in heard if 0x81 <= m.arbitration_id <= 0xFF and _emcy_code(m) and m.timestamp <= until
        ]
        gaps = np.diff([m.timestamp for m in heard if m.arbitration_id == 0x080])
        return bool(emcy) and 1e3 * float(gaps.max()) > RIDE_MS

    # can.player is not ours: a replay its own process stalled (its SYNCs stopped longer than a drive
    # rides out) runs again; an EMCY while its SYNCs kept coming is the simulated drives' and fails
    for _ in range(REPLAYS):
        heard = replayed()
        if not player_stalled(heard):
            break
    else:
        raise AssertionError(
            f"can.player's SYNCs stopped longer than {RIDE_MS} ms in each of {REPLAYS} replays"
        )
    drives = [m for m in heard if not _is_masters(m.arbitration_id)]
    replayed_until = max(m.timestamp for m in heard if _is_masters(m.arbitration_id))
    syncs = np.diff([m.timestamp for m in heard if m.arbitration_id == 0x080])

    def count(frames: list[can.Message], cob_id: int) -> int:
        return sum(f.arbitration_id == cob_id for f in frames)

    assert count(heard, 0x080) == count(frames, 0x080)  # the whole replay went out
    for cob_id in (0x581, 0x582, 0x583, 0x183, 0x283):
        assert count(drives, cob_id) == count(frames, cob_id), hex(cob_id)
    emcy = [m for m in drives if 0x81 <= m.arbitration_id <= 0xFF and _emcy_code(m)]
    assert not [m for m in emcy if m.timestamp <= replayed_until], (  # none while the master's frames came
        f"EMCY {[hex(_emcy_code(m)) for m in emcy]} while the replay lasted, its SYNCs at most "
        f"{1e3 * syncs.max():.1f} ms apart"
    )
    last = [m for m in drives if m.arbitration_id == 0x183][-1]
    traced = [f for f in frames if f.arbitration_id == 0x183][-1]
    assert (
        abs(
            int.from_bytes(last.data[:4], "little", signed=True)
            - int.from_bytes(traced.data[:4], "little", signed=True)
        )
        < PER_REV // 100
    )
