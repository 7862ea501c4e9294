"""Simulated drives built from the vendor EDS/DCF files (read in place): each behaves as that drive
on the bus -- its identity, only the modes its 0x6502 lists, its feedback objects and units, no
object its file lacks, its gain objects driving the same loops through the profile's scales."""

from __future__ import annotations

import math

import canopen
import pytest

from drive_bridge.cia.setpoint import supported_modes
from drive_bridge.params.profile import load_profile
from drive_bridge.params.read import sdo_variable
from drive_bridge.resources import vendor_dir
from drive_bridge.sim import kernel
from drive_bridge.sim.vendors import SPECS
from harness.support import Bench, clean_config

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(not vendor_dir().is_dir(), reason="../shared/eds-vendor not present"),
]
VENDOR_FILES = sorted(n for n in SPECS if n != "drive_bridge_servo.eds")


def bench(name: str) -> tuple[Bench, canopen.RemoteNode]:
    b = Bench(clean_config(), eds=vendor_dir() / name)
    return b, b.nodes["y"]


@pytest.mark.parametrize("name", VENDOR_FILES)
def test_identity_and_modes_are_the_files(name):
    b, node = bench(name)
    info = node.object_dictionary.device_information
    for sub, want in ((1, info.vendor_number), (2, info.product_number), (3, info.revision_number)):
        assert node.sdo[0x1018][sub].raw == (want or 0)
    assert node.sdo[0x1000].raw & 0xFFFF == 402
    bits = node.sdo[0x6502].raw
    listed = supported_modes(bits)
    assert listed == supported_modes(SPECS[name].supported_modes or node.object_dictionary[0x6502].default)
    for mode in (8, 7, 3, 1):
        if mode in listed:
            node.sdo[0x6060].raw = mode
            assert node.sdo[0x6061].raw == mode
        else:  # a mode the drive does not list is refused
            with pytest.raises(canopen.SdoAbortedError):
                node.sdo[0x6060].raw = mode


@pytest.mark.parametrize("name", VENDOR_FILES)
def test_no_object_the_file_lacks(name):
    b, node = bench(name)
    od = node.object_dictionary
    for index in (0x60B2, 0x1010, 0x6077, 0x6076):
        if index not in od:
            with pytest.raises(canopen.SdoAbortedError) as exc:
                node.sdo.upload(index, 1 if index == 0x1010 else 0)
            assert exc.value.code == 0x06020000  # object does not exist


@pytest.mark.parametrize("name", VENDOR_FILES)
def test_gains_through_the_profile_drive_the_loops(name):
    b, node = bench(name)
    profile = load_profile(SPECS[name].profile).bind(b.robot.config.axes["y"].motor.kt)
    drive = b.robot.drives["y"]
    cols = {  # what each gain drives, written out apart from the simulated drive's own map
        "KpP": kernel.KPP,
        "FwF": kernel.FWF,
        "KpS": kernel.KPS,
        "KiS": kernel.KIS,
        "KpC": kernel.KPC,
        "KiC": kernel.KIC,
        "PidP": kernel.PID_P,
        "PidI": kernel.PID_I,
        "PidD": kernel.PID_D,
        "PidFFv": kernel.PID_FFV,
        "PidFFa": kernel.PID_FFA,
    }
    if profile.select is not None:  # the Nanotec's 321Ah-321Dh run once 3212h:04 selects them
        sdo_variable(node, profile.select[0]).raw = profile.select[1]
    for param, entry in profile.entries.items():
        if param == "gain_objects":
            continue
        col = cols[param]
        value = drive.plant_param[col] * 1.25 or 1e-4
        sdo_variable(node, entry).raw = entry.to_device(value)
        assert drive.plant_param[col] == pytest.approx(
            entry.to_si(entry.held(entry.to_device(value))), rel=1e-6
        )
    if not profile.entries:  # the iPOS: no gain objects, the factory loops run
        assert drive.plant_param[kernel.KPS] > 0


def test_the_nanotec_runs_321Ah_to_321Dh_only_once_3212h_04_selects_them():
    """Strict as the drive: gains written to 321Bh change nothing while 3212h:04 = 0 (3210h runs);
    setting it switches the loops to what 321Ah-321Dh hold, clearing it back to 3210h."""
    b, node = bench("nanotec_C5-E-2-09.eds")
    drive = b.robot.drives["y"]
    kps = drive.plant_param[kernel.KPS]
    assert node.sdo[0x3212][4].raw == 0
    node.sdo[0x321B][1].raw = 2 * node.sdo[0x321B][1].raw
    assert drive.plant_param[kernel.KPS] == kps
    node.sdo[0x3212][4].raw = 1
    assert drive.plant_param[kernel.KPS] == pytest.approx(2 * kps, rel=1e-3)
    node.sdo[0x3212][4].raw = 0
    assert drive.plant_param[kernel.KPS] == kps


def test_the_epos2_runs_its_position_pid_at_1_kHz_and_its_velocity_pi_is_not_in_the_loop():
    """In its position modes the EPOS2 runs the position PID of its profile (0x60FB, current) at the
    declared 1 kHz; 0x60F9 (the velocity PI) is held but drives nothing."""
    b, node = bench("maxon_epos2_50-5.eds")
    drive = b.robot.drives["y"]
    assert drive.plant_param[kernel.STRUCT] == kernel.POSITION_PID and drive.plant_param[kernel.LOOP_DIV] == 2
    before = drive.plant_param.copy()
    node.sdo[0x60F9][1].raw = 2 * node.sdo[0x60F9][1].raw + 1
    assert (drive.plant_param == before).all()
    kt = b.robot.config.axes["y"].motor.kt
    node.sdo[0x60FB][1].raw = 3000  # 0.01 A/rad on the bus (the profile's reading)
    assert drive.plant_param[kernel.PID_P] == pytest.approx(3000 / 100 * kt)


def test_maxon_reports_velocity_in_rpm_and_current_in_mA():
    b, node = bench("maxon_epos2_50-5.eds")
    drive = b.robot.drives["y"]
    drive.plant_state[kernel.V] = drive.plant_state[kernel.VMEAS] = 10.0  # rad/s, as its loop measures it
    drive.plant_state[kernel.I_SUM], drive.plant_state[kernel.I_COUNT] = 1.5, 1.0  # 1.5 A averaged
    b.robot.advance(0)
    b.robot.plant.time += 0.002
    drive.refresh_actuals()
    own = drive.node.sdo  # its own SDO server, read at this instant (over the bus a loop tick later)
    assert own[0x6078].raw == pytest.approx(1500, abs=2)
    assert own[0x606C].raw == pytest.approx(10.0 * 60 / (2 * math.pi), abs=2)


@pytest.mark.parametrize("name", ["pilz_prbt_0_1.dcf", "technosoft_iPOS.eds"])
def test_interpolated_position_follows_only_with_bit_4(name):
    """IP: enabled with controlword 0x0F the drive holds (statusword bit 12 clear); bit 4 enables
    interpolation, bit 12 confirms it, and the records move the axis."""
    b, node = bench(name)
    node.nmt.send_command(0x01)
    node.sdo[0x60C2][1].raw, node.sdo[0x60C2][2].raw = 2, -3
    node.sdo[0x6065].raw = 10**6
    node.sdo[0x6060].raw = 7
    for cw in (0x06, 0x07, 0x0F):
        node.sdo[0x6040].raw = cw
    start = node.sdo[0x6064].raw
    inc_per_rad = b.robot.drives["y"].inc_per_rad
    node.sdo[0x60C1][1].raw = start + round(0.5 * inc_per_rad)
    for _ in range(20):
        b.net.sync.transmit()
    assert not node.sdo[0x6041].raw & 0x1000 and abs(node.sdo[0x6064].raw - start) < 0.01 * inc_per_rad
    node.sdo[0x6040].raw = 0x1F
    for k in range(1, 200):
        node.sdo[0x60C1][1].raw = start + round(min(k * 0.005, 0.5) * inc_per_rad)
        b.net.sync.transmit()
    assert node.sdo[0x6041].raw & 0x1000
    assert node.sdo[0x6064].raw - start == pytest.approx(0.5 * inc_per_rad, rel=0.01)


def test_a_nanotec_on_3210h_is_read_as_it_runs_and_switched_only_with_the_whole_set():
    """The master reads what runs (3210h through nanotec_c5e_3210 while 3212h:04 = 0), refuses a
    partial set that would switch the drive onto 321Ah-321Dh, and a whole set switches it."""
    from drive_bridge.params.read import read_parameters
    from drive_bridge.params.write import write_parameters
    from drive_bridge.sim.vendors import factory

    b, node = bench("nanotec_C5-E-2-09.eds")
    profile = load_profile("nanotec_c5e").bind(b.robot.config.axes["y"].motor.kt)
    running = read_parameters(node, profile)
    assert running["gain_objects"] == 0
    for g in ("KpP", "KpS", "KiS", "KpC", "KiC", "FwF"):
        assert running[g] == pytest.approx(factory().gains[g], rel=1e-3), g
    from drive_bridge.params.check import ValueRefused

    with pytest.raises(ValueRefused, match="needs all of them"):
        write_parameters(node, profile, {"KpS": 2 * running["KpS"]}, store=False)
    assert node.sdo[0x3212][4].raw == 0
    whole = {k: v for k, v in running.items() if k != "gain_objects"} | {"KpS": 2 * running["KpS"]}
    assert write_parameters(node, profile, whole, store=False).ok
    assert node.sdo[0x3212][4].raw == 1
    assert b.robot.drives["y"].plant_param[kernel.KPS] == pytest.approx(2 * running["KpS"], rel=1e-3)
