"""Errors by what they mean, and the one table from meaning to exit code.

Every error the tool reports to a person is a :class:`DriveBridgeError`: its
message is one line naming the file, key, axis or object and what to do, and
its ``exit_code`` says how the command ended: :data:`EXIT_TABLE`, the table
``drive-bridge --help`` prints and the documentation's exit-code page is made from.
"""

from __future__ import annotations

import os

#: (code, kind, meaning) of every way a command ends
EXIT_TABLE = (
    (0, "ok", "everything asked for was done"),
    (
        1,
        "internal",
        "a defect of drive-bridge (any unexpected exception); commission keeps the traceback in error.log",
    ),
    (
        2,
        "user",
        "bad configuration, argument or input file: one line naming the file and key (UserError, "
        "ConfigError)",
    ),
    (
        3,
        "bus",
        "a node is missing or no CiA 402 drive, does not answer, or refuses a value: SDO abort, failed "
        "transaction (BusError, DriveRefused)",
    ),
    (
        4,
        "motion",
        "motion stopped by a fault, Ctrl-C, SIGTERM or SIGHUP: every axis quick-stopped and held, the "
        "data recorded so far written (MotionAborted, Interrupted)",
    ),
    (
        5,
        "degraded",
        "done, but a wall-clock run missed its timing limits (late SYNCs, gaps, missing samples): the "
        "data are kept, the warning says what was missed",
    ),
    (6, "not_accepted", "commission completed, but an axis FAILs its acceptance criteria (the verdict)"),
    (
        7,
        "unavailable",
        "a history command could not reach or use the history database (commission, write and "
        "identify never fail for it: their record waits in the outbox for 'history sync')",
    ),
    (
        130,
        "interrupted",
        "Ctrl-C, SIGTERM or SIGHUP while nothing moved; a write in progress restores every drive "
        "first (KeyboardInterrupt, WriteInterrupted)",
    ),
)
EXIT_CODES = {kind: code for code, kind, _ in EXIT_TABLE}


def exit_codes_text(width: int = 100) -> str:
    """The exit-code table as lines of text at most ``width`` long (``drive-bridge --help``).

    Parameters
    ----------
    width : int
        The lines' width [characters].

    Returns
    -------
    str
        The table.
    """
    import textwrap

    return "\n".join(
        textwrap.fill(meaning, width, initial_indent=f"  {code:>3}  {kind:<13} ", subsequent_indent=" " * 21)
        for code, kind, meaning in EXIT_TABLE
    )


class DriveBridgeError(Exception):
    """Base of every error drive-bridge reports as one message and an exit code."""

    kind = "internal"

    @property
    def exit_code(self) -> int:
        """The exit code a command ends with after this error (:data:`EXIT_TABLE`)."""
        return EXIT_CODES[self.kind]

    def __str__(self) -> str:
        """The message on one line (a library's multi-line text folded in)."""
        return " ".join(super().__str__().split())


class InternalError(DriveBridgeError):
    """Something drive-bridge got wrong itself (never the user's or the drive's doing)."""


class UserError(DriveBridgeError):
    """A mistake the user can fix: bad configuration, bad argument, bad log, unknown node."""

    kind = "user"


class ConfigError(UserError):
    """A configuration file is wrong; the message names the file and key.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    key : str
        The key (dotted), "" for the file as a whole.
    problem : str
        What is wrong, and what to do.
    """

    def __init__(self, path: str | os.PathLike[str], key: str, problem: str):
        where = f"{path}: {key}" if key else f"{path}"
        super().__init__(f"{where}: {problem}")
        self.path = path
        self.key = key
        self.problem = problem


class BusError(DriveBridgeError):
    """The bus or a node does not answer, or answers wrongly."""

    kind = "bus"


class DriveRefused(BusError):
    """A drive refused a value or a command (an SDO abort, a failed transaction)."""


class WriteInterrupted(DriveBridgeError):
    """A parameter write cut short by Ctrl-C, SIGTERM or SIGHUP (the drives were restored)."""

    kind = "interrupted"


class MotionAborted(DriveBridgeError):
    """Motion was stopped by a fault or by the user; data up to the stop is kept.

    ``axis`` names the axis that caused the stop (None for Ctrl-C or a bus-wide cause).

    Parameters
    ----------
    reason : str
        Why, in words.
    axis : str, optional
        The axis that caused it.
    emcy : int, optional
        The drive's EMCY error code, where one caused it.
    """

    kind = "motion"

    def __init__(self, reason: str, axis: str | None = None, emcy: int | None = None):
        super().__init__(f"axis {axis}: {reason}" if axis else reason)
        self.reason = reason
        self.axis = axis
        self.emcy = emcy  # the EMCY error code that caused the stop, if one did


class GuardStop(MotionAborted):
    """Motion stopped by a guard of the run itself (e.g. the gain experiment's velocity guard)."""


class RanDry(MotionAborted):
    """Motion stopped where a drive's interpolation FIFO ran dry: the master was away longer than
    the records kept ahead cover; the drive made a planned stop and holds (no fault).

    Parameters
    ----------
    reason : str
        Why, in words.
    axis : str
        The axis whose FIFO ran dry.
    row : int
        The plan row it ran dry at.
    """

    def __init__(self, reason: str, axis: str, row: int):
        super().__init__(reason, axis)
        self.row = row


class Interrupted(MotionAborted):
    """Motion stopped because the user pressed Ctrl-C, or a SIGTERM / SIGHUP arrived.

    Parameters
    ----------
    detail : str
        What was running.
    signal : str
        Ctrl-C, SIGTERM or SIGHUP.
    """

    def __init__(self, detail: str = "", signal: str = "Ctrl-C"):
        who = "by the user (Ctrl-C)" if signal == "Ctrl-C" else f"by {signal}"
        super().__init__(f"interrupted {who}" + (f"; {detail}" if detail else ""))
        self.signal = signal


def exit_code(exc: BaseException) -> int:
    """The exit code a command ends with after ``exc`` (see the table above).

    Parameters
    ----------
    exc : BaseException
        What ended it.

    Returns
    -------
    int
        The exit code.
    """
    if isinstance(exc, DriveBridgeError):
        return exc.exit_code
    if isinstance(exc, KeyboardInterrupt):
        return EXIT_CODES["interrupted"]
    return EXIT_CODES["internal"]
