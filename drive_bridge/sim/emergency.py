"""A simulated drive's emergency producer (CiA 301): the EMCY frame, the error code 0x603F and
the predefined error field 0x1003 (the newest first, at most :data:`HISTORY` entries)."""

from __future__ import annotations

import struct
from collections.abc import Callable

HISTORY = 8  # entries 0x1003 holds


class EmcyProducer:
    """The EMCY producer of node ``node_id``; ``send(cob_id, data)`` puts a frame on the bus.

    Parameters
    ----------
    node_id : int
        The node.
    send : callable
        ``send(cob_id, data)``.
    """

    def __init__(self, node_id: int, send: Callable[[int, bytes], None]):
        self.node_id = node_id
        self._send = send
        #: the error code of the fault the drive is in (0x603F; 0: none)
        self.error_code = 0
        #: the predefined error field 0x1003, newest first
        self.history: list[int] = []

    def send(self, code: int) -> None:
        """An EMCY with error ``code`` (0x0000: error reset, the error register cleared).

        Parameters
        ----------
        code : int
            The error code.
        """
        self._send(0x80 + self.node_id, struct.pack("<HB5s", code, 0x01 if code else 0x00, b"\x00" * 5))

    def fault(self, code: int) -> None:
        """A fault with error ``code``: held in 0x603F, kept in 0x1003, said by EMCY.

        Parameters
        ----------
        code : int
            The error code.
        """
        self.error_code = code
        self.history.insert(0, code)
        del self.history[HISTORY:]
        self.send(code)

    def reset(self) -> None:
        """The fault reset: 0x603F cleared, EMCY 0x0000."""
        self.error_code = 0
        self.send(0x0000)

    def field(self, sub: int) -> int:
        """0x1003 as read: sub-index 0 the number of errors, 1.. each one, newest first.

        Parameters
        ----------
        sub : int
            The sub-index.

        Returns
        -------
        int
            Its value.
        """
        if sub == 0:
            return len(self.history)
        return self.history[sub - 1] if sub <= len(self.history) else 0
