"""Benchmark of identification (numbers in the README).

    python tools/bench_identify.py crb [--seeds 50]       # estimator spread against the reported std
    python tools/bench_identify.py coverage [--cases 40]  # true values within 3 reported std?
    python tools/bench_identify.py consistency [--seeds 60]  # the consistency check's false alarms and power
    python tools/bench_identify.py speed                   # 3 axes, 300 s at 500 Hz, with residual tracing
    python tools/bench_identify.py full [--log DIR] [--against REV] [--profile N] [--floor]
                                                           # the full paper campaign (867 s), where the time goes

crb: a log measured 50 times with different torque-noise seeds, identified as a user would
(``identify``: tracing, torque alignment); the standard deviation of J, c0, c1 over the seeds
against the std each fit reports (averaged; autocorrelation- and heteroskedasticity-consistent),
and how far the plant's values lie from the mean estimate in reported std.  Two plants: the
simulated Y axis (plant J, c0, c1 only) on a 60 s campaign, and the independent closed-loop plant
of the tests (``harness/plants.py``, 40 s at 1 kHz).  coverage: the independent plant with
structure no library effect or one-variable spline models (friction or torque depending on two
variables at once), amplitudes, plants and seeds drawn at random (seeded): the share of cases
where the true J, c0, c1 lie within 3 reported std.  speed: the shipped robot (with its hidden
effects), the default campaign cut to 100 s per axis, one axis after the other: 300 s of log.
consistency: the independent plants of :mod:`harness.consistency` (sines; the paper's trapezoid
levels) over ``--seeds`` noise seeds: the share of clean seeds flagged against the stated false-alarm
rate (with its binomial 95 % interval), whether the p-values are uniform as they must be on clean
data (Kolmogorov-Smirnov), and the seeds flagged where the inertia steps +10 %, +50 % halfway, with
the step each says it detects.
full: the log of the full paper campaign (``--log``: a record directory, as ``commission --sim``
leaves in ``campaign/``; default: the shipped robot's plant run bus-free through the campaign,
867 s at 500 Hz), identified as ``commission`` does; beside it the plain least squares of the same
axes (the same-run reference), and with ``--against REV`` the same log identified by the code of
git revision REV (a worktree, in a process of its own, the runs alternated): the speed-up measured
in one run.  ``--profile N``: the N functions the time goes to (cProfile, internal time).
``--floor``: the axes identified one after the other in this process, the CPU time of the stages a
faster implementation of the same method could at most remove counted apart (:data:`REMOVABLE`),
and the least time the rest would take on this machine's cores, the log's parse added (as
measured): what any implementation of these stages leaves of the run.
"""

from __future__ import annotations

import argparse
import contextlib
import cProfile
import importlib
import itertools
import json
import os
import pstats
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from drive_bridge.config import load_bus_config  # noqa: E402
from drive_bridge.ident import identify  # noqa: E402
from drive_bridge.master.campaign import build_plan  # noqa: E402
from drive_bridge.resources import DEFAULT_BUS_CONFIG  # noqa: E402
from drive_bridge.sim.plantlog import plant_log, write_log  # noqa: E402
from drive_bridge.sim.robot_config import DEFAULT_CONFIG as SIM_DEFAULT  # noqa: E402
from drive_bridge.sim.robot_config import load_sim_config  # noqa: E402
from tools.reference import least_squares, stamp, worktree  # noqa: E402


def plan_for(axes, seconds_per_axis):
    cfg = load_bus_config(DEFAULT_BUS_CONFIG)
    camp = replace(cfg.campaign, max_axis_time_s=seconds_per_axis, together=False)
    return build_plan(camp, {a: cfg.nodes[a].limits for a in axes}, dict.fromkeys(axes, 0.0), 0.002)


def _sim_y_logs(seeds: int):
    """The simulated Y axis's plant values, and its log once per noise seed.  The noise is the
    plant's own (``torque_noise_Nm`` with the config's seed): added before the drive rounds the
    torque to per mille, as a drive's current measurement is; noise added to a log already
    rounded would leave the rounding error of the noise-free torque, the same in every log."""
    sim = load_sim_config(SIM_DEFAULT)
    y = sim.axes["y"]
    y.effects, y.cp, y.D, y.torque_noise_Nm = {}, 0.0, 0.0, 0.004
    plan = plan_for(["y"], 60.0)
    return (
        {"J": y.J, "c0": y.c0, "c1": y.c1},
        (
            plant_log(replace(sim, axes={"y": y}, seed=seed), {"y": plan.demand[:, 0]})
            for seed in range(seeds)
        ),
    )


def _independent_logs(seeds: int):
    """The independent plant's values, and its log once per noise seed (the consistency check's
    "sines" family, clean)."""
    from harness.consistency import FAMILIES

    make = FAMILIES["sines"][0]
    return {"J": 1e-4, "c0": 0.3, "c1": 5e-4}, (make(seed, 0.0) for seed in range(seeds))


def crb(seeds: int) -> None:
    for name, logs in (
        ("simulated Y axis, 60 s campaign, torque noise 0.004 Nm + quantisation", _sim_y_logs),
        ("independent closed-loop plant, 40 s at 1 kHz, noise 0.004 Nm", _independent_logs),
    ):
        estimates, bounds = [], []
        plant, cols = logs(seeds)
        with tempfile.TemporaryDirectory() as tmp:
            for c in cols:
                r = identify(write_log(Path(tmp) / "log.csv", c), axes=["y"])["y"]
                estimates.append([r.model.params_[k] for k in ("J", "c1", "c0")])
                bounds.append([r.param_std[k] for k in ("J", "c1", "c0")])
        est, bound = np.array(estimates), np.mean(bounds, axis=0)
        print(f"{seeds} seeds, {name}")
        for i, k in enumerate(("J", "c1", "c0")):
            spread = est[:, i].std(ddof=1)
            off = abs(est[:, i].mean() - plant[k]) / bound[i]
            print(
                f"  {k:<3} mean {est[:, i].mean():.6g} (plant {plant[k]:.6g}, {off:.1f} reported std away), "
                f"spread {spread:.3g}, reported std {bound[i]:.3g}, ratio {spread / bound[i]:.2f}"
            )


STRUCTURES = {  # torque [Nm] no library effect nor a one-variable spline describes, with no part
    # that J, c0 or c1 could take as their own (zero mean over the stroke or the log); a ∈ [0.3, 1.5]
    "friction ∝ q·v (a guide tighter at one end, more with speed)": lambda a: (
        lambda q, v, a_, t: a * 0.002 * q * v
    ),
    "torque ∝ sin(q)·q̈ (an inertia that varies ±20 % along the stroke)": lambda a: (
        lambda q, v, a_, t: a * 2e-5 * np.sin(q) * a_
    ),
    "friction ∝ v·(t − 20 s) (heating with speed, about the middle of the log)": lambda a: (
        lambda q, v, a_, t: a * 5e-6 * v * (t - 20.0)
    ),
}


def coverage(cases: int, verbose: bool = False) -> None:
    from harness.plants import closed_loop_log

    rng = np.random.default_rng(0)
    inside = {k: 0 for k in ("J", "c0", "c1")}
    worst = {k: 0.0 for k in inside}
    with tempfile.TemporaryDirectory() as tmp:
        for case in range(cases):
            kind = list(STRUCTURES)[case % len(STRUCTURES)]
            plant = {
                "J": float(rng.uniform(0.8e-4, 1.5e-4)),
                "c0": float(rng.uniform(0.1, 0.4)),
                "c1": float(rng.uniform(2e-4, 8e-4)),
            }
            extra = STRUCTURES[kind](float(rng.uniform(0.3, 1.5)))
            cols = closed_loop_log(
                np.arange(40000) / 1000, seed=int(rng.integers(1 << 30)), extra=extra, **plant
            )
            r = identify(write_log(Path(tmp) / "log.csv", cols), axes=["y"])["y"]
            if verbose:
                print(
                    f"  case {case}: {kind}; effects {[e.effect.name for e in r.effects]}; "
                    f"consistent {r.diagnostics.consistency.get('consistent')}; "
                    + ", ".join(
                        f"{k} {(r.model.params_[k] - plant[k]) / r.param_std[k]:+.1f} std" for k in inside
                    )
                )
            for k in inside:
                z = abs(r.model.params_[k] - plant[k]) / r.param_std[k]
                inside[k] += z <= 3
                worst[k] = max(worst[k], z)
    print(
        f"{cases} cases of the independent plant with structure the model cannot describe "
        f"({len(STRUCTURES)} kinds, plants and amplitudes drawn at random, seed 0)"
    )
    for k in inside:
        print(
            f"  {k:<3} true value within 3 reported std in {inside[k]}/{cases} = {inside[k] / cases:.0%}, "
            f"worst {worst[k]:.1f} std"
        )


def consistency(seeds: int) -> None:
    from scipy import stats

    from harness.consistency import FAMILIES, checked

    for family, (_, words) in FAMILIES.items():
        clean = checked(family, range(seeds))
        rate = clean[0]["test"]["false_alarm_rate"]
        flagged = sum(a["consistent"] is False for a in clean)
        low, high = stats.binomtest(flagged, seeds, rate).proportion_ci(0.95)
        ks = stats.kstest([a["test"]["p_value"] for a in clean], "uniform").pvalue
        print(f"{family}: {words}")
        print(
            f"  clean: {flagged} of {seeds} flagged ({flagged / seeds:.1%}, 95 % interval {low:.1%}-{high:.1%}; "
            f"stated rate {rate:.0%}); p-values uniform: KS p = {ks:.2f}"
        )
        for step in (0.10, 0.50):
            answers = checked(family, range(seeds), step)
            hit = sum(a["consistent"] is False for a in answers)
            said = np.median([a["test"]["detects"]["J"] for a in answers])
            print(
                f"  J +{step:.0%} halfway: {hit} of {seeds} flagged; the step it says it sees 95 % of the time: {said:.1%} (median)"
            )


def speed() -> None:
    sim = load_sim_config(SIM_DEFAULT)
    plan = plan_for(list(sim.axes), 100.0)
    cols = plant_log(sim, {a: plan.demand[:, i] for i, a in enumerate(plan.axes)})
    with tempfile.TemporaryDirectory() as tmp:
        path = write_log(Path(tmp) / "log.csv", cols)
        t0 = time.perf_counter()
        results = identify(path)
        wall = time.perf_counter() - t0
    n = len(cols["time_s"])
    plain = sum(
        min(
            least_squares(cols["time_s"], cols[f"{a}_position_rad"], cols[f"{a}_torque_Nm"]) for _ in range(5)
        )
        for a in results
    )
    print(stamp())
    print(
        f"{n} rows ({n * 0.002:.0f} s at 500 Hz), 3 axes, identification with residual tracing and GA: "
        f"{wall:.2f} s; a plain filter + 3-column least squares of the same axes (tools/reference.py): "
        f"{plain * 1e3:.0f} ms -> {wall / plain:.0f}x that"
    )
    for a, r in results.items():
        print(
            f"  {a}: {[e.effect.name for e in r.effects]}, RMSE {r.before.rmse:.4g} -> {r.after.rmse:.4g} Nm"
        )


def full_log(directory: Path) -> Path:
    """The full paper campaign of the shipped robot, bus-free, as a log CSV in ``directory``."""
    cfg = load_bus_config(DEFAULT_BUS_CONFIG)
    sim = load_sim_config(SIM_DEFAULT)
    plan = build_plan(
        cfg.campaign,
        {a: cfg.nodes[a].limits for a in sim.axes},
        dict.fromkeys(sim.axes, 0.0),
        cfg.master.sync_period_s,
    )
    return write_log(
        directory / "log.csv", plant_log(sim, {a: plan.demand[:, i] for i, a in enumerate(plan.axes)})
    )


# (a result's reported std and genetic fit as the code since issue 45 names them, and as the code
# before it did: the model's own std, ``ga_coef``; so that --against reaches back to that code)
TIMED = """import json, sys, time
from drive_bridge.ident import identify
t0 = time.perf_counter()
results = identify(sys.argv[1], seed=0)
wall = time.perf_counter() - t0
std = {a: getattr(r, "param_std", None) or r.model.param_std_ for a, r in results.items()}
ga = {a: r.ga.coef if hasattr(r, "ga") else r.ga_coef for a, r in results.items()}
print(json.dumps({"wall": wall,
                  "params": {a: {k: r.model.params_[k] for k in ("J", "c0", "c1")} for a, r in results.items()},
                  "std": {a: {k: std[a][k] for k in ("J", "c0", "c1")} for a in results},
                  "ga": {a: {k: float(c) for k, c in zip(r.model.coef_names, ga[a]) if k in ("J", "c0", "c1")}
                         for a, r in results.items()},
                  "effects": {a: [t.effect.name for t in r.effects] for a, r in results.items()}}))
"""


def _timed(root: Path, log: Path) -> dict:
    """One identification of ``log`` by the code under ``root``, in a process of its own."""
    env = {**os.environ, "PYTHONPATH": str(root)}
    out = subprocess.run(
        [sys.executable, "-c", TIMED, str(log)], cwd=root, env=env, check=True, capture_output=True, text=True
    ).stdout
    return json.loads(out.strip().splitlines()[-1])


#: the stages of identification a faster implementation of the same method could at most remove, as
#: (module, function): the filters at the log's rate (the low-pass every regressor column goes through
#: as the torque does, and the decimation's), the differentiator (of the positions, and of the torque
#: for its delay) and the positions' fractional delay, and the effects' searches of their nonlinear
#: parameters (differential evolution); under every name a module calls them by
REMOVABLE = {
    "filters": [("scipy.signal", "sosfiltfilt"), ("scipy.signal", "filtfilt")],
    "derivatives and delays": [
        ("drive_bridge.ident.signals", "derivative"),
        ("drive_bridge.ident.model", "derivative"),  # (the torque's rate, for its delay)
        ("drive_bridge.ident.signals", "_delayed"),
    ],
    "effects' searches": [("scipy.optimize", "differential_evolution")],
}


@contextlib.contextmanager
def _stage_clocks():
    """A dict of the CPU time [s] spent in each stage of :data:`REMOVABLE` while inside (a call
    within a call counted once, by the outer one)."""
    spent = dict.fromkeys(REMOVABLE, 0.0)
    depth = [0]
    saved = []

    def clocked(stage: str, func):
        def call(*args, **kwargs):
            depth[0] += 1
            start = time.process_time()
            try:
                return func(*args, **kwargs)
            finally:
                depth[0] -= 1
                if not depth[0]:
                    spent[stage] += time.process_time() - start

        return call

    for stage, places in REMOVABLE.items():
        for module, name in places:
            owner = importlib.import_module(module)
            saved.append((owner, name, getattr(owner, name)))
            setattr(owner, name, clocked(stage, getattr(owner, name)))
    try:
        yield spent
    finally:
        for owner, name, func in saved:
            setattr(owner, name, func)


def floor(log: Path) -> None:
    """``--floor``: see the module's docstring."""
    from drive_bridge.blas import one_thread
    from drive_bridge.forking import processes
    from drive_bridge.ident.identify import identify_axis
    from drive_bridge.ident.logdata import read_log

    start = time.perf_counter()
    data = read_log(log)
    parse = time.perf_counter() - start
    total, rest, spent = {}, {}, {}
    with one_thread():
        for axis in data.axes:
            with _stage_clocks() as clocks:
                start = time.process_time()
                identify_axis(data, axis, seed=0)
                total[axis] = time.process_time() - start
            rest[axis] = total[axis] - sum(clocks.values())
            for stage, seconds in clocks.items():
                spent[stage] = spent.get(stage, 0.0) + seconds
    cores = min(processes(), len(rest))
    best = min(  # the axes shared out to the cores as well as they can be (every assignment tried)
        max(sum(r for r, core in zip(rest.values(), cores_of) if core == c) for c in range(cores))
        for cores_of in itertools.product(range(cores), repeat=len(rest))
    )
    cpu = sum(total.values())
    print(
        f"the axes one after the other, one process: {cpu:.2f} s of CPU ("
        + ", ".join(f"{a} {t:.2f}" for a, t in total.items())
        + "); of it "
        + ", ".join(f"{stage} {t:.2f} s ({t / cpu:.0%})" for stage, t in spent.items())
    )
    print(
        f"without those stages: {sum(rest.values()):.2f} s of CPU ("
        + ", ".join(f"{a} {t:.2f}" for a, t in rest.items())
        + f"): on {cores} cores at best {best:.2f} s, the parse {parse:.2f} s -> at least "
        f"{best + parse:.2f} s for any implementation of them"
    )


def full(log_dir: str | None, against: str | None, profile: int, runs: int, at_floor: bool = False) -> None:
    with (
        tempfile.TemporaryDirectory() as tmp,
        worktree(ROOT, against) if against else contextlib.nullcontext() as other,
    ):
        log = Path(log_dir) / "log.csv" if log_dir else full_log(Path(tmp))
        mine, theirs = [], []
        for _ in range(runs):  # alternated: the machine's speed drifts
            mine.append(_timed(ROOT, log))
            if other is not None:
                theirs.append(_timed(other, log))
        from drive_bridge.ident.logdata import read_log

        data = read_log(log)
        plain = sum(min(least_squares(data.t, ax.q, ax.tau) for _ in range(5)) for ax in data.axes.values())
        print(stamp())
        best = min(r["wall"] for r in mine)
        print(f"{log}: {len(data.t)} rows ({len(data.t) * data.dt:.0f} s), {len(data.axes)} axes")
        walls = ", ".join(f"{r['wall']:.2f}" for r in mine)
        print(
            f"identify (as commission runs it): {walls} s; a plain filter + "
            f"3-column least squares of the same axes: {plain * 1e3:.0f} ms -> {best / plain:.0f}x that"
        )
        if theirs:
            ref = min(r["wall"] for r in theirs)
            walls = ", ".join(f"{r['wall']:.2f}" for r in theirs)
            print(f"revision {against}: {walls} s -> this code takes {best / ref:.2f}x its time")
            worst = max(
                abs(mine[0]["params"][a][k] - theirs[0]["params"][a][k]) / theirs[0]["std"][a][k]
                for a in theirs[0]["params"]
                for k in ("J", "c0", "c1")
            )
            worst_ga = max(
                abs(mine[0]["ga"][a][k] - theirs[0]["ga"][a][k]) / theirs[0]["std"][a][k]
                for a in theirs[0]["ga"]
                for k in ("J", "c0", "c1")
            )
            print(
                f"  J, c0, c1 differ by at most {worst:.2g} of their std (the genetic algorithm's "
                f"{worst_ga:.2g}); effects "
                + (
                    "the same"
                    if mine[0]["effects"] == theirs[0]["effects"]
                    else f"differ: {mine[0]['effects']} vs {theirs[0]['effects']}"
                )
            )
        for a, p in mine[0]["params"].items():
            print(
                f"  {a}: J {p['J']:.6g}, c0 {p['c0']:.6g}, c1 {p['c1']:.6g}; effects {mine[0]['effects'][a]}"
            )
        if at_floor:
            floor(log)
        if profile:
            os.environ["DRIVE_BRIDGE_WORKERS"] = "1"  # in this process: a profile sees no forked worker
            prof = cProfile.Profile()
            prof.runcall(identify, log, seed=0)
            print(
                f"where the time goes (cProfile, the axes one after the other, the {profile} largest "
                f"internal times):"
            )
            pstats.Stats(prof).sort_stats("tottime").print_stats(profile)


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("mode", choices=["crb", "coverage", "consistency", "speed", "full"])
    parser.add_argument("--log", help="full: a record directory (default: a plant log of the paper campaign)")
    parser.add_argument(
        "--against", help="full: a git revision whose identification is timed in the same run"
    )
    parser.add_argument("--profile", type=int, default=0, help="full: print the N largest internal times")
    parser.add_argument("--runs", type=int, default=2, help="full: timed runs of each code")
    parser.add_argument(
        "--floor",
        action="store_true",
        help="full: what the run takes at least without its filters and searches",
    )
    parser.add_argument("--seeds", type=int, default=50)
    parser.add_argument("--cases", type=int, default=42)
    parser.add_argument("--verbose", action="store_true", help="coverage: one line per case")
    args = parser.parse_args()
    if args.mode == "crb":
        crb(args.seeds)
    elif args.mode == "coverage":
        coverage(args.cases, args.verbose)
    elif args.mode == "consistency":
        consistency(args.seeds)
    elif args.mode == "full":
        full(args.log, args.against, args.profile, args.runs, args.floor)
    else:
        speed()
