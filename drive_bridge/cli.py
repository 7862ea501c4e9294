"""Command line: ``drive-bridge scan | record | decode``.

A user mistake prints one line naming what is wrong and exits 2; a bus
problem exits 3; motion stopped by a fault or Ctrl-C exits 4 after the data
recorded so far has been written.
"""
from __future__ import annotations

import argparse
import sys
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

from . import __version__
from .config import load_bus_config
from .errors import MotionAborted, UserError

DEFAULT_CONFIG = Path(__file__).resolve().parents[1] / "config" / "bus.yml"


@contextmanager
def open_link(config, sim: bool, realtime: bool = False, sim_config: str | None = None):
    """The link the master talks through: the configured bus, or the simulated robot."""
    if not sim:
        from .master.link import BusLink
        try:
            link = BusLink.open(config.master.interface, config.master.channel, config.master.bitrate)
        except Exception as exc:       # python-can raises many kinds for a missing interface
            raise UserError(f"{config.path}: cannot open bus {config.master.interface}:"
                            f"{config.master.channel} ({exc})") from None
    else:
        from .sim.config import DEFAULT_CONFIG as SIM_DEFAULT, load_sim_config
        robot_cfg = load_sim_config(sim_config or SIM_DEFAULT)      # errors show here, not in the child
        if realtime:
            from .master.link import BusLink
            from .sim.process import SimProcess
            drives = SimProcess(sim_config or SIM_DEFAULT, config.master.sync_period_s)
            link = BusLink(drives.bus)
            link.on_close.append(drives.shutdown)
        else:
            from .sim.lockstep import LockstepLink
            from .sim.robot import SimRobot
            channel = f"{config.master.channel}-sim"          # closed again below, so reusable
            robot = SimRobot(robot_cfg, channel, sync_period=config.master.sync_period_s)
            link = LockstepLink(robot, channel)
    try:
        yield link
    finally:
        link.close()


def _load(args):
    config = load_bus_config(args.config)
    if getattr(args, "axes", None):
        config = config.only([a.strip() for a in args.axes.split(",") if a.strip()])
    if getattr(args, "quick", False):
        config = replace(config, campaign=config.campaign.quick())
    if getattr(args, "together", False):
        config = replace(config, campaign=replace(config.campaign, together=True))
    return config


def cmd_scan(args) -> int:
    from .master.bringup import scan
    config = _load(args)
    with open_link(config, args.sim, args.realtime, args.sim_config) as link:
        result = scan(link, config)
    by_id = {n.node_id: a for a, n in config.nodes.items()}
    for node_id, ident in sorted(result.found.items()):
        kind = "CiA 402 drive" if ident["device_type"] & 0xFFFF == 402 else f"device type 0x{ident['device_type']:08X}"
        print(f"node {node_id:3d}  axis {by_id[node_id]:<4} {kind}  vendor 0x{ident['vendor_id']:08X} "
              f"product 0x{ident['product_code']:08X} rev 0x{ident['revision']:08X} serial {ident['serial']}")
    for axis in result.missing:
        print(f"node {config.nodes[axis].node_id:3d}  axis {axis:<4} MISSING: configured but no answer")
    for node_id in result.unexpected:
        print(f"node {node_id:3d}  not configured: answered but is not in {config.path}")
    for axis in result.wrong_type:
        print(f"axis {axis}: not a CiA 402 drive")
    return 0 if not (result.missing or result.wrong_type) else 3


def cmd_record(args) -> int:
    from .progress import CampaignProgress
    from .record import record
    config = _load(args)
    bars = []

    def on_plan(plan):
        print(f"campaign: {', '.join(plan.axes)}, {len(plan.segments)} segments, "
              f"{plan.duration:.1f} s of motion", file=sys.stderr)
        bars.append(CampaignProgress(plan))
        return bars[0]

    with open_link(config, args.sim, args.realtime, args.sim_config) as link:
        try:
            result = record(config, link, args.out, on_plan=on_plan)
        finally:
            for bar in bars:
                bar.close()
    print(f"bus load {result.bus_load}; {result.cycles_sent} SYNC cycles in {result.wall_time_s:.1f} s")
    for axis in result.plan.axes:
        print(f"  axis {axis}: {result.samples[axis]} samples, {result.missing[axis]} missing")
    print(f"wrote {result.out_dir / 'log.csv'}, meta.yaml, trace.blf")
    if result.aborted is not None:
        raise result.aborted
    return 0


def cmd_decode(args) -> int:
    import numpy as np
    from .logs import decode_trace
    names, values, fmts, _ = decode_trace(Path(args.trace), args.meta)
    out = Path(args.out) if args.out else Path(args.trace).with_name("decoded.csv")
    np.savetxt(out, values, fmt=fmts, delimiter=",", header=",".join(names), comments="")
    print(f"wrote {out}: {len(values)} rows, {len(names)} columns")
    return 0


def cmd_identify(args) -> int:
    import warnings
    from .ident import identify
    from .ident.report import as_json, summary, write_markdown
    warnings.filterwarnings("ignore", module="scipy.optimize")     # DE's vectorized/updating note
    progress = None if args.json else (lambda axis: print(f"identifying axis {axis} ...", file=sys.stderr))
    axes = [a.strip() for a in args.axis.split(",")] if args.axis else None
    results = identify(args.log, args.validate, axes, seed=args.seed, cutoff_hz=args.cutoff,
                       decimation=args.decimate, progress=progress)
    if args.out:
        report = write_markdown(results, Path(args.out), str(args.log))
        if not args.json:
            print(f"wrote {report} (plots and identify.json beside it)", file=sys.stderr)
    print(as_json(results) if args.json else summary(results))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="drive-bridge", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"drive-bridge {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    def bus_options(p):
        p.add_argument("--config", default=str(DEFAULT_CONFIG), help="bus configuration (default: %(default)s)")
        p.add_argument("--sim", action="store_true", help="run against the simulated robot in-process")
        p.add_argument("--realtime", action="store_true", help="with --sim: wall clock instead of lockstep")
        p.add_argument("--sim-config", help="with --sim: simulator YAML (default: the shipped robot)")

    p = sub.add_parser("scan", help="list the nodes on the bus and check them against the config")
    bus_options(p)
    p.set_defaults(func=cmd_scan)

    p = sub.add_parser("record", help="run the excitation campaign and log torque, velocity, position")
    bus_options(p)
    p.add_argument("--quick", action="store_true", help="a few seconds per axis (demo, tests)")
    p.add_argument("--axes", help="comma-separated axes to move (default: all configured)")
    p.add_argument("--together", action="store_true", help="move all axes at once (exposes coupling)")
    p.add_argument("--out", required=True, help="output directory")
    p.set_defaults(func=cmd_record)

    p = sub.add_parser("identify", help="identify J, c0, c1 from a log and trace the residual to its effects")
    p.add_argument("log", help="log CSV, or a record output directory")
    p.add_argument("--validate", help="a second log to validate on (default: held-out parts of LOG)")
    p.add_argument("--axis", help="axis name(s), comma-separated (default: every axis that moves)")
    p.add_argument("--json", action="store_true", help="print exactly one JSON object (automation)")
    p.add_argument("--out", help="directory for the Markdown report, its plots and identify.json")
    p.add_argument("--cutoff", type=float, help="low-pass cut-off [Hz] (default: from the data)")
    p.add_argument("--decimate", type=int, help="decimation factor (default: from the cut-off)")
    p.add_argument("--seed", type=int, default=0, help="seed of the evolutionary fits (default: 0)")
    p.set_defaults(func=cmd_identify)

    p = sub.add_parser("decode", help="rebuild log.csv from a raw CAN trace")
    p.add_argument("trace", help="trace file written by record (trace.blf)")
    p.add_argument("--meta", help="meta.yaml of the recording (default: beside the trace)")
    p.add_argument("--out", help="CSV to write (default: decoded.csv beside the trace)")
    p.set_defaults(func=cmd_decode)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if getattr(args, "realtime", False) and not args.sim:
        print("drive-bridge: error: --realtime only applies with --sim", file=sys.stderr)
        return 2
    try:
        return args.func(args)
    except UserError as exc:
        print(f"drive-bridge: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except MotionAborted as exc:
        print(f"drive-bridge: motion stopped: {exc}. Axes were quick-stopped; "
              f"the data recorded so far is kept.", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("drive-bridge: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
