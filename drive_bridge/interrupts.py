"""SIGTERM and SIGHUP handled like Ctrl-C, and spans of work no signal may cut short.

A service manager or ``timeout`` sends SIGTERM, a closed terminal SIGHUP: while
:func:`handled` is active (the CLI's whole run) each raises :class:`Terminated`,
a KeyboardInterrupt, so every path that ends Ctrl-C safely (quick stop in
motion, restore in a write) ends these the same way.  Inside :func:`deferred`
(restoring a drive's backup) a signal is held and raised when the span ends.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

HANDLED: dict[int, str] = {signal.SIGINT: "Ctrl-C", signal.SIGTERM: "SIGTERM"}
if hasattr(signal, "SIGHUP"):
    HANDLED[signal.SIGHUP] = "SIGHUP"


class Terminated(KeyboardInterrupt):
    """A stop asked for by a signal; ``name`` says which (Ctrl-C, SIGTERM, SIGHUP).

    Parameters
    ----------
    name : str
        Ctrl-C, SIGTERM or SIGHUP.
    """

    def __init__(self, name: str = "Ctrl-C"):
        super().__init__(name)
        self.name = name


class _State:
    deferring = 0  # nested deferred() blocks open
    pending: str | None = None  # the first signal they hold


_state = _State()


def _handler(signum: int, frame: object) -> None:
    name = HANDLED.get(signum, f"signal {signum}")
    if _state.deferring:
        _state.pending = _state.pending or name
        return
    raise Terminated(name)


def signal_name(exc: BaseException) -> str:
    """Ctrl-C, SIGTERM or SIGHUP for an interrupt (a plain KeyboardInterrupt is Ctrl-C).

    Parameters
    ----------
    exc : BaseException
        The interrupt.

    Returns
    -------
    str
        Its name.
    """
    return getattr(exc, "name", "Ctrl-C")


@contextmanager
def handled() -> Iterator[None]:
    """SIGINT, SIGTERM and SIGHUP raise :class:`Terminated` inside this block (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.signal(s, _handler) for s in HANDLED}
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


@contextmanager
def deferred(raise_after: bool = True) -> Iterator[dict[str, str | None]]:
    """Hold every handled signal until the block ends; then raise it (``raise_after``), or leave
    its name in the yielded dict's ``"signal"`` for the caller to report.

    Parameters
    ----------
    raise_after : bool
        Raise the signal held when the block ends.

    Yields
    ------
    dict
        ``{"signal": name or None}``.
    """
    held: dict[str, str | None] = {"signal": None}
    _state.deferring += 1
    try:
        yield held
    finally:
        _state.deferring -= 1
        if not _state.deferring:
            held["signal"], _state.pending = _state.pending, None
            if raise_after and held["signal"]:
                raise Terminated(held["signal"])
