"""The motion a simulated drive makes itself (CiA 402), one interpolation period at a time: the
quick stop's ramp, halt, profile velocity (mode 3), profile position (mode 1) and the homing
mode's search (:mod:`.home_search`), and the statusword bits that watch it over their windows and
window times -- bit 10 target reached, bit 12 set-point acknowledged (profile position) or speed
= 0 (profile velocity)."""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from ..cia.objects import (
    POSITION_WINDOW,
    POSITION_WINDOW_TIME,
    PROFILE_ACCELERATION,
    PROFILE_DECELERATION,
    PROFILE_VELOCITY,
    QUICK_STOP_DECELERATION,
    QUICK_STOP_OPTION,
    TARGET_POSITION,
    TARGET_VELOCITY,
    VELOCITY_THRESHOLD,
    VELOCITY_THRESHOLD_TIME,
    VELOCITY_WINDOW,
    VELOCITY_WINDOW_TIME,
)
from ..cia.p402 import CW_HALT_BIT, ENABLED, HM, PP, PV, QUICK_STOP
from . import kernel
from .home_search import HomeSearch
from .plant import Plant
from .robot_config import SimAxis
from .storage import ObjectStorage
from .vendors import factory

#: profile velocity's windows where the drive has no object for them (0x606D velocity window,
#: 0x606F velocity threshold, "speed = 0"), about 5 rpm [rad/s]; their times 0x606E / 0x6070 [ms]
VELOCITY_WINDOW_RAD_S = 0.5


class Dwell:
    """A condition that counts once it has held for a time: CiA 402's windows and their window times
    (position window 0x6067 for 0x6068, velocity window 0x606D for 0x606E, threshold 0x606F for 0x6070)."""

    def __init__(self) -> None:
        self.since: float | None = None

    def restart(self) -> None:
        """Not inside since any time: the next ``held`` starts the count."""
        self.since = None

    def held(self, inside: bool, now: float, duration: float) -> bool:
        """Whether ``inside`` has been true since at least ``duration`` [s] before ``now`` [s].

        Parameters
        ----------
        inside : bool
            The condition now.
        now : float
            [s].
        duration : float
            [s].

        Returns
        -------
        bool
            Held long enough.
        """
        if not inside:
            self.restart()
            return False
        if self.since is None:
            self.since = now
        return now - self.since >= duration - 1e-9


class ProfileDrive(Protocol):
    """What the profiles need of their drive (:class:`.drive.SimDrive`)."""

    axis: SimAxis
    state: int  # CiA 402 state
    mode: int  # the mode of operation (0x6061)
    controlword: int
    plant: Plant
    plant_state: np.ndarray  # the axis's kernel state row
    plant_demand: np.ndarray  # the axis's demand row
    pos_per_rad: float  # position unit per rad
    vel_per_si: float  # velocity unit per rad/s
    inc_per_rad: float  # encoder increments per rad
    origin_rad: float  # the plant position the drive counts as 0
    v_dem: float  # the demand velocity [rad/s]
    objects: ObjectStorage

    def within_limits(self, position: float) -> float:
        """A position held inside the software position limits.

        Parameters
        ----------
        position : float
            [rad, plant].

        Returns
        -------
        float
            The position within the limits.
        """
        ...


class ProfileMotion:
    """The profiles of ``drive``: the profile position move under way (``target``, and the ``goal``
    of the last set-point accepted), whether the set-point was ``acknowledged``, whether the target
    is ``reached``, and the homing search (``homing``).

    Parameters
    ----------
    drive : ProfileDrive
        The drive.
    """

    def __init__(self, drive: ProfileDrive):
        self.drive = drive
        self.target: float | None = None  # PP: the demand is still travelling to it [rad, plant]
        self.goal: float | None = None  # PP: the target of the last set-point accepted [rad, plant]
        self.acknowledged = False  # PP: statusword bit 12
        self.reached = False  # statusword bit 10
        self.homing = HomeSearch(drive, self.ramp)  # HM: the search for home
        # bit 10 of profile position / velocity, bit 12 of profile velocity (speed = 0)
        self.position_window, self.velocity_window, self.threshold = Dwell(), Dwell(), Dwell()

    @property
    def halted(self) -> bool:
        """Controlword bit 8 (halt) in a mode whose profile the drive makes itself."""
        return bool(self.drive.controlword & CW_HALT_BIT) and self.drive.mode in (PV, PP, HM)

    def deceleration(self) -> float:
        """The profile deceleration 0x6084 [rad/s²] (the acceleration 0x6083 where it has none).

        Returns
        -------
        float
            [rad/s²].
        """
        objects = self.drive.objects
        return (
            objects.get_or(PROFILE_DECELERATION, 0, objects.get(PROFILE_ACCELERATION)) / self.drive.vel_per_si
        )

    def ramp(self, v_target: float, accel: float, T: float, limit: bool = True) -> None:
        """Move the demand velocity toward ``v_target`` at ``accel`` and integrate P1 (inside the
        software position limits unless ``limit`` is False).

        Parameters
        ----------
        v_target : float
            [rad/s].
        accel : float
            [rad/s²].
        T : float
            The period [s].
        limit : bool
            Held inside the software position limits.
        """
        drive = self.drive
        step = accel * T
        v_new = (
            v_target
            if abs(v_target - drive.v_dem) <= step
            else drive.v_dem + math.copysign(step, v_target - drive.v_dem)
        )
        p1 = drive.plant_demand[kernel.P0] + 0.5 * (drive.v_dem + v_new) * T
        drive.plant_demand[kernel.P1] = drive.within_limits(p1) if limit else p1
        drive.v_dem = v_new

    def period(self, T: float) -> bool:
        """The demand of the period of ``T`` [s] that starts now; True where a quick stop came to
        rest with an option code 0x605A that then disables the drive.

        Parameters
        ----------
        T : float
            The period [s].

        Returns
        -------
        bool
            A quick stop came to rest and disables the drive.
        """
        drive, objects, d = self.drive, self.drive.objects, self.drive.plant_demand
        state, mode, per_si = drive.state, drive.mode, drive.vel_per_si
        if state == QUICK_STOP:
            self.ramp(
                0.0,
                objects.get_or(QUICK_STOP_DECELERATION, 0, factory().quick_stop_rad_s2 * per_si) / per_si,
                T,
            )
            return drive.v_dem == 0.0 and objects.get_or(QUICK_STOP_OPTION, 0, 2) in (0, 1, 2, 3)
        if state == ENABLED and mode in (PV, PP) and self.halted:
            self.ramp(0.0, self.deceleration(), T)  # halt (0x605D 1): down on the profile deceleration
        elif state == ENABLED and mode == PV:
            self.ramp(objects.get(TARGET_VELOCITY) / per_si, objects.get(PROFILE_ACCELERATION) / per_si, T)
        elif state == ENABLED and mode == PP and self.target is not None:
            dist = self.target - d[kernel.P0]
            acc, dec = objects.get(PROFILE_ACCELERATION) / per_si, self.deceleration()
            v_max = min(
                objects.get_or(PROFILE_VELOCITY, 0, factory().profile_velocity_rad_s * per_si) / per_si,
                math.sqrt(2 * dec * abs(dist)),
            )
            self.ramp(math.copysign(v_max, dist), acc, T)
            if abs(dist) <= abs(drive.v_dem) * T or abs(dist) < 1.0 / drive.inc_per_rad:
                d[kernel.P1] = self.target
                drive.v_dem = 0.0
                self.target = None  # the demand is there; the axis is when it settles
        elif state == ENABLED and mode == HM and self.homing.phase:
            self.homing.period(T)
        else:
            drive.v_dem = 0.0
        return False

    def new_setpoint(self, controlword: int) -> None:
        """Profile position: a new set-point (bit 4 up) taken -- the target 0x607A, absolute or
        relative (bit 6) -- and acknowledged.

        Parameters
        ----------
        controlword : int
            0x6040's value.
        """
        drive = self.drive
        target = drive.objects.get(TARGET_POSITION) / drive.pos_per_rad
        self.target = (
            target + drive.origin_rad if not controlword & 0x40 else drive.plant_demand[kernel.P1] + target
        )
        self.goal = self.target
        self.acknowledged = True
        self.reached = False
        self.position_window.restart()

    def hold(self) -> None:
        """Held where it stands: no move, no search under way."""
        self.target = self.goal = None
        self.homing.phase = None

    def speed_zero(self) -> bool:
        """The speed inside the velocity threshold 0x606F for the threshold time 0x6070.

        Returns
        -------
        bool
            Held long enough.
        """
        drive = self.drive
        return self.threshold.held(
            abs(drive.plant_state.item(kernel.VMEAS)) <= self._velocity_window(VELOCITY_THRESHOLD),
            drive.plant.time,
            drive.objects.get_or(VELOCITY_THRESHOLD_TIME, 0, 0) / 1000.0,
        )

    def _velocity_window(self, index: int) -> float:
        """0x606D (velocity window) or 0x606F (velocity threshold) [rad/s], where the drive has none
        ``VELOCITY_WINDOW_RAD_S``."""
        per_si = self.drive.vel_per_si
        return self.drive.objects.get_or(index, 0, VELOCITY_WINDOW_RAD_S * per_si) / per_si

    def update_reached(self) -> None:
        """Bits 10 and 12 as the axis moves, each over its window and window time: speed = 0 inside
        the velocity threshold 0x606F for 0x6070; quick stop and halt reached once the demand is 0 and
        the axis stands; profile velocity reached with the demand at 0x60FF and the speed inside the
        velocity window 0x606D for 0x606E; profile position reached once the demand is at the target
        and the axis has stood inside the position window 0x6067 for 0x6068."""
        drive, objects = self.drive, self.drive.objects
        if drive.state != QUICK_STOP and drive.mode not in (PV, PP, HM):
            return  # (CSP and IP: bit 10 is not theirs)
        now, speed = drive.plant.time, drive.plant_state.item(kernel.VMEAS)
        if drive.state == QUICK_STOP or self.halted:
            self.reached = drive.v_dem == 0.0 and self.speed_zero()
        elif drive.mode == PV:
            target = objects.get(TARGET_VELOCITY) / drive.vel_per_si
            inside = drive.v_dem == target and abs(speed - target) <= self._velocity_window(VELOCITY_WINDOW)
            self.reached = self.velocity_window.held(
                inside, now, objects.get_or(VELOCITY_WINDOW_TIME, 0, 0) / 1000.0
            )
        elif drive.mode == PP and self.target is None and self.goal is not None:
            inside = abs(drive.plant_state[kernel.ENC] - self.goal) * drive.pos_per_rad <= objects.get_or(
                POSITION_WINDOW, 0, 1000
            )
            self.reached = self.position_window.held(
                inside, now, objects.get_or(POSITION_WINDOW_TIME, 0, 10) / 1000.0
            )
