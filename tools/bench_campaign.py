"""Benchmark: the short designed campaign against the paper's full campaign, side by side.

    python tools/bench_campaign.py [--robot all|shipped|second]

On the same simulated robot (the shipped one, and tools/robots/second.yaml with other hidden
effects) and the same seeds, records each campaign in lockstep, identifies it and prints per axis:
motion time, J, c0, c1 with their std (and the std ratio short / full), the effects found and the
final validation RMSE; with the date and machine, and each campaign's wall time.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from drive_bridge.config import load_bus_config  # noqa: E402
from drive_bridge.connect import open_link  # noqa: E402
from drive_bridge.ident import identify  # noqa: E402
from drive_bridge.recorder import record  # noqa: E402
from drive_bridge.resources import DEFAULT_BUS_CONFIG  # noqa: E402
from drive_bridge.sim.robot_config import DEFAULT_CONFIG, load_sim_config  # noqa: E402
from tools.reference import stamp  # noqa: E402

ROBOTS = {"shipped": DEFAULT_CONFIG, "second": ROOT / "tools" / "robots" / "second.yaml"}


def run(robot: Path, design: str) -> tuple[dict, dict, float, float]:
    cfg = load_bus_config(DEFAULT_BUS_CONFIG)
    cfg = replace(cfg, campaign=replace(cfg.campaign, design=design))
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        with open_link(cfg, sim=True, sim_config=str(robot)) as link:
            result = record(cfg, link, out)
        t1 = time.perf_counter()
        results = identify(Path(out) / "log.csv")
        t2 = time.perf_counter()
    motion = {
        a: sum(s.end - s.start for s in result.plan.segments if a in s.axes) * result.plan.period
        for a in result.plan.axes
    }
    return results, motion, t1 - t0, t2 - t1


def main(robots: list[str]) -> None:
    print(stamp())
    for name in robots:
        plant = load_sim_config(ROBOTS[name])
        runs = {d: run(ROBOTS[name], d) for d in ("paper", "short")}
        print(
            f"\nrobot {name} ({ROBOTS[name].name}); wall time: "
            + ", ".join(f"{d} campaign {r[2]:.1f} s + identify {r[3]:.1f} s" for d, r in runs.items())
        )
        for a, ax in plant.axes.items():
            hidden = ", ".join(ax.effects) or "none"
            print(f"  axis {a} (hidden: {hidden})")
            for d, (res, motion, _, _) in runs.items():
                r = res[a]
                p, sd = r.model.params_, r.param_std
                vals = "  ".join(f"{k} {p[k]:.5g} ± {sd[k]:.2g}" for k in ("J", "c0", "c1"))
                print(
                    f"    {d:<5} {motion[a]:6.1f} s  {vals}  effects {[t.effect.name for t in r.effects]}  "
                    f"RMSE {r.after.rmse:.4g} (noise floor {r.diagnostics.noise_floor:.3g})"
                )
            full, short = runs["paper"][0][a].param_std, runs["short"][0][a].param_std
            print(
                "    std short / full: "
                + ", ".join(f"{k} {short[k] / full[k]:.2f}" for k in ("J", "c0", "c1"))
                + f"; plant J {ax.J:.5g}, c0 {ax.c0:.5g}, c1 {ax.c1:.5g}"
            )


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--robot", choices=["all", *ROBOTS], default="all")
    args = parser.parse_args()
    main(list(ROBOTS) if args.robot == "all" else [args.robot])
