"""The PDOs of a simulated drive as the master maps them, with CiA 301's rules for a mapping
change: the COB-ID changes only while the PDO is invalid and never to a restricted CAN-ID, the
mapping only while the PDO is invalid and its sub-index 0 is 0, only PDO-mappable objects of the
right direction with their own length, at most 8 entries and 64 bits; no reserved transmission
type.  Synchronous RPDOs wait for the next SYNC; synchronous TPDOs go out on every n-th SYNC their
transmission type says; event-driven TPDOs (254, 255) go out on a change of their data (no sooner
than the inhibit time after the last) and when their event timer runs out."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import canopen
from canopen.objectdictionary import ODVariable
from canopen.sdo import SdoAbortedError

from ..cia.objects import RPDO_COMMUNICATION, RPDO_MAPPING, TPDO_COMMUNICATION, TPDO_MAPPING
from ..cia.pdo import PdoCodec

PDO_INVALID = 0x8000_0000
ABORT_RANGE = 0x06090030
ABORT_STATE = 0x08000022
ABORT_NOT_MAPPABLE = 0x06040041
ABORT_PDO_LENGTH = 0x06040042
#: CiA 301 §7.3.5: CAN-IDs no PDO may use (NMT, SYNC/EMCY, TIME, SDO, NMT error control, LSS)
RESTRICTED_IDS = (
    range(0x000, 0x080),
    range(0x101, 0x181),
    range(0x581, 0x600),
    range(0x601, 0x680),
    range(0x6E0, 0x700),
    range(0x701, 0x780),
    range(0x780, 0x800),
)
RESERVED_TRANSMISSION = {"t": range(241, 252), "r": range(241, 254)}
CAN_29BIT = 0x2000_0000


def restricted(cob_id: int) -> bool:
    """Whether a PDO COB-ID's CAN-ID is one CiA 301 reserves for other services.

    Parameters
    ----------
    cob_id : int
        The COB-ID.

    Returns
    -------
    bool
        Reserved.
    """
    return any((cob_id & 0x7FF) in r for r in RESTRICTED_IDS)


@dataclass
class EventPdo:
    """An event-driven TPDO: its codec, the getters of its objects, inhibit time and event timer [s].

    Parameters
    ----------
    codec : PdoCodec
        Its codec.
    getters : list of callable
        The readers of its objects.
    inhibit_s : float
        Its inhibit time [s].
    timer_s : float
        Its event timer [s] (0: off).
    last_time : float
        When it was last sent [s].
    last_data : bytes, optional
        What it last sent.
    """

    codec: PdoCodec
    getters: list[Callable[[], int]]
    inhibit_s: float
    timer_s: float
    last_time: float = -float("inf")
    last_data: bytes | None = field(default=None, repr=False)

    def due(self, now: float, data: bytes) -> bool:
        """Whether to send ``data`` now (and, if so, noted as sent).

        Parameters
        ----------
        now : float
            [s].
        data : bytes
            Its data now.

        Returns
        -------
        bool
            Due: changed, or the event timer ran out, and the inhibit time passed.
        """
        if now - self.last_time < self.inhibit_s - 1e-9:
            return False
        if data == self.last_data and not (self.timer_s and now - self.last_time >= self.timer_s - 1e-9):
            return False
        self.last_time, self.last_data = now, data
        return True


class PdoMapping:
    """The valid RPDOs (COB-ID -> codec, transmission type) and TPDOs (codec, transmission type,
    the getters of their objects) of one drive, rebuilt from its object dictionary; the
    synchronous RPDOs received for the next SYNC (``pending``) and the SYNCs counted.

    ``value(index, sub)`` reads an object as the drive holds it; ``getter(index, sub)`` gives
    the callable a TPDO samples an object with.

    Parameters
    ----------
    od : canopen.ObjectDictionary
        The drive's object dictionary.
    value : callable
        ``value(index, sub)``.
    getter : callable
        ``getter(index, sub)``.
    """

    def __init__(
        self,
        od: canopen.ObjectDictionary,
        value: Callable[[int, int], int],
        getter: Callable[[int, int], Callable[[], int]],
    ):
        self.od, self._value, self._getter = od, value, getter
        self.rpdos: dict[int, tuple[PdoCodec, int]] = {}
        self.tpdos: list[tuple[PdoCodec, int, list[Callable[[], int]]]] = []
        self.events: list[EventPdo] = []
        #: the synchronous RPDOs (codec, data) received since the last SYNC: the next period's
        self.pending: list[tuple[PdoCodec, bytes]] = []
        self._syncs = 0  # SYNCs counted (what a synchronous TPDO's transmission type divides)

    def reset(self) -> None:
        """Power-up: no RPDO pending, the SYNCs counted from 0, the PDOs as the objects map them."""
        self.pending = []
        self._syncs = 0
        self.rebuild()

    def count_sync(self) -> int:
        """One more SYNC: its count.

        Returns
        -------
        int
            The SYNCs counted.
        """
        self._syncs += 1
        return self._syncs

    def synchronous_frames(self) -> Iterator[tuple[int, bytes]]:
        """A SYNC counted: (COB-ID, data) of each synchronous TPDO due at it, its objects read now."""
        count = self.count_sync()
        for codec, ttype, getters in self.tpdos:
            if 1 <= ttype <= 240 and count % ttype == 0:
                yield codec.cob_id, codec.struct.pack(*[g() for g in getters])

    def event_frames(self, now: float) -> Iterator[tuple[int, bytes]]:
        """(COB-ID, data) of each event-driven TPDO due at ``now`` [s], its objects read now.

        Parameters
        ----------
        now : float
            [s].

        Yields
        ------
        (int, bytes)
            COB-ID, data.
        """
        for pdo in self.events:
            data = pdo.codec.struct.pack(*[g() for g in pdo.getters])
            if pdo.due(now, data):
                yield pdo.codec.cob_id, data

    def check_write(self, index: int, sub: int, value: int) -> None:
        """Raise SdoAbortedError when a write to a PDO parameter breaks CiA 301's rules.

        Parameters
        ----------
        index, sub : int
            The object.
        value : int
            The value.

        Raises
        ------
        SdoAbortedError
            With the abort code a drive gives.
        """
        is_map = (index & 0xFF00) in (RPDO_MAPPING, TPDO_MAPPING)
        comm = (index & ~0x0200) if is_map else index  # 0x16xx -> 0x14xx, 0x1Axx -> 0x18xx
        cob = self._value(comm, 1)
        if not is_map:
            if (
                sub == 1
                and not cob & PDO_INVALID
                and not value & PDO_INVALID
                and (value & 0x7FF) != (cob & 0x7FF)
            ):
                raise SdoAbortedError(ABORT_RANGE)  # change the COB-ID only while invalid
            if sub == 1 and (value & CAN_29BIT or (not value & PDO_INVALID and restricted(value))):
                raise SdoAbortedError(ABORT_RANGE)  # a restricted CAN-ID, or 29-bit (not supported)
            if sub == 2 and value in RESERVED_TRANSMISSION["t" if index >= TPDO_COMMUNICATION else "r"]:
                raise SdoAbortedError(ABORT_RANGE)  # reserved transmission type
            return
        if not cob & PDO_INVALID:
            raise SdoAbortedError(ABORT_STATE)  # map only while the PDO is invalid
        if sub == 0:
            bits = 0
            for n in range(1, value + 1):
                entry = self._value(index, n)
                if (
                    self._mappable(entry >> 16, (entry >> 8) & 0xFF, index >= TPDO_MAPPING, entry & 0xFF)
                    is None
                ):
                    raise SdoAbortedError(ABORT_NOT_MAPPABLE)
                bits += entry & 0xFF
            if value > 8 or bits > 64:
                raise SdoAbortedError(ABORT_PDO_LENGTH)
        else:
            if self._value(index, 0) != 0:
                raise SdoAbortedError(ABORT_STATE)  # sub 0 must be 0 while entries change
            if (
                value
                and self._mappable(value >> 16, (value >> 8) & 0xFF, index >= TPDO_MAPPING, value & 0xFF)
                is None
            ):
                raise SdoAbortedError(ABORT_NOT_MAPPABLE)

    def _mappable(self, index: int, sub: int, tpdo: bool, bits: int | None = None) -> ODVariable | None:
        """The object an entry maps, None where it cannot be mapped so (not mappable, the wrong
        direction, or ``bits`` other than its own length)."""
        var = self.od.get_variable(index, sub)
        if (
            var is None
            or not var.pdo_mappable
            or (tpdo and not var.readable)
            or (not tpdo and not var.writable)
        ):
            return None
        if bits is not None and bits != len(var):
            return None
        return var

    def rebuild(self) -> None:
        """Compile the codecs of every valid PDO."""
        self.rpdos, self.tpdos, self.events = {}, [], []
        for n in range(4):
            for comm, mapping, table in (
                (RPDO_COMMUNICATION + n, RPDO_MAPPING + n, "r"),
                (TPDO_COMMUNICATION + n, TPDO_MAPPING + n, "t"),
            ):
                if comm not in self.od:  # the drive has fewer PDOs
                    continue
                cob = self._value(comm, 1)
                if cob & PDO_INVALID:
                    continue
                entries = [
                    (e >> 16, (e >> 8) & 0xFF)
                    for e in (self._value(mapping, k) for k in range(1, self._value(mapping, 0) + 1))
                ]
                codec = PdoCodec.of(cob & 0x7FF, self.od, entries)
                ttype = self._value(comm, 2)
                if table == "r":
                    self.rpdos[codec.cob_id] = (codec, ttype)
                elif ttype in (254, 255):
                    inhibit, timer = (
                        self._value(comm, k) if self.od.get_variable(comm, k) is not None else 0
                        for k in (3, 5)
                    )
                    self.events.append(
                        EventPdo(
                            codec,
                            [self._getter(i, s) for i, s in codec.entries],
                            inhibit * 1e-4,
                            timer * 1e-3,
                        )
                    )
                else:
                    self.tpdos.append((codec, ttype, [self._getter(i, s) for i, s in codec.entries]))
