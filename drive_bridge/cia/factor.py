"""What a drive says about its units: the CiA 402 factor group decoded to device units per SI unit.

A drive reports positions and velocities in the units its factor group sets: the encoder
resolution 0x608F (increments per motor revolutions), the gear ratio 0x6091 (motor revolutions
per driving-shaft revolutions), the feed constant 0x6092 (feed in position units per
driving-shaft revolutions) and the SI unit codes 0x60A8 (position) and 0x60A9 (velocity) of
CiA 402 / CiA 303-2: bits 24-31 a power-of-ten exponent (signed), bits 16-23 the unit, bits 8-15
the time unit of a velocity.  ``0xFF410000`` is 0.1 degree, ``0x00B44700`` revolutions per minute
(the Nanotec C5-E's factory units), ``0x00B50000`` encoder increments.

Everything here is motor side: device units per motor radian and per motor rad/s.  The master
reads these objects at bring-up (:mod:`drive_bridge.master.drive_units`); the simulated drives use
the same decoding to report in the units their object dictionary holds.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

#: angular unit codes -> units per revolution
ANGLE_PER_REV = {0x41: 360.0, 0x42: 21600.0, 0x43: 1296000.0, 0x40: 400.0, 0x10: 2 * math.pi, 0xB4: 1.0}
INCREMENT, METRE, NONE = 0xB5, 0x01, 0x00
#: time unit codes -> seconds
TIME_S = {0x03: 1.0, 0x47: 60.0, 0x48: 3600.0}
UNIT_NAMES = {
    0x41: "°",
    0x42: "′",
    0x43: "″",
    0x40: "gon",
    0x10: "rad",
    0xB4: "rev",
    INCREMENT: "inc",
    METRE: "m",
    NONE: "(dimensionless)",
}
TIME_NAMES = {0x03: "s", 0x47: "min", 0x48: "h"}
#: the objects of the factor group: index -> sub-indices read
OBJECTS = {0x608F: (1, 2), 0x6091: (1, 2), 0x6092: (1, 2), 0x60A8: (0,), 0x60A9: (0,)}


def exponent(code: int) -> int:
    """The power of ten of a 0x60A8 / 0x60A9 code (bits 24-31, signed).

    Parameters
    ----------
    code : int
        The unit code.

    Returns
    -------
    int
        The exponent.
    """
    b = (code >> 24) & 0xFF
    return b - 256 if b >= 128 else b


def describe(code: int | None, velocity: bool = False) -> str:
    """A unit code in words, as "0.1 °" or "rev/min" (None: a unit the drive does not name).

    Parameters
    ----------
    code : int or None
        0x60A8's or 0x60A9's value.
    velocity : bool
        A velocity unit (its time base named too).

    Returns
    -------
    str
        The unit in words, with the code in hex.
    """
    if code is None:
        return "a unit the drive does not name"
    e, unit, time = exponent(code), (code >> 16) & 0xFF, (code >> 8) & 0xFF
    name = UNIT_NAMES.get(unit, f"unit 0x{unit:02X}")
    if velocity:
        name += "/" + TIME_NAMES.get(time, f"time 0x{time:02X}")
    return (f"{10.0**e:g} " if e else "") + name + f" (0x{code:08X})"


def _ratio(pair: tuple[int, int] | None) -> float | None:
    if pair is None:
        return 1.0
    num, den = pair
    return num / den if num and den else None


@dataclass(frozen=True)
class FactorGroup:
    """The factor group as a drive holds it (None: the drive has no such object).

    Parameters
    ----------
    encoder : (int, int), optional
        0x608F: increments, motor revolutions.
    gear : (int, int), optional
        0x6091: motor revolutions, shaft revolutions.
    feed : (int, int), optional
        0x6092: feed [position units], shaft revolutions.
    position_unit : int, optional
        0x60A8.
    velocity_unit : int, optional
        0x60A9.
    """

    encoder: tuple[int, int] | None = None
    gear: tuple[int, int] | None = None
    feed: tuple[int, int] | None = None
    position_unit: int | None = None
    velocity_unit: int | None = None

    @classmethod
    def read(cls, value: Callable[[int, int], Any]) -> FactorGroup:
        """From ``value(index, sub)``, which returns None where the drive has no such object.

        Parameters
        ----------
        value : callable
            ``value(index, sub)``: the object's value, or None.

        Returns
        -------
        FactorGroup
            The factor group.
        """

        def pair(index: int) -> tuple[int, int] | None:
            a, b = value(index, 1), value(index, 2)
            return None if a is None or b is None else (int(a), int(b))

        return cls(pair(0x608F), pair(0x6091), pair(0x6092), value(0x60A8, 0), value(0x60A9, 0))

    def _per_motor_rad(self, unit: int, scale: float) -> float | None:
        """Device units of ``unit`` × ``scale`` per motor radian; None where the group cannot say."""
        gear = _ratio(self.gear)  # motor revolutions per shaft revolution
        if gear is None:
            return None
        if unit == INCREMENT:
            if self.encoder is None or not all(self.encoder):
                return None
            return self.encoder[0] / self.encoder[1] / (2 * math.pi) / scale
        if unit in ANGLE_PER_REV:
            return ANGLE_PER_REV[unit] / scale / gear / (2 * math.pi)
        if unit == METRE:  # the feed constant is in position units already
            feed = _ratio(self.feed)
            return None if self.feed is None or feed is None else feed / gear / (2 * math.pi)
        return None

    @property
    def position_per_rad(self) -> float | None:
        """Position units per motor radian; None where the drive's objects do not determine it
        (no 0x60A8, an encoder resolution it does not report, a unit this does not know)."""
        if self.position_unit is None:
            return None
        return self._per_motor_rad((self.position_unit >> 16) & 0xFF, 10.0 ** exponent(self.position_unit))

    @property
    def velocity_per_rad_s(self) -> float | None:
        """Velocity units per motor rad/s; None where the drive's objects do not determine it."""
        code = self.velocity_unit
        if code is None or (code >> 8) & 0xFF not in TIME_S:
            return None
        unit = (code >> 16) & 0xFF
        if unit == METRE:  # the feed constant is in position units: from those to these
            pos = self.position_unit
            if pos is None or (pos >> 16) & 0xFF != METRE:
                return None
            per_rad = self._per_motor_rad(METRE, 1.0)
            per_rad = None if per_rad is None else per_rad * 10.0 ** (exponent(pos) - exponent(code))
        else:
            per_rad = self._per_motor_rad(unit, 10.0 ** exponent(code))
        return None if per_rad is None else per_rad * TIME_S[(code >> 8) & 0xFF]
