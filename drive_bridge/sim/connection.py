"""The simulated robot as a backend of :func:`drive_bridge.connect.open_link` (``--sim``): its
drives in lockstep on the master's thread, or on the wall clock in a process of their own on
udp_multicast, each drive the one its node's EDS/DCF describes."""

from __future__ import annotations

import logging
from pathlib import Path

from ..cia.buses import BusSpec
from ..config import BusConfig
from ..errors import UserError
from ..master.link import BusLink, Link
from .kernel import VELOCITY_TICK_S
from .process import SimProcess
from .robot_config import DEFAULT_CONFIG as SIM_DEFAULT
from .robot_config import load_sim_config
from .vendors import spec_for

log = logging.getLogger(__name__)


def simulated_link(
    config: BusConfig,
    *,
    realtime: bool = False,
    sim_config: str | None = None,
    watch: str | Path | None = None,
) -> Link:
    """The simulated robot ``sim_config`` (a YAML, or a shipped robot by name; default the shipped
    ``robot``) as the drives of ``config``: in lockstep, or with ``realtime`` on the wall clock.
    Raises UserError for a SYNC period the drives cannot run or a node without a simulated drive.

    Parameters
    ----------
    config : BusConfig
        The bus configuration (its nodes get simulated drives).
    realtime : bool
        On the wall clock, the drives in a process of their own.
    sim_config : str, optional
        The simulated robot.
    watch : str or Path, optional
        With ``realtime``: where the drives' process writes the plant as it moves
        (:class:`~drive_bridge.sim.process.PlantWatch`).

    Returns
    -------
    Link
        The link.

    Raises
    ------
    UserError
        A SYNC period the drives cannot run, or a node without a simulated drive.
    """
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
        drives = SimProcess(sim_config or SIM_DEFAULT, config.master.sync_period_s, eds, watch)
        bus_link = BusLink(drives.bus, BusSpec("udp_multicast", drives.group, None, {"port": drives.port}))
        bus_link.simulator = drives  # the drives' process (tests stall it to prove the supervision)
        bus_link.on_close.append(drives.shutdown)
        return bus_link
    from .lockstep import LockstepLink  # the robot in this process (numba's kernels with it)
    from .robot import SimRobot

    channel = f"{config.master.channel or 'drive-bridge'}-sim"  # closed with the link, so reusable
    robot = SimRobot(robot_cfg, channel, sync_period=config.master.sync_period_s, eds=eds)
    return LockstepLink(robot, channel)
