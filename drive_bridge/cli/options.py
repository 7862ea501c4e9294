"""Options the commands share, declared once, and what they turn into."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import can

from ..canconf import resolve
from ..config import BusConfig, load_bus_config
from ..errors import UserError
from ..outputs import json_text
from ..resources import DEFAULT_BUS_CONFIG
from ..session import Options

if TYPE_CHECKING:
    from ..master.bringup import AxisLink
    from ..master.campaign import Plan

    #: the motion a command would run, planned from where the axes stand: (title, Plan) pairs
    Plans = Callable[[dict[str, AxisLink]], list[tuple[str, Plan]]]


def bus(p: argparse.ArgumentParser) -> None:
    """How to reach the drives: the bus configuration, or the simulated robot.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The command's parser (the arguments are added to it).
    """
    p.add_argument(
        "--config",
        default=str(DEFAULT_BUS_CONFIG),
        help="bus configuration (default: the simulated robot's, shipped with drive-bridge)",
    )
    p.add_argument("--sim", action="store_true", help="run against the simulated robot in-process")
    p.add_argument("--realtime", action="store_true", help="with --sim: wall clock instead of lockstep")
    p.add_argument(
        "--sim-config",
        help="with --sim: simulator YAML, or a shipped robot by name: robot (the default), "
        "compliant (Y on a lightly damped spring), wearing (X's friction rising as it runs)",
    )
    p.add_argument(
        "-i",
        "--interface",
        help="python-can interface (socketcan, pcan, kvaser, vector ...; default: "
        "bus.yml master.interface, else python-can's configuration)",
    )
    p.add_argument(
        "-c",
        "--channel",
        type=can_channel,
        help="python-can channel (can0, PCAN_USBBUS1, 0 ...; default as for --interface)",
    )
    p.add_argument("-b", "--bitrate", type=int, help="bitrate [bit/s] (default as for --interface)")
    p.add_argument(
        "--accept-identity",
        type=int,
        action="append",
        default=[],
        metavar="NODE",
        help="go on although node NODE's identity (0x1018) is not the one its EDS/DCF names "
        "(recorded in the output; repeat for more nodes)",
    )


def campaign(p: argparse.ArgumentParser) -> None:
    """Which excitation: the paper's campaign or the short designed one.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The command's parser (the arguments are added to it).
    """
    from ..config import DESIGNS

    p.add_argument(
        "--campaign",
        choices=DESIGNS,
        help="paper: the paper's trapezoid campaign (the reference); "
        "short: a multisine per axis designed for the identification, campaign.short_time_s per axis "
        "(default: bus.yml campaign.design, else paper)",
    )


def can_channel(text: str) -> str | int:
    """A channel as python-can's configuration files read it: digits are a number (kvaser, vector);
    anything else (a name, "1.5", "true") is the text as given.

    Parameters
    ----------
    text : str
        The channel as given.

    Returns
    -------
    str or int
        The channel.
    """
    value = can.util.cast_from_string(text)
    return value if isinstance(value, int) and not isinstance(value, bool) else text


def drive(p: argparse.ArgumentParser, params: bool = True) -> None:
    """Bus, drive profile, --params (a tune result) and --json: what tune/write/validate share.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The command's parser (the arguments are added to it).
    params : bool
        With ``--params``.
    """
    bus(p)
    p.add_argument(
        "--profile",
        default=None,
        help="drive profile: a shipped name or a YAML file (default: the profile the bus "
        "configuration names, else drive_bridge_servo)",
    )
    if params:
        p.add_argument("--params", required=True, help="tune result (tune.json)")
    json_flag(p)


def motion(p: argparse.ArgumentParser) -> None:
    """``--yes``: a command that moves a real machine asks the person beside it first.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The command's parser (the arguments are added to it).
    """
    p.add_argument(
        "--yes",
        action="store_true",
        help="move the real axes without asking (automation; the person who gives it vouches that "
        "the machine's surroundings are clear); --sim never asks",
    )


def dry_run(p: argparse.ArgumentParser) -> None:
    """``--dry-run`` on a command that moves: everything up to the first setpoint, read only.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The command's parser (the arguments are added to it).
    """
    p.add_argument(
        "--dry-run",
        action="store_true",
        help="scan, read the drives' units and positions, plan and check every motion against the "
        "limits, print the plan and stop: nothing that changes a drive's behaviour is written, "
        "nothing moves",
    )


def asks(args: argparse.Namespace, config: BusConfig, what: str) -> bool:
    """Whether :func:`confirm_motion` will ask a person (not with --sim or --yes); UserError, before
    anything is sent, when it would have to and no one is at a terminal.

    Parameters
    ----------
    args : argparse.Namespace
        The command line.
    config : BusConfig
        The bus configuration.
    what : str
        What will move, in words.

    Returns
    -------
    bool
        A person will be asked.

    Raises
    ------
    UserError
        Asking is needed and no one is at a terminal.
    """
    if args.sim or getattr(args, "yes", False) or getattr(args, "dry_run", False):
        return False
    if not sys.stdin.isatty():
        axes = ", ".join(f"{a} (node {n.node_id})" for a, n in config.nodes.items())
        raise UserError(
            f"{what} moves the real axes {axes} on {config.master.interface}:{config.master.channel}, "
            f"and no one at a terminal can confirm it: give --yes when the machine is clear to move "
            f"(nothing was written or moved)"
        )
    return True


def confirm_motion(
    args: argparse.Namespace, config: BusConfig, what: str, preview: Callable[[], str] | None = None
) -> None:
    """Before a command that moves a real machine writes anything: ``--yes``, or a person at a
    terminal who types ``yes`` after reading what will move (``preview()``: the plan, read without
    writing anything); otherwise UserError (nothing written, nothing moved).  --sim moves nothing
    real and is never asked about.

    Parameters
    ----------
    args : argparse.Namespace
        The command line.
    config : BusConfig
        The bus configuration.
    what : str
        What will move, in words.
    preview : callable, optional
        The plan in words, read without writing anything.

    Raises
    ------
    UserError
        Not confirmed (nothing written, nothing moved).
    """
    if not asks(args, config, what):
        return
    axes = ", ".join(f"{a} (node {n.node_id})" for a, n in config.nodes.items())
    if preview is not None:
        print(preview(), file=sys.stderr)
    print(
        f"{what} will enable and move the real axes {axes} on {config.master.interface}:"
        f"{config.master.channel}; each moves within the limits of {config.path} (a stretch a stall of "
        f"this computer stops, the drives' planned stop, is moved again from its start). Stand clear.",
        file=sys.stderr,
    )
    try:
        answer = input("Type 'yes' to move: ")
    except EOFError:
        answer = ""
    if answer.strip().lower() != "yes":
        raise UserError(f"{what} not confirmed: nothing was written or moved")


def json_flag(p: argparse.ArgumentParser) -> None:
    """``--json``: every command has it.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The command's parser (the arguments are added to it).
    """
    p.add_argument(
        "--json",
        action="store_true",
        help="print the result as one JSON object on stdout (its schema ships in the package); "
        "messages go to stderr",
    )


def print_json(doc: dict) -> None:
    """The one JSON object a ``--json`` command prints: a result :func:`~drive_bridge.outputs.stamped`
    with its schema.

    Parameters
    ----------
    doc : dict
        The result.
    """
    print(json_text(doc))


def motor(p: argparse.ArgumentParser) -> None:
    """Motor data for drives that do not report it (tune and commission design the current loop).

    Parameters
    ----------
    p : argparse.ArgumentParser
        The command's parser (the arguments are added to it).
    """
    p.add_argument("--motor-R", type=float, help="motor resistance [Ω] if the drive does not report it")
    p.add_argument("--motor-L", type=float, help="motor inductance [H] if the drive does not report it")


def write_checks(p: argparse.ArgumentParser) -> None:
    """The margin floor a written gain set must keep, and the deliberate override.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The command's parser (the arguments are added to it).
    """
    from ..params.check import GM_FLOOR_DB, PM_FLOOR_DEG

    p.add_argument(
        "--min-phase-margin",
        type=float,
        default=PM_FLOOR_DEG,
        metavar="DEG",
        help="refuse gains whose loop phase margin on the identified model is below this "
        "(default: %(default)s°)",
    )
    p.add_argument(
        "--min-gain-margin",
        type=float,
        default=GM_FLOOR_DB,
        metavar="DB",
        help="refuse gains whose loop gain margin is below this (default: %(default)s dB)",
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="write a gain set below the margin floor (recorded in the output); never values "
        "outside the drive's ranges",
    )
    p.add_argument(
        "--allow-unverified-scales",
        action="store_true",
        help="write through drive-profile scales that have no documented source (marked in the output)",
    )


def _seed(text: str) -> int:
    value = int(text)
    if not 0 <= value < 2**32:
        raise argparse.ArgumentTypeError(f"must be a whole number from 0 to {2**32 - 1}, got {text}")
    return value


def db(p: argparse.ArgumentParser) -> None:
    """``--db``: the history database.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The command's parser (the arguments are added to it).
    """
    p.add_argument(
        "--db",
        metavar="URL",
        help="history database: sqlite:///PATH or postgresql://USER@HOST/DATABASE "
        "(default: DRIVE_BRIDGE_DB, else history.sqlite in the user's data "
        "directory); a password belongs in PGPASSWORD or ~/.pgpass, not here",
    )


def history(p: argparse.ArgumentParser, asked: bool = False) -> None:
    """Whether the run is kept in the history database: by default (``--no-history`` not to), or
    only when ``asked`` (``--history``).

    Parameters
    ----------
    p : argparse.ArgumentParser
        The command's parser (the arguments are added to it).
    asked : bool
        Kept only when asked.
    """
    if asked:
        p.add_argument(
            "--history", action="store_true", help="keep the identification in the history database"
        )
    else:
        p.add_argument(
            "--no-history",
            dest="history",
            action="store_false",
            help="do not keep this run in the history database",
        )
    db(p)


def figures(p: argparse.ArgumentParser) -> None:
    """``--no-figures``: the reports without their figures.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The command's parser (the arguments are added to it).
    """
    p.add_argument(
        "--no-figures",
        dest="figures",
        action="store_false",
        help="do not draw the reports' figures (faster, for scripts that read only the JSON); "
        "the reports say they were left out",
    )


def seed(p: argparse.ArgumentParser) -> None:
    """``--seed``: the seed of the evolutionary fits.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The command's parser (the arguments are added to it).
    """
    p.add_argument("--seed", type=_seed, default=0, help="seed of the evolutionary fits (default: 0)")


def out_dir(path: str | None) -> None:
    """UserError before any work when ``--out`` names something that is not a directory.

    Parameters
    ----------
    path : str or None
        ``--out``.

    Raises
    ------
    UserError
        A file of that name exists.
    """
    if path and Path(path).exists() and not Path(path).is_dir():
        raise UserError(f"--out {path}: a file of that name exists; --out names a directory")


def axes_list(text: str | None) -> list[str] | None:
    """A comma-separated list of names (None when not given).

    Parameters
    ----------
    text : str or None
        The list.

    Returns
    -------
    list of str or None
        The names.
    """
    return [a.strip() for a in text.split(",") if a.strip()] if text else None


def config(args: argparse.Namespace) -> BusConfig:
    """The bus configuration of ``--config``, restricted to ``--axes`` and with the campaign
    options (``--campaign``, ``--quick``, ``--together``) applied.

    Parameters
    ----------
    args : argparse.Namespace
        The command line.

    Returns
    -------
    BusConfig
        The configuration.

    Raises
    ------
    UserError
        A combination of options that does not hold, or a configuration that is wrong.
    """
    if getattr(args, "realtime", False) and not args.sim:
        raise UserError("--realtime only applies with --sim")
    cfg = load_bus_config(args.config)
    if getattr(args, "accept_identity", None):
        cfg = replace(cfg, accept_identity=frozenset(args.accept_identity))
    if axes := axes_list(getattr(args, "axes", None)):
        cfg = cfg.only(axes)
    if getattr(args, "campaign", None):
        cfg = replace(cfg, campaign=replace(cfg.campaign, design=args.campaign))
    if getattr(args, "quick", False):
        cfg = replace(cfg, campaign=cfg.campaign.quick())
    if getattr(args, "together", False):
        cfg = replace(cfg, campaign=replace(cfg.campaign, together=True))
    if not getattr(args, "sim", False):  # the simulated robot needs no CAN interface
        cfg = resolve(
            cfg,
            getattr(args, "interface", None),
            getattr(args, "channel", None),
            getattr(args, "bitrate", None),
        )
    for note in cfg.master.notes:
        print(f"drive-bridge: note: {note}", file=sys.stderr)
    return cfg


def session_options(args: argparse.Namespace) -> Options:
    """What a Session needs from the command line.

    Parameters
    ----------
    args : argparse.Namespace
        The command line.

    Returns
    -------
    Options
        The session's options.
    """
    R, L = getattr(args, "motor_R", None), getattr(args, "motor_L", None)
    return Options(
        sim=args.sim,
        realtime=args.realtime,
        sim_config=args.sim_config,
        profile=getattr(args, "profile", Options.profile),
        motor=(R, L) if R and L else None,
        seed=getattr(args, "seed", 0),
        force=getattr(args, "force", False),
        pm_floor=getattr(args, "min_phase_margin", Options.pm_floor),
        gm_floor=getattr(args, "min_gain_margin", Options.gm_floor),
        allow_unverified_scales=getattr(args, "allow_unverified_scales", False),
        history=getattr(args, "history", False),
        db=getattr(args, "db", None),
        figures=getattr(args, "figures", True),
    )
