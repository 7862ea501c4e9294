"""Benchmark: lockstep speed of a full 3-axis campaign through the master, and wall-clock timing.

    python tools/bench_record.py lockstep [--seconds 300]    # campaign time / wall time
    python tools/bench_record.py realtime [--seconds 60]     # late cycles, lost samples, SYNC period p99

Lockstep: the whole master (bring-up, canopen PDO dispatch, BLF trace, CSV) against the
simulated drives; prints the real-time factor, and as a ratio to the plain python-can pump of
tools/reference.py measured in the same run, before and after (the bus itself, in Python here).  Realtime: the drives run against the wall
clock in their own thread; the master streams at 500 Hz and the SYNC time stamps of the
log give the period statistics.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from drive_bridge.connect import open_link                 # noqa: E402
from drive_bridge.config import load_bus_config          # noqa: E402
from drive_bridge.record import record                   # noqa: E402
from drive_bridge.resources import DEFAULT_BUS_CONFIG   # noqa: E402
from tools.reference import pump, stamp                  # noqa: E402


def campaign_config(seconds: float):
    cfg = load_bus_config(DEFAULT_BUS_CONFIG)
    return replace(cfg, campaign=replace(cfg.campaign, max_axis_time_s=seconds / 3, together=False))


def lockstep(seconds: float) -> None:
    cfg = campaign_config(seconds)
    reference = [pump()]
    with tempfile.TemporaryDirectory() as out, open_link(cfg, sim=True) as link:
        t0 = time.perf_counter()
        result = record(cfg, link, out)
        wall = time.perf_counter() - t0
    reference.append(pump())
    motion = result.cycles_sent * cfg.master.sync_period_s
    speed, ref = motion / wall, float(np.mean(reference))
    print(stamp())
    print(f"lockstep: {motion:.1f} s of campaign ({result.cycles_sent} SYNC cycles, 3 axes) in {wall:.2f} s "
          f"-> {speed:.1f}x real time; missing samples {sum(result.missing.values())}")
    print(f"plain python-can pump (same frames per cycle): {reference[0]:.1f}x before, {reference[1]:.1f}x after "
          f"-> master with drives at {speed / ref:.2f}x the pump")


def realtime(seconds: float) -> None:
    cfg = campaign_config(seconds)
    cfg = replace(cfg, campaign=replace(cfg.campaign, together=True, max_axis_time_s=seconds))
    with tempfile.TemporaryDirectory() as out, open_link(cfg, sim=True, realtime=True) as link:
        result = record(cfg, link, out)
        data = np.loadtxt(Path(out) / "log.csv", delimiter=",", skiprows=1, usecols=(1,))
    period = cfg.master.sync_period_s
    dt = np.diff(data)
    late = np.count_nonzero(dt > 1.5 * period)
    print(f"realtime: {len(data)} cycles ({len(data) * period:.1f} s), late cycles (> 1.5 periods) {late} "
          f"({100 * late / max(1, len(dt)):.2f} %), samples lost {sum(result.missing.values())}, "
          f"SYNC period mean {dt.mean() * 1e3:.3f} ms, p99 {np.percentile(dt, 99) * 1e3:.3f} ms, "
          f"max {dt.max() * 1e3:.3f} ms; status {'ok' if result.ok else result.aborted}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("mode", choices=["lockstep", "realtime"])
    parser.add_argument("--seconds", type=float, default=None)
    args = parser.parse_args()
    if args.mode == "lockstep":
        lockstep(args.seconds or 300.0)
    else:
        realtime(args.seconds or 60.0)
