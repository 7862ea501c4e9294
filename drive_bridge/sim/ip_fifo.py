"""The project drive's deep interpolation buffer (CiA 402 0x60C4, buffer organisation 0: FIFO): the
position records 0x60C1:1 a master streams ahead of the SYNCs that take them, one a period while
interpolation is enabled, so that the drive's motion runs on its own clock whatever the master's
host does meanwhile.

Where it runs dry while interpolating (the master away longer than the buffer held), the drive
makes a planned stop: it ramps the last record's velocity down on its quick-stop deceleration and
holds there, still enabled, its statusword's bit 12 clear until interpolation is enabled again
(controlword bit 4, 0 then 1) -- a stop the master can resume from, not a fault.
"""

from __future__ import annotations

from .pvt_buffer import ERR_OVERFLOW  # (a record into a full buffer: a fault, the master's error)
from .record_buffer import RecordBuffer


class IpFifo(RecordBuffer[int]):
    """Position records [position unit] received and not yet taken, whether access is enabled
    (0x60C4:6) and whether the buffer ran dry while interpolating.

    Parameters
    ----------
    capacity : int
        0x60C4:1, the records it holds at most.
    """

    def __init__(self, capacity: int) -> None:
        super().__init__()
        self.capacity = capacity
        self.dry = False

    def reset(self) -> None:
        """Power-up: empty, access disabled."""
        super().reset()
        self.dry = False

    def put(self, position: int) -> int | None:
        """A record 0x60C1:1 into the buffer (dropped while access is disabled): None, or the EMCY
        code of the fault a full buffer answers with.

        Parameters
        ----------
        position : int
            [position unit].

        Returns
        -------
        int or None
            The EMCY code of an overflow.
        """
        if not self.enabled:
            return None
        if len(self.records) >= self.capacity:
            return ERR_OVERFLOW
        self.records.append(position)
        return None

    def take(self) -> int | None:
        """The next record of a period (None: the buffer is empty, and counts as run dry).

        Returns
        -------
        int or None
            [position unit].
        """
        if self.records:
            return self.records.popleft()
        self.dry = True
        return None

    @property
    def fill(self) -> int:
        """The records it holds now (0x60C4:2)."""
        return len(self.records)
