"""Benchmark: lockstep speed of a full 3-axis campaign through the master, and wall-clock timing.

    python tools/bench_record.py lockstep [--seconds 300] [--runs 3] [--against REV] [--profile N]
    python tools/bench_record.py realtime [--seconds 60]     # late cycles, lost samples, SYNC period p99

Lockstep: the whole master (bring-up, canopen PDO dispatch, BLF trace, CSV) against the
simulated drives, each run a process of its own; prints the real-time factor and, as the target
is set, its ratio to the plain python-can pump of tools/reference.py measured in the same process
right before and after (the bus itself, in Python here).  ``--against REV`` times git revision
REV the same way, the runs alternated, and says whether both wrote the same log.  ``--profile N``
prints where a run's time goes (cProfile, the N largest internal times; it slows the run ~3x).
Realtime: the drives run against the wall clock in their own thread; the master streams at
500 Hz and the SYNC time stamps of the log give the period statistics.
"""

from __future__ import annotations

import argparse
import contextlib
import cProfile
import json
import os
import pstats
import subprocess
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from drive_bridge.config import load_bus_config  # noqa: E402
from drive_bridge.connect import open_link  # noqa: E402
from drive_bridge.recorder import record  # noqa: E402
from drive_bridge.resources import DEFAULT_BUS_CONFIG  # noqa: E402
from tools.reference import stamp, worktree  # noqa: E402


def campaign_config(seconds: float):
    cfg = load_bus_config(DEFAULT_BUS_CONFIG)
    return replace(cfg, campaign=replace(cfg.campaign, max_axis_time_s=seconds / 3, together=False))


TIMED = """import hashlib, importlib.util, json, sys, tempfile, time
from dataclasses import replace
from pathlib import Path
spec = importlib.util.spec_from_file_location("reference", sys.argv[2])   # this checkout's pump
reference = importlib.util.module_from_spec(spec)
spec.loader.exec_module(reference)
from drive_bridge.config import load_bus_config
from drive_bridge.connect import open_link
from drive_bridge.recorder import record
from drive_bridge.resources import DEFAULT_BUS_CONFIG
cfg = load_bus_config(DEFAULT_BUS_CONFIG)
cfg = replace(cfg, campaign=replace(cfg.campaign, max_axis_time_s=float(sys.argv[1]) / 3, together=False))
before = reference.pumps()
with tempfile.TemporaryDirectory() as out, open_link(cfg, sim=True) as link:
    t0 = time.perf_counter()
    result = record(cfg, link, out)
    wall = time.perf_counter() - t0
    digest = hashlib.sha256((Path(out) / "log.csv").read_bytes()).hexdigest()
print(json.dumps({"wall": wall, "cycles": result.cycles_sent, "missing": sum(result.missing.values()),
                  "pump": [before, reference.pumps()], "log": digest}))
"""


def _timed(code: Path, seconds: float) -> dict:
    """One lockstep campaign recorded by the code under ``code`` (the pump: this checkout's)."""
    env = {**os.environ, "PYTHONPATH": str(code), "SOURCE_DATE_EPOCH": "1764000000"}
    pump = ROOT / "tools" / "reference.py"
    out = subprocess.run(
        [sys.executable, "-c", TIMED, str(seconds), str(pump)],
        cwd=code,
        env=env,
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    return json.loads(out.strip().splitlines()[-1])


def _line(name: str, runs: list[dict], period: float) -> float:
    speeds = [r["cycles"] * period / r["wall"] for r in runs]
    ratios = [s / float(np.mean(r["pump"])) for s, r in zip(speeds, runs)]
    print(
        f"{name}: {runs[0]['cycles'] * period:.1f} s of campaign ({runs[0]['cycles']} SYNC cycles, 3 axes), "
        f"missing samples {runs[0]['missing']}; per run "
        + ", ".join(
            f"{r['wall']:.2f} s = {s:.1f}x real time (pump {r['pump'][0]:.1f}x/{r['pump'][1]:.1f}x)"
            for r, s in zip(runs, speeds)
        )
        + f" -> master with drives at {float(np.median(ratios)):.2f}x the pump (median)"
    )
    return float(np.median(ratios))


def lockstep(seconds: float, runs: int, against: str | None, profile: int) -> None:
    period = campaign_config(seconds).master.sync_period_s
    print(stamp())
    with worktree(ROOT, against) if against else contextlib.nullcontext() as other:
        mine, theirs = [], []
        for _ in range(runs):  # alternated: the machine's speed drifts
            mine.append(_timed(ROOT, seconds))
            if other is not None:
                theirs.append(_timed(other, seconds))
    ratio = _line("this code", mine, period)
    if theirs:
        ref = _line(f"revision {against}", theirs, period)
        same = "the same log" if theirs[0]["log"] == mine[0]["log"] else "a DIFFERENT log"
        print(f"  -> {ratio / ref:.2f}x the speed of {against}; both wrote {same}")
    if profile:
        cfg = campaign_config(seconds)
        with tempfile.TemporaryDirectory() as out, open_link(cfg, sim=True) as link:
            prof = cProfile.Profile()
            prof.runcall(record, cfg, link, out)
        print(f"where the time goes (cProfile, the {profile} largest internal times):")
        pstats.Stats(prof).sort_stats("tottime").print_stats(profile)


def realtime(seconds: float) -> None:
    cfg = campaign_config(seconds)
    cfg = replace(cfg, campaign=replace(cfg.campaign, together=True, max_axis_time_s=seconds))
    with tempfile.TemporaryDirectory() as out, open_link(cfg, sim=True, realtime=True) as link:
        result = record(cfg, link, out)
        data = np.loadtxt(Path(out) / "log.csv", delimiter=",", skiprows=1, usecols=(1,))
    period = cfg.master.sync_period_s
    dt = np.diff(data)
    late = np.count_nonzero(dt > 1.5 * period)
    print(
        f"realtime: {len(data)} cycles ({len(data) * period:.1f} s), late cycles (> 1.5 periods) {late} "
        f"({100 * late / max(1, len(dt)):.2f} %), samples lost {sum(result.missing.values())}, "
        f"SYNC period mean {dt.mean() * 1e3:.3f} ms, p99 {np.percentile(dt, 99) * 1e3:.3f} ms, "
        f"max {dt.max() * 1e3:.3f} ms; status {'ok' if result.ok else result.aborted}"
    )


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("mode", choices=["lockstep", "realtime"])
    parser.add_argument("--seconds", type=float, default=None)
    parser.add_argument("--runs", type=int, default=3, help="lockstep: runs of each revision")
    parser.add_argument("--against", help="lockstep: a git revision timed in the same run")
    parser.add_argument("--profile", type=int, default=0, help="lockstep: print the N largest internal times")
    args = parser.parse_args()
    if args.mode == "lockstep":
        lockstep(args.seconds or 300.0, args.runs, args.against, args.profile)
    else:
        realtime(args.seconds or 60.0)
