"""Bring-up of the configured drives: scan, identity, NMT, heartbeats both ways, EMCY, the drive's
units, the limits and stop behaviour inside the drive, PDO mapping."""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import canopen
from canopen.emcy import EmcyError
from canopen.pdo.base import PdoBase, PdoMap

from ..cia.objects import (
    ABORT_CONNECTION_OPTION,
    BUFFER_CLEAR,
    BUFFER_MAXIMUM,
    CYCLE_PERIOD,
    DEVICE_TYPE,
    FAULT_REACTION_OPTION,
    FOLLOWING_ERROR_TIMEOUT,
    FOLLOWING_ERROR_WINDOW,
    HEARTBEAT_CONSUMER,
    HEARTBEAT_PRODUCER,
    HOME_OFFSET,
    IDENTITY_OBJECT,
    INTERPOLATION_DATA_CONFIGURATION,
    INTERPOLATION_SUB_MODE,
    INTERPOLATION_TIME_PERIOD,
    MAX_MOTOR_SPEED,
    MAX_PROFILE_VELOCITY,
    MAX_TORQUE,
    POSITION_ACTUAL,
    QUICK_STOP_DECELERATION,
    QUICK_STOP_OPTION,
    RPDO_COMMUNICATION,
    SOFTWARE_POSITION_LIMIT,
    SUPPORTED_DRIVE_MODES,
    SYNC_COUNTER_OVERFLOW,
    TARGET_POSITION,
    TPDO_COMMUNICATION,
)
from ..cia.od import default, limits, variable
from ..cia.p301 import MAX_SYNC_COUNTER
from ..cia.p402 import (
    ABORT_QUICK_STOP,
    CSP,
    FAULT_REACTION_QUICK_STOP_RAMP,
    IP,
    MODE_NAMES,
    QUICK_STOP_RAMP_AND_HOLD,
)
from ..cia.pdo import PdoCodec
from ..cia.sdo import pdo_objects, read_if_readable, sdo_object, snapshot, write_setting
from ..cia.setpoint import (
    IP_RECORD,
    IP_SUB_MODE,
    PVT,
    choose,
    describe_modes,
    record_sub_mode,
    supported_modes,
)
from ..config import BusConfig, MasterConfig, NodeConfig, PdoConfig
from ..errors import BusError, DriveRefused, InternalError
from ..outputs import hex_object, identity_hex, stamped
from .buffered import Feed, Streaming, buffered_node, capacity_in, feed_way, records_ahead
from .drive_limits import read_limits
from .drive_units import read_units, reconcile
from .link import Clock, Link
from .sdo_states import Drive402

log = logging.getLogger(__name__)

CIA402_PROFILE = 402


@dataclass
class AxisLink:
    """A brought-up axis: its node, state machine, PDO codecs and live monitors.

    Parameters
    ----------
    name : str
        The axis (bus.yml's key).
    cfg : NodeConfig
        Its node's configuration.
    node : canopen.RemoteNode
        The drive on the bus, with its object dictionary.
    drive : Drive402
        Its CiA 402 state machine as the master drives it.
    identity : dict
        The drive's identity (0x1018: vendor, product, revision, serial) as read.
    mode : int
        The operating mode the master streams in (8 CSP, 7 IP; 0 before it is chosen).
    setpoint : (int, int)
        The object carrying its setpoints (index, subindex).
    modes : list of int
        The operating modes the drive supports (0x6502).
    rpdos, tpdos : list of PdoCodec
        The PDOs as mapped, master to drive and back.
    last_heartbeat : float or None
        When the drive's last heartbeat came [s, the link's clock].
    nmt_state : int or None
        The NMT state that heartbeat said.
    emcy : list of (float, int)
        The drive's EMCY messages: (time [s], error code).
    units : dict
        What the drive said about its units (:mod:`.drive_units`).
    drive_limits : dict
        The limits and stop behaviour written into it, as read back ("0xIIII:S" -> value).
    homed : bool
        Referenced by homing: the drive's homing has run in this bring-up.
    before : dict
        Every object bring-up overwrote, as the drive held it before ("0xIIII:S" -> raw value):
        what a store of all parameters must put back to leave the stored set as it was.
    streaming : Streaming
        How its setpoints reach the drive (ahead into its FIFO, or one per SYNC) and why.
    sync_producer : bool
        Its drive produces the SYNC on its own clock while the master streams (:mod:`.timekeeper`).
    """

    name: str
    cfg: NodeConfig
    node: canopen.RemoteNode
    drive: Drive402
    identity: dict
    mode: int = 0
    setpoint: tuple[int, int] = (TARGET_POSITION, 0)
    modes: list[int] = field(default_factory=list)
    rpdos: list[PdoCodec] = field(default_factory=list)
    tpdos: list[PdoCodec] = field(default_factory=list)
    last_heartbeat: float | None = None
    nmt_state: int | None = None
    emcy: list[tuple[float, int]] = field(default_factory=list)
    units: dict = field(default_factory=dict)
    drive_limits: dict = field(default_factory=dict)
    homed: bool = False
    before: dict = field(default_factory=dict)
    streaming: Streaming = Streaming(0, "one setpoint per SYNC, as the RPDOs map it")
    sync_producer: bool = False

    def process_data(self) -> dict:
        """How the master exchanges this axis' process data, as bringup.json holds it.

        Returns
        -------
        dict
            The operating mode (number and name), the setpoint object and each PDO's COB-ID and
            mapping, in hex as CANopen writes them; the drive's units and limits as read back.
        """

        def pdos(codecs: list[PdoCodec]) -> list[dict[str, Any]]:
            return [
                {"cob_id": f"0x{c.cob_id:03X}", "mapping": [hex_object(i, s) for i, s in c.entries]}
                for c in codecs
            ]

        return {
            "mode": self.mode,
            "mode_name": MODE_NAMES.get(self.mode, str(self.mode)),
            "setpoint": hex_object(*self.setpoint),
            "rpdo": pdos(self.rpdos),
            "tpdo": pdos(self.tpdos),
            "units": self.units,
            "drive_limits": self.drive_limits,
        }

    def start_rad(self) -> float:
        """Where a motion planned now starts.

        Returns
        -------
        float
            Where the axis stands [rad], or for an axis that homes first, its home (the home
            offset 0x607C where the drive has one, else 0).
        """
        if self.cfg.homing is None or self.homed:
            return self.position_rad()
        offset = read_if_readable(self.node, HOME_OFFSET, 0, f"axis {self.name}'s home offset") or 0
        return float(self.cfg.scaling.position_from_device(offset))

    @property
    def torque_constant(self) -> float | None:
        """Its motor's torque constant [Nm/A] from the bus configuration (None: not given)."""
        return self.cfg.scaling.torque_constant_Nm_per_A

    def position_rad(self) -> float:
        """The drive's position actual (0x6064) now, read by SDO.

        Returns
        -------
        float
            The position [rad, motor side].

        Raises
        ------
        BusError
            The drive did not answer, naming the axis.
        """
        try:
            return float(self.cfg.scaling.position_from_device(self.node.sdo[POSITION_ACTUAL].raw))
        except (canopen.SdoCommunicationError, canopen.SdoAbortedError) as exc:
            raise BusError(f"axis {self.name}: reading its position (0x6064) failed ({exc})") from exc


@dataclass
class ScanResult:
    """What a scan found (:func:`scan`).

    Parameters
    ----------
    found : dict of int to dict
        Node id -> its identity.
    missing : list of str
        Configured axes that did not answer.
    unexpected : list of int
        Node ids that answered but are not configured.
    wrong_type : list of str
        Configured axes that are not CiA 402 drives.
    identity_mismatch : dict of str to str
        Axis -> how the node's identity (0x1018) differs from its EDS/DCF.
    identity_accepted : dict of str to str
        The same, for those accepted with ``--accept-identity``.
    """

    found: dict[int, dict]
    missing: list[str]
    unexpected: list[int]
    wrong_type: list[str]
    identity_mismatch: dict[str, str] = field(default_factory=dict)
    identity_accepted: dict[str, str] = field(default_factory=dict)

    def as_dict(self, config: BusConfig) -> dict:
        """scan.json / ``scan --json``: the nodes found (by axis where configured), missing,
        unexpected, wrong type, identities that differ from the EDS/DCF (and those accepted with
        --accept-identity).

        Parameters
        ----------
        config : BusConfig
            The bus configuration (the axes' names).

        Returns
        -------
        dict
            The document (schema ``scan``).
        """
        by_id = {n.node_id: a for a, n in config.nodes.items()}
        return stamped(
            "scan",
            {
                "found": {
                    by_id.get(i, str(i)): {"node_id": i, **identity_hex(ident)}
                    for i, ident in self.found.items()
                },
                "missing": self.missing,
                "unexpected": self.unexpected,
                "wrong_type": self.wrong_type,
                "identity_mismatch": self.identity_mismatch,
                "identity_accepted": self.identity_accepted,
            },
        )


def _identity(node: canopen.RemoteNode, axis: str) -> dict:
    try:
        return {
            "device_type": node.sdo[DEVICE_TYPE].raw,
            "vendor_id": node.sdo[IDENTITY_OBJECT][1].raw,
            "product_code": node.sdo[IDENTITY_OBJECT][2].raw,
            "revision": node.sdo[IDENTITY_OBJECT][3].raw,
            "serial": node.sdo[IDENTITY_OBJECT][4].raw,
        }
    except (canopen.SdoCommunicationError, canopen.SdoAbortedError) as exc:
        raise BusError(
            f"axis {axis} (node {node.id}): reading its identity (0x1000, 0x1018) failed ({exc})"
        ) from exc


#: identity fields of 0x1018 and the [DeviceInfo] entries of an EDS/DCF that name them
IDENTITY_FIELDS = (
    ("vendor_id", "vendor_number", "vendor"),
    ("product_code", "product_number", "product"),
    ("revision", "revision_number", "revision"),
)


def identity_mismatch(ident: dict, od: canopen.ObjectDictionary) -> str | None:
    """How a node's identity differs from what its EDS/DCF names (fields the file leaves out are
    not compared); None when it matches.

    Parameters
    ----------
    ident : dict
        The identity the node reported.
    od : canopen.ObjectDictionary
        Its EDS/DCF.

    Returns
    -------
    str or None
        The differences, in words.
    """
    info = od.device_information
    wrong = [
        (label, ident[key], getattr(info, attr))
        for key, attr, label in IDENTITY_FIELDS
        if getattr(info, attr, None) is not None and ident[key] != getattr(info, attr)
    ]
    if not wrong:
        return None
    node = ", ".join(f"{label} 0x{have:08X}" for label, have, _ in wrong)
    eds = ", ".join(f"{label} 0x{want:08X}" for label, _, want in wrong)
    return f"the node is {node}; its EDS/DCF names {eds}"


def remote_node(net: canopen.Network, node_id: int) -> canopen.RemoteNode:
    """The master's view of node ``node_id``, as :func:`scan` added it to ``net``.

    Parameters
    ----------
    net : canopen.Network
        The master's network.
    node_id : int
        The node.

    Returns
    -------
    canopen.RemoteNode
        The node.
    """
    node = net[node_id]
    if not isinstance(node, canopen.RemoteNode):
        raise InternalError(f"node {node_id} is on the network as a {type(node).__name__}, not a remote node")
    return node


def scan(link: Link, config: BusConfig) -> ScanResult:
    """Ask every node id who is there; compare with the configuration.

    Parameters
    ----------
    link : Link
        The link to the bus.
    config : BusConfig
        The bus configuration.

    Returns
    -------
    ScanResult
        What answered, what did not, and how each compares with its EDS/DCF.
    """
    net = link.network
    net.scanner.reset()
    net.scanner.search()
    link.clock.sleep(0.2)
    answered = set(net.scanner.nodes)
    by_id = {n.node_id: n for n in config.nodes.values()}
    found: dict[int, dict] = {}
    missing: list[str] = []
    wrong: list[str] = []
    mismatch: dict[str, str] = {}
    accepted: dict[str, str] = {}
    for axis, ncfg in config.nodes.items():
        if ncfg.node_id not in answered:
            missing.append(axis)
            continue
        node = (
            net.add_node(ncfg.node_id, ncfg.od) if ncfg.node_id not in net else remote_node(net, ncfg.node_id)
        )
        node.sdo.RESPONSE_TIMEOUT = config.master.sdo_timeout_s
        found[ncfg.node_id] = _identity(node, axis)
        if found[ncfg.node_id]["device_type"] & 0xFFFF != CIA402_PROFILE:
            wrong.append(axis)
        differs = identity_mismatch(found[ncfg.node_id], ncfg.od)
        if differs:
            (accepted if ncfg.node_id in config.accept_identity else mismatch)[axis] = (
                f"{differs} ({ncfg.dcf})"
            )
    unexpected = sorted(i for i in answered if i not in by_id)
    return ScanResult(found, missing, unexpected, wrong, mismatch, accepted)


def _configure_pdos(
    node: canopen.RemoteNode, node_id: int, maps: PdoBase, configured: tuple[PdoConfig, ...], base: int
) -> list[PdoCodec]:
    """Map the configured PDOs and disable the drive's others (of PDOs 1-4, those its EDS/DCF has)."""
    codecs = []
    by_num = {p.number: p for p in configured}
    comm_base = RPDO_COMMUNICATION if base == 0x200 else TPDO_COMMUNICATION
    for num in range(1, 5):
        if comm_base + num - 1 not in node.object_dictionary:
            continue
        pdo: PdoMap = maps[num]
        pdo.clear()
        pc = by_num.get(num)
        pdo.cob_id = pc.cob_id if pc is not None and pc.cob_id else base + 0x100 * (num - 1) + node_id
        pdo.enabled = pc is not None
        if pc is not None:
            for index, sub in pc.mapping:
                pdo.add_variable(index, sub)
            pdo.trans_type = pc.transmission
            od = node.object_dictionary
            if base == 0x180 and od.get_variable(comm_base + num - 1, 3):  # as configured, never the EDS
                pdo.inhibit_time = pc.inhibit_time_100us  # default (Nanotec's: 10 ms)
            if base == 0x180 and od.get_variable(comm_base + num - 1, 5):
                pdo.event_timer = pc.event_timer_ms or 0
        pdo.save()
        if pc is not None:
            codecs.append(PdoCodec.of(pdo.cob_id, node.object_dictionary, pc.mapping))
    return codecs


def check_scan(result: ScanResult, config: BusConfig) -> None:
    """Raise BusError naming the axis when a configured node is missing, is not the drive its
    EDS/DCF describes (identity 0x1018, unless accepted), or is no CiA 402 drive.

    Parameters
    ----------
    result : ScanResult
        The scan.
    config : BusConfig
        The bus configuration.

    Raises
    ------
    BusError
        As above.
    """
    if result.missing:
        ids = ", ".join(f"{a} (node {config.nodes[a].node_id})" for a in result.missing)
        alone = config.master.interface == "virtual" and len(result.missing) == len(config.nodes)
        raise BusError(
            f"no answer from {ids} on {config.master.interface}:{config.master.channel}; "
            + (
                "python-can's virtual bus carries only what this process puts on it: --sim runs the "
                "simulated robot, or name your adapter's interface and channel in "
                f"{config.path} (master.interface, master.channel)"
                if alone
                else f"check power, wiring, bitrate and node_id in {config.path}"
            )
        )
    if result.identity_mismatch:
        ax, why = next(iter(result.identity_mismatch.items()))
        node_id = config.nodes[ax].node_id
        raise BusError(
            f"axis {ax} (node {node_id}) is not the drive its EDS/DCF describes: {why}; nothing was "
            f"written. Connect that drive, name this drive's own EDS/DCF in {config.path}, or give "
            f"--accept-identity {node_id} to go on deliberately"
        )
    if result.wrong_type:
        ax = result.wrong_type[0]
        dt = result.found[config.nodes[ax].node_id]["device_type"]
        raise BusError(
            f"axis {ax} (node {config.nodes[ax].node_id}) is not a CiA 402 drive "
            f"(device type 0x{dt:08X}); check node_id in {config.path}"
        )


def bring_up(link: Link, config: BusConfig) -> dict[str, AxisLink]:
    """Scan, check and configure every configured drive (drives stay disabled).

    Parameters
    ----------
    link : Link
        The link to the bus.
    config : BusConfig
        The bus configuration.

    Returns
    -------
    dict of str to AxisLink
        The brought-up axes.

    Raises
    ------
    BusError
        A node missing or no CiA 402 drive, naming the axis.
    DriveRefused
        A drive that refuses a setting or keeps another value.
    """
    result = scan(link, config)
    check_scan(result, config)
    net = link.network
    clock = link.clock
    axes: dict[str, AxisLink] = {}
    period = config.master.sync_period_s
    link.start_heartbeat(config.master.heartbeat_node_id, config.master.heartbeat_period_s)
    log.info(
        "master heartbeat: node %d every %g s",
        config.master.heartbeat_node_id,
        config.master.heartbeat_period_s,
    )
    counter = sync_counter(config)
    for name, ncfg in config.nodes.items():
        node = remote_node(net, ncfg.node_id)
        node.nmt.send_command(0x80)  # pre-operational
        before = snapshot(node, name, [(i, s) for i, s, _ in ncfg.sdo])
        for index, sub, value in ncfg.sdo:  # first: they may set the drive's units
            write_setting(node, name, index, sub, value)
        ax = _axis(link, config, result, name, ncfg, {})
        ncfg = ax.cfg
        log.info(
            "axis %s: units %s per rad (%s); assumed from bus.yml: %s",
            name,
            f"{ncfg.scaling.inc_per_rad:.6g}",
            ax.units.get("position_unit") or "not reported",
            "; ".join(ax.units.get("assumed_from_bus_yml") or []) or "nothing",
        )
        ax.mode, ax.setpoint, ax.modes = _streaming_mode(node, ncfg, config.path)
        ax.streaming = _streaming(link, config, node, ax)
        if ax.streaming.buffered:
            ax.cfg = ncfg = buffered_node(ncfg, ax.streaming.record)
            ax.mode, ax.setpoint = IP, ax.streaming.record
        log.info("axis %s: %s", name, ax.streaming.why)
        written = drive_settings(name, ncfg, period, config.master, ax.streaming.depth, counter)
        before |= _unseen(snapshot(node, name, [(i, s) for i, s, _ in written]), before)
        before |= _unseen(snapshot(node, name, pdo_objects(node.object_dictionary)), before)
        if ncfg.rpdo and INTERPOLATION_SUB_MODE in ncfg.od:
            before |= _unseen(snapshot(node, name, [(INTERPOLATION_SUB_MODE, 0)]), before)
        ax.before = before
        for index, sub, value in written:
            write_setting(node, name, index, sub, value)
        ax.drive_limits = read_back(node, name, written)
        log.info("axis %s: limits and stop behaviour written and read back: %s", name, ax.drive_limits)
        try:
            ax.rpdos = _configure_pdos(node, ncfg.node_id, node.rpdo, ncfg.rpdo, 0x200)
            ax.tpdos = _configure_pdos(node, ncfg.node_id, node.tpdo, ncfg.tpdo, 0x180)
        except canopen.SdoAbortedError as exc:
            raise DriveRefused(
                f"axis {name}: the drive refused the PDO mapping ({exc}); "
                f"check nodes.{name}.rpdo / tpdo in {config.path}"
            ) from exc
        log.info(
            "axis %s: streams in mode %d (%s), setpoint %s",
            name,
            ax.mode,
            MODE_NAMES.get(ax.mode, "?"),
            hex_object(*ax.setpoint),
        )
        if ax.mode == IP:
            if INTERPOLATION_SUB_MODE in ncfg.od:
                write_setting(node, name, INTERPOLATION_SUB_MODE, 0, _sub_mode(ax))
            if (
                ax.setpoint == PVT and INTERPOLATION_DATA_CONFIGURATION in ncfg.od
            ) or ax.streaming.buffered:  # clear the record buffer, then enable it
                write_setting(node, name, INTERPOLATION_DATA_CONFIGURATION, BUFFER_CLEAR, 0)
                write_setting(node, name, INTERPOLATION_DATA_CONFIGURATION, BUFFER_CLEAR, 1)
        _watch(net, ax, clock)
        axes[name] = ax
    return axes


def _unseen(values: dict[str, int], seen: dict[str, int]) -> dict[str, int]:
    """The values of a snapshot whose objects an earlier snapshot does not hold (it keeps the first)."""
    return {k: v for k, v in values.items() if k not in seen}


def _axis(
    link: Link,
    config: BusConfig,
    result: ScanResult,
    name: str,
    ncfg: NodeConfig,
    planned: dict[tuple[int, int], int | float],
) -> AxisLink:
    """An axis with the units its drive reports (``planned``: values the node's ``sdo`` list will
    have written, read as the drive would hold them), checked against bus.yml and its stroke."""
    node = remote_node(link.network, ncfg.node_id)
    units = read_units(node, name, planned)
    ncfg = reconcile(ncfg, units, config.path)
    from_drive: list[str] = []
    if ncfg.limits_from_drive:
        ncfg, from_drive = read_limits(node, ncfg, config.path)
        log.warning("axis %s: no limits in %s, the drive's: %s", name, config.path, "; ".join(from_drive))
    if ncfg.reference == "here":  # the stroke around where the axis stands now
        try:
            here = float(ncfg.scaling.position_from_device(sdo_object(node, POSITION_ACTUAL, 0).raw))
        except (canopen.SdoCommunicationError, canopen.SdoAbortedError) as exc:
            raise BusError(
                f"axis {name}: reading its position (0x6064) for reference: here failed ({exc})"
            ) from exc
        lim = ncfg.limits
        ncfg = replace(
            ncfg,
            limits=replace(lim, position_min=lim.position_min + here, position_max=lim.position_max + here),
        )
    _check_range(ncfg, config.path)
    return AxisLink(
        name,
        ncfg,
        node,
        Drive402(node, name, link.clock, config.master.state_timeout_s),
        result.found[ncfg.node_id],
        units=units.as_dict() | ({"limits_from_drive": from_drive} if from_drive else {}),
    )


def plan_bring_up(link: Link, config: BusConfig) -> dict[str, AxisLink]:
    """What :func:`bring_up` would do, read only (``--dry-run``): scan and its checks, the drive's
    units reconciled with bus.yml (the node's ``sdo`` list taken as written), the streaming mode,
    and in ``drive_limits`` the settings bring-up would write; nothing that changes a drive's
    behaviour is sent.

    Parameters
    ----------
    link : Link
        The link to the bus.
    config : BusConfig
        The bus configuration.

    Returns
    -------
    dict of str to AxisLink
        The axes as bring-up would leave them (``drive_limits``: what it would write).

    Raises
    ------
    BusError
        A node missing or no CiA 402 drive, naming the axis.
    """
    result = scan(link, config)
    check_scan(result, config)
    axes = {}
    for name, ncfg in config.nodes.items():
        ax = _axis(link, config, result, name, ncfg, {(i, s): v for i, s, v in ncfg.sdo})
        ax.mode, ax.setpoint, ax.modes = _streaming_mode(ax.node, ax.cfg, config.path)
        ax.streaming = _streaming(link, config, ax.node, ax)
        if ax.streaming.buffered:
            ax.cfg = buffered_node(ax.cfg, ax.streaming.record)
            ax.mode, ax.setpoint = IP, ax.streaming.record
        if ax.mode == IP and INTERPOLATION_SUB_MODE in ax.cfg.od:
            _sub_mode(ax)
        ax.drive_limits = {
            hex_object(i, s): v
            for i, s, v in drive_settings(
                name,
                ax.cfg,
                config.master.sync_period_s,
                config.master,
                ax.streaming.depth,
                sync_counter(config),
            )
        }
        axes[name] = ax
    return axes


def _sub_mode(ax: AxisLink) -> int:
    """The interpolation sub-mode (0x60C0) the axis's records are taken in; for position records
    (:func:`~..cia.setpoint.record_sub_mode`) the choice is said and added to ``ax.streaming``."""
    if ax.setpoint != IP_RECORD:
        return IP_SUB_MODE[ax.setpoint]
    sub_mode, words = record_sub_mode(
        int(ax.identity.get("vendor_id") or 0), limits(variable(ax.cfg.od, INTERPOLATION_SUB_MODE))
    )
    log.info("axis %s: %s", ax.name, words)
    ax.streaming = replace(ax.streaming, why=f"{ax.streaming.why}; {words}")
    return sub_mode


def _streaming_mode(
    node: canopen.RemoteNode, ncfg: NodeConfig, path: str | os.PathLike[str]
) -> tuple[int, tuple[int, int], list[int]]:
    """The mode to stream in and its setpoint object, from the modes the drive lists in 0x6502
    (read from the drive; the EDS/DCF default where the drive does not answer) and the setpoint
    objects the RPDOs map; and every mode the drive lists."""
    axis = ncfg.axis
    bits = None
    if SUPPORTED_DRIVE_MODES in ncfg.od:
        try:
            bits = int(sdo_object(node, SUPPORTED_DRIVE_MODES, 0).raw)
        except canopen.SdoAbortedError:
            bits = default(ncfg.od, SUPPORTED_DRIVE_MODES)
        except canopen.SdoCommunicationError as exc:
            raise BusError(f"axis {axis}: no SDO answer reading its supported modes 0x6502 ({exc})") from exc
    if bits is None:
        raise DriveRefused(
            f"axis {axis}: the drive does not say which operating modes it supports (0x6502 "
            f"neither readable nor in {ncfg.dcf.name}); drive-bridge streams only in a mode "
            f"the drive lists"
        )
    mapped = [e for p in ncfg.rpdo for e in p.mapping]
    chosen = choose(bits, mapped, (ncfg.position_mode,) if ncfg.position_mode else (CSP, IP))
    if chosen is None and ncfg.position_mode:
        raise DriveRefused(
            f"axis {axis}: nodes.{axis}.position_mode in {path} is {ncfg.position_mode} "
            f"({MODE_NAMES[ncfg.position_mode]}), but the drive supports {describe_modes(bits)} "
            f"(0x6502 = 0x{bits:08X}) and the RPDOs map {', '.join(hex_object(*e) for e in mapped)}: "
            f"map its setpoint object, or leave position_mode out"
        )
    if chosen is None:
        raise DriveRefused(
            f"axis {axis}: no streaming mode: the drive supports {describe_modes(bits)} "
            f"(0x6502 = 0x{bits:08X}); drive-bridge streams in {MODE_NAMES[8]} (8, RPDO maps "
            f"0x607A) or {MODE_NAMES[7]} (7, RPDO maps 0x60C1:1 or 0x20C1); map the setpoint "
            f"object of a mode the drive has in nodes.{axis}.rpdo of {path}"
        )
    return (*chosen, supported_modes(bits))


def _streaming(link: Link, config: BusConfig, node: canopen.RemoteNode, ax: AxisLink) -> Streaming:
    """How the axis streams in this run (``master.streaming``): ahead into its drive's FIFO on the
    wall clock where the drive has one (``auto``; ``buffered``: required), else one setpoint per SYNC."""
    way, ncfg = config.master.streaming, ax.cfg
    as_mapped = (
        f"one setpoint per SYNC in mode {ax.mode} ({MODE_NAMES.get(ax.mode, '?')}), as the RPDOs map it"
    )
    if way == "per_sync":
        return Streaming(0, f"{as_mapped} (master.streaming: per_sync)")
    if way == "auto" and not link.threaded:
        return Streaming(0, f"{as_mapped} (lockstep: simulated time keeps every SYNC on time)")
    depth = records_ahead(config.master)
    said = read_if_readable(
        node, INTERPOLATION_DATA_CONFIGURATION, BUFFER_MAXIMUM, f"axis {ax.name}'s interpolation buffer size"
    )
    capacity = capacity_in(ncfg) if said is None else int(said)  # what the drive says wins
    feed = feed_way(ncfg, ax.modes, capacity, depth, config.master.sync_period_s)
    cover = f"({config.master.stall_cover_s * 1e3:.0f} ms, master.stall_cover_ms)"
    if isinstance(feed, Feed) and feed.record == PVT:
        ms = round(feed.stride * config.master.sync_period_s * 1e3)
        return Streaming(
            depth,
            f"ahead into its PVT buffer ({capacity} records, each of {ms} ms on the drive's own clock): "
            f"{math.ceil(depth / feed.stride)} records {cover} kept ahead of the time the drive takes "
            f"them, so a stall of this host that long leaves the motion untouched (past them the "
            f"buffer underflows: a fault on this drive)",
            PVT,
            feed.stride,
        )
    if isinstance(feed, Feed):
        return Streaming(
            depth,
            f"ahead into its interpolation FIFO ({capacity} records): {depth} records {cover} kept "
            f"ahead of the SYNCs that take them, so a stall of this host that long leaves the motion "
            f"untouched",
        )
    reason = feed
    if way == "buffered":
        raise DriveRefused(
            f"axis {ax.name}: master.streaming in {config.path} is buffered, but {reason}; "
            f"set master.streaming to auto or per_sync"
        )
    return Streaming(0, f"{as_mapped}: not ahead, {reason}; a stall of this host stops its setpoints")


def settings(
    axis: str, ncfg: NodeConfig, period: float, master: MasterConfig | None = None
) -> list[tuple[int, int, int | float]]:
    """The SDO writes of a node's settings besides its PDOs, in order (also what ``export ros2``
    gives Lely's master): the node's own ``sdo`` list, then :func:`drive_settings`.

    Parameters
    ----------
    axis : str
        The axis.
    ncfg : NodeConfig
        Its node's configuration.
    period : float
        The SYNC period [s].
    master : MasterConfig, optional
        The master's configuration (its heartbeat).

    Returns
    -------
    list of (int, int, int or float)
        (index, sub, value), in order.
    """
    return [*ncfg.sdo, *drive_settings(axis, ncfg, period, master)]


def sync_counter(config: BusConfig) -> int:
    """The SYNC counter's overflow value the bus runs with: :data:`~drive_bridge.cia.p301.MAX_SYNC_COUNTER`
    where every node's EDS/DCF has 0x1019 writable and the run brings up every node bus.yml names
    (each SYNC then carries its count, 1..240, and a lost one shows as a gap), else 0: a SYNC
    consumer expecting another length answers with EMCY 0x8240, and a drive left out of the run is
    not told the counter.

    Parameters
    ----------
    config : BusConfig
        The bus configuration.

    Returns
    -------
    int
        0x1019 for every node.
    """

    def writable(ncfg: NodeConfig) -> bool:
        var = ncfg.od.get_variable(SYNC_COUNTER_OVERFLOW, 0)
        return var is not None and var.writable and CYCLE_PERIOD in ncfg.od

    every = config.nodes and not config.left_out and all(writable(n) for n in config.nodes.values())
    return MAX_SYNC_COUNTER if every else 0


def drive_settings(
    axis: str,
    ncfg: NodeConfig,
    period: float,
    master: MasterConfig | None = None,
    ahead: int = 0,
    counter: int = 0,
) -> list[tuple[int, int, int | float]]:
    """What bring-up writes after reading the drive's units, each where the drive's EDS/DCF has the
    object: its heartbeat; the consumer of the master's heartbeat (0x1016:1,
    ``master.heartbeat_multiplier`` of its periods, 3 by default) and what to do when it stops
    (0x6007: quick stop); quick stop as ramp-and-hold (0x605A), fault
    reaction as a quick-stop ramp (0x605E); in the drive's units (once known), the following-error
    window and timeout, software position limits, max profile velocity and max motor speed, the
    quick-stop deceleration, the max torque where bus.yml gives one; the interpolation period
    0x60C2 and the communication cycle 0x1006.

    Parameters
    ----------
    axis : str
        The axis.
    ncfg : NodeConfig
        Its node's configuration.
    period : float
        The SYNC period [s].
    master : MasterConfig, optional
        The master's configuration (its heartbeat).
    ahead : int
        Records the master keeps ahead in the drive's FIFO (0: none): the consumer time of the
        master's heartbeat then also covers the stall they cover, and a heartbeat period more.
    counter : int
        The SYNC counter's overflow value 0x1019 (:func:`sync_counter`; 0: none), written where the
        drive has it writable while the cycle period 0x1006 is 0, as CiA 301 allows.

    Returns
    -------
    list of (int, int, int or float)
        (index, sub, value), in order.
    """
    od, sc, lim = ncfg.od, ncfg.scaling, ncfg.drive_limits

    def has(index: int, sub: int = 0) -> bool:
        var = od.get_variable(index, sub)
        return var is not None and var.writable

    out: list[tuple[int, int, int | float]] = [(HEARTBEAT_PRODUCER, 0, ncfg.heartbeat_producer_ms)]
    if master is not None and has(HEARTBEAT_CONSUMER, 1):
        consumer_ms = master.drive_consumer_ms
        if ahead:
            consumer_ms = max(consumer_ms, math.ceil((ahead * period + 2 * master.heartbeat_period_s) * 1000))
        out.append((HEARTBEAT_CONSUMER, 1, master.heartbeat_node_id << 16 | consumer_ms))
    # when it loses the master (0x6007): quick stop; on a quick stop (0x605A): ramp down on the
    # quick-stop deceleration, then stay in QUICK STOP ACTIVE, holding the axis; on a fault
    # (0x605E): ramp down on the quick-stop deceleration
    for index, value in (
        (ABORT_CONNECTION_OPTION, ABORT_QUICK_STOP),
        (QUICK_STOP_OPTION, QUICK_STOP_RAMP_AND_HOLD),
        (FAULT_REACTION_OPTION, FAULT_REACTION_QUICK_STOP_RAMP),
    ):
        if has(index):
            out.append((index, 0, value))
    if sc.increments_per_rev:  # the drive's units are known (from_drive: after bring-up read them)
        inc, vel = sc.inc_per_rad, sc.velocity_per_rad_s
        out += [
            (FOLLOWING_ERROR_WINDOW, 0, round(ncfg.following_error_window_rad * inc)),
            (SOFTWARE_POSITION_LIMIT, 1, round(ncfg.limits.position_min * inc)),
            (SOFTWARE_POSITION_LIMIT, 2, round(ncfg.limits.position_max * inc)),
        ]
        if lim is not None:
            optional = [
                (FOLLOWING_ERROR_TIMEOUT, lim.following_error_timeout_ms),
                (
                    QUICK_STOP_DECELERATION,
                    round(lim.quick_stop_deceleration * vel),
                ),  # velocity units per second
                (MAX_PROFILE_VELOCITY, round(lim.max_velocity * vel)),
                (MAX_MOTOR_SPEED, math.ceil(lim.max_velocity * 60 / (2 * math.pi))),
            ]  # rpm
            if lim.max_torque_Nm is not None:
                optional.append((MAX_TORQUE, round(lim.max_torque_Nm / sc.rated_torque_Nm * 1000)))
            out += [(index, 0, value) for index, value in optional if has(index)]
    if INTERPOLATION_TIME_PERIOD in ncfg.od:
        out += _interpolation_period(axis, ncfg, period)
    if CYCLE_PERIOD in ncfg.od:
        if has(SYNC_COUNTER_OVERFLOW):  # (0 where the bus runs without: one left from before is cleared)
            out += [(CYCLE_PERIOD, 0, 0), (SYNC_COUNTER_OVERFLOW, 0, counter)]
        out.append((CYCLE_PERIOD, 0, round(period * 1e6)))
    return out


def _interpolation_period(axis: str, ncfg: NodeConfig, period: float) -> list[tuple[int, int, int]]:
    """0x60C2: the SYNC period as value × 10^index, in the first unit (ms, 0.1 ms ... µs) both
    fit within the drive's EDS/DCF limits.  maxon's PVT records carry their own time: a drive
    whose 0x60C2 cannot hold the period is left as it is for them; any other is refused."""
    lo1, hi1 = limits(variable(ncfg.od, INTERPOLATION_TIME_PERIOD, 1))
    lo2, hi2 = limits(variable(ncfg.od, INTERPOLATION_TIME_PERIOD, 2))
    for exponent in (-3, -4, -5, -6):
        value = period * 10**-exponent
        if abs(value - round(value)) > 1e-6 or not 1 <= round(value) <= 255:
            continue
        if (
            (lo1 is None or lo1 <= round(value))
            and (hi1 is None or round(value) <= hi1)
            and (lo2 is None or lo2 <= exponent)
            and (hi2 is None or exponent <= hi2)
        ):
            return [(INTERPOLATION_TIME_PERIOD, 1, round(value)), (INTERPOLATION_TIME_PERIOD, 2, exponent)]
    if any(entry == PVT for p in ncfg.rpdo for entry in p.mapping):
        return []
    raise DriveRefused(
        f"axis {axis}: the drive's interpolation time period 0x60C2 cannot be "
        f"{period * 1e3:g} ms within the limits of its EDS/DCF (value {lo1}..{hi1}, "
        f"index {lo2}..{hi2}); set master.sync_period to a period it can hold"
    )


def _check_range(ncfg: NodeConfig, path: str | os.PathLike[str]) -> None:
    """The stroke must fit the drive's 32-bit position in its own units (known only now with from_drive)."""
    if not ncfg.limits.fits_32_bits(ncfg.scaling.inc_per_rad):
        raise DriveRefused(
            f"axis {ncfg.axis}: limits.stroke of nodes.{ncfg.axis} in {path} does not fit the "
            f"drive's 32-bit position range in its units ({ncfg.scaling.inc_per_rad:.6g} per rad)"
        )


def read_back(
    node: canopen.RemoteNode, axis: str, written: Sequence[tuple[int, int, int | float]]
) -> dict[str, int | float]:
    """Each setting as the drive now holds it; DriveRefused where it kept another value.

    Parameters
    ----------
    node : canopen.RemoteNode
        The drive.
    axis : str
        Its axis, for the errors.
    written : sequence of (int, int, int or float)
        What was written.

    Returns
    -------
    dict of str to int or float
        Address -> value as read back.

    Raises
    ------
    DriveRefused
        A setting it kept another value of.
    """
    out = {}
    for (index, sub), value in {(i, s): v for i, s, v in written}.items():  # (the last of each written)
        if not variable(node.object_dictionary, index, sub).readable:
            continue
        held = read_if_readable(node, index, sub, f"axis {axis}'s setting back")
        if held is None:
            continue  # write-only on this drive: what was written stands
        if held != value:
            raise DriveRefused(
                f"axis {axis}: 0x{index:04X}:{sub} was written {value} but the drive holds {held}; "
                f"it does not take the setting: nothing moves with a limit it did not keep"
            )
        out[hex_object(index, sub)] = held
    return out


def _watch(net: canopen.Network, ax: AxisLink, clock: Clock) -> None:
    """Heartbeat consumer and EMCY listener of one axis (they only record; the loop decides)."""

    def on_heartbeat(can_id: int, data: bytearray, timestamp: float) -> None:
        ax.last_heartbeat = clock.now()
        ax.nmt_state = data[0] & 0x7F if data else None

    def on_emcy(error: EmcyError) -> None:
        if error.code:
            ax.emcy.append((clock.now(), error.code))

    net.subscribe(0x700 + ax.cfg.node_id, on_heartbeat)
    ax.node.emcy.add_callback(on_emcy)
