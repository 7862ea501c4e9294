"""A simulated drive's heartbeat consumer (CiA 301, 0x1016): the nodes it watches, when it last
heard each, and which fell silent for longer than its consumer time.  Watching a node starts with
its first heartbeat; a node found silent is reported once, and watched again from its next one.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator

from ..cia.objects import HEARTBEAT_CONSUMER


class HeartbeatConsumer:
    """The heartbeat consumer of one drive, configured from its object 0x1016 through ``read``
    ((index, sub) -> value; None where the object does not exist).

    Parameters
    ----------
    read : callable
        ``read(index, sub)``.
    """

    def __init__(self, read: Callable[[int, int], int | None]):
        self._read = read
        #: node-ID -> consumer time [s]
        self.watched: dict[int, float] = {}
        self._heard: dict[int, float] = {}  # node-ID -> when its last heartbeat came [s]
        self.configure()

    def configure(self) -> None:
        """Read 0x1016 again (after a write to it or a reset): what is watched, and for how long;
        a node no longer watched is forgotten."""
        self.watched = {}
        sub = 1
        while (value := self._read(HEARTBEAT_CONSUMER, sub)) is not None:
            if value >> 16 & 0x7F and value & 0xFFFF:
                self.watched[value >> 16 & 0x7F] = (value & 0xFFFF) / 1000.0
            sub += 1
        self._heard = {node: t for node, t in self._heard.items() if node in self.watched}

    def heard(self, node: int, now: float) -> None:
        """A heartbeat of ``node`` at ``now`` [s].

        Parameters
        ----------
        node : int
            The node.
        now : float
            [s].
        """
        if node in self.watched:
            self._heard[node] = now

    def fallen_silent(self, now: float) -> Iterator[int]:
        """Each watched node silent at ``now`` [s] for longer than its consumer time (once).

        Parameters
        ----------
        now : float
            [s].

        Yields
        ------
        int
            The node.
        """
        for node, last in list(self._heard.items()):
            if now - last > self.watched[node] + 1e-9:
                del self._heard[node]
                yield node

    def next_due(self) -> float:
        """The earliest time [s] a watched node's silence would be found (inf: none watched yet).

        Returns
        -------
        float
            [s].
        """
        return min((last + self.watched[node] for node, last in self._heard.items()), default=math.inf)
