"""The master against the simulated robot: bring-up, campaign, logs, decode, fault paths."""
from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from conftest import BUS_CONFIG, ROOT, Bench, clean_config
from drive_bridge.cli import main
from drive_bridge.config import load_bus_config
from drive_bridge.errors import MotionAborted
from drive_bridge.record import record

SIM_CLEAN = """
seed: 3
axes:
  x: {node_id: 1, serial: 1, plant: {J: 0.000089, c0: 0.2198, c1: 0.000312}}
  y: {node_id: 2, serial: 2, plant: {J: 0.0001, c0: 0.323, c1: 0.0005}}
  z: {node_id: 3, serial: 3, plant: {J: 0.0001, c0: 0.323, c1: 0.0005}%s}
"""


def quick_config(**campaign):
    cfg = load_bus_config(BUS_CONFIG)
    return replace(cfg, campaign=replace(cfg.campaign.quick(), **campaign))


def run_record(tmp_path, sim_cfg, config=None, axes=None, on_progress=None):
    config = config or quick_config()
    if axes:
        config = config.only(axes)
    bench = Bench(sim_cfg)
    hook = (lambda plan: (lambda k: on_progress(bench, k))) if on_progress else None
    return bench, record(config, bench.link, tmp_path, on_plan=hook)


def read_csv(path):
    with open(path) as f:
        names = f.readline().strip().split(",")
    return names, np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


# ---------------------------------------------------------------- CLI and configuration
def test_scan_lists_the_three_drives(capsys):
    assert main(["scan", "--sim"]) == 0
    out = capsys.readouterr().out
    for node_id, axis in ((1, "x"), (2, "y"), (3, "z")):
        assert f"node   {node_id}  axis {axis}" in out and "CiA 402 drive" in out


def test_scan_reports_missing_and_unexpected_nodes(tmp_path, capsys):
    text = BUS_CONFIG.read_text().replace("node_id: 3", "node_id: 9")
    cfg = tmp_path / "bus.yml"
    cfg.write_text(text.replace("../eds/", str(ROOT / "eds") + "/"))
    assert main(["scan", "--sim", "--config", str(cfg)]) == 3
    out = capsys.readouterr().out
    assert "axis z    MISSING" in out and "node   3  not configured" in out


BAD_CONFIGS = [
    ("  sync_period: 2000", "  sync_period: 2000\n  colour: red", "master.colour: unknown key"),
    ("    node_id: 2\n", "", "nodes.y.node_id: missing"),
    ("  bitrate: 1000000", "  bitrate: fast", "master.bitrate: must be int"),
    ("dcf: ../eds/drive_bridge_servo.eds", "dcf: ../eds/nope.eds", "nodes.x.dcf: EDS/DCF file not found"),
    ("max_velocity_m_s: 0.230, max_acceleration_m_s2: 5.0}\n  z",
     "max_velocity_m_s: 0.8, max_acceleration_m_s2: 5.0}\n  z",
     "nodes.y.limits.max_velocity_m_s: 0.8 m/s is 4800 rpm at the motor, above the drive's max motor speed"),
    ("        - {index: 0x607A, sub_index: 0}", "", "nodes.x.rpdo: must map 0x607A"),
]


@pytest.mark.parametrize("old,new,message", BAD_CONFIGS)
def test_bad_configuration_is_one_clear_message(tmp_path, capsys, old, new, message):
    text = BUS_CONFIG.read_text()
    assert old in text
    cfg = tmp_path / "bus.yml"
    cfg.write_text(text.replace(old, new, 1).replace("../eds/", str(ROOT / "eds") + "/"))
    assert main(["record", "--sim", "--quick", "--config", str(cfg), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert str(cfg) in err and message in err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_unknown_axis_is_refused(tmp_path, capsys):
    assert main(["record", "--sim", "--axes", "x,w", "--out", str(tmp_path)]) == 2
    assert "no axis named 'w'" in capsys.readouterr().err


def test_bus_load_above_budget_is_refused(tmp_path, capsys):
    cfg = tmp_path / "bus.yml"
    cfg.write_text(BUS_CONFIG.read_text().replace("sync_period: 2000", "sync_period: 1000")
                   .replace("../eds/", str(ROOT / "eds") + "/"))
    assert main(["record", "--sim", "--quick", "--config", str(cfg), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "above the 80% budget" in err and "sync_period" in err
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())


def test_three_axes_at_500_hz_fit_at_1_mbit():
    from drive_bridge.master.busload import bus_load
    load = bus_load(load_bus_config(BUS_CONFIG))
    assert 0.4 < load.load < 0.8


def test_profile_outside_the_stroke_is_refused_before_motion(tmp_path):
    bench = Bench(clean_config())
    bench.robot.state[0, 0] = 30.0                        # X stands beyond its stroke (13.1 rad)
    try:
        with pytest.raises(Exception, match="outside the stroke"):
            record(quick_config().only(["x"]), bench.link, tmp_path)
        assert bench.robot.drives["x"].state != 4          # never enabled
        assert not (tmp_path / "log.csv").exists()
    finally:
        bench.close()


# ---------------------------------------------------------------- the campaign and its logs
def test_campaign_levels_cycles_and_log_units(tmp_path):
    cfg = quick_config(cycles=2, max_axis_time_s=30.0)
    bench, result = run_record(tmp_path, clean_config(), cfg, axes=["y"])
    assert result.ok
    meta = yaml.safe_load((tmp_path / "meta.yaml").read_text())
    levels = [s for s in meta["segments"] if s["kind"] == "level"]
    assert [(s["velocity_fraction"], s["acceleration_fraction"]) for s in levels] == \
        [(0.4, 0.4), (0.4, 0.8), (0.8, 0.4), (0.8, 0.8)]
    assert all(s["cycles"] == 2 for s in levels)
    counts = meta["counts"]
    assert counts["cycles_sent"] == counts["cycles_planned"] == counts["samples_received"]["y"]
    assert counts["samples_missing"] == {"y": 0}
    names, data = read_csv(tmp_path / "log.csv")
    for col in ("time_s", "y_position_rad", "y_velocity_rad_s", "y_torque_Nm", "y_position_demand_rad",
                "y_statusword"):
        assert col in names
    c = {n: data[:, i] for i, n in enumerate(names)}
    assert np.allclose(np.diff(c["time_s"]), 0.002)
    # the 80 % level runs at 0.8 * 0.23 m/s = 115.6 rad/s at the motor (10 mm lead)
    fast = levels[-1]
    span = (c["time_s"] >= fast["start_s"]) & (c["time_s"] < fast["end_s"])
    assert np.max(np.abs(c["y_velocity_rad_s"][span])) == pytest.approx(0.8 * 0.23 * 2 * math.pi / 0.01, rel=0.05)
    # the move spans 5 % of the 240 mm stroke: 12 mm = 7.54 rad
    assert np.ptp(c["y_position_rad"][span]) == pytest.approx(0.012 * 2 * math.pi / 0.01, rel=0.02)
    assert np.max(np.abs(c["y_position_demand_rad"] - c["y_position_rad"])) < 0.6
    # torque in Nm: while cruising forward, J*0 + c1*v + c0 (clean plant, Table II)
    v = c["y_velocity_rad_s"]
    cruise = span & (v > 0.95 * v[span].max())
    assert np.median(c["y_torque_Nm"][cruise]) == pytest.approx(0.323 + 0.0005 * v[cruise].mean(), rel=0.05)


def test_decode_rebuilds_the_same_csv(tmp_path, capsys):
    assert main(["record", "--sim", "--quick", "--axes", "x,z", "--out", str(tmp_path)]) == 0
    assert main(["decode", str(tmp_path / "trace.blf"), "--out", str(tmp_path / "decoded.csv")]) == 0
    assert (tmp_path / "decoded.csv").read_bytes() == (tmp_path / "log.csv").read_bytes()


def test_lockstep_records_are_identical(tmp_path):
    for name in ("a", "b"):
        assert main(["record", "--sim", "--quick", "--axes", "z", "--out", str(tmp_path / name)]) == 0
    for f in ("log.csv", "trace.blf"):
        assert (tmp_path / "a" / f).read_bytes() == (tmp_path / "b" / f).read_bytes()


def test_together_moves_all_axes_at_once(tmp_path):
    bench, result = run_record(tmp_path, clean_config(), quick_config(together=True))
    assert result.ok
    levels = [s for s in result.plan.segments if s.kind == "level"]
    assert all(s.axes == ("x", "y", "z") for s in levels)
    names, data = read_csv(tmp_path / "log.csv")
    c = {n: data[:, i] for i, n in enumerate(names)}
    moving = [np.abs(c[f"{a}_velocity_rad_s"]) > 0.5 for a in "xyz"]
    assert np.any(moving[0] & moving[1] & moving[2])


# ---------------------------------------------------------------- fault paths
def assert_stopped_and_kept(bench, tmp_path, result, axis, reason):
    assert not result.ok and result.aborted.axis == axis and reason in result.aborted.reason
    meta = yaml.safe_load((tmp_path / "meta.yaml").read_text())
    assert meta["status"] == "aborted" and meta["abort"]["axis"] == axis
    names, data = read_csv(tmp_path / "log.csv")
    assert 0 < len(data) < meta["counts"]["cycles_planned"]
    assert len(data) == meta["counts"]["cycles_sent"]
    bench.link.clock.sleep(0.01)                             # the holding brakes engage
    for drive in bench.robot.drives.values():                # every axis stands still, disabled
        assert drive.s[1] == 0.0 and drive.state in (1, 7)   # SWITCH ON DISABLED or FAULT


@pytest.fixture(autouse=True)
def _close_benches():
    yield
    for bench in list(Bench.open):
        bench.close()


def test_following_error_fault_stops_every_axis(tmp_path):
    # a hidden 5 Nm load on Y is more than the drive's 3.8 Nm: it cannot follow
    sim = clean_config(effects={"y": {"load": {"LOAD": 5.0}}})
    bench, result = run_record(tmp_path, sim, quick_config(together=True))
    assert_stopped_and_kept(bench, tmp_path, result, "y", "following error (EMCY 0x8611)")


def test_heartbeat_loss_stops_every_axis(tmp_path):
    def silence_z(bench, k):
        if k == 500:
            bench.robot.drives["z"].node.data_store[0x1017] = {0: b"\x00\x00"}   # producer off
            bench.robot.drives["z"]._cache.pop((0x1017, 0), None)
    bench, result = run_record(tmp_path, clean_config(), quick_config(together=True), on_progress=silence_z)
    assert_stopped_and_kept(bench, tmp_path, result, "z", "heartbeat lost")


def test_missing_tpdos_stop_every_axis(tmp_path):
    def unplug_x(bench, k):
        if k == 400:
            bench.robot.drives["x"].online = False
    bench, result = run_record(tmp_path, clean_config(), quick_config(together=True), on_progress=unplug_x)
    assert not result.ok and result.aborted.axis == "x" and "no TPDO for 3" in result.aborted.reason
    assert "axis x: quick stop not confirmed" in result.aborted.reason    # it is gone from the bus
    names, data = read_csv(tmp_path / "log.csv")
    assert np.isnan(data[-1, names.index("x_position_rad")]) and data[-1, names.index("x_valid")] == 0
    # every SYNC after the unplug is a counted gap (3 checked + the one sent before the check)
    gaps = np.flatnonzero(data[:, names.index("x_valid")] == 0)
    assert result.missing["x"] == len(gaps) == 4 and np.all(np.diff(gaps) == 1)
    assert result.missing["y"] == result.missing["z"] == 0


def test_ctrl_c_stops_every_axis(tmp_path):
    def interrupt(bench, k):
        if k == 300:
            raise KeyboardInterrupt
    bench, result = run_record(tmp_path, clean_config(), quick_config(together=True), on_progress=interrupt)
    assert not result.ok and "Ctrl-C" in result.aborted.reason
    assert (tmp_path / "log.csv").exists()


def test_cli_exit_code_after_a_fault(tmp_path, capsys):
    sim = tmp_path / "sim.yaml"
    sim.write_text(SIM_CLEAN % ", effects: {load: {torque_Nm: 6.0}}")
    assert main(["record", "--sim", "--quick", "--sim-config", str(sim), "--axes", "z",
                 "--out", str(tmp_path / "o")]) == 4
    err = capsys.readouterr().err
    assert "axis z: drive sent following error" in err and "data recorded so far is kept" in err
    assert (tmp_path / "o" / "log.csv").exists()


# ---------------------------------------------------------------- wall clock
def test_wall_clock_campaign_against_drives_in_their_own_process(tmp_path, capsys):
    """--realtime: the drives run in a child process on python-can's udp_multicast bus and the
    master streams at 500 Hz against the wall clock; the trace still decodes to the same CSV."""
    out = tmp_path / "rt"
    assert main(["record", "--sim", "--realtime", "--quick", "--axes", "y", "--out", str(out)]) == 0
    names, data = read_csv(out / "log.csv")
    meta = yaml.safe_load((out / "meta.yaml").read_text())
    counts = meta["counts"]
    assert counts["cycles_sent"] == counts["cycles_planned"] == len(data)
    assert counts["samples_missing"]["y"] <= 0.01 * len(data)           # feedback attributed by bus time
    period = np.diff(data[:, names.index("sync_time_s")])
    assert abs(np.median(period) - 0.002) < 1e-4                       # SYNC at 500 Hz of wall time
    demand, position = data[:, names.index("y_position_demand_rad")], data[:, names.index("y_position_rad")]
    assert np.nanmax(np.abs(demand - position)) < 0.5                  # the drive followed
    assert main(["decode", str(out / "trace.blf")]) == 0
    assert (out / "decoded.csv").read_bytes() == (out / "log.csv").read_bytes()
