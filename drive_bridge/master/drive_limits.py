"""Limits from the drive: where bus.yml gives no ``limits`` (a ros2_canopen bus.yml has none), the
stroke, velocity and acceleration an axis may use are the ones its drive holds, read at bring-up
in the drive's units (known by then) before anything is written or moved.

==========================  =====================================================================
stroke                      software position limits 0x607D:1 / :2 (a drive without them, or
                            with them off -- min >= max, or the type's whole range -- is refused:
                            nothing says how far the axis may travel)
velocity                    max profile velocity 0x607F, else max motor speed 0x6080 [rpm]; the
                            campaign plans within 1/``DRIVE_LIMIT_MARGIN`` of it, as it does within
                            bus.yml's limits, so the drive's own limit stays above every setpoint
acceleration                max acceleration / deceleration 0x60C5 / 0x60C6, else profile
                            acceleration / deceleration 0x6083 / 0x6084 (the smaller of each pair)
quick-stop deceleration     0x6085, else twice the acceleration (a default, said)
==========================  =====================================================================

What bus.yml leaves to a default (the following-error window and timeout, how the axis is held) is
said with its value too. Bring-up writes the same stroke and velocity back, so the drive keeps them.
"""

from __future__ import annotations

import math
import os
from dataclasses import replace

import canopen
from canopen.objectdictionary import datatypes

from ..cia.objects import (
    MAX_ACCELERATION,
    MAX_DECELERATION,
    MAX_MOTOR_SPEED,
    MAX_PROFILE_VELOCITY,
    PROFILE_ACCELERATION,
    PROFILE_DECELERATION,
    QUICK_STOP_DECELERATION,
    SOFTWARE_POSITION_LIMIT,
)
from ..cia.od import variable
from ..cia.sdo import read_if_readable
from ..config import DRIVE_LIMIT_MARGIN, DriveLimits, Limits, NodeConfig
from ..errors import DriveRefused

#: the unsigned value a drive holds for "no limit" (0xFFFFFFFF), and 0 ("not set")
NO_LIMIT = (0, 2**32 - 1)


def read_limits(
    node: canopen.RemoteNode, ncfg: NodeConfig, path: str | os.PathLike[str]
) -> tuple[NodeConfig, list[str]]:
    """``ncfg`` with the limits its drive holds (``ncfg.scaling`` in the drive's units already),
    and what was read and what defaulted, in words with the values; DriveRefused where the drive
    holds no stroke, velocity or acceleration.

    Parameters
    ----------
    node : canopen.RemoteNode
        The drive.
    ncfg : NodeConfig
        The node's configuration.
    path : str or os.PathLike
        bus.yml, for the errors.

    Returns
    -------
    ncfg : NodeConfig
        The configuration with the drive's limits.
    read : list of str
        What was read and what defaulted, with the values.

    Raises
    ------
    DriveRefused
        A drive that holds no stroke, velocity or acceleration.
    """
    axis, sc = ncfg.axis, ncfg.scaling
    per_rad, per_rad_s = sc.inc_per_rad, sc.velocity_per_rad_s

    def read(index: int, sub: int = 0) -> int | None:
        value = read_if_readable(node, index, sub, f"axis {axis}'s limits")
        return None if value is None else int(value)

    def limit(index: int) -> int | None:
        """The limit the drive holds in ``index``; None where it has none (absent, 0, or 0xFFFFFFFF)."""
        value = read(index)
        return None if value in NO_LIMIT else value

    def refused(what: str, objects: str) -> DriveRefused:
        return DriveRefused(
            f"axis {axis}: nodes.{axis} in {path} has no limits, and the drive holds no {what} "
            f"({objects}): give nodes.{axis}.limits (stroke, max velocity, max acceleration), or set "
            f"{objects} in the drive"
        )

    said: list[str] = []
    low, high = read(SOFTWARE_POSITION_LIMIT, 1), read(SOFTWARE_POSITION_LIMIT, 2)
    full = _type_range(ncfg, SOFTWARE_POSITION_LIMIT, 1)
    if low is None or high is None or low >= high or (low, high) == full:
        raise refused("stroke", "software position limits 0x607D")
    stroke = (low / per_rad, high / per_rad)
    said.append(f"stroke {stroke[0]:.6g} .. {stroke[1]:.6g} rad (0x607D)")
    if (velocity := limit(MAX_PROFILE_VELOCITY)) is not None:
        drive_max, source = velocity / per_rad_s, "0x607F"
    elif (rpm := limit(MAX_MOTOR_SPEED)) is not None:
        drive_max, source = rpm * 2 * math.pi / 60.0, "0x6080"
    else:
        raise refused("velocity limit", "max profile velocity 0x607F or max motor speed 0x6080")
    said.append(
        f"max velocity {drive_max / DRIVE_LIMIT_MARGIN:.6g} rad/s (1/{DRIVE_LIMIT_MARGIN:g} of {source})"
    )
    acceleration = None
    for pair in ((MAX_ACCELERATION, MAX_DECELERATION), (PROFILE_ACCELERATION, PROFILE_DECELERATION)):
        values = [v for v in map(limit, pair) if v is not None]
        if values:
            acceleration = min(values) / per_rad_s  # acceleration units: velocity units per s
            said.append(f"max acceleration {acceleration:.6g} rad/s² (0x{pair[0]:04X}/0x{pair[1]:04X})")
            break
    if acceleration is None:
        raise refused("acceleration limit", "0x60C5/0x60C6 or 0x6083/0x6084")
    quick_stop = limit(QUICK_STOP_DECELERATION)
    if quick_stop is None:
        deceleration = 2 * acceleration
        said.append(f"quick-stop deceleration {deceleration:.6g} rad/s² (default: twice the acceleration)")
    else:
        deceleration = quick_stop / per_rad_s
        said.append(f"quick-stop deceleration {deceleration:.6g} rad/s² (0x6085)")
    old = ncfg.drive_limits
    timeout = old.following_error_timeout_ms if old else 10
    holding = old.holding if old else "enabled"
    said.append(
        f"defaults: following-error window {ncfg.following_error_window_rad:g} rad, timeout {timeout} ms, "
        f"holding {holding}"
    )
    limits = Limits(stroke[0], stroke[1], drive_max / DRIVE_LIMIT_MARGIN, acceleration)
    drive_limits = DriveLimits(
        max_velocity=drive_max,
        quick_stop_deceleration=deceleration,
        following_error_timeout_ms=timeout,
        max_torque_Nm=old.max_torque_Nm if old else None,
        holding=holding,
    )
    return replace(ncfg, limits=limits, drive_limits=drive_limits), said


def _type_range(ncfg: NodeConfig, index: int, sub: int) -> tuple[int, int] | None:
    """The whole range of the object's data type (a software limit there limits nothing)."""
    var = ncfg.od.get_variable(index, sub)
    if var is None:
        return None
    bits = len(variable(ncfg.od, index, sub))
    return (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1) if var.data_type in datatypes.SIGNED_TYPES else None
