"""``commission``: the whole job in one command, resumable, ending in summary.json and report.html."""
from __future__ import annotations

from . import bus, options


def register(sub) -> None:
    from ..commission import STEPS
    p = sub.add_parser("commission", help="the whole job: scan, bring-up, campaign, identify, tune, write, validate",
                       description="Every step in one run directory (--out), resumable after the last completed "
                                   "step; summary.json and a self-contained report.html whatever happens.")
    options.drive(p, params=False)
    options.motion(p)
    options.write_checks(p)
    p.add_argument("--out", required=True, help="run directory: every step's output, summary.json, report.html")
    p.add_argument("--steps", help=f"run only these steps, comma-separated ({', '.join(STEPS)}); "
                                   "default: resume after the last completed one")
    p.add_argument("--restart", action="store_true", help="start over: discard the previous run in --out")
    options.campaign(p)
    p.add_argument("--quick", action="store_true", help="a few seconds of campaign per axis (demo)")
    options.seed(p)
    options.motor(p)
    p.set_defaults(func=cmd_commission)


def cmd_commission(args) -> int:
    from ..commission import commission
    options.out_dir(args.out)
    config = options.config(args)
    steps = options.axes_list(args.steps)
    if steps is None or {"campaign", "validate"} & set(steps):
        preview = (lambda: bus.campaign_preview(args, config)) if steps is None or "campaign" in steps else None
        options.confirm_motion(args, config, "commission", preview)
    result = commission(config, args.out, options.session_options(args),
                        steps=steps, restart=args.restart)
    if args.json:
        options.print_json(result.summary)
    return result.exit_code
