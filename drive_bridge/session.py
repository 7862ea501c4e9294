"""A session with the drives of one bus configuration: the link, the nodes and the
brought-up axes, each opened on first use and closed with the session.

Every command that talks to drives, and every step of ``commission``, works
through a :class:`Session`, so a step behaves the same run alone or in the
whole job.
"""

from __future__ import annotations

from contextlib import ExitStack
from dataclasses import dataclass

import canopen

from .config import BusConfig
from .connect import open_link
from .errors import BusError
from .master.bringup import AxisLink, bring_up, check_scan, remote_node, scan
from .master.link import Link
from .params.check import GM_FLOOR_DB, PM_FLOOR_DEG
from .params.profile import DEFAULT_PROFILE, Profile, load_profile


@dataclass
class Options:
    """How a session or a commissioning reaches the drives and what it runs with.

    Parameters
    ----------
    sim : bool
        The simulated robot instead of the configured bus.
    realtime : bool
        With ``sim``: on the wall clock, the drives in a process of their own.
    sim_config : str, optional
        With ``sim``: the simulator's YAML or a shipped robot by name.
    profile : str, optional
        The drive profile; default the one bus.yml names, else the project's drive.
    motor : (float, float), optional
        R [Ω], L [H] for drives that do not report their motor.
    seed : int
        Seed of the evolutionary fits.
    force : bool
        Write a gain set below the margin floor (recorded).
    pm_floor, gm_floor : float
        The margin floor [°], [dB] a written gain set must keep.
    allow_unverified_scales : bool
        Write through drive-profile scales without a documented source.
    history : bool
        Keep the run in the history database (:mod:`drive_bridge.history`).
    db : str, optional
        That database's URL; default ``DRIVE_BRIDGE_DB``, else the user's SQLite file.
    figures : bool
        Draw the reports' figures (PNG files beside them); without them the reports say so.
    """

    sim: bool = False
    realtime: bool = False
    sim_config: str | None = None
    profile: str | None = None  # None: the one bus.yml names, else the project's drive
    motor: tuple[float, float] | None = None
    seed: int = 0
    force: bool = False
    pm_floor: float = PM_FLOOR_DEG
    gm_floor: float = GM_FLOOR_DB
    allow_unverified_scales: bool = False
    history: bool = True  # keep the run in the history database (commission, write)
    db: str | None = None  # that database's URL (None: DRIVE_BRIDGE_DB, else the user's SQLite file)
    figures: bool = True  # draw the reports' figures

    @property
    def writes_unverified(self) -> bool:
        """Write through unverified scales: when asked to, and always to the simulated drives, which
        take the profile's scales by construction (the output still marks them unverified)."""
        return self.allow_unverified_scales or self.sim


class Session:
    """The drives of a bus configuration, reached as the options say: drive-bridge's counterpart of
    ``canopen.Network``. Nothing is opened, scanned or written until it is asked for; a context
    manager closes what it opened.

    Parameters
    ----------
    config : BusConfig
        The bus configuration (:func:`drive_bridge.load_bus_config`).
    options : Options, optional
        How to reach the drives (default: the configured bus, the project's drive profile).
    link : Link, optional
        An open link to use instead of opening one.

    Attributes
    ----------
    link : Link
        The link, opened on first use (:func:`drive_bridge.open_link`).
    nodes : dict of str to canopen.RemoteNode
        The configured nodes found on the bus, by axis (a scan; nothing written).
    axes : dict of str to AxisLink
        The drives brought up (PDO mapping, heartbeat, limits; they stay disabled).
    identities : dict of str to dict
        Each axis's drive identity (0x1018) as the scan or bring-up read it.
    profile : Profile
        The drive profile in use.

    Examples
    --------
    >>> from drive_bridge import Options, Session, load_bus_config
    >>> from drive_bridge.resources import data
    >>> with Session(load_bus_config(data("config", "bus.yml")), Options(sim=True)) as session:
    ...     sorted(session.axes)
    ['x', 'y', 'z']
    """

    def __init__(self, config: BusConfig, options: Options | None = None, link: Link | None = None):
        self.config = config
        self.options = options or Options()
        self._stack = ExitStack()
        self._link = link
        self._nodes: dict[str, canopen.RemoteNode] | None = None
        self._axes: dict[str, AxisLink] | None = None
        self._profile: Profile | None = None
        self._identities: dict[str, dict] = {}

    def __enter__(self) -> Session:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Close what the session opened (the link it opened, and with it the simulated drives);
        a link given to the session stays open."""
        self._stack.close()

    @property
    def profile(self) -> Profile:
        """The drive profile in use: the options', else the one bus.yml names, else the project's
        drive (loaded on first use)."""
        if self._profile is None:
            self._profile = load_profile(self.options.profile or self.config.profile or DEFAULT_PROFILE)
        return self._profile

    @property
    def link(self) -> Link:
        """The link the master talks through, opened on first use as the options say
        (:func:`drive_bridge.open_link`)."""
        if self._link is None:
            o = self.options
            self._link = self._stack.enter_context(open_link(self.config, o.sim, o.realtime, o.sim_config))
        return self._link

    @property
    def nodes(self) -> dict[str, canopen.RemoteNode]:
        """The configured nodes, found on the bus (scan), with their EDS/DCF; nothing written."""
        if self._axes is not None:
            return {a: ax.node for a, ax in self._axes.items()}
        if self._nodes is None:
            found = scan(self.link, self.config)
            check_scan(found, self.config)
            self._identities = {a: found.found[n.node_id] for a, n in self.config.nodes.items()}
            self._nodes = {a: remote_node(self.link.network, n.node_id) for a, n in self.config.nodes.items()}
        return self._nodes

    @property
    def identities(self) -> dict[str, dict]:
        """Each configured axis's drive identity (0x1018 vendor, product, revision, serial) as the
        scan or bring-up read it; empty before either."""
        if self._axes is not None:
            return {a: ax.identity for a, ax in self._axes.items()}
        return self._identities

    def holding(self) -> dict[str, str]:
        """How each brought-up axis is held now, read from the drives.

        Returns
        -------
        dict of str to str
            Per axis, in words (``switched off, on its brake``, ``powered, holding its position
            (profile position, halt)``, ...) and where it stands [rad, motor side]; ``unknown: ...``
            for a drive that does not answer; empty where no axis was brought up.
        """
        from .master.hold import holding_of

        out = {}
        for name, ax in (self._axes or {}).items():
            try:
                out[name] = f"{holding_of(ax, ax.drive.state())}, at {ax.position_rad():.4f} rad (0x6064)"
            except (canopen.SdoCommunicationError, canopen.SdoAbortedError, BusError) as exc:
                out[name] = f"unknown: the drive does not answer ({exc})"
        return out

    @property
    def axes(self) -> dict[str, AxisLink]:
        """The configured drives brought up: PDO mapping, heartbeat, limits (drives stay disabled)."""
        if self._axes is None:
            self._axes = bring_up(self.link, self.config)
        return self._axes
