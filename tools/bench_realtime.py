"""Benchmark: the wall clock.  ``drive-bridge commission --sim --realtime``, each run as a user
starts it, beside the machine's own floor measured in the same run.

    python tools/bench_realtime.py [--campaign short|paper] [--runs 3] [--load idle|loaded|both]
                                   [--floor-seconds 30] [--against REV] [--config BUS_YML]

The floor (``harness/machine_floor.py``): a plain Python loop pinned to each CPU at SCHED_FIFO on the same
2 ms absolute schedule (as cyclictest measures: sleep to the next deadline, note how late it woke),
each in a process of its own, for
``--floor-seconds`` right before the runs of each condition, and again *during* each run.  Per
run: its verdict, the campaign's late cycles, SYNC period p99 and max, the largest SYNC gap in
periods, the age of the feedback when the engine had it (p99, max), the samples missing, whether
any motion aborted -- and each late SYNC of the campaign (a gap over 1.5 periods, from the
trace's stamps) set against the floor of the same moment (one plain loop pinned to each CPU):
"machine" where the loop on every CPU was held up as long at the same time (no CPU there for a
task of the engine's priority); "a vCPU" where the loop on one CPU was (a virtual CPU the host
did not run: every timer on it fires late, the engine's too when it slept there -- which CPU it
slept on is not recorded, so this is the most the machine can explain); "ours" where neither
was.  The largest of ours is what the engine adds to the machine.
``loaded``: two CPU-bound processes beside it (the floor measured beside them too); ``stalled``: every
process of the master (its main process and its engine's, never the simulated drives') stopped for
``--stall-ms`` at random moments, ``--stall-every`` seconds apart on average (``harness/stalls.py``;
issue 68's third condition), the stalls made counted per run.
``--against REV`` runs git revision REV the same way, alternated with this code; ``--config`` runs
another bus.yml (ros2_canopen's, ``drive_bridge/data/config/ros2_canopen.yml``), lockstep's too.
The acceptance (issue 42): every run PASS, 0 aborts, 0 samples missing, late cycles <= 0.1 %
idle (<= 0.5 % loaded) and the largest SYNC gap <= 5 periods.  Issue 68's: in each condition every run
completes with 0 drive faults and 0 samples missing, its verdict lockstep's and J, c0 and c1 of every
axis within 3 combined standard deviations of lockstep's -- the same campaign run once in lockstep
first, each run's distance printed beside it.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import asdict
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from harness.machine_floor import PERIOD_S, floor_during, machine_explains  # noqa: E402
from harness.stalls import injector  # noqa: E402
from tools.reference import stamp, worktree  # noqa: E402


def against_floor(trace: Path, held: list[list[tuple[float, float]]]) -> dict:
    """Each late SYNC of the campaign's trace [ms late] set against the floor of the same moment:
    the machine's (the plain loop on *every* CPU held up as long: no CPU was there for a task of
    the engine's priority), a vCPU's (the loop on one CPU held up as long: a timer on that CPU
    fired late) or ours (neither)."""
    import can

    syncs = np.array([m.timestamp for m in can.BLFReader(str(trace)) if m.arbitration_id == 0x080])
    per_cpu = [(np.array([t for t, _ in cpu]), np.array([w for _, w in cpu])) for cpu in held]
    kinds: dict[str, list[float]] = {"machine": [], "vcpu": [], "ours": []}
    for i in np.flatnonzero(np.diff(syncs) > 1.5 * PERIOD_S):
        gap_ms = (syncs[i + 1] - syncs[i]) * 1e3
        late_ms = gap_ms - PERIOD_S * 1e3
        held_ms = [
            float(stalls[(starts >= syncs[i] - PERIOD_S) & (starts <= syncs[i + 1])].max(initial=0.0))
            for starts, stalls in per_cpu
        ]
        kind = (
            "machine"
            if machine_explains(gap_ms, min(held_ms))
            else "vcpu"
            if machine_explains(gap_ms, max(held_ms))
            else "ours"
        )
        kinds[kind].append(late_ms)
    return {
        "late_syncs": sum(map(len, kinds.values())),
        **{kind: len(late) for kind, late in kinds.items()},
        **{f"{kind}_max_ms": max(late, default=0.0) for kind, late in kinds.items()},
    }


def floor(seconds: float) -> dict:
    """The machine's own floor: how late the plain loops wake on a 2 ms schedule [ms], for
    ``seconds`` with nothing of ours running."""
    with floor_during() as result:
        time.sleep(seconds)
    return asdict(result)


@contextlib.contextmanager
def load(kind: str) -> Iterator[None]:
    """Two CPU-bound processes beside the block (``loaded``), or nothing (``idle``)."""
    hogs = [
        subprocess.Popen([sys.executable, "-c", "while True: pass"])
        for _ in range(2 if kind == "loaded" else 0)
    ]
    try:
        yield
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()


#: the identified parameters compared with the lockstep run's
COMPARED = ("J", "c0", "c1")


def identified(out: Path) -> dict[str, dict[str, tuple[float, float]]]:
    """Per axis, J, c0 and c1 of a run's identify.json with their standard deviations."""
    path = out / "identify" / "identify.json"
    if not path.exists():
        return {}
    axes = json.loads(path.read_text())["axes"]
    return {
        axis: {
            k: (float(a["params"][k]), float(a["param_std"].get(k) or 0.0))
            for k in COMPARED
            if k in a["params"]
        }
        for axis, a in axes.items()
    }


def lockstep(code: Path, campaign: str, config: tuple[str, ...]) -> dict:
    """The same campaign in lockstep (the same plan and seed): its verdict and parameters, the reference."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        env = {**os.environ, "PYTHONPATH": str(code), "XDG_DATA_HOME": tmp}
        command = [sys.executable, "-m", "drive_bridge", "commission", "--sim", "--campaign", campaign]
        command += ["--out", str(out), "--no-history", "--yes", *config]
        proc = subprocess.run(command, cwd=code, env=env, capture_output=True, text=True)
        summary = json.loads((out / "summary.json").read_text()) if (out / "summary.json").exists() else {}
        verdict = summary.get("verdict", {})
        return {
            "exit": proc.returncode,
            "verdict": verdict.get("overall") if isinstance(verdict, dict) else verdict,
            "params": identified(out),
        }


def against_lockstep(params: dict, reference: dict) -> tuple[float, str]:
    """The largest |wall clock - lockstep| of J, c0, c1 over any axis, in combined standard deviations
    (sqrt(std_wall² + std_lockstep²)), and which."""
    worst, which = 0.0, ""
    for axis, values in reference.items():
        for name, (ref, ref_std) in values.items():
            if axis not in params or name not in params[axis]:
                return math.inf, f"{axis} {name} not identified"
            value, std = params[axis][name]
            combined = math.hypot(std, ref_std)
            distance = abs(value - ref) / combined if combined > 0 else (0.0 if value == ref else math.inf)
            if distance >= worst:
                worst, which = distance, f"{axis} {name}"
    return worst, which


def commission(
    code: Path,
    campaign: str,
    stalls: tuple[float, float] | None = None,
    seed: int = 0,
    config: tuple[str, ...] = (),
) -> dict:
    """One ``commission --sim --realtime`` run of the code under ``code``, with ``stalls`` (length,
    mean wait [s]) of the master's processes where given, their moments drawn with ``seed``; its
    figures."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        env = {**os.environ, "PYTHONPATH": str(code), "XDG_DATA_HOME": tmp}
        command = [sys.executable, "-m", "drive_bridge", "commission", "--sim", "--realtime"]
        command += ["--campaign", campaign, "--out", str(out), "--no-history", "--yes", *config]
        made = Path(tmp) / "stalls.jsonl"
        t0 = time.perf_counter()
        with floor_during() as beside:
            proc = subprocess.Popen(
                command, cwd=code, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
            )
            stalling = injector(proc.pid, *stalls, seed=seed, log=made) if stalls else None
            try:
                stdout, stderr = proc.communicate()
            finally:
                if stalling is not None:
                    stalling.terminate()
                    stalling.wait()
        wall = time.perf_counter() - t0
        stalled = len(made.read_text().splitlines()) if made.exists() else 0
        trace = out / "campaign" / "trace.blf"
        matched = against_floor(trace, beside.held) if trace.exists() else {}
        summary = json.loads((out / "summary.json").read_text()) if (out / "summary.json").exists() else {}
        meta_path = out / "campaign" / "meta.yaml"
        meta = yaml.safe_load(meta_path.read_text()) if meta_path.exists() else {}
        streams = [yaml.safe_load(p.read_text()) for p in sorted(out.rglob("meta.yaml"))]
        sync = np.empty(0)
        if (out / "campaign" / "log.csv").exists():
            sync = np.loadtxt(out / "campaign" / "log.csv", delimiter=",", skiprows=1, usecols=(1,), ndmin=1)
        params = identified(out)
    timing = meta.get("timing", {})
    engine = timing.get("engine", {})
    gaps = np.diff(sync[np.isfinite(sync)]) * 1e3 if sync.size > 1 else np.zeros(1)
    aborts = [s.get("abort", {}).get("reason") for s in streams if s.get("status") == "aborted"]
    verdict = summary.get("verdict", {})
    return {
        "exit": proc.returncode,
        "wall_s": wall,
        "stalls": stalled,
        "verdict": verdict.get("overall") if isinstance(verdict, dict) else verdict,
        "late_pct": timing.get("late_cycles_pct"),
        "p99_ms": float(np.percentile(gaps, 99)),
        "max_ms": float(gaps.max()),
        "gap_periods": float(gaps.max()) / (PERIOD_S * 1e3),
        "age": engine.get("feedback_age_ms", {}),
        "missing": sum((timing.get("samples_missing") or {}).values()),
        "skipped": engine.get("periods_skipped"),
        "host": engine.get("host", timing.get("priority")),
        "floor": asdict(beside),
        "matched": matched,
        "params": params,
        "unmet": {
            axis: v.get("unmet")
            for axis, v in ((verdict.get("axes") or {}) if isinstance(verdict, dict) else {}).items()
            if v.get("unmet")
        },
        "faults": sum(1 for a in aborts if a and "EMCY" in str(a)),
        "aborts": aborts
        or [line.strip() for line in (stdout + stderr).splitlines() if "FAILED:" in line]
        or ([stderr.strip().splitlines()[-1]] if proc.returncode not in (0, 5, 6) and stderr.strip() else []),
    }


def line(name: str, r: dict, reference: dict | None = None) -> str:
    age = r["age"]
    compared = ""
    if reference is not None:
        worst, which = against_lockstep(r["params"], reference["params"])
        compared = (
            f"; verdict {'as' if r['verdict'] == reference['verdict'] else 'NOT as'} lockstep's "
            f"({reference['verdict']}), J/c0/c1 at most {worst:.2f} combined std from lockstep's ({which})"
        )
        if r["verdict"] != reference["verdict"] and r["unmet"]:
            compared += f"; unmet: {r['unmet']}"
    return (
        f"  {name}: {r['verdict']} (exit {r['exit']}, {r['wall_s']:.0f} s"
        + (f", {r['stalls']} stalls of the master" if r["stalls"] else "")
        + f"): late cycles {r['late_pct']} %, "
        f"SYNC period p99 {r['p99_ms']:.2f} ms, max {r['max_ms']:.2f} ms ({r['gap_periods']:.1f} periods), "
        f"feedback age p99 {age.get('p99', '?')} ms max {age.get('max', '?')} ms, samples missing "
        f"{r['missing']}, periods skipped {r['skipped']}, aborts {len(r['aborts'])}"
        + (f" ({'; '.join(str(a) for a in r['aborts'])})" if r["aborts"] else "")
        + compared
        + f"\n    the floor during the run: max {r['floor']['max']:.2f} ms, {r['floor']['over_3ms_pct']:.3f} % over 3 ms"
        + (
            f"; late SYNCs {m['late_syncs']}: {m['machine']} the machine's (every CPU's floor held; up to "
            f"{m['machine_max_ms']:.1f} ms late), {m['vcpu']} a vCPU's (one CPU's floor held; up to "
            f"{m['vcpu_max_ms']:.1f} ms), {m['ours']} ours (up to {m['ours_max_ms']:.1f} ms) "
            if (m := r["matched"])
            else ""
        )
    )


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--campaign", choices=["short", "paper"], default="short")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--load", choices=["idle", "loaded", "stalled", "both", "all"], default="both")
    parser.add_argument("--stall-ms", type=float, default=200.0, help="with stalled: each stall [ms]")
    parser.add_argument("--stall-every", type=float, default=2.0, help="with stalled: the mean wait [s]")
    parser.add_argument("--floor-seconds", type=float, default=30.0)
    parser.add_argument("--against", help="a git revision run the same way, alternated with this code")
    parser.add_argument("--config", help="a bus.yml (default: the simulated robot's own)")
    args = parser.parse_args()
    config = ("--config", str(Path(args.config).resolve())) if args.config else ()
    print(stamp())
    conditions = {"both": ["idle", "loaded"], "all": ["idle", "loaded", "stalled"]}.get(
        args.load, [args.load]
    )
    stalls = (args.stall_ms / 1e3, args.stall_every)
    reference = lockstep(ROOT, args.campaign, config)
    print(f"lockstep (the same plan and seed): {reference['verdict']} (exit {reference['exit']})", flush=True)
    with worktree(ROOT, args.against) if args.against else contextlib.nullcontext() as other:
        for condition in conditions:
            with load(condition):
                f = floor(args.floor_seconds)
                print(
                    f"{condition}: the machine's floor ({f['granted']}, {args.floor_seconds:g} s on a 2 ms schedule): "
                    f"wakes late p99 {f['p99']:.3f} ms, p99.9 {f['p999']:.3f} ms, max {f['max']:.3f} ms, "
                    f"{f['over_3ms_pct']:.3f} % over 3 ms",
                    flush=True,
                )
                for run in range(args.runs):
                    stalled = stalls if condition == "stalled" else None
                    print(
                        line(
                            f"{args.campaign} run {run + 1}",
                            commission(ROOT, args.campaign, stalled, run, config),
                            reference,
                        ),
                        flush=True,
                    )
                    if other is not None:
                        print(
                            line(
                                f"{args.against} run {run + 1}",
                                commission(other, args.campaign, stalled, run, config),
                            ),
                            flush=True,
                        )


if __name__ == "__main__":
    main()
