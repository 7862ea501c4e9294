"""Each drive against its own past and against its siblings.

For every drive and axis, the latest run's identified parameters are compared with

* the same drive's previous run on that axis: the difference in units of the combined std
  (``sqrt(std_now² + std_before²)``), so noise is not news;
* its siblings: the latest value of every other drive of the same type (0x1018 vendor and product)
  in the same axis role, as median and spread (1.4826 × the median absolute deviation, never less
  than the median of their own std).

A change is named when it is both significant and material: at least :data:`SIGMAS` combined std
and ``threshold`` relative to the previous value, or at least :data:`SPREADS` spreads and
``threshold`` relative to the siblings' median.  A parameter the data did not determine is never
compared (its std says nothing is known).  Simulated runs are compared only with simulated runs.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass, field
from datetime import datetime

import numpy as np

from ..outputs import hex32
from .store import ParameterRow

SIGMAS = 3.0  # a change against the drive's own past: at least this many combined std ...
SPREADS = 3.0  # ... against its siblings: at least this many spreads ...
THRESHOLD = 0.10  # ... and, either way, at least this much relative change
MIN_SIBLINGS = 3  # fewer siblings than this give no median and spread worth a word


@dataclass
class Comparison:
    """One parameter of one drive's axis in its latest run, against its past and its siblings.

    Parameters
    ----------
    axis : str
        The axis role.
    serial : int or None
        The drive's serial number (0x1018:4); None: unknown.
    drive_type : (int or None, int or None)
        The drive's vendor and product (0x1018:1, :2).
    name : str
        The parameter (J, c0, c1, KpS, ...).
    unit : str or None
        Its unit.
    value, std : float
        Its value and std in this run (std None: not reported).
    run_id : str
        The run.
    when : datetime
        When the run started.
    previous, previous_std : float, optional
        The value and std in the drive's previous run on that axis.
    previous_when : datetime, optional
        When that run started.
    sigmas : float, optional
        (value - previous) / their combined std.
    relative : float, optional
        (value - previous) / |previous|.
    siblings : int
        How many other drives of the same type in the same axis role have a determined value.
    median, spread : float, optional
        Their median and spread (1.4826 × the median absolute deviation, at least the median of
        their std).
    spreads : float, optional
        (value - median) / spread.
    relative_to_median : float, optional
        (value - median) / |median|.
    changed : bool
        Named against its own past.
    stands_out : bool
        Named against its siblings.
    """

    axis: str
    serial: int | None
    drive_type: tuple[int | None, int | None]
    name: str
    unit: str | None
    value: float
    std: float | None
    run_id: str
    when: datetime
    previous: float | None = None
    previous_std: float | None = None
    previous_when: datetime | None = None
    sigmas: float | None = None
    relative: float | None = None
    siblings: int = 0
    median: float | None = None
    spread: float | None = None
    spreads: float | None = None
    relative_to_median: float | None = None
    changed: bool = False
    stands_out: bool = False

    @property
    def named(self) -> bool:
        """Named at all: changed against its past or standing out among its siblings."""
        return self.changed or self.stands_out

    def words(self) -> str:
        """The comparison in one line.

        Returns
        -------
        str
            As ``serial 1002, axis y: c0 +38 % (21 σ) since 2026-06-02 and 3.1 spread above its 11
            siblings``.
        """
        parts = []
        if self.previous is not None and self.relative is not None and self.previous_when is not None:
            parts.append(
                f"{self.relative * 100:+.0f} % ({sigma_text(self.sigmas)} σ) since {self.previous_when.date()}"
            )
        if self.spreads is not None:
            side = "above" if self.spreads >= 0 else "below"
            parts.append(f"{abs(self.spreads):.1f} spread {side} its {self.siblings} siblings")
        return f"{drive_name(self.serial)}, axis {self.axis}: {self.name} " + " and ".join(
            parts or ["no history"]
        )

    def as_dict(self) -> dict:
        """The comparison as ``history compare --json`` gives it.

        Returns
        -------
        dict
            Every field (the serial in hex, times in ISO 8601), ``named`` and ``words``.
        """
        return {
            "axis": self.axis,
            "serial": None if self.serial is None else hex32(self.serial),
            "parameter": self.name,
            "unit": self.unit,
            "value": self.value,
            "std": self.std,
            "run_id": self.run_id,
            "when": self.when.isoformat(),
            "previous": self.previous,
            "previous_std": self.previous_std,
            "previous_when": self.previous_when and self.previous_when.isoformat(),
            "sigmas": self.sigmas,
            "relative": self.relative,
            "siblings": self.siblings,
            "siblings_median": self.median,
            "siblings_spread": self.spread,
            "spreads": self.spreads,
            "relative_to_median": self.relative_to_median,
            "changed": self.changed,
            "stands_out": self.stands_out,
            "named": self.named,
            "words": self.words(),
        }


def drive_name(serial: int | str | None) -> str:
    """A drive as the words name it.

    Parameters
    ----------
    serial : int or str or None
        Its serial number (None: unknown).

    Returns
    -------
    str
        ``serial 1002``, or ``drive of unknown serial``.
    """
    return "drive of unknown serial" if serial is None else f"serial {serial}"


def sigma_text(z: float | None) -> str:
    """A change in combined std as the words say it.

    Parameters
    ----------
    z : float or None
        The change in combined std (None: no std).

    Returns
    -------
    str
        Two digits below 10, whole above, ∞ without a std.
    """
    return "∞" if z is None or math.isinf(z) else f"{abs(z):.2g}" if abs(z) < 10 else f"{abs(z):.0f}"


@dataclass
class History:
    """The parameters of every run, grouped: per (simulated, vendor, product, serial, axis) the
    runs in time order, each a dict of its parameter rows by name.

    Parameters
    ----------
    rows : list of ParameterRow
        Every parameter of every run (:meth:`.store.HistoryStore.parameters`).
    """

    rows: list[ParameterRow]
    runs: dict[tuple, list[tuple[str, datetime, dict[str, ParameterRow]]]] = field(init=False)

    def __post_init__(self) -> None:
        grouped: dict[tuple, dict[str, dict[str, ParameterRow]]] = defaultdict(dict)
        for r in self.rows:
            grouped[self.key(r)].setdefault(r.run_id, {})[r.name] = r
        self.runs = {
            k: sorted(
                ((rid, next(iter(p.values())).started, p) for rid, p in v.items()), key=lambda x: (x[1], x[0])
            )
            for k, v in grouped.items()
        }

    @staticmethod
    def key(r: ParameterRow) -> tuple:
        """The drive-axis a row belongs to.

        Parameters
        ----------
        r : ParameterRow
            A parameter of a run.

        Returns
        -------
        tuple
            (simulated, vendor, product, serial, axis).
        """
        return (r.simulated, r.vendor_id, r.product_code, r.serial, r.axis)

    def series(self, key: tuple, name: str) -> list[ParameterRow]:
        """One drive-axis's values of a parameter, oldest first (undetermined ones included).

        Parameters
        ----------
        key : tuple
            The drive-axis (:meth:`key`).
        name : str
            The parameter.

        Returns
        -------
        list of ParameterRow
            Its value in each run.
        """
        return [p[name] for _, _, p in self.runs.get(key, []) if name in p]

    def siblings(self, key: tuple, name: str, upto: datetime | None = None) -> list[ParameterRow]:
        """The latest determined value of a parameter of every other drive of the same type and axis
        role.

        Parameters
        ----------
        key : tuple
            The drive-axis (:meth:`key`) whose siblings are asked for.
        name : str
            The parameter.
        upto : datetime, optional
            Only runs up to then (the siblings as they stood then).

        Returns
        -------
        list of ParameterRow
            One per sibling.
        """
        sim, vendor, product, serial, axis = key
        out = []
        for k, runs in self.runs.items():
            if k[:3] == (sim, vendor, product) and k[4] == axis and k[3] != serial:
                vals = [
                    p[name]
                    for _, t, p in runs
                    if name in p and p[name].determined and (upto is None or t <= upto)
                ]
                if vals:
                    out.append(vals[-1])
        return out


def compare_one(
    history: History, key: tuple, run_id: str, threshold: float = THRESHOLD, latest_siblings: bool = False
) -> list[Comparison]:
    """One run's parameters on one drive-axis, each against the run before it on that drive-axis
    and against the siblings.

    Parameters
    ----------
    history : History
        The parameters of every run.
    key : tuple
        The drive-axis (:meth:`History.key`).
    run_id : str
        The run.
    threshold : float
        The relative change a difference must reach to be named, besides its significance.
    latest_siblings : bool
        The siblings as they stand now, not as they stood at the run.

    Returns
    -------
    list of Comparison
        One per determined parameter of the run; empty where the drive-axis has no such run.
    """
    runs = history.runs.get(key, [])
    at = next((i for i, (rid, _, _) in enumerate(runs) if rid == run_id), None)
    if at is None:
        return []
    _, when, params = runs[at]
    before = runs[at - 1][2] if at > 0 else {}
    before_when = runs[at - 1][1] if at > 0 else None
    out = []
    for name, p in params.items():
        if not p.determined:
            continue
        c = Comparison(p.axis, p.serial, p.drive_type, name, p.unit, p.value, p.std, run_id, when)
        q = before.get(name)
        if q is not None and q.determined and q.value != 0:
            c.previous, c.previous_std, c.previous_when = q.value, q.std, before_when
            combined = math.hypot(p.std or 0.0, q.std or 0.0)
            diff = p.value - q.value
            c.sigmas = diff / combined if combined > 0 else math.copysign(math.inf, diff) if diff else 0.0
            c.relative = diff / abs(q.value)
            c.changed = abs(c.sigmas) >= SIGMAS and abs(c.relative) >= threshold
        sib = history.siblings(key, name, upto=None if latest_siblings else when)
        c.siblings = len(sib)
        if len(sib) >= MIN_SIBLINGS:
            values = np.array([s.value for s in sib])
            median = float(np.median(values))
            # never narrower than what one identification resolves: three siblings that agree by
            # chance do not make a 1 % difference news
            spread = max(
                float(1.4826 * np.median(np.abs(values - median))),
                float(np.median([s.std or 0.0 for s in sib])),
            )
            c.median, c.spread = median, spread
            if spread > 0 and median != 0:
                c.spreads = (p.value - median) / spread
                c.relative_to_median = (p.value - median) / abs(median)
                c.stands_out = abs(c.spreads) >= SPREADS and abs(c.relative_to_median) >= threshold
        out.append(c)
    return out


def compare(
    history: History, axis: str | None = None, serial: int | None = None, threshold: float = THRESHOLD
) -> list[Comparison]:
    """Every drive-axis's latest run against its past and its siblings.

    Parameters
    ----------
    history : History
        The parameters of every run.
    axis : str, optional
        Only this axis role.
    serial : int, optional
        Only the drive of this serial number.
    threshold : float
        The relative change a difference must reach to be named, besides its significance.

    Returns
    -------
    list of Comparison
        Per drive-axis and parameter, ordered by serial, axis and parameter.
    """
    out = []
    for key, runs in sorted(history.runs.items(), key=lambda kv: (str(kv[0][3]), kv[0][4], kv[0][0])):
        if (axis is None or key[4] == axis) and (serial is None or key[3] == serial):
            out += compare_one(history, key, runs[-1][0], threshold, latest_siblings=True)
    return out
