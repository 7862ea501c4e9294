"""``history``: the runs kept in the history database, one run in full, each drive against its past
and its siblings, and sending what waits in the outbox."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from ..document import measured, number
from ..errors import EXIT_CODES, UserError
from ..outputs import stamped
from . import options

if TYPE_CHECKING:
    from ..history import HistoryStore


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add this module's commands to the command line.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The command line's subparsers.
    """
    p = sub.add_parser(
        "history",
        help="what was commissioned when, and what changed since: list, show, compare, sync",
        description="The history database keeps every commission and write (and identify --history): "
        "when, which version, which drives (0x1018), the identified parameters with "
        "their std, gains, margins, following error, what was written and stored.",
    )
    verbs = p.add_subparsers(dest="verb", required=True, metavar="VERB")
    v = verbs.add_parser("list", help="the runs, newest first")
    v.add_argument("--axis", help="only runs with this axis")
    v.add_argument(
        "--drive", type=_serial, metavar="SERIAL", help="only runs with the drive of this serial (0x1018:4)"
    )
    v.add_argument("--limit", type=int, default=50, help="at most this many runs (default: %(default)s)")
    v.set_defaults(func=cmd_list)
    v = verbs.add_parser("show", help="one run in full")
    v.add_argument("run", help="run id (or its first characters)")
    v.set_defaults(func=cmd_show)
    v = verbs.add_parser(
        "compare",
        help="each drive's latest identification against its previous one and its "
        "siblings (same drive type and axis role); changes named in words",
    )
    v.add_argument("--axis", help="only this axis")
    v.add_argument("--drive", type=_serial, metavar="SERIAL", help="only the drive of this serial (0x1018:4)")
    v.add_argument(
        "--threshold",
        type=float,
        default=10.0,
        metavar="PERCENT",
        help="smallest relative change named (default: %(default)g %%; it must also exceed 3 combined "
        "std, or 3 spreads of the siblings)",
    )
    v.set_defaults(func=cmd_compare)
    v = verbs.add_parser(
        "sync", help="send the records that wait in the outbox (the database was unreachable)"
    )
    v.set_defaults(func=cmd_sync)
    v = verbs.add_parser(
        "rejected", help="the records set aside because the database refused what they hold, and why"
    )
    v.set_defaults(func=cmd_rejected)
    for v in verbs.choices.values():
        options.db(v)
        options.json_flag(v)


def _serial(text: str) -> int:
    try:
        return int(text, 0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a serial number: {text!r} (decimal, or 0x... hex)") from None


def _store(args: argparse.Namespace) -> HistoryStore:
    from ..history import HistoryStore

    return HistoryStore(args.db)


def cmd_list(args: argparse.Namespace) -> int:
    """The ``history list`` command (``history list``): the runs kept.

    Parameters
    ----------
    args : argparse.Namespace
        The command line.

    Returns
    -------
    int
        The exit code (:data:`drive_bridge.errors.EXIT_TABLE`).
    """
    store = _store(args)
    runs = store.runs(args.limit, args.axis, args.drive)
    if args.json:
        options.print_json(stamped("history", {"verb": "list", "database": store.where, "runs": runs}))
        return 0
    print(f"{len(runs)} run(s) in {store.where}, newest first")
    for r in runs:
        drives = ", ".join(
            f"{a['axis']}={int(a['serial'], 16) if a['serial'] is not None else '?'}" for a in r["axes"]
        )
        print(
            f"{r['run_id'][:12]}  {r['started_at'][:16].replace('T', ' ')}  {r['kind']:<10} "
            f"{r['verdict'] or r['status'] or '':<10} {'sim ' if r['simulated'] else ''}{drives}  "
            f"{r['out_dir'] or ''}"
        )
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    """The ``history show`` command (``history show``): one run in full.

    Parameters
    ----------
    args : argparse.Namespace
        The command line.

    Returns
    -------
    int
        The exit code (:data:`drive_bridge.errors.EXIT_TABLE`).
    """
    store = _store(args)
    rec = store.record(args.run)
    if args.json:
        options.print_json(stamped("history", {"verb": "show", "database": store.where, "run": rec}))
        return 0
    print(
        f"run {rec['run_id']}: {rec['kind']} {rec['started']} → {rec['updated']}, drive-bridge {rec['version']}"
        f"{' (simulated)' if rec['simulated'] else ''}"
    )
    print(f"  status {rec['status']}, verdict {rec['verdict'] or '—'}; run directory {rec['out'] or '—'}")
    if rec.get("config"):
        print(f"  bus configuration {rec['config']['path']} (sha256 {str(rec['config']['sha256'])[:16]}...)")
    for a in rec["axes"]:
        d = a.get("drive") or {}
        ident = (
            f"vendor {d['vendor_id']} product {d['product_code']} revision {d['revision']} "
            f"serial {int(d['serial'], 16)} ({d['serial']})"
            if d
            else "drive unknown"
        )
        print(f"axis {a['axis']} (node {a.get('node_id')}, {ident}): verdict {a.get('verdict') or '—'}")
        for name, p in (a.get("parameters") or {}).items():
            print(
                f"  {name:<28} {measured(p['value'], p['std']):<24} {p['unit'] or '':<10}"
                f"{'' if p['determined'] else ' UNDETERMINED'}"
            )
        if a.get("effects"):
            print(f"  effects: {', '.join(a['effects'])}")
        if a.get("gains_after"):
            print(
                "  gains: "
                + ", ".join(
                    f"{k} {number((a.get('gains_before') or {}).get(k), '.4g')} → {number(v, '.4g')}"
                    for k, v in a["gains_after"].items()
                )
            )
        for traj, fe in (a.get("following_error") or {}).items():
            print(
                f"  following error {traj}: RMS {number(fe['fe_rms_before'], '.3g')} → "
                f"{number(fe['fe_rms_after'], '.3g')} rad"
            )
        if a.get("written") is not None:
            bad = [w["parameter"] for w in a["written"] if not w["verified"]]
            print(
                f"  written: {len(a['written'])} object(s), "
                + (f"NOT verified: {', '.join(bad)}" if bad else "all read back")
                + (", stored" if a.get("stored") else ", not stored")
            )
    return 0


def cmd_compare(args: argparse.Namespace) -> int:
    """The ``history compare`` command (``history compare``): each drive against its past and its siblings.

    Parameters
    ----------
    args : argparse.Namespace
        The command line.

    Returns
    -------
    int
        The exit code (:data:`drive_bridge.errors.EXIT_TABLE`).
    """
    from ..history import History, compare
    from ..history.compare import drive_name

    if not 0 <= args.threshold < 1000:
        raise UserError(f"--threshold {args.threshold}: give a percentage between 0 and 1000")
    store = _store(args)
    comparisons = compare(History(store.parameters()), args.axis, args.drive, args.threshold / 100)
    named = [c for c in comparisons if c.named]
    if args.json:
        options.print_json(
            stamped(
                "history",
                {
                    "verb": "compare",
                    "database": store.where,
                    "threshold": args.threshold / 100,
                    "named": [c.words() for c in named],
                    "comparisons": [c.as_dict() for c in comparisons],
                },
            )
        )
        return 0
    if not comparisons:
        print(
            f"nothing to compare in {store.where}"
            + (" for that axis/drive" if args.axis or args.drive else "")
        )
        return 0
    print(f"changed ({len(named)}):" if named else "no drive changed beyond noise and the threshold")
    for c in named:
        print(f"  {c.words()}")
    print()
    key = None
    for c in comparisons:
        if (c.serial, c.axis) != key:
            key = (c.serial, c.axis)
            print(f"{drive_name(c.serial)}, axis {c.axis} (latest {c.when.date()}):")
        change = "first" if c.relative is None else f"{c.relative * 100:+.1f} % ({number(c.sigmas, '.2g')} σ)"
        sib = "" if c.spreads is None else f"; {number(c.spreads, '.2g')} spread from {c.siblings} siblings"
        print(f"  {'*' if c.named else ' '} {c.name:<28} {measured(c.value, c.std):<24} {change}{sib}")
    return 0


def cmd_sync(args: argparse.Namespace) -> int:
    """The ``history sync`` command (``history sync``): the outbox sent to the database.

    Parameters
    ----------
    args : argparse.Namespace
        The command line.

    Returns
    -------
    int
        The exit code (:data:`drive_bridge.errors.EXIT_TABLE`).
    """
    from ..history import HistoryUnavailable, send
    from ..history.outbox import waiting

    store = _store(args)
    sent = send(store)
    other = sum(e["database"] != store.where for _, e in waiting())
    if args.json:
        options.print_json(
            stamped(
                "history",
                {
                    "verb": "sync",
                    "database": store.where,
                    "sent": sent.sent,
                    "already": sent.already,
                    "left": sent.left,
                    "failed": sent.failed,
                    "rejected": [{"run_id": r, "reason": why} for r, why in sent.rejected],
                    "waiting_for_other_databases": other,
                },
            )
        )
    else:
        print(
            f"history sync to {store.where}: {len(sent.sent)} record(s) sent, {len(sent.already)} already there"
            + (f"; {sent.left} still waiting: {sent.failed}" if sent.failed else ""),
            file=sys.stderr,
        )
        for run_id, why in sent.rejected:
            print(
                f"run {run_id} set aside, not kept: {why} ('drive-bridge history rejected' lists it)",
                file=sys.stderr,
            )
        if other:
            print(f"{other} record(s) in the outbox are for another database (--db)", file=sys.stderr)
    if sent.failed:
        raise HistoryUnavailable(f"history database {store.where}: {sent.failed}")
    return EXIT_CODES["user"] if sent.rejected else 0


def cmd_rejected(args: argparse.Namespace) -> int:
    """The ``history rejected`` command (``history rejected``): the records set aside.

    Parameters
    ----------
    args : argparse.Namespace
        The command line.

    Returns
    -------
    int
        The exit code (:data:`drive_bridge.errors.EXIT_TABLE`).
    """
    from ..history.outbox import rejected, rejected_dir

    entries = rejected()
    if args.json:
        options.print_json(
            stamped("history", {"verb": "rejected", "folder": str(rejected_dir()), "rejected": entries})
        )
        return 0
    if not entries:
        print(f"no record set aside ({rejected_dir()})")
    for e in entries:
        print(f"{e['run_id']}  {e['set_aside'] or ''}  for {e['database']}: {e['reason']}  ({e['path']})")
    return 0
