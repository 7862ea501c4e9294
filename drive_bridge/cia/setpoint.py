"""How position setpoints reach a drive: the operating modes the master streams in and the
objects that carry a setpoint in each (CiA 402), shared by the master, the log decoder and the
simulated drives.

* cyclic synchronous position (mode 8): one target position 0x607A per SYNC;
* interpolated position (mode 7): one interpolation data record per SYNC, either the standard
  0x60C1:1 (a position; sub-mode 0, linear interpolation, or a vendor's higher-order sub-mode of
  position records) or maxon's 0x20C1 PVT record (sub-mode -1: position 32 bit, velocity 24 bit,
  time 8 bit in ms); controlword bit 4 enables interpolation and statusword bit 12 confirms it.

Linear interpolation, the one sub-mode CiA 402 defines, makes a demand without acceleration inside
a record: a drive's acceleration feed-forward has nothing to act on, and the following error of a
stiff axis grows with the acceleration (10x CSP's on the project's drive).  Vendors give position
records a higher-order sub-mode under a negative, manufacturer-specific number (Parker SLVD-N: -2,
"cubic interpolation only position"); the master selects one only where the drive's vendor is
named in :data:`POSITION_RECORD_SUB_MODES` and its object dictionary admits the value.
"""

from __future__ import annotations

from .p402 import CSP, IP, MODE_NAMES

PVT = (0x20C1, 0)
#: maxon's interpolation buffer status (0x20C4:1): underflow/overflow warnings and errors, enabled,
#: interpolating (:mod:`drive_bridge.sim.pvt_buffer` has its bits)
PVT_BUFFER_STATUS = (0x20C4, 1)
#: the longest time a PVT record carries: its time field is 8 bits of ms [s]
PVT_RECORD_MAX_S = 0.255
IP_RECORD = (0x60C1, 1)  # CiA 402's interpolation data record: a position
#: object that carries a position setpoint -> the mode it is streamed in
SETPOINT_OBJECTS = {(0x607A, 0): CSP, IP_RECORD: IP, PVT: IP}
#: interpolation sub-mode (0x60C0) of each interpolated-position setpoint object
IP_SUB_MODE = {IP_RECORD: 0, PVT: -1}
#: vendor (0x1018:1) -> (0x60C0 value, in words) of its drives' higher-order interpolation of
#: position records 0x60C1:1: the demand through the records with its acceleration, as in CSP
POSITION_RECORD_SUB_MODES = {
    0x00000DB1: (-2, "the parabola through the last three records (drive-bridge servo)"),
}


def record_sub_mode(vendor_id: int, limits: tuple[float | None, float | None]) -> tuple[int, str]:
    """The interpolation sub-mode (0x60C0) to stream position records 0x60C1:1 in, and why.

    Parameters
    ----------
    vendor_id : int
        The drive's vendor (0x1018:1) as read.
    limits : (float or None, float or None)
        The range 0x60C0 admits, as its EDS/DCF gives it (None: not given).

    Returns
    -------
    (int, str)
        The sub-mode and the reason in words.
    """
    lowest, highest = limits
    known = POSITION_RECORD_SUB_MODES.get(vendor_id)
    if known is None:
        why = "no higher-order sub-mode is known for its vendor"
    else:
        sub_mode, words = known
        if (lowest is None or lowest <= sub_mode) and (highest is None or sub_mode <= highest):
            return (
                sub_mode,
                f"interpolation sub-mode {sub_mode} (0x60C0): {words}, its acceleration fed forward",
            )
        why = "its vendor's higher-order sub-mode is outside the range 0x60C0 admits"
    return 0, (
        f"interpolation sub-mode 0 (0x60C0, linear; {why}): no acceleration inside a record, "
        "so the following error grows with the acceleration"
    )


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
