"""Streaming ahead: how an axis's setpoints reach its drive, chosen per run and said.

A drive with a deep interpolation buffer takes the plan's records in interpolated position mode on
its own clock, and the master writes them ahead of the time they are taken, in an event-driven
RPDO of their own (transmission type 255), keeping ``master.stall_cover_ms`` of them in the
buffer, at most :data:`~.engine.FEED_PER_PERIOD` a period and axis (a refill never floods the
bus): a stall of the master's host shorter than that leaves the motion untouched.  Two kinds:

* CiA 402's FIFO (0x60C4 organised as a FIFO, holding more records than the master keeps ahead,
  its fill 0x60C4:2 mappable): position records 0x60C1:1, one a SYNC; the fill is read back in a
  synchronous TPDO of its own, and a FIFO run dry is the drive's planned stop.
* maxon's PVT buffer (64 records of 0x20C1, each carrying its own time up to 255 ms; its fill not
  mappable, its status 0x20C4:1 is): one record spans as many SYNC periods as it takes to keep
  the stall cover in half the buffer.  An underflow is a fault on maxon's drives, so the
  records kept ahead are all there is between a stall and a stop.

The controlword (and the torque offset, where mapped) stays synchronous.  Otherwise the drive takes
one setpoint per SYNC as the RPDOs map it (CSP, or IP one record a SYNC): a stall of the host then
stops the setpoints with it.  Which way each axis streams, and why, is recorded with the run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from ..cia.objects import (
    BUFFER_CLEAR,
    BUFFER_FILL,
    BUFFER_MAXIMUM,
    INTERPOLATION_DATA_CONFIGURATION,
    RPDO_COMMUNICATION,
    TPDO_COMMUNICATION,
)
from ..cia.od import default
from ..cia.p402 import IP
from ..cia.setpoint import IP_RECORD, PVT, PVT_BUFFER_STATUS, PVT_RECORD_MAX_S, SETPOINT_OBJECTS
from ..config import MasterConfig, NodeConfig, PdoConfig

#: an event-driven RPDO (CiA 301: manufacturer-specific event; acted on when received)
EVENT_DRIVEN = 255
#: times a run streams a stretch of motion again after a drive's FIFO ran dry in it (a host away
#: more often than that ends the run with the planned stop said)
MAX_REPEATS = 3
FILL = (INTERPOLATION_DATA_CONFIGURATION, BUFFER_FILL)


@dataclass(frozen=True)
class Streaming:
    """How one axis's setpoints reach its drive.

    Parameters
    ----------
    depth : int
        SYNC periods of records kept ahead in the drive's buffer (0: one setpoint per SYNC).
    why : str
        The choice and its reason, in words.
    record : (int, int)
        The record object fed ahead: 0x60C1:1, or maxon's PVT record 0x20C1.
    stride : int
        SYNC periods one record spans (a PVT record's own time; 1 for 0x60C1:1).
    """

    depth: int
    why: str
    record: tuple[int, int] = IP_RECORD
    stride: int = 1

    @property
    def buffered(self) -> bool:
        """Fed ahead into the drive's FIFO."""
        return self.depth > 0


def records_ahead(master: MasterConfig) -> int:
    """The records kept ahead: ``master.stall_cover_ms`` in SYNC periods.

    Parameters
    ----------
    master : MasterConfig
        The master's configuration.

    Returns
    -------
    int
        Records.
    """
    return math.ceil(master.stall_cover_s / master.sync_period_s - 1e-9)


@dataclass(frozen=True)
class Feed:
    """What a drive's buffer is fed ahead: the record object, and the SYNC periods one spans.

    Parameters
    ----------
    record : (int, int)
        0x60C1:1, or maxon's PVT record 0x20C1.
    stride : int
        SYNC periods one record spans.
    """

    record: tuple[int, int]
    stride: int = 1


def feed_way(
    ncfg: NodeConfig, modes: list[int], capacity: int | None, depth: int, period_s: float
) -> Feed | str:
    """How the axis's drive is fed ``depth`` SYNC periods of records ahead, or why it cannot be.

    Parameters
    ----------
    ncfg : NodeConfig
        Its node's configuration (its EDS/DCF).
    modes : list of int
        The modes the drive lists (0x6502).
    capacity : int or None
        The records its buffer holds, as the drive says (0x60C4:1; None: not said).
    depth : int
        The SYNC periods to keep ahead.
    period_s : float
        The SYNC period [s].

    Returns
    -------
    Feed or str
        The way, or the reason there is none, in words.
    """
    od = ncfg.od
    if IP not in modes:
        return "the drive has no interpolated position mode (0x6502)"
    pvt = od.get_variable(*PVT)
    if pvt is not None and pvt.pdo_mappable:
        return _pvt_feed(ncfg, capacity, depth, period_s)
    record, fill = od.get_variable(*IP_RECORD), od.get_variable(*FILL)
    clear = od.get_variable(INTERPOLATION_DATA_CONFIGURATION, BUFFER_CLEAR)
    if record is None or not record.pdo_mappable:
        return "its EDS/DCF maps no interpolation data record 0x60C1:1"
    if fill is None or not fill.pdo_mappable or clear is None:
        return (
            "its interpolation buffer's fill (0x60C4:2) is not mappable, or it cannot be cleared (0x60C4:6)"
        )
    if capacity is None or capacity < 2 * depth:
        return (
            f"its interpolation buffer holds {capacity or 1} record(s) (0x60C4:1), fewer than twice the "
            f"{depth} kept ahead"
        )
    if (
        _free(ncfg, RPDO_COMMUNICATION, ncfg.rpdo) is None
        or _free(ncfg, TPDO_COMMUNICATION, ncfg.tpdo) is None
    ):
        return "no RPDO and TPDO left beside those bus.yml maps"
    return Feed(IP_RECORD)


def _pvt_feed(ncfg: NodeConfig, capacity: int | None, depth: int, period_s: float) -> Feed | str:
    """maxon's PVT buffer: records of whole ms, long enough that ``depth`` periods take at most half
    of its ``capacity`` records."""
    od = ncfg.od
    status = od.get_variable(*PVT_BUFFER_STATUS)
    if (
        status is None
        or not status.pdo_mappable
        or od.get_variable(INTERPOLATION_DATA_CONFIGURATION, BUFFER_CLEAR) is None
    ):
        return "its PVT buffer's status (0x20C4:1) is not mappable, or it cannot be cleared (0x60C4:6)"
    if not capacity:
        return "its PVT buffer does not say how many records it holds (0x60C4:1)"
    stride = max(1, math.ceil(2 * depth / capacity - 1e-9))
    while abs(stride * period_s * 1e3 - round(stride * period_s * 1e3)) > 1e-6:
        stride += 1  # a record's time is whole ms
    if stride * period_s > PVT_RECORD_MAX_S + 1e-9:
        return (
            f"its PVT buffer holds {capacity} records: {depth} periods kept ahead in half of them take "
            f"records of {stride * period_s * 1e3:.0f} ms, longer than the 255 ms one carries"
        )
    if _free(ncfg, RPDO_COMMUNICATION, ncfg.rpdo) is None or (
        not _mapped(ncfg, PVT_BUFFER_STATUS) and _free(ncfg, TPDO_COMMUNICATION, ncfg.tpdo) is None
    ):
        return "no RPDO and TPDO left beside those bus.yml maps"
    return Feed(PVT, stride)


def _mapped(ncfg: NodeConfig, entry: tuple[int, int]) -> bool:
    """A TPDO of bus.yml carries ``entry``."""
    return any(entry in p.mapping for p in ncfg.tpdo)


def capacity_in(ncfg: NodeConfig) -> int | None:
    """The records the drive's FIFO holds as its EDS/DCF says (0x60C4:1; None: not said).

    Parameters
    ----------
    ncfg : NodeConfig
        Its node's configuration.

    Returns
    -------
    int or None
        Records.
    """
    if ncfg.od.get_variable(INTERPOLATION_DATA_CONFIGURATION, BUFFER_MAXIMUM) is None:
        return None
    value = default(ncfg.od, INTERPOLATION_DATA_CONFIGURATION, BUFFER_MAXIMUM)
    return None if value is None else int(value)


def buffered_node(ncfg: NodeConfig, record: tuple[int, int] = IP_RECORD) -> NodeConfig:
    """The node's PDOs for streaming ahead: its RPDOs without their setpoint object (one left empty
    is dropped), an event-driven RPDO carrying ``record``, a synchronous TPDO carrying what shows the
    buffer (the fill 0x60C4:2; for PVT records maxon's status 0x20C4:1, unless a TPDO carries it
    already); each new one the first number the drive has that bus.yml leaves free.

    Parameters
    ----------
    ncfg : NodeConfig
        Its node's configuration (:func:`feed_way` found a way).
    record : (int, int)
        The record object fed ahead (:attr:`Feed.record`).

    Returns
    -------
    NodeConfig
        With the PDOs of the run.
    """
    rpdos = [
        replace(p, mapping=tuple(e for e in p.mapping if e not in SETPOINT_OBJECTS))
        for p in ncfg.rpdo
        if any(e not in SETPOINT_OBJECTS for e in p.mapping)
    ]
    records = PdoConfig(_free(ncfg, RPDO_COMMUNICATION, ncfg.rpdo) or 0, EVENT_DRIVEN, (record,))
    shows = PVT_BUFFER_STATUS if record == PVT else FILL
    tpdos = ncfg.tpdo
    if not _mapped(ncfg, shows):
        tpdos = (*tpdos, PdoConfig(_free(ncfg, TPDO_COMMUNICATION, ncfg.tpdo) or 0, 1, (shows,)))
    return replace(ncfg, rpdo=(*rpdos, records), tpdo=tpdos, position_mode=IP)


def _free(ncfg: NodeConfig, communication: int, configured: tuple[PdoConfig, ...]) -> int | None:
    """The first PDO number (1..4) the drive has that ``configured`` does not use."""
    used = {p.number for p in configured}
    return next(
        (n for n in range(1, 5) if n not in used and communication + n - 1 in ncfg.od),
        None,
    )
