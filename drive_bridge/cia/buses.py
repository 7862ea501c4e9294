"""Opening a python-can bus, and what it takes to open the same bus again (:class:`BusSpec`): the
master's cyclic engine opens a handle of its own on the master's bus
(:mod:`drive_bridge.master.coprocess`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import can

from .multicast import INTERFACE as MULTICAST_NOECHO
from .multicast import RECEIVE_BUFFER, UDP_GROUP, UDP_PORT, raise_receive_buffer


@dataclass(frozen=True)
class BusSpec:
    """A python-can bus as :func:`open_bus` opens it.

    Parameters
    ----------
    interface : str
        python-can's interface name.
    channel : str or int, optional
        Its channel.
    bitrate : int, optional
        [bit/s], where the interface takes one.
    options : dict
        The interface's own arguments.
    """

    interface: str
    channel: str | int | None = None
    bitrate: int | None = None
    options: dict = field(default_factory=dict)

    def open(self) -> can.BusABC:
        """Open it (:func:`open_bus`).

        Returns
        -------
        can.BusABC
            The bus.
        """
        return open_bus(self.interface, self.channel, self.bitrate, self.options)

    @property
    def in_process(self) -> bool:
        """Whether only this process can reach the bus (python-can's virtual bus)."""
        return self.interface == "virtual"


def open_bus(
    interface: str, channel: str | int | None, bitrate: int | None = None, options: dict | None = None
) -> can.BusABC:
    """A python-can bus that does not hand its own frames back (``bitrate`` where the interface
    takes one; ``options``: the interface's own arguments, :mod:`drive_bridge.canconf`).

    Parameters
    ----------
    interface : str
        python-can's interface name (``udp_multicast`` opens the echo-free one).
    channel : str or int, optional
        Its channel.
    bitrate : int, optional
        [bit/s].
    options : dict, optional
        The interface's own arguments.

    Returns
    -------
    can.BusABC
        The bus.
    """
    if interface in ("udp_multicast", MULTICAST_NOECHO):  # python-can's echoes every frame to its sender
        opts = dict(options or {})
        return can.Bus(
            interface=MULTICAST_NOECHO,
            channel=str(channel or UDP_GROUP),
            port=opts.pop("port", None) or UDP_PORT,
            **opts,
        )
    kwargs = {**(options or {}), "interface": interface, "channel": channel, "receive_own_messages": False}
    if bitrate and interface != "virtual":
        kwargs["bitrate"] = bitrate
    if interface == "virtual":
        kwargs["preserve_timestamps"] = False
    bus = can.Bus(**kwargs)
    sock = getattr(bus, "socket", None)
    if interface == "socketcan" and sock is not None:  # (a lost frame shows as a gap in the SYNC counter)
        raise_receive_buffer(sock, RECEIVE_BUFFER)
    return bus
