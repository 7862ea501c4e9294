"""The simulated drives are as strict as real ones: where a real drive would jump, fall, fault or
refuse, so do they (each test here fails against a lenient simulator)."""

from __future__ import annotations

from dataclasses import replace

import canopen
import pytest

from drive_bridge.sim import kernel
from harness.paths import VENDOR_EDS
from harness.support import Bench, clean_config

pytestmark = pytest.mark.slow

GRAVITY_Z = {"z": {"load": {"LOAD": 0.4}}}  # above the screw's 0.323 Nm of friction


def falling_z(brake: bool):
    cfg = clean_config(effects=GRAVITY_Z)
    cfg.axes["z"] = replace(cfg.axes["z"], brake=brake)
    return cfg


@pytest.mark.parametrize("brake", [False, True])
def test_a_disabled_vertical_axis_falls_without_a_brake_and_stands_with_one(bench, brake):
    b = bench(falling_z(brake))
    b.link.clock.sleep(0.5)
    q = b.robot.plant.state[2, kernel.Q]
    if brake:
        assert q == 0.0
    else:
        assert q < -10.0  # 0.5 s of free fall against viscous friction: tens of rad


def test_an_end_stop_stops_the_fall():
    cfg = falling_z(False)
    cfg.axes["z"] = replace(cfg.axes["z"], end_stops_rad=(-5.0, 5.0))
    b = Bench(cfg)
    b.link.clock.sleep(1.0)
    assert b.robot.plant.state[2, kernel.Q] == -5.0 and b.robot.plant.state[2, kernel.V] == 0.0


def _enable_by_sdo(node):
    for cw in (0x06, 0x07, 0x0F):
        node.sdo[0x6040].raw = cw


def test_csp_enable_takes_the_target_as_it_stands_and_a_stale_one_makes_the_axis_jump(bench):
    b = bench()
    node = b.nodes["y"]
    node.nmt.send_command(0x80)
    node.sdo[0x6060].raw = 8
    start = node.sdo[0x6064].raw
    node.sdo[0x607A].raw = start + 2_000_000  # stale: 12 rad away
    _enable_by_sdo(node)
    codes = []
    node.emcy.add_callback(lambda e: codes.append(e.code))
    b.link.clock.sleep(0.05)
    assert abs(node.sdo[0x6064].raw - start) > 10_000  # it jumped toward the stale target ...
    assert 0x8611 in codes  # ... and faulted on the following error
    assert node.sdo[0x6041].raw & 0x0008


def test_csp_enable_with_the_target_preloaded_does_not_move(bench):
    b = bench()
    node = b.nodes["y"]
    node.sdo[0x6060].raw = 8
    start = node.sdo[0x6064].raw
    node.sdo[0x607A].raw = start
    _enable_by_sdo(node)
    b.link.clock.sleep(0.05)
    assert abs(node.sdo[0x6064].raw - start) <= 2 and not node.sdo[0x6041].raw & 0x0008


@pytest.mark.parametrize(
    "option, state",
    [(3, "QUICK STOP ACTIVE"), (1, "FAULT"), (2, "SWITCH ON DISABLED"), (0, "OPERATION ENABLED")],
)
def test_the_heartbeat_consumer_acts_when_the_master_falls_silent(bench, option, state):
    from drive_bridge.cia.p402 import state_name

    b = bench()
    node = b.nodes["x"]
    node.sdo[0x1016][1].raw = 127 << 16 | 300
    node.sdo[0x6007].raw = option
    node.sdo[0x605A].raw = 6
    node.sdo[0x6060].raw = 8
    node.sdo[0x607A].raw = node.sdo[0x6064].raw
    _enable_by_sdo(node)
    codes = []
    node.emcy.add_callback(lambda e: codes.append(e.code))
    b.link.start_heartbeat(127, 0.1)
    b.link.clock.sleep(1.0)
    assert state_name(node.sdo[0x6041].raw) == "OPERATION ENABLED" and not codes  # watched, alive
    b.link.stop_heartbeat()
    b.link.clock.sleep(0.25)
    assert state_name(node.sdo[0x6041].raw) == "OPERATION ENABLED"  # not yet: 0.3 s
    b.link.clock.sleep(0.2)
    assert 0x8130 in codes and state_name(node.sdo[0x6041].raw) == state


def _abort(fn):
    with pytest.raises(canopen.SdoAbortedError) as exc:
        fn()
    return exc.value.code


def test_pdo_parameters_are_refused_as_cia301_refuses_them(bench):
    node = bench().nodes["x"]
    node.nmt.send_command(0x80)
    tpdo, rpdo = node.sdo[0x1800], node.sdo[0x1400]
    assert _abort(lambda: setattr(tpdo[2], "raw", 245)) == 0x06090030  # reserved transmission type
    assert _abort(lambda: setattr(rpdo[2], "raw", 252)) == 0x06090030  # RTR types are not an RPDO's
    tpdo[1].raw = tpdo[1].raw | 0x8000_0000
    tpdo[1].raw = 0x8000_0701  # a restricted CAN-ID may stand while the PDO is invalid ...
    assert _abort(lambda: setattr(tpdo[1], "raw", 0x701)) == 0x06090030  # ... never in a valid PDO
    tpdo[1].raw = 0x8000_0181
    mapping = node.sdo[0x1A00]
    mapping[0].raw = 0
    assert _abort(lambda: setattr(mapping[1], "raw", 0x6064_0010)) == 0x06040041  # 16 bits of a 32-bit object
    mapping[1].raw = 0x6064_0020  # its own length is fine


def test_an_rpdo_shorter_than_its_mapping_raises_emcy_8210(bench):
    b = bench()
    node = b.nodes["x"]
    codes = []
    node.emcy.add_callback(lambda e: codes.append(e.code))
    node.nmt.send_command(0x01)
    b.net.send_message(0x201, b"\x06\x00")  # RPDO1 of the factory mapping is longer
    b.robot.process()
    b.link.pump()
    assert 0x8210 in codes


def test_an_event_driven_tpdo_is_sent(bench):
    b = bench()
    node = b.nodes["x"]
    seen = []
    b.net.subscribe(0x181, lambda cob, data, ts: seen.append(ts))
    node.nmt.send_command(0x80)
    tpdo = node.sdo[0x1800]
    tpdo[1].raw = 0x8000_0181
    tpdo[2].raw = 255
    tpdo[5].raw = 100  # event timer: 100 ms
    tpdo[1].raw = 0x181
    node.nmt.send_command(0x01)
    b.link.clock.sleep(1.0)
    b.link.pump()
    assert 8 <= len(seen) <= 12  # on its timer (the axis stands: no change of data)


def test_the_nanotec_faithful_drive_starts_in_its_factory_units_and_changes_them_when_told(bench):
    eds = VENDOR_EDS / "nanotec_C5-E-2-09.eds"
    if not eds.exists():
        pytest.skip("../shared/eds-vendor not present")
    b = Bench(clean_config(), eds=eds)
    node, drive = b.nodes["y"], b.robot.drives["y"]
    assert node.sdo[0x60A8].raw == 0xFF410000 and node.sdo[0x60A9].raw == 0x00B44700
    b.robot.plant.state[1, kernel.Q] = 1.0
    drive.refresh_actuals()
    assert abs(node.sdo[0x6064].raw - 573) <= 1  # 1 rad in tenths of a degree
    node.sdo[0x60A8].raw = 0x00B50000  # encoder increments
    drive.refresh_actuals()
    assert abs(node.sdo[0x6064].raw - 65536 / 6.283185307) <= 1


def _epos2():
    eds = VENDOR_EDS / "maxon_epos2_50-5.eds"
    if not eds.exists():
        pytest.skip("../shared/eds-vendor not present")
    return Bench(clean_config(), eds=eds)


def _interpolating(b, node):
    """EPOS2-faithful drive y in interpolated position (PVT), buffer enabled, interpolation active."""
    node.nmt.send_command(0x80)
    node.sdo[0x60C4][6].raw = 0
    node.sdo[0x60C4][6].raw = 1
    node.sdo[0x6060].raw = 7
    for cw in (0x06, 0x07, 0x0F, 0x1F):
        node.sdo[0x6040].raw = cw


def test_the_maxon_fifo_underflows_when_a_record_does_not_come():
    """maxon's PVT records are taken on the drive's own clock, each after its own time, SYNC or
    not: four records of 20 ms keep it interpolating for 80 ms; past them the buffer underflows,
    a fault with EMCY 0xFF02."""
    from drive_bridge.cia.setpoint import pack_pvt

    b = _epos2()
    node, drive = b.nodes["y"], b.robot.drives["y"]
    codes = []
    node.emcy.add_callback(lambda e: codes.append(e.code))
    start = node.sdo[0x6064].raw
    node.nmt.send_command(0x80)
    node.sdo[0x60C4][6].raw = 0
    node.sdo[0x60C4][6].raw = 1
    assert node.sdo[0x60C4][1].raw == 64  # the drive says its size (maxon's EDS gives none)
    for k in range(1, 5):
        node.sdo[0x20C1].raw = pack_pvt(start + 10 * k, 0, 20)
    node.sdo[0x6060].raw = 7
    for cw in (0x06, 0x07, 0x0F, 0x1F):
        node.sdo[0x6040].raw = cw
    b.net.sync.transmit()  # interpolation starts with the period: the first record
    b.link.pump()
    b.robot.idle(0.050)  # no SYNC: the records go on, one each 20 ms
    assert len(drive.pvt.records) == 1
    assert not node.sdo[0x6041].raw & 0x0008 and node.sdo[0x20C4][1].raw & 0xC000 == 0xC000
    b.robot.idle(0.050)  # past the last record's time: nothing to take
    b.link.pump()
    assert node.sdo[0x6041].raw & 0x0008 and node.sdo[0x20C4][1].raw & 0x0100 and 0xFF02 in codes


def test_the_maxon_fifo_overflows_past_64_records_and_ignores_records_while_disabled():
    from drive_bridge.cia.setpoint import pack_pvt

    b = _epos2()
    node = b.nodes["y"]
    node.sdo[0x20C1].raw = pack_pvt(10**6, 0, 2)  # buffer access not enabled: dropped
    assert len(b.robot.drives["y"].pvt.records) == 0
    node.sdo[0x60C4][6].raw = 1
    for _ in range(64):
        node.sdo[0x20C1].raw = pack_pvt(0, 0, 2)
    b.robot.drives["y"].refresh_actuals()
    assert node.sdo[0x20C4][1].raw & 0x0002  # above the overflow warning level (60)
    node.sdo[0x20C1].raw = pack_pvt(0, 0, 2)
    b.robot.drives["y"].refresh_actuals()
    assert node.sdo[0x20C4][1].raw & 0x0200 and node.sdo[0x6041].raw & 0x0008


def _filling(b, node):
    """The project's drive y in interpolated position with its deep FIFO (0x60C4) enabled, enabled
    without interpolation (bit 4 clear): records wait in the buffer."""
    node.nmt.send_command(0x80)
    node.sdo[0x60C4][6].raw = 0
    node.sdo[0x60C4][6].raw = 1
    node.sdo[0x6060].raw = 7
    for cw in (0x06, 0x07, 0x0F):
        node.sdo[0x6040].raw = cw


def test_the_deep_fifo_takes_one_record_a_period_and_a_run_dry_is_a_planned_stop(bench):
    """Records written ahead wait while interpolation is off, then go one a SYNC; past the last the
    drive ramps down on its quick-stop deceleration and holds, enabled, bit 12 clear, no EMCY (a
    strict drive with a one-record buffer would fault on the missing setpoint instead); bit 4 off
    and on again resumes from the records written meanwhile."""
    b = bench()
    node, drive = b.nodes["y"], b.robot.drives["y"]
    codes = []
    node.emcy.add_callback(lambda e: codes.append(e.code))
    _filling(b, node)
    start = node.sdo[0x6064].raw
    step = 2000  # increments a period: about 6 rad/s
    for k in range(1, 301):
        node.sdo[0x60C1][1].raw = start + k * step
    assert node.sdo[0x60C4][2].raw == 300  # all held while interpolation is off
    b.net.sync.transmit()
    assert node.sdo[0x60C4][2].raw == 300 and abs(node.sdo[0x6064].raw - start) < 50
    node.sdo[0x6040].raw = 0x1F
    for _ in range(100):
        b.net.sync.transmit()
    b.link.pump()
    assert node.sdo[0x60C4][2].raw == 200 and node.sdo[0x6041].raw & 0x1000  # interpolation active
    moved = node.sdo[0x6064].raw - start
    assert 95 * step < moved < 101 * step
    for _ in range(250):  # 200 records left, then 50 periods without one
        b.net.sync.transmit()
    b.link.pump()
    status = node.sdo[0x6041].raw
    assert drive.ran_dry and status & 0x006F == 0x0027 and not status & 0x1000 and codes == []
    stopped_at = node.sdo[0x6064].raw
    assert stopped_at > start + 300 * step  # it ramped down past the last record, not a jump back
    for _ in range(20):
        b.net.sync.transmit()
    assert abs(node.sdo[0x6064].raw - stopped_at) < 200  # held
    for k in range(1, 11):  # the master back: its records, then bit 4 again
        node.sdo[0x60C1][1].raw = stopped_at - k * step
    node.sdo[0x6040].raw = 0x0F
    node.sdo[0x6040].raw = 0x1F
    for _ in range(12):
        b.net.sync.transmit()
    b.link.pump()
    assert not drive.ran_dry or node.sdo[0x60C4][2].raw == 0
    assert node.sdo[0x6064].raw < stopped_at - 5 * step and codes == []


def test_the_deep_fifo_faults_on_an_overflow(bench):
    b = bench()
    node = b.nodes["y"]
    _filling(b, node)
    capacity = node.sdo[0x60C4][1].raw
    start = node.sdo[0x6064].raw
    for _ in range(capacity):
        node.sdo[0x60C1][1].raw = start
    assert not node.sdo[0x6041].raw & 0x0008
    node.sdo[0x60C1][1].raw = start
    assert node.sdo[0x6041].raw & 0x0008  # FAULT


def test_a_sync_of_another_length_than_its_counter_says_is_answered_with_emcy_8240(bench):
    """CiA 301: a SYNC consumer whose 0x1019 is 0 expects no data, one whose 0x1019 is 2..240 the
    counter byte; any other length is answered with EMCY 0x8240 (the SYNC still taken)."""
    b = bench()
    node = b.nodes["y"]
    codes = []
    node.emcy.add_callback(lambda e: codes.append(e.code))
    node.nmt.send_command(0x80)
    b.net.send_message(0x80, b"\x01")  # a counted SYNC; the drive counts none
    b.link.pump()
    assert 0x8240 in codes
    codes.clear()
    node.sdo[0x1006].raw = 0
    node.sdo[0x1019].raw = 240
    b.net.send_message(0x80, b"\x02")
    b.link.pump()
    assert codes == []
    b.net.sync.transmit()  # a SYNC without the counter, now
    b.link.pump()
    assert 0x8240 in codes
