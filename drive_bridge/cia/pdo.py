"""One PDO's layout and codec, shared by the master (bring-up, streaming, decoding a trace) and
the simulated drives: the COB-ID, the mapped objects in order, and the little-endian struct of
their data types (canopen's own type table)."""

from __future__ import annotations

import struct
from collections.abc import Iterable
from dataclasses import dataclass
from functools import cached_property

import canopen
from canopen.objectdictionary import ODVariable

from .od import variable


@dataclass(frozen=True)
class PdoCodec:
    """Packs and unpacks one PDO; built once per mapping.

    Parameters
    ----------
    cob_id : int
        The PDO's COB-ID.
    entries : tuple of (int, int)
        (index, sub-index) of each object, in mapping order.
    struct : struct.Struct
        The frame's layout (little-endian, each object's type).
    """

    cob_id: int
    entries: tuple[tuple[int, int], ...]
    struct: struct.Struct

    @classmethod
    def of(cls, cob_id: int, od: canopen.ObjectDictionary, entries: Iterable[tuple[int, int]]) -> PdoCodec:
        """The codec of ``entries`` ((index, sub-index) pairs) with their types from ``od``.

        Parameters
        ----------
        cob_id : int
            The PDO's COB-ID.
        od : canopen.ObjectDictionary
            The drive's object dictionary (the objects' types).
        entries : iterable of (int, int)
            The objects, in mapping order.

        Returns
        -------
        PdoCodec
            The codec.

        Raises
        ------
        KeyError
            An object ``od`` does not have.
        """
        entries = tuple((int(i), int(s)) for i, s in entries)
        variables = [variable(od, i, s) for i, s in entries]
        return cls(cob_id, entries, struct.Struct("<" + "".join(_struct_format(v) for v in variables)))

    @cached_property
    def objects(self) -> tuple[int, ...]:
        """The mapped object indices, in mapping order."""
        return tuple(i for i, _ in self.entries)

    @cached_property
    def spans(self) -> list[tuple[int, int]]:
        """Byte slice (start, end) of each entry in the frame."""
        out, offset = [], 0
        for code in self.struct.format.lstrip("<"):
            size = struct.calcsize("<" + code)
            out.append((offset, offset + size))
            offset += size
        return out

    def as_dict(self) -> dict:
        """How meta.yaml records it (enough to decode a trace without the EDS).

        Returns
        -------
        dict
            ``cob_id``, ``format``, ``objects``, ``sub_indices``.
        """
        return {
            "cob_id": self.cob_id,
            "format": self.struct.format,
            "objects": list(self.objects),
            "sub_indices": [s for _, s in self.entries],
        }

    @classmethod
    def from_dict(cls, d: dict) -> PdoCodec:
        """:meth:`as_dict` read back (a meta.yaml without ``sub_indices``: sub-index 0 each).

        Parameters
        ----------
        d : dict
            The dict.

        Returns
        -------
        PdoCodec
            The codec.
        """
        subs = d.get("sub_indices", [0] * len(d["objects"]))
        return cls(d["cob_id"], tuple(zip(d["objects"], subs)), struct.Struct(d["format"]))


def _struct_format(var: ODVariable) -> str:
    """The struct format of a mapped object's data type; ValueError naming the object where the
    type has no fixed size to map."""
    if var.data_type is None or var.data_type not in ODVariable.STRUCT_TYPES:
        raise ValueError(f"0x{var.index:04X}:{var.subindex} has no fixed-size data type to map into a PDO")
    return ODVariable.STRUCT_TYPES[var.data_type].format.lstrip("<")
