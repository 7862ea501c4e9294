"""The SYNC of drives that stream, in one compiled call.

While every drive follows the master in CSP with its controlword held
(:attr:`SimDrive.streaming <drive_bridge.sim.drive.SimDrive.streaming>`), a SYNC does the same
for each: sample the actual values, send the synchronous TPDOs, take the target the RPDOs
brought, start the next interpolation period.  :class:`SteadyStream` lays the drives' PDOs out
once and runs that SYNC as :func:`.cyclic.steady_period` (the Python drive's own functions for
actual values and the period, compiled), sending the TPDO bytes it packed.  Whatever else may
happen in a period -- a fault, a heartbeat due or a watched node's silence, a controlword or a
modes of operation that changes, an RPDO writing anything else, a TPDO mapping an object the
compiled path does not know -- is the Python drive's: :meth:`SteadyStream.period` declines
before changing anything, and the robot runs the SYNC as before.  Both give the same frames byte
for byte (``tests/sim/test_steady.py``).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from ..cia.objects import (
    CONTROLWORD,
    FOLLOWING_ERROR_ACTUAL,
    MODES_OF_OPERATION,
    POSITION_ACTUAL,
    STATUSWORD,
    TARGET_POSITION,
    TORQUE_ACTUAL,
    TORQUE_OFFSET,
    VELOCITY_ACTUAL,
    VELOCITY_OFFSET,
)
from . import cyclic
from .plant import Plant

if TYPE_CHECKING:
    from .drive import SimDrive

#: TPDO objects whose value changes every period -> what steady_period computes for them
#: (every other mapped object is constant while the drive streams, read when the plan is refreshed)
MEASURED = {
    STATUSWORD: cyclic.SRC_STATUSWORD,
    POSITION_ACTUAL: cyclic.SRC_POSITION,
    VELOCITY_ACTUAL: cyclic.SRC_VELOCITY,
    TORQUE_ACTUAL: cyclic.SRC_TORQUE,
    FOLLOWING_ERROR_ACTUAL: cyclic.SRC_FOLLOWING_ERROR,
}
#: what an RPDO of a streaming drive may write: the controlword and the modes of operation (both
#: held: a master may send its mode every period, as ros2_canopen's mapping does), the CSP target
#: and the torque and velocity offsets (the kernel reads those only as the plant advances: they
#: are written as the Python drive writes them)
STREAMED = {
    (CONTROLWORD, 0),
    (MODES_OF_OPERATION, 0),
    (TARGET_POSITION, 0),
    (TORQUE_OFFSET, 0),
    (VELOCITY_OFFSET, 0),
}
OFFSETS = (TORQUE_OFFSET, VELOCITY_OFFSET)
#: struct codes of the integer types a TPDO entry may have -> (signed, size in bytes)
INTEGERS = {
    "b": (True, 1),
    "B": (False, 1),
    "h": (True, 2),
    "H": (False, 2),
    "i": (True, 4),
    "I": (False, 4),
    "l": (True, 4),
    "L": (False, 4),
    "q": (True, 8),
}
#: what the statusword's bits 11 (internal limit active) and 13 (following error) leave to the period
STATUS_PER_PERIOD = 0x0800 | 0x2000


class SteadyStream:
    """The streaming SYNC of the ``drives`` of ``plant`` (in its row order), sending through
    ``send`` (COB-ID, data): their PDOs laid out for :func:`.cyclic.steady_period` (``supported``
    False where one cannot be).

    Parameters
    ----------
    plant : Plant
        The plant.
    drives : list of SimDrive
        Its drives, in row order.
    send : callable
        ``send(cob_id, data)``.
    """

    def __init__(self, plant: Plant, drives: list[SimDrive], send: Callable[[int, bytes], None]):
        self.plant = plant
        self.drives = drives
        self.send = send
        self.stale = True  # the per-drive values (limits, times, constants) to be read anew
        self.own_periods = False  # a drive interpolates over a period of its own (0x60C2)
        self._offsets: dict[tuple[int, int], int] = {}  # (axis, object) -> the offset it last wrote
        self.supported = self._layout()

    def _layout(self) -> bool:
        entries: list[list[int]] = []
        #: per drive: (row of ``out``, COB-ID, transmission type, length) of each synchronous TPDO
        self.tpdos: list[list[tuple[int, int, int, int]]] = []
        self._constants: list[tuple[int, Callable[[], int]]] = []  # (entry, its getter)
        row = 0
        for a, drive in enumerate(self.drives):
            written = {e for codec, _ in drive.rpdos.values() for e in codec.entries}
            if drive.pdos.events or not written <= STREAMED or any(t > 240 for _, t in drive.rpdos.values()):
                return False
            current = set(drive.spec.current_objects)
            mine: list[tuple[int, int, int, int]] = []
            for codec, ttype, getters in drive.pdos.tpdos:
                if not 1 <= ttype <= 240:
                    continue
                for (index, sub), (lo, hi), code, getter in zip(
                    codec.entries, codec.spans, codec.struct.format.lstrip("<"), getters
                ):
                    if code not in INTEGERS or (index, sub) in written:
                        return False
                    signed, size = INTEGERS[code]
                    bits = 8 * size
                    low, high = (-(1 << bits - 1), (1 << bits - 1) - 1) if signed else (0, (1 << bits) - 1)
                    source = cyclic.SRC_CURRENT if index in current else MEASURED.get(index, cyclic.SRC_CONST)
                    if source == cyclic.SRC_CONST:
                        self._constants.append((len(entries), getter))
                    entries.append([a, source, 0, row, lo, hi - lo, low, high])
                mine.append((row, codec.cob_id, ttype, codec.struct.size))
                row += 1
            self.tpdos.append(mine)
        self.entries = np.array(entries, dtype=np.int64).reshape(-1, cyclic.N_ENTRY)
        self.out = np.zeros((max(1, row), 8), dtype=np.uint8)
        self.axes = np.zeros((len(self.drives), cyclic.N_AXIS))
        self.noisy = int(np.count_nonzero(self.plant.drive_rows[:, cyclic.X_NOISE]))  # noise samples a period
        return True

    def _refresh(self) -> None:
        """Read what holds while the drives stream: limits, fault thresholds, the statusword's
        steady bits, the constant TPDO objects and when a drive next has its own business."""
        self.wake = math.inf
        for a, drive in enumerate(self.drives):
            axis = self.axes[a]
            axis[cyclic.A_LO], axis[cyclic.A_HI] = drive.software_limits()
            axis[cyclic.A_FE_TICKS] = drive.following_error_ticks()
            axis[cyclic.A_TIMEOUT] = drive.setpoint_timeout()
            axis[cyclic.A_STATUS] = drive.statusword & ~STATUS_PER_PERIOD
            self.wake = min(self.wake, drive.next_due())
        # a drive interpolating over another period than the SYNC's (0x60C2) runs in Python
        self.own_periods = any(d.interpolation_ticks() != self.plant.ticks_per_period for d in self.drives)
        if not self.own_periods:
            self.plant.period_ticks[:] = self.plant.ticks_per_period
        for entry, getter in self._constants:
            self.entries[entry, cyclic.E_CONST] = getter()
        self._offsets.clear()  # the Python drive may have written others since
        self.stale = False

    def period(self) -> bool:
        """Run this SYNC of every drive (the plant has advanced to it); False, having changed
        nothing, where it is the Python drive's to run.

        Returns
        -------
        bool
            Run here.
        """
        if not self.supported:
            return False
        for drive in self.drives:
            if not drive.streaming:
                return False
        if self.stale:
            self._refresh()
        if self.own_periods:
            return False
        plant = self.plant
        now = plant.time
        if now >= self.wake - 1e-9:
            return False
        axes = self.axes
        taken = []
        for a, drive in enumerate(self.drives):
            axes[a, cyclic.A_HAS_SETPOINT] = 0.0
            for codec, data in drive.pdos.pending:
                values = codec.struct.unpack_from(data)
                for (index, _), value in zip(codec.entries, values):
                    if (index == CONTROLWORD and value != drive.controlword) or (
                        index == MODES_OF_OPERATION and value != drive.mode
                    ):
                        return False
                    if index == TARGET_POSITION:
                        axes[a, cyclic.A_SETPOINT] = value
                        axes[a, cyclic.A_HAS_SETPOINT] = 1.0
                taken.append((a, drive, codec, data, values))
        noise, index = plant.reserve_noise(self.noisy)
        index = cyclic.steady_period(
            plant.state,
            plant.param,
            plant.demand,
            plant.drive_rows,
            axes,
            self.entries,
            noise,
            index,
            now,
            plant.sync_period,
            self.out,
        )
        if index == cyclic.SLOW:
            return False
        if index == cyclic.OUT_OF_RANGE:
            raise struct.error("a value the simulated drive sends does not fit its TPDO entry")
        plant.take_noise(index)
        offsets = self._offsets
        for a, drive, codec, data, values in taken:
            for (i, sub), (lo, hi), value in zip(codec.entries, codec.spans, values):
                if i in OFFSETS and offsets.get((a, i)) != value:  # (the loops read them as they advance)
                    drive.write(i, sub, value)
                    offsets[(a, i)] = value
                drive.objects.keep(i, sub, data[lo:hi], value)
        out, send = self.out, self.send
        for drive, tpdos in zip(self.drives, self.tpdos):
            drive.pdos.pending.clear()
            count = drive.pdos.count_sync()
            for row, cob_id, ttype, size in tpdos:
                if count % ttype == 0:
                    send(cob_id, out[row, :size].tobytes())
        return True
