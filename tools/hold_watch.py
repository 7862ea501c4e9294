"""Acceptance (issue 67): an axis without a brake on the wall clock.  ``commission --sim --realtime``
as the command runs it, the simulated plant watched from the drives' process, beside the machine's
load of the hour.

    python tools/hold_watch.py [--campaign short|paper] [--runs 3] [--load idle|loaded|both] [--axis z]

Per run: how it ended (exit code, the step that failed and why), how far the axis strayed while no
motion was commanded (from the plant, not from what the master read) against its hold tolerance,
its power state at the end, and per axis whether the gains stored came from the measured response
or the model and what the run said about it: a stored set whose loop crossover lies further than
``measured_response.factor`` from the model-based design's with nothing said is counted.
``loaded``: two CPU-bound processes beside it.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from harness.holding import MotionSpans, uncommanded  # noqa: E402
from tools.bench_realtime import load  # noqa: E402
from tools.reference import stamp  # noqa: E402

HELD = {4: "enabled", 5: "quick stop active"}  # the power states an axis is held under power in


def unsaid(out: Path) -> list[str]:
    """The axes whose stored gains cross over further than the factor from the model-based design's
    without the run saying why."""
    tune = out / "tune.json"
    if not (out / "write" / "write.json").exists() or not tune.exists():
        return []
    bad = []
    for axis, tuned in json.loads(tune.read_text())["axes"].items():
        record = tuned.get("measured_response")
        if not record or not record["used"] or record["departs"]:
            continue
        for loop, model_hz in record["crossover_hz"]["model"].items():
            stored = tuned["margins"][loop]["crossover_hz"]
            if max(stored / model_hz, model_hz / stored) > record["factor"]:
                bad.append(f"{axis} {loop}")
    return bad


def run(campaign: str, axis: str) -> dict:
    """One wall-clock commissioning with the plant watched; its figures."""
    from drive_bridge.commissioning import Options, commission
    from drive_bridge.config import load_bus_config
    from drive_bridge.sim.connection import simulated_link

    config = load_bus_config(ROOT / "config" / "bus.yml")
    config = replace(config, campaign=replace(config.campaign, design=campaign))
    with tempfile.TemporaryDirectory() as tmp:
        out, watch = Path(tmp) / "run", Path(tmp) / "plant.txt"
        reporter = MotionSpans()
        link = simulated_link(config, realtime=True, watch=watch)
        try:
            result = commission(
                config, out, Options(sim=True, realtime=True, history=False), reporter=reporter, link=link
            )
        finally:
            link.close()
        moved, state = uncommanded(watch, reporter.spans, axis)
        tolerance = config.nodes[axis].drive_limits.hold_tolerance
        tune = json.loads((out / "tune.json").read_text())["axes"] if (out / "tune.json").exists() else {}
        stored_unsaid = unsaid(out)
        return {
            "exit": result.exit_code,
            "failed_step": result.failed_step,
            "reason": result.reason,
            "strayed_rad": round(moved, 5),
            "hold_tolerance_rad": tolerance,
            "held_at_end": HELD.get(state, f"NOT HELD (state {state})"),
            "gains_from": {
                a: "measured response" if (t.get("measured_response") or {}).get("used") else "model"
                for a, t in tune.items()
            },
            "suspect": {
                a: t["measured_response"]["suspect"]
                for a, t in tune.items()
                if (t.get("measured_response") or {}).get("suspect")
            },
            "stored_unsaid": stored_unsaid,
            "ok": moved <= tolerance and state in HELD and not stored_unsaid,
        }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--campaign", choices=["short", "paper"], default="short")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--load", choices=["idle", "loaded", "both"], default="both")
    parser.add_argument("--axis", default="z")
    args = parser.parse_args()
    print(stamp())
    for kind in ["idle", "loaded"] if args.load == "both" else [args.load]:
        for n in range(args.runs):
            with load(kind):
                figures = run(args.campaign, args.axis)
            print(json.dumps({"load": kind, "run": n + 1, **figures}), flush=True)


if __name__ == "__main__":
    main()
