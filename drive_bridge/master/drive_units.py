"""Units from the drive: what a drive says about its units, read at bring-up and reconciled with
bus.yml's ``scaling`` before anything else is written or moved.

Read where the drive's EDS/DCF has the objects: the factor group (0x608F encoder, 0x6091 gear,
0x6092 feed, 0x60A8 / 0x60A9 SI units; :mod:`drive_bridge.cia.factor`), the rated torque 0x6076
[mNm], the rated current 0x6075 [mA] and the max torque 0x6072 [per mille of rated torque].
Where the drive says something bus.yml contradicts, bring-up refuses, naming both values and the
two ways out; with ``scaling: from_drive`` the drive's units are taken.  What the drive does not
report stays bus.yml's assumption and is said so (bring-up output, bringup.json, meta.yaml).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, replace
from typing import Any

import canopen

from ..cia.factor import FactorGroup, describe
from ..cia.objects import MAX_TORQUE, MOTOR_RATED_CURRENT, MOTOR_RATED_TORQUE
from ..cia.sdo import read_if_readable
from ..config import NodeConfig
from ..errors import DriveRefused

REL_TOLERANCE = 1e-6  # units agree when they differ by less than this, relatively
TORQUE_TOLERANCE = 1e-3  # rated torque / current: the drive reports mNm / mA


@dataclass
class DriveUnits:
    """What one drive reported (None: it has no such object or did not answer).

    Parameters
    ----------
    group : FactorGroup
        Its factor group.
    rated_torque_Nm : float, optional
        0x6076 [Nm].
    rated_current_A : float, optional
        0x6075 [A].
    max_torque_permille : int, optional
        0x6072 [per mille of the rated torque].
    assumed : list of str
        What bus.yml assumed because the drive does not say it.
    """

    group: FactorGroup
    rated_torque_Nm: float | None = None
    rated_current_A: float | None = None
    max_torque_permille: int | None = None
    assumed: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        """bringup.json / meta.yaml: what the drive said, in its units and per SI unit.

        Returns
        -------
        dict
            Units in words and per SI unit, the factor group, rated torque and current, max torque, what
            was assumed.
        """
        g = self.group
        return {
            "position_unit": None if g.position_unit is None else describe(g.position_unit),
            "velocity_unit": None if g.velocity_unit is None else describe(g.velocity_unit, velocity=True),
            "position_per_rad": g.position_per_rad,
            "velocity_per_rad_s": g.velocity_per_rad_s,
            "encoder": None if g.encoder is None else list(g.encoder),
            "gear": None if g.gear is None else list(g.gear),
            "feed": None if g.feed is None else list(g.feed),
            "rated_torque_Nm": self.rated_torque_Nm,
            "rated_current_A": self.rated_current_A,
            "max_torque_permille": self.max_torque_permille,
            "assumed_from_bus_yml": self.assumed,
        }


def read_units(
    node: canopen.RemoteNode, axis: str, planned: dict[tuple[int, int], Any] | None = None
) -> DriveUnits:
    """Read every unit object the drive's EDS/DCF has (an object the drive refuses to read counts as
    absent); ``planned`` ((index, sub) -> value) stands for values about to be written.

    Parameters
    ----------
    node : canopen.RemoteNode
        The drive.
    axis : str
        Its axis, for the errors.
    planned : dict of (int, int) to object, optional
        Values about to be written.

    Returns
    -------
    DriveUnits
        What it reported.

    Raises
    ------
    BusError
        The drive does not answer.
    """

    def value(index: int, sub: int) -> Any:
        if (
            planned
            and (index, sub) in planned
            and node.object_dictionary.get_variable(index, sub) is not None
        ):
            return planned[(index, sub)]
        return read_if_readable(node, index, sub, f"axis {axis}'s units")

    group = FactorGroup.read(value)
    torque, current, max_torque = (
        value(MOTOR_RATED_TORQUE, 0),
        value(MOTOR_RATED_CURRENT, 0),
        value(MAX_TORQUE, 0),
    )
    return DriveUnits(
        group, torque / 1000.0 if torque else None, current / 1000.0 if current else None, max_torque
    )


def reconcile(ncfg: NodeConfig, units: DriveUnits, path: str | os.PathLike[str]) -> NodeConfig:
    """The node's configuration with the units the drive works in.

    With ``from_drive`` the drive's units replace what bus.yml leaves open; otherwise every unit the
    drive reports must agree with bus.yml, else DriveRefused (nothing of the node's limits, PDOs or
    motion has been written yet); a rated torque bus.yml does not give is the drive's 0x6076.

    Parameters
    ----------
    ncfg : NodeConfig
        The node's configuration.
    units : DriveUnits
        What the drive reported.
    path : str or os.PathLike
        bus.yml, for the errors.

    Returns
    -------
    NodeConfig
        The configuration in the drive's units.

    Raises
    ------
    DriveRefused
        A unit the drive reports that bus.yml contradicts.
    """
    axis, sc = ncfg.axis, ncfg.scaling
    pos, vel = units.group.position_per_rad, units.group.velocity_per_rad_s
    if ncfg.units_from_drive:
        missing = [
            what
            for what, v in (
                ("position units (0x60A8 with 0x608F, 0x6091, 0x6092)", pos),
                ("velocity units (0x60A9)", vel),
            )
            if v is None
        ]
        rated = sc.rated_torque_Nm or units.rated_torque_Nm
        if not rated:
            missing.append("rated torque (0x6076)")
        if missing or pos is None or vel is None or not rated:
            raise DriveRefused(
                f"axis {axis}: nodes.{axis}.scaling in {path} takes the units from the drive, "
                f"but the drive does not report its {', '.join(missing)}; give them in "
                f"nodes.{axis}.scaling (increments_per_rev, velocity_unit, rated_torque_Nm)"
            )
        sc = replace(
            sc, increments_per_rev=pos * 2 * math.pi, velocity_units_per_rad_s=vel, rated_torque_Nm=rated
        )
        units.assumed = [] if units.rated_torque_Nm is not None else [f"rated torque {sc.rated_torque_Nm} Nm"]
        return replace(ncfg, scaling=sc)
    problems, assumed = [], []
    if not sc.rated_torque_Nm:  # bus.yml gives none (a ros2_canopen bus.yml): the drive's own
        if units.rated_torque_Nm is None:
            raise DriveRefused(
                f"axis {axis}: nodes.{axis} in {path} gives no rated torque and the drive does not "
                f"report its 0x6076: give nodes.{axis}.scaling.rated_torque_Nm"
            )
        sc = replace(sc, rated_torque_Nm=units.rated_torque_Nm)
        ncfg = replace(ncfg, scaling=sc)
    if pos is None:
        assumed.append(
            f"position {sc.increments_per_rev} units per motor revolution (the drive does not report "
            f"its position unit)"
        )
    elif not _agree(pos, sc.inc_per_rad):
        problems.append(
            f"positions in {describe(units.group.position_unit)}, {pos:.6g} per rad, where bus.yml "
            f"gives increments_per_rev {sc.increments_per_rev} ({sc.inc_per_rad:.6g} per rad): "
            f"it would move {sc.inc_per_rad / pos:.3g}× the planned stroke"
        )
    if vel is None:
        assumed.append(f"velocity in {sc.velocity_unit} (the drive does not report its velocity unit)")
    elif not _agree(vel, sc.velocity_per_rad_s):
        problems.append(
            f"velocities in {describe(units.group.velocity_unit, velocity=True)}, {vel:.6g} per rad/s, "
            f"where bus.yml gives {sc.velocity_per_rad_s:.6g} per rad/s ({sc.velocity_unit})"
        )
    if units.rated_torque_Nm is None:
        assumed.append(f"rated torque {sc.rated_torque_Nm} Nm (the drive does not report 0x6076)")
    elif abs(units.rated_torque_Nm - sc.rated_torque_Nm) > TORQUE_TOLERANCE * sc.rated_torque_Nm:
        problems.append(
            f"rated torque 0x6076 = {units.rated_torque_Nm:g} Nm where bus.yml gives "
            f"rated_torque_Nm {sc.rated_torque_Nm:g}"
        )
    per_unit = sc.current_per_unit_A
    rated_A = units.rated_current_A
    if (
        sc.torque_feedback == "current"
        and per_unit is not None
        and per_unit != 1e-3
        and rated_A is not None
        and abs(rated_A - per_unit * 1000) > TORQUE_TOLERANCE * rated_A
    ):
        problems.append(
            f"rated current 0x6075 = {rated_A:g} A where bus.yml gives rated_current_A {per_unit * 1000:g}"
        )
    if problems:
        raise DriveRefused(
            f"axis {axis} (node {ncfg.node_id}): the drive reports {'; '.join(problems)}. Nothing of its limits, "
            f"PDOs or motion was written. Either take the drive's units (nodes.{axis}.scaling: {{from_drive: true}} "
            f"in {path}), or have bring-up set the units bus.yml assumes: list the factor group's values in "
            f"nodes.{axis}.sdo (e.g. {{index: 0x60A8, value: 0x00B50000}} for encoder increments, {{index: 0x60A9, "
            f"value: 0x00B50300}} for increments per second); they are written first and read back"
        )
    units.assumed = assumed
    return ncfg


def _agree(a: float, b: float) -> bool:
    return abs(a - b) <= REL_TOLERANCE * max(abs(a), abs(b))
