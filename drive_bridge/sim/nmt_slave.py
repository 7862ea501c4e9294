"""A simulated node's NMT slave (CiA 301): its NMT state, the commands addressed to it, its
boot-up message and its heartbeat producer (0x1017), all in simulation time.  What a reset
command resets is the node's (:meth:`NmtSlave.command` hands it back)."""

from __future__ import annotations

import math
from collections.abc import Callable

from ..cia.p301 import NMT_OPERATIONAL, NMT_PREOP, NMT_STOPPED

#: NMT command specifiers -> the state they put a node in
STATE_OF_COMMAND = {0x01: NMT_OPERATIONAL, 0x02: NMT_STOPPED, 0x80: NMT_PREOP}
RESET_NODE, RESET_COMMUNICATION = 0x81, 0x82


class NmtSlave:
    """The NMT slave of node ``node_id``: ``send(cob_id, data)`` puts a frame on the bus, and
    ``heartbeat_ms()`` reads its producer heartbeat time 0x1017 [ms] as the node holds it now.

    Parameters
    ----------
    node_id : int
        The node.
    send : callable
        ``send(cob_id, data)``.
    heartbeat_ms : callable
        Reads 0x1017 [ms].
    """

    def __init__(self, node_id: int, send: Callable[[int, bytes], None], heartbeat_ms: Callable[[], int]):
        self.node_id = node_id
        self._send = send
        self._heartbeat_ms = heartbeat_ms
        #: the NMT state (CiA 301's codes, as the heartbeat carries them)
        self.state = NMT_PREOP
        self._next_beat = 0.0  # when the next heartbeat is due [s]

    def boot(self, now: float) -> None:
        """Initialisation done at ``now`` [s]: pre-operational, the boot-up message, the first
        heartbeat one period later.

        Parameters
        ----------
        now : float
            [s].
        """
        self.state = NMT_PREOP
        self._send(0x700 + self.node_id, b"\x00")
        self._next_beat = now + self._heartbeat_ms() / 1000.0

    def command(self, data: bytes) -> int | None:
        """An NMT command frame: a state command addressed to this node (or to all) taken; a reset
        command addressed to it returned (:data:`RESET_NODE`, :data:`RESET_COMMUNICATION`) for the
        node to carry out, then :meth:`boot`; None otherwise.

        Parameters
        ----------
        data : bytes
            The frame's data.

        Returns
        -------
        int or None
            The reset to carry out.
        """
        if len(data) < 2 or data[1] not in (0, self.node_id):
            return None
        if data[0] in STATE_OF_COMMAND:
            self.state = STATE_OF_COMMAND[data[0]]
        elif data[0] in (RESET_NODE, RESET_COMMUNICATION):
            return data[0]
        return None

    def heartbeat_time_written(self, now: float, value_ms: int) -> None:
        """0x1017 written at ``now`` [s]: the first heartbeat one new period from now.

        Parameters
        ----------
        now : float
            [s].
        value_ms : int
            The new period [ms].
        """
        self._next_beat = now + value_ms / 1000.0

    def beat(self, now: float) -> None:
        """The heartbeat, where one is due at ``now`` [s] (a late one is sent once, never a burst).

        Parameters
        ----------
        now : float
            [s].
        """
        period = self._heartbeat_ms() / 1000.0
        if period > 0 and now >= self._next_beat - 1e-9:
            self._send(0x700 + self.node_id, bytes([self.state]))
            self._next_beat = max(self._next_beat + period, now)

    def next_due(self) -> float:
        """When [s] the next heartbeat is due (inf: the producer is off).

        Returns
        -------
        float
            [s].
        """
        return self._next_beat if self._heartbeat_ms() > 0 else math.inf
