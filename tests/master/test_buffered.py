"""Streaming ahead (issue 68): the drive keeps time and takes records from its FIFO; the master
feeds it ahead and may stall.  Lockstep proves the logic; stalls injected into a wall-clock master
(SIGSTOP/SIGCONT of its processes, the simulated drives left running) prove the design."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
import yaml

from drive_bridge.cia.setpoint import PVT, record_sub_mode
from drive_bridge.cli import main
from drive_bridge.config import load_bus_config
from drive_bridge.connect import open_link
from drive_bridge.errors import BusError
from drive_bridge.logs import decode_trace
from drive_bridge.master.bringup import bring_up
from drive_bridge.master.buffered import MAX_REPEATS, Feed, buffered_node, feed_way, records_ahead
from drive_bridge.master.campaign import approach_move
from drive_bridge.master.engine import FEED_PER_PERIOD
from drive_bridge.params.profile import load_profile
from drive_bridge.params.write import write_parameters
from drive_bridge.recorder import record
from drive_bridge.resources import DEFAULT_BUS_CONFIG as BUS_CONFIG
from drive_bridge.resources import data
from drive_bridge.tuning import motion
from drive_bridge.tuning.design import design_gains
from harness.paths import VENDOR_EDS
from harness.stalls import injector, simulator_process, stalling_at
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
    assert feed_way(ours, [1, 3, 6, 7, 8], 1024, depth, 0.002) == Feed((0x60C1, 1))
    assert "no interpolated position mode" in feed_way(ours, [1, 3, 6, 8], 1024, depth, 0.002)
    assert "holds 1 record(s)" in feed_way(ours, [7, 8], 1, depth, 0.002)
    node = buffered_node(ours)
    assert node.rpdo[-1].transmission == 255 and node.rpdo[-1].mapping == ((0x60C1, 1),)
    assert node.tpdo[-1].mapping == ((0x60C4, 2),)
    assert all((0x607A, 0) not in p.mapping for p in node.rpdo)


def test_buffered_refuses_a_drive_without_a_deep_fifo_by_axis_and_key(tmp_path, capsys):
    """config/examples/nanotec_c5e.yml (the C5-E's buffer holds one record) with
    ``master.streaming: buffered``: the run is refused before anything is enabled, naming the axis,
    the reason and the key."""
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
def record_stalled(tmp_path, length_s: float, every_s: float, seed: int, edit: str = "", cfg=None, axes="z"):
    """``drive-bridge record --sim --realtime --quick --axes z`` in a process of its own, its main
    process and engine stopped ``length_s`` at random moments ``every_s`` apart on average (the
    simulated drives left running): (exit code, meta.yaml, log.csv, the stalls made, stderr).
    ``cfg``: the bus.yml (default: the shipped one); ``axes``: those recorded."""
    cfg = cfg or bus_yml_beside(tmp_path)
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
            axes,
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
    assert (out / "log.csv").exists(), f"exit {master.returncode}, no log.csv: {err}"
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


def maxon_z_bus_yml(tmp_path):
    """The shipped bus.yml with z on maxon's EPOS2 (config/examples/maxon_epos2.yml's node, its
    vendor EDS read in place): x keeps time for the bus, z has no SYNC of its own."""
    eds = VENDOR_EDS / "maxon_epos2_50-5.eds"
    if not eds.exists():
        pytest.skip("../shared/eds-vendor not present")
    doc = yaml.safe_load(bus_yml_beside(tmp_path).read_text())
    maxon = yaml.safe_load(data("config", "examples", "maxon_epos2.yml").read_text())["defaults"]
    doc["nodes"]["z"].update(maxon, dcf=str(eds), scaling={**maxon["scaling"], "feed_m_per_rev": 0.010})
    cfg = tmp_path / "mixed.yml"
    cfg.write_text(yaml.safe_dump(doc, sort_keys=False))
    return cfg


def test_maxon_pvt_records_span_periods_to_keep_the_cover_in_half_the_buffer():
    """maxon's 64 PVT records hold 500 ms ahead in half of them with records of 16 ms (8 SYNC
    periods of 2 ms, whole ms); a cover 64 records of 255 ms cannot hold is refused with the reason;
    the records fed ahead go into an event-driven RPDO, and the status 0x20C4:1 that bus.yml maps
    already is not mapped twice."""
    if not (VENDOR_EDS / "maxon_epos2_50-5.eds").exists():
        pytest.skip("../shared/eds-vendor not present")
    config = load_bus_config(data("config", "examples", "maxon_epos2.yml"))
    node = config.nodes["z"]
    depth = records_ahead(config.master)
    assert depth == 250  # 500 ms of 2 ms periods
    assert feed_way(node, [1, 3, 6, 7], 64, depth, 0.002) == Feed(PVT, 8)
    assert feed_way(node, [1, 3, 6, 7], 64, 250, 0.0015).stride == 8  # 12 ms: whole ms
    assert "longer than the 255 ms" in feed_way(node, [1, 3, 6, 7], 64, 5000, 0.002)
    assert "does not say how many records" in feed_way(node, [1, 3, 6, 7], None, 250, 0.002)
    fed = buffered_node(node, PVT)
    assert fed.rpdo[-1].transmission == 255 and fed.rpdo[-1].mapping == ((0x20C1, 0),)
    assert all((0x20C1, 0) not in p.mapping for p in fed.rpdo[:-1])
    assert fed.tpdo == node.tpdo  # 0x20C4:1 was mapped by bus.yml


@pytest.mark.realtime
@pytest.mark.slow
def test_maxon_pvt_records_fed_ahead_ride_out_stalls_on_the_drives_own_clock(tmp_path):
    """maxon's EPOS2 as z (no SYNC of its own, no CSP, no FIFO fill to read) beside the project's
    drive x, which keeps time for the bus, on the wall clock: z's PVT buffer fed ahead with 16 ms
    records, the master stopped 200 ms once a second on average; z takes the records on its own
    clock, never underflows (nor at the plan's end, the master away or not), and every SYNC has
    its row."""
    code, meta, (names, data), made, err = record_stalled(
        tmp_path, 0.2, 1.0, seed=7, cfg=maxon_z_bus_yml(tmp_path), axes="x,z"
    )
    assert code == 0, err
    assert meta["timing"]["engine"]["sync_source"].startswith("drive x (node 1), on its own clock")
    assert (
        "ahead into its PVT buffer (64 records, each of 16 ms" in meta["timing"]["engine"]["streaming"]["z"]
    )
    assert meta["timing"]["samples_missing"] == {"x": 0, "z": 0}
    assert len(made) >= 3, made
    status = column(names, data, "z_ip_buffer_status").astype(int)
    assert not np.any(status & 0x0300)  # no underflow, no overflow
    position, demand = column(names, data, "z_position_rad"), column(names, data, "z_position_demand_rad")
    assert np.max(np.abs(position - demand)) < 0.01 * np.ptp(demand)


@pytest.mark.realtime
@pytest.mark.slow
def test_a_stall_longer_than_the_fifo_holds_is_a_planned_stop(tmp_path):
    """With 150 ms kept ahead, 200 ms stalls a second apart empty the FIFO: each time the drive ramps
    down and holds, enabled, no fault, and the segment runs again; a host away more often than
    MAX_REPEATS ends the run with the planned stop said. (The heartbeat the drive waits for, 150 ms
    and two of the master's periods, outlasts each stall.)"""
    code, meta, _, made, err = record_stalled(tmp_path, 0.2, 1.0, seed=2, edit="stall_cover_ms: 150")
    assert made
    assert "Traceback" not in err
    repeats = meta.get("repeats") or []
    assert all("no fault" in r["ran_dry"]["reason"] and r["ran_dry"]["axis"] == "z" for r in repeats)
    if code == 0:  # the stalls past the FIFO were no more than the run repeats
        assert 1 <= len(repeats) <= MAX_REPEATS and meta["timing"]["samples_missing"] == {"z": 0}
    else:
        assert code == 4 and len(repeats) == MAX_REPEATS, err
        assert "its interpolation FIFO ran dry" in err and "no fault" in err
        assert meta["abort"]["axis"] == "z" and not meta["abort"].get("emcy")


@pytest.mark.realtime
@pytest.mark.slow
def test_a_segment_the_fifo_ran_dry_in_is_streamed_again_and_the_campaign_goes_on(tmp_path):
    """40 ms kept ahead, the master's engine stopped 200 ms halfway through the plan: z's FIFO runs
    dry and its drive makes a planned stop; the segment it was in is streamed again from its start
    after an approach, in a trace of its own, and the campaign completes: a row for every plan row,
    none missing, the repeat in meta.yaml, and the log decoded from the two traces as written live."""
    config = buffered(quick_config(), stall_cover_s=0.04).only(["z"])

    with open_link(config, sim=True, realtime=True) as link:
        on_plan, done = stalling_at(lambda: link.engine.pid, [0.5], 0.2)
        result = record(config, link, tmp_path, on_plan=on_plan)
    assert done
    assert result.ok, result.aborted
    assert 1 <= len(result.repeats) <= MAX_REPEATS
    repeat = result.repeats[0]
    assert repeat["ran_dry"]["axis"] == "z" and "ran dry" in repeat["ran_dry"]["reason"]
    segment = result.plan.segments[repeat["segment"]]
    begin = repeat["from_row"]  # the segment's start, or where its first move starts from rest
    assert begin <= segment.start <= repeat["ran_dry"]["row"] < segment.end
    assert np.array_equal(result.plan.demand[begin], result.plan.demand[begin - 1])
    assert f"segment {repeat['segment']} ({segment.kind}) streamed again from row" in result.repeated()
    meta = yaml.safe_load((tmp_path / "meta.yaml").read_text())
    assert meta["status"] == "ok" and meta["repeats"] == result.repeats
    assert (tmp_path / repeat["trace"]).is_file()
    names, data = read_csv(tmp_path / "log.csv")
    assert len(data) == len(result.plan.demand) and result.missing == {"z": 0}
    demand = column(names, data, "z_position_demand_rad")
    assert np.allclose(demand, result.plan.demand[:, 0], atol=1e-5)  # every plan row, in order, once
    position = column(names, data, "z_position_rad")
    assert np.max(np.abs(position - demand)) < 0.05 * np.ptp(demand)
    decoded_names, decoded, _, _, problem = decode_trace(tmp_path / "trace.blf")
    assert problem is None and decoded_names == names
    assert np.allclose(decoded, data, equal_nan=True)


@pytest.mark.realtime
@pytest.mark.slow
def test_a_host_that_holds_master_and_drives_up_together_leaves_no_trace(tmp_path):
    """The host holds the engine and the simulated drives up together for 400 ms, twice (a VM's
    vCPUs held: what the idle paper campaign met) -- longer than the 300 ms the master waits for a
    heartbeat, shorter than the records kept ahead.  The engine does not count the time it was
    away as the drives' silence, and judges the SYNCs and TPDOs they then send in a burst, stamped
    in the past, by those stamps once read: no "heartbeat lost" or "no SYNC" stop, no repeat, a
    row for every SYNC.  (Before, it stopped: heartbeat lost; the paper campaign stopped twice
    with "no TPDO: no feedback for 22 ms".)"""
    config = buffered(quick_config()).only(["x", "z"])
    with open_link(config, sim=True, realtime=True) as link:
        on_plan, done = stalling_at(
            lambda: [link.engine.pid, simulator_process(os.getpid())], [0.3, 0.6], 0.4
        )
        result = record(config, link, tmp_path, on_plan=on_plan)
    assert result.ok, result.aborted
    assert len(done) == 2
    assert result.timing.engine["sync_source"].startswith("drive x (node 1), on its own clock")
    assert result.missing == {"x": 0, "z": 0} and not result.repeats


@pytest.mark.realtime
@pytest.mark.slow
def test_an_error_while_a_segment_is_repeated_still_leaves_the_rows_recorded(tmp_path, monkeypatch):
    """The FIFO ran dry and the drive holds; the position read the repeat starts from fails (a
    drive gone quiet): the error goes on up, but log.csv has the rows of the stream before it and
    meta.yaml says the run was aborted and why."""
    config = buffered(quick_config(), stall_cover_s=0.04).only(["z"])

    def gone_quiet(plan, segment, here):
        raise BusError("axis z: no SDO response")

    monkeypatch.setattr("drive_bridge.recorder.resume_plan", gone_quiet)
    with open_link(config, sim=True, realtime=True) as link:
        on_plan, done = stalling_at(lambda: link.engine.pid, [0.5], 0.2)
        with pytest.raises(BusError, match="no SDO response"):
            record(config, link, tmp_path, on_plan=on_plan)
    assert done
    meta = yaml.safe_load((tmp_path / "meta.yaml").read_text())
    assert meta["status"] == "aborted" and "no SDO response" in meta["abort"]["reason"]
    names, data = read_csv(tmp_path / "log.csv")
    sent = meta["counts"]["cycles_sent"]
    assert 0 < sent < meta["counts"]["cycles_planned"] and len(data) == sent


@pytest.mark.realtime
@pytest.mark.slow
def test_a_motion_whose_fifo_ran_dry_runs_again_from_where_the_axes_stopped(tmp_path):
    """A validation's motion (40 ms kept ahead) with the master's engine stopped 200 ms in it: the
    drive's planned stop, then the whole motion again after an approach; what comes back is the
    motion measured whole."""
    config = buffered(quick_config(), stall_cover_s=0.04).only(["z"])
    with open_link(config, sim=True, realtime=True) as link:
        axes = bring_up(link, config)
        here = axes["z"].position_rad()
        lim = axes["z"].cfg.limits
        there = here + 0.3 * (lim.position_max - here)
        out = approach_move(lim, here, there, config.master.sync_period_s, level=0.5)
        demand = {"z": np.concatenate([out, out[::-1]])}
        on_plan, done = stalling_at(lambda: link.engine.pid, [0.5], 0.2)
        measured = motion.run(config, link, axes, demand, on_plan=on_plan)
    assert done
    assert measured.aborted is None, measured.aborted
    assert len(measured.position["z"]) == len(demand["z"]) and np.all(np.isfinite(measured.position["z"]))
    assert np.allclose(measured.demand["z"][1:], demand["z"][:-1], atol=1e-5)
