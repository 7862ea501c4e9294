"""One window of an axis's production motion identified: J, c0 and c1 with their std where the
data determine all three, else why not, in words a maintenance engineer reads at a glance
("one direction only", "too little acceleration", "standing still") with the identification's
own reason beside them."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from ..errors import UserError
from ..history.record import identified

#: the parameters a window must determine to be kept
PARAMETERS = ("J", "c0", "c1")
MIN_MOVING_S = 5.0  # less motion than this in a window: standing still, as far as identification goes


def when(stamp: float) -> str:
    """A frame time stamp [s since the epoch] as an ISO 8601 time (UTC).

    Parameters
    ----------
    stamp : float
        [s since the epoch].

    Returns
    -------
    str
        The time.
    """
    return datetime.fromtimestamp(stamp, timezone.utc).isoformat(timespec="milliseconds")


def _short(name: str, reason: str) -> str:
    """The identification's reason for ``name`` in a few words."""
    if "one direction" in reason:
        return "one direction only"
    if "narrow band" in reason:
        return "one speed only"
    if "std of zero" in reason:
        return "too little acceleration" if name == "J" else f"not told from zero ({reason})"
    return reason


@dataclass
class Window:
    """An axis's window: its span (frame time stamps [s]), moving time [s], and either the
    parameters or why not.

    Parameters
    ----------
    axis : str
        The axis.
    first, last : float
        Its span [s since the epoch].
    moving_s : float
        Its moving time [s].
    values : dict of str to dict, optional
        Name -> value, std, unit, determined.
    why : str, optional
        Why it gave none, in words.
    reasons : dict of str to str
        Per parameter, the identification's words.
    ident : dict, optional
        The axis's identify.json, where it was identified.
    """

    axis: str
    first: float
    last: float
    moving_s: float
    values: dict[str, dict[str, Any]] | None = None
    why: str | None = None
    reasons: dict[str, str] = field(default_factory=dict)
    ident: dict | None = None

    @property
    def determined(self) -> bool:
        """J, c0 and c1 all determined: the window has values."""
        return self.values is not None

    def as_dict(self) -> dict:
        """The window as the monitor's ``window`` event.

        Returns
        -------
        dict
            Axis, span, moving time, values or why not.
        """
        return {
            "axis": self.axis,
            "from": when(self.first),
            "to": when(self.last),
            "moving_s": round(self.moving_s, 3),
            "determined": self.determined,
            "parameters": self.values,
            "why": self.why,
            "reasons": self.reasons,
        }


def standing(axis: str, first: float, last: float, moving_s: float) -> Window:
    """A window in which ``axis`` moved too little to identify anything.

    Parameters
    ----------
    axis : str
        The axis.
    first, last : float
        Its span [s since the epoch].
    moving_s : float
        Its moving time [s].

    Returns
    -------
    Window
        The window, with why.
    """
    why = f"standing still: {moving_s:.1f} s of motion in {last - first:.0f} s"
    return Window(axis, first, last, moving_s, why=why)


def identify_window(log: Path, axis: str, first: float, last: float, moving_s: float, seed: int) -> Window:
    """Identify ``axis`` on the window's log ``log``; the window keeps values only where J, c0 and
    c1 are all determined.

    Parameters
    ----------
    log : Path
        The window's log.
    axis : str
        The axis.
    first, last : float
        Its span [s since the epoch].
    moving_s : float
        Its moving time [s].
    seed : int
        The identification's seed.

    Returns
    -------
    Window
        Its values, or why not.
    """
    if moving_s < MIN_MOVING_S:
        return standing(axis, first, last, moving_s)
    # (imported here: the identification's scipy, in the process that identifies; the listening
    # process needs none of it)
    from ..ident import identify
    from ..ident.presentation import as_json

    try:
        results = identify(log, None, [axis], seed=seed)
    except UserError as exc:
        return Window(axis, first, last, moving_s, why=f"not identified: {exc}".replace(f"{log}: ", ""))
    doc = json.loads(as_json(results))["axes"][axis]
    values = identified(doc)["parameters"]
    reasons = dict(doc.get("undetermined") or {})
    missing = [n for n in PARAMETERS if not (values.get(n) or {}).get("determined")]
    if missing:
        for n in missing:
            reasons.setdefault(n, "not identified")
        why = "; ".join(f"{n}: {_short(n, reasons[n])}" for n in missing)
        return Window(axis, first, last, moving_s, why=why, reasons=reasons, ident=doc)
    return Window(
        axis,
        first,
        last,
        moving_s,
        values={n: values[n] for n in PARAMETERS},
        reasons=reasons,
        ident=doc,
    )
