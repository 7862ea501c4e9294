"""Drive profiles: which object of one drive model holds each abstract parameter, and in what units.

A profile is a YAML file (``profiles/*.yaml``): the drive's EDS/DCF (``package/…``
shipped in ``drive_bridge/data``, ``vendor/…`` in the vendor folder, read in place:
``$DRIVE_BRIDGE_VENDOR_EDS``, else ``../shared/eds-vendor`` or ``shared/eds-vendor``
from the working directory), the store object, and per abstract parameter (J, c0, c1, offset,
cp, dc0, dc1, periodic_amplitude/period/phase, ff_enable, KpP, FwF, KpS, KiS, KpC, KiC, and a position
PID's PidP, PidI, PidD, PidFFv, PidFFa) its index, sub-index,
data type and scaling: device value = scale × SI value, or scale / SI value for
``reciprocal`` (a reset time written for an integral rate); ``per_torque_constant`` where the
drive holds the value in current rather than torque (device value = scale × SI value / kt, kt the
axis's torque constant [Nm/A]: :meth:`Profile.bind`); and optionally the
drive's range in SI (``min``, ``max``), and the ``source`` of its scale and unit (a document
and section; ``source`` at the top covers every entry).  A scale without a source is
unverified: shown as such in every write output, and written to a drive only with
``--allow-unverified-scales``.  A parameter a
drive has no object for is simply absent: the writer reports it as not
supported.  The ``controller`` section declares the structure and loop rates the drive runs
(:mod:`.controller`).  ``select`` names an object that must hold ``value`` for the profile's gain
objects to run (Nanotec's 3212h:04): every set of gains written sets it (the parameter
``gain_objects``), and a drive not on them is read through the profile ``otherwise`` names.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Protocol

import canopen
import numpy as np
from canopen.objectdictionary import datatypes

from ..cia.od import load_od
from ..errors import ConfigError, UserError
from ..resources import data, shipped, vendor_dir
from ..yamlconf import Section, load_yaml
from .controller import PID, Controller, load_controller


class MotorAxis(Protocol):
    """What :meth:`Profile.for_axis` reads of an axis (a brought-up one is
    :class:`~drive_bridge.master.bringup.AxisLink`)."""

    @property
    def name(self) -> str:
        """The axis."""
        ...

    @property
    def torque_constant(self) -> float | None:
        """Its motor's torque constant [Nm/A] (None: not given)."""


PROFILE_DIR = shipped("params", "profiles")
DEFAULT_PROFILE = "drive_bridge_servo"
PARAMETERS = (
    "J",
    "c0",
    "c1",
    "offset",
    "cp",
    "dc0",
    "dc1",
    "periodic_amplitude",
    "periodic_period",
    "periodic_phase",
    "ff_enable",
    "KpP",
    "FwF",
    "KpS",
    "KiS",
    "KpC",
    "KiC",
    *PID,
    "gain_objects",
)
SELECT = "gain_objects"  # the parameter of a profile's select object
TYPES = {
    name: getattr(datatypes, name)
    for name in (
        "UNSIGNED8",
        "UNSIGNED16",
        "UNSIGNED32",
        "INTEGER8",
        "INTEGER16",
        "INTEGER32",
        "REAL32",
        "REAL64",
    )
}


@dataclass(frozen=True)
class Entry:
    """Where one abstract parameter lives on the drive, and its scaling.

    Parameters
    ----------
    parameter : str
        The abstract parameter (J, c0, KpS, ...).
    index, sub : int
        Its object on the drive.
    type : str
        The object's data type (``INTEGER32``, ``REAL32``, ...).
    scale : float
        Device value = scale × SI value (or scale / SI value, ``reciprocal``).
    reciprocal : bool
        The drive holds the inverse (a reset time written for an integral rate).
    unit : str
        The parameter's SI unit (and, where it differs, what the bus carries).
    min, max : float, optional
        The drive's range [SI], where the profile states it.
    source : str, optional
        The document (and section) the scale and unit come from; None: unverified.
    per_torque_constant : bool
        Held in current: the scale is per kt until :meth:`Profile.bind` divides it out.
    """

    parameter: str
    index: int
    sub: int
    type: str
    scale: float
    reciprocal: bool
    unit: str
    min: float | None = None  # the drive's range [SI], where the profile states it
    max: float | None = None
    source: str | None = None  # the document (and section) the scale and unit come from
    per_torque_constant: bool = False  # held in current: scale / kt (bound by Profile.bind)

    @property
    def verified(self) -> bool:
        """The scale has a documented source; without one it is this project's reading only."""
        return self.source is not None

    @property
    def is_integer(self) -> bool:
        """The object holds an integer (any type but REAL32/REAL64)."""
        return not self.type.startswith("REAL")

    def to_device(self, value: float) -> int | float:
        """An SI value in the object's units.

        Parameters
        ----------
        value : float
            The value, SI.

        Returns
        -------
        int or float
            The device value: rounded for an integer object; infinite for a reciprocal of 0.
        """
        raw = (self.scale / value if value else float("inf")) if self.reciprocal else value * self.scale
        return round(raw) if self.is_integer else float(raw)

    def held(self, device: float) -> int | float:
        """A device value as the drive holds it (what a read-back returns).

        Parameters
        ----------
        device : float
            The device value written.

        Returns
        -------
        int or float
            An integer, or a float rounded to the object's REAL32.
        """
        if self.is_integer:
            return int(device)
        return float(np.float32(device)) if self.type == "REAL32" else float(device)

    def to_si(self, raw: float) -> float:
        """A device value in SI.

        Parameters
        ----------
        raw : float
            The value the object holds.

        Returns
        -------
        float
            The value, SI (infinite for a reciprocal of 0).
        """
        return (self.scale / raw if raw else float("inf")) if self.reciprocal else raw / self.scale

    def where(self) -> str:
        """The object as CANopen writes it.

        Returns
        -------
        str
            ``0xIIII:S``.
        """
        return f"0x{self.index:04X}:{self.sub}"

    @property
    def index_sub(self) -> tuple[int, int]:
        """(index, subindex) of the object."""
        return self.index, self.sub


@dataclass
class Profile:
    """One drive model's objects for the abstract parameters, and their units (see the module).

    Parameters
    ----------
    name : str
        The profile's name (its file's stem).
    path : Path
        The profile's YAML file.
    drive : str
        The drive model, in words.
    eds : Path
        The drive's EDS/DCF.
    entries : dict of str to Entry
        Per abstract parameter (J, c0, KpS, ...): its object, data type and scaling.
    save : (int, int) or None
        The store-parameters object (index, subindex); None: the drive cannot store.
    motor : dict of str to (int, int), optional
        Where the drive reports its motor's R [Ω] and L [H] (index, subindex).
    controller : Controller
        The structure and loop rates the drive runs (:mod:`.controller`).
    select : (Entry, int, Profile or None), optional
        The object that must hold a value for the profile's gain objects to run, that value, and
        the profile that runs otherwise.
    setpoint_timeout : (float, str), optional
        How long the drive follows without a new setpoint before it stops on its own, in
        interpolation periods (0x60C2), and the source that says so (None: not documented).
    """

    name: str
    path: Path
    drive: str
    eds: Path
    entries: dict[str, Entry]
    save: tuple[int, int] | None
    motor: dict[str, tuple[int, int]] | None = None
    controller: Controller = Controller()
    select: tuple[Entry, int, Profile | None] | None = None
    setpoint_timeout: tuple[float, str] | None = None

    def object_dictionary(self, node_id: int) -> canopen.ObjectDictionary:
        """The drive's object dictionary from its EDS/DCF.

        Parameters
        ----------
        node_id : int
            The node id its ``$NODEID`` entries resolve to.

        Returns
        -------
        canopen.ObjectDictionary
            The drive's objects.
        """
        return load_od(self.eds, node_id)

    def for_axis(self, ax: MotorAxis) -> Profile:
        """:meth:`bind` for an axis, with its motor's torque constant.

        Parameters
        ----------
        ax : MotorAxis
            The axis (its name and torque constant [Nm/A]).

        Returns
        -------
        Profile
            The profile bound to that motor.
        """
        return self.bind(ax.torque_constant, ax.name)

    def bind(self, torque_constant: float | None, axis: str = "") -> Profile:
        """This profile for one axis: the entries the drive holds in current get their scale per Nm
        (the profile that runs otherwise too).

        Parameters
        ----------
        torque_constant : float or None
            The axis motor's torque constant [Nm/A].
        axis : str
            The axis, for the error's words.

        Returns
        -------
        Profile
            A copy whose entries are all in SI torque units.

        Raises
        ------
        UserError
            An entry needs the torque constant and it is not given.
        """
        select = self.select
        if select is not None and select[2] is not None:
            select = (select[0], select[1], select[2].bind(torque_constant, axis))
        current = [e for e in self.entries.values() if e.per_torque_constant]
        if not current:
            return replace(self, select=select)
        if not torque_constant or not torque_constant > 0:
            raise UserError(
                f"{'axis ' + axis + ': ' if axis else ''}the {self.drive} holds "
                f"{', '.join(e.parameter for e in current)} in current: give the motor's torque "
                f"constant (scaling.torque_constant_Nm_per_A in the bus configuration)"
            )
        return replace(
            self,
            select=select,
            entries={
                k: replace(e, scale=e.scale / torque_constant, per_torque_constant=False)
                if e.per_torque_constant
                else e
                for k, e in self.entries.items()
            },
        )

    def otherwise(self) -> Profile | None:
        """The profile whose objects run while the select object does not select this one's.

        Returns
        -------
        Profile or None
            That profile (bound to the same motor); None where the profile has no select object.
        """
        return None if self.select is None else self.select[2]

    def drive_values(self, values: dict[str, float]) -> dict[str, float]:
        """A parameter set in the cascade's terms (tune's) as this drive holds it.

        Parameters
        ----------
        values : dict of str to float
            The set in the cascade's terms, SI.

        Returns
        -------
        dict of str to float
            Its controller's parameters (:meth:`.controller.Controller.to_drive`) and the select
            object (:meth:`with_select`).

        Raises
        ------
        UserError
            A set the drive cannot hold.
        """
        return self.with_select(self.controller.to_drive(values))

    def with_select(self, values: dict[str, float]) -> dict[str, float]:
        """A drive's parameter set with the select object set where it writes a gain object of this
        profile; a set that names ``gain_objects`` itself keeps its value.

        Parameters
        ----------
        values : dict of str to float
            The drive's parameter set.

        Returns
        -------
        dict of str to float
            The set, with ``gain_objects`` first where it is needed.

        Raises
        ------
        UserError
            A set that would switch the drive onto the profile's gain objects without all of them
            (the others would run with whatever those objects hold).
        """
        gains = [k for k in self.entries if k != SELECT]
        if self.select is None or SELECT in values or not any(k in gains for k in values):
            return values
        missing = [k for k in gains if k not in values]
        if missing:
            raise UserError(
                f"setting {', '.join(k for k in gains if k in values)} switches the {self.drive} onto "
                f"the profile's gain objects ({self.select[0].where()} = {self.select[1]}): the set "
                f"needs all of them (missing: {', '.join(missing)})"
            )
        return {SELECT: float(self.select[1]), **values}


def available() -> list[str]:
    """The shipped drive profiles.

    Returns
    -------
    list of str
        Their names, sorted.
    """
    return sorted(p.stem for p in PROFILE_DIR.glob("*.yaml"))


def load_profile(name_or_path: str | Path) -> Profile:
    """A shipped profile by name or a profile YAML file, checked against its EDS.

    Parameters
    ----------
    name_or_path : str or Path
        A shipped profile's name (see :func:`available`) or a profile YAML file.

    Returns
    -------
    Profile
        The profile, every object present in its EDS, of the declared type, writable.

    Raises
    ------
    ConfigError
        No such profile, or a key that does not hold, named with its file.
    """
    path = Path(name_or_path)
    if not path.suffix:
        path = PROFILE_DIR / f"{name_or_path}.yaml"
        if not path.exists():
            raise ConfigError(name_or_path, "", f"no such drive profile (shipped: {', '.join(available())})")
    top = Section(path, "", load_yaml(path))
    drive = top.get("drive", str)
    source = top.get("source", str, None)  # for every entry that does not name its own
    eds_ref = top.get("eds", str)
    kind, _, rel = eds_ref.partition("/")
    if kind == "package":
        eds = data(rel)
    elif kind == "vendor":
        eds = vendor_dir() / rel
    else:
        raise top.error(
            "eds", "must start with package/ (shipped in drive_bridge/data) or vendor/ (the vendor folder)"
        )
    if not eds.exists():
        raise top.error(
            "eds",
            f"{eds} not found"
            + (" (set DRIVE_BRIDGE_VENDOR_EDS to the vendor EDS folder)" if kind == "vendor" else ""),
        )
    save_sec = top.section("save", required=False)
    save = None
    if save_sec.keys():
        save = (save_sec.get("index", int), save_sec.get("sub", int))
    save_sec.done()
    motor_sec = top.section("motor", required=False)
    motor = None
    if motor_sec.keys():
        motor = {}
        for key in ("R", "L"):
            ms = motor_sec.section(key)
            motor[key] = (ms.get("index", int, low=0, high=0xFFFF), ms.get("sub", int, 0, low=0, high=255))
            ms.done()
    motor_sec.done()
    controller = load_controller(top.section("controller", required=False))
    setpoint_timeout = _setpoint_timeout(top.section("supervision", required=False))
    od = load_od(eds, 1)
    select_sec = top.section("select", required=False)
    select = None
    if select_sec.keys():
        index, sub = (
            select_sec.get("index", int, low=0, high=0xFFFF),
            select_sec.get("sub", int, 0, low=0, high=255),
        )
        value, otherwise = select_sec.get("value", int), select_sec.get("otherwise", str, None)
        var = od.get_variable(index, sub)
        if var is None:
            raise select_sec.error("index", f"{eds.name} has no object 0x{index:04X}:{sub}")
        type_name = next(
            (n for n, t in TYPES.items() if t == var.data_type and not n.startswith("REAL")), None
        )
        if type_name is None or "w" not in var.access_type:
            raise select_sec.error(
                "index", f"{eds.name}: 0x{index:04X}:{sub} is not a writable integer object"
            )
        select = (
            Entry(
                SELECT,
                index,
                sub,
                type_name,
                1.0,
                False,
                "1: the profile's gain objects run",
                source=select_sec.get("source", str, None),
            ),
            value,
            None if otherwise is None else load_profile(otherwise),
        )
    select_sec.done()
    params = top.section("parameters")
    entries = {}
    for name in params.keys():
        if name not in PARAMETERS:
            raise params.error(name, f"unknown parameter (known: {', '.join(PARAMETERS)})")
        sec = params.section(name)
        entry = Entry(
            name,
            sec.get("index", int),
            sec.get("sub", int, 0),
            sec.get("type", str),
            sec.get("scale", float, 1.0),
            sec.get("reciprocal", bool, False),
            sec.get("unit", str, ""),
            sec.get("min", float, None),
            sec.get("max", float, None),
            sec.get("source", (str, type(None)), source),
            sec.get("per_torque_constant", bool, False),
        )
        if entry.min is not None and entry.max is not None and entry.min > entry.max:
            raise params.error(f"{name}.min", f"min {entry.min} is above max {entry.max}")
        if entry.reciprocal and entry.per_torque_constant:  # bind scales by 1/kt: right for scale × SI only
            raise params.error(
                f"{name}.per_torque_constant", "a reciprocal value (a reset time) holds no current"
            )
        sec.done()
        if entry.type not in TYPES:
            raise params.error(
                f"{name}.type", f"unknown data type {entry.type!r} (known: {', '.join(TYPES)})"
            )
        var = od.get_variable(entry.index, entry.sub)
        if var is None:
            raise params.error(name, f"{eds.name} has no object {entry.where()}")
        if var.data_type != TYPES[entry.type]:
            raise params.error(
                f"{name}.type",
                f"{eds.name} declares {entry.where()} as data type 0x{var.data_type:04X}, not {entry.type}",
            )
        if "w" not in var.access_type:
            raise params.error(name, f"{eds.name}: {entry.where()} is not writable ({var.access_type})")
        entries[name] = entry
    params.done()
    if save is not None and save[0] not in od:
        raise top.error("save", f"{eds.name} has no object 0x{save[0]:04X}")
    top.done()
    if motor is not None:
        for key, (index, sub) in motor.items():
            if od.get_variable(index, sub) is None:
                raise top.error(f"motor.{key}", f"{eds.name} has no object 0x{index:04X}:{sub}")
    if select is not None:
        entries[SELECT] = select[0]
    return Profile(path.stem, path, drive, eds, entries, save, motor, controller, select, setpoint_timeout)


def _setpoint_timeout(sec: Section) -> tuple[float, str] | None:
    """``supervision``: the drive's setpoint-loss timeout [interpolation periods] and its source."""
    if not sec.keys():
        return None
    out = (sec.get("setpoint_timeout_periods", float, low=1.0, high=1e6), sec.get("source", str))
    sec.done()
    return out


@functools.cache
def _shipped_setpoint_timeouts() -> dict[str, tuple[str, float, str]]:
    """EDS file name -> (profile, setpoint-loss timeout [periods], source), of every shipped profile
    that names one (read from the YAML alone: no EDS needed)."""
    out = {}
    for name in available():
        doc = load_yaml(PROFILE_DIR / f"{name}.yaml")
        sup = doc.get("supervision") if isinstance(doc, dict) else None
        if isinstance(sup, dict) and "setpoint_timeout_periods" in sup:
            out[Path(str(doc["eds"])).name] = (
                name,
                float(sup["setpoint_timeout_periods"]),
                str(sup.get("source", "")),
            )
    return out


def setpoint_timeout_for(dcfs: list[Path], period: float) -> tuple[float | None, str]:
    """How long the drives follow without a new setpoint before they stop on their own.

    Parameters
    ----------
    dcfs : list of Path
        The drives' EDS/DCF files.
    period : float
        The interpolation period [s].

    Returns
    -------
    timeout : float or None
        [s] the shortest a shipped profile for one of those files names; None where none names one.
    source : str
        Where it comes from ("" where none names one).
    """
    known = [_shipped_setpoint_timeouts().get(Path(d).name) for d in dcfs]
    found = [
        (periods * period, f"drive profile {name}: {periods:g} interpolation periods ({source})")
        for name, periods, source in (k for k in known if k is not None)
    ]
    return min(found) if found else (None, "")
