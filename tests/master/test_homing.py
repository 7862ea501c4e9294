"""reference: home: the drive's own homing (CiA 402 mode 6) before the first motion, the stroke as
the drive counts after it, and every way a homing can fail ending with the axis quick-stopped."""

from __future__ import annotations

from dataclasses import replace

import pytest

from drive_bridge.config import load_bus_config
from drive_bridge.errors import ConfigError, MotionAborted, UserError
from drive_bridge.master.bringup import bring_up
from drive_bridge.master.homing import home
from drive_bridge.recorder import record
from drive_bridge.sim import kernel
from drive_bridge.sim.home_search import LIMIT_SWITCH_INSET_RAD
from harness.support import Bench, bus_yml_beside, clean_config, read_csv

Z_LIMITS = "    limits: {stroke_m: [-0.120, 0.120], max_velocity_m_s: 0.230, max_acceleration_m_s2: 5.0}\n    holding: enabled"
END_STOPS = (-75.398, 75.398)  # the shipped robot's Z: its stroke's ends, +-0.12 m


def _config(tmp_path, homing: str, stroke="[0.0, 0.235]", axis="z"):
    """The shipped bus.yml, Z homing as ``homing`` says with ``stroke`` [m] counted from home; a quick campaign."""
    text = Z_LIMITS.replace("[-0.120, 0.120]", stroke) + f"\n    reference: home\n    homing: {homing}"
    path = bus_yml_beside(tmp_path, Z_LIMITS, text)
    cfg = load_bus_config(path).only([axis])
    return replace(cfg, campaign=cfg.campaign.quick())


def _bench(initial=END_STOPS[0]):
    """The robot with Z against its lower end stop, without a brake (it rests there)."""
    cfg = clean_config()
    z = replace(cfg.axes["z"], end_stops_rad=END_STOPS, initial_position_rad=initial, brake=False)
    return Bench(replace(cfg, axes={**cfg.axes, "z": z}))


def test_a_campaign_runs_in_the_frame_its_homing_set(tmp_path):
    """Method 17 (negative limit switch): Z leaves its lower switch, the switch's edge becomes 0,
    and the stroke [0, 0.235] m of bus.yml lies inside the machine. In the encoder's frame at
    power-up Z stands 75 rad below that stroke: without homing the plan is refused."""
    config = _config(tmp_path, "{method: 17}")
    unhomed = replace(config, nodes={"z": replace(config.nodes["z"], reference="absolute", homing=None)})
    with pytest.raises(UserError, match="outside the stroke"):
        record(unhomed, _bench().link, tmp_path / "unhomed")
    bench = _bench()
    drive = bench.robot.drives["z"]
    result = record(config, bench.link, tmp_path / "rec")
    assert result.ok, result.aborted
    edge = END_STOPS[0] + LIMIT_SWITCH_INSET_RAD
    assert drive.origin_rad == pytest.approx(edge)
    reported = drive.node.sdo[0x6064].raw / drive.pos_per_rad
    assert reported == pytest.approx(drive.plant_state[kernel.Q] - edge, abs=2 / drive.inc_per_rad)
    names, data = read_csv(tmp_path / "rec" / "log.csv")
    z = data[:, names.index("z_position_rad")]
    span = config.nodes["z"].limits
    assert span.position_min - 1e-3 <= z.min() and z.max() <= span.position_max  # inside the homed stroke
    assert z.max() > 10.0  # and it moved up it


def test_homing_here_takes_the_standing_position_as_zero(tmp_path):
    config = _config(tmp_path, "{method: 37}", stroke="[-0.05, 0.05]")
    bench = _bench(initial=-30.0)
    axes = bring_up(bench.link, config)
    assert axes["z"].position_rad() == pytest.approx(-30.0, abs=1e-3)
    home(bench.link, axes, config)
    assert axes["z"].homed and axes["z"].position_rad() == pytest.approx(0.0, abs=1e-3)
    home(bench.link, axes, config)  # once per bring-up
    assert axes["z"].drive.state() == "OPERATION ENABLED"


@pytest.mark.parametrize(
    "homing,why", [("{method: 1}", "homing error"), ("{method: 18, timeout_s: 0.5}", "not homed within")]
)
def test_a_homing_that_fails_quick_stops_the_axis_before_anything_streams(tmp_path, homing, why):
    """A method the drive does not have (homing error, bit 13); a switch that never comes (the
    timeout: Z starts 20 rad below the upper switch at 5 % speed): each ends as a motion stop that
    names it, the axis quick-stopped and standing, not one SYNC sent."""
    config = _config(tmp_path, homing)
    bench = _bench(initial=END_STOPS[1] - 20.0)
    syncs = []
    bench.link.network.traces += (
        type(
            "T",
            (),
            {
                "on_message_received": lambda self, m: (
                    syncs.append(m) if m.arbitration_id == 0x80 and not m.data else None
                )
            },
        )(),
    )
    with pytest.raises(MotionAborted) as stop:
        record(config, bench.link, tmp_path / "rec")
    assert why in str(stop.value) and "quick-stopped" in str(stop.value) and stop.value.axis == "z"
    drive = bench.robot.drives["z"]
    assert drive.node.sdo[0x6041].raw & 0x6F == 0x07  # QUICK STOP ACTIVE: held, powered
    assert abs(drive.plant_state[kernel.V]) < 1e-3 and not syncs


def test_reference_home_needs_a_homing_section_and_a_drive_that_can_home(tmp_path):
    path = bus_yml_beside(tmp_path, Z_LIMITS, Z_LIMITS + "\n    reference: home")
    with pytest.raises(ConfigError, match="reference: home and a homing section go together"):
        load_bus_config(path)
    path = bus_yml_beside(
        tmp_path,
        Z_LIMITS,
        Z_LIMITS + "\n    reference: home\n    homing: {method: 17, switch_speed_m_s: 1.0}",
    )
    with pytest.raises(ConfigError, match="switch_speed_m_s.*above the axis's own limit"):
        load_bus_config(path)


def test_the_plan_says_the_axis_homes_first(tmp_path, capsys):
    from drive_bridge.cli import main

    path = bus_yml_beside(
        tmp_path,
        Z_LIMITS,
        Z_LIMITS.replace("[-0.120, 0.120]", "[0.0, 0.235]")
        + "\n    reference: home\n    homing: {method: 17, timeout_s: 60}",
    )
    assert (
        main(
            [
                "record",
                "--sim",
                "--quick",
                "--axes",
                "z",
                "--config",
                str(path),
                "--dry-run",
                "--out",
                str(tmp_path / "r"),
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "z: homes first (method 17, 0.0115 / 0.0023 m/s, within 60 s)" in out and "z: from 0 m" in out
