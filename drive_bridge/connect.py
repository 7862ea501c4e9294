"""Opening the link the master talks through, by the name of its backend, as python-can opens an
interface by its name: ``bus`` (the configured python-can bus) or ``simulated`` (the simulated
robot's drives: :func:`drive_bridge.sim.connection.simulated_link`, imported only when asked for)."""

from __future__ import annotations

import importlib
import logging
from collections.abc import Iterator
from contextlib import contextmanager

from .config import BusConfig
from .errors import UserError
from .master.link import BusLink, Link

log = logging.getLogger(__name__)

#: the ways the master reaches the drives, by name -> "module:function" opening a Link for a bus
#: configuration (keywords ``realtime``, ``sim_config``)
BACKENDS = {"bus": "drive_bridge.connect:bus_link", "simulated": "drive_bridge.sim.connection:simulated_link"}


def bus_link(config: BusConfig, **_: object) -> Link:
    """The link backend ``bus``: the bus bus.yml (or the command line, or python-can's
    configuration) names.

    Parameters
    ----------
    config : BusConfig
        The bus configuration: ``master.interface``, ``channel``, ``bitrate`` and the interface's
        options.
    **_ : object
        What the simulated backend takes and a bus does not (``realtime``, ``sim_config``).

    Returns
    -------
    Link
        A :class:`~drive_bridge.master.link.BusLink` on the open bus.

    Raises
    ------
    UserError
        No interface named, or the bus does not open (python-can's reason said).
    """
    m = config.master
    if m.interface is None:
        raise UserError(
            f"{config.path}: no CAN interface named: give master.interface (and channel) in "
            f"bus.yml, -i/--interface and -c/--channel, or python-can's configuration "
            f"(CAN_INTERFACE, ~/.canrc)"
        )
    log.info("bus %s:%s at %s bit/s", m.interface, m.channel, m.bitrate)
    try:
        return BusLink.open(m.interface, m.channel, m.bitrate, m.can_options)
    except Exception as exc:  # python-can raises many kinds for a missing interface
        raise UserError(f"{config.path}: cannot open bus {m.interface}:{m.channel} ({exc})") from exc


@contextmanager
def open_link(
    config: BusConfig, sim: bool, realtime: bool = False, sim_config: str | None = None
) -> Iterator[Link]:
    """The link the master talks through: the configured bus, or the simulated robot.

    A context manager: the link is closed on leaving it (on the simulated robot, the drives'
    process or thread too).

    Parameters
    ----------
    config : BusConfig
        The bus configuration (:func:`load_bus_config`).
    sim : bool
        Talk to the simulated robot instead of the configured bus.
    realtime : bool
        With ``sim``: the drives in a process of their own on the wall clock (udp_multicast)
        instead of lockstep, where simulated time waits for the master.
    sim_config : str, optional
        With ``sim``: the simulator's YAML, or a shipped robot by name (``robot``,
        ``compliant``); default the shipped ``robot``.

    Yields
    ------
    Link
        The open link (:class:`drive_bridge.master.link.Link`).

    Raises
    ------
    UserError
        No CAN interface named, a bus that cannot be opened, a SYNC period the simulated drives
        cannot run, or a node whose EDS/DCF has no simulated drive.
    """
    backend = "simulated" if sim else "bus"
    module, function = BACKENDS[backend].split(":")
    link = getattr(importlib.import_module(module), function)(
        config, realtime=realtime, sim_config=sim_config
    )
    try:
        yield link
    finally:
        link.close()
