"""The PDOs of a simulated drive as the master maps them, with CiA 301's rules for a mapping
change: the COB-ID changes only while the PDO is invalid, the mapping only while the PDO is
invalid and its sub-index 0 is 0, only PDO-mappable objects of the right direction, at most
8 entries and 64 bits."""
from __future__ import annotations

from typing import Callable

import canopen
from canopen.objectdictionary import ODVariable
from canopen.sdo import SdoAbortedError

from ..pdo import PdoCodec

PDO_INVALID = 0x8000_0000
ABORT_RANGE = 0x06090030
ABORT_STATE = 0x08000022
ABORT_NOT_MAPPABLE = 0x06040041
ABORT_PDO_LENGTH = 0x06040042


class PdoMapping:
    """The valid RPDOs (COB-ID -> codec, transmission type) and TPDOs (codec, transmission type,
    the getters of their objects) of one drive, rebuilt from its object dictionary.

    ``value(index, sub)`` reads an object as the drive holds it; ``getter(index, sub)`` gives
    the callable a TPDO samples an object with."""

    def __init__(self, od: canopen.ObjectDictionary, value: Callable[[int, int], int],
                 getter: Callable[[int, int], Callable[[], int]]):
        self.od, self._value, self._getter = od, value, getter
        self.rpdos: dict[int, tuple[PdoCodec, int]] = {}
        self.tpdos: list[tuple[PdoCodec, int, list[Callable[[], int]]]] = []

    def check_write(self, index: int, sub: int, value: int) -> None:
        """Raise SdoAbortedError when a write to a PDO parameter breaks CiA 301's rules."""
        is_map = (index & 0xFF00) in (0x1600, 0x1A00)
        comm = (index & ~0x0200) if is_map else index      # 0x16xx -> 0x14xx, 0x1Axx -> 0x18xx
        cob = self._value(comm, 1)
        if not is_map:
            if sub == 1 and not cob & PDO_INVALID and not value & PDO_INVALID and \
                    (value & 0x7FF) != (cob & 0x7FF):
                raise SdoAbortedError(ABORT_RANGE)    # change the COB-ID only while invalid
            return
        if not cob & PDO_INVALID:
            raise SdoAbortedError(ABORT_STATE)        # map only while the PDO is invalid
        if sub == 0:
            bits = 0
            for n in range(1, value + 1):
                entry = self._value(index, n)
                if self._mappable(entry >> 16, (entry >> 8) & 0xFF, tpdo=index >= 0x1A00) is None:
                    raise SdoAbortedError(ABORT_NOT_MAPPABLE)
                bits += entry & 0xFF
            if value > 8 or bits > 64:
                raise SdoAbortedError(ABORT_PDO_LENGTH)
        else:
            if self._value(index, 0) != 0:
                raise SdoAbortedError(ABORT_STATE)    # sub 0 must be 0 while entries change
            if value and self._mappable(value >> 16, (value >> 8) & 0xFF, tpdo=index >= 0x1A00) is None:
                raise SdoAbortedError(ABORT_NOT_MAPPABLE)

    def _mappable(self, index: int, sub: int, tpdo: bool) -> ODVariable | None:
        var = self.od.get_variable(index, sub)
        if var is None or not var.pdo_mappable or (tpdo and not var.readable) or (not tpdo and not var.writable):
            return None
        return var

    def rebuild(self) -> None:
        """Compile the codecs of every valid PDO."""
        self.rpdos, self.tpdos = {}, []
        for n in range(4):
            for comm, mapping, table in ((0x1400 + n, 0x1600 + n, "r"), (0x1800 + n, 0x1A00 + n, "t")):
                if comm not in self.od:                    # the drive has fewer PDOs
                    continue
                cob = self._value(comm, 1)
                if cob & PDO_INVALID:
                    continue
                entries = [(e >> 16, (e >> 8) & 0xFF) for e in (self._value(mapping, k)
                                                                 for k in range(1, self._value(mapping, 0) + 1))]
                codec = PdoCodec.of(cob & 0x7FF, self.od, entries)
                ttype = self._value(comm, 2)
                if table == "r":
                    self.rpdos[codec.cob_id] = (codec, ttype)
                else:
                    self.tpdos.append((codec, ttype, [self._getter(i, s) for i, s in codec.entries]))
