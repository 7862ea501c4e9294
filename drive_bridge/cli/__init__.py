"""Command line of drive-bridge: commission CANopen servo axes (scan, record, identify, tune,
write, validate, or all of it with commission), and the history of what was commissioned.

Each command is a thin layer over the same core function the ``commission`` step of that name
calls: it parses, calls and prints.  Errors end as :mod:`drive_bridge.errors` says: one line, no
traceback, and the exit code of the error's kind (its ``EXIT_TABLE``, which ``--help`` prints).
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import warnings

from .. import interrupts
from ..blas import one_thread
from ..errors import EXIT_CODES, DriveBridgeError, MotionAborted, exit_code, exit_codes_text
from ..version import __version__
from . import bus, commission, history, identification, monitor, tuning

#: the command modules, in the order of the job (``drive-bridge --help`` lists them this way)
COMMANDS = (bus, identification, tuning, commission, history, monitor)


def build_parser() -> argparse.ArgumentParser:
    """The command line: every command's parser, the exit-code table in its epilog.

    Returns
    -------
    argparse.ArgumentParser
        The parser.
    """
    lines = __doc__.splitlines()
    parser = argparse.ArgumentParser(
        prog="drive-bridge",
        description=" ".join(lines[:2]),
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="Run 'drive-bridge COMMAND --help' for a command's options.\n\n"
        "exit codes:\n" + exit_codes_text(),
    )
    parser.add_argument("--version", action="version", version=f"drive-bridge {__version__}")
    parser.add_argument(
        "-v",
        "--verbose",
        action="count",
        default=0,
        help="-v: drive-bridge's log messages (bring-up, units, enabling, stopping, writing); "
        "-vv: also its debug messages and python-can's, canopen's and library warnings",
    )
    parser.add_argument("-q", "--quiet", action="store_true", help="log errors only")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module in COMMANDS:
        module.register(sub)
    return parser


#: the loggers the CLI shows: drive-bridge's own, then (with -vv) its libraries' and their warnings
LIBRARY_LOGGERS = ("canopen", "can", "py.warnings")


def log_to_stderr(verbose: int, quiet: bool) -> logging.Handler:
    """drive-bridge's log on stderr at warning level (-v info, -vv debug, -q errors only); python-can's
    and canopen's only with -vv (at the default their lines are not for the person at the machine:
    what matters is in drive-bridge's own message).

    Parameters
    ----------
    verbose : int
        ``-v`` given this many times.
    quiet : bool
        ``-q``.

    Returns
    -------
    logging.Handler
        The handler (to remove it again).
    """
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("drive-bridge: %(levelname)s %(name)s: %(message)s"))
    level = logging.ERROR if quiet else {0: logging.WARNING, 1: logging.INFO}.get(verbose, logging.DEBUG)
    own = logging.getLogger("drive_bridge")
    own.setLevel(level)
    own.addHandler(handler)
    for name in LIBRARY_LOGGERS:
        lib = logging.getLogger(name)
        if verbose >= 2 and not quiet:
            lib.setLevel(logging.INFO)
            lib.addHandler(handler)
        elif not lib.handlers:
            lib.addHandler(logging.NullHandler())
    return handler


def main(argv: list[str] | None = None) -> int:
    """Run one command; SIGTERM and SIGHUP end it like Ctrl-C (:mod:`drive_bridge.interrupts`).

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default: the process's).

    Returns
    -------
    int
        The exit code (:data:`drive_bridge.errors.EXIT_TABLE`).
    """
    with interrupts.handled(), warnings.catch_warnings():
        try:
            return _run(argv)
        except KeyboardInterrupt as exc:  # a signal before or after a command's own handling
            print(f"drive-bridge: interrupted ({interrupts.signal_name(exc)})", file=sys.stderr)
            return exit_code(exc)
        except BrokenPipeError:  # the reader of our output went away (| head): stop quietly
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return 1


def _run(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    if args.verbose >= 2 and not args.quiet:
        logging.captureWarnings(True)  # library warnings as log lines
    else:
        warnings.simplefilter("ignore")  # library warnings are not for the person at the machine
    loggers = [logging.getLogger(name) for name in ("drive_bridge", *LIBRARY_LOGGERS)]
    levels = [logger.level for logger in loggers]
    handler = log_to_stderr(args.verbose, args.quiet)
    try:
        with one_thread():  # OpenBLAS's own threads would spin between its calls (drive_bridge.blas)
            return _command(args)
    finally:  # main() may run again in this process (tests, the API): its loggers left as they were
        for logger, level in zip(loggers, levels):
            logger.removeHandler(handler)
            logger.setLevel(level)
        logging.captureWarnings(False)


def _command(args: argparse.Namespace) -> int:
    """Run the command, each error ending as :mod:`drive_bridge.errors` says."""
    try:
        return args.func(args)
    except MotionAborted as exc:
        print(
            f"drive-bridge: motion stopped: {exc}. Axes were quick-stopped; "
            f"the data recorded so far is kept.",
            file=sys.stderr,
        )
        return exc.exit_code
    except DriveBridgeError as exc:
        print(f"drive-bridge: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt as exc:
        print(
            f"drive-bridge: interrupted ({interrupts.signal_name(exc)}); nothing was moving", file=sys.stderr
        )
        return exit_code(exc)
    except BrokenPipeError:
        raise
    except OSError as exc:  # an output the user named cannot be written
        where = f"{exc.filename}: " if exc.filename else ""
        print(
            f"drive-bridge: error: {where}{exc.strerror or exc}; choose another output path", file=sys.stderr
        )
        return EXIT_CODES["user"]
