"""The commissioned node as a DCF (CiA 306) that Lely's dcfchk and dcfgen and canopen read.

``[DeviceComissioning]`` holds the node-ID and the bitrate; ``$NODEID`` is resolved; every
configuration object of the node — readable and writable, from the communication area
(PDO communication and mapping, heartbeat, SYNC) to the profile and vendor objects
(following-error window, software limits, interpolation period, gains, model) — carries as
ParameterValue the value read back from the drive, so loading the DCF onto a replacement drive
reproduces the commissioning, and the file never claims a value the drive did not report.
Process data (what a PDO maps) and commands (controlword, mode of operation) are left out:
they are not configuration.  REAL32/REAL64 values are written as their IEEE 754 bit patterns,
descriptions that CiA 306 has no key for are dropped, signed values a vendor wrote as two's
complement are written as the negative numbers they are.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import canopen
from canopen.objectdictionary import ODVariable, datatypes
from canopen.sdo import SdoAbortedError, SdoCommunicationError

from .od import float_bits, signed, variables

COMMANDS = {0x6040, 0x6060}  # controlword, modes of operation: commands, not settings
MAPPING = (range(0x1600, 0x1800), range(0x1A00, 0x1C00))
NOT_VALUES = (datatypes.DOMAIN, datatypes.OCTET_STRING)


def configuration(od: canopen.ObjectDictionary) -> list[ODVariable]:
    """The node's configuration objects: readable and writable, 0x1000-0x9FFF, no command.

    Parameters
    ----------
    od : canopen.ObjectDictionary
        The node's object dictionary.

    Returns
    -------
    list of ODVariable
        Those objects.
    """
    return [
        v
        for v in variables(od)
        if 0x1000 <= v.index <= 0x9FFF
        and v.index not in COMMANDS
        and v.readable
        and v.writable
        and v.data_type not in NOT_VALUES
    ]


def read_back(node: canopen.RemoteNode, objects: list[ODVariable]) -> dict[tuple[int, int], Any]:
    """Each object's value as the drive reports it (SDO upload); objects the drive does not
    have (an abort) are left out.

    Parameters
    ----------
    node : canopen.RemoteNode
        The drive.
    objects : list of ODVariable
        The objects.

    Returns
    -------
    dict of (int, int) to object
        (index, sub) -> value.

    Raises
    ------
    SdoCommunicationError
        The drive does not answer.
    """
    values: dict[tuple[int, int], Any] = {}
    for var in objects:
        try:
            raw = node.sdo.upload(var.index, var.subindex)
        except SdoAbortedError:
            continue
        values[var.index, var.subindex] = var.decode_raw(raw)
    return values


def mapped(values: dict[tuple[int, int], Any]) -> set[tuple[int, int]]:
    """The objects the PDO mappings in ``values`` map (process data).

    Parameters
    ----------
    values : dict of (int, int) to object
        Objects' values, the PDO mappings among them.

    Returns
    -------
    set of (int, int)
        (index, sub) of each object mapped.
    """
    out = set()
    for (index, sub), v in values.items():
        if sub and any(index in r for r in MAPPING) and isinstance(v, int) and v:
            out.add((v >> 16, (v >> 8) & 0xFF))
    return out


def parameter_value(var: ODVariable, value: Any) -> str:
    """``value`` as a DCF entry of ``var``'s type (a signed value that a vendor file wrote as its
    two's complement, 0xFFFF for an INTEGER16 -1, as the negative number CiA 306 tools expect).

    Parameters
    ----------
    var : ODVariable
        The object.
    value : object
        Its value.

    Returns
    -------
    str
        The entry's text.
    """
    if var.data_type in datatypes.FLOAT_TYPES:
        return float_bits(float(value), var.data_type)
    if isinstance(value, int):
        value = signed(var, value)
        return f"0x{value:X}" if value >= 0 else str(value)
    return str(value)


def export_dcf(node: canopen.RemoteNode, path: str | Path, bitrate: int) -> Path:
    """Read every configuration object back from ``node`` and write the DCF to ``path``.

    Parameters
    ----------
    node : canopen.RemoteNode
        The drive (with its node id).
    path : str or Path
        The DCF to write.
    bitrate : int
        The bus's bitrate [bit/s], written into the DCF.

    Returns
    -------
    Path
        The DCF written.

    Raises
    ------
    SdoCommunicationError
        The drive does not answer, naming the node.
    """
    od = node.object_dictionary
    try:
        values = read_back(node, configuration(od))
    except SdoCommunicationError as exc:
        raise SdoCommunicationError(
            f"node {node.id}: reading the configuration back for its DCF: {exc}"
        ) from exc
    process = mapped(values)
    if node.id is None:
        raise ValueError("a DCF is exported from a node with its node-ID")
    return write_dcf(od, path, node.id, bitrate, {k: v for k, v in values.items() if k not in process})


def write_dcf(
    od: canopen.ObjectDictionary,
    path: str | Path,
    node_id: int,
    bitrate: int,
    values: dict[tuple[int, int], Any],
) -> Path:
    """``od`` (changed in place) as a CiA 306 clean DCF at ``path``: the node-ID and bitrate,
    defaults resolved (``$NODEID``, REALs as bit patterns, signed as such), no descriptions, and
    ``values`` (by index and sub-index) as the only ParameterValues.

    Parameters
    ----------
    od : canopen.ObjectDictionary
        The object dictionary (changed in place).
    path : str or Path
        The DCF to write.
    node_id : int
        The node id.
    bitrate : int
        The bitrate [bit/s].
    values : dict of (int, int) to object
        The ParameterValues.

    Returns
    -------
    Path
        The DCF written.
    """
    for var in variables(od):  # *_raw: the text canopen's exporter writes
        var.description = ""  # not a CiA 306 key of an object
        if isinstance(var.default, (int, float)):
            setattr(var, "default_raw", parameter_value(var, var.default))  # noqa: B010 (not in canopen's types)
        value = values.get((var.index, var.subindex))
        var.value = value
        setattr(var, "value_raw", None if value is None else parameter_value(var, value))  # noqa: B010
    od.node_id, od.bitrate = node_id, bitrate
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    canopen.export_od(od, str(path), doc_type="dcf")
    return path
