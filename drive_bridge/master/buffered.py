"""Streaming ahead: how an axis's setpoints reach its drive, chosen per run and said.

A drive with a deep interpolation buffer (CiA 402 0x60C4 organised as a FIFO, holding more records
than the master keeps ahead, its fill 0x60C4:2 mappable) takes the plan's position records
0x60C1:1 in interpolated position mode, one a SYNC on its own clock.  The master then writes them
ahead of the SYNCs that take them, in an event-driven RPDO of their own (transmission type 255),
keeping ``master.stall_cover_ms`` of them in the buffer, at most
:data:`~.engine.FEED_PER_PERIOD` a period and axis (a refill never floods the bus): a stall of the master's host shorter than that leaves
the motion untouched.  The controlword (and the torque offset, where mapped) stays synchronous;
the fill is read back in a synchronous TPDO of its own.

Otherwise the drive takes one setpoint per SYNC as the RPDOs map it (CSP, or IP one record a
SYNC): a stall of the host then stops the setpoints with it.  Which way each axis streams, and
why, is recorded with the run.
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
from ..cia.setpoint import IP_RECORD, SETPOINT_OBJECTS
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
        Records kept ahead in the drive's FIFO (0: one setpoint per SYNC).
    why : str
        The choice and its reason, in words.
    """

    depth: int
    why: str

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


def why_not(ncfg: NodeConfig, modes: list[int], capacity: int | None, depth: int) -> str | None:
    """Why the axis's drive cannot be fed ``depth`` records ahead (None: it can).

    Parameters
    ----------
    ncfg : NodeConfig
        Its node's configuration (its EDS/DCF).
    modes : list of int
        The modes the drive lists (0x6502).
    capacity : int or None
        The records its FIFO holds, as the drive says (0x60C4:1; None: not said).
    depth : int
        The records to keep ahead.

    Returns
    -------
    str or None
        The reason, in words.
    """
    od = ncfg.od
    record, fill = od.get_variable(*IP_RECORD), od.get_variable(*FILL)
    clear = od.get_variable(INTERPOLATION_DATA_CONFIGURATION, BUFFER_CLEAR)
    if IP not in modes:
        return "the drive has no interpolated position mode (0x6502)"
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
    return None


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


def buffered_node(ncfg: NodeConfig) -> NodeConfig:
    """The node's PDOs for streaming ahead: its RPDOs without their setpoint object (one left empty
    is dropped), an event-driven RPDO carrying the record 0x60C1:1, a synchronous TPDO carrying the
    fill 0x60C4:2; each new one the first number the drive has that bus.yml leaves free.

    Parameters
    ----------
    ncfg : NodeConfig
        Its node's configuration (:func:`why_not` found nothing).

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
    record = PdoConfig(_free(ncfg, RPDO_COMMUNICATION, ncfg.rpdo) or 0, EVENT_DRIVEN, (IP_RECORD,))
    fill = PdoConfig(_free(ncfg, TPDO_COMMUNICATION, ncfg.tpdo) or 0, 1, (FILL,))
    return replace(ncfg, rpdo=(*rpdos, record), tpdo=(*ncfg.tpdo, fill), position_mode=IP)


def _free(ncfg: NodeConfig, communication: int, configured: tuple[PdoConfig, ...]) -> int | None:
    """The first PDO number (1..4) the drive has that ``configured`` does not use."""
    used = {p.number for p in configured}
    return next(
        (n for n in range(1, 5) if n not in used and communication + n - 1 in ncfg.od),
        None,
    )
