"""Benchmark: wall time and memory of ``drive-bridge commission --sim`` with the full paper campaign
(25 cycles or 300 s per axis) or the short designed one, as a new process, the way a user runs it.

    python tools/bench_commission.py [--runs 3] [--campaign paper|short]

Prints each run's wall time, the steps' durations from its summary.json, the peak resident memory
of the main process and of its worker processes, and the campaign's speed as a ratio to the plain
python-can pump of tools/reference.py measured in the same run (right before each run).  The
targets (issue 30): the paper campaign within its bus exchange at the pump's rate (867.5 s of
motion / the pump's speed) plus 10 s; the short one within 15 s; the main process under 400 MB.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from tools.reference import pumps, stamp  # noqa: E402

MOTION_S = {"paper": 867.47, "short": 90.0}  # each campaign's motion on the simulated robot [s]
TARGET_MB = 400

#: the command as a user runs it, and at its exit the peak resident memory of the process and of the
#: largest of its children (the identification's forked workers) into the file $BENCH_MEMORY
RUN = """import atexit, json, os, resource, runpy, sys
def peaks():
    with open(os.environ["BENCH_MEMORY"], "w") as f:
        json.dump({"main": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                   "workers": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024}, f)
atexit.register(peaks)
sys.argv = ["drive-bridge", *sys.argv[1:]]
runpy.run_module("drive_bridge", run_name="__main__")
"""


def main(runs: int, design: str) -> None:
    print(stamp())
    walls, bounds = [], []
    for i in range(runs):
        ref = pumps()
        with tempfile.TemporaryDirectory() as tmp:
            out, memory = Path(tmp) / "run", Path(tmp) / "memory.json"
            t0 = time.perf_counter()
            subprocess.run(
                [sys.executable, "-c", RUN, "commission", "--sim", "--campaign", design, "--out", str(out)],
                check=True,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                env={**os.environ, "BENCH_MEMORY": str(memory)},
            )
            wall = time.perf_counter() - t0
            summary = json.loads((out / "summary.json").read_text())
            peak = json.loads(memory.read_text())
        walls.append(wall)
        bound = MOTION_S[design] / ref + 10.0 if design == "paper" else 15.0
        bounds.append(bound)
        steps = ", ".join(f"{s['name']} {s['duration_s']:.1f}" for s in summary["steps"])
        campaign_s = next(s["duration_s"] for s in summary["steps"] if s["name"] == "campaign")
        print(
            f"run {i + 1}: {wall:.1f} s wall ({summary['status']}; target {bound:.1f} s: "
            f"{'met' if wall <= bound else f'{wall - bound:.1f} s over'}); steps [s]: {steps}; "
            f"campaign {MOTION_S[design] / campaign_s:.1f}x real time = {MOTION_S[design] / campaign_s / ref:.2f}x "
            f"the pump ({ref:.1f}x); peak memory {peak['main']:.0f} MB (target {TARGET_MB}), "
            f"its workers {peak['workers']:.0f} MB"
        )
    print(
        f"wall time: min {min(walls):.1f} s, max {max(walls):.1f} s; "
        f"as a share of its target: {min(w / b for w, b in zip(walls, bounds)):.2f}-"
        f"{max(w / b for w, b in zip(walls, bounds)):.2f}"
    )


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--campaign", choices=list(MOTION_S), default="paper")
    args = parser.parse_args()
    main(args.runs, args.campaign)
