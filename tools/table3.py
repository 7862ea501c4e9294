"""The paper's Table III gain scenarios against the tuned set, on the same simulated axes and
reference trajectories (the README's table).

    python tools/table3.py [--axes x,y,z]

Runs the shipped simulated robot in lockstep: a record campaign (25 cycles or 300 s per axis),
identification with residual tracing, the model-based design, then every scenario on the
point-to-point moves and the 3-D path.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from drive_bridge.config import load_bus_config  # noqa: E402
from drive_bridge.connect import open_link  # noqa: E402
from drive_bridge.ident import identify  # noqa: E402
from drive_bridge.master.bringup import bring_up  # noqa: E402
from drive_bridge.paper import TABLE_III  # noqa: E402
from drive_bridge.params.cascade import loop_margins  # noqa: E402
from drive_bridge.params.profile import load_profile  # noqa: E402
from drive_bridge.recorder import record  # noqa: E402
from drive_bridge.resources import DEFAULT_BUS_CONFIG  # noqa: E402
from drive_bridge.tuning.tune import model_from_identify, tune_axis  # noqa: E402
from drive_bridge.tuning.validate import validate  # noqa: E402


def main(axes: list[str]) -> None:
    warnings.filterwarnings("ignore", module="scipy.optimize")
    config = load_bus_config(DEFAULT_BUS_CONFIG).only(axes)
    profile = load_profile("drive_bridge_servo")
    with tempfile.TemporaryDirectory() as tmp, open_link(config, sim=True) as link:
        record(config, link, tmp)
        ident = identify(tmp)
        models = {a: model_from_identify(ident[a].model.params_) for a in axes}
        links = bring_up(link, config)
        tuned, designs, motors = {}, {}, {}
        for a in axes:
            motors[a] = float(links[a].node.sdo[0x2002][1].raw), float(links[a].node.sdo[0x2002][2].raw)
            t = tune_axis(a, models[a], *motors[a], {})
            tuned[a], designs[a] = t.parameters(), t.design
        factory_current = {
            k: float(links[axes[0]].node.sdo[0x2000][i].raw) for i, k in ((5, "KpC"), (6, "KiC"))
        }
        scenarios = {n: {a: dict(g) for a in axes} for n, g in TABLE_III.items()}
        scenarios["tuned gains, model FF off"] = {a: {**tuned[a], "ff_enable": 0.0} for a in axes}
        scenarios["tuned + model FF"] = tuned
        runs = validate(config, link, links, profile, scenarios, models)
    print(
        "| scenario | KpP / KpS / KiS / FwF | trajectory | "
        + " | ".join(f"{a} FE rms [mrad]" for a in axes)
        + " |"
    )
    print("| --- | --- | --- | " + " | ".join("---" for _ in axes) + " |")
    for r in runs:
        g = scenarios[r.scenario][axes[0]]
        gains = f"{g['KpP']:.0f} / {g['KpS']:.3g} / {g['KiS']:.3g} / {g['FwF']:.3g}"
        print(
            f"| {r.scenario} | {gains} | {r.trajectory} | "
            + " | ".join(f"{r.axes[a].fe_rms * 1e3:.3g}" for a in axes)
            + " |"
        )
    print("\nvelocity loop margins on the identified model (python-control), phase [°] / gain [dB]:")
    for name, per_axis in scenarios.items():
        cells = []
        for a in axes:
            gains = {**factory_current, **per_axis[a]}
            vel, _ = loop_margins(models[a]["J"], models[a]["c1"], gains, *motors[a])
            cells.append(f"{a} {vel.phase_margin_deg:.1f} / {vel.gain_margin_db:.1f}")
        print(f"  {name}: " + ", ".join(cells))
    for a in axes:
        d = designs[a]
        print(
            f"\naxis {a}: velocity loop PM {d.velocity.phase_margin_deg:.1f}°, GM {d.velocity.gain_margin_db:.1f} dB; "
            f"position loop PM {d.position.phase_margin_deg:.1f}°, GM {d.position.gain_margin_db:.1f} dB"
        )
        for traj in ("point_to_point", "path"):
            best = min(
                r.axes[a].fe_rms
                for r in runs
                if r.trajectory == traj and r.scenario in TABLE_III and r.aborted is None
            )
            mine = next(
                r.axes[a].fe_rms for r in runs if r.trajectory == traj and r.scenario == "tuned + model FF"
            )
            print(
                f"  {traj}: best Table III {best * 1e3:.3g} mrad, tuned {mine * 1e3:.3g} mrad: {best / mine:.1f}x"
            )


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--axes", default="x,y,z")
    main(parser.parse_args().axes.split(","))
