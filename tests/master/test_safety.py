"""The hazards of a real machine, each against strict simulated drives: enabling with a stale
target, a vertical axis without a brake after a motion, a quick stop and Ctrl-C, a master that
falls silent, a drive in units bus.yml does not assume.  Each test fails against a master that
enables by SDO, ends a motion with Shutdown, quick-stops without 0x605A, sends no heartbeat, or
takes its units from bus.yml alone."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from drive_bridge.cia.p402 import state_name
from drive_bridge.master.bringup import bring_up
from drive_bridge.master.supervision import VelocityGuard
from drive_bridge.sim import kernel
from drive_bridge.tuning.motion import run
from harness.support import Bench, clean_config, quick_config

pytestmark = pytest.mark.slow

Z = 2  # Z's row in the kernel arrays


def _z_at(b) -> float:
    return float(b.robot.plant.state[Z, kernel.Q])


@pytest.fixture
def robot(shipped_sim_config):
    """The shipped robot: Z has gravity above its friction, no brake, rests on its lower end stop."""
    b = Bench(shipped_sim_config)
    config = quick_config()
    return b, config, bring_up(b.link, config)


def test_enabling_with_a_stale_target_does_not_move_the_axis():
    b = Bench(clean_config())
    config = quick_config()
    axes = bring_up(b.link, config)
    start = axes["y"].position_rad()
    axes["y"].node.sdo[0x607A].raw = axes["y"].node.sdo[0x6064].raw + 2_000_000  # left by an earlier program
    motion = run(config, b.link, {"y": axes["y"]}, {"y": np.full(100, start)})
    assert motion.aborted is None
    assert np.max(np.abs(motion.position["y"] - start)) < 1e-4
    # Z (holding: enabled) is held powered in profile position after a motion: switching it back to
    # CSP takes 0x607A as it stands, before any RPDO flows
    z0 = axes["z"].position_rad()
    assert run(config, b.link, {"z": axes["z"]}, {"z": np.full(100, z0)}).aborted is None
    assert state_name(axes["z"].drive.statusword()) == "OPERATION ENABLED"
    axes["z"].node.sdo[0x607A].raw = axes["z"].node.sdo[0x6064].raw + 2_000_000
    excursion = []  # every 2 ms of the run, enabling included
    b.robot.timers.append(lambda t: excursion.append(abs(float(b.robot.plant.state[2, kernel.Q]) - z0)))
    motion = run(config, b.link, {"z": axes["z"]}, {"z": np.full(100, z0)})
    assert motion.aborted is None
    assert max(excursion) < 1e-4


def test_z_holds_its_position_for_10_s_after_a_motion(robot):
    b, config, axes = robot
    x0 = axes["x"].position_rad()
    motion = run(config, b.link, axes, {"x": np.full(50, x0 + 1.0), "z": np.full(50, 0.0)})
    assert motion.aborted is None
    assert state_name(axes["z"].drive.statusword()) == "OPERATION ENABLED"
    held = _z_at(b)
    assert abs(held) < 0.01  # it got there ...
    b.link.clock.sleep(10.0)
    assert abs(_z_at(b) - held) < 1e-3  # ... and stays, powered: no fall
    assert state_name(axes["x"].drive.statusword()) == "READY TO SWITCH ON"  # holding: brake


@pytest.mark.parametrize("how", ["guard", "ctrl-c"])
def test_z_holds_its_position_for_10_s_after_a_quick_stop(robot, how):
    b, config, axes = robot
    z0 = _z_at(b)
    approach = 0.2 * axes["z"].cfg.limits.max_velocity  # the approach runs at 20 % of the limits
    guard = VelocityGuard({"z": 0.5 * approach}) if how == "guard" else None

    def on_plan(plan):
        def progress(k):
            if how == "ctrl-c" and k >= 600:  # mid-approach, Z moving up at 46 mm/s
                raise KeyboardInterrupt

        return progress

    motion = run(config, b.link, axes, {"z": np.full(50, 0.0)}, guard=guard, on_plan=on_plan)
    assert motion.aborted is not None and ("guard" in motion.aborted.reason) == (how == "guard")
    assert state_name(axes["z"].drive.statusword()) == "QUICK STOP ACTIVE"
    stopped = _z_at(b)
    assert stopped > z0 + 0.05  # it stopped off its end stop
    b.link.clock.sleep(0.5)  # the stop settles (stiction, then the integrator)
    held = _z_at(b)
    assert abs(held - stopped) < 0.02
    b.link.clock.sleep(10.0)
    assert abs(_z_at(b) - held) < 1e-3


@pytest.mark.parametrize("multiplier", [None, 6.0])
def test_every_moving_drive_quick_stops_by_itself_when_the_master_heartbeat_stops(
    shipped_sim_config, multiplier
):
    """Bring-up set each drive's heartbeat consumer (0x1016: ``master.heartbeat_multiplier`` of the
    master's periods, 3 where bus.yml does not say), abort connection option (0x6007: quick stop)
    and quick stop option (0x605A: ramp and hold); the master then falls silent 1 s into a motion of
    all three axes.  Each drive waits as long as it was told, no shorter and no longer."""
    b, config = Bench(shipped_sim_config), quick_config()
    if multiplier is not None:
        config = replace(config, master=replace(config.master, heartbeat_multiplier=multiplier))
    axes = bring_up(b.link, config)
    periods = multiplier or 3
    for ax in axes.values():  # as the drives hold it, read back
        assert ax.drive_limits["0x1016:1"] == 127 << 16 | round(periods * 100)
    emcy = {a: [] for a in axes}
    for a, ax in axes.items():
        ax.node.emcy.add_callback(lambda e, a=a: emcy[a].append((b.robot.time, e.code)))
    silent, speeds = {}, []
    b.robot.timers.append(lambda t: speeds.append((t, *np.abs(b.robot.plant.state[:, kernel.V]))))

    def on_plan(plan):
        def progress(k):
            if b.robot.time > 1.0 and not silent:
                b.link.stop_heartbeat()  # as a SIGKILL would
                silent["t"] = b.robot.time

        return progress

    start = {a: ax.position_rad() for a, ax in axes.items()}
    run(config, b.link, axes, {a: np.full(50, start[a] + 8.0) for a in axes}, on_plan=on_plan)
    period = config.master.heartbeat_period_s
    for a in axes:
        t_emcy = min(t for t, code in emcy[a] if code == 0x8130)
        assert (periods - 1) * period < t_emcy - silent["t"] <= periods * period + 0.01, a
    ramp = max(
        axes[a].cfg.limits.max_velocity * 0.2 / axes[a].cfg.drive_limits.quick_stop_deceleration for a in axes
    )
    still = next(t for t, *v in speeds if t > silent["t"] and max(v) < 0.05)
    assert still - silent["t"] <= periods * period + ramp + 0.05
    assert state_name(axes["z"].drive.statusword()) == "QUICK STOP ACTIVE"  # and holds, powered
    held = _z_at(b)
    b.link.clock.sleep(5.0)
    assert abs(_z_at(b) - held) < 1e-3


def _nanotec(tmp_path, from_drive: bool):
    """Simulated Nanotec-faithful drives on their factory units (0.1 °, rpm), and
    config/examples/nanotec_c5e.yml without the factor-group writes: (config, bench)."""
    import yaml

    from drive_bridge.config import load_bus_config
    from drive_bridge.resources import data, vendor_dir

    eds = vendor_dir() / "nanotec_C5-E-2-09.eds"
    if not eds.exists():
        pytest.skip("../shared/eds-vendor not present")
    doc = yaml.safe_load(data("config", "examples", "nanotec_c5e.yml").read_text())
    doc["defaults"].pop("sdo", None)
    if from_drive:
        doc["defaults"]["scaling"] = {"from_drive": True, "rated_torque_Nm": 1.27}
    out = tmp_path / "bus.yml"
    out.write_text(yaml.safe_dump(doc))
    return load_bus_config(out), Bench(clean_config(), eds=eds)


def test_a_nanotec_on_factory_units_is_refused_before_anything_moves(tmp_path):
    from drive_bridge.errors import DriveRefused

    config, b = _nanotec(tmp_path, from_drive=False)
    writes = []
    for drive in b.robot.drives.values():
        drive.sdo_fault = lambda op, index, sub: writes.append((index, sub)) if op == "write" else None
    with pytest.raises(DriveRefused) as exc:
        bring_up(b.link, config)
    msg = str(exc.value)
    assert "0.1 °" in msg and "0xFF410000" in msg and "18.2× the planned stroke" in msg
    assert "from_drive" in msg and "0x60A8" in msg
    assert not [w for w in writes if w[0] in (0x607D, 0x6065, 0x6040) or 0x1400 <= w[0] < 0x1C00]


def test_from_drive_commissions_a_nanotec_on_factory_units_with_the_planned_stroke(tmp_path):
    config, b = _nanotec(tmp_path, from_drive=True)
    axes = bring_up(b.link, config)
    assert axes["y"].cfg.scaling.inc_per_rad == pytest.approx(3600 / (2 * np.pi))
    assert axes["y"].units["position_unit"].startswith("0.1 °")
    start = axes["y"].position_rad()
    target = start + 20.0  # rad, motor side
    motion = run(config, b.link, {"y": axes["y"]}, {"y": np.full(100, target)})
    assert motion.aborted is None
    moved = float(b.robot.plant.state[1, kernel.Q]) - start
    assert moved == pytest.approx(20.0, rel=0.01)


def _epos2_bench():
    from drive_bridge.config import load_bus_config
    from drive_bridge.resources import data, vendor_dir

    eds = vendor_dir() / "maxon_epos2_50-5.eds"
    if not eds.exists():
        pytest.skip("../shared/eds-vendor not present")
    config = load_bus_config(data("config", "examples", "maxon_epos2.yml")).only(["y"])
    b = Bench(clean_config(), eds=eds)
    return b, config, bring_up(b.link, config)


def test_records_an_earlier_program_left_in_the_buffer_are_not_played():
    from drive_bridge.cia.setpoint import pack_pvt

    b, config, axes = _epos2_bench()
    node = axes["y"].node
    for _ in range(20):  # far away: a jump if the drive played them
        node.sdo[0x20C1].raw = pack_pvt(node.sdo[0x6064].raw + 500_000, 0, 2)
    start = axes["y"].position_rad()
    motion = run(config, b.link, axes, {"y": np.full(100, start)})
    assert motion.aborted is None and np.max(np.abs(motion.position["y"] - start)) < 1e-3


def test_a_record_that_does_not_come_stops_the_run_naming_the_buffer_underflow():
    b, config, axes = _epos2_bench()
    cob = next(c.cob_id for c in axes["y"].rpdos if (0x20C1, 0) in c.entries)
    lost = []

    def on_plan(plan):
        def progress(k):  # one record lost on the bus, mid-motion
            if k >= 300 and not lost:
                lost.append(k)
                route = b.robot._routes[cob]
                b.robot._routes[cob] = lambda data: b.robot._routes.__setitem__(cob, route)

        return progress

    start = axes["y"].position_rad()
    motion = run(config, b.link, axes, {"y": np.full(500, start + 5.0)}, on_plan=on_plan)
    assert motion.aborted is not None and "interpolation buffer ran empty" in str(motion.aborted)


def test_a_node_without_scaling_takes_the_units_the_drive_reports(tmp_path):
    """A ros2_canopen bus.yml has no drive-bridge scaling: where the drive reports its units (the
    project's drive: 0x608F, 0x60A8/0x60A9 in increments, 0x6076), bring-up takes them."""
    import yaml

    from drive_bridge.config import load_bus_config
    from harness.support import bus_yml_beside

    path = bus_yml_beside(tmp_path)
    doc = yaml.safe_load(path.read_text())
    doc["defaults"].pop("scaling")
    doc["nodes"] = {
        "y": {
            "node_id": 2,
            "limits": {
                "stroke_rad": [-70.0, 70.0],
                "max_velocity_rad_s": 140.0,
                "max_acceleration_rad_s2": 3000.0,
            },
        }
    }
    path.write_text(yaml.safe_dump(doc))
    config = load_bus_config(path)
    assert config.nodes["y"].units_from_drive
    b = Bench(clean_config())
    axes = bring_up(b.link, config)
    sc = axes["y"].cfg.scaling
    assert sc.increments_per_rev == pytest.approx(2**20) and sc.velocity_per_rad_s == pytest.approx(
        2**20 / (2 * np.pi)
    )
    assert sc.rated_torque_Nm == pytest.approx(1.27) and axes["y"].units["assumed_from_bus_yml"] == []


def test_reference_here_lays_the_stroke_around_the_axis_and_the_drive_limits_bound_the_motion(tmp_path):
    """reference: here: the stroke (and 0x607D) around where the axis stands at bring-up; a motion
    that would leave the software position limits the drive holds is refused before the first
    setpoint, with the numbers."""
    import yaml

    from drive_bridge.config import load_bus_config
    from drive_bridge.errors import UserError
    from harness.support import bus_yml_beside

    path = bus_yml_beside(tmp_path)
    doc = yaml.safe_load(path.read_text())
    doc["nodes"] = {"y": {**doc["nodes"]["y"], "reference": "here"}}
    path.write_text(yaml.safe_dump(doc))
    config = load_bus_config(path)
    cfg = clean_config()
    b = Bench(cfg)
    b.robot.plant.state[1, kernel.Q] = 100.0  # far from the encoder's zero
    b.robot.drives["y"].refresh_actuals()
    axes = bring_up(b.link, config)
    lim = axes["y"].cfg.limits
    assert lim.position_min == pytest.approx(100.0 - 75.398, abs=1e-3) and lim.position_max == pytest.approx(
        175.398, abs=1e-3
    )
    assert axes["y"].drive_limits["0x607D:2"] == round(lim.position_max * axes["y"].cfg.scaling.inc_per_rad)
    motion = run(config, b.link, axes, {"y": np.full(50, 101.0)})
    assert motion.aborted is None and float(b.robot.plant.state[1, kernel.Q]) == pytest.approx(
        101.0, abs=1e-3
    )
    axes["y"].drive_limits["0x607D:2"] = round(
        101.5 * axes["y"].cfg.scaling.inc_per_rad
    )  # the drive's, narrower
    with pytest.raises(UserError, match="outside the software position limits the drive holds"):
        run(config, b.link, axes, {"y": np.full(50, 102.0)})
    assert float(b.robot.plant.state[1, kernel.Q]) == pytest.approx(101.0, abs=1e-3)


def test_a_gain_set_that_lets_a_held_axis_sag_is_put_back_before_it_is_stored(robot):
    """Z held powered at mid-stroke; a set written while it holds that cannot carry its load (the
    velocity loop 28x soft, no model feed-forward: what issue 67's corrupted measurement gave):
    watched once it reads back, Z leaves its hold tolerance within the watch, so the whole set is
    put back and nothing stored (before, one read right after the read-back found Z 42 mrad down,
    under its 50 mrad tolerance, and the set was stored while Z went on sagging)."""
    from drive_bridge.master.hold import HeldAxes
    from drive_bridge.params.profile import load_profile
    from drive_bridge.params.write import write_drives

    b, config, axes = robot
    z = axes["z"]
    assert run(config, b.link, {"z": z}, {"z": np.full(50, 0.0)}).aborted is None
    soft = {"KpP": 11.6, "KpS": 0.0043, "KiS": 5.0, "ff_enable": 0.0}
    held = HeldAxes({"z": z})
    outcome = write_drives(
        {"z": z.node},
        load_profile("drive_bridge_servo"),
        {"z": soft},
        backup_dir=None,
        force=True,
        strayed=held.strayed,
    )
    result = outcome.results["z"]
    assert not outcome.ok and "axis z: left the position it was held at" in result.error
    assert result.ram == "backup" and result.stored_set == "unchanged"
    assert state_name(z.drive.statusword()) == "OPERATION ENABLED"  # still held, powered
