"""What may be written to a drive, checked before the first write of a transaction.

A value is refused when it is not finite, has a sign no physical axis has,
lies outside the drive profile's range in SI (``min``/``max`` of the profile
entry: the drive's own limits), or, in device units, outside the EDS
LowLimit/HighLimit or its data type.  A gain set is refused when the loop
margins it gives on the model it was designed for (recomputed from the exact
values written) fall below a floor, unless forced.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import canopen
import numpy as np
from canopen.objectdictionary import datatypes

from ..cia.od import variable
from ..errors import UserError
from .cascade import loop_margins, measured_margins
from .profile import Entry, Profile

if TYPE_CHECKING:
    from ..ident.frf import Frf

log = logging.getLogger(__name__)

#: sign of each abstract parameter, whatever the drive: (lowest, lowest allowed itself, highest);
#: a model term of 0 is "no feed-forward of that kind" (the factory model of a drive)
PHYSICAL = {
    "J": (0.0, True, None),
    "c0": (0.0, True, None),
    "c1": (0.0, True, None),
    "PidI": (0.0, True, None),
    "PidFFv": (0.0, True, None),
    "PidFFa": (0.0, True, None),
    "periodic_amplitude": (0.0, True, None),
    "periodic_period": (0.0, True, None),
    "ff_enable": (0.0, True, 1.0),
    "FwF": (0.0, True, None),
    **{g: (0.0, False, None) for g in ("KpP", "KpS", "KiS", "KpC", "KiC", "PidP", "PidD")},
}
INTEGER_RANGES = {
    datatypes.UNSIGNED8: (0, 2**8 - 1),
    datatypes.UNSIGNED16: (0, 2**16 - 1),
    datatypes.UNSIGNED32: (0, 2**32 - 1),
    datatypes.INTEGER8: (-(2**7), 2**7 - 1),
    datatypes.INTEGER16: (-(2**15), 2**15 - 1),
    datatypes.INTEGER32: (-(2**31), 2**31 - 1),
}
REAL_MAX = {
    datatypes.REAL32: float(np.finfo(np.float32).max),
    datatypes.REAL64: float(np.finfo(np.float64).max),
}
#: the floor a written gain set must keep on its model (industrial tuners warn below these)
PM_FLOOR_DEG, GM_FLOOR_DB = 30.0, 4.0


class ValueRefused(UserError):
    """A value that must not reach a drive; the message names the axis, parameter and range."""


def check_value(entry: Entry, var: canopen.objectdictionary.ODVariable, value: Any) -> str | None:
    """Why a value must not be written to an object.

    Parameters
    ----------
    entry : Entry
        The parameter's object and scaling (its range, where the profile states one).
    var : canopen.objectdictionary.ODVariable
        The object as the drive's EDS describes it (data type, range, access).
    value : object
        The value, SI.

    Returns
    -------
    str or None
        Why; None: it may be written.
    """
    name, unit = entry.parameter, f" {entry.unit}" if entry.unit else ""
    try:
        value = float(value)
    except (TypeError, ValueError):
        return f"{name} = {value!r} is not a number"
    if not math.isfinite(value):
        return f"{name} = {value} is not a finite number"
    low, low_ok, high = PHYSICAL.get(name, (None, True, None))
    if low is not None and (value < low or (value == low and not low_ok)):
        return f"{name} = {value:.6g}{unit} must be {'≥' if low_ok else '>'} {low:g}"
    if high is not None and value > high:
        return f"{name} = {value:.6g}{unit} must be ≤ {high:g}"
    if name == "ff_enable" and value not in (0.0, 1.0):
        return f"ff_enable = {value:g} must be 0 or 1"
    if entry.min is not None and value < entry.min or entry.max is not None and value > entry.max:
        shown = ("" if x is None else f"{x:g}" for x in (entry.min, entry.max))
        return f"{name} = {value:.6g}{unit} is outside the drive's range {'..'.join(shown)}{unit} (drive profile)"
    device = entry.to_device(value)
    if isinstance(device, float) and not math.isfinite(device):
        return f"{name} = {value:.6g}{unit} has no value in device units"
    if var.data_type in REAL_MAX and abs(device) > REAL_MAX[var.data_type]:
        return f"{name} = {value:.6g}{unit} overflows {entry.where()}'s data type"
    lo, hi = INTEGER_RANGES.get(var.data_type, (None, None)) if var.data_type is not None else (None, None)
    if var.min is not None:
        lo = var.min
    if var.max is not None:
        hi = var.max
    if (lo is not None and device < lo) or (hi is not None and device > hi):
        return (
            f"{name} = {value:.6g}{unit} is {device} in device units, outside {entry.where()}'s range "
            f"{lo}..{hi} (EDS and data type)"
        )
    return None


def check_set(profile: Profile, od: canopen.ObjectDictionary, values: dict) -> list[str]:
    """Every reason a parameter set must not be written to a drive.

    Parameters
    ----------
    profile : Profile
        The drive's profile.
    od : canopen.ObjectDictionary
        Its object dictionary.
    values : dict
        The set: name -> value, SI.

    Returns
    -------
    list of str
        Every reason, each naming the parameter (empty: it may be written).
    """
    problems = [
        p
        for name, v in values.items()
        if name in profile.entries
        for p in [
            check_value(
                profile.entries[name], variable(od, profile.entries[name].index, profile.entries[name].sub), v
            )
        ]
        if p
    ]
    amp, period = values.get("periodic_amplitude", 0.0), values.get("periodic_period", 0.0)
    if not problems and amp and not period:
        problems.append(
            f"periodic_amplitude = {amp:.6g} needs a periodic_period > 0 (0 switches the ripple off)"
        )
    return problems


@dataclass
class MarginCheck:
    """The margins of the gains written, on the model they were designed for (and on the plant's
    measured response where there is one: the worse of the two).

    Parameters
    ----------
    phase_margin_deg : float
        [°].
    gain_margin_db : float
        [dB].
    ok : bool
        Both at least the floor.
    """

    phase_margin_deg: float
    gain_margin_db: float
    ok: bool

    def as_dict(self) -> dict:
        """The margins as write.json holds them.

        Returns
        -------
        dict
            ``phase_margin_deg``, ``gain_margin_db``, ``ok``.
        """
        return {
            "phase_margin_deg": self.phase_margin_deg,
            "gain_margin_db": self.gain_margin_db,
            "ok": self.ok,
        }


def written_si(profile: Profile, values: dict) -> dict[str, float]:
    """A parameter set as the drive will hold it: through its controller's parameters and device
    units and back (rounding, REAL32).

    Parameters
    ----------
    profile : Profile
        The drive's profile.
    values : dict
        The set in the cascade's terms, SI.

    Returns
    -------
    dict of str to float
        The same set as the drive will hold it, SI.
    """
    held = {
        name: float(e.to_si(e.held(e.to_device(v)))) if (e := profile.entries.get(name)) else float(v)
        for name, v in profile.controller.to_drive(values).items()
    }
    return profile.controller.from_drive(held)


def check_margins(
    profile: Profile,
    values: dict,
    L: float | None,
    *,
    pm_floor: float = PM_FLOOR_DEG,
    gm_floor: float = GM_FLOOR_DB,
    frf: Frf | None = None,
) -> tuple[dict, str | None]:
    """Velocity- and position-loop margins of the gains in ``values``, as written, on the model
    of the same set (J, c1) with motor inductance ``L`` [H] and, where the axis's response was
    measured (``frf``: :class:`~drive_bridge.ident.frf.Frf`), on that too -- the worse of the two; a
    loop whose crossover lies above the band measured is not verified -- and why the set must not
    be written (None: it may).  A set without gains, or without J, cannot be checked: that is a
    reason too.

    Parameters
    ----------
    profile : Profile
        The drive's profile.
    values : dict
        The set: gains and model, SI.
    L : float or None
        The motor's inductance [H] (None: not known).
    pm_floor : float
        The phase margin floor [°].
    gm_floor : float
        The gain margin floor [dB].
    frf : Frf, optional
        The axis's measured response.

    Returns
    -------
    margins : dict
        The velocity and position loops' margins (:class:`MarginCheck` as dicts).
    why : str or None
        Why the set must not be written; None: it may.
    """
    gains = ("KpP", "KpS", "KiS", "KpC")
    if not any(g in values for g in gains):
        return {}, None  # no gains in this set: nothing to check
    missing = [g for g in gains if g not in values]
    if missing or not values.get("J") or L is None:
        what = ", ".join(missing) or ("the model's J" if not values.get("J") else "the motor inductance L")
        return {}, f"the loop margins cannot be checked without {what}"
    w = written_si(profile, {g: values[g] for g in gains})
    if not {"KpP", "KiS"} <= set(w):
        return {}, "the position PID written has no cascade to check the margins of (complex roots)"
    tick = profile.controller.timing.tick_s
    model = loop_margins(values["J"], max(values.get("c1", 0.0), 0.0), w, 0.0, L, tick)
    measured = measured_margins(w, frf, w["KpC"] / L, tick) if frf is not None else (None, None)
    unverified = [
        name for name, m in zip(("velocity", "position"), measured) if frf is not None and m is None
    ]
    worse = [m if other is None else m.worse(other) for m, other in zip(model, measured)]
    out = {
        name: MarginCheck(
            m.phase_margin_deg,
            m.gain_margin_db,
            name not in unverified and m.phase_margin_deg >= pm_floor and m.gain_margin_db >= gm_floor,
        )
        for name, m in zip(("velocity", "position"), worse)
    }
    where = "on the identified model" + (" and the measured response" if frf is not None else "")
    bad = [
        f"{name} loop PM {m.phase_margin_deg:.1f}° / GM {m.gain_margin_db:.1f} dB"
        for name, m in out.items()
        if not m.ok and name not in unverified
    ]
    reason = (
        "; ".join(
            (
                [f"{' and '.join(bad)} {where}, below the floor of {pm_floor:g}° / {gm_floor:g} dB"]
                if bad
                else []
            )
            + [
                f"the {name} loop crosses over above the band its response was measured in: not verified"
                for name in unverified
            ]
        )
        or None
    )
    return {k: v.as_dict() for k, v in out.items()}, reason


@dataclass
class GateResult:
    """What the gate let through (:func:`screen`).

    Parameters
    ----------
    margins : dict of str to dict
        Per axis, the margins of its set.
    forced : list of str
        The sets written below the floor because ``force`` said so.
    unverified : list of str
        The scales without a documented source it writes.
    """

    margins: dict[str, dict]
    forced: list[str]
    unverified: list[str]


def screen(
    profiles: dict[str, Profile],
    values: dict[str, dict],
    inductance: dict[str, float | None],
    *,
    force: bool = False,
    pm_floor: float = PM_FLOOR_DEG,
    gm_floor: float = GM_FLOOR_DB,
    allow_unverified_scales: bool = False,
    dry_run: bool = False,
    frf: dict | None = None,
) -> tuple[GateResult, str | None]:
    """The one check every gain set passes before it reaches a drive (``write``, ``validate``):
    scales with a documented source (else only with ``allow_unverified_scales``; a dry run shows
    them), and the loop margins of each axis's set on its model (J, c1) with the motor inductance
    ``inductance[axis]`` [H] -- and on its measured response, where ``frf`` has one -- above the
    floor (else only with ``force``, recorded).  ``profiles``: each axis's, bound to its motor
    (:func:`~.write.bind_axes`).

    Parameters
    ----------
    profiles : dict of str to Profile
        Per axis, its drive's profile, bound to its motor.
    values : dict of str to dict
        Per axis, the set (SI).
    inductance : dict of str to float or None
        Per axis, the motor inductance [H].
    force : bool
        Let a set below the floor through (recorded).
    pm_floor : float
        The phase margin floor [°].
    gm_floor : float
        The gain margin floor [dB].
    allow_unverified_scales : bool
        Let a scale without a documented source through.
    dry_run : bool
        Nothing will be written: unverified scales are shown, not refused.
    frf : dict, optional
        Per axis, its measured response.

    Returns
    -------
    result : GateResult
        What passed.
    why : str or None
        Why the sets must not reach the drives; None: they may (ranges are :func:`check_set`'s).
    """
    drive_sets, unheld = {}, []
    for a, v in values.items():
        try:
            drive_sets[a] = profiles[a].drive_values(v)
        except UserError as exc:
            unheld.append(f"axis {a}: {exc}")
    if unheld:
        return GateResult({}, [], []), "; ".join(unheld)
    unverified = sorted(
        {
            f"{k} ({e.where()})"
            for a, v in drive_sets.items()
            for k in v
            if (e := profiles[a].entries.get(k)) is not None and not e.verified
        }
    )
    profile = next(iter(profiles.values()))
    if unverified and not dry_run and not allow_unverified_scales:
        return GateResult({}, [], unverified), (
            f"the {profile.drive} profile has no documented source for the scale of {', '.join(unverified)} "
            f"({profile.path}); check them against the drive's manual, or --allow-unverified-scales to write "
            f"them anyway"
        )
    margins: dict[str, dict] = {}
    refused: list[str] = []
    forced: list[str] = []
    for a, v in values.items():
        margins[a], reason = check_margins(
            profiles[a], v, inductance.get(a), pm_floor=pm_floor, gm_floor=gm_floor, frf=(frf or {}).get(a)
        )
        if reason:
            (forced if force else refused).append(f"axis {a}: {reason}")
    for reason in forced:
        log.warning("written below the margin floor (--force): %s", reason)
    result = GateResult(margins, forced, unverified)
    return result, ("; ".join(refused) + " (--force writes it anyway and records that)") if refused else None


def gate(
    profiles: dict[str, Profile], values: dict[str, dict], inductance: dict[str, float | None], **checks: Any
) -> GateResult:
    """:func:`screen`, refusing before anything is written.

    Parameters
    ----------
    profiles : dict of str to Profile
        Per axis, its drive's profile, bound to its motor.
    values : dict of str to dict
        Per axis, the set (SI).
    inductance : dict of str to float or None
        Per axis, the motor inductance [H].
    **checks : object
        :func:`screen`'s keyword arguments.

    Returns
    -------
    GateResult
        What passed.

    Raises
    ------
    ValueRefused
        A set the gate refuses, and why.
    """
    result, refused = screen(profiles, values, inductance, **checks)
    if refused:
        raise ValueRefused(f"refused before anything was written: {refused}")
    return result
