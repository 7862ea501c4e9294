"""The record job against the simulated robot: campaign, logs, decode, determinism, wall clock."""

from __future__ import annotations

import math
import subprocess

import can
import numpy as np
import pytest
import yaml

from drive_bridge.cli import main
from drive_bridge.recorder import record
from harness.machine_floor import beside_the_floor, meta_stall_ms
from harness.support import (
    Bench,
    bus_yml_beside,
    clean_config,
    decodes_to_the_log,
    quick_config,
    read_csv,
    tool,
)

from .master.test_stream import run_record

pytestmark = [pytest.mark.slow, pytest.mark.realtime]


SIM_CLEAN = """
seed: 3
axes:
  x: {node_id: 1, serial: 1, plant: {J: 0.000089, c0: 0.2198, c1: 0.000312}}
  y: {node_id: 2, serial: 2, plant: {J: 0.0001, c0: 0.323, c1: 0.0005}}
  z: {node_id: 3, serial: 3, plant: {J: 0.0001, c0: 0.323, c1: 0.0005}%s}
"""


def test_profile_outside_the_stroke_is_refused_before_motion(tmp_path):
    bench = Bench(clean_config())
    bench.robot.plant.state[0, 0] = 30.0  # X stands beyond its stroke (13.1 rad)
    try:
        with pytest.raises(Exception, match="outside the stroke"):
            record(quick_config().only(["x"]), bench.link, tmp_path)
        assert bench.robot.drives["x"].state != 4  # never enabled
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
    assert [(s["velocity_fraction"], s["acceleration_fraction"]) for s in levels] == [
        (0.4, 0.4),
        (0.4, 0.8),
        (0.8, 0.4),
        (0.8, 0.8),
    ]
    assert all(s["cycles"] == 2 for s in levels)
    counts = meta["counts"]
    assert counts["cycles_sent"] == counts["cycles_planned"] == counts["samples_received"]["y"]
    assert counts["samples_missing"] == {"y": 0}
    names, data = read_csv(tmp_path / "log.csv")
    for col in (
        "time_s",
        "y_position_rad",
        "y_velocity_rad_s",
        "y_torque_Nm",
        "y_position_demand_rad",
        "y_statusword",
    ):
        assert col in names
    c = {n: data[:, i] for i, n in enumerate(names)}
    assert np.allclose(np.diff(c["time_s"]), 0.002)
    # the 80 % level runs at 0.8 * 0.23 m/s = 115.6 rad/s at the motor (10 mm lead)
    fast = levels[-1]
    span = (c["time_s"] >= fast["start_s"]) & (c["time_s"] < fast["end_s"])
    assert np.max(np.abs(c["y_velocity_rad_s"][span])) == pytest.approx(
        0.8 * 0.23 * 2 * math.pi / 0.01, rel=0.05
    )
    # the move spans 5 % of the 240 mm stroke: 12 mm = 7.54 rad
    assert np.ptp(c["y_position_rad"][span]) == pytest.approx(0.012 * 2 * math.pi / 0.01, rel=0.02)
    assert np.max(np.abs(c["y_position_demand_rad"] - c["y_position_rad"])) < 0.6
    # torque in Nm: while cruising forward, J*0 + c1*v + c0 (clean plant, Table II)
    v = c["y_velocity_rad_s"]
    cruise = span & (v > 0.95 * v[span].max())
    assert np.median(c["y_torque_Nm"][cruise]) == pytest.approx(0.323 + 0.0005 * v[cruise].mean(), rel=0.05)


@pytest.mark.parametrize("config", [None, "maxon_epos2"])
def test_decode_rebuilds_the_same_csv(tmp_path, capsys, config):
    """Also for maxon's EPOS2: PVT records 0x20C1, velocity in rpm, current in mA."""
    from drive_bridge.resources import data, vendor_dir

    extra = []
    if config:
        if not vendor_dir().is_dir():
            pytest.skip("../shared/eds-vendor not present")
        extra = ["--config", str(data("config", "examples", f"{config}.yml"))]
    assert main(["record", "--sim", "--quick", "--axes", "x,z", "--out", str(tmp_path)] + extra) == 0
    assert main(["decode", str(tmp_path / "trace.blf"), "--out", str(tmp_path / "decoded.csv")]) == 0
    assert (tmp_path / "decoded.csv").read_bytes() == (tmp_path / "log.csv").read_bytes()


def test_lockstep_records_are_identical(tmp_path, monkeypatch):
    """The trace's start is the wall clock's; SOURCE_DATE_EPOCH fixes it, and then the trace too is
    identical byte for byte."""
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1795000000")
    for name in ("a", "b"):
        assert main(["record", "--sim", "--quick", "--axes", "z", "--out", str(tmp_path / name)]) == 0
    for f in ("log.csv", "trace.blf"):
        assert (tmp_path / "a" / f).read_bytes() == (tmp_path / "b" / f).read_bytes()


@pytest.mark.parametrize("realtime", [False, True], ids=["lockstep", "wall clock"])
def test_the_trace_reads_like_a_capture(tmp_path, realtime):
    """From the bus's opening: scan and bring-up SDOs, NMT, then SYNC and PDOs, the stop; every
    frame stamped (wall-clock time, also in lockstep), none zero, in time order; decode still
    rebuilds log.csv byte for byte."""
    import time

    t0 = time.time()
    args = ["record", "--sim", "--quick", "--axes", "z", "--out", str(tmp_path)] + (
        ["--realtime"] if realtime else []
    )

    def recorded() -> tuple[int, dict]:
        return main(args), yaml.safe_load((tmp_path / "meta.yaml").read_text())

    # on the wall clock a run the machine stalled (CI, 2026-11-25: 3 TPDOs of 3233 missing, in a row;
    # its own floor held up as long) runs again
    code, meta = beside_the_floor(recorded, lambda run: meta_stall_ms(run[1])) if realtime else recorded()
    degraded = meta["timing"]["degraded"]
    assert code == (5 if degraded else 0) and (realtime or not degraded)  # a loaded machine: said, not hidden
    with can.LogReader(str(tmp_path / "trace.blf")) as reader:
        frames = list(reader)
    stamps = np.array([f.timestamp for f in frames])
    assert np.all(stamps > 0) and np.all(np.diff(stamps) >= 0)
    assert t0 - 1 <= stamps[0] <= time.time() + 1  # a real start time
    ids = [f.arbitration_id for f in frames]
    first_sync = ids.index(0x080)
    assert 0x603 in ids[:first_sync] and 0x583 in ids[:first_sync]  # bring-up SDOs of node 3 first
    assert 0x000 in ids[:first_sync]  # NMT
    assert main(["decode", str(tmp_path / "trace.blf"), "--out", str(tmp_path / "decoded.csv")]) == 0
    if realtime:
        decodes_to_the_log(tmp_path)
    else:
        assert (tmp_path / "decoded.csv").read_bytes() == (tmp_path / "log.csv").read_bytes()
    tshark = tool("tshark")
    if tshark:  # Wireshark's CANopen dissector: every frame, none malformed, real time
        args = [tshark, "-r", str(tmp_path / "trace.blf"), "-d", "can.subdissector,canopen"]
        fields = subprocess.run(
            args + ["-T", "fields", "-e", "frame.time_epoch", "-e", "frame.protocols"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.split("\n")
        rows = [r.split("\t") for r in fields if r]
        assert len(rows) == len(frames)
        # (a SYNC without counter has no data byte: this dissector leaves it plain CAN)
        assert all(p.endswith(":canopen") for (_, p), f in zip(rows, frames) if f.dlc)
        assert abs(float(rows[0][0]) - stamps[0]) < 1e-3
        malformed = subprocess.run(args + ["-Y", "_ws.malformed"], capture_output=True, text=True, check=True)
        assert malformed.stdout.strip() == ""


def test_together_moves_all_axes_at_once(tmp_path):
    bench, result = run_record(tmp_path, clean_config(), quick_config(together=True))
    assert result.ok
    levels = [s for s in result.plan.segments if s.kind == "level"]
    assert all(s.axes == ("x", "y", "z") for s in levels)
    names, data = read_csv(tmp_path / "log.csv")
    c = {n: data[:, i] for i, n in enumerate(names)}
    moving = [np.abs(c[f"{a}_velocity_rad_s"]) > 0.5 for a in "xyz"]
    assert np.any(moving[0] & moving[1] & moving[2])


def test_cli_exit_code_after_a_fault(tmp_path, capsys):
    sim = tmp_path / "sim.yaml"
    sim.write_text(SIM_CLEAN % ", effects: {load: {torque_Nm: 6.0}}")
    assert (
        main(
            [
                "record",
                "--sim",
                "--quick",
                "--sim-config",
                str(sim),
                "--axes",
                "z",
                "--out",
                str(tmp_path / "o"),
            ]
        )
        == 4
    )
    err = capsys.readouterr().err
    assert "axis z: drive sent following error" in err and "data recorded so far is kept" in err
    assert (tmp_path / "o" / "log.csv").exists()


# ---------------------------------------------------------------- wall clock
def wall_clock_record(out, *options: str) -> tuple[int, dict]:
    """``record --sim --realtime --quick --axes y`` (and ``options``) into ``out``: its exit code
    and its meta.yaml."""
    code = main(["record", "--sim", "--realtime", "--quick", "--axes", "y", *options, "--out", str(out)])
    return code, yaml.safe_load((out / "meta.yaml").read_text())


def test_wall_clock_campaign_against_drives_in_their_own_process(tmp_path, capsys):
    """--realtime: the drives run in a child process on python-can's udp_multicast bus and the
    master streams at 500 Hz against the wall clock; the trace still decodes to the same CSV, and
    the run reports its timing as the log shows it -- degraded (exit 5) when a loaded machine
    made it miss its limits, never a silent ok."""
    out = tmp_path / "rt"
    # a run the machine itself stalled past the drive's watch (its own floor held up as long) runs again
    code, meta = beside_the_floor(lambda: wall_clock_record(out), lambda run: meta_stall_ms(run[1]))
    captured = capsys.readouterr()
    names, data = read_csv(out / "log.csv")
    counts, timing = meta["counts"], meta["timing"]
    assert meta["status"] == "ok", (meta.get("abort"), timing)
    assert counts["cycles_sent"] == counts["cycles_planned"] == len(data)
    sync = data[:, names.index("sync_time_s")]
    gaps = np.diff(sync[np.isfinite(sync)])  # (a late master's skipped periods have no SYNC)
    late = np.count_nonzero(gaps > 1.5 * 0.002) / len(gaps) * 100
    assert timing["clock"] == "wall" and timing["late_cycles_pct"] == pytest.approx(late, abs=1e-3)
    assert timing["max_sync_gap_ms"] == pytest.approx(gaps.max() * 1e3, abs=2e-3)
    assert timing["samples_missing"]["y"] == counts["samples_missing"]["y"]
    assert code == (5 if timing["degraded"] else 0)
    assert ("timing degraded" in captured.err) == timing["degraded"] and "timing: wall clock" in captured.out
    assert abs(np.median(gaps) - 0.002) < 1e-4  # SYNC at 500 Hz of wall time
    demand, position = data[:, names.index("y_position_demand_rad")], data[:, names.index("y_position_rad")]
    # the drive followed: where the SYNCs came on time (a late cycle or a missing sample leaves the
    # rows after it comparing a demand with a position the drive reported while it caught up)
    late_rows = np.flatnonzero(np.isfinite(sync))[1:][gaps > 1.5 * 0.002]
    upset = np.union1d(late_rows, np.flatnonzero(data[:, names.index("y_valid")] == 0))
    steady = np.ones(len(data), bool)
    for k in upset:
        steady[k : k + 10] = False
    assert steady.mean() > 0.5 and np.nanmax(np.abs(demand - position)[steady]) < 0.5
    assert main(["decode", str(out / "trace.blf")]) == 0
    decodes_to_the_log(out)


def test_a_run_past_its_timing_limits_is_degraded_with_exit_5(tmp_path, capsys):
    """Limits no host-timed wall clock can keep (every SYNC exactly on time): the run says so.  The master's
    supervision of the feedback and the drives' following-error window widened (the drives' watch of
    the master's heartbeat and setpoints kept as shipped): on a loaded machine a late SYNC while Y
    accelerates would stop the run first, rightly, and this test is about the timing limits."""
    cfg = bus_yml_beside(
        tmp_path,
        "heartbeat_consumer_ms: 300  # a drive whose heartbeat is silent this long is lost\n"
        "  sdo_timeout_s: 0.5\n  state_timeout_s: 1.0\n"
        "  heartbeat_producer: 100",
        "heartbeat_consumer_ms: 2000\n  sdo_timeout_s: 0.5\n  state_timeout_s: 1.0\n"
        "  tpdo_miss_limit: 100\n  timing: {max_gap_periods: 1.0}\n  heartbeat_producer: 100\n"
        "  sync_producer: interface\n  streaming: per_sync",
    )
    cfg.write_text(
        cfg.read_text().replace("following_error_window_rad: 0.6", "following_error_window_rad: 10.0", 1)
    )
    assert "tpdo_miss_limit: 100" in cfg.read_text() and "following_error_window_rad: 10.0" in cfg.read_text()
    out = tmp_path / "rt"
    # a run the machine itself stalled past the drive's setpoint watch (its own floor held up as
    # long in the same attempt) runs again; a stall the floor does not show is ours and fails here
    code, meta = beside_the_floor(
        lambda: wall_clock_record(out, "--config", str(cfg)), lambda run: meta_stall_ms(run[1])
    )
    assert code == 5, meta.get("abort")
    timing = meta["timing"]
    assert (
        meta["status"] == "ok"
        and timing["degraded"]
        and any("largest SYNC gap" in r for r in timing["reasons"])
    )
    assert "WARNING: timing degraded" in capsys.readouterr().err
    assert (out / "log.csv").exists()


def test_torque_from_the_current_actual_value_for_drives_without_0x6077(tmp_path):
    """A drive that reports no torque (like maxon's EPOS2): 0x6078 (per mille of the rated current)
    times the torque constant gives the same torque_Nm column as 0x6077 on the same run."""
    from dataclasses import replace as dc_replace

    from drive_bridge.config import load_bus_config

    cfg = bus_yml_beside(tmp_path)
    doc = yaml.safe_load(cfg.read_text())
    doc["nodes"]["y"]["scaling"].update(
        {
            "torque_feedback": "current",
            "current_unit": "permille",
            "rated_current_A": 1.27 / 0.2,
            "torque_constant_Nm_per_A": 0.2,
        }
    )
    doc["nodes"]["y"]["tpdo"] = {
        1: {"transmission": 1, "mapping": [{"index": 0x6064}, {"index": 0x6078}, {"index": 0x6041}]},
        2: {"transmission": 1, "mapping": [{"index": 0x606C}]},
    }
    cfg.write_text(yaml.safe_dump(doc))
    logs = {}
    for name, config in (("torque", quick_config()), ("current", load_bus_config(cfg))):
        config = dc_replace(config, campaign=quick_config().campaign).only(["y"])
        bench, result = run_record(tmp_path / name, clean_config(), config)
        assert result.ok
        bench.close()
        logs[name] = read_csv(tmp_path / name / "log.csv")
    (n_t, d_t), (n_c, d_c) = logs["torque"], logs["current"]
    torque, current = d_t[:, n_t.index("y_torque_Nm")], d_c[:, n_c.index("y_torque_Nm")]
    assert np.nanmax(np.abs(torque)) > 0.2 and np.allclose(torque, current, atol=1.3e-3, equal_nan=True)
    assert main(["decode", str(tmp_path / "current" / "trace.blf")]) == 0
    assert (tmp_path / "current" / "decoded.csv").read_bytes() == (
        tmp_path / "current" / "log.csv"
    ).read_bytes()


def test_torque_from_a_vendor_object_with_its_scale(tmp_path):
    """maxon's EPOS2 also reports its averaged current in 0x2027 (mA): logged as torque through
    its configured scale (Nm per unit = torque constant / 1000), the same Nm as from 0x6078."""
    from drive_bridge.resources import data, vendor_dir

    if not vendor_dir().is_dir():
        pytest.skip("../shared/eds-vendor not present")
    src = data("config", "examples", "maxon_epos2.yml")
    doc = yaml.safe_load(src.read_text())
    doc["defaults"]["scaling"] = {
        "increments_per_rev": 16384,
        "rated_torque_Nm": 1.27,
        "velocity_unit": "rpm",
        "torque_feedback": "object",
        "torque_object": 0x2027,
        "torque_Nm_per_unit": 0.2e-3,
    }
    doc["defaults"]["tpdo"][1]["mapping"][1] = {"index": 0x2027, "sub_index": 0}
    cfg = tmp_path / "bus.yml"
    cfg.write_text(yaml.safe_dump(doc))
    out = {}
    for name, path in (("object", cfg), ("current", src)):
        assert (
            main(
                [
                    "record",
                    "--sim",
                    "--quick",
                    "--axes",
                    "y",
                    "--config",
                    str(path),
                    "--out",
                    str(tmp_path / name),
                ]
            )
            == 0
        )
        names, values = read_csv(tmp_path / name / "log.csv")
        out[name] = values[:, names.index("y_torque_Nm")]
    assert np.nanmax(np.abs(out["object"])) > 0.2 and np.allclose(
        out["object"], out["current"], equal_nan=True
    )
    meta = yaml.safe_load((tmp_path / "object" / "meta.yaml").read_text())
    assert meta["axes"]["y"]["scaling"]["torque_index"] == 0x2027
    assert main(["decode", str(tmp_path / "object" / "trace.blf")]) == 0
    assert (tmp_path / "object" / "decoded.csv").read_bytes() == (
        tmp_path / "object" / "log.csv"
    ).read_bytes()


def test_streaming_starts_without_a_yaml_dump_while_the_drives_watch_for_setpoints(tmp_path, monkeypatch):
    """Once enabled, the drives watch for setpoints (10 periods: 20 ms); meta.yaml learns how many
    SYNCs enabling took right then, without a YAML dump (one took 26 ms: every 3-axis wall-clock run
    stopped with loss of setpoint 0x8250 after two cycles), and what it says lets decode skip exactly
    those SYNCs."""
    import drive_bridge.recorder as recording
    from drive_bridge import logs

    in_window, dumped_there, told = [], [], []
    dump = logs.yaml.safe_dump
    monkeypatch.setattr(
        logs.yaml, "safe_dump", lambda *a, **k: (dumped_there.append(bool(in_window)), dump(*a, **k))[1]
    )
    stream = recording.stream

    def watched_stream(*args, on_start, **kwargs):
        def started(cycles: int) -> None:
            in_window.append(True)
            try:
                on_start(cycles)
            finally:
                in_window.clear()
            told.append(
                (cycles, yaml.safe_load((tmp_path / "meta.yaml").read_text())["counts"]["sync_before_plan"])
            )

        return stream(*args, on_start=started, **kwargs)

    monkeypatch.setattr(recording, "stream", watched_stream)
    bench = Bench(clean_config())
    try:
        result = record(quick_config(together=True), bench.link, tmp_path)
    finally:
        bench.close()
    assert result.ok and dumped_there and True not in dumped_there  # meta dumped before and after, not then
    meta = yaml.safe_load((tmp_path / "meta.yaml").read_text())
    assert told and told[0][0] > 0 and told[0][0] == told[0][1] == meta["counts"]["sync_before_plan"]
    assert main(["decode", str(tmp_path / "trace.blf")]) == 0
    decodes_to_the_log(tmp_path)


def test_a_log_whose_first_periods_had_no_sync_keeps_its_sync_times():
    """A wall-clock master late at the plan's start skipped its first periods (no SYNC, NaN): the other
    rows' SYNC times are counted from the plan's first period on the SYNCs' schedule (before, the
    whole column read NaN, and with it every check of the run's timing against its log)."""
    from drive_bridge.logs import since_start

    stamps = 1000.0 + np.arange(6) * 0.002 + np.array([0, 0, 0, 1e-4, 0, 3e-3])
    stamps[:2] = np.nan
    times = since_start(stamps, 0.002)
    assert np.isnan(times[:2]).all()
    assert times[2:] == pytest.approx([0.004, 0.0061, 0.008, 0.013])
    assert since_start(1000.0 + np.arange(3) * 0.002, 0.002) == pytest.approx([0.0, 0.002, 0.004])
