"""Reading EDS/DCF files with canopen, around the traps of real vendor files."""

from __future__ import annotations

import functools
import io
import pickle
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import canopen
from canopen.objectdictionary import ODVariable, datatypes

from ..errors import ConfigError


def load_od(path: str | Path, node_id: int) -> canopen.ObjectDictionary:
    """Import an EDS or DCF; files that are not UTF-8 are read as Windows-1252; REAL values
    written as IEEE 754 bit patterns and signed values written as two's complement are read as
    the numbers they are.  Each call gives an object dictionary of its own (a file read before,
    unchanged since, is not parsed again: configparser takes 0.02-0.15 s a file, a copy 1-15 ms).

    Parameters
    ----------
    path : str or Path
        The EDS or DCF.
    node_id : int
        The node id its ``$NODEID`` entries resolve to.

    Returns
    -------
    canopen.ObjectDictionary
        The object dictionary, a copy of its own.

    Raises
    ------
    ConfigError
        The file cannot be read or parsed, naming it.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ConfigError(path, "", f"cannot read EDS/DCF: {exc.strerror}") from exc
    return pickle.loads(_parsed(str(path), raw, node_id))


@functools.lru_cache(maxsize=32)
def _parsed(path: str, raw: bytes, node_id: int) -> bytes:
    """The object dictionary of file ``path`` holding ``raw`` for ``node_id``, pickled."""
    return pickle.dumps(_parse(Path(path), raw, node_id))


def _parse(path: Path, raw: bytes, node_id: int) -> canopen.ObjectDictionary:
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        text = raw.decode("cp1252", errors="replace")
    source = io.StringIO(text)
    source.name = str(path)
    try:
        od = canopen.import_od(source, node_id)
    except Exception as exc:  # canopen raises bare parser errors of several kinds
        raise ConfigError(path, "", f"not a readable EDS/DCF: {exc}") from exc
    for var in variables(od):
        if var.data_type in datatypes.FLOAT_TYPES:
            for as_written, as_read in (("default_raw", "default"), ("value_raw", "value")):
                if getattr(var, as_read, None) is None and getattr(var, as_written, None):
                    setattr(var, as_read, float_from_bits(getattr(var, as_written), var.data_type))
        elif var.data_type in datatypes.SIGNED_TYPES:  # a vendor's 0xFD for an INTEGER8 -3
            var.default, var.value = signed(var, var.default), signed(var, var.value)
    return od


def variable(od: canopen.ObjectDictionary, index: int, sub: int = 0) -> ODVariable:
    """Object ``index``:``sub`` of ``od``; KeyError naming it where ``od`` has none.

    Parameters
    ----------
    od : canopen.ObjectDictionary
        The object dictionary.
    index, sub : int
        The object.

    Returns
    -------
    ODVariable
        The object.

    Raises
    ------
    KeyError
        ``od`` has no such object.
    """
    var = od.get_variable(index, sub)
    if var is None:
        raise KeyError(f"0x{index:04X}:{sub} is not in the object dictionary")
    return var


def default(od: canopen.ObjectDictionary, index: int, sub: int = 0) -> Any:
    """The default value ``od`` gives object ``index``:``sub``; None where it has no such object or no default.

    Parameters
    ----------
    od : canopen.ObjectDictionary
        The object dictionary.
    index, sub : int
        The object.

    Returns
    -------
    object
        Its default value, or None.
    """
    var = od.get_variable(index, sub)
    return None if var is None else var.default


def variables(od: canopen.ObjectDictionary) -> Iterator[ODVariable]:
    """Every variable of ``od``, sub-indices included.

    Parameters
    ----------
    od : canopen.ObjectDictionary
        The object dictionary.

    Yields
    ------
    ODVariable
        Each variable.
    """
    for obj in od.values():
        if isinstance(obj, canopen.objectdictionary.ODVariable):
            yield obj
        else:
            yield from obj.values()


def float_from_bits(raw: str, data_type: int) -> float | None:
    """A REAL32/REAL64 written as its IEEE 754 bit pattern (``0x43160000`` = 150.0), as Lely
    and CiA 306 tools write them; None when ``raw`` is not an integer.

    Parameters
    ----------
    raw : str
        The value as the file writes it.
    data_type : int
        The object's data type (REAL32, REAL64).

    Returns
    -------
    float or None
        The number.
    """
    try:
        bits = int(raw.strip(), 0)
    except ValueError:
        return None
    if data_type == datatypes.REAL32:
        return struct.unpack(">f", (bits & 0xFFFFFFFF).to_bytes(4, "big"))[0]
    return struct.unpack(">d", (bits & 0xFFFFFFFFFFFFFFFF).to_bytes(8, "big"))[0]


def float_bits(value: float, data_type: int) -> str:
    """``value`` as the IEEE 754 bit pattern an EDS/DCF holds for a REAL32/REAL64.

    Parameters
    ----------
    value : float
        The number.
    data_type : int
        REAL32 or REAL64.

    Returns
    -------
    str
        ``0x…`` (8 or 16 hex digits).
    """
    if data_type == datatypes.REAL32:
        return f"0x{struct.unpack('>I', struct.pack('>f', value))[0]:08X}"
    return f"0x{struct.unpack('>Q', struct.pack('>d', value))[0]:016X}"


def signed(var: ODVariable, value: Any) -> Any:
    """``value`` of ``var`` as the number it is where a file wrote a signed type's value as its
    two's complement (0xFD for an INTEGER8 -3); anything else as it is.

    Parameters
    ----------
    var : ODVariable
        The object (its data type).
    value : object
        The value as read.

    Returns
    -------
    object
        The number it is.
    """
    bits = len(var) if var.data_type in datatypes.SIGNED_TYPES else 0
    if isinstance(value, int) and bits and (1 << (bits - 1)) <= value < (1 << bits):
        return value - (1 << bits)
    return value


def limits(var: ODVariable) -> tuple[float | None, float | None]:
    """The (LowLimit, HighLimit) an EDS/DCF gives ``var``, signed types as the numbers they are;
    None where it gives none.

    Parameters
    ----------
    var : ODVariable
        The object.

    Returns
    -------
    low, high : float or None
        Its range.
    """
    return signed(var, getattr(var, "min", None)), signed(var, getattr(var, "max", None))
