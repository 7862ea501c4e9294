"""The recording of a streamed plan: samples in device units, one row per SYNC period, as the
cyclic engine writes them live and as :func:`drive_bridge.logs.decode_trace` rebuilds them from a
trace (SI once, afterwards, in :mod:`drive_bridge.logs`)."""

from __future__ import annotations

from collections import deque
from collections.abc import Callable

import numpy as np

from ..cia.objects import CONTROLWORD
from ..cia.pdo import PdoCodec
from ..cia.setpoint import SETPOINT_OBJECTS, position_of
from .engine import (
    Arrays,
)

#: decoding a trace: a TPDO is placed in the row of the newest SYNC before its time stamp, looking
#: back at most this many rows (a reply the master took in after the next SYNC went out)
FEEDBACK_LAG = 1


class Recording:
    """Samples in device units, one row per SYNC period of the plan.

    ``raw`` holds the TPDO objects of every axis side by side (``columns``
    names them as (axis, index)); ``got`` says which TPDO of which row arrived;
    ``demand`` is the position each drive took at the row's SYNC (what the last
    RPDO before it carried); ``sync_time`` the SYNC's time stamp, NaN for a period
    a late master sent no SYNC in (``skipped``).  :meth:`handlers` gives the
    per-COB-ID callbacks that rebuild it from a trace (:mod:`drive_bridge.logs`);
    live, the cyclic engine writes the same arrays (``arrays``, its own).

    A TPDO belongs to the last SYNC sent before it; when it is read after the
    next SYNC went out, its frame time stamp (taken when it reached the bus,
    before that SYNC) still places it in its own row.

    Parameters
    ----------
    tpdos : dict of str to list of PdoCodec
        Per axis, its TPDOs.
    rpdos : dict of str to list of PdoCodec
        Per axis, its RPDOs.
    n_cycles : int
        The plan's rows.
    arrays : Arrays, optional
        The cyclic engine's arrays, where it writes them live.
    """

    def __init__(
        self,
        tpdos: dict[str, list[PdoCodec]],
        rpdos: dict[str, list[PdoCodec]],
        n_cycles: int,
        arrays: Arrays | None = None,
    ):
        self.axes = list(tpdos)
        self.columns: list[tuple[str, int]] = []
        self._tpdo_slots: list[tuple[int, PdoCodec, int, int]] = []  # (cob, codec, first column, got column)
        for axis, codecs in tpdos.items():
            for codec in codecs:
                self._tpdo_slots.append((codec.cob_id, codec, len(self.columns), len(self._tpdo_slots)))
                self.columns.extend((axis, index) for index in codec.objects)
        self._rpdo_slots = []
        #: decode: per axis whose setpoints come in RPDOs of records alone (interpolation data,
        #: streamed one a SYNC or fed ahead into the drive's FIFO), the records not yet taken: one
        #: each SYNC, in order, as the drive takes them
        self._queued: dict[int, deque[int]] = {}
        for ai, codecs in enumerate(rpdos.values()):
            for codec in codecs:
                for pos, entry in enumerate(codec.entries):
                    if entry in SETPOINT_OBJECTS:
                        self._rpdo_slots.append((codec.cob_id, codec, pos, ai, entry))
                        if CONTROLWORD not in codec.objects:
                            self._queued[ai] = deque()
        #: per axis, the columns of ``got`` (its TPDOs): a row is complete when all of them arrived
        self.slots = {
            axis: [slot for _, _, first, slot in self._tpdo_slots if self.columns[first][0] == axis]
            for axis in self.axes
        }
        if arrays is not None:
            self.raw, self.got, self.demand, self.sync_time = (
                arrays.raw,
                arrays.got,
                arrays.demand,
                arrays.sync_time,
            )
        else:
            self.raw = np.zeros((n_cycles, len(self.columns)), dtype=np.int64)
            self.got = np.zeros((n_cycles, len(self._tpdo_slots)), dtype=bool)
            self.demand = np.zeros((n_cycles, len(self.axes)), dtype=np.int64)
            self.sync_time = np.full(n_cycles, np.nan)
        self.pending = [0] * len(self.axes)  # position the last RPDO carried, per axis (decode)
        self.sync_index = -1  # row of the last SYNC sent (TPDOs after it belong to it)
        self.last_sync_time = -np.inf
        self.rows = 0  # rows up to the last one with a SYNC
        #: SYNCs still to come before the plan's first (decode: those that enabled the drives)
        self.skip_syncs = 0
        #: rows whose period got no SYNC (a late master sends the SYNC of the period it is in)
        self.skipped: set[int] = set()

    def column(self, axis: str, index: int) -> int:
        """The column of ``raw`` that holds an object of an axis.

        Parameters
        ----------
        axis : str
            The axis.
        index : int
            The object's index.

        Returns
        -------
        int
            The column.
        """
        return self.columns.index((axis, index))

    def handlers(self) -> dict[int, Callable]:
        """COB-ID -> callback(can_id, data, timestamp) for every TPDO and RPDO of the plan.

        Returns
        -------
        dict of int to callable
            The callbacks.
        """
        out: dict[int, Callable[..., None]] = {}
        raw, got, sync_time = self.raw, self.got, self.sync_time
        for cob, codec, first, slot in self._tpdo_slots:

            def on_tpdo(
                can_id: int,
                data: bytearray,
                ts: float,
                first: int = first,
                last: int = first + len(codec.objects),
                unpack: Callable = codec.struct.unpack_from,
                size: int = codec.struct.size,
                slot: int = slot,
            ) -> None:
                row = back = self.sync_index
                if ts < self.last_sync_time and row < len(raw):  # reached the bus before that SYNC
                    while back > 0 and back >= row - FEEDBACK_LAG and not sync_time[back] <= ts:
                        back -= 1
                    if sync_time[back] <= ts:
                        row = back
                if 0 <= row < len(raw) and len(data) >= size:
                    raw[row, first:last] = unpack(data)
                    got[row, slot] = True

            out[cob] = on_tpdo
        for cob, codec, pos, ai, entry in self._rpdo_slots:

            def on_rpdo(
                can_id: int,
                data: bytearray,
                ts: float,
                unpack: Callable = codec.struct.unpack_from,
                pos: int = pos,
                ai: int = ai,
                entry: tuple[int, int] = entry,
            ) -> None:
                position = position_of(entry, unpack(data)[pos])
                if ai in self._queued:
                    self._queued[ai].append(position)
                else:
                    self.pending[ai] = position

            out[cob] = on_rpdo
        return out

    def on_sync(self, timestamp: float, lost: int = 0) -> None:
        """A SYNC: the next row (past the periods a late master skipped, and the SYNCs its counter
        says were ``lost`` before it), the SYNCs that enabled the drives before the plan's first not
        counted.

        Parameters
        ----------
        timestamp : float
            Its time stamp [s].
        lost : int
            SYNCs sent before it that the trace does not hold.
        """
        lost_before_plan = min(lost, self.skip_syncs)
        self.skip_syncs -= lost_before_plan
        self.sync_index += lost - lost_before_plan
        if self.skip_syncs > 0:
            self.skip_syncs -= 1
            return
        for ai, records in self._queued.items():
            if records:
                self.pending[ai] = records.popleft()
        self.last_sync_time = timestamp
        self.sync_index += 1
        while self.sync_index in self.skipped:
            self.sync_index += 1
        if self.sync_index < len(self.raw):
            self.sync_time[self.sync_index] = timestamp
            self.demand[self.sync_index] = self.pending
            self.rows = self.sync_index + 1

    def valid(self, axis: str) -> np.ndarray:
        """Per row: every TPDO of ``axis`` arrived (a complete sample).

        Parameters
        ----------
        axis : str
            The axis.

        Returns
        -------
        numpy.ndarray
            A boolean per row.
        """
        return np.asarray(self.got[:, self.slots[axis]].all(axis=1))

    def missing(self) -> dict[str, int]:
        """Rows without a complete sample, per axis (rows of periods without a SYNC included).

        Returns
        -------
        dict of str to int
            Per axis, the count.
        """
        return {axis: int(np.count_nonzero(~self.valid(axis)[: self.rows])) for axis in self.axes}

    def resume(self, keep: int, then: Recording, skip: int) -> None:
        """Its first ``keep`` rows, then the rows of ``then`` (the same axes and PDOs: the plan
        streamed again from row ``keep`` after ``skip`` rows of approach): a segment repeated.
        A repeat stopped before its approach ended leaves the rows as they were.

        Parameters
        ----------
        keep : int
            The rows kept (the repeated segment's first row).
        then : Recording
            The repeat's recording (truncated).
        skip : int
            Its approach's rows.
        """
        if len(then.raw) <= skip:
            return
        self.raw = np.concatenate([self.raw[:keep], then.raw[skip:]])
        self.got = np.concatenate([self.got[:keep], then.got[skip:]])
        self.demand = np.concatenate([self.demand[:keep], then.demand[skip:]])
        self.sync_time = np.concatenate([self.sync_time[:keep], then.sync_time[skip:]])
        self.skipped = {r for r in self.skipped if r < keep} | {
            r - skip + keep for r in then.skipped if r >= skip
        }
        self.rows = len(self.raw)

    def truncate(self) -> None:
        """Drop rows after the last SYNC (the plan was not finished) -- but for the plan's last
        periods a late master sent no SYNC in (``skipped``): rows of the run like any period
        skipped, as the engine counts them (:meth:`.engine.Engine._on_sync`)."""
        while self.rows < len(self.raw) and self.rows in self.skipped:
            self.rows += 1
        n = self.rows
        self.raw, self.got, self.demand, self.sync_time = (
            self.raw[:n],
            self.got[:n],
            self.demand[:n],
            self.sync_time[:n],
        )
