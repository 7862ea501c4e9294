"""SDO on the protocol floor: a drive's objects read and written with canopen, each failure in
the project's words (:class:`~drive_bridge.errors.BusError` where the drive does not answer,
:class:`~drive_bridge.errors.DriveRefused` where it aborts a write); its settings as raw objects,
written inside the range its EDS/DCF gives, read as a snapshot and put back -- the PDO
communication and mapping objects through CiA 301's procedure (the PDO invalid while it changes,
its mapping count 0 while its entries do).

Bring-up keeps a snapshot of everything it overwrites, so that a store (0x1010:1 saves every
parameter) that must be undone can put the drive's stored set back as it was before bring-up.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from typing import Any

import canopen
from canopen.sdo import SdoVariable

from ..errors import BusError, DriveRefused
from ..outputs import hex_object
from .objects import CYCLE_PERIOD, SYNC_COUNTER_OVERFLOW
from .od import limits, variable

log = logging.getLogger(__name__)

SDO_ERRORS = (canopen.SdoAbortedError, canopen.SdoCommunicationError)


def sdo_object(node: canopen.RemoteNode, index: int, sub: int) -> SdoVariable:
    """The SDO accessor of object ``index``:``sub`` on ``node``.

    Parameters
    ----------
    node : canopen.RemoteNode
        The drive.
    index, sub : int
        The object.

    Returns
    -------
    SdoVariable
        canopen's accessor (``.raw`` reads and writes it).
    """
    return SdoVariable(node.sdo, variable(node.object_dictionary, index, sub))


def read_if_readable(node: canopen.RemoteNode, index: int, sub: int, what: str) -> Any:
    """Object ``index``:``sub`` as the drive holds it; None where its EDS/DCF has no such object or
    the drive refuses the read (an abort: the object is not there to read); BusError naming
    ``what`` where the drive does not answer.

    Parameters
    ----------
    node : canopen.RemoteNode
        The drive.
    index, sub : int
        The object.
    what : str
        What it is, for the error.

    Returns
    -------
    object
        Its value in device units, or None.

    Raises
    ------
    BusError
        The drive does not answer.
    """
    if node.object_dictionary.get_variable(index, sub) is None:
        return None
    try:
        return sdo_object(node, index, sub).raw
    except canopen.SdoAbortedError:
        return None
    except canopen.SdoCommunicationError as exc:
        raise BusError(f"node {node.id}: no SDO answer reading {what} (0x{index:04X}:{sub}) ({exc})") from exc


def describe_sdo_error(exc: Exception) -> str:
    """One phrase for an SDO failure: the abort code and its CiA 301 text, or the lost answer.

    Parameters
    ----------
    exc : Exception
        canopen's SdoAbortedError or SdoCommunicationError.

    Returns
    -------
    str
        The phrase.
    """
    if isinstance(exc, canopen.SdoAbortedError):
        return (
            f"SDO abort 0x{exc.code:08X}: {canopen.SdoAbortedError.CODES.get(exc.code, 'unknown abort code')}"
        )
    if isinstance(exc, canopen.SdoCommunicationError):
        return f"no answer ({exc}): the node may have dropped off the bus"
    return f"{type(exc).__name__}: {exc}"


PDO_COMM = (0x1400, 0x1800)  # RPDO / TPDO communication parameters; mapping at +0x200
PDO_INVALID = 0x80000000


def write_setting(node: canopen.RemoteNode, axis: str, index: int, sub: int, value: int | float) -> None:
    """SDO download of ``value``, checked against the range the drive's EDS/DCF gives first.

    Parameters
    ----------
    node : canopen.RemoteNode
        The drive.
    axis : str
        Its axis, for the errors.
    index, sub : int
        The object.
    value : int or float
        The value, in device units.

    Raises
    ------
    DriveRefused
        Outside the range its EDS/DCF gives (nothing written), or the drive refuses it.
    BusError
        The drive does not answer.
    """
    lo, hi = limits(variable(node.object_dictionary, index, sub))
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise DriveRefused(
            f"axis {axis}: 0x{index:04X}:{sub} = {value} is outside the range its EDS/DCF gives "
            f"({lo}..{hi}); nothing was written to it"
        )
    log.debug("axis %s: 0x%04X:%d = %s", axis, index, sub, value)
    try:
        node.sdo.download(index, sub, variable(node.object_dictionary, index, sub).encode_raw(value))
    except canopen.SdoAbortedError as exc:
        raise DriveRefused(f"axis {axis}: writing 0x{index:04X}:{sub} = {value} was refused ({exc})") from exc
    except canopen.SdoCommunicationError as exc:
        raise BusError(f"axis {axis}: no SDO answer writing 0x{index:04X}:{sub} ({exc})") from exc


def pdo_objects(od: canopen.ObjectDictionary) -> list[tuple[int, int]]:
    """The communication (COB-ID, transmission type, inhibit time, event timer) and mapping
    objects of PDOs 1-4 that the drive's EDS/DCF has writable.

    Parameters
    ----------
    od : canopen.ObjectDictionary
        The drive's object dictionary.

    Returns
    -------
    list of (int, int)
        (index, sub) of each.
    """
    out = []
    for base in PDO_COMM:
        for num in range(4):
            for index, subs in ((base + num, (1, 2, 3, 5)), (base + 0x200 + num, range(9))):
                out += [
                    (index, sub)
                    for sub in subs
                    if (var := od.get_variable(index, sub)) is not None and var.writable and var.readable
                ]
    return out


def snapshot(node: canopen.RemoteNode, axis: str, objects: Iterable[tuple[int, int]]) -> dict[str, int]:
    """``objects`` ((index, sub) pairs) as the drive holds them now, by address "0xIIII:S";
    those it does not let be read and written are left out.

    Parameters
    ----------
    node : canopen.RemoteNode
        The drive.
    axis : str
        Its axis, for the errors.
    objects : iterable of (int, int)
        The objects.

    Returns
    -------
    dict of str to int
        Address -> raw value, in the order given.

    Raises
    ------
    BusError
        The drive does not answer.
    """
    out = {}
    for index, sub in objects:
        var = node.object_dictionary.get_variable(index, sub)
        if var is None or not var.readable or not var.writable:
            continue
        value = read_if_readable(node, index, sub, f"axis {axis}'s setting")
        if value is not None:
            out[hex_object(index, sub)] = value
    return out


def address(key: str) -> tuple[int, int]:
    """The (index, sub) of an address "0xIIII:S".

    Parameters
    ----------
    key : str
        The address.

    Returns
    -------
    (int, int)
        Index and subindex.
    """
    index, sub = key.split(":")
    return int(index, 16), int(sub)


def put_back(node: canopen.RemoteNode, axis: str, values: dict[str, int]) -> None:
    """Write a :func:`snapshot` back, in its order; each PDO it holds is made invalid first, its
    mapping count set to 0 while the entries are written, and its COB-ID (valid or not, as it was)
    written last; the SYNC counter's overflow 0x1019 with the communication cycle period 0x1006 at 0
    (CiA 301 takes it only then), the period written after it.  DriveRefused / BusError at the first
    object the drive does not take.

    Parameters
    ----------
    node : canopen.RemoteNode
        The drive.
    axis : str
        Its axis, for the errors.
    values : dict of str to int
        The snapshot: address -> raw value.

    Raises
    ------
    DriveRefused
        The first object the drive refuses.
    BusError
        The drive does not answer.
    """
    pdos: dict[int, dict[tuple[int, int], int]] = {}
    counter, period = hex_object(SYNC_COUNTER_OVERFLOW, 0), hex_object(CYCLE_PERIOD, 0)
    if counter in values:
        cycle = values.get(period)
        if cycle is None:
            cycle = read_if_readable(node, CYCLE_PERIOD, 0, f"axis {axis}'s communication cycle period")
        write_setting(node, axis, CYCLE_PERIOD, 0, 0)
        write_setting(node, axis, SYNC_COUNTER_OVERFLOW, 0, values[counter])
        if cycle is not None:
            write_setting(node, axis, CYCLE_PERIOD, 0, cycle)
        values = {key: value for key, value in values.items() if key not in (counter, period)}
    for key, value in values.items():
        index, sub = address(key)
        comm = index - 0x200 if 0x1600 <= index <= 0x17FF or 0x1A00 <= index <= 0x1BFF else index
        if 0x1400 <= comm <= 0x15FF or 0x1800 <= comm <= 0x19FF:
            pdos.setdefault(comm, {})[(index, sub)] = value
        else:
            write_setting(node, axis, index, sub, value)
    for comm, objects in pdos.items():
        mapping = comm + 0x200
        now = read_if_readable(node, comm, 1, f"axis {axis}'s PDO COB-ID")
        if now is not None and not now & PDO_INVALID:
            write_setting(node, axis, comm, 1, now | PDO_INVALID)
        entries = sorted((sub, v) for (index, sub), v in objects.items() if index == mapping and sub > 0)
        if (mapping, 0) in objects:
            write_setting(node, axis, mapping, 0, 0)
            for sub, v in entries:
                write_setting(node, axis, mapping, sub, v)
            write_setting(node, axis, mapping, 0, objects[(mapping, 0)])
        for sub in (2, 3, 5):
            if (comm, sub) in objects:
                write_setting(node, axis, comm, sub, objects[(comm, sub)])
        if (comm, 1) in objects:
            write_setting(node, axis, comm, 1, objects[(comm, 1)])
