"""Bus-load budget of a cyclic plan: bits on the wire per second against the bitrate."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import canopen

from ..cia.od import variable
from ..config import BusConfig
from ..errors import UserError

MAX_LOAD = 0.80


def frame_bits(data_bytes: int) -> int:
    """Worst-case bits of a standard (11-bit) data frame, stuff bits and interframe space included.

    Parameters
    ----------
    data_bytes : int
        Its data length.

    Returns
    -------
    int
        The bits.
    """
    body = 34 + 8 * data_bytes  # bits exposed to stuffing: SOF .. CRC
    return body + (body - 1) // 4 + 13  # + stuff bits + CRC delimiter, ACK, EOF, IFS


@dataclass(frozen=True)
class BusLoad:
    """A SYNC period's load on the bus (:func:`bus_load`).

    Parameters
    ----------
    bits_per_cycle : int
        Worst-case bits per SYNC period.
    bits_per_second : float
        [bit/s].
    load : float
        The share of the bitrate.
    """

    bits_per_cycle: int
    bits_per_second: float
    load: float

    def describe(self) -> str:
        """The load in words.

        Returns
        -------
        str
            ``12.3 % (123 kbit/s)``.
        """
        return f"{self.load * 100:.1f} % ({self.bits_per_second / 1000:.0f} kbit/s)"


def pdo_bytes(od: canopen.ObjectDictionary, mapping: Iterable[tuple[int, int]]) -> int:
    """Bytes of a PDO that maps ``mapping`` ((index, sub-index) pairs).

    Parameters
    ----------
    od : canopen.ObjectDictionary
        The drive's object dictionary (the objects' sizes).
    mapping : iterable of (int, int)
        The objects mapped.

    Returns
    -------
    int
        The bytes.
    """
    return sum(len(variable(od, i, s)) for i, s in mapping) // 8


def bus_load(config: BusConfig) -> BusLoad:
    """Load of one SYNC period: SYNC + every enabled RPDO and TPDO of every node.

    Parameters
    ----------
    config : BusConfig
        The bus configuration (its nodes' PDOs, the bitrate).

    Returns
    -------
    BusLoad
        The load.
    """
    bits: float = frame_bits(0)  # SYNC
    for node in config.nodes.values():
        for pdo in node.rpdo:
            bits += frame_bits(pdo_bytes(node.od, pdo.mapping))
        for pdo in node.tpdo:
            bits += frame_bits(pdo_bytes(node.od, pdo.mapping)) / pdo.transmission
    per_s = bits / config.master.sync_period_s
    return BusLoad(int(bits), per_s, per_s / config.master.nominal_bitrate)


def check_bus_load(config: BusConfig) -> BusLoad:
    """Refuse a plan above 80 % of the bitrate with what to change.

    Parameters
    ----------
    config : BusConfig
        The bus configuration.

    Returns
    -------
    BusLoad
        The load.

    Raises
    ------
    UserError
        Above 80 %, with what to change.
    """
    load = bus_load(config)
    if load.load > MAX_LOAD:
        raise UserError(
            f"{config.path}: the cyclic plan needs {load.describe()} of {config.master.nominal_bitrate / 1000:.0f} "
            f"kbit/s, above the {MAX_LOAD:.0%} budget. Map fewer or shorter PDOs (nodes.<axis>.tpdo/rpdo), "
            f"send TPDOs every n-th SYNC (transmission: n), lengthen master.sync_period, "
            f"or raise master.bitrate."
        )
    return load
