"""Benchmark of identification (numbers in the README).

    python tools/bench_identify.py crb [--seeds 50]       # estimator spread against the reported std
    python tools/bench_identify.py coverage [--cases 40]  # true values within 3 reported std?
    python tools/bench_identify.py speed                   # 3 axes, 300 s at 500 Hz, with residual tracing

crb: a log measured 50 times with different torque-noise seeds, identified as a user would
(``identify``: tracing, torque alignment); the standard deviation of J, c0, c1 over the seeds
against the std each fit reports (averaged; autocorrelation- and heteroskedasticity-consistent),
and how far the plant's values lie from the mean estimate in reported std.  Two plants: the
simulated Y axis (plant J, c0, c1 only) on a 60 s campaign, and the independent closed-loop plant
of the tests (``tests/ident/generator.py``, 40 s at 1 kHz).  coverage: the independent plant with
structure no library effect or one-variable spline models (friction or torque depending on two
variables at once), amplitudes, plants and seeds drawn at random (seeded): the share of cases
where the true J, c0, c1 lie within 3 reported std.  speed: the shipped robot (with its hidden
effects), the default campaign cut to 100 s per axis, one axis after the other: 300 s of log.
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

from drive_bridge.config import load_bus_config                       # noqa: E402
from drive_bridge.ident import identify                               # noqa: E402
from drive_bridge.master.campaign import build_plan                   # noqa: E402
from drive_bridge.sim.config import load_sim_config                   # noqa: E402
from drive_bridge.sim.plantlog import plant_log, write_log           # noqa: E402
from drive_bridge.resources import DEFAULT_BUS_CONFIG   # noqa: E402
from drive_bridge.sim.config import DEFAULT_CONFIG as SIM_DEFAULT   # noqa: E402
from tools.reference import least_squares, stamp                    # noqa: E402


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
    return ({"J": y.J, "c0": y.c0, "c1": y.c1},
            (plant_log(replace(sim, axes={"y": y}, seed=seed), {"y": plan.demand[:, 0]}) for seed in range(seeds)))


def _independent_logs(seeds: int):
    """The independent plant's values, and its log once per noise seed."""
    from tests.ident.generator import closed_loop_log
    return ({"J": 1e-4, "c0": 0.3, "c1": 5e-4},
            (closed_loop_log(np.arange(40000) / 1000, seed=seed) for seed in range(seeds)))


def crb(seeds: int) -> None:
    for name, logs in (("simulated Y axis, 60 s campaign, torque noise 0.004 Nm + quantisation", _sim_y_logs),
                       ("independent closed-loop plant, 40 s at 1 kHz, noise 0.004 Nm", _independent_logs)):
        estimates, bounds = [], []
        plant, cols = logs(seeds)
        with tempfile.TemporaryDirectory() as tmp:
            for c in cols:
                r = identify(write_log(Path(tmp) / "log.csv", c), axes=["y"])["y"]
                estimates.append([r.model.params_[k] for k in ("J", "c1", "c0")])
                bounds.append([r.model.param_std_[k] for k in ("J", "c1", "c0")])
        est, bound = np.array(estimates), np.mean(bounds, axis=0)
        print(f"{seeds} seeds, {name}")
        for i, k in enumerate(("J", "c1", "c0")):
            spread = est[:, i].std(ddof=1)
            off = abs(est[:, i].mean() - plant[k]) / bound[i]
            print(f"  {k:<3} mean {est[:, i].mean():.6g} (plant {plant[k]:.6g}, {off:.1f} reported std away), "
                  f"spread {spread:.3g}, reported std {bound[i]:.3g}, ratio {spread / bound[i]:.2f}")


STRUCTURES = {      # torque [Nm] no library effect nor a one-variable spline describes, with no part
    # that J, c0 or c1 could take as their own (zero mean over the stroke or the log); a ∈ [0.3, 1.5]
    "friction ∝ q·v (a guide tighter at one end, more with speed)":
        lambda a: lambda q, v, a_, t: a * 0.002 * q * v,
    "torque ∝ sin(q)·q̈ (an inertia that varies ±20 % along the stroke)":
        lambda a: lambda q, v, a_, t: a * 2e-5 * np.sin(q) * a_,
    "friction ∝ v·(t − 20 s) (heating with speed, about the middle of the log)":
        lambda a: lambda q, v, a_, t: a * 5e-6 * v * (t - 20.0),
}


def coverage(cases: int, verbose: bool = False) -> None:
    from tests.ident.generator import closed_loop_log
    rng = np.random.default_rng(0)
    inside = {k: 0 for k in ("J", "c0", "c1")}
    worst = {k: 0.0 for k in inside}
    with tempfile.TemporaryDirectory() as tmp:
        for case in range(cases):
            kind = list(STRUCTURES)[case % len(STRUCTURES)]
            plant = {"J": float(rng.uniform(0.8e-4, 1.5e-4)), "c0": float(rng.uniform(0.1, 0.4)),
                     "c1": float(rng.uniform(2e-4, 8e-4))}
            extra = STRUCTURES[kind](float(rng.uniform(0.3, 1.5)))
            cols = closed_loop_log(np.arange(40000) / 1000, seed=int(rng.integers(1 << 30)), extra=extra, **plant)
            r = identify(write_log(Path(tmp) / "log.csv", cols), axes=["y"])["y"]
            if verbose:
                print(f"  case {case}: {kind}; effects {[e.effect.name for e in r.effects]}; "
                      f"consistent {r.consistency.get('consistent')}; " + ", ".join(
                    f"{k} {(r.model.params_[k] - plant[k]) / r.model.param_std_[k]:+.1f} std" for k in inside))
            for k in inside:
                z = abs(r.model.params_[k] - plant[k]) / r.model.param_std_[k]
                inside[k] += z <= 3
                worst[k] = max(worst[k], z)
    print(f"{cases} cases of the independent plant with structure the model cannot describe "
          f"({len(STRUCTURES)} kinds, plants and amplitudes drawn at random, seed 0)")
    for k in inside:
        print(f"  {k:<3} true value within 3 reported std in {inside[k]}/{cases} = {inside[k] / cases:.0%}, "
              f"worst {worst[k]:.1f} std")


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
    plain = sum(min(least_squares(cols["time_s"], cols[f"{a}_position_rad"], cols[f"{a}_torque_Nm"]) for _ in range(5))
                for a in results)
    print(stamp())
    print(f"{n} rows ({n * 0.002:.0f} s at 500 Hz), 3 axes, identification with residual tracing and GA: "
          f"{wall:.2f} s; a plain filter + 3-column least squares of the same axes (tools/reference.py): "
          f"{plain * 1e3:.0f} ms -> {wall / plain:.0f}x that")
    for a, r in results.items():
        print(f"  {a}: {[e.effect.name for e in r.effects]}, RMSE {r.before.rmse:.4g} -> {r.after.rmse:.4g} Nm")


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("mode", choices=["crb", "coverage", "speed"])
    parser.add_argument("--seeds", type=int, default=50)
    parser.add_argument("--cases", type=int, default=42)
    parser.add_argument("--verbose", action="store_true", help="coverage: one line per case")
    args = parser.parse_args()
    if args.mode == "crb":
        crb(args.seeds)
    elif args.mode == "coverage":
        coverage(args.cases, args.verbose)
    else:
        speed()
