"""``commission``: the whole job in one command, resumable, ending in summary.json and report.html."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from . import bus, options

if TYPE_CHECKING:
    from ..master.bringup import AxisLink
    from ..master.campaign import Plan


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add this module's commands to the command line.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The command line's subparsers.
    """
    from ..commissioning.steps import STEP_FUNCTIONS

    p = sub.add_parser(
        "commission",
        help="the whole job: scan, bring-up, campaign, identify, measure, tune, write, validate",
        description="Every step in one run directory (--out), resumable after the last completed "
        "step; summary.json and a self-contained report.html whatever happens.",
    )
    options.drive(p, params=False)
    options.motion(p)
    options.write_checks(p)
    options.dry_run(p)
    p.add_argument(
        "--out", required=True, help="run directory: every step's output, summary.json, report.html"
    )
    p.add_argument(
        "--steps",
        help=f"run only these steps, comma-separated ({', '.join(STEP_FUNCTIONS)}); "
        "default: resume after the last completed one",
    )
    p.add_argument("--restart", action="store_true", help="start over: discard the previous run in --out")
    options.campaign(p)
    p.add_argument(
        "--quick",
        action="store_true",
        help="a few seconds of campaign per axis (a demo: too short to "
        "determine every parameter, which tune then refuses)",
    )
    options.seed(p)
    options.motor(p)
    options.history(p)
    options.figures(p)
    p.set_defaults(func=cmd_commission)


def cmd_commission(args: argparse.Namespace) -> int:
    """The ``commission`` command: the whole job, step by step.

    Parameters
    ----------
    args : argparse.Namespace
        The command line.

    Returns
    -------
    int
        The exit code (:data:`drive_bridge.errors.EXIT_TABLE`).
    """
    from ..commissioning import commission

    options.out_dir(args.out)
    config = options.config(args)
    steps = options.axes_list(args.steps)
    moving = [s for s in ("campaign", "measure", "validate") if steps is None or s in steps]
    if moving or args.dry_run:
        from ..params.profile import DEFAULT_PROFILE, load_profile

        profile = load_profile(options.session_options(args).profile or config.profile or DEFAULT_PROFILE)

        def plans(axes: dict[str, AxisLink]) -> list[tuple[str, Plan]]:
            from ..tuning.measure import measure_plans

            out = bus.campaign_plans(config)(axes) if "campaign" in moving else []
            end = {a: float(out[0][1].demand[-1, i]) for i, a in enumerate(out[0][1].axes)} if out else None
            if "measure" in moving:
                measured = measure_plans(
                    config, axes, profile, end or {a: ax.start_rad() for a, ax in axes.items()}
                )
                end = {**(end or {}), **{p.axes[0]: float(p.demand[-1, 0]) for _, p in measured}} or None
                out += measured
            return out + (
                bus.validate_plans(config, "each scenario the gain gate admits")(axes, end)
                if "validate" in moving
                else []
            )

        if args.dry_run:
            return bus.dry_run_end(bus.preview(args, config, plans))
        options.confirm_motion(args, config, "commission", lambda: bus.preview(args, config, plans))
    result = commission(config, args.out, options.session_options(args), steps=steps, restart=args.restart)
    if args.json:
        options.print_json(result.summary)
    return result.exit_code
