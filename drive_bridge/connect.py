"""Opening the link the master talks through: the configured bus, or the simulated robot
(``--sim``: the only place outside the tests that reaches into ``drive_bridge.sim``)."""

from __future__ import annotations

import logging
from collections.abc import Iterator
from contextlib import contextmanager

from .cia.buses import BusSpec
from .config import BusConfig
from .errors import UserError
from .master.link import BusLink, Link

log = logging.getLogger(__name__)


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
    link: Link
    if not sim:
        m = config.master
        if m.interface is None:
            raise UserError(
                f"{config.path}: no CAN interface named: give master.interface (and channel) in "
                f"bus.yml, -i/--interface and -c/--channel, or python-can's configuration "
                f"(CAN_INTERFACE, ~/.canrc)"
            )
        log.info("bus %s:%s at %s bit/s", m.interface, m.channel, m.bitrate)
        try:
            link = BusLink.open(m.interface, m.channel, m.bitrate, m.can_options)
        except Exception as exc:  # python-can raises many kinds for a missing interface
            raise UserError(f"{config.path}: cannot open bus {m.interface}:{m.channel} ({exc})") from exc
    else:
        from .sim.kernel import VELOCITY_TICK_S
        from .sim.robot_config import DEFAULT_CONFIG as SIM_DEFAULT
        from .sim.robot_config import load_sim_config

        robot_cfg = load_sim_config(sim_config or SIM_DEFAULT)  # errors show here, not in the child
        ticks = config.master.sync_period_s / VELOCITY_TICK_S
        if abs(ticks - round(ticks)) > 1e-6:
            raise UserError(
                f"{config.path}: master.sync_period: the simulated drives run their loops every "
                f"{VELOCITY_TICK_S * 1e6:.0f} µs, so the SYNC period must be a multiple of it "
                f"(got {config.master.sync_period_s * 1e6:.0f} µs)"
            )
        # each simulated drive is the drive its node's EDS/DCF describes (by axis name)
        eds = {a: n.dcf for a, n in config.nodes.items() if a in robot_cfg.axes}
        from .sim.vendors import spec_for

        for axis, path in eds.items():
            try:
                spec_for(path)
            except ValueError as exc:  # no simulated drive for this node's EDS/DCF
                raise UserError(f"{config.path}: nodes.{axis}.dcf: --sim: {exc}") from exc
        log.info(
            "simulated robot %s, %s, drives %s",
            sim_config or SIM_DEFAULT,
            "wall clock" if realtime else "lockstep",
            ", ".join(f"{a}: {p.name}" for a, p in eds.items()),
        )
        if realtime:
            from .sim.process import SimProcess

            drives = SimProcess(sim_config or SIM_DEFAULT, config.master.sync_period_s, eds)
            bus_link = BusLink(
                drives.bus, BusSpec("udp_multicast", drives.group, None, {"port": drives.port})
            )
            bus_link.simulator = drives  # the drives' process (tests stall it to prove the supervision)
            bus_link.on_close.append(drives.shutdown)
            link = bus_link
        else:
            from .sim.lockstep import LockstepLink
            from .sim.robot import SimRobot

            channel = f"{config.master.channel or 'drive-bridge'}-sim"  # closed again below, so reusable
            robot = SimRobot(robot_cfg, channel, sync_period=config.master.sync_period_s, eds=eds)
            link = LockstepLink(robot, channel)
    try:
        yield link
    finally:
        link.close()
