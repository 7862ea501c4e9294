"""``identify``: J, c0, c1 and the effects the residual points to, from a log."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from . import options


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add this module's commands to the command line.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The command line's subparsers.
    """
    p = sub.add_parser(
        "identify",
        help="identify J, c0, c1 from a log and trace the residual to its effects",
        description="Least squares and differential evolution on a log CSV (or a record "
        "directory), then residual tracing: effects found, added, error before -> after.",
    )
    p.add_argument("log", help="log CSV, or a record output directory")
    p.add_argument("--validate", help="a second log to validate on (default: held-out parts of LOG)")
    p.add_argument("--axis", help="axis name(s), comma-separated (default: every axis that moves)")
    options.json_flag(p)
    p.add_argument(
        "--out", help="directory for the report (identify.html, identify.md), its plots and identify.json"
    )
    p.add_argument("--cutoff", type=float, help="low-pass cut-off [Hz] (default: from the data)")
    p.add_argument(
        "--torque-delay",
        type=float,
        metavar="MS",
        help="delay of the logged torque behind the position [ms] (default: estimated from the data; "
        "0: take the log's instants as they are)",
    )
    p.add_argument("--decimate", type=int, help="decimation factor (default: from the cut-off)")
    p.add_argument(
        "--torque-sign",
        type=int,
        choices=(1, -1),
        default=1,
        help="-1: the torque was logged with the opposite sign convention to the position (default: 1)",
    )
    options.seed(p)
    options.history(p, asked=True)
    options.figures(p)
    p.set_defaults(func=cmd_identify)


def cmd_identify(args: argparse.Namespace) -> int:
    """The ``identify`` command: J, c0, c1 and the effects of a log.

    Parameters
    ----------
    args : argparse.Namespace
        The command line.

    Returns
    -------
    int
        The exit code (:data:`drive_bridge.errors.EXIT_TABLE`).
    """
    from ..history.record import now
    from ..ident import identify
    from ..ident.presentation import as_json, summary, write_report

    options.out_dir(args.out)
    started = now()
    progress = None if args.json else (lambda axis: print(f"identifying axis {axis} ...", file=sys.stderr))
    results = identify(
        args.log,
        args.validate,
        options.axes_list(args.axis),
        seed=args.seed,
        cutoff_hz=args.cutoff,
        decimation=args.decimate,
        progress=progress,
        torque_delay_s=None if args.torque_delay is None else args.torque_delay / 1e3,
        torque_sign=args.torque_sign,
    )
    if args.out:
        report = write_report(results, Path(args.out), str(args.log), figures=args.figures)
        if not args.json:
            beside = "plots and identify.json" if args.figures else "identify.json"
            print(f"wrote {report} and identify.html ({beside} beside them)", file=sys.stderr)
    print(as_json(results) if args.json else summary(results))
    if args.history:
        from ..history import keep
        from ..history.record import identify_record, new_run_id

        record = identify_record(new_run_id(), started, json.loads(as_json(results)), args.log, args.out)
        print(keep(record, args.db).line(), file=sys.stderr)
    return 0
