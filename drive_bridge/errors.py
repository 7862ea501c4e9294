"""Exceptions that the CLI turns into one clear message and an exit code."""
from __future__ import annotations


class UserError(Exception):
    """A mistake the user can fix: bad configuration, bad log, unknown node.

    The CLI prints the message alone (no traceback) and exits with ``exit_code``.
    """

    exit_code = 2


class ConfigError(UserError):
    """A configuration file is wrong; the message names the file and key."""

    def __init__(self, path, key: str, problem: str):
        where = f"{path}: {key}" if key else f"{path}"
        super().__init__(f"{where}: {problem}")
        self.path = path
        self.key = key
        self.problem = problem


class BusError(UserError):
    """The bus or a node does not answer or answers wrongly."""

    exit_code = 3


class MotionAborted(Exception):
    """Motion was stopped by a fault or by the user; data up to the stop is kept.

    ``axis`` names the axis that caused the stop (None for Ctrl-C or a bus-wide cause).
    """

    exit_code = 4

    def __init__(self, reason: str, axis: str | None = None):
        super().__init__(f"axis {axis}: {reason}" if axis else reason)
        self.reason = reason
        self.axis = axis


class Interrupted(MotionAborted):
    """Motion stopped because the user pressed Ctrl-C."""

    def __init__(self, detail: str = ""):
        super().__init__("interrupted by the user (Ctrl-C)" + (f"; {detail}" if detail else ""))
