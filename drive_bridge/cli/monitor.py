"""``monitor``: listen to a running machine, identify each window of its production motion, keep
each axis's J, c0 and c1 in the history and name their drift as it happens."""

from __future__ import annotations

import argparse
import hashlib
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
        "monitor",
        help="listen only: identify J, c0, c1 from a running machine's production motion, name drift",
        description="Listens to the bus (never sends a frame), decodes each axis's TPDOs and setpoint "
        "RPDOs as bus.yml maps them, identifies every window of motion and keeps the windows whose "
        "data determine J, c0 and c1 in the history; each is set against the drive's last "
        "commissioning and recent windows, and a change beyond the noise is named. Runs until "
        "Ctrl-C or SIGTERM (exit 0, resumable from --dir), or for one window with --once.",
    )
    p.add_argument(
        "--config",
        default=str(options.DEFAULT_BUS_CONFIG),
        help="bus configuration: the PDO mapping and units of the machine's drives (default: the "
        "simulated robot's)",
    )
    p.add_argument("-i", "--interface", help="python-can interface (default: bus.yml master.interface)")
    p.add_argument("-c", "--channel", type=options.can_channel, help="python-can channel")
    p.add_argument("-b", "--bitrate", type=int, help="bitrate [bit/s]")
    p.add_argument(
        "--dir",
        help="where the rolling log, the state a restart resumes from and events.jsonl live "
        "(default: monitor/<bus config name> in drive-bridge's data directory)",
    )
    p.add_argument(
        "--window",
        type=_positive,
        default=600.0,
        metavar="S",
        help="an axis's window closes with this much of its motion [s] (default: 600)",
    )
    p.add_argument(
        "--max-span",
        type=_positive,
        default=3600.0,
        metavar="S",
        help="... or once it spans this long, whatever it holds [s] (default: 3600)",
    )
    p.add_argument("--once", action="store_true", help="stop once every axis has closed one window")
    p.add_argument(
        "--sim",
        action="store_true",
        help="listen to the simulated robot running a week of pick-and-place production (lockstep, "
        "in minutes; without --dir in a fresh temporary directory)",
    )
    p.add_argument(
        "--sim-config",
        help="with --sim: simulator YAML, or a shipped robot by name: robot, compliant, wearing (the "
        "default: X's friction wears over the week)",
    )
    p.add_argument("--shifts", type=int, default=21, help="with --sim: shifts in the week (default: 21)")
    p.add_argument(
        "--shift-s", type=_positive, default=60.0, help="with --sim: motion per shift [s] (default: 60)"
    )
    options.json_flag(p)
    options.seed(p)
    options.history(p)
    p.set_defaults(func=cmd_monitor)


def _positive(text: str) -> float:
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"{text}: must be more than 0")
    return value


def cmd_monitor(args: argparse.Namespace) -> int:
    """The ``monitor`` command: a running machine watched without sending a frame.

    Parameters
    ----------
    args : argparse.Namespace
        The command line.

    Returns
    -------
    int
        The exit code (:data:`drive_bridge.errors.EXIT_TABLE`).
    """
    from ..monitor import Monitor, Settings, listen
    from ..outputs import json_text, stamped

    config = options.config(args)  # (the interface from -i/-c/-b, bus.yml or python-can's; its notes said)
    if args.dir:
        directory = Path(args.dir)
    elif args.sim:  # a simulated week starts afresh each time
        import tempfile

        directory = Path(tempfile.mkdtemp(prefix="drive-bridge-monitor-sim-"))
    else:
        directory = default_dir(config.path)
    settings = Settings(
        window_s=args.window,
        max_span_s=args.max_span,
        seed=args.seed,
        db=args.db,
        history=args.history,
        simulated=args.sim,
    )
    events = directory / "events.jsonl"

    def say(text: str) -> None:
        print(text, file=sys.stderr if args.json else sys.stdout, flush=True)

    def emit(event: dict) -> None:
        line = json_text(stamped("monitor", event))
        if event["event"] != "window":
            with open(events, "a", encoding="utf-8") as f:  # for a plant system to pick up
                f.write(line + "\n")
        if args.json:
            print(line, flush=True)
        if event["event"] == "window":
            kept = event.get("kept")
            text = _window_words(event)
            say(text + (f"; {kept['where']}" if kept else ""))
        else:
            say(("DRIFT " if event["event"] == "drift" else "") + event["words"])

    # on a live bus the windows are identified beside the listening, in a worker process
    monitor = Monitor(config, directory, settings, emit, background=not args.sim)
    for axis, drive in monitor.drives.items():
        ref = monitor.drift[axis].reference
        say(
            f"axis {axis}: node {drive.node_id}, "
            + (
                f"serial {drive.serial}, "
                if drive.serial
                else "drive identity unknown (no commissioning kept), "
            )
            + f"reference: {ref.source if ref else 'the first window it identifies'}"
        )
    say(f"state and rolling log in {directory}")
    if args.sim:
        from ..monitor.simulated import simulated_week

        week = simulated_week(
            config,
            monitor,
            say,
            sim_config=args.sim_config or "wearing",
            shifts=args.shifts,
            shift_s=args.shift_s,
            seed=args.seed,
        )
        monitor.stop()
        if week.aborted is not None:
            raise week.aborted
        travel = ", ".join(f"{a} {d:.0f} rad" for a, d in week.travel_rad.items())
        say(
            f"simulated week done: {week.shifts} shifts, {sum(monitor.closed.values())} windows; travelled: {travel}"
        )
        return 0
    seen = listen(monitor, config, say, once=args.once)
    say(
        f"stopped{f' ({seen.stopped_by})' if seen.stopped_by else ''}: {seen.frames} frames, "
        f"{seen.error_frames} error frames, {sum(monitor.closed.values())} windows closed; the rolling log "
        f"and state are kept in {directory} for the next start"
    )
    return 0


def _window_words(event: dict) -> str:
    from ..monitor.window import PARAMETERS

    span = f"{event['from'][:19]} .. {event['to'][11:19]}, {event['moving_s']:.0f} s moving"
    if not event["determined"]:
        return f"axis {event['axis']}: window {span}: no values ({event['why']})"
    p = event["parameters"]
    values = ", ".join(f"{n} {p[n]['value']:.4g} ± {p[n]['std']:.2g}" for n in PARAMETERS)
    return f"axis {event['axis']}: window {span}: {values}"


def default_dir(config: Path) -> Path:
    """``monitor/<bus config name>-<hash of its path>`` in the user's data directory.

    Parameters
    ----------
    config : Path
        The bus configuration.

    Returns
    -------
    Path
        The directory.
    """
    from ..history.location import data_dir

    digest = hashlib.sha256(str(config.resolve()).encode()).hexdigest()[:8]
    return data_dir() / "monitor" / f"{config.stem}-{digest}"
