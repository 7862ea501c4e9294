"""Scan and bring-up against the simulated robot."""

from __future__ import annotations

import pytest

from drive_bridge.cli import main
from harness.support import bus_yml_beside


def test_scan_lists_the_three_drives(capsys):
    assert main(["scan", "--sim"]) == 0
    out = capsys.readouterr().out
    for node_id, axis in ((1, "x"), (2, "y"), (3, "z")):
        assert f"node   {node_id}  axis {axis}" in out and "CiA 402 drive" in out


def test_scan_reports_missing_and_unexpected_nodes(tmp_path, capsys):
    cfg = bus_yml_beside(tmp_path, "node_id: 3", "node_id: 9")
    assert main(["scan", "--sim", "--config", str(cfg)]) == 3
    out = capsys.readouterr().out
    assert "axis z    MISSING" in out and "node   3  not configured" in out


def _nanotec_y(tmp_path):
    """The shipped bus.yml with Y's drive described by the Nanotec C5-E's EDS (read in place)."""
    import yaml

    from drive_bridge.resources import vendor_dir

    eds = vendor_dir() / "nanotec_C5-E-2-09.eds"
    if not eds.exists():
        pytest.skip("../shared/eds-vendor not present")
    cfg = bus_yml_beside(tmp_path)
    doc = yaml.safe_load(cfg.read_text())
    doc["nodes"]["y"]["dcf"] = str(eds)
    cfg.write_text(yaml.safe_dump(doc))
    return cfg


def test_a_node_that_is_not_the_drive_its_eds_describes_stops_before_any_write(tmp_path):
    """The bus.yml names the Nanotec EDS for Y, the node on the bus is the project's drive."""
    from drive_bridge.config import load_bus_config
    from drive_bridge.errors import EXIT_CODES, BusError
    from drive_bridge.master.bringup import bring_up, check_scan, scan
    from harness.support import Bench, clean_config

    cfg = load_bus_config(_nanotec_y(tmp_path))
    bench = Bench(clean_config())
    with pytest.raises(BusError) as exc:
        check_scan(scan(bench.link, cfg), cfg)
    msg = str(exc.value)
    assert "axis y (node 2) is not the drive its EDS/DCF describes" in msg and EXIT_CODES[exc.value.kind] == 3
    assert "vendor 0x00000DB1" in msg and "vendor 0x0000026C" in msg and "--accept-identity 2" in msg
    writes = []
    bench.robot.drives["y"].sdo_fault = lambda op, index, sub: (
        writes.append((index, sub)) if op == "write" else None
    )
    with pytest.raises(BusError, match="is not the drive"):
        bring_up(bench.link, cfg)
    assert writes == []  # nothing was written to any drive


def test_accept_identity_is_the_deliberate_override_and_is_recorded(tmp_path):
    from dataclasses import replace

    from drive_bridge.config import load_bus_config
    from drive_bridge.master.bringup import check_scan, scan
    from harness.support import Bench, clean_config

    cfg = replace(load_bus_config(_nanotec_y(tmp_path)), accept_identity=frozenset({2}))
    bench = Bench(clean_config())
    result = scan(bench.link, cfg)
    check_scan(result, cfg)  # goes on
    assert "y" in result.identity_accepted and "y" in result.as_dict(cfg)["identity_accepted"]


def test_scan_sees_each_vendor_drive_as_its_own_eds_describes(tmp_path, capsys):
    """--sim builds each node's drive from the EDS/DCF bus.yml names: the Nanotec's identity."""
    assert main(["scan", "--sim", "--config", str(_nanotec_y(tmp_path))]) == 0
    assert "axis y    CiA 402 drive  vendor 0x0000026C product 0x00000011" in capsys.readouterr().out


def test_bring_up_streams_in_a_mode_the_drive_lists_or_refuses_naming_its_modes():
    """0x6502 is read from the drive: CSP where listed and 0x607A mapped; a drive without a mode
    whose setpoint object is mapped is refused before it moves, with the modes it has. (IP on
    drives that have it: tests/commissioning/test_vendor_drives.py.)"""
    from drive_bridge.config import load_bus_config
    from drive_bridge.errors import DriveRefused
    from drive_bridge.master.bringup import bring_up
    from harness.support import BUS_CONFIG, Bench, clean_config

    cfg = load_bus_config(BUS_CONFIG).only(["y"])
    bench = Bench(clean_config())
    axes = bring_up(bench.link, cfg)
    assert (axes["y"].mode, axes["y"].setpoint) == (8, (0x607A, 0))
    bench.robot.drives["y"].sdo_fault = lambda op, index, sub: (
        0x25 if (op, index) == ("read", 0x6502) else None
    )
    with pytest.raises(DriveRefused) as exc:  # PP, PV, homing only
        bring_up(bench.link, cfg)
    assert "profile position (1), profile velocity (3), homing (6)" in str(exc.value)
    assert "nodes.y.rpdo" in str(exc.value)
    bench.robot.drives["y"].sdo_fault = lambda op, index, sub: (
        0x45 if (op, index) == ("read", 0x6502) else None
    )
    with pytest.raises(DriveRefused, match="0x60C1:1"):  # IP listed, but its record is not mapped
        bring_up(bench.link, cfg)


def test_a_dry_run_writes_nothing_and_plans_what_the_run_then_does(tmp_path, capsys):
    """record --dry-run: scan, the drives' units, the plan from where the axes stand, every check,
    and not one SDO write, NMT command or PDO; the plan it prints is the one the real run streams."""
    import numpy as np

    from drive_bridge.master.bringup import plan_bring_up
    from drive_bridge.master.campaign import build_plan
    from drive_bridge.recorder import record
    from harness.support import Bench, clean_config, quick_config

    config = quick_config()
    bench = Bench(clean_config())
    writes = []
    for drive in bench.robot.drives.values():
        drive.sdo_fault = lambda op, index, sub: writes.append((index, sub)) if op == "write" else None
    sent = []
    bench.link.network.traces += (type("T", (), {"on_message_received": lambda self, m: sent.append(m)})(),)
    axes = plan_bring_up(bench.link, config)
    planned = build_plan(
        config.campaign,
        {n: a.cfg.limits for n, a in axes.items()},
        {n: a.position_rad() for n, a in axes.items()},
        config.master.sync_period_s,
    )
    assert writes == [] and not [m for m in sent if m.arbitration_id in (0x000, 0x080)]
    assert axes["y"].drive_limits["0x607D:2"] > 0 and axes["y"].mode == 8
    for drive in bench.robot.drives.values():
        drive.sdo_fault = None
    done = record(config, bench.link, tmp_path)
    assert done.ok and np.array_equal(done.plan.demand, planned.demand)
    assert main(["record", "--sim", "--quick", "--dry-run", "--out", str(tmp_path / "cli")]) == 0
    out = capsys.readouterr().out
    assert "campaign x, y, z, 18 segments" in out and "z: from -0.12 m" in out and "nothing moved" in out
    assert not (tmp_path / "cli" / "log.csv").exists()


def test_validate_streams_the_trajectories_its_dry_run_planned(tmp_path):
    """validate --dry-run's plans (read-only bring-up, not one write) are the ones each scenario
    then streams, the approach from where the axes stand included."""
    import numpy as np

    from drive_bridge.cli.bus import validate_plans
    from drive_bridge.master.bringup import bring_up, plan_bring_up
    from drive_bridge.params.profile import load_profile
    from drive_bridge.tuning.validate import run_scenarios
    from harness.support import BUS_CONFIG, Bench, clean_config, load_bus_config

    config = load_bus_config(BUS_CONFIG).only(["y"])
    bench = Bench(clean_config())
    writes = []
    bench.robot.drives["y"].sdo_fault = lambda op, index, sub: (
        writes.append((index, sub)) if op == "write" else None
    )
    previewed = [
        plan for _, plan in validate_plans(config, "one scenario")(plan_bring_up(bench.link, config))
    ]
    assert writes == [] and len(previewed) == 2
    bench.robot.drives["y"].sdo_fault = None
    streamed = []
    axes = bring_up(bench.link, config)
    profile = load_profile("drive_bridge_servo")
    runs = run_scenarios(
        config,
        bench.link,
        axes,
        profile,
        {"held": {"y": {}}},
        {"y": {}},
        on_plan=lambda plan: streamed.append(plan),
    )
    assert not any(r.aborted for r in runs) and len(streamed) == 2
    assert np.array_equal(previewed[0].demand, streamed[0].demand)
    # the path starts where the axis came to rest after the first: that, to the encoder's resolution
    assert np.max(np.abs(previewed[1].demand - streamed[1].demand)) < 1e-4
    assert previewed[1].duration == streamed[1].duration
