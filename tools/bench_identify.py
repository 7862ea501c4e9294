"""Benchmark of identification (numbers in the README).

    python tools/bench_identify.py crb [--seeds 50]     # estimator spread against the Cramér-Rao bound
    python tools/bench_identify.py speed                 # 3 axes, 300 s at 500 Hz, with residual tracing

crb: one simulated campaign of the Y axis (plant J, c0, c1 only), measured
50 times with different torque-noise seeds; the standard deviation of J, c0,
c1 over the seeds against the std each fit reports (averaged; since issue 13
the autocorrelation- and heteroskedasticity-consistent one), and how far the
plant's values lie from the mean estimate in reported std.  speed: the shipped robot (with its hidden effects), the default
campaign cut to 100 s per axis, one axis after the other: 300 s of log.
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
from drive_bridge.ident.logdata import read_log                      # noqa: E402
from drive_bridge.ident.model import AxisModel                        # noqa: E402
from drive_bridge.ident.signals import choose_settings, prepare       # noqa: E402
from drive_bridge.master.campaign import build_plan                   # noqa: E402
from drive_bridge.sim.config import load_sim_config                   # noqa: E402
from drive_bridge.sim.plantlog import plant_log, write_log           # noqa: E402
from drive_bridge.resources import DEFAULT_BUS_CONFIG   # noqa: E402
from drive_bridge.sim.config import DEFAULT_CONFIG as SIM_DEFAULT   # noqa: E402


def plan_for(axes, seconds_per_axis):
    cfg = load_bus_config(DEFAULT_BUS_CONFIG)
    camp = replace(cfg.campaign, max_axis_time_s=seconds_per_axis, together=False)
    return build_plan(camp, {a: cfg.nodes[a].limits for a in axes}, dict.fromkeys(axes, 0.0), 0.002)


def crb(seeds: int) -> None:
    sim = load_sim_config(SIM_DEFAULT)
    y = sim.axes["y"]
    y.effects, y.cp, y.D, y.torque_noise_Nm = {}, 0.0, 0.0, 0.0
    sim = replace(sim, axes={"y": y})
    plan = plan_for(["y"], 60.0)
    clean = plant_log(sim, {"y": plan.demand[:, 0]})
    rated = y.motor.rated_torque_Nm
    estimates, bounds = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(seeds):
            cols = dict(clean)
            noise = 0.004 * np.random.default_rng(seed).standard_normal(len(cols["time_s"]))
            cols["y_torque_Nm"] = np.round((clean["y_torque_Nm"] + noise) / rated * 1000) * rated / 1000
            log = read_log(write_log(Path(tmp) / "log.csv", cols))
            s = prepare(log, "y", choose_settings(log, "y"))
            m = AxisModel().fit(s)
            estimates.append(m.coef_)
            bounds.append(np.sqrt(np.diag(m.cov_)))
    est, bound = np.array(estimates), np.mean(bounds, axis=0)
    print(f"{seeds} seeds, Y axis, 60 s campaign, torque noise 0.004 Nm + quantisation")
    for i, name in enumerate(("J", "c1", "c0")):
        spread = est[:, i].std(ddof=1)
        off = abs(est[:, i].mean() - getattr(y, name)) / bound[i]
        print(f"  {name:<3} mean {est[:, i].mean():.6g} (plant {getattr(y, name):.6g}, {off:.1f} reported std away), "
              f"spread {spread:.3g}, reported std {bound[i]:.3g}, ratio {spread / bound[i]:.2f}")


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
    print(f"{n} rows ({n * 0.002:.0f} s at 500 Hz), 3 axes, identification with residual tracing and GA: "
          f"{wall:.2f} s")
    for a, r in results.items():
        print(f"  {a}: {[e.effect.name for e in r.effects]}, RMSE {r.before.rmse:.4g} -> {r.after.rmse:.4g} Nm")


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("mode", choices=["crb", "speed"])
    parser.add_argument("--seeds", type=int, default=50)
    args = parser.parse_args()
    crb(args.seeds) if args.mode == "crb" else speed()
