"""Command line: ``drive-bridge scan | record | decode``.

A user mistake prints one line naming what is wrong and exits 2; a bus
problem exits 3; motion stopped by a fault or Ctrl-C exits 4 after the data
recorded so far has been written.
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from . import __version__
from .config import load_bus_config
from .connect import open_link
from .errors import MotionAborted, UserError

DEFAULT_CONFIG = Path(__file__).resolve().parents[1] / "config" / "bus.yml"


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


def cmd_tune(args) -> int:
    import json
    import warnings
    from .master.bringup import bring_up
    from .params.profile import load_profile
    from .params.write import read_parameters
    from .tuning.experiment import run_experiment
    from .tuning.tune import GAINS, motor_data, read_identify_json, tune_axis
    warnings.filterwarnings("ignore", module="scipy.optimize")
    config = _load(args)
    models = read_identify_json(args.ident)
    names = [a for a in config.nodes if a in models]
    if not names:
        raise UserError(f"{args.ident}: none of its axes ({', '.join(models)}) is in {config.path}")
    profile = load_profile(args.profile)
    results = {}
    with open_link(config, args.sim, args.realtime, args.sim_config) as link:
        axes = bring_up(link, config.only(names))
        for a in names:
            node = axes[a].node
            R, L = motor_data(node, args.motor_R, args.motor_L)
            before = read_parameters(node, profile, GAINS)
            t = tune_axis(a, models[a], R, L, before)
            if args.experiment:
                t.experiment = run_experiment(config, link, axes, a, profile, before.get("KpS", t.design.KpS))
            results[a] = t
    doc = {"axes": {a: t.as_dict() for a, t in results.items()}}
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=1, default=float))
    if args.json:
        print(json.dumps(doc, default=float))
        return 0
    for a, t in results.items():
        d = t.design
        print(f"axis {a}: J {t.model['J']:.4g} kg·m², c1 {t.model['c1']:.4g} Nm·s/rad")
        for g in GAINS:
            print(f"  {g:<4} {t.before.get(g, float('nan')):>10.5g} -> {getattr(d, g):.5g}")
        print(f"  velocity loop: phase margin {d.velocity.phase_margin_deg:.1f}°, gain margin "
              f"{d.velocity.gain_margin_db:.1f} dB, crossover {d.velocity.crossover_hz:.0f} Hz"
              + ("" if t.before_margins is None else f" (before: {t.before_margins[0].phase_margin_deg:.1f}°, "
                 f"{t.before_margins[0].gain_margin_db:.1f} dB)"))
        print(f"  position loop: phase margin {d.position.phase_margin_deg:.1f}°, gain margin "
              f"{d.position.gain_margin_db:.1f} dB, crossover {d.position.crossover_hz:.0f} Hz")
        if t.experiment is not None:
            e = t.experiment
            print(f"  paper's procedure on the drive: KpS {e.KpS if e.KpS is None else round(e.KpS, 4)} after "
                  f"{len(e.steps)} steps (model-based: {d.KpS:.4g})")
    print(f"wrote {out}")
    return 0


def _remote_nodes(link, config, profile, names):
    import canopen
    nodes = {}
    for a in names:
        node = canopen.RemoteNode(config.nodes[a].node_id, profile.object_dictionary(config.nodes[a].node_id))
        link.network.add_node(node)
        nodes[a] = node
    return nodes


def cmd_write(args) -> int:
    import json
    from .params.profile import load_profile
    from .params.write import export_dcf, write_all, write_parameters
    from .tuning.tune import read_tune_json
    config = _load(args)
    params = read_tune_json(args.params)
    names = [a for a in config.nodes if a in params]
    profile = load_profile(args.profile)
    with open_link(config, args.sim, args.realtime, args.sim_config) as link:
        nodes = _remote_nodes(link, config, profile, names)
        if args.dry_run:
            results = {a: write_parameters(nodes[a], profile, params[a], dry_run=True) for a in names}
        else:
            results = write_all(nodes, profile, params, backup_dir=args.backup_dir)
            for a, r in results.items():
                if args.dcf_dir and r.ok:
                    export_dcf(nodes[a], r, Path(args.dcf_dir) / f"{a}.dcf")
    ok = all(r.ok for r in results.values()) and len(results) == len(names)
    if args.json:
        print(json.dumps({"ok": ok, "axes": {a: r.as_dict() for a, r in results.items()}}, default=float))
    else:
        for a, r in results.items():
            print(f"axis {a} (node {r.node_id}, {r.drive}){' — dry run, nothing written' if r.dry_run else ''}:")
            for w in r.objects:
                state = "verified" if w.verified else ("" if r.dry_run else "NOT verified")
                print(f"  {w.parameter:<9} 0x{w.index:04X}:{w.sub:<2} {_num(w.old_si):>11} -> {_num(w.new_si):<11} "
                      f"{w.unit:<18} (device {w.old_device} -> {w.new_device}) {state}")
            for name in r.unsupported:
                print(f"  {name:<9} not supported by {r.drive}: not written")
            if r.stored:
                print("  stored to non-volatile memory (0x1010 'save')")
            for n in r.notes:
                print(f"  note: {n}")
            if r.error:
                print(f"  FAILED: {r.error}; backup {'restored' if r.restored else 'NOT fully restored'}",
                      file=sys.stderr)
    return 0 if ok else 3


def _num(v) -> str:
    return "?" if v is None else f"{v:.6g}"


def cmd_validate(args) -> int:
    import json
    from .master.bringup import bring_up
    from .params.profile import load_profile
    from .paper import TABLE_III
    from .tuning.tune import drive_model, read_tune_json
    from .tuning.validate import validate
    config = _load(args)
    params = read_tune_json(args.params)
    names = [a for a in config.nodes if a in params]
    model = {a: drive_model(params[a]) for a in names}
    scenarios = {n: {a: dict(g) for a in names} for n, g in TABLE_III.items()}
    scenarios["tuned + model feed-forward"] = {a: params[a] for a in names}
    profile = load_profile(args.profile)
    with open_link(config, args.sim, args.realtime, args.sim_config) as link:
        axes = bring_up(link, config.only(names))
        runs = validate(config, link, axes, profile, scenarios, model)
    doc = {"runs": [r.as_dict() for r in runs]}
    if args.out:
        Path(args.out).mkdir(parents=True, exist_ok=True)
        (Path(args.out) / "validate.json").write_text(json.dumps(doc, indent=1, default=float))
    if args.json:
        print(json.dumps(doc, default=float))
        return 0
    print(f"{'scenario':<28} {'trajectory':<15} {'axis':<4} {'FE rms [rad]':>12} {'FE max [rad]':>12} "
          f"{'overshoot %':>11} {'settling s':>10} {'torque RMSE [Nm]':>16}")
    for r in runs:
        for a, m in r.axes.items():
            print(f"{r.scenario:<28} {r.trajectory:<15} {a:<4} {m.fe_rms:>12.3g} {m.fe_max:>12.3g} "
                  f"{_num(m.overshoot_pct):>11} {_num(m.settling_s):>10} {m.torque_rmse:>16.3g}")
        if r.aborted:
            print(f"  {r.scenario}, {r.trajectory}: stopped: {r.aborted}")
    return 0


def cmd_commission(args) -> int:
    import json
    import warnings
    from .commission import Options, commission
    warnings.filterwarnings("ignore", module="scipy.optimize")
    config = _load(args)
    steps = [s.strip() for s in args.steps.split(",") if s.strip()] if args.steps else None
    motor = (args.motor_R, args.motor_L) if args.motor_R and args.motor_L else None
    result = commission(config, args.out, Options(args.sim, args.realtime, args.sim_config, args.profile, motor,
                                                  args.seed), steps=steps, restart=args.restart)
    if args.json:
        print(json.dumps(result.summary, default=float))
    return result.exit_code


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

    def drive_options(p, params: bool = True):
        """Bus, drive profile, --params (a tune result) and --json: what tune/write/validate share."""
        bus_options(p)
        p.add_argument("--profile", default="drive_bridge_servo",
                       help="drive profile: a shipped name or a YAML file (default: %(default)s)")
        if params:
            p.add_argument("--params", required=True, help="tune result (tune.json)")
        p.add_argument("--json", action="store_true", help="print the result as one JSON object")

    def motor_options(p):
        """Motor data for drives that do not report it (tune and commission design the current loop)."""
        p.add_argument("--motor-R", type=float, help="motor resistance [Ω] if the drive does not report it")
        p.add_argument("--motor-L", type=float, help="motor inductance [H] if the drive does not report it")

    p = sub.add_parser("tune", help="design the cascade gains from identified models (margins with python-control)")
    drive_options(p, params=False)
    p.add_argument("--ident", required=True, help="identify --json output (identify.json)")
    p.add_argument("--out", default="tune.json", help="where to write the result (default: %(default)s)")
    p.add_argument("--experiment", action="store_true", help="also run the paper's gain-raising procedure on the drive")
    motor_options(p)
    p.set_defaults(func=cmd_tune)

    p = sub.add_parser("write", help="write gains and model to the drives: backup, verify, then store")
    drive_options(p)
    p.add_argument("--dry-run", action="store_true", help="print old -> new and write nothing")
    p.add_argument("--backup-dir", default="backup", help="where the backups go (default: %(default)s)")
    p.add_argument("--dcf-dir", help="export each commissioned node as a DCF here")
    p.set_defaults(func=cmd_write)

    p = sub.add_parser("validate", help="reference trajectories: Table III scenarios against the tuned set")
    drive_options(p)
    p.add_argument("--out", help="directory for validate.json")
    p.set_defaults(func=cmd_validate)

    p = sub.add_parser("commission", help="the whole job: scan, bring-up, campaign, identify, tune, write, validate")
    drive_options(p, params=False)
    p.add_argument("--out", required=True, help="run directory: every step's output, summary.json, report.html")
    p.add_argument("--steps", help="run only these steps, comma-separated (scan, bringup, campaign, identify, "
                                   "tune, write, validate); default: resume after the last completed one")
    p.add_argument("--restart", action="store_true", help="start over: discard the previous run in --out")
    p.add_argument("--quick", action="store_true", help="a few seconds of campaign per axis (demo)")
    p.add_argument("--seed", type=int, default=0, help="seed of the evolutionary fits (default: 0)")
    motor_options(p)
    p.set_defaults(func=cmd_commission)

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
