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
    """Conversion for one axis.

    increments_per_rev: device position units per motor revolution: encoder increments (0x608F),
        or what the drive's own position unit (0x60A8) makes of a revolution.
    feed_m_per_rev: load travel per motor revolution (belt pulley or screw lead);
        None for a rotary axis.
    rated_torque_Nm: the drive's rated torque (0x6076 in mNm / 1000).
    """

    increments_per_rev: float
    rated_torque_Nm: float
    feed_m_per_rev: float | None = None
    torque_feedback: str = "torque"  # "torque": 0x6077; "current": 0x6078 × torque constant;
    # "object": the vendor object torque_index × torque_per_unit_Nm
    current_per_unit_A: float | None = None  # A per unit of 0x6078 (rated current / 1000, or 0.001 for mA)
    torque_constant_Nm_per_A: float | None = None
    torque_index: int | None = None
    torque_per_unit_Nm: float | None = None
    velocity_unit: str = "inc/s"  # of 0x606C and the other velocities: "inc/s" or "rpm"
    #: device velocity units per rad/s as the drive reports them (its 0x60A9, with ``scaling:
    #: from_drive``); None: from ``velocity_unit``
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
        """m, m/s or m/s² of a linear axis to rad, rad/s or rad/s² of the motor."""
        if self.feed_m_per_rev is None:
            return value_m
        return value_m * (2 * math.pi / self.feed_m_per_rev)

    # --- SI <-> device --------------------------------------------------------------
    def position_to_device(self, rad: ArrayLike) -> np.ndarray:
        """rad -> increments (rounded to the nearest increment)."""
        return np.rint(np.asarray(rad) * self.inc_per_rad).astype(np.int64)

    def position_from_device(self, increments: ArrayLike) -> np.ndarray:
        return np.asarray(increments, dtype=float) / self.inc_per_rad

    def velocity_to_device(self, rad_s: ArrayLike) -> np.ndarray:
        return np.rint(np.asarray(rad_s) * self.velocity_per_rad_s).astype(np.int64)

    def velocity_from_device(self, value: ArrayLike) -> np.ndarray:
        return np.asarray(value, dtype=float) / self.velocity_per_rad_s

    def torque_to_device(self, Nm: ArrayLike) -> np.ndarray:
        """Nm -> per mille of rated torque."""
        return np.rint(np.asarray(Nm) / self.rated_torque_Nm * 1000).astype(np.int64)

    def torque_from_device(self, per_mille: ArrayLike) -> np.ndarray:
        return np.asarray(per_mille, dtype=float) * (self.rated_torque_Nm / 1000.0)

    def torque_from_feedback(self, raw: ArrayLike) -> np.ndarray:
        """The axis's torque feedback (its :attr:`torque_object`, device units) -> Nm."""
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

    @property
    def torque_object(self) -> int:
        """The object the axis's torque is measured by: 0x6077, 0x6078 for current feedback, or the
        configured vendor object."""
        if self.torque_feedback == "object" and self.torque_index is not None:
            return self.torque_index
        return 0x6078 if self.torque_feedback == "current" else 0x6077
