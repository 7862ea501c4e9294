"""Streaming ahead (issue 68): the drive keeps time and takes records from its FIFO; the master
feeds it ahead and may stall.  Lockstep proves the logic; stalls injected into a wall-clock master
(SIGSTOP/SIGCONT of its processes, the simulated drives left running) prove the design."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
import yaml

from drive_bridge.cia.setpoint import record_sub_mode
from drive_bridge.cli import main
from drive_bridge.config import load_bus_config
from drive_bridge.master.buffered import buffered_node, records_ahead, why_not
from drive_bridge.master.engine import FEED_PER_PERIOD
from drive_bridge.params.profile import load_profile
from drive_bridge.params.write import write_parameters
from drive_bridge.recorder import record
from drive_bridge.resources import DEFAULT_BUS_CONFIG as BUS_CONFIG
from drive_bridge.tuning.design import design_gains
from harness.paths import VENDOR_EDS
from harness.stalls import injector
from harness.support import PAPER, Bench, bus_yml_beside, clean_config, quick_config, read_csv


def buffered(config, **master):
    return replace(config, master=replace(config.master, streaming="buffered", **master))


def column(names, data, name):
    return data[:, names.index(name)]


def test_in_lockstep_the_fifo_is_fed_ahead_and_the_axis_follows_the_plan(tmp_path):
    """master.streaming: buffered: z in interpolated position with the record RPDO event-driven;
    before interpolation starts its FIFO holds the records kept ahead, it never runs below them
    while the plan lasts, the log has a row for every SYNC and the axis follows the plan."""
    config = buffered(quick_config()).only(["z"])
    bench = Bench(clean_config())
    result = record(config, bench.link, tmp_path)
    assert result.ok
    meta = yaml.safe_load((tmp_path / "meta.yaml").read_text())
    assert meta["timing"]["engine"]["streaming"]["z"].startswith("ahead into its interpolation FIFO")
    assert meta["timing"]["samples_missing"] == {"z": 0}
    names, data = read_csv(tmp_path / "log.csv")
    fill = column(names, data, "z_ip_buffer_fill")
    depth = records_ahead(config.master)
    rows = len(fill)
    # a record a SYNC taken, one more written: full but for the last rows of the plan
    assert fill[0] >= depth - FEED_PER_PERIOD
    assert np.all(fill[: rows - depth] >= depth - 1)
    assert np.all(np.diff(fill[rows - depth + 1 :]) <= 0)
    assert np.all(np.isfinite(column(names, data, "sync_time_s")))
    position = column(names, data, "z_position_rad")
    demand = column(names, data, "z_position_demand_rad")
    assert np.max(np.abs(position - demand)) < 0.05 * np.ptp(demand)


def test_records_fed_ahead_follow_as_closely_as_csp_on_the_drives_higher_order_sub_mode(tmp_path):
    """The project's drive takes position records in its sub-mode -2 (the parabola through the
    records, acceleration fed forward): z's following error fed ahead, on tuned gains with the
    drive's model feed-forward, is CSP's (in linear interpolation, sub-mode 0, a multiple of it),
    and the run says the choice."""
    fe_rms = {}
    plant = PAPER["z"]
    tuned = {**design_gains(plant["J"], plant["c1"], R=0.8, L=0.002).gains(), **plant, "ff_enable": 1.0}
    for way in ("buffered", "per_sync"):
        config = replace(quick_config(), master=replace(quick_config().master, streaming=way)).only(["z"])
        out = tmp_path / way
        bench = Bench(clean_config())
        assert write_parameters(bench.nodes["z"], load_profile("drive_bridge_servo"), tuned, store=False).ok
        assert record(config, bench.link, out).ok
        names, data = read_csv(out / "log.csv")
        demand, position = column(names, data, "z_position_demand_rad"), column(names, data, "z_position_rad")
        # the position a row answers is read at a later SYNC: the error at the lag that fits best
        fe_rms[way] = min(
            float(np.sqrt(np.mean((demand[: -lag or None] - position[lag:]) ** 2))) for lag in range(4)
        )
        streaming = yaml.safe_load((out / "meta.yaml").read_text())["timing"]["engine"]["streaming"]["z"]
    assert fe_rms["buffered"] == pytest.approx(fe_rms["per_sync"], rel=0.1)
    meta = yaml.safe_load((tmp_path / "buffered" / "meta.yaml").read_text())
    assert "interpolation sub-mode -2 (0x60C0): the parabola" in meta["timing"]["engine"]["streaming"]["z"]
    assert "sub-mode" not in streaming  # CSP: no interpolation sub-mode to choose


def test_position_records_are_linear_where_no_higher_order_sub_mode_is_known():
    """A vendor not named, or a range 0x60C0 does not admit: linear, the cost said."""
    assert record_sub_mode(0x0DB1, (-2, 0))[0] == -2
    assert record_sub_mode(0x0DB1, (None, None))[0] == -2
    for vendor, limits in ((0x9A, (-32768, 32767)), (0x0DB1, (0, 0))):
        sub_mode, why = record_sub_mode(vendor, limits)
        assert sub_mode == 0 and "following error grows with the acceleration" in why
    assert "no higher-order sub-mode is known for its vendor" in record_sub_mode(0x9A, (None, None))[1]
    assert "outside the range 0x60C0 admits" in record_sub_mode(0x0DB1, (0, 0))[1]


def test_auto_streams_per_sync_in_lockstep_and_says_why(tmp_path):
    bench = Bench(clean_config())
    result = record(quick_config().only(["z"]), bench.link, tmp_path)
    assert result.ok
    meta = yaml.safe_load((tmp_path / "meta.yaml").read_text())
    assert "lockstep: simulated time keeps every SYNC on time" in meta["timing"]["engine"]["streaming"]["z"]


def test_a_drive_without_a_deep_fifo_is_streamed_per_sync_or_refused_by_name(tmp_path):
    """The reasons a drive cannot be fed ahead, from its EDS; ``buffered`` then refuses the run naming
    the axis and the key, before anything is enabled."""
    config = load_bus_config(BUS_CONFIG)
    ours = config.nodes["z"]
    depth = records_ahead(config.master)
    assert why_not(ours, [1, 3, 6, 7, 8], 1024, depth) is None
    assert "no interpolated position mode" in why_not(ours, [1, 3, 6, 8], 1024, depth)
    assert "holds 1 record(s)" in why_not(ours, [7, 8], 1, depth)
    node = buffered_node(ours)
    assert node.rpdo[-1].transmission == 255 and node.rpdo[-1].mapping == ((0x60C1, 1),)
    assert node.tpdo[-1].mapping == ((0x60C4, 2),)
    assert all((0x607A, 0) not in p.mapping for p in node.rpdo)


def test_buffered_refuses_a_drive_without_a_deep_fifo_by_axis_and_key(tmp_path, capsys):
    """config/examples/nanotec_c5e.yml (the C5-E's buffer holds one record) with
    ``master.streaming: buffered``: the run is refused before anything is enabled, naming the axis,
    the reason and the key."""
    from drive_bridge.resources import data

    if not (VENDOR_EDS / "nanotec_C5-E-2-09.eds").exists():
        pytest.skip("../shared/eds-vendor not present")
    cfg = tmp_path / "bus.yml"
    cfg.write_text(
        data("config", "examples", "nanotec_c5e.yml")
        .read_text()
        .replace("master:\n", "master:\n  streaming: buffered\n", 1)
        .replace("vendor/", f"{VENDOR_EDS}/")
    )
    code = main(
        ["record", "--sim", "--quick", "--axes", "y", "--config", str(cfg), "--out", str(tmp_path / "run")]
    )
    err = capsys.readouterr().err
    assert code != 0 and "Traceback" not in err
    assert "axis y: master.streaming in" in err and "is buffered, but" in err and "0x60C4" in err
    assert not (tmp_path / "run" / "log.csv").exists()


# ------------------------------------------------------------------ the wall clock, stalls injected
def record_stalled(tmp_path, length_s: float, every_s: float, seed: int, edit: str = ""):
    """``drive-bridge record --sim --realtime --quick --axes z`` in a process of its own, its main
    process and engine stopped ``length_s`` at random moments ``every_s`` apart on average (the
    simulated drives left running): (exit code, meta.yaml, log.csv, the stalls made, stderr)."""
    cfg = bus_yml_beside(tmp_path)
    if edit:
        cfg.write_text(cfg.read_text().replace("master:\n", f"master:\n  {edit}\n", 1))
    out = tmp_path / "run"
    master = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "drive_bridge",
            "record",
            "--sim",
            "--realtime",
            "--quick",
            "--axes",
            "z",
            "--config",
            str(cfg),
            "--out",
            str(out),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    log = tmp_path / "stalls.jsonl"
    stalls = injector(master.pid, length_s, every_s, seed=seed, log=log)
    try:
        _, err = master.communicate(timeout=240)
    finally:
        stalls.terminate()
        stalls.wait()
    made = [json.loads(line) for line in log.read_text().splitlines()] if log.exists() else []
    meta = yaml.safe_load((out / "meta.yaml").read_text())
    return master.returncode, meta, read_csv(out / "log.csv"), made, err


@pytest.mark.realtime
@pytest.mark.slow
def test_stalls_the_fifo_covers_leave_no_trace(tmp_path):
    """The master's processes stopped 200 ms at a time, once a second on average: the drive keeps
    the SYNC and takes its records meanwhile; the run completes with a row for every SYNC, each on
    the drive's 2 ms grid, and the stalls made fell inside the motion."""
    code, meta, (names, data), made, err = record_stalled(tmp_path, 0.2, 1.0, seed=5)
    assert code == 0, err
    assert meta["timing"]["samples_missing"] == {"z": 0}
    assert meta["timing"]["engine"]["sync_source"].startswith("drive z (node 3), on its own clock")
    sync = column(names, data, "sync_time_s")
    assert np.all(np.isfinite(sync)) and np.allclose(np.diff(sync), 0.002, atol=1e-5)
    assert all(s["lasted_s"] >= 0.2 for s in made)
    began = meta["timing"].get("started_at")
    assert len(made) >= 3, made  # (about 7 s of motion, a stall a second)
    assert began is None or any(s["began"] > began for s in made)


@pytest.mark.realtime
@pytest.mark.slow
def test_a_stall_longer_than_the_fifo_holds_is_a_planned_stop(tmp_path):
    """With 20 ms kept ahead, a 200 ms stall empties the FIFO: the drive ramps down and holds,
    enabled, no fault; the run ends saying so."""
    code, meta, _, made, err = record_stalled(tmp_path, 0.2, 0.5, seed=2, edit="stall_cover_ms: 20")
    assert made
    assert code == 4, err
    assert "its interpolation FIFO ran dry" in err and "no fault" in err
    assert meta["abort"]["axis"] == "z" and not meta["abort"].get("emcy")
    assert "Traceback" not in err
