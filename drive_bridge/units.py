"""The one scaling layer between SI (motor side) and drive device units.

Inside drive-bridge every quantity is SI on the motor side: rad, rad/s,
rad/s², Nm.  Linear axes are described in m, m/s, m/s² (load side) and turned
into motor radians through the feed constant.  Device units exist only at the
bus: positions in encoder increments, velocities in increments/s (or rpm, as maxon's EPOS2
reports them), torque in
per mille of the rated torque (0x6076) -- or, for a drive without a torque
actual value, the current actual value (0x6078: per mille of the rated current
0x6075, or mA) times the motor's torque constant, or a vendor object with its
scale (Nm per unit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
from numpy.typing import ArrayLike

#: a value or the values of a signal (the same kind comes back)
N = TypeVar("N", float, np.ndarray)


@dataclass(frozen=True)
class Scaling:
    """Conversion for one axis: device units at the bus edge, SI motor side inside.

    Parameters
    ----------
    increments_per_rev : float
        Device position units per motor revolution: encoder increments (0x608F), or what the
        drive's own position unit (0x60A8) makes of a revolution.
    rated_torque_Nm : float
        The drive's rated torque [Nm] (0x6076 in mNm / 1000).
    feed_m_per_rev : float, optional
        Load travel per motor revolution [m] (belt pulley or screw lead); None for a rotary axis.
    torque_feedback : {"torque", "current", "object"}
        Where the torque is read: 0x6077; 0x6078 × the torque constant; the vendor object
        ``torque_index`` × ``torque_per_unit_Nm``.
    current_per_unit_A : float, optional
        [A] per unit of 0x6078 (rated current / 1000, or 0.001 for mA).
    torque_constant_Nm_per_A : float, optional
        The motor's torque constant [Nm/A].
    torque_index : int, optional
        The vendor object that carries the torque.
    torque_per_unit_Nm : float, optional
        [Nm] per unit of it.
    velocity_unit : {"inc/s", "rpm"}
        Of 0x606C and the other velocities.
    velocity_units_per_rad_s : float, optional
        Device velocity units per rad/s as the drive reports them (its 0x60A9, with ``scaling:
        from_drive``); None: from ``velocity_unit``.
    """

    increments_per_rev: float
    rated_torque_Nm: float
    feed_m_per_rev: float | None = None
    torque_feedback: str = "torque"
    current_per_unit_A: float | None = None
    torque_constant_Nm_per_A: float | None = None
    torque_index: int | None = None
    torque_per_unit_Nm: float | None = None
    velocity_unit: str = "inc/s"
    velocity_units_per_rad_s: float | None = None

    @property
    def inc_per_rad(self) -> float:
        """Device position units per motor rad (encoder increments, or the drive's position unit)."""
        return self.increments_per_rev / (2 * math.pi)

    @property
    def velocity_per_rad_s(self) -> float:
        """Device velocity units per rad/s."""
        if self.velocity_units_per_rad_s is not None:
            return self.velocity_units_per_rad_s
        return 60.0 / (2 * math.pi) if self.velocity_unit == "rpm" else self.inc_per_rad

    # --- load side (m) <-> motor side (rad) -----------------------------------------
    def load_to_motor(self, value_m: N) -> N:
        """m, m/s or m/s² of a linear axis to rad, rad/s or rad/s² of the motor.

        Parameters
        ----------
        value_m : float or numpy.ndarray
            [m], [m/s] or [m/s²], load side.

        Returns
        -------
        float or numpy.ndarray
            [rad], [rad/s] or [rad/s²], motor side (as it is on a rotary axis).
        """
        if self.feed_m_per_rev is None:
            return value_m
        return value_m * (2 * math.pi / self.feed_m_per_rev)

    # --- SI <-> device --------------------------------------------------------------
    def position_to_device(self, rad: ArrayLike) -> np.ndarray:
        """rad -> increments (rounded to the nearest increment).

        Parameters
        ----------
        rad : array_like
            Position [rad], motor side.

        Returns
        -------
        numpy.ndarray
            [increments], int64.
        """
        return np.rint(np.asarray(rad) * self.inc_per_rad).astype(np.int64)

    def position_from_device(self, increments: ArrayLike) -> np.ndarray:
        """increments -> rad.

        Parameters
        ----------
        increments : array_like
            Position [device units].

        Returns
        -------
        numpy.ndarray
            [rad], motor side.
        """
        return np.asarray(increments, dtype=float) / self.inc_per_rad

    def velocity_to_device(self, rad_s: ArrayLike) -> np.ndarray:
        """rad/s -> device velocity units (rounded).

        Parameters
        ----------
        rad_s : array_like
            Velocity [rad/s], motor side.

        Returns
        -------
        numpy.ndarray
            [device units], int64.
        """
        return np.rint(np.asarray(rad_s) * self.velocity_per_rad_s).astype(np.int64)

    def velocity_from_device(self, value: ArrayLike) -> np.ndarray:
        """Device velocity units -> rad/s.

        Parameters
        ----------
        value : array_like
            Velocity [device units].

        Returns
        -------
        numpy.ndarray
            [rad/s], motor side.
        """
        return np.asarray(value, dtype=float) / self.velocity_per_rad_s

    def torque_to_device(self, Nm: ArrayLike) -> np.ndarray:
        """Nm -> per mille of rated torque.

        Parameters
        ----------
        Nm : array_like
            Torque [Nm].

        Returns
        -------
        numpy.ndarray
            [per mille of the rated torque], int64 (rounded).
        """
        return np.rint(np.asarray(Nm) / self.rated_torque_Nm * 1000).astype(np.int64)

    def torque_from_device(self, per_mille: ArrayLike) -> np.ndarray:
        """Per mille of rated torque -> Nm.

        Parameters
        ----------
        per_mille : array_like
            Torque [per mille of the rated torque].

        Returns
        -------
        numpy.ndarray
            [Nm].
        """
        return np.asarray(per_mille, dtype=float) * (self.rated_torque_Nm / 1000.0)

    def torque_from_feedback(self, raw: ArrayLike) -> np.ndarray:
        """The axis's torque feedback (its object's value, device units) -> Nm.

        Parameters
        ----------
        raw : array_like
            The feedback [device units].

        Returns
        -------
        numpy.ndarray
            [Nm].
        """
        return np.asarray(raw, dtype=float) * self.feedback_Nm_per_unit

    @property
    def feedback_Nm_per_unit(self) -> float:
        """Nm per unit of the torque feedback: per mille of the rated torque; per mille of the rated
        current, or mA, times the torque constant; or the vendor object's scale."""
        if self.torque_feedback == "current" and self.current_per_unit_A and self.torque_constant_Nm_per_A:
            return self.current_per_unit_A * self.torque_constant_Nm_per_A
        if self.torque_feedback == "object" and self.torque_per_unit_Nm:
            return self.torque_per_unit_Nm
        if self.torque_feedback == "torque":
            return self.rated_torque_Nm / 1000.0
        raise ValueError(f"torque feedback {self.torque_feedback!r} without its scale")
