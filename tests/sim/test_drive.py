"""The simulated drives, seen only through the bus: SDO, PDO, NMT, EMCY, heartbeat."""

from __future__ import annotations

import math

import canopen
import numpy as np
import pytest

from drive_bridge.sim.drive import SETPOINT_TIMEOUT_PERIODS
from harness.support import clean_config

INC_PER_RAD = 2**20 / (2 * math.pi)


def map_pdos(node):
    node.tpdo.read()
    node.rpdo.read()
    for maps in (node.tpdo, node.rpdo):
        for n in (2, 3, 4):
            maps[n].enabled = False
    t = node.tpdo[1]
    t.clear()
    for index in (0x6064, 0x6077, 0x6041):
        t.add_variable(index)
    t.trans_type, t.enabled = 1, True
    r = node.rpdo[1]
    r.clear()
    r.add_variable(0x6040)
    r.add_variable(0x607A)
    r.trans_type, r.enabled = 1, True
    node.tpdo.save()
    node.rpdo.save()


def enable_csp(node):
    node.sdo[0x6060].raw = 8
    for cw in (0x06, 0x07, 0x0F):
        node.sdo[0x6040].raw = cw
    assert node.sdo[0x6041].raw & 0x6F == 0x27


def run_csp(bench, node, targets_rad):
    """Stream targets [rad] one per SYNC; returns (position rad, torque Nm, statusword) per SYNC."""
    rows = []
    node.tpdo[1].add_callback(lambda m: rows.append((m[0x6064].raw, m[0x6077].raw, m[0x6041].raw)))
    p0 = node.sdo[0x6064].raw
    for target in targets_rad:
        node.rpdo[1][0x6040].raw = 0x0F
        node.rpdo[1][0x607A].raw = p0 + round(target * INC_PER_RAD)
        node.rpdo[1].transmit()
        bench.net.sync.transmit()
    node.tpdo[1].callbacks.clear()
    a = np.array(rows, dtype=float)
    return a[:, 0] / INC_PER_RAD - p0 / INC_PER_RAD, a[:, 1] * 1.27e-3, a[:, 2].astype(int)


def smooth_move(distance, duration, period=0.002, hold=0.3):
    s = np.linspace(0, 1, round(duration / period))
    return np.concatenate(
        [distance * (10 * s**3 - 15 * s**4 + 6 * s**5), np.full(round(hold / period), distance)]
    )


def started(bench, axis="x"):
    node = bench.nodes[axis]
    map_pdos(node)
    bench.net.nmt.send_command(0x01)
    enable_csp(node)
    return node


def test_identity_and_device_type(bench):
    b = bench()
    node = b.nodes["y"]
    assert node.sdo[0x1000].raw & 0xFFFF == 402
    assert node.sdo[0x1018][4].raw == 101
    assert node.sdo[0x6076].raw == 1270
    assert node.sdo[0x6502].raw & 0x80


def test_state_machine_transitions_fault_and_quick_stop(bench):
    b = bench()
    node = b.nodes["x"]
    sw = lambda: node.sdo[0x6041].raw & 0x6F  # noqa: E731
    assert sw() & 0x4F == 0x40  # switch on disabled
    node.sdo[0x6040].raw = 0x0F  # enable operation from SOD is not a transition
    assert sw() & 0x4F == 0x40
    node.sdo[0x6060].raw = 8
    for cw, expected in ((0x06, 0x21), (0x07, 0x23), (0x0F, 0x27), (0x07, 0x23), (0x0F, 0x27)):
        node.sdo[0x6040].raw = cw
        assert sw() == expected, hex(cw)
    node.sdo[0x6040].raw = 0x0B  # quick stop: ramp, then switch on disabled (0x605A = 2)
    assert sw() in (0x07, 0x40)
    b.link.clock.sleep(0.1)
    assert sw() & 0x4F == 0x40
    node.sdo[0x605A].raw = 6  # stay in quick stop active
    for cw in (0x06, 0x07, 0x0F, 0x0B):
        node.sdo[0x6040].raw = cw
    b.link.clock.sleep(0.1)
    assert sw() == 0x07
    node.sdo[0x6040].raw = 0x00  # disable voltage
    assert sw() & 0x4F == 0x40


def test_unsupported_mode_is_refused(bench):
    node = bench().nodes["x"]
    with pytest.raises(canopen.SdoAbortedError) as err:
        node.sdo[0x6060].raw = 4
    assert err.value.code == 0x06090030
    assert node.sdo[0x6061].raw == 0


def test_dynamic_pdo_mapping_rules(bench):
    b = bench()
    node = b.nodes["x"]
    with pytest.raises(canopen.SdoAbortedError):  # mapping while the PDO is valid
        node.sdo[0x1A00][1].raw = 0x60770010
    node.sdo[0x1800][1].raw = 0x80000181
    with pytest.raises(canopen.SdoAbortedError):  # entries only while sub 0 is 0
        node.sdo[0x1A00][1].raw = 0x60770010
    node.sdo[0x1A00][0].raw = 0
    with pytest.raises(canopen.SdoAbortedError) as err:  # 0x2000 is not PDO-mappable
        node.sdo[0x1A00][1].raw = 0x20000120
    assert err.value.code == 0x06040041
    node.sdo[0x1A00][1].raw = 0x60770010
    node.sdo[0x1A00][2].raw = 0x606C0020
    node.sdo[0x1A00][0].raw = 2
    node.sdo[0x1800][1].raw = 0x181
    b.net.nmt.send_command(0x01)
    frames = []
    b.net.subscribe(0x181, lambda c, d, t: frames.append(bytes(d)))
    b.net.sync.transmit()
    assert len(frames) == 1 and len(frames[0]) == 6  # torque (2) + velocity (4) as mapped


def test_tpdos_only_in_operational(bench):
    b = bench()
    node = b.nodes["x"]
    map_pdos(node)
    frames = []
    b.net.subscribe(0x181, lambda c, d, t: frames.append(d))
    b.net.sync.transmit()
    assert frames == []  # pre-operational
    b.net.nmt.send_command(0x01)
    b.net.sync.transmit()
    assert len(frames) == 1


def test_heartbeat_in_simulation_time(bench):
    b = bench()
    node = b.nodes["z"]
    node.sdo[0x1017].raw = 50
    beats = []
    b.net.subscribe(0x703, lambda c, d, t: beats.append((t, d[0])))
    b.link.clock.sleep(0.5)
    assert len(beats) == 10
    assert all(state == 0x7F for _, state in beats)
    assert np.allclose(np.diff([t for t, _ in beats]), 0.05)


def test_csp_tracking_with_default_gains(bench):
    """1 rad S-curve in 0.5 s (peak 3.75 rad/s): following error stays under 20 mrad."""
    b = bench()
    node = started(b)
    ref = smooth_move(1.0, 0.5)
    pos, torque, sw = run_csp(b, node, ref)
    # the drive interpolates towards the target sent before the previous SYNC: compare with that
    err = ref[:-1] - pos[1:]
    assert np.max(np.abs(err)) < 0.02
    assert abs(pos[-1] - 1.0) < 0.002
    assert all(s & 0x6F == 0x27 for s in sw)


def step_response(bench, kps):
    b = bench()
    node = started(b)
    node.sdo[0x2000][3].raw = kps
    pos, _, _ = run_csp(b, node, np.full(150, 0.05))
    return pos


def test_gain_write_changes_the_step_response(bench):
    soft = step_response(bench, 0.03)
    stiff = step_response(bench, 0.12)
    t90 = lambda p: np.argmax(p >= 0.045)  # noqa: E731
    assert t90(soft) > 5 * t90(stiff)  # a soft velocity loop is much slower
    assert np.max(stiff) > np.max(soft)  # and the stiff one overshoots the step


def test_gains_written_to_a_held_axis_keep_the_torque_it_holds(bench):
    """z held against its load for 1 s (its velocity integrator carries the load), then KpS written
    a third lower: the torque goes on as it was and z stays put (an integrator that held the
    velocity error, scaled by KpS, dropped a third of its torque and let z sag)."""
    b = bench(clean_config(effects={"z": {"load": {"LOAD": 0.4}}}))  # gravity, as robot.yaml's z
    node = started(b, "z")
    pos, torque, _ = run_csp(b, node, np.zeros(500))
    held = np.mean(torque[-20:])
    assert abs(held) > 0.1  # the integrator carries the load
    node.sdo[0x2000][3].raw = node.sdo[0x2000][3].raw * 2 / 3
    after, torque_after, sw = run_csp(b, node, np.zeros(100))
    assert np.max(np.abs(torque_after - held)) < 0.05 * abs(held)
    assert np.max(np.abs(after - pos[-1])) < 1e-4
    assert all(s & 0x6F == 0x27 for s in sw)


def test_unstable_gains_oscillate_then_fault_with_emcy(bench):
    b = bench()
    node = started(b)
    emcy = []
    node.emcy.add_callback(lambda e: emcy.append(e.code))
    node.sdo[0x6065].raw = round(0.02 * INC_PER_RAD)  # a commissioning following-error window
    node.sdo[0x6066].raw = 1  # ... and time-out [ms]
    node.sdo[0x2000][3].raw = 0.6  # velocity loop far beyond its phase margin
    pos, torque, sw = run_csp(b, node, np.full(500, 0.01))  # a small step excites it
    assert emcy and emcy[0] == 0x8611  # following error
    assert sw[-1] & 0x4F == 0x08  # fault
    moving = torque[: np.argmax(sw & 0x08)]
    assert np.max(np.abs(moving)) > 1.0  # it oscillated hard before the fault
    node.sdo[0x6040].raw = 0x80  # fault reset
    assert node.sdo[0x6041].raw & 0x4F == 0x40
    assert emcy[-1] == 0  # EMCY "error reset"


def test_loss_of_setpoint_faults(bench):
    b = bench()
    node = started(b)
    run_csp(b, node, np.zeros(10))
    emcy = []
    node.emcy.add_callback(lambda e: emcy.append(e.code))
    for _ in range(SETPOINT_TIMEOUT_PERIODS - 1):  # SYNC keeps coming, RPDOs stop
        b.net.sync.transmit()
    assert emcy == []  # within the drive's tolerance
    for _ in range(2):
        b.net.sync.transmit()
    assert emcy == [0x8250]


def test_software_position_limit_clamps_demand(bench):
    b = bench()
    node = b.nodes["x"]
    node.sdo[0x607D][1].raw = -round(0.2 * INC_PER_RAD)
    node.sdo[0x607D][2].raw = round(0.2 * INC_PER_RAD)
    map_pdos(node)
    b.net.nmt.send_command(0x01)
    enable_csp(node)
    pos, _, sw = run_csp(b, node, np.linspace(0, 0.4, 200))
    assert np.max(pos) < 0.2 + 1e-3
    assert any(s & 0x0800 for s in sw)  # internal limit active


def test_store_and_restore_parameters(bench):
    b = bench()
    node = b.nodes["x"]
    node.sdo[0x2000][1].raw = 200.0
    b.net.nmt.send_command(0x81)  # reset node: unsaved value is lost
    assert node.sdo[0x2000][1].raw == pytest.approx(150.0)
    node.sdo[0x2000][1].raw = 200.0
    node.sdo[0x1010][1].raw = 0x65766173  # 'save'
    b.net.nmt.send_command(0x81)
    assert node.sdo[0x2000][1].raw == pytest.approx(200.0)


def test_lockstep_is_deterministic(bench):
    def run():
        b = bench(clean_config(noise=0.004, seed=7))
        node = started(b)
        return run_csp(b, node, smooth_move(0.5, 0.3))

    a, c = run(), run()
    for x, y in zip(a, c):
        assert np.array_equal(x, y)


EFFECTS = {
    "load": {"LOAD": 0.1},
    "position_periodic": {"PER_AMP": 0.05, "PER_PERIOD": 0.5, "PER_PHASE": 0.0},
    "stribeck": {"STR_AMP": 0.1, "STR_VEL": 0.5},
    "direction_asymmetry": {"ASYM_DC0": 0.05, "ASYM_DC1": 0.0},
    "cross_axis": {"CPL_SRC": "z", "CPL_COEF": 0.1},
    "drift": {"DRIFT_FRAC": 0.5, "DRIFT_TAU": 100.0},
}


def constant_velocity_torque(bench, effect=None, axis="x", v=2.0, z_offset=0.0):
    """Mean and shape of torque while axis moves +v then -v [rad/s] (z parked at z_offset)."""
    cfg = clean_config(effects={axis: {effect: EFFECTS[effect]}} if effect else None)
    b = bench(cfg)
    if z_offset:
        b.robot.plant.state[2, 0] = z_offset  # park Z (the coupling source)
    node = started(b, axis)
    t = np.arange(0, 1.0, 0.002)
    fwd = v * t
    ref = np.concatenate([fwd, fwd[-1] - v * t])
    pos, torque, _ = run_csp(b, node, ref)
    n = len(t)
    return pos, torque, slice(n // 4, n - 10), slice(n + n // 4, 2 * n - 10)


@pytest.mark.parametrize("effect", list(EFFECTS))
def test_each_hidden_effect_shows_in_the_torque(bench, effect):
    _, base, f, r = constant_velocity_torque(bench)
    pos, tq, f, r = constant_velocity_torque(bench, effect, z_offset=10.0 if effect == "cross_axis" else 0.0)
    d_fwd, d_back = tq[f].mean() - base[f].mean(), tq[r].mean() - base[r].mean()
    if effect == "load":  # same sign both ways
        assert d_fwd == pytest.approx(0.1, abs=0.01) and d_back == pytest.approx(0.1, abs=0.01)
    elif effect == "position_periodic":  # ripple with position, period 0.5 rad
        resid = tq[f] - base[f]
        phase = 2 * np.pi * pos[f] / 0.5
        amp = 2 * np.mean(resid * np.sin(phase))
        assert amp == pytest.approx(0.05, rel=0.2)
    elif effect == "stribeck":  # extra friction fades at 2 rad/s...
        assert abs(d_fwd) < 0.01
        _, slow, f2, _ = constant_velocity_torque(bench, effect, v=0.2)
        _, slow_base, _, _ = constant_velocity_torque(bench, v=0.2)
        assert slow[f2].mean() - slow_base[f2].mean() > 0.05  # ...but not at 0.2 rad/s
    elif effect == "direction_asymmetry":  # more friction one way, less the other
        assert d_fwd == pytest.approx(0.05, abs=0.01) and d_back == pytest.approx(0.05, abs=0.01)
    elif effect == "cross_axis":  # friction grows with Z position
        assert d_fwd == pytest.approx(1.0, abs=0.05) and d_back == pytest.approx(-1.0, abs=0.05)
    elif effect == "drift":  # warm-up: friction 1.5 x at t = 0
        assert d_fwd == pytest.approx(0.5 * 0.2198, rel=0.1) and d_back < -0.08


def test_profile_position_acknowledges_the_set_point_and_reaches_the_target_in_its_window(bench):
    """CiA 402 profile position: statusword bit 12 follows the set-point handshake (controlword bit 4),
    bit 10 only once the axis stands inside the position window 0x6067 for 0x6068 ms."""
    b = bench()
    node = b.nodes["y"]
    node.sdo[0x6060].raw = 1
    node.sdo[0x6067].raw = 50  # a tight window: 50 increments
    for cw in (0x06, 0x07, 0x0F):
        node.sdo[0x6040].raw = cw
    start = node.sdo[0x6064].raw
    node.sdo[0x607A].raw = start + 2**20  # one revolution
    node.sdo[0x6040].raw = 0x1F  # new set-point
    sw = node.sdo[0x6041].raw
    assert sw & 0x1000 and not sw & 0x0400
    node.sdo[0x6040].raw = 0x0F
    assert not node.sdo[0x6041].raw & 0x1000
    for _ in range(300):
        b.link.clock.sleep(0.01)
        sw = node.sdo[0x6041].raw
        if sw & 0x0400:
            break
    assert sw & 0x0400
    assert abs(node.sdo[0x6064].raw - (start + 2**20)) <= node.sdo[0x6067].raw


@pytest.mark.parametrize("read_every_s", [0.0303, 0.0017])
def test_profile_velocity_runs_on_the_drives_own_clock_whenever_it_is_asked(bench, read_every_s):
    """Profile velocity, 0 -> 4 rev/s at 4 rev/s²: however often the master looks (every 30.3 ms, or
    every 1.7 ms: never on the drive's period), the ramp takes its 1 s, the speed then is 0x60FF to
    0.1 %, bit 10 is set only there and bit 12 (speed = 0) only standing; halt (bit 8) brings it
    down on the profile deceleration 0x6084 and says reached once it stands. (The drive's periods
    used to start only after the ticks asked for: a look off its period held the demand, and the
    axis ran 1.6 % slow with dips to standstill.)"""
    b = bench()
    node, rev = b.nodes["y"], 2**20
    node.sdo[0x6060].raw = 3
    node.sdo[0x6083].raw, node.sdo[0x6084].raw = 4 * rev, 8 * rev
    for cw in (0x06, 0x07, 0x0F):
        node.sdo[0x6040].raw = cw
    assert node.sdo[0x6041].raw & 0x1000  # standing: speed = 0
    node.sdo[0x60FF].raw = 4 * rev
    rows = []
    for _ in range(round(1.5 / read_every_s)):
        b.link.clock.sleep(read_every_s)
        rows.append((b.robot.time, node.sdo[0x606C].raw / rev, node.sdo[0x6041].raw))
    t0 = rows[0][0] - read_every_s
    t, v, sw = (np.array(c) for c in zip(*rows))
    reached = t[np.flatnonzero(sw & 0x0400)[0]] - t0
    assert reached == pytest.approx(1.0, abs=0.01 + read_every_s)
    assert not np.any(sw[t - t0 < reached] & 0x0400) and not np.any(sw[t - t0 > 0.05] & 0x1000)
    assert np.all(np.abs(v[t - t0 > reached + 0.01] - 4.0) < 0.004)
    node.sdo[0x6040].raw = 0x010F  # halt
    b.link.clock.sleep(0.25)
    assert not node.sdo[0x6041].raw & 0x0400  # 4 rev/s at 8 rev/s²: still slowing down at 0.25 s
    b.link.clock.sleep(0.3)
    sw = node.sdo[0x6041].raw
    assert sw & 0x1400 == 0x1400 and node.sdo[0x606C].raw == 0  # stands: reached, speed = 0


def test_no_sdo_in_nmt_stopped(bench):
    b = bench()
    node = b.nodes["y"]
    node.sdo.RESPONSE_TIMEOUT = 0.05
    node.nmt.send_command(0x02)  # stopped
    b.link.clock.sleep(0.01)
    with pytest.raises(canopen.SdoCommunicationError):
        _ = node.sdo[0x6041].raw
    node.nmt.send_command(0x80)  # pre-operational: SDO again
    b.link.clock.sleep(0.01)
    assert node.sdo[0x6041].raw & 0x40


def test_torque_and_velocity_offsets_reach_the_loops(bench):
    """0x60B2 adds to the torque command and 0x60B1 to the velocity command, as in a real drive:
    a held axis moves off its setpoint by a torque offset above its static friction."""
    from drive_bridge.sim import kernel

    b = bench()
    node = started(b, "y")
    drive = b.robot.drives["y"]
    node.sdo[0x60B1].raw = 1000
    assert drive.plant_demand[kernel.V_OFF] == pytest.approx(1000 / INC_PER_RAD)
    node.sdo[0x60B1].raw = 0
    p0 = node.sdo[0x6064].raw
    held = run_csp(b, node, np.zeros(10))[0]
    node.sdo[0x60B2].raw = 600  # 0.76 Nm, above c0 = 0.32 Nm
    assert drive.plant_demand[kernel.T_OFF] == pytest.approx(0.6 * 1.27)
    pushed = run_csp(b, node, np.zeros(10))[0]
    assert np.max(np.abs(held)) < np.max(np.abs(pushed)) and node.sdo[0x6064].raw != p0


def test_the_interpolation_period_is_refused_a_change_while_enabled(bench):
    """0x60C2 written with the period the drive runs is taken whatever its state; another period
    while the drive is enabled is refused with abort 0x08000022 (the device state), and taken
    once it is disabled."""
    node = bench().nodes["x"]
    map_pdos(node)
    node.sdo[0x60C2][2].raw, node.sdo[0x60C2][1].raw = -3, 2  # the 2 ms it runs at
    enable_csp(node)
    node.sdo[0x60C2][1].raw = 2  # the same: taken
    with pytest.raises(canopen.SdoAbortedError) as refused:
        node.sdo[0x60C2][1].raw = 4
    assert refused.value.code == 0x08000022 and node.sdo[0x60C2][1].raw == 2
    node.sdo[0x6040].raw = 0x06
    node.sdo[0x60C2][1].raw = 4
    assert node.sdo[0x60C2][1].raw == 4
