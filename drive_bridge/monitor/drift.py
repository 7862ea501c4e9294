"""Drift named as it happens: each window's J, c0 and c1 against the drive's last commissioning
(or, where none is kept, the first window the monitor identified) and against its recent windows,
in units of the combined std as ``history compare`` measures a change.

A parameter is beyond its reference where it differs by at least :data:`SIGMAS` combined std
*and* :data:`THRESHOLD` of the reference (noise is not news, nor is a significant 1 %); it is
named once it has been beyond, on the same side, in :data:`PERSIST` windows in a row -- one odd
window names nothing -- and named again only after it has come back.  ``since`` is the first
window of that run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from ..history.compare import SIGMAS, THRESHOLD, drive_name, sigma_text
from .window import PARAMETERS, Window, when

PERSIST = 2  # windows in a row beyond the reference before a change is named
RECENT = 5  # the windows a new one is also set against (their mean)


@dataclass
class Reference:
    """What an axis's windows are set against: value and std per parameter, where they come from.

    Parameters
    ----------
    values : dict of str to (float, float)
        Name -> (value, std), SI.
    source : str
        ``commissioning <run id> of <time>`` or ``first monitored window of <time>``.
    """

    values: dict[str, tuple[float, float]]
    source: str


@dataclass
class AxisDrift:
    """One axis's reference, its recent windows and the changes running.

    Parameters
    ----------
    reference : Reference, optional
        What its windows are set against.
    recent : list of dict
        The last windows' values.
    runs : dict of str to list
        Parameter -> [side (+1/-1), windows in a row beyond, first window's start, named].
    """

    reference: Reference | None = None
    recent: list[dict[str, float]] = field(default_factory=list)
    runs: dict[str, list[Any]] = field(default_factory=dict)

    def as_dict(self) -> dict:
        """The state as the monitor's state file holds it.

        Returns
        -------
        dict
            ``reference``, ``recent``, ``runs``.
        """
        ref = self.reference
        return {
            "reference": None if ref is None else {"values": ref.values, "source": ref.source},
            "recent": self.recent,
            "runs": self.runs,
        }

    @classmethod
    def from_dict(cls, d: dict) -> AxisDrift:
        """:meth:`as_dict` read back.

        Parameters
        ----------
        d : dict
            The dict.

        Returns
        -------
        AxisDrift
            The state.
        """
        ref = d.get("reference")
        return cls(
            None
            if ref is None
            else Reference({k: tuple(v) for k, v in ref["values"].items()}, ref["source"]),
            list(d.get("recent") or []),
            dict(d.get("runs") or {}),
        )


def _event(w: Window, serial: str | None, name: str, ref: Reference, sigmas: float, **more: Any) -> dict:
    """``name`` of window ``w`` against ``ref``, ``sigmas`` combined std apart, as a JSON-ready dict."""
    value, std = w.values[name]["value"], w.values[name]["std"]  # type: ignore[index]
    ref_value, ref_std = ref.values[name]
    return {
        "axis": w.axis,
        "serial": serial,
        "parameter": name,
        "unit": w.values[name]["unit"],  # type: ignore[index]
        "value": value,
        "std": std,
        "reference": ref_value,
        "reference_std": ref_std,
        "reference_from": ref.source,
        "relative": (value - ref_value) / abs(ref_value),
        "sigmas": sigmas,
        "window": {"from": when(w.first), "to": when(w.last)},
        **more,
    }


def judge(state: AxisDrift, w: Window, serial: str | None) -> list[dict]:
    """Set the determined window ``w`` against the axis's reference and recent windows; the
    changes to name now (``event``: ``drift``, or ``back`` for one that came back within the
    noise), as JSON-ready dicts with their words.

    Parameters
    ----------
    state : AxisDrift
        The axis's state (updated here).
    w : Window
        The window.
    serial : str or None
        The drive's serial number, for the words.

    Returns
    -------
    list of dict
        The events.
    """
    assert w.values is not None
    values = {n: w.values[n]["value"] for n in PARAMETERS}
    if state.reference is None:
        stds = {n: w.values[n]["std"] or 0.0 for n in PARAMETERS}
        state.reference = Reference(
            {n: (values[n], stds[n]) for n in PARAMETERS}, f"first monitored window of {when(w.first)}"
        )
    ref = state.reference
    events = []
    recent = state.recent[-RECENT:]
    for name in PARAMETERS:
        ref_value, ref_std = ref.values[name]
        std = w.values[name]["std"] or 0.0
        diff = values[name] - ref_value
        combined = math.hypot(std, ref_std)
        sigmas = diff / combined if combined > 0 else (math.inf if diff else 0.0)
        beyond = abs(sigmas) >= SIGMAS and ref_value != 0 and abs(diff / ref_value) >= THRESHOLD
        side = 1 if diff > 0 else -1
        run = state.runs.get(name)
        trend = (
            (values[name] - sum(r[name] for r in recent) / len(recent)) / abs(ref_value)
            if recent and ref_value
            else None
        )
        if beyond:
            if run is None or run[0] != side:
                run = [side, 0, w.first, False]
            run[1] += 1
            state.runs[name] = run
            if run[1] >= PERSIST and not run[3]:
                run[3] = True
                e = _event(w, serial, name, ref, sigmas, event="drift", since=when(run[2]), trend=trend)
                e["words"] = (
                    f"{drive_name(serial)}, axis {w.axis}: {name} {e['relative'] * 100:+.0f} % "
                    f"({sigma_text(sigmas)} σ) since {e['since'][:16]} against the {ref.source}"
                )
                events.append(e)
        elif run is not None:
            if run[3]:
                e = _event(w, serial, name, ref, sigmas, event="back", since=when(run[2]), trend=trend)
                e["words"] = (
                    f"{drive_name(serial)}, axis {w.axis}: {name} back within the noise of its reference "
                    f"({e['relative'] * 100:+.0f} %, {sigma_text(sigmas)} σ)"
                )
                events.append(e)
            del state.runs[name]
    state.recent = (state.recent + [values])[-RECENT:]
    return events
