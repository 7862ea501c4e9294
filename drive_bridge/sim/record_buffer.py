"""What a drive's interpolation buffer is, whatever its records: the records received and not yet
taken, whether access is enabled, and CiA 402's buffer clear 0x60C4:6 over both (maxon's PVT buffer
:mod:`.pvt_buffer`, the project drive's FIFO :mod:`.ip_fifo`)."""

from __future__ import annotations

from collections import deque
from typing import Generic, TypeVar

Record = TypeVar("Record")


class RecordBuffer(Generic[Record]):
    """Records received and not yet taken, and whether access is enabled (0x60C4:6)."""

    def __init__(self) -> None:
        self.records: deque[Record] = deque()
        self.enabled = False

    def reset(self) -> None:
        """Power-up: empty, access disabled."""
        self.records.clear()
        self.enabled = False

    def control(self, value: int) -> None:
        """0x60C4:6, buffer clear: 0 clears it and disables access, 1 enables access.

        Parameters
        ----------
        value : int
            0 or 1.
        """
        if value == 0:
            self.records.clear()
        self.enabled = value == 1
