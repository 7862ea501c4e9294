"""Benchmark: how long the test suite takes here -- issue 43's goal (the suite ≤ 120 s idle, ``-m "not
slow"`` ≤ 30 s) measured with its references in the same run.

    python tools/bench_suite.py [--quick] [--runs 1] [--against REV]

Runs ``python -m pytest`` as the README's test command does (the project's options: two workers)
on this checkout, with ``--quick`` only the tests not marked slow; with ``--against REV`` the same
on git revision REV (a worktree with ``../shared`` beside it, as this checkout has it), the runs
alternated (the machine's speed drifts within the hour), each checkout's quick run once untimed
first (a fresh worktree compiles its modules and numba's kernels in its first run).  Beside each
run, the machine's speed that moment: the plain python-can pump of ``tools/reference.py`` [x real time] right before it -- the
suite is CPU-bound Python, and the pump says how fast this machine runs such code today (it moves by
up to 2x between days).  Prints per run the wall time, the CPU time of the suite's processes (user +
system, every worker and every process a test started) and pytest's own summary.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import resource
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tools.reference import pumps, stamp, worktree  # noqa: E402

GOAL_S = {False: 120.0, True: 30.0}  # issue 43: the whole suite, the quick run (-m "not slow")


def children_cpu() -> float:
    """CPU time [s] (user + system) of every process this one has waited for so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def pytest(root: Path, quick: bool) -> subprocess.CompletedProcess:
    """The README's test command on the checkout at ``root`` (``quick``: ``-m "not slow"``)."""
    command = [sys.executable, "-m", "pytest"] + (["-m", "not slow"] if quick else [])
    env = {**os.environ, "PYTHONPATH": str(root)}
    return subprocess.run(command, cwd=root, env=env, capture_output=True, text=True)


def run_suite(root: Path, quick: bool) -> dict:
    """One run of the suite of the checkout at ``root``: wall [s], cpu [s], pytest's summary line
    and its exit status, and the pump's speed right before it."""
    pump = pumps()
    cpu, t0 = children_cpu(), time.perf_counter()
    done = pytest(root, quick)
    wall, cpu = time.perf_counter() - t0, children_cpu() - cpu
    lines = [line for line in done.stdout.splitlines() if re.search(r"\d+ (passed|failed|error)", line)]
    failed = re.findall(r"^_{3,} (\S.*?) _{3,}$", done.stdout, re.MULTILINE)  # each failure's heading
    return {
        "wall": wall,
        "cpu": cpu,
        "summary": (lines or done.stdout.strip().splitlines() or [""])[-1].strip("= ")
        + "".join(f"\n    failed: {name}" for name in failed),
        "code": done.returncode,
        "pump": pump,
    }


@contextlib.contextmanager
def checkout(revision: str) -> Iterator[Path]:
    """A worktree of ``revision`` with this checkout's ``../shared`` beside it (the tests read it there)."""
    with worktree(ROOT, revision) as path:
        shared = ROOT.parent / "shared"
        if shared.is_dir():
            (path.parent / "shared").symlink_to(shared.resolve())
        yield path


def describe(run: dict) -> str:
    return (
        f"{run['wall']:.1f} s (CPU {run['cpu']:.0f} s; pump {run['pump']:.1f}x real time just before): "
        f"{run['summary']}" + ("" if run["code"] == 0 else f" -- exit {run['code']}")
    )


def main(quick: bool, runs: int, against: str | None) -> int:
    what = 'pytest -m "not slow"' if quick else "the whole suite"
    mine, theirs = [], []
    with checkout(against) if against else contextlib.nullcontext() as other:
        for root in [ROOT] + ([other] if other else []):  # compiled modules and numba's kernels cached
            pytest(root, quick=True)
        for _ in range(runs):  # alternated: the machine's speed drifts
            mine.append(run_suite(ROOT, quick))
            if other is not None:
                theirs.append(run_suite(other, quick))
    print(stamp())
    print(f"{what}, this checkout (goal: <= {GOAL_S[quick]:g} s idle):")
    for run in mine:
        print("  " + describe(run))
    if theirs:
        print(f"revision {against}, alternated with it:")
        for run in theirs:
            print("  " + describe(run))
        best, ref = min(r["wall"] for r in mine), min(r["wall"] for r in theirs)
        print(f"-> this checkout takes {best / ref:.2f}x the time of {against} (best runs)")
    return max(r["code"] for r in mine + theirs)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help='only the tests not marked slow (-m "not slow")')
    parser.add_argument("--runs", type=int, default=1, help="runs of each checkout (default 1)")
    parser.add_argument("--against", help="a git revision to time beside this checkout, alternated")
    args = parser.parse_args()
    sys.exit(main(args.quick, args.runs, args.against))
