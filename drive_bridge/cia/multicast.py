"""python-can's ``udp_multicast`` bus without the echo of its own frames, registered with
python-can as the interface ``udp_multicast_noecho`` (an entry point of group ``can.interface``,
as python-can's own backends are): ``can.Bus(interface="udp_multicast_noecho", channel=GROUP,
port=PORT)``.  The master opens it wherever bus.yml names ``udp_multicast``
(:func:`drive_bridge.cia.buses.open_bus`), and the wall-clock simulated drives serve on it.

It relies on python-can's ``UdpMulticastBus._multicast.recv`` (and its ``_socket``) and
``can.interfaces.udp_multicast.utils.unpack_message``, pinned by ``tests/cia/test_multicast.py``;
pyproject.toml bounds python-can above by the version that test passed on.
"""

from __future__ import annotations

import platform
import socket
import sys
from typing import Any

import can
from can.interfaces.udp_multicast import UdpMulticastBus
from can.interfaces.udp_multicast.utils import unpack_message

#: python-can udp_multicast's default IPv4 group (its own default is an IPv6 group) and port
UDP_GROUP, UDP_PORT = "239.74.163.2", 43113
#: the name python-can knows this bus by (pyproject.toml's entry point)
INTERFACE = "udp_multicast_noecho"
#: the receive buffer a bus of the master's asks for [bytes]: some 20 000 frames (a frame takes about
#: 830 bytes of it on Linux), a few seconds of a 3-axis stream -- what queues while the master's
#: host is stalled, the drives keeping time meanwhile
RECEIVE_BUFFER = 16 << 20
#: Linux's SO_RCVBUFFORCE (a receive buffer beyond net.core.rmem_max, with CAP_NET_ADMIN), which
#: Python's socket module does not name: 33 in asm-generic/socket.h (x86, ARM, RISC-V, MIPS,
#: POWER); sparc, parisc and alpha number it otherwise and go without
RECEIVE_BUFFER_FORCE = getattr(socket, "SO_RCVBUFFORCE", None) or (
    33
    if sys.platform == "linux" and not platform.machine().startswith(("sparc", "parisc", "alpha"))
    else None
)


def raise_receive_buffer(sock: socket.socket, size: int) -> None:
    """Ask for a receive buffer of ``size`` bytes on ``sock``: beyond net.core.rmem_max where the
    process may (SO_RCVBUFFORCE), else as far as rmem_max allows.

    Parameters
    ----------
    sock : socket.socket
        The socket.
    size : int
        [bytes].
    """
    for option in (RECEIVE_BUFFER_FORCE, socket.SO_RCVBUF):
        if option is None:
            continue
        try:
            sock.setsockopt(socket.SOL_SOCKET, option, size)
            return
        except OSError:
            continue


class LoopbackMulticastBus(UdpMulticastBus):
    """udp_multicast bus that drops the echo of its own frames, with the time stamp chosen.

    Multicast loops every datagram back to its sender.  In CANopen each COB-ID
    has exactly one producer, so a frame whose COB-ID this bus has sent itself
    is its own echo.

    ``stamps``: ``"kernel"`` -- when the frame reached this socket (SO_TIMESTAMPNS), as a CAN
    controller stamps what it receives; what a simulated drive judges the master's frames by, so
    that a stall of the simulator's own process does not look like a late master.  ``"sender"`` --
    the time its sender put it on the bus (python-can packs it into the datagram): what the master
    reads the simulated drives' frames by, since a simulated drive stamps each reply with the time
    its hardware would have sent it, whenever its process got round to it.

    The receive buffer is raised (to ``receive_buffer`` bytes where the OS allows): the default
    holds a few hundred frames, a few tens of ms of a 3-axis stream; :data:`RECEIVE_BUFFER` holds
    about 20 000.

    Parameters
    ----------
    channel : str
        The multicast group.
    port : int
        The UDP port.
    stamps : {"sender", "kernel"}
        Which time stamp a received frame carries (above).
    receive_buffer : int
        The socket's receive buffer [bytes]: a listener that may be held up for longer than
        ``RECEIVE_BUFFER`` lasts (one recording a whole stream at normal priority beside drives
        and a master first in line for the CPU) asks for more.
    **kwargs : object
        python-can's ``UdpMulticastBus`` arguments.

    Raises
    ------
    ValueError
        Another ``stamps``.
    """

    def __init__(
        self,
        channel: str = UDP_GROUP,
        port: int = UDP_PORT,
        stamps: str = "sender",
        receive_buffer: int = RECEIVE_BUFFER,
        **kwargs: Any,
    ):
        if stamps not in ("sender", "kernel"):
            raise ValueError(f"stamps must be 'sender' or 'kernel', not {stamps!r}")
        super().__init__(channel, port, **kwargs)
        self._sent_ids: set[int] = set()
        self._kernel_stamps = stamps == "kernel"
        raise_receive_buffer(self._multicast._socket, receive_buffer)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self._sent_ids.add(msg.arbitration_id)
        super().send(msg, timeout)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        while True:
            result = self._multicast.recv(timeout)
            if not result:
                return None, False
            msg = unpack_message(
                result[0], replace={"timestamp": result[2]} if self._kernel_stamps else None, check=True
            )
            if msg.arbitration_id not in self._sent_ids:
                return msg, False
            timeout = 0.0  # an echo: the next frame already waiting, if any (recv(0) drains past echoes)
