"""The bus configuration: one clear message for every mistake, the bus-load budget."""

from __future__ import annotations

import pytest
import yaml

from drive_bridge.cli import main
from drive_bridge.config import load_bus_config
from harness.support import BUS_CONFIG, EDS, bus_yml_beside

BAD_CONFIGS = [
    ("  sync_period: 2000", "  sync_period: 2000\n  colour: red", "master.colour: unknown key"),
    ("    node_id: 2\n", "", "nodes.y.node_id: missing"),
    ("  bitrate: 1000000", "  bitrate: fast", "master.bitrate: must be int"),
    ("dcf: ../eds/drive_bridge_servo.eds", "dcf: ../eds/nope.eds", "nodes.x.dcf: EDS/DCF file not found"),
    (
        "max_velocity_m_s: 0.230, max_acceleration_m_s2: 5.0}\n    holding: brake\n  z",
        "max_velocity_m_s: 0.8, max_acceleration_m_s2: 5.0}\n    holding: brake\n  z",
        "nodes.y.limits.max_velocity_m_s: 0.8 m/s is 4800 rpm at the motor, above the drive's max motor speed",
    ),
    ("        - {index: 0x607A, sub_index: 0}", "", "nodes.x.rpdo: must map a position setpoint (0x607A"),
    (
        "  heartbeat_producer: 100     # ms: the master's",
        "  heartbeat_multiplier: 1\n  heartbeat_producer: 100     # ms: the master's",
        "master.heartbeat_multiplier: must be >= 1.5, got 1.0",
    ),
]


@pytest.mark.parametrize("old,new,message", BAD_CONFIGS)
def test_bad_configuration_is_one_clear_message(tmp_path, capsys, old, new, message):
    assert old in BUS_CONFIG.read_text()
    cfg = bus_yml_beside(tmp_path, old, new)
    assert main(["record", "--sim", "--quick", "--config", str(cfg), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert str(cfg) in err and message in err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_unknown_axis_is_refused(tmp_path, capsys):
    assert main(["record", "--sim", "--axes", "x,w", "--out", str(tmp_path)]) == 2
    assert "no axis named 'w'" in capsys.readouterr().err


def test_bus_load_above_budget_is_refused(tmp_path, capsys):
    cfg = bus_yml_beside(tmp_path, "sync_period: 2000", "sync_period: 1000")
    assert main(["record", "--sim", "--quick", "--config", str(cfg), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "above the 80% budget" in err and "sync_period" in err
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())


def test_three_axes_at_500_hz_fit_at_1_mbit():
    from drive_bridge.master.busload import bus_load

    load = bus_load(load_bus_config(BUS_CONFIG))
    assert 0.4 < load.load < 0.8


@pytest.mark.parametrize(
    "form,options,master,drive_consumer_ms",
    [
        ("bus.yml", None, None, 300),
        ("bus.yml", None, 20, 2000),
        ("ros2_canopen.yml", None, None, 300),
        ("ros2_canopen.yml", 5, None, 500),
        ("ros2_canopen.yml", 5, 2.5, 250),
    ],
)
def test_the_drives_consumer_time_of_the_master_heartbeat_is_lelys_heartbeat_multiplier(
    tmp_path, form, options, master, drive_consumer_ms
):
    """Lely's ``heartbeat_multiplier`` (the master's own, else ``options``', else 3) times the
    master's ``heartbeat_producer`` is the consumer time bring-up writes to each drive (0x1016:1)."""
    from drive_bridge.master.bringup import drive_settings
    from drive_bridge.resources import data

    doc = yaml.safe_load(data("config", form).read_text())
    doc.setdefault("options", {})
    if form == "bus.yml":
        doc.pop("options")
        doc["defaults"]["dcf"] = str(EDS)
    else:
        doc["options"]["dcf_path"] = str(EDS.parent)
    if options is not None:
        doc["options"]["heartbeat_multiplier"] = options
    if master is not None:
        doc["master"]["heartbeat_multiplier"] = master
    cfg = tmp_path / "bus.yml"
    cfg.write_text(yaml.safe_dump(doc))
    config = load_bus_config(cfg)
    assert config.master.drive_consumer_ms == drive_consumer_ms
    settings = drive_settings("x", config.nodes["x"], config.master.sync_period_s, config.master)
    assert (0x1016, 1, 127 << 16 | drive_consumer_ms) in settings


def test_a_hold_tolerance_is_read_in_the_axis_own_units(tmp_path):
    """``hold_tolerance_m`` on a linear axis (Z: a 10 mm lead), at the motor in rad; without it 0.05 rad;
    a negative one is one clear message."""
    from drive_bridge.config import HOLD_TOLERANCE_RAD
    from drive_bridge.errors import UserError

    holding = "    holding: enabled\n"
    assert load_bus_config(BUS_CONFIG).nodes["z"].drive_limits.hold_tolerance == HOLD_TOLERANCE_RAD
    cfg = load_bus_config(bus_yml_beside(tmp_path, holding, holding + "    hold_tolerance_m: 0.0001\n"))
    assert cfg.nodes["z"].drive_limits.hold_tolerance == pytest.approx(0.0001 / 0.010 * 2 * 3.141592653589793)
    bad = bus_yml_beside(tmp_path, holding, holding + "    hold_tolerance_m: -1\n")
    with pytest.raises(UserError, match="nodes.z.hold_tolerance_m"):
        load_bus_config(bad)
