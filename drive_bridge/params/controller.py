"""The controller a drive runs in its streaming mode, as its profile declares it.

A profile's ``controller`` section names the structure, the loop rates [Hz] and, per item, the
document (and section) it comes from; an item without a source is unverified, shown as such in
tune.json and the report.  Structures:

``cascade``
    position P (+ velocity feed-forward FwF) → velocity PI → current PI.  Parameters KpP [1/s],
    FwF [1], KpS [Nm·s/rad], KiS [1/s], KpC [V/A], KiC [1/s].
``position_pid``
    position PID (+ velocity and acceleration feed-forward) → current PI, as maxon's EPOS2 runs
    in its position modes.  Parameters PidP [Nm/rad], PidI [Nm/(rad·s)], PidD [Nm·s/rad],
    PidFFv [Nm·s/rad], PidFFa [kg·m²], KpC, KiC (the profile turns torque into the drive's
    current with the axis's torque constant).

A position PID on the position error is exactly the cascade P–PI with FwF = 1 at the same rate
(its D term acts on the error's rate, demand velocity less measured): D = KpS,
P = KpS·(KpP + KiS), I = KpS·KiS·KpP.  So the tuner designs the cascade for the drive's rate and
the PID drive is written the same loop; its feed-forward carries the model's viscous friction
(PidFFv = c1) and inertia (PidFFa = J).  Back from a PID, KpP and KiS are the roots of
x² − (P/D)·x + I/D (KpP the larger: the same loop either way); a PID with complex roots has no
cascade and is reported without one.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field

from ..errors import UserError
from ..yamlconf import Section

STRUCTURES = ("cascade", "position_pid")
GAINS = ("KpP", "FwF", "KpS", "KiS", "KpC", "KiC")  # a cascade's gains (tune's terms)
CASCADE = ("KpP", "FwF", "KpS", "KiS")
PID = ("PidP", "PidI", "PidD", "PidFFv", "PidFFa")
RATES = ("position", "velocity", "current")
LOOP_TICK_S = 0.5e-3  # the project drive's velocity / position loop period (2 kHz)
CURRENT_RATE_HZ = 8000.0  # ... and its current loop's rate


@dataclass(frozen=True)
class Timing:
    """The rates of the loops a design is for.

    Parameters
    ----------
    tick_s : float
        The period of the loop closed around the position and velocity [s] (the velocity loop of a
        cascade, a position PID).
    current_hz : float
        The current loop's rate [Hz].
    """

    tick_s: float = LOOP_TICK_S
    current_hz: float = CURRENT_RATE_HZ


@dataclass(frozen=True)
class Controller:
    """What runs in the drive.

    Parameters
    ----------
    structure : {"cascade", "position_pid"}
        The controller's structure (:data:`STRUCTURES`).
    rates_hz : dict of str to float or None
        The loop rates [Hz]: position, velocity, current (a position PID has no velocity loop:
        None).
    sources : dict of str to str
        Per item (``structure`` or a rate), the document that says so (absent: unverified).
    """

    structure: str = "cascade"
    rates_hz: dict[str, float | None] = field(
        default_factory=lambda: {
            "position": 1 / LOOP_TICK_S,
            "velocity": 1 / LOOP_TICK_S,
            "current": CURRENT_RATE_HZ,
        }
    )
    sources: dict[str, str] = field(default_factory=dict)

    @property
    def timing(self) -> Timing:
        """The rates the design is for: the loop closed around the velocity (a cascade's velocity
        loop, a position PID) and the current loop."""
        loop = "velocity" if self.structure == "cascade" else "position"
        inner, current = self.rates_hz[loop], self.rates_hz["current"]
        if not inner or not current:
            raise ValueError(f"a {self.structure} controller needs its {loop} and current loop rates")
        return Timing(1.0 / inner, current)

    def unverified(self) -> list[str]:
        """The items declared without a source.

        Returns
        -------
        list of str
            ``structure`` and the rates, where unverified.
        """
        return [
            k
            for k in ("structure", *RATES)
            if k not in self.sources and (k == "structure" or self.rates_hz.get(k) is not None)
        ]

    def as_dict(self) -> dict:
        """The controller as tune.json holds it.

        Returns
        -------
        dict
            Structure, rates, sources and what is unverified.
        """
        return {
            "structure": self.structure,
            "rates_hz": dict(self.rates_hz),
            "sources": dict(self.sources),
            "unverified": self.unverified(),
        }

    @classmethod
    def from_dict(cls, d: dict | None) -> Controller:
        """:meth:`as_dict` read back (tune.json's ``controller``).

        Parameters
        ----------
        d : dict or None
            The dict; None: a tune.json written before the controller was recorded.

        Returns
        -------
        Controller
            The controller; the project's cascade for None.
        """
        if not d:
            return cls()
        return cls(d["structure"], dict(d["rates_hz"]), dict(d.get("sources") or {}))

    def to_drive(self, values: dict[str, float]) -> dict[str, float]:
        """A parameter set in the cascade's terms (tune's) as this drive's parameters, SI: the
        same for a cascade; for a position PID the gains and the model's J and c1 as the PID and
        its feed-forward.

        Parameters
        ----------
        values : dict of str to float
            The set in the cascade's terms, SI.

        Returns
        -------
        dict of str to float
            The drive's parameters, SI.

        Raises
        ------
        UserError
            A set the drive's structure cannot hold.
        """
        if self.structure == "cascade":
            return dict(values)
        out = {k: v for k, v in values.items() if k not in (*CASCADE, "J", "c1")}
        gains = [g for g in ("KpP", "KpS", "KiS") if g in values]
        if gains and len(gains) < 3:
            raise UserError(
                f"a position PID holds KpP, KpS and KiS only together (given: {', '.join(gains)})"
            )
        if "FwF" in values and values["FwF"] != 1.0:
            raise UserError(
                f"FwF = {values['FwF']:g}: a position PID acts on the error's rate, the whole demand "
                f"velocity (FwF = 1)"
            )
        if gains:
            kpp, kps, kis = values["KpP"], values["KpS"], values["KiS"]
            out.update(PidP=kps * (kpp + kis), PidI=kps * kis * kpp, PidD=kps)
        if "c1" in values:
            out["PidFFv"] = values["c1"]
        if "J" in values:
            out["PidFFa"] = values["J"]
        return out

    def drive_names(self, names: Iterable[str]) -> list[str]:
        """The drive's parameters that hold some of the cascade's terms.

        Parameters
        ----------
        names : iterable of str
            The cascade's terms (KpP, KpS, ...).

        Returns
        -------
        list of str
            The drive's parameters that hold them.
        """
        if self.structure == "cascade":
            return list(names)
        held = {
            "KpP": PID[:3],
            "KpS": PID[:3],
            "KiS": PID[:3],
            "FwF": PID[:3],
            "c1": ("PidFFv",),
            "J": ("PidFFa",),
        }
        return list(dict.fromkeys(d for n in names for d in held.get(n, (n,))))

    def from_drive(self, values: dict[str, float]) -> dict[str, float]:
        """This drive's parameters in the cascade's terms (:meth:`to_drive` undone).

        Parameters
        ----------
        values : dict of str to float
            The drive's parameters, SI.

        Returns
        -------
        dict of str to float
            The cascade's terms, SI.
        """
        if self.structure == "cascade":
            return dict(values)
        out = {k: v for k, v in values.items() if k not in PID}
        if "PidFFv" in values:
            out["c1"] = values["PidFFv"]
        if "PidFFa" in values:
            out["J"] = values["PidFFa"]
        if all(k in values for k in ("PidP", "PidI", "PidD")) and values["PidD"] > 0:
            d = values["PidD"]
            half, prod = values["PidP"] / d / 2, values["PidI"] / d
            if half * half >= prod:
                root = math.sqrt(half * half - prod)
                out.update(KpP=half + root, KiS=half - root, KpS=d, FwF=1.0)
        return out


def load_controller(sec: Section) -> Controller:
    """The ``controller`` section of a profile.

    Parameters
    ----------
    sec : Section
        The section (:class:`~drive_bridge.yamlconf.Section`).

    Returns
    -------
    Controller
        The controller; the project drive's cascade and rates, unverified, where the profile has
        none.

    Raises
    ------
    ConfigError
        A key that does not hold, named with the file.
    """
    if not sec.keys():
        return Controller()
    structure = sec.get("structure", str)
    if structure not in STRUCTURES:
        raise sec.error(
            "structure", f"unknown controller structure {structure!r} (known: {', '.join(STRUCTURES)})"
        )
    rates = sec.section("rates_hz")
    rates_hz: dict[str, float | None] = {}
    for name in RATES:
        needed = not (name == "velocity" and structure == "position_pid")
        rates_hz[name] = rates.get(name, float, low=1.0, high=1e6) if needed else None
    rates.done()
    sources_sec = sec.section("sources", required=False)
    sources = {k: sources_sec.get(k, str) for k in sources_sec.keys()}
    unknown = set(sources) - {"structure", *RATES}
    if unknown:
        raise sources_sec.error(
            sorted(unknown)[0], f"not a controller item (items: structure, {', '.join(RATES)})"
        )
    sources_sec.done()
    sec.done()
    return Controller(structure, rates_hz, sources)
