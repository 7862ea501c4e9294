"""``scan``, ``record``, ``decode``, ``export``, ``sim`` and ``check-eds``: the nodes on the bus, the
excitation campaign, the raw trace, the bus for other tools, the simulated drives as a process of
their own, the files that describe the nodes."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from ..config import BusConfig, NodeConfig, load_bus_config
from ..errors import EXIT_CODES, UserError
from ..master.bringup import AxisLink, check_scan, scan
from ..outputs import stamped
from ..resources import DEFAULT_BUS_CONFIG
from ..session import Session
from . import options

if TYPE_CHECKING:
    from ..master.campaign import Plan
    from ..master.timing import Timing


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add this module's commands to the command line.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The command line's subparsers.
    """
    p = sub.add_parser(
        "scan",
        help="list the nodes on the bus and check them against the configuration",
        description="Ask every node who is there: identity (0x1018) and device type (0x1000); "
        "a configured node that is missing or no CiA 402 drive ends with exit 3.",
    )
    options.bus(p)
    options.json_flag(p)
    p.set_defaults(func=cmd_scan)

    p = sub.add_parser(
        "record",
        help="bring up the drives, run the excitation campaign, log torque, velocity, position",
        description="Bring-up, the excitation campaign and its logs "
        "(log.csv, meta.yaml, trace.blf) in --out.",
    )
    options.bus(p)
    options.motion(p)
    options.campaign(p)
    p.add_argument("--quick", action="store_true", help="a few seconds per axis (demo, tests)")
    options.dry_run(p)
    p.add_argument("--axes", help="comma-separated axes to move (default: all configured)")
    p.add_argument("--together", action="store_true", help="move all axes at once (exposes coupling)")
    p.add_argument("--out", required=True, help="output directory")
    options.json_flag(p)
    p.set_defaults(func=cmd_record)

    p = sub.add_parser(
        "jog",
        help="move one axis slowly to a position (a safe start, away from an end stop)",
        description="One axis to --to POS or by --by DELTA (m for a linear axis, rad for a rotary "
        "one), slowly, through the same bring-up, limits, stop and hold as every motion: "
        "an S-curve from where it stands, inside its stroke; Ctrl-C stops it.",
    )
    options.bus(p)
    options.motion(p)
    p.add_argument("axis", help="the axis to move")
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument("--to", type=float, help="the position to go to [m | rad]")
    where.add_argument("--by", type=float, help="the distance to go [m | rad]")
    p.add_argument(
        "--speed", type=float, help="peak speed [m/s | rad/s] (default: 10 %% of the axis's limit)"
    )
    options.dry_run(p)
    p.set_defaults(func=cmd_jog)

    p = sub.add_parser(
        "decode",
        help="rebuild log.csv from a raw CAN trace",
        description="Rebuild the log of a recording from its CAN trace and meta.yaml "
        "(byte-identical to the live log.csv, except samples the live log "
        "marked missing that the trace holds).",
    )
    p.add_argument("trace", help="trace file written by record (trace.blf)")
    p.add_argument("--meta", help="meta.yaml of the recording (default: beside the trace)")
    p.add_argument("--out", help="CSV to write (default: decoded.csv beside the trace)")
    options.json_flag(p)
    p.set_defaults(func=cmd_decode)

    p = sub.add_parser(
        "export",
        help="write the bus for other tools: ros2_canopen's bus.yml and DCFs",
        description="ros2: bus.yml in ros2_canopen's format and one DCF per node in --out, for "
        "ros2_canopen and Lely's dcfgen (the same node setup as drive-bridge's "
        "bring-up: PDOs, heartbeat, interpolation period, limits).",
    )
    p.add_argument("target", choices=["ros2"], help="the format")
    p.add_argument("--config", default=None, help="bus configuration (default: the shipped one)")
    p.add_argument("--out", required=True, help="output directory")
    options.json_flag(p)
    p.set_defaults(func=cmd_export)

    p = sub.add_parser(
        "sim",
        help="run the simulated robot's drives on a CAN bus until stopped",
        description="The simulated drives as a process of their own, against the wall clock, on "
        "any python-can bus (udp_multicast on a machine without CAN; socketcan vcan0 "
        "where the kernel has it), for another master -- a PLC, ros2_canopen, your own "
        "code, or drive-bridge in another process -- to be tested against. Each drive "
        "is the one its node's EDS/DCF in --config describes. Runs until Ctrl-C or "
        "SIGTERM; a master that dies meanwhile leaves the drives to their heartbeat "
        "consumers.",
    )
    p.add_argument(
        "--config",
        default=str(DEFAULT_BUS_CONFIG),
        help="bus configuration: the drives' node-IDs and EDS/DCFs, the SYNC period (default: shipped)",
    )
    p.add_argument(
        "--sim-config",
        help="simulator YAML: the plant, or a shipped robot by name: robot (the "
        "default), compliant (Y on a lightly damped spring)",
    )
    p.add_argument(
        "-i", "--interface", default="udp_multicast", help="python-can interface (default udp_multicast)"
    )
    p.add_argument(
        "-c",
        "--channel",
        type=options.can_channel,
        help="python-can channel (default: udp_multicast's group 239.74.163.2)",
    )
    p.add_argument("--port", type=int, help="udp_multicast port (default 43113)")
    p.add_argument("-b", "--bitrate", type=int, help="bitrate [bit/s] where the interface takes one")
    p.set_defaults(func=cmd_sim)

    p = sub.add_parser(
        "check-eds",
        help="say what in an EDS/DCF is not CiA 306, and what drive-bridge can use",
        description="Check EDS/DCF files against CiA 306 (and with Lely's dcf-tools linter where "
        "installed) and list what drive-bridge finds in them (modes, feedback objects, "
        "PDOs). drive-bridge itself reads such files as they are. Exit 0: standard; "
        "1: something non-standard found; 2: a file cannot be read at all.",
    )
    p.add_argument("files", nargs="+", metavar="FILE", help="EDS or DCF files")
    options.json_flag(p)
    p.set_defaults(func=cmd_check_eds)


def cmd_scan(args: argparse.Namespace) -> int:
    """The ``scan`` command: the configured nodes found on the bus.

    Parameters
    ----------
    args : argparse.Namespace
        The command line.

    Returns
    -------
    int
        The exit code (:data:`drive_bridge.errors.EXIT_TABLE`).
    """
    config = options.config(args)
    with Session(config, options.session_options(args)) as session:
        result = scan(session.link, config)
    if args.json:
        options.print_json(result.as_dict(config))
        check_scan(result, config)
        return 0
    by_id = {n.node_id: a for a, n in config.nodes.items()}
    for node_id, ident in sorted(result.found.items()):
        kind = (
            "CiA 402 drive"
            if ident["device_type"] & 0xFFFF == 402
            else f"device type 0x{ident['device_type']:08X}"
        )
        print(
            f"node {node_id:3d}  axis {by_id.get(node_id, '?'):<4} {kind}  vendor 0x{ident['vendor_id']:08X} "
            f"product 0x{ident['product_code']:08X} rev 0x{ident['revision']:08X} serial {ident['serial']}"
        )
    for axis in result.missing:
        print(f"node {config.nodes[axis].node_id:3d}  axis {axis:<4} MISSING: configured but no answer")
    for node_id in result.unexpected:
        print(f"node {node_id:3d}  not configured: answered but is not in {config.path}")
    for axis, why in result.identity_accepted.items():
        print(f"axis {axis}: identity ACCEPTED although it differs (--accept-identity): {why}")
    check_scan(result, config)
    return 0


def cmd_record(args: argparse.Namespace) -> int:
    """The ``record`` command: the excitation campaign streamed and recorded (the robot moves).

    Parameters
    ----------
    args : argparse.Namespace
        The command line.

    Returns
    -------
    int
        The exit code (:data:`drive_bridge.errors.EXIT_TABLE`).
    """
    from ..progress import CampaignProgress
    from ..recorder import record

    options.out_dir(args.out)
    config = options.config(args)
    if args.dry_run:
        return dry_run_end(preview(args, config, campaign_plans(config)))
    options.confirm_motion(args, config, "record", lambda: preview(args, config, campaign_plans(config)))
    bars = []

    def on_plan(plan: Plan) -> CampaignProgress:
        print(
            f"campaign: {', '.join(plan.axes)}, {len(plan.segments)} segments, "
            f"{plan.duration:.1f} s of motion",
            file=sys.stderr,
        )
        print(plan_lines(plan, config), file=sys.stderr)
        bars.append(CampaignProgress(plan))
        return bars[0]

    with Session(config, options.session_options(args)) as session:
        try:
            result = record(config, session.link, args.out, on_plan=on_plan)
        finally:
            for bar in bars:
                bar.close()
    if args.json:
        options.print_json(result.as_dict())
    else:
        print(f"bus load {result.bus_load}; {result.cycles_sent} SYNC cycles in {result.wall_time_s:.1f} s")
        for axis in result.plan.axes:
            print(f"  axis {axis}: {result.samples[axis]} samples, {result.missing[axis]} missing")
        print(timing_line(result.timing))
        if result.repeats:
            print(f"  {result.repeated()}")
        print(f"wrote {result.out_dir / 'log.csv'}, meta.yaml, trace.blf")
        print(holding_lines(result.holding))
    if result.aborted is not None:
        raise result.aborted
    return degraded_exit([] if not result.timing.degraded else result.timing.reasons)


def cmd_sim(args: argparse.Namespace) -> int:
    """The ``sim`` command: the simulated drives on a bus of their own, for other masters.

    Parameters
    ----------
    args : argparse.Namespace
        The command line.

    Returns
    -------
    int
        The exit code (:data:`drive_bridge.errors.EXIT_TABLE`).
    """
    from ..cia.buses import open_bus
    from ..sim.process import serve
    from ..sim.robot_config import DEFAULT_CONFIG

    config = load_bus_config(args.config)
    eds = {a: str(n.dcf) for a, n in config.nodes.items()}
    try:
        options: dict = {"port": args.port} if args.port else {}
        if args.interface == "udp_multicast":  # the drives judge the master by arrival: the kernel's stamp
            options["stamps"] = "kernel"
        bus = open_bus(args.interface, args.channel, args.bitrate, options)
    except Exception as exc:  # python-can raises many kinds for a missing interface
        raise UserError(f"cannot open bus {args.interface}:{args.channel} ({exc})") from exc
    print(
        f"simulated drives of {args.sim_config or DEFAULT_CONFIG} on {args.interface}"
        f"{':' + str(args.channel) if args.channel else ''}; Ctrl-C stops them",
        file=sys.stderr,
    )

    def until() -> None:
        while True:
            time.sleep(3600)

    try:
        serve(args.sim_config or DEFAULT_CONFIG, bus, config.master.sync_period_s, eds, until)
    except KeyboardInterrupt:
        print("simulated drives stopped", file=sys.stderr)
    return 0


JOG_LEVEL = 0.1  # a jog's default speed and acceleration: this share of the axis's limits


def cmd_jog(args: argparse.Namespace) -> int:
    """The ``jog`` command: one axis moved to a position (the robot moves).

    Parameters
    ----------
    args : argparse.Namespace
        The command line.

    Returns
    -------
    int
        The exit code (:data:`drive_bridge.errors.EXIT_TABLE`).
    """
    import math

    import numpy as np

    from ..master.homing import home
    from ..tuning import motion

    config = options.config(args).only([args.axis])
    ncfg = config.nodes[args.axis]
    k, unit = own_units(ncfg)
    for name, value in (("--to", args.to), ("--by", args.by), ("--speed", args.speed)):
        if value is not None and not math.isfinite(value):
            raise UserError(f"{name} must be a finite number [{unit}], got {value}")

    def jog_level(cfg: NodeConfig) -> float:
        """The share of the axis's limits (as bring-up found them) the jog runs at."""
        if args.speed is None:
            return JOG_LEVEL
        level = float(cfg.scaling.load_to_motor(args.speed)) / cfg.limits.max_velocity
        if not 0 < level <= 1:
            raise UserError(
                f"--speed {args.speed} {unit}/s must be above 0 and within the axis's limit "
                f"{cfg.limits.max_velocity * k:.4g} {unit}/s"
            )
        return level

    def target(ax: AxisLink) -> float:
        """Where the jog goes [rad motor side], from where ``ax`` stands (homed first where it homes)."""
        if args.to is not None:
            return float(ax.cfg.scaling.load_to_motor(args.to))
        return ax.start_rad() + float(ax.cfg.scaling.load_to_motor(args.by))

    def plans(axes: dict[str, AxisLink]) -> list[tuple[str, Plan]]:
        ax = axes[args.axis]
        level = jog_level(ax.cfg)
        plan, _ = motion.plan(
            config,
            axes,
            {args.axis: np.array([target(ax)])},
            {args.axis: ax.start_rad()},
            kind="jog",
            level=level,
            approach_level=level,
        )
        return [(f"jog {args.axis}", plan)]

    if args.dry_run:
        return dry_run_end(preview(args, config, plans))
    options.confirm_motion(args, config, f"jog {args.axis}", lambda: preview(args, config, plans))
    with Session(config, options.session_options(args)) as session:
        ax = session.axes[args.axis]
        home(session.link, {args.axis: ax}, config)

        def on_plan(plan: Plan) -> None:
            print(
                f"jog {args.axis}: {plan.duration:.1f} s of motion\n{plan_lines(plan, config)}",
                file=sys.stderr,
            )

        level = jog_level(ax.cfg)
        moved = motion.run(
            config,
            session.link,
            {args.axis: ax},
            {args.axis: np.array([target(ax)])},
            kind="jog",
            level=level,
            approach_level=level,
            on_plan=on_plan,
        )
        holding = session.holding()
    if moved.aborted is not None:
        raise moved.aborted
    print(f"{args.axis} at {float(moved.position[args.axis][-1]) * k:.6g} {unit}")
    print(holding_lines(holding))
    return 0


def own_units(ncfg: NodeConfig) -> tuple[float, str]:
    """An axis's own unit (m for a linear axis, rad for a rotary one) and the factor from motor rad to it.

    Parameters
    ----------
    ncfg : NodeConfig
        The axis's node.

    Returns
    -------
    factor : float
        Own units per motor rad.
    unit : str
        ``m`` or ``rad``.
    """
    return 1.0 / float(ncfg.scaling.load_to_motor(1.0)), "m" if ncfg.linear else "rad"


def plan_lines(plan: Plan, config: BusConfig) -> str:
    """The plan as the person beside the machine reads it: per axis, where it starts, the span it
    covers, its peaks, inside which limits (the axis's own units: m for a linear axis).

    Parameters
    ----------
    plan : Plan
        The plan.
    config : BusConfig
        The bus configuration (each axis's unit).

    Returns
    -------
    str
        The lines.
    """
    from ..master.campaign import plan_summary

    lines = []
    for a, d in plan_summary(plan, plan.limits).items():
        k, unit = own_units(config.nodes[a])
        lim = d["limits"]
        jerk = "" if lim["max_jerk_rad_s3"] is None else f" / {lim['max_jerk_rad_s3'] * k:.4g}"
        lines.append(
            f"  {a}: from {d['start_rad'] * k:.4g} {unit}, spans {d['min_rad'] * k:.4g} .. "
            f"{d['max_rad'] * k:.4g} {unit} (stroke {lim['stroke_rad'][0] * k:.4g} .. "
            f"{lim['stroke_rad'][1] * k:.4g}); peaks {d['peak_velocity_rad_s'] * k:.4g} {unit}/s, "
            f"{d['peak_acceleration_rad_s2'] * k:.4g} {unit}/s², {d['peak_jerk_rad_s3'] * k:.4g} {unit}/s³ "
            f"(limits {lim['max_velocity_rad_s'] * k:.4g}, {lim['max_acceleration_rad_s2'] * k:.4g}{jerk})"
        )
    return "\n".join(lines)


def motion_preview(session: Session, config: BusConfig, plans: options.Plans) -> str:
    """Motion as it would run from where the axes stand, planned and checked over a read-only
    bring-up of ``session`` (nothing that changes a drive's behaviour is written): for --dry-run
    and for the question before a real run. ``plans(axes)`` gives (title, Plan) pairs, each checked
    against the axes' limits as it is planned.

    Parameters
    ----------
    session : Session
        The drives (brought up read-only here).
    config : BusConfig
        The bus configuration.
    plans : callable
        ``plans(axes)``: (title, Plan) pairs.

    Returns
    -------
    str
        The motion in words.
    """
    from ..master.bringup import plan_bring_up
    from ..master.busload import check_bus_load

    load = check_bus_load(config)
    axes = plan_bring_up(session.link, config)
    lines = [f"bus load {load.describe()}"]
    for title, plan in plans(axes):
        lines += [f"{title}: {plan.duration:.1f} s of motion", plan_lines(plan, config)]
    for a, ax in axes.items():
        if (h := ax.cfg.homing) is not None:
            k, unit = own_units(ax.cfg)
            lines.append(
                f"  {a}: homes first (method {h.method}, {h.switch_speed * k:.4g} / {h.zero_speed * k:.4g} "
                f"{unit}/s, within {h.timeout_s:g} s); its motion starts at its home"
            )
        assumed = ax.units.get("assumed_from_bus_yml") or []
        lines.append(
            f"  {a}: units as the drive reports them: {ax.units.get('position_unit') or 'not reported'}"
            + (f"; assumed from bus.yml: {'; '.join(assumed)}" if assumed else "")
        )
    return "\n".join(lines)


def campaign_plans(config: BusConfig) -> options.Plans:
    """The campaign planned from where the axes stand, for :func:`motion_preview`.

    Parameters
    ----------
    config : BusConfig
        The bus configuration.

    Returns
    -------
    callable
        ``plans(axes)``.
    """
    from ..master.campaign import build_plan

    def plans(axes: dict[str, AxisLink]) -> list[tuple[str, Plan]]:
        start = {name: ax.start_rad() for name, ax in axes.items()}
        plan = build_plan(
            config.campaign, {n: a.cfg.limits for n, a in axes.items()}, start, config.master.sync_period_s
        )
        return [(f"campaign {', '.join(plan.axes)}, {len(plan.segments)} segments", plan)]

    return plans


def validate_plans(config: BusConfig, scenarios: str) -> Callable[..., list[tuple[str, Plan]]]:
    """The validation's reference trajectories, one after the other from ``start`` (axis ->
    [rad]; default: where the axes stand), each ``scenarios`` runs both, for :func:`motion_preview`.

    Parameters
    ----------
    config : BusConfig
        The bus configuration.
    scenarios : str
        The scenarios, in words (the titles).

    Returns
    -------
    callable
        ``plans(axes, start=None)``.
    """
    from ..tuning import motion
    from ..tuning.validate import reference_demands

    def plans(axes: dict[str, AxisLink], start: dict[str, float] | None = None) -> list[tuple[str, Plan]]:
        start = start or {name: ax.start_rad() for name, ax in axes.items()}
        out = []
        for traj, demand, _, level in reference_demands(
            {a: ax.cfg.limits for a, ax in axes.items()}, config.master.sync_period_s
        ):
            out.append(
                (
                    f"validate {traj}, with {scenarios}",
                    motion.plan(config, axes, demand, start, kind=traj, level=level)[0],
                )
            )
            start = {a: float(d[-1]) for a, d in demand.items()}
        return out

    return plans


def preview(args: argparse.Namespace, config: BusConfig, plans: options.Plans) -> str:
    """:func:`motion_preview` in a session of its own.

    Parameters
    ----------
    args : argparse.Namespace
        The command line.
    config : BusConfig
        The bus configuration.
    plans : callable
        ``plans(axes)``.

    Returns
    -------
    str
        The motion in words.
    """
    with Session(config, options.session_options(args)) as session:
        return motion_preview(session, config, plans)


def dry_run_end(text: str) -> int:
    """What ``--dry-run`` prints last: the plan, and that nothing moved.

    Parameters
    ----------
    text : str
        The plan in words.

    Returns
    -------
    int
        0.
    """
    print(text)
    print("dry run: nothing was written that changes a drive's behaviour, nothing moved")
    return 0


def holding_lines(holding: dict[str, str] | None) -> str:
    """The command's last lines: how each axis is held now (an axis held powered stays so until the
    master's heartbeat stops with this command; then the drive quick-stops and holds by itself).

    Parameters
    ----------
    holding : dict of str to str or None
        Per axis, how it is held.

    Returns
    -------
    str
        The lines ("" without).
    """
    if not holding:
        return "no axis was enabled"
    return "\n".join(f"  axis {a}: {how}" for a, how in holding.items())


def timing_line(t: Timing) -> str:
    """One line on how a run kept its clock.

    Parameters
    ----------
    t : Timing
        The run's timing.

    Returns
    -------
    str
        The line.
    """
    if t.clock != "wall":
        return "timing: lockstep (simulation time, every SYNC on time)"
    line = (
        f"timing: wall clock, {t.late_cycles_pct:.3g} % late cycles, largest SYNC gap {t.max_sync_gap_ms:.3g} ms, "
        f"mean period {t.mean_sync_period_ms:.4g} ms; sending thread {t.priority}"
    )
    source, ways = t.engine.get("sync_source"), t.engine.get("streaming") or {}
    if source:
        line += f"\n  SYNC from {source}"
    for axis, why in ways.items():
        line += f"\n  axis {axis} streams {why}"
    return line


def degraded_exit(reasons: list[str]) -> int:
    """0, or the degraded exit code with a warning naming what missed its limits.

    Parameters
    ----------
    reasons : list of str
        What missed its timing limits.

    Returns
    -------
    int
        The exit code.
    """
    if not reasons:
        return 0
    print(
        f"drive-bridge: WARNING: timing degraded ({'; '.join(reasons)}): the data are kept; check the load "
        f"on this machine or raise master.timing limits (exit {EXIT_CODES['degraded']})",
        file=sys.stderr,
    )
    return EXIT_CODES["degraded"]


def cmd_decode(args: argparse.Namespace) -> int:
    """The ``decode`` command: log.csv rebuilt from a trace and its meta.yaml.

    Parameters
    ----------
    args : argparse.Namespace
        The command line.

    Returns
    -------
    int
        The exit code (:data:`drive_bridge.errors.EXIT_TABLE`).
    """
    from ..errors import UserError
    from ..logs import decode_trace
    from ..outputs import write_table

    names, values, fmts, _, problem = decode_trace(Path(args.trace), args.meta)
    out = Path(args.out) if args.out else Path(args.trace).with_name("decoded.csv")
    if out.is_dir():
        raise UserError(f"--out {out} is a directory; name the CSV file to write")
    write_table(out, names, values, fmts)
    if args.json:
        options.print_json(
            stamped(
                "decode",
                {
                    "trace": str(args.trace),
                    "out": str(out),
                    "rows": len(values),
                    "columns": list(names),
                    "problem": problem,
                },
            )
        )
    else:
        print(f"wrote {out}: {len(values)} rows, {len(names)} columns")
    if problem:
        raise UserError(f"{args.trace}: {problem}; the {len(values)} rows before it are in {out}")
    return 0


def cmd_check_eds(args: argparse.Namespace) -> int:
    """The ``check-eds`` command: an EDS/DCF checked against CiA 306.

    Parameters
    ----------
    args : argparse.Namespace
        The command line.

    Returns
    -------
    int
        The exit code (:data:`drive_bridge.errors.EXIT_TABLE`).
    """
    from ..cia.edscheck import check

    reports = [check(name) for name in args.files]
    clean = all(r.standard for r in reports)
    if args.json:
        options.print_json(stamped("check-eds", {"standard": clean, "files": [r.as_dict() for r in reports]}))
        return 0 if clean else 1
    for report in reports:
        lely = (
            "Lely dcf-tools not installed (pip install dcf-tools)"
            if report.lely is None
            else f"Lely dcf-tools: {len(report.lely)} finding(s)"
        )
        print(f"{report.path}: {'CiA 306' if report.standard else 'NOT standard'}; {lely}")
        for line in report.findings:
            print(f"  {line}")
        for line in report.lely or ():
            print(f"  lely: {line}")
        for line in report.drive:
            print(f"  drive-bridge: {line}")
    return 0 if clean else 1


def cmd_export(args: argparse.Namespace) -> int:
    """The ``export`` command: the bus configuration for another master (ros2_canopen, Lely).

    Parameters
    ----------
    args : argparse.Namespace
        The command line.

    Returns
    -------
    int
        The exit code (:data:`drive_bridge.errors.EXIT_TABLE`).
    """
    from ..config import load_bus_config
    from ..resources import DEFAULT_BUS_CONFIG
    from ..ros2 import export

    options.out_dir(args.out)
    paths = export(load_bus_config(args.config or DEFAULT_BUS_CONFIG), args.out)
    if args.json:
        options.print_json(
            stamped("export", {"target": args.target, "out": str(args.out), "files": [p.name for p in paths]})
        )
    else:
        print(f"wrote {', '.join(p.name for p in paths)} in {args.out}")
    return 0
