"""Benchmark: how long a command takes to start -- ``drive-bridge --help`` (the parser of every
command: what each command waits before it does anything) as a person at the machine starts it.

    python tools/bench_startup.py [--runs 7] [--against REV]

Beside it, in the same run and alternated with it (the machine's speed drifts): the floor, a
Python that imports what every command needs (numpy, python-can, canopen, PyYAML) and nothing else;
with ``--against REV`` the same command from git revision REV (a worktree).  Prints the median
wall time of each [s] and the ratios.  What the parser must not import is a test's
(``tests/test_api.py``: python-control, matplotlib and scipy.signal are loaded by the commands
that compute with them).
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tools.reference import stamp, worktree  # noqa: E402

FLOOR = "import numpy, can, canopen, yaml"


def _wall(command: list[str], cwd: Path) -> float:
    start = time.perf_counter()
    subprocess.run(command, cwd=cwd, check=True, capture_output=True)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=7)
    parser.add_argument("--against", help="a git revision whose start is timed in the same run")
    args = parser.parse_args()
    help_command = [sys.executable, "-m", "drive_bridge", "--help"]  # (-m: the tree it runs in)
    with worktree(ROOT, args.against) if args.against else contextlib.nullcontext() as other:
        runs: dict[str, list[float]] = {"this code": [], "floor": [], **({args.against: []} if other else {})}
        for _ in range(args.runs + 1):  # the first round warms the caches, and is not counted
            rounds = {
                "this code": _wall(help_command, ROOT),
                "floor": _wall([sys.executable, "-c", FLOOR], ROOT),
                **({args.against: _wall(help_command, other)} if other else {}),
            }
            for name, wall in rounds.items():
                runs[name].append(wall)
    median = {name: statistics.median(walls[1:]) for name, walls in runs.items()}
    print(stamp())
    print(f"drive-bridge --help: {median['this code']:.3f} s (median of {args.runs})")
    print(
        f"floor ({FLOOR}): {median['floor']:.3f} s -> {median['this code'] / median['floor']:.2f}x the floor"
    )
    if args.against:
        ref = median[args.against]
        print(
            f"revision {args.against}: {ref:.3f} s -> this code takes {median['this code'] / ref:.2f}x its time"
        )


if __name__ == "__main__":
    main()
