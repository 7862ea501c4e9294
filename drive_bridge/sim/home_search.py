"""The homing mode (CiA 402 mode 6) of a simulated drive: the methods it has, and the search for
home one interpolation period at a time.

Methods (0x6098): 17/18 search the negative/positive limit switch (set ``LIMIT_SWITCH_INSET_RAD``
inside the axis's mechanical end stops, motor side) at the switch speed 0x6099:1 and leave it at
the zero speed 0x6099:2, the switch's edge being home (the drive counts the home offset 0x607C
there); 35/37 take the position where the axis stands as home.  The homing acceleration is
0x609A.  The software position limits do not apply before home is known.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy as np

from ..cia.objects import HOME_OFFSET, HOMING_ACCELERATION, HOMING_METHOD, HOMING_SPEEDS
from . import kernel
from .robot_config import SimAxis
from .storage import ObjectStorage

HOMING_SWITCH = {17: -1, 18: 1}  # method -> the direction of its limit switch
HOMING_HERE = (35, 37)
LIMIT_SWITCH_INSET_RAD = 0.5


class HomingDrive(Protocol):
    """What the search needs of its drive (:class:`.drive.SimDrive`)."""

    axis: SimAxis
    plant_state: np.ndarray  # the axis's kernel state row
    pos_per_rad: float  # position unit per rad
    vel_per_si: float  # velocity unit per rad/s
    origin_rad: float  # the plant position the drive counts as 0
    v_dem: float  # the demand velocity [rad/s]
    objects: ObjectStorage  # its objects (the homing method, offset, speeds and acceleration)


class HomeSearch:
    """The homing of ``drive``: ``phase`` of a search under way ("switch", "leave", "stop"; None:
    none), and whether home was ``attained`` or the method ended in an ``error`` (statusword bits 12
    and 13 in homing mode).  ``ramp(v_target [rad/s], accel [rad/s²], period [s], limit=False)``
    moves the demand as the drive's profiles do (:meth:`.profile_motion.ProfileMotion.ramp`).

    Parameters
    ----------
    drive : HomingDrive
        The drive.
    ramp : callable
        Moves the demand.
    """

    def __init__(self, drive: HomingDrive, ramp: Callable[..., None]):
        self.drive = drive
        self._ramp = ramp
        self.phase: str | None = None
        self.attained = self.error = False

    def start(self) -> None:
        """Bit 4 up in homing mode: the method 0x6098 says how home is found."""
        drive = self.drive
        method = drive.objects.get_or(HOMING_METHOD, 0, 0)
        self.attained = self.error = False
        if method in HOMING_HERE:
            drive.origin_rad = (
                drive.plant_state[kernel.ENC] - drive.objects.get_or(HOME_OFFSET, 0, 0) / drive.pos_per_rad
            )
            self.attained = True
        elif method in HOMING_SWITCH:
            self.phase = "switch"
        else:
            self.error = True  # a method this drive does not have

    def interrupt(self) -> None:
        """Bit 4 down: a search under way ramps to rest."""
        if self.phase in ("switch", "leave"):
            self.phase = "stop"

    def period(self, period_s: float) -> None:
        """One period [s] of a homing on a limit switch: toward it, off it (its edge is home), then
        to rest.

        Parameters
        ----------
        period_s : float
            [s].
        """
        drive = self.drive
        direction = HOMING_SWITCH.get(drive.objects.get_or(HOMING_METHOD, 0, 0), -1)
        accel = drive.objects.get_or(HOMING_ACCELERATION, 0, 0) / drive.vel_per_si
        if self.phase == "switch":
            self._ramp(
                direction * drive.objects.get_or(HOMING_SPEEDS, 1, 0) / drive.vel_per_si,
                accel,
                period_s,
                limit=False,
            )
            if self._on_switch(direction):
                self.phase = "leave"
        elif self.phase == "leave":
            self._ramp(
                -direction * drive.objects.get_or(HOMING_SPEEDS, 2, 0) / drive.vel_per_si,
                accel,
                period_s,
                limit=False,
            )
            if not self._on_switch(direction):
                edge = self._switch_edge(direction)
                assert edge is not None  # the switch was made: the axis has end stops
                drive.origin_rad = edge - drive.objects.get_or(HOME_OFFSET, 0, 0) / drive.pos_per_rad
                self.phase = "stop"
                self.attained = True
        else:
            self._ramp(0.0, accel, period_s, limit=False)
            if drive.v_dem == 0.0:
                self.phase = None  # at rest: statusword bit 10

    def _switch_edge(self, direction: int) -> float | None:
        """Where the limit switch in ``direction`` starts [rad, plant]; None on an axis without end stops."""
        stops = self.drive.axis.end_stops_rad
        if stops is None:
            return None
        return stops[0] + LIMIT_SWITCH_INSET_RAD if direction < 0 else stops[1] - LIMIT_SWITCH_INSET_RAD

    def _on_switch(self, direction: int) -> bool:
        """Whether the limit switch in ``direction`` is made."""
        edge = self._switch_edge(direction)
        position = self.drive.plant_state[kernel.ENC]
        return edge is not None and (position <= edge if direction < 0 else position >= edge)
