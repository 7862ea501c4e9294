"""maxon's PVT input buffer (EPOS Application Note "Interpolation Position Mode", Dec 2008,
pp. 13-16): the records interpolated position mode takes one a period, its status 0x20C4:1 and
what an underflow or an overflow does.  The EMCY codes are the simulation's choice (maxon's are
not in ../shared)."""

from __future__ import annotations

from ..cia.setpoint import unpack_pvt
from .record_buffer import RecordBuffer

RECORDS = 64  # the buffer's size
#: 0x20C4:1 status bits
UNDERFLOW_WARNING, OVERFLOW_WARNING, UNDERFLOW, OVERFLOW = 0x0001, 0x0002, 0x0100, 0x0200
ENABLED, ACTIVE = 0x4000, 0x8000
#: the EMCY codes of an underflow and an overflow (the trajectory aborted: a fault)
ERR_UNDERFLOW, ERR_OVERFLOW = 0xFF02, 0xFF03


class PvtBuffer(RecordBuffer[tuple[int, int, int]]):
    """The records (position, velocity, time [ms], in device units) received and not yet taken,
    whether access to the buffer is enabled, and the error bits latched since it was last cleared."""

    def __init__(self) -> None:
        super().__init__()
        self.errors = 0

    def reset(self) -> None:
        """Power-up: empty, disabled, no error."""
        super().reset()
        self.errors = 0

    def control(self, value: int) -> None:
        """0x60C4:6, buffer clear: 0 clears and disables it (and its errors), 1 enables it.

        Parameters
        ----------
        value : int
            0 or 1.
        """
        super().control(value)
        if value == 0:
            self.errors = 0

    def put(self, value: int) -> int | None:
        """A PVT record (0x20C1 as written) into the buffer: None, or the EMCY code of the fault it
        causes (an overflow).  With access disabled it is dropped.

        Parameters
        ----------
        value : int
            The record.

        Returns
        -------
        int or None
            The EMCY code of the fault it causes.
        """
        if not self.enabled:
            return None
        if len(self.records) >= RECORDS:
            self.errors |= OVERFLOW
            return ERR_OVERFLOW
        self.records.append(unpack_pvt(value))
        return None

    def take(self) -> tuple[int, int, int] | None:
        """The next record, or None where the buffer ran dry (an underflow, latched).

        Returns
        -------
        (int, int, int) or None
            Position, velocity, time.
        """
        if self.records:
            return self.records.popleft()
        self.errors |= UNDERFLOW
        return None

    def status(self, active: bool, low: int, high: int) -> int:
        """0x20C4:1: the latched errors, enabled, ``active`` (interpolating), and the warnings of a
        fill below ``low`` or above ``high`` records (0x20C4:2 and :3).

        Parameters
        ----------
        active : bool
            Interpolating.
        low, high : int
            The warning limits [records].

        Returns
        -------
        int
            The status.
        """
        n = len(self.records)
        status = self.errors | (ENABLED if self.enabled else 0) | (ACTIVE if active else 0)
        if n < low:
            status |= UNDERFLOW_WARNING
        if n > high:
            status |= OVERFLOW_WARNING
        return status
