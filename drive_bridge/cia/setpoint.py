"""How position setpoints reach a drive: the operating modes the master streams in and the
objects that carry a setpoint in each (CiA 402), shared by the master, the log decoder and the
simulated drives.

* cyclic synchronous position (mode 8): one target position 0x607A per SYNC;
* interpolated position (mode 7): one interpolation data record per SYNC, either the standard
  0x60C1:1 (sub-mode 0, linear interpolation) or maxon's 0x20C1 PVT record (sub-mode -1:
  position 32 bit, velocity 24 bit, time 8 bit in ms); controlword bit 4 enables interpolation
  and statusword bit 12 confirms it.
"""

from __future__ import annotations

from .p402 import CSP, IP, MODE_NAMES

PVT = (0x20C1, 0)
IP_RECORD = (0x60C1, 1)  # CiA 402's interpolation data record: a position
#: object that carries a position setpoint -> the mode it is streamed in
SETPOINT_OBJECTS = {(0x607A, 0): CSP, IP_RECORD: IP, PVT: IP}
#: interpolation sub-mode (0x60C0) of each interpolated-position setpoint object
IP_SUB_MODE = {IP_RECORD: 0, PVT: -1}


def supported_modes(bits: int) -> list[int]:
    """The CiA 402 modes a 0x6502 value lists (bit n-1 is mode n; bit 4 is reserved).

    Parameters
    ----------
    bits : int
        0x6502's value.

    Returns
    -------
    list of int
        The modes.
    """
    return [m for m in MODE_NAMES if bits >> (m - 1) & 1]


def describe_modes(bits: int) -> str:
    """The modes a 0x6502 value lists, in words.

    Parameters
    ----------
    bits : int
        0x6502's value.

    Returns
    -------
    str
        ``cyclic synchronous position (8), ...`` or ``none``.
    """
    modes = supported_modes(bits)
    return ", ".join(f"{MODE_NAMES[m]} ({m})" for m in modes) or "none"


def pack_pvt(position_inc: int, velocity: int, time_ms: int) -> int:
    """maxon's interpolation data record 0x20C1 (UNSIGNED64): position, velocity (the drive's
    velocity unit), time [ms] from the low byte up.

    Parameters
    ----------
    position_inc : int
        Position [increments].
    velocity : int
        Velocity [the drive's velocity unit].
    time_ms : int
        Time [ms].

    Returns
    -------
    int
        The record.
    """
    return (position_inc & 0xFFFFFFFF) | (velocity & 0xFFFFFF) << 32 | (time_ms & 0xFF) << 56


def unpack_pvt(record: int) -> tuple[int, int, int]:
    """(position, velocity, time_ms) of a 0x20C1 record, signed as the drive reads them.

    Parameters
    ----------
    record : int
        The record.

    Returns
    -------
    (int, int, int)
        Position [increments], velocity, time [ms].
    """
    pos = record & 0xFFFFFFFF
    vel = record >> 32 & 0xFFFFFF
    return (pos - (1 << 32) if pos >> 31 else pos, vel - (1 << 24) if vel >> 23 else vel, record >> 56 & 0xFF)


def position_of(entry: tuple[int, int], value: int) -> int:
    """The position [increments] a setpoint object's value carries.

    Parameters
    ----------
    entry : (int, int)
        The setpoint object (0x607A, or the data record 0x20C1).
    value : int
        Its value.

    Returns
    -------
    int
        The position [increments].
    """
    return unpack_pvt(value)[0] if entry == PVT else value


def choose(
    bits: int, mapped: list[tuple[int, int]], modes: tuple[int, ...] = (CSP, IP)
) -> tuple[int, tuple[int, int]] | None:
    """(mode, setpoint object) to stream in: the first of ``modes`` (by default cyclic synchronous
    position, then interpolated position) the drive has (0x6502 ``bits``) with its setpoint object
    mapped in the RPDOs (0x607A; the data record); None when none.

    Parameters
    ----------
    bits : int
        0x6502's value.
    mapped : list of (int, int)
        The objects the RPDOs map.
    modes : tuple of int
        The modes in the order they are preferred.

    Returns
    -------
    (int, (int, int)) or None
        The mode and its setpoint object.
    """
    for mode in modes:
        if bits >> (mode - 1) & 1:
            entry = next((e for e in mapped if SETPOINT_OBJECTS.get(e) == mode), None)
            if entry is not None:
                return mode, entry
    return None
