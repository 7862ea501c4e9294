"""Frames in, samples out: a listener that rebuilds each axis's samples from the SYNCs, TPDOs and
setpoint RPDOs it sees, one row per SYNC, in chunks of :data:`CHUNK_S` seconds (the same
:class:`~drive_bridge.master.recording.Recording` a record and a decoded trace use), and hands
each chunk on in SI, as log.csv's columns.  It never sends: it has nothing to send with."""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import can
import numpy as np

from ..cia.p301 import SYNC_COB_ID
from ..logs import to_table
from ..master.recording import Recording
from .layout import Layout

log = logging.getLogger(__name__)

CHUNK_S = 10.0  # the samples of this many seconds of SYNCs are handed on together
NO_SYNC_FRAMES = 1000  # this many PDOs without a SYNC: said once (the drives send them event-driven)
IDLE_S = 1.0  # no SYNC for this long: the samples so far are handed on (the machine stopped)


@dataclass
class Chunk:
    """The samples of one axis over a stretch of SYNCs: ``time`` [s] (each row's SYNC, as
    stamped on the bus), ``columns`` (log.csv's names, SI) with ``values`` (rows x columns) and,
    per row, whether the axis moved.

    Parameters
    ----------
    axis : str
        The axis.
    time : numpy.ndarray
        Each row's SYNC time stamp [s].
    columns : list of str
        log.csv's names.
    values : numpy.ndarray
        Rows × columns, SI.
    moving : numpy.ndarray
        Per row, whether the axis moved.
    """

    axis: str
    time: np.ndarray
    columns: list[str]
    values: np.ndarray
    moving: np.ndarray

    @property
    def moving_s(self) -> float:
        """Time the axis moved [s] (its moving rows times their median spacing)."""
        if len(self.time) < 2:
            return 0.0
        return float(np.count_nonzero(self.moving) * np.median(np.diff(self.time)))


class Listener(can.Listener):
    """Samples of every axis of ``layout`` from the frames it is handed (:meth:`frame`, or as a
    python-can listener); ``on_chunk`` gets each axis's :class:`Chunk` every :data:`CHUNK_S` of
    SYNCs, and when the SYNCs stop for :data:`IDLE_S` (:meth:`idle`).

    Parameters
    ----------
    layout : Layout
        What it decodes.
    on_chunk : callable
        Gets each :class:`Chunk`.
    chunk_s : float
        SYNC time per chunk [s].
    """

    def __init__(self, layout: Layout, on_chunk: Callable[[Chunk], None], chunk_s: float = CHUNK_S):
        self.layout = layout
        self.on_chunk = on_chunk
        self._rows = max(16, round(chunk_s / layout.period))
        self.syncs = 0
        self.last_sync: float | None = None
        #: per axis, whether a setpoint RPDO was seen (else its demand column is left out)
        self.setpoints_seen: set[str] = set()
        self._setpoint_cobs = {c.cob_id for codecs in layout.rpdos.values() for c in codecs}
        #: each PDO's length as bus.yml maps it; a frame of another length is not decoded
        self._sizes = {
            c.cob_id: (a, c.struct.size)
            for group in (layout.tpdos, layout.rpdos)
            for a, cs in group.items()
            for c in cs
        }
        #: COB-ID -> the length its frames had where it was not the mapping's (said once each)
        self.mismatched: dict[int, int] = {}
        self._unsynced = 0  # PDOs before any SYNC
        self._start()

    def _start(self) -> None:
        self._rec = Recording(self.layout.tpdos, self.layout.rpdos, self._rows)
        self._handlers = self._rec.handlers()

    def frame(self, can_id: int, data: bytes | bytearray, timestamp: float) -> None:
        """One frame seen on the bus at ``timestamp`` [s].

        Parameters
        ----------
        can_id : int
            Its COB-ID.
        data : bytes or bytearray
            Its data.
        timestamp : float
            [s].
        """
        if can_id == SYNC_COB_ID and len(data) <= 1:
            if self._rec.rows >= self._rows:
                self.flush()
            self._rec.on_sync(timestamp)
            self.syncs += 1
            self.last_sync = timestamp
            return
        handler = self._handlers.get(can_id)
        if handler is not None:
            if not self.syncs:
                self._unsynced += 1
                if self._unsynced == NO_SYNC_FRAMES:
                    log.warning(
                        "%d PDOs and no SYNC so far: monitor takes one row per SYNC (synchronous "
                        "TPDOs); the machine's drives seem to send theirs event-driven, which it "
                        "cannot sample",
                        NO_SYNC_FRAMES,
                    )
            axis, size = self._sizes[can_id]
            if len(data) != size:
                if can_id not in self.mismatched:
                    self.mismatched[can_id] = len(data)
                    log.warning(
                        "axis %s: PDO 0x%03X carries %d bytes, bus.yml maps %d: the drive's mapping is "
                        "not bus.yml's (its frames are not decoded); give bus.yml the mapping the "
                        "production master configures",
                        axis,
                        can_id,
                        len(data),
                        size,
                    )
                return
            handler(can_id, data, timestamp)
            if can_id in self._setpoint_cobs:
                self.setpoints_seen.add(axis)

    def on_message_received(self, msg: can.Message) -> None:
        if not (msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id):
            self.frame(msg.arbitration_id, msg.data, msg.timestamp)

    def idle(self, now: float) -> None:
        """Hand on the samples so far where no SYNC came for :data:`IDLE_S` up to ``now`` [s]
        (on the clock the frames are stamped with).

        Parameters
        ----------
        now : float
            [s].
        """
        if self._rec.rows and self.last_sync is not None and now - self.last_sync >= IDLE_S:
            self.flush()

    def flush(self) -> None:
        """Hand on the samples so far, one :class:`Chunk` per axis, and start afresh."""
        rec, n = self._rec, self._rec.rows
        self._start()
        if n < 2:
            return
        rec.truncate()
        names, values, _ = to_table(rec, self.layout.scaling, self.layout.period)
        time = rec.sync_time[:n].copy()
        for axis in self.layout.tpdos:
            keep = [
                j
                for j, name in enumerate(names)
                if name.startswith(f"{axis}_")
                and not (name.endswith("_position_demand_rad") and axis not in self.setpoints_seen)
            ]
            columns = [names[j] for j in keep]
            table = values[:, keep]
            self.on_chunk(Chunk(axis, time, columns, table, self._moving(axis, columns, table, time)))

    def _moving(self, axis: str, columns: list[str], table: np.ndarray, time: np.ndarray) -> np.ndarray:
        """Per row: the axis moves faster than its threshold (the velocity it reports where a TPDO
        maps it, else the position's slope)."""
        by_name = dict(zip(columns, table.T))
        velocity = by_name.get(f"{axis}_velocity_rad_s")
        if velocity is None:
            position = by_name[f"{axis}_position_rad"]
            velocity = np.gradient(position, time) if len(time) > 1 else np.zeros(len(time))
        return np.nan_to_num(np.abs(velocity)) > self.layout.moving_rad_s[axis]
