"""Benchmark: wall time of ``drive-bridge commission --sim`` with the full paper campaign
(25 cycles or 300 s per axis) or the short designed one, as a new process, the way a user runs it.

    python tools/bench_commission.py [--runs 3] [--campaign paper|short]

Prints each run's wall time and the steps' durations from its summary.json, and the campaign's
speed as a ratio to the plain python-can pump of tools/reference.py measured in the same run.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from tools.reference import pump, stamp                   # noqa: E402


MOTION_S = {"paper": 867.47, "short": 90.0}     # each campaign's motion on the simulated robot [s]


def main(runs: int, design: str) -> None:
    print(stamp())
    ref = pump()
    print(f"plain python-can pump (tools/reference.py): {ref:.1f}x real time")
    walls = []
    for i in range(runs):
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "run"
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "drive_bridge", "commission", "--sim", "--campaign", design,
                            "--out", str(out)], check=True, stderr=subprocess.DEVNULL)
            wall = time.perf_counter() - t0
            summary = json.loads((out / "summary.json").read_text())
        walls.append(wall)
        steps = ", ".join(f"{s['name']} {s['duration_s']:.1f}" for s in summary["steps"])
        campaign_s = next(s["duration_s"] for s in summary["steps"] if s["name"] == "campaign")
        print(f"run {i + 1}: {wall:.1f} s wall ({summary['status']}); steps [s]: {steps}; campaign "
              f"{MOTION_S[design] / campaign_s:.1f}x real time = {MOTION_S[design] / campaign_s / ref:.2f}x the pump")
    print(f"wall time: min {min(walls):.1f} s, max {max(walls):.1f} s")


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--campaign", choices=list(MOTION_S), default="paper")
    args = parser.parse_args()
    main(args.runs, args.campaign)
