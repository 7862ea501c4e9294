"""Bus configuration (bus.yml), in the spirit of ros2_canopen's bus.yml.

``master`` holds the bus and timing, ``defaults`` is merged into every node,
``nodes`` is keyed by axis name, ``campaign`` sets the excitation.  Every
problem is a :class:`ConfigError` naming the file and the key.  Limits are SI
(m for linear axes, rad for rotary), converted to the motor side here.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import canopen
from canopen.objectdictionary import datatypes

from .cia.objects import (
    CONTROLWORD,
    CURRENT_ACTUAL,
    FOLLOWING_ERROR_ACTUAL,
    HOMING_ACCELERATION,
    HOMING_METHOD,
    HOMING_SPEEDS,
    INTERPOLATION_DATA_RECORD,
    MAX_MOTOR_SPEED,
    MODES_OF_OPERATION,
    MODES_OF_OPERATION_DISPLAY,
    POSITION_ACTUAL,
    RPDO_COMMUNICATION,
    STATUSWORD,
    TARGET_POSITION,
    TARGET_TORQUE,
    TARGET_VELOCITY,
    TORQUE_ACTUAL,
    TORQUE_OFFSET,
    TPDO_COMMUNICATION,
    VELOCITY_ACTUAL,
    VELOCITY_OFFSET,
    torque_object,
)
from .cia.od import default, load_od, variable
from .cia.p402 import CSP, IP, MODE_NAMES
from .cia.setpoint import SETPOINT_OBJECTS
from .errors import ConfigError
from .resources import vendor_dir
from .units import Scaling
from .yamlconf import Section, finite_number, load_yaml

log = logging.getLogger(__name__)

#: objects the master must find in the PDO mapping: what it streams and what it logs
REQUIRED_RPDO = {CONTROLWORD: "controlword"}
REQUIRED_TPDO = {
    POSITION_ACTUAL: "position actual",
    VELOCITY_ACTUAL: "velocity actual",
    STATUSWORD: "statusword",
}
#: what the master logs the torque from (scaling.torque_feedback): 0x6077, 0x6078, or a vendor object
TORQUE_FEEDBACK = {
    "torque": "torque actual",
    "current": "current actual",
    "object": "the torque feedback object",
}
#: objects the master can fill in an RPDO / log from a TPDO
TOP_KEYS = {"options", "master", "defaults", "nodes", "campaign", "acceptance"}
TPDO_TRANSMISSION = set(range(0, 241)) | {252, 253, 254, 255}  # CiA 301: 241..251 reserved
RPDO_TRANSMISSION = set(range(0, 241)) | {254, 255}
#: keys of a ros2_canopen / Lely dcfgen bus.yml that drive-bridge accepts but does not use
ROS_KEYS = {
    "driver",
    "package",
    "period",
    "enable_lazy_load",
    "position_mode",
    "velocity_mode",
    "switching_state",
    "homing_mode",
    "scale_pos_to_dev",
    "scale_pos_from_dev",
    "scale_vel_to_dev",
    "scale_vel_from_dev",
    "scale_eff_to_dev",
    "scale_eff_from_dev",
    "sdo_timeout_ms",
    "polling",
    "diagnostics",
    "namespace",
    "offset_pos_to_dev",
    "offset_pos_from_dev",
    "use_interpolation",
    "ignore_offsets",
}
LELY_NODE_KEYS = {
    "dcf_path",
    "revision_number",
    "serial_number",
    "vendor_id",
    "product_code",
    "heartbeat_multiplier",
    "heartbeat_consumer",
    "error_behavior",
    "boot",
    "mandatory",
    "reset_communication",
    "software_file",
    "software_version",
    "restore_configuration",
    "configuration_file",
    "time_cob_id",
    "retry_factor",
    "guard_time",
    "life_time_factor",
}
LELY_MASTER_KEYS = {
    "vendor_id",
    "product_code",
    "revision_number",
    "serial_number",
    "sync_window",
    "sync_overflow",
    "time_cob_id",
    "emcy_inhibit_time",
    "heartbeat_consumer",
    "error_behavior",
    "nmt_inhibit_time",
    "start",
    "start_nodes",
    "start_all_nodes",
    "reset_all_nodes",
    "stop_all_nodes",
    "boot_time",
}
# what the master fills in an RPDO (0x6060: the streaming mode; 0x60FF, 0x6071: zero, as a
# ros2_canopen CiA 402 mapping has them) and logs from a TPDO (0x6061: the mode the drive runs)
RPDO_OBJECTS = {
    CONTROLWORD,
    TARGET_POSITION,
    INTERPOLATION_DATA_RECORD,
    0x20C1,
    VELOCITY_OFFSET,
    TORQUE_OFFSET,
    MODES_OF_OPERATION,
    TARGET_VELOCITY,
    TARGET_TORQUE,
}
TPDO_OBJECTS = {
    POSITION_ACTUAL,
    VELOCITY_ACTUAL,
    TORQUE_ACTUAL,
    STATUSWORD,
    FOLLOWING_ERROR_ACTUAL,
    CURRENT_ACTUAL,
    MODES_OF_OPERATION_DISPLAY,
    0x20C4,
}


@dataclass(frozen=True)
class TimingLimits:
    """Limits of a wall-clock run (bus.yml ``master.timing``): a run past them is degraded.

    Parameters
    ----------
    max_late_pct : float
        Late cycles (SYNC gaps over 1.5 periods) and, judged apart, SYNCs before their setpoints [% of all].
    max_gap_periods : float
        The largest SYNC gap [periods].
    max_missing_pct : float
        Samples missing, any axis [% of rows].
    """

    max_late_pct: float = 1.0
    max_gap_periods: float = 5.0
    max_missing_pct: float = 0.5


@dataclass(frozen=True)
class PdoConfig:
    """One PDO as bus.yml maps it (written at bring-up).

    Parameters
    ----------
    number : int
        The PDO's number, 1..4.
    transmission : int
        Its transmission type (1..240: every n-th SYNC; 254/255: event-driven).
    mapping : tuple of (int, int)
        The objects it carries, (index, subindex), in order.
    cob_id : int, optional
        Its COB-ID; None: the predefined connection set (ros2_canopen's ``auto``).
    event_timer_ms : int, optional
        A TPDO's event timer (sub 5) [ms], where given (else 0: off).
    inhibit_time_100us : int
        A TPDO's inhibit time (sub 3) [100 µs]; 0 for synchronous PDOs.
    """

    number: int
    transmission: int
    mapping: tuple[tuple[int, int], ...]
    cob_id: int | None = None
    event_timer_ms: int | None = None
    inhibit_time_100us: int = 0


@dataclass(frozen=True)
class Limits:
    """Axis limits, motor side.

    Parameters
    ----------
    position_min, position_max : float
        The stroke [rad].
    max_velocity : float
        [rad/s].
    max_acceleration : float
        [rad/s²].
    max_jerk : float, optional
        [rad/s³]; None where not configured.
    """

    position_min: float
    position_max: float
    max_velocity: float
    max_acceleration: float
    max_jerk: float | None = None

    def fits_32_bits(self, per_rad: float) -> bool:
        """Whether the stroke fits a drive's 32-bit position.

        Parameters
        ----------
        per_rad : float
            The drive's position units per rad.

        Returns
        -------
        bool
            Both ends of the stroke within ±2³¹ units.
        """
        return max(abs(self.position_min), abs(self.position_max)) * per_rad < 2**31


#: the limits of an axis whose limits bring-up has not read from its drive yet: no motion fits them
NO_MOTION = Limits(0.0, 0.0, 0.0, 0.0)


#: ros2_canopen's placeholder for the bus configuration's own directory (its cogen replaces it)
BUS_CONFIG_PATH = "@BUS_CONFIG_PATH@"
#: ros2_canopen's scale pairs: to the device and back, each the other's inverse
ROS_SCALES = (("scale_pos_to_dev", "scale_pos_from_dev"), ("scale_vel_to_dev", "scale_vel_from_dev"))
#: how far a ``_from_dev`` may be from its ``_to_dev``'s inverse, relative: the rounding of a value
#: written with five significant digits (ros2_canopen uses each as given)
ROS_SCALE_AGREEMENT = 1e-4

HOLDING = ("brake", "enabled")
REFERENCES = ("absolute", "here", "home")
DEFAULT_MASTER_NODE_ID = 127
#: the drives' consumer time of the master's heartbeat, in its periods, unless bus.yml says (Lely's default)
HEARTBEAT_MULTIPLIER = 3.0
#: how setpoints reach the drives (master.streaming): see MasterConfig
STREAMING_WAYS = ("auto", "per_sync", "buffered")
#: the longest stall of the master's host the drives' FIFOs ride out, where bus.yml does not say: a
#: host without PREEMPT_RT is held up 10-100 ms, a loaded one longer, and two stalls may come
#: before a refill is done [s]
STALL_COVER_S = 0.5
#: the drive's own limits are set this much beyond the configured ones (the campaign stays inside those)
DRIVE_LIMIT_MARGIN = 1.25


@dataclass(frozen=True)
class Homing:
    """``reference: home``: the drive's own homing (CiA 402 mode 6), run before the first motion.

    Parameters
    ----------
    method : int
        The homing method (0x6098), as the drive's manual numbers them for how the axis is wired.
    switch_speed, zero_speed : float
        The speeds searching for the switch and for zero [rad/s] (0x6099:1, :2).
    acceleration : float
        The homing acceleration [rad/s²] (0x609A).
    timeout_s : float
        How long it may take [s].
    """

    method: int
    switch_speed: float
    zero_speed: float
    acceleration: float
    timeout_s: float


@dataclass(frozen=True)
class DriveLimits:
    """What bring-up writes into the drive besides the software position limits, SI motor side.

    Parameters
    ----------
    max_velocity : float
        The velocity it may never exceed [rad/s].
    quick_stop_deceleration : float
        [rad/s²].
    following_error_timeout_ms : int
        [ms].
    max_torque_Nm : float or None
        [Nm]; None: the drive's own, read and recorded.
    holding : {"enabled", "brake"}
        How the axis is held when no motion runs: ``brake`` -- the drive's brake holds it with
        the power stage off; ``enabled`` -- the drive holds it at its position, powered.
    hold_tolerance : float
        How far an axis held ``enabled`` may stray while no motion is commanded [rad]: past it, a
        gain set just written is put back (it does not hold the load).
    """

    max_velocity: float
    quick_stop_deceleration: float
    following_error_timeout_ms: int
    max_torque_Nm: float | None
    holding: str = "enabled"
    hold_tolerance: float = 0.05  # HOLD_TOLERANCE_RAD


@dataclass(frozen=True)
class NodeConfig:
    """One axis's node as bus.yml configures it.

    Parameters
    ----------
    axis : str
        The axis (bus.yml's key).
    node_id : int
        Its node id.
    dcf : Path
        Its EDS/DCF.
    od : canopen.ObjectDictionary
        The object dictionary read from it.
    scaling : Scaling
        Its units: device values to SI, motor side (:mod:`drive_bridge.units`).
    limits : Limits
        The stroke, velocity and acceleration the campaign stays within.
    linear : bool
        A linear axis: a feed constant given, bus.yml's positions in m, load side.
    heartbeat_producer_ms : int
        The drive's heartbeat period written at bring-up [ms].
    following_error_window_rad : float
        The following-error window written at bring-up [rad].
    rpdo, tpdo : tuple of PdoConfig
        The PDOs written at bring-up.
    sdo : tuple of (int, int, int or float)
        Objects written at bring-up as given: (index, subindex, value).
    profile : str, optional
        The drive profile (``params/profiles``) of this node's drive.
    motor : (float, float), optional
        Winding R [Ω], L [H] where the drive does not report them.
    source : dict
        The node's entry as bus.yml gives it, defaults merged in (load units, as written).
    drive_limits : DriveLimits, optional
        What bring-up writes into the drive besides the position limits.
    units_from_drive : bool
        ``scaling: from_drive``: the position and velocity units (and the rated torque where
        bus.yml gives none) are the drive's own, read at bring-up.
    limits_from_drive : bool
        No ``limits`` in bus.yml: the stroke, velocity and acceleration are the drive's own
        (0x607D, 0x607F or 0x6080, 0x60C5/0x60C6 or 0x6083/0x6084), read at bring-up; until then
        ``limits`` is :data:`NO_MOTION`.
    reference : {"absolute", "here", "home"}
        Where the stroke is: positions as the drive counts them, laid out around the position the
        axis stands at when it is brought up, or as the drive counts them after its homing has run.
    homing : Homing, optional
        The drive's homing, with ``reference: home``.
    position_mode : int, optional
        ros2_canopen's ``position_mode``: the one streaming mode to use (8 CSP, 7 IP); None: CSP
        where the drive and the RPDOs allow it, else IP.
    """

    axis: str
    node_id: int
    dcf: Path
    od: canopen.ObjectDictionary = field(repr=False, compare=False)
    scaling: Scaling
    limits: Limits
    linear: bool
    heartbeat_producer_ms: int
    following_error_window_rad: float
    rpdo: tuple[PdoConfig, ...]
    tpdo: tuple[PdoConfig, ...]
    sdo: tuple[tuple[int, int, int | float], ...]
    profile: str | None = None
    motor: tuple[float, float] | None = None
    source: dict = field(default_factory=dict, repr=False, compare=False)
    drive_limits: DriveLimits | None = None
    units_from_drive: bool = False
    limits_from_drive: bool = False
    reference: str = "absolute"
    homing: Homing | None = None
    position_mode: int | None = None


HOLD_TOLERANCE_RAD = 0.05  # motor side: how far a held axis may stray uncommanded, where bus.yml does not say
DEFAULT_BITRATE = 1_000_000  # bit/s, when nothing names the bitrate


@dataclass(frozen=True)
class MasterConfig:
    """The master's side of bus.yml.

    Parameters
    ----------
    interface, channel : str, optional
        The python-can interface and channel as bus.yml names them (None: not named;
        :func:`drive_bridge.canconf.resolve` fills them from the command line and python-can's own
        configuration).
    bitrate : int, optional
        [bit/s], as named.
    sync_period_s : float
        The SYNC period [s].
    heartbeat_timeout_s : float
        How long the master waits for a drive's heartbeat before it takes the drive as lost [s]
        (``master.heartbeat_consumer_ms``).
    sdo_timeout_s : float
        How long an SDO answer is waited for [s].
    state_timeout_s : float
        How long a CiA 402 state change is waited for [s].
    tpdo_miss_limit : int or None
        Periods of missing feedback before a stop (None: as the drives wait).
    timing : TimingLimits
        The limits of a wall-clock run.
    can_options : dict
        Interface-specific arguments for ``can.Bus``.
    notes : tuple of str
        Where the interface came from, what was neutralised or ignored.
    node_id : int, optional
        The master's own node id (a ros2_canopen / Lely bus.yml).
    heartbeat_period_s : float
        The master's heartbeat period [s], which every drive's consumer watches.
    heartbeat_multiplier : float
        The drives' consumer time of the master's heartbeat, in its periods (Lely's
        ``heartbeat_multiplier``; bring-up writes it to 0x1016).
    streaming : {"auto", "per_sync", "buffered"}
        How setpoints reach the drives: ``auto`` ahead into each drive's interpolation FIFO on the
        wall clock where the drive has one, else one per SYNC as the RPDOs map them; ``per_sync``;
        ``buffered`` (required, refused where a drive cannot) -- :mod:`drive_bridge.master.buffered`.
    stall_cover_s : float
        The longest stall of the master's host the drives' FIFOs ride out [s]
        (``master.stall_cover_ms``): the records kept ahead.
    sync_producer : {"auto", "interface"}
        Who sends SYNC on the wall clock: ``auto`` a drive that can, else the interface where it
        sends periodic frames itself (the kernel's broadcast manager on socketcan), else the
        engine's own loop (host-timed); ``interface`` no drive -- :mod:`drive_bridge.master.timekeeper`.
    """

    interface: str | None
    channel: str | int | None
    bitrate: int | None
    sync_period_s: float
    heartbeat_timeout_s: float
    sdo_timeout_s: float
    state_timeout_s: float
    tpdo_miss_limit: int | None
    timing: TimingLimits = TimingLimits()
    can_options: dict = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    node_id: int | None = None
    heartbeat_period_s: float = 0.1
    heartbeat_multiplier: float = HEARTBEAT_MULTIPLIER
    streaming: str = "auto"
    stall_cover_s: float = STALL_COVER_S
    sync_producer: str = "auto"

    @property
    def drive_consumer_ms(self) -> int:
        """The drives' consumer time of the master's heartbeat, as bring-up writes it (0x1016:1) [ms]."""
        return round(self.heartbeat_multiplier * self.heartbeat_period_s * 1000)

    @property
    def heartbeat_node_id(self) -> int:
        """The node-ID the master's heartbeat carries (bus.yml master.node_id, else 127)."""
        return self.node_id if self.node_id is not None else DEFAULT_MASTER_NODE_ID

    @property
    def nominal_bitrate(self) -> int:
        """The bitrate the bus load is checked against: the configured one, else CANopen's 1 Mbit/s
        (the bus may then be slower than the check assumes; the notes say so)."""
        return self.bitrate or DEFAULT_BITRATE


@dataclass(frozen=True)
class CampaignConfig:
    """The excitation campaign (bus.yml ``campaign``).

    Parameters
    ----------
    velocity_levels : tuple of float
        The trapezoids' speeds, as shares of the axis's max velocity.
    acceleration_levels : tuple of float
        Their accelerations, as shares of the axis's max acceleration.
    cycles : int
        Forward and backward cycles per level ...
    max_axis_time_s : float
        ... or this cap per axis [s], whichever comes first.
    move_fraction : float
        The share of the stroke moved over, centred.
    dwell_s : float
        The pause at each end of a move [s].
    together : bool
        All axes move at once (exposes a coupling between them), not one after the other.
    design : {"paper", "short"}
        ``paper``: the paper's trapezoids at velocity × acceleration levels (the reference);
        ``short``: a multisine per axis designed for the identification, ``short_time_s`` per axis.
    short_time_s : float
        The short campaign's time per axis [s].
    """

    velocity_levels: tuple[float, ...] = (0.2, 0.4, 0.8)
    acceleration_levels: tuple[float, ...] = (0.2, 0.4, 0.8)
    cycles: int = 25
    max_axis_time_s: float = 300.0
    move_fraction: float = 0.8
    dwell_s: float = 0.05
    together: bool = False
    design: str = "paper"
    short_time_s: float = 30.0

    def quick(self) -> CampaignConfig:
        """A few seconds of motion per axis, for demos and tests.

        Returns
        -------
        CampaignConfig
            The two highest levels, one cycle, at most 5 s per axis (the short design: 8 s).
        """
        return replace(
            self,
            velocity_levels=self.velocity_levels[-2:],
            acceleration_levels=self.acceleration_levels[-2:],
            cycles=1,
            max_axis_time_s=min(self.max_axis_time_s, 5.0),
            move_fraction=min(self.move_fraction, 0.05),
            short_time_s=min(self.short_time_s, 8.0),
        )


DESIGNS = ("paper", "short")


@dataclass(frozen=True)
class Acceptance:
    """What the commissioning's verdict checks (bus.yml ``acceptance``; see
    :mod:`drive_bridge.commissioning.verdict`).

    Parameters
    ----------
    min_phase_margin_deg : float
        The loops' phase margin at least [°].
    min_gain_margin_db : float
        Their gain margin at least [dB].
    min_fe_improvement : float
        The following error over the reference trajectories at least this many times smaller
        than with the factory set.
    max_rmse_over_noise : float
        The model's RMSE at most this many times the log's noise floor.
    max_relative_std : float
        The relative std of J, c0, c1 at most.
    require_consistent : bool
        J, c0, c1 consistent between the parts of the data.
    """

    min_phase_margin_deg: float = 45.0
    min_gain_margin_db: float = 8.0
    min_fe_improvement: float = 2.0
    max_rmse_over_noise: float = 2.0
    max_relative_std: float = 0.05
    require_consistent: bool = True


@dataclass(frozen=True)
class BusConfig:
    """A bus configuration (bus.yml), checked (:func:`load_bus_config`).

    Parameters
    ----------
    path : Path
        The file it was read from.
    master : MasterConfig
        The master's side: the bus, SYNC period [s], heartbeats, timing limits.
    nodes : dict of str to NodeConfig
        Per axis: node id, EDS/DCF, units and scaling, limits, PDO mapping.
    campaign : CampaignConfig
        The excitation campaign (speed and acceleration levels, times).
    accept_identity : frozenset of int
        Node ids whose identity may differ from their EDS/DCF (``--accept-identity``: a
        deliberate override).
    acceptance : Acceptance
        What the commissioning's verdict checks.
    left_out : tuple of str
        Axes bus.yml names that this run leaves out (:meth:`only`): their drives are on the bus but
        not brought up.
    """

    path: Path
    master: MasterConfig
    nodes: dict[str, NodeConfig]
    campaign: CampaignConfig
    accept_identity: frozenset[int] = frozenset()
    acceptance: Acceptance = Acceptance()
    left_out: tuple[str, ...] = ()

    @property
    def profile(self) -> str | None:
        """The drive profile the nodes name (``profile`` in bus.yml); None when none does."""
        names = {n.profile for n in self.nodes.values()}
        if len(names) > 1:
            raise ConfigError(
                self.path,
                "nodes",
                f"the nodes name different drive profiles "
                f"({sorted(map(str, names))}); one run commissions one drive model: split the bus "
                f"into one file per model",
            )
        return names.pop()

    @property
    def torque_constants(self) -> dict[str, float | None]:
        """axis -> its motor's torque constant [Nm/A] where the configuration gives one."""
        return {a: n.scaling.torque_constant_Nm_per_A for a, n in self.nodes.items()}

    def only(self, axes: list[str]) -> BusConfig:
        """The same configuration restricted to some of its axes.

        Parameters
        ----------
        axes : list of str
            The axes to keep.

        Returns
        -------
        BusConfig
            A copy with only those nodes.

        Raises
        ------
        ConfigError
            An axis the configuration does not have, named.
        """
        unknown = [a for a in axes if a not in self.nodes]
        if unknown:
            raise ConfigError(
                self.path, "nodes", f"no axis named {unknown[0]!r} (configured: {', '.join(self.nodes)})"
            )
        return replace(
            self,
            nodes={a: self.nodes[a] for a in axes},
            left_out=self.left_out + tuple(a for a in self.nodes if a not in axes),
        )


def _pdos(
    sec: Section,
    key: str,
    od: canopen.ObjectDictionary,
    allowed: set[int],
    required: dict[int, str],
    added: list[str] | None = None,
) -> tuple[PdoConfig, ...]:
    """The PDOs of ``key`` (rpdo/tpdo), each checked against the drive's EDS/DCF; every object of
    ``required`` mapped, or (``added`` a list: a mapping written for another master) added where
    it fits -- to an enabled PDO with room, else as a synchronous PDO of its own -- and said there."""
    pdo_sec = sec.section(key)
    result = []
    seen: set[int] = set()
    for num in pdo_sec.keys():
        if not isinstance(num, int) or not 1 <= num <= 4:
            raise pdo_sec.error(str(num), "PDO numbers are 1 to 4")
        if (RPDO_COMMUNICATION if key == "rpdo" else TPDO_COMMUNICATION) + num - 1 not in od:
            raise pdo_sec.error(str(num), f"the drive has no {key.upper()} {num} in its EDS/DCF")
        p = pdo_sec.section(num)
        enabled = p.get("enabled", bool, True)
        trans = p.get("transmission", int, 1, low=0, high=255)
        allowed_types = TPDO_TRANSMISSION if key == "tpdo" else RPDO_TRANSMISSION
        if trans not in allowed_types:
            raise p.error("transmission", f"0x{trans:02X} is reserved by CiA 301 for a {key.upper()}")
        if key == "tpdo" and enabled and not 1 <= trans <= 240:
            raise p.error(
                "transmission",
                f"0x{trans:02X} is not synchronous: the master logs one sample per SYNC "
                f"from each TPDO it reads (use 1..240)",
            )
        cob = p.get("cob_id", (int, str), "auto")
        if cob != "auto" and (isinstance(cob, str) or not 0x181 <= cob <= 0x57F):
            raise p.error("cob_id", f"must be 'auto' or an 11-bit PDO COB-ID 0x181..0x57F, got {cob!r}")
        timer = p.get("event_timer", int, None, low=0, high=65535)
        inhibit = p.get("inhibit_time", int, 0, low=0, high=65535)  # 100 µs, as CiA 301 and Lely
        for lely_only in ("event_deadline", "sync_start"):
            p.get(lely_only, int, None, low=0, high=65535)  # accepted as Lely takes them; not used
        mapping = []
        bits = 0
        for n, entry in enumerate(p.get("mapping", list, ... if enabled else [])):
            e = Section(sec.path, f"{p.key}.mapping[{n}]", entry)
            index = e.get("index", int, low=0, high=0xFFFF)
            sub = e.get("sub_index", int, 0, low=0, high=255)
            e.done()
            if index not in allowed:
                raise e.error(
                    "index",
                    f"0x{index:04X} is not an object the master can "
                    f"{'send' if key == 'rpdo' else 'log'} (use: "
                    f"{', '.join(f'0x{i:04X}' for i in sorted(allowed))})",
                )
            var = od.get_variable(index, sub)
            if var is None:
                raise e.error("index", f"0x{index:04X}:{sub} is not in the drive's EDS/DCF")
            if not var.pdo_mappable:
                raise e.error("index", f"0x{index:04X} is not PDO-mappable in the drive's EDS/DCF")
            if index == 0x20C4 and sub != 1:
                raise e.error("sub_index", "0x20C4:1 is the interpolation buffer status the master checks")
            if index in (INTERPOLATION_DATA_RECORD, 0x20C1) and (index, sub) not in SETPOINT_OBJECTS:
                raise e.error(
                    "sub_index",
                    f"0x{index:04X}:{sub} carries no position setpoint (use "
                    f"{'0x60C1:1' if index == 0x60C1 else '0x20C1:0'})",
                )
            bits += len(var)
            mapping.append((index, sub))
        p.done()
        if bits > 64:
            raise p.error("mapping", f"{bits} bits do not fit in one 8-byte PDO")
        if enabled:
            seen.update(i for i, _ in mapping)
            result.append(
                PdoConfig(num, trans, tuple(mapping), None if cob == "auto" else cob, timer, inhibit)
            )
    pdo_sec.done()
    if added is not None:
        result = _add_missing(result, [i for i in required if i not in seen], od, key, added)
        seen.update(i for p in result for i, _ in p.mapping)
    missing = [f"0x{i:04X} ({name})" for i, name in required.items() if i not in seen]
    if key == "rpdo" and not any(e in SETPOINT_OBJECTS for p in result for e in p.mapping):
        missing.append(
            "a position setpoint (0x607A target position for cyclic synchronous position, or "
            "0x60C1:1 / maxon's 0x20C1 interpolation data record for interpolated position)"
        )
    if missing:
        raise pdo_sec.error("", f"must map {', '.join(missing)}")
    return tuple(result)


def _position_mode(sec: Section, ignored: set[str]) -> int | None:
    """ros2_canopen's ``position_mode``, honoured where drive-bridge can stream in it."""
    mode = sec.get("position_mode", int, None)
    if mode is not None and mode not in (CSP, IP):
        raise sec.error(
            "position_mode",
            f"{mode} ({MODE_NAMES.get(mode, 'not a CiA 402 mode')}): drive-bridge streams its setpoints "
            f"in {MODE_NAMES[CSP]} (8) or {MODE_NAMES[IP]} (7); give one of them, or leave it out",
        )
    ignored.discard("position_mode")
    return mode


def _ros_velocity_scale(
    sec: Section, data: dict, feed: float | None, notes: list[str] | None = None
) -> float | None:
    """Device velocity units per motor rad/s from ros2_canopen's ``scale_vel_to_dev`` (device units
    per rad/s of the axis, or per m/s with a feed); None where it is not given (the position's
    units per second, :class:`~drive_bridge.units.Scaling`'s own). Each ``_from_dev`` given must
    be its ``_to_dev``'s inverse to what a person writes (:data:`ROS_SCALE_AGREEMENT`); the
    ``_to_dev`` is the one used, and a pair that agrees only that far is said in ``notes``."""
    for to_dev, from_dev in ROS_SCALES:
        forth, back = data.get(to_dev), data.get(from_dev)
        for key, value in ((to_dev, forth), (from_dev, back)):
            if value is not None and not (finite_number(value) and value > 0):
                raise sec.error(key, f"must be a number above 0, got {value!r}")
        if forth is None or back is None:
            continue
        mismatch = abs(forth * back - 1)
        if mismatch > ROS_SCALE_AGREEMENT:
            raise sec.error(
                from_dev,
                f"{back} is not 1/{to_dev} = 1/{forth} = {1 / forth:.6g} (they differ by {mismatch:.2g} "
                f"relative, more than {ROS_SCALE_AGREEMENT:g}): ros2_canopen commands the drive with one "
                f"and reads it with the other; give them as each other's inverse",
            )
        if mismatch > 1e-9 and notes is not None:
            notes.append(
                f"{sec.path}: {sec.key}.{from_dev} {back} is 1/{to_dev} to {mismatch:.2g} relative (as written, "
                f"rounded); {to_dev} = {forth} is used"
            )
    per_axis_unit = data.get("scale_vel_to_dev")
    if per_axis_unit is None:
        return None
    return float(per_axis_unit) * ((feed or 2 * math.pi) / (2 * math.pi))


def _add_missing(
    pdos: list[PdoConfig], objects: list[int], od: canopen.ObjectDictionary, key: str, added: list[str]
) -> list[PdoConfig]:
    """``pdos`` with each of ``objects`` (sub 0) mapped where it fits, each addition said in ``added``."""
    pdos = list(pdos)
    for index in objects:
        var = od.get_variable(index, 0)
        if var is None or not var.pdo_mappable:
            continue  # refused by the caller, naming it
        bits = {p.number: sum(len(variable(od, i, sub)) for i, sub in p.mapping) for p in pdos}
        room = [n for n, p in enumerate(pdos) if p.transmission <= 240 and bits[p.number] + len(var) <= 64]
        if room:
            p = pdos[room[0]]
            pdos[room[0]] = replace(p, mapping=(*p.mapping, (index, 0)))
        else:
            base = RPDO_COMMUNICATION if key == "rpdo" else TPDO_COMMUNICATION
            free = [n for n in range(1, 5) if base + n - 1 in od and n not in bits]
            if not free:
                continue
            p = PdoConfig(free[0], 1, ((index, 0),))
            pdos.append(p)
        added.append(f"0x{index:04X} to {key.upper()} {p.number}")
    return pdos


def _node(
    path: Path,
    axis: str,
    data: dict,
    dcf_path: str | None = None,
    unused: set | None = None,
    notes: list[str] | None = None,
) -> NodeConfig:
    ros_units = "scaling" not in data and "scale_pos_to_dev" in data  # ros2_canopen's scaling alone
    if data.get("scaling") == "from_drive" or ("scaling" not in data and not ros_units):
        data = {**data, "scaling": {"from_drive": True}}  # everything from the drive (a rotary axis)
    sec = Section(path, f"nodes.{axis}", data)
    node_id = sec.get("node_id", int, low=1, high=127)
    name = sec.get("dcf", str)
    vendor = name.startswith("vendor/")
    dcf = (vendor_dir() / name[len("vendor/") :] if vendor else path.parent / name).resolve()
    if not vendor and not dcf.is_file() and dcf_path:  # ros2_canopen: beside bus.yml, or in options.dcf_path
        dcf = (path.parent / dcf_path.replace(BUS_CONFIG_PATH, ".") / name).resolve()
    scale_pos = data.get("scale_pos_to_dev")
    ignored = sec.accept((ROS_KEYS | LELY_NODE_KEYS) - {"dcf_path"})
    sec.get("dcf_path", str, None)
    if not dcf.is_file():
        raise sec.error(
            "dcf",
            f"EDS/DCF file not found: {dcf}"
            + (
                " (vendor/ files are read from $DRIVE_BRIDGE_VENDOR_EDS or ../shared/eds-vendor)"
                if vendor
                else ""
            ),
        )
    od = load_od(dcf, node_id)
    sc = sec.section("scaling", required=not ros_units)
    from_drive = sc.get("from_drive", bool, False)
    feed = sc.get("feed_m_per_rev", float, None, low=1e-6, high=100.0)
    feedback = sc.get("torque_feedback", str, "torque", choices=list(TORQUE_FEEDBACK))
    velocity_unit = sc.get("velocity_unit", str, "inc/s", choices=["inc/s", "rpm"])
    per_unit = torque_index = torque_per_unit = None
    # the motor's torque constant: for current feedback, and for gains a drive holds in current
    kt = sc.get("torque_constant_Nm_per_A", float, ... if feedback == "current" else None, low=1e-6, high=1e3)
    if feedback == "object":  # torque = a vendor object × its scale
        torque_index = sc.get("torque_object", int, low=0x2000, high=0x5FFF)
        var = od.get_variable(torque_index, 0)
        if var is None or not var.pdo_mappable or not var.readable:
            raise sc.error(
                "torque_object",
                f"0x{torque_index:04X}:0 is not a readable, PDO-mappable object of the drive's EDS/DCF",
            )
        torque_per_unit = sc.get("torque_Nm_per_unit", float, low=1e-9, high=1e3)
    if feedback == "current":  # torque = current actual (0x6078) × torque constant
        unit_ = sc.get("current_unit", str, "permille", choices=["permille", "mA"])
        per_unit = (
            sc.get("rated_current_A", float, low=1e-6, high=1e5) / 1000.0 if unit_ == "permille" else 1e-3
        )
    inc = sc.get("increments_per_rev", int, None, low=1, high=2**31 - 1)
    # ros2_canopen: device units per rad (or m): per motor revolution
    per_rev = scale_pos * (feed or 2 * math.pi) if finite_number(scale_pos) and scale_pos > 0 else None
    if inc is None and per_rev is not None and not from_drive:
        inc = round(per_rev)
        ignored.discard("scale_pos_to_dev")
        if ros_units:
            ignored.difference_update(k for pair in ROS_SCALES for k in pair)
    elif inc is not None and per_rev is not None:  # both: they must agree
        if round(per_rev) != inc:
            raise sec.error(
                "scale_pos_to_dev",
                f"{scale_pos} device units per {'m' if feed else 'rad'} is {per_rev:.6g} per motor "
                f"revolution, but scaling.increments_per_rev is {inc}: give one, or make them agree",
            )
        ignored.discard("scale_pos_to_dev")
    position_mode = _position_mode(sec, ignored)
    if unused is not None:
        unused.update(ignored)
    if inc is None and not from_drive:
        raise sc.error(
            "increments_per_rev",
            "missing (the encoder's increments per motor revolution; a "
            "ros2_canopen scale_pos_to_dev gives it; or from_drive: true takes "
            "the drive's own units)",
        )
    if from_drive and inc is not None:
        raise sc.error(
            "increments_per_rev",
            "give it or from_drive: true, not both (from_drive takes the drive's own position unit)",
        )
    scaling = Scaling(
        increments_per_rev=inc or 0,
        # (0: the drive's own 0x6076, read at bring-up)
        rated_torque_Nm=sc.get(
            "rated_torque_Nm", float, 0.0 if from_drive or ros_units else ..., low=1e-6, high=1e6
        ),
        velocity_units_per_rad_s=_ros_velocity_scale(sec, data, feed, notes) if ros_units else None,
        feed_m_per_rev=feed,
        torque_feedback=feedback,
        current_per_unit_A=per_unit,
        torque_constant_Nm_per_A=kt,
        velocity_unit=velocity_unit,
        torque_index=torque_index,
        torque_per_unit_Nm=torque_per_unit,
    )
    sc.done()
    unit = "m" if feed else "rad"
    limits_from_drive = "limits" not in data
    lim = sec.section("limits", required=False)
    qs = lim.get(f"quick_stop_deceleration_{unit}_s2", float, None, low=1e-9, high=1e8)
    fe_timeout = lim.get("following_error_timeout_ms", int, 10, low=1, high=65535)
    max_torque = lim.get("max_torque_Nm", float, None, low=1e-6, high=1e6)
    if limits_from_drive:  # read at bring-up (:mod:`.master.drive_limits`): until then nothing may move
        limits = NO_MOTION
    else:
        stroke = lim.get("stroke_" + unit, list)
        if (
            len(stroke) != 2
            or not all(finite_number(v) and abs(v) < 1e9 for v in stroke)
            or stroke[0] >= stroke[1]
        ):
            raise lim.error("stroke_" + unit, f"must be [min, max] in {unit} with min < max, got {stroke!r}")
        vmax = lim.get(f"max_velocity_{unit}_s", float, low=1e-9, high=1e6)
        amax = lim.get(f"max_acceleration_{unit}_s2", float, low=1e-9, high=1e8)
        jmax = lim.get(f"max_jerk_{unit}_s3", float, None, low=1e-9, high=1e12)
        limits = Limits(
            float(scaling.load_to_motor(stroke[0])),
            float(scaling.load_to_motor(stroke[1])),
            float(scaling.load_to_motor(vmax)),
            float(scaling.load_to_motor(amax)),
            None if jmax is None else float(scaling.load_to_motor(jmax)),
        )
    lim.done()
    if default(od, MAX_MOTOR_SPEED) and not limits_from_drive:
        drive_max = default(od, MAX_MOTOR_SPEED) * 2 * math.pi / 60.0
        if limits.max_velocity > drive_max * (1 + 1e-9):
            raise lim.error(
                f"max_velocity_{unit}_s",
                f"{vmax} {unit}/s is {limits.max_velocity * 60 / (2 * math.pi):.0f} rpm at the motor, "
                f"above the drive's max motor speed 0x6080 = {default(od, 0x6080)} rpm",
            )
    if not limits.fits_32_bits(
        scaling.inc_per_rad
    ):  # with from_drive, bring-up checks it in the drive's units
        raise lim.error("stroke_" + unit, "does not fit the drive's 32-bit position range with this scaling")
    sdo = []
    for n, entry in enumerate(sec.get("sdo", list, [])):
        e = Section(path, f"nodes.{axis}.sdo[{n}]", entry)
        index, sub = e.get("index", int, low=0, high=0xFFFF), e.get("sub_index", int, 0, low=0, high=255)
        value = e.get("value", (int, float), low=-(2**63), high=2**64 - 1)
        e.done()
        var = od.get_variable(index, sub)
        if var is None:
            raise e.error("index", f"0x{index:04X}:{sub} is not in the drive's EDS/DCF")
        if var.data_type not in datatypes.FLOAT_TYPES:
            if not float(value).is_integer():
                raise e.error("value", f"0x{index:04X}:{sub} holds an integer, got {value!r}")
            value = int(value)
        sdo.append((index, sub, value))
    torque_added: list[str] = []
    tpdo = _pdos(
        sec,
        "tpdo",
        od,
        TPDO_OBJECTS | {torque_object(scaling.torque_feedback, scaling.torque_index)},
        {
            **REQUIRED_TPDO,
            torque_object(scaling.torque_feedback, scaling.torque_index): TORQUE_FEEDBACK[feedback],
        },
        added=torque_added if ros_units else None,
    )
    if torque_added and notes is not None:
        notes.append(
            f"nodes.{axis}.tpdo: {', '.join(torque_added)} (drive-bridge logs the torque; "
            f"the mapping written for ros2_canopen does not carry it)"
        )
    hold = sec.get(f"hold_tolerance_{unit}", float, None, low=1e-9, high=1e3)
    drive_limits = DriveLimits(
        max_velocity=DRIVE_LIMIT_MARGIN * limits.max_velocity,
        quick_stop_deceleration=float(scaling.load_to_motor(qs)) if qs else 2 * limits.max_acceleration,
        following_error_timeout_ms=fe_timeout,
        max_torque_Nm=max_torque,
        holding=sec.get("holding", str, "enabled", choices=list(HOLDING)),
        hold_tolerance=HOLD_TOLERANCE_RAD if hold is None else float(scaling.load_to_motor(hold)),
    )
    cfg = NodeConfig(
        axis=axis,
        node_id=node_id,
        dcf=dcf,
        od=od,
        scaling=scaling,
        limits=limits,
        linear=bool(feed),
        heartbeat_producer_ms=sec.get("heartbeat_producer", int, 100, low=1, high=65535),
        following_error_window_rad=sec.get("following_error_window_rad", float, 0.6, low=1e-6, high=1e6),
        rpdo=_pdos(sec, "rpdo", od, RPDO_OBJECTS, REQUIRED_RPDO),
        tpdo=tpdo,
        sdo=tuple(sdo),
        profile=sec.get("profile", str, None),
        motor=_motor(sec),
        source=data,
        drive_limits=drive_limits,
        units_from_drive=from_drive,
        limits_from_drive=limits_from_drive,
        reference=sec.get("reference", str, "absolute", choices=list(REFERENCES)),
        homing=_homing(sec, od, scaling, limits, unit, limits_from_drive),
        position_mode=position_mode,
    )
    if (cfg.reference == "home") != (cfg.homing is not None):
        raise sec.error(
            "homing" if cfg.homing else "reference",
            "reference: home and a homing section go together: "
            "homing says how the drive finds its home (method, speeds), reference: home that it runs",
        )
    sec.done()
    return cfg


#: the CiA 402 homing objects a drive needs for ``reference: home``
HOMING_OBJECTS = ((HOMING_METHOD, 0), (HOMING_SPEEDS, 1), (HOMING_SPEEDS, 2), (HOMING_ACCELERATION, 0))


def _homing(
    sec: Section,
    od: canopen.ObjectDictionary,
    scaling: Scaling,
    limits: Limits,
    unit: str,
    limits_from_drive: bool = False,
) -> Homing | None:
    """``homing: {method, switch_speed_<unit>_s, zero_speed_<unit>_s, acceleration_<unit>_s2,
    timeout_s}`` (speeds by default 5 % and 1 % of the axis's velocity limit, the acceleration 10 %
    of its own: given, where the limits are the drive's, read only at bring-up), in load units as
    the limits are."""
    h = sec.section("homing", required=False)
    if not h.keys():
        return None
    method = h.get("method", int, low=-128, high=127)
    missing = [f"0x{i:04X}:{s}" for i, s in HOMING_OBJECTS if od.get_variable(i, s) is None]
    if missing:
        raise h.error(
            "method",
            f"the drive's EDS/DCF has no homing objects {', '.join(missing)}: it cannot home "
            f"over CANopen; use reference: here or absolute",
        )
    to_motor = lambda v: None if v is None else float(scaling.load_to_motor(v))  # noqa: E731
    vmax, amax = limits.max_velocity, limits.max_acceleration
    given = ... if limits_from_drive else None  # (no limits yet to take a default from)
    switch = to_motor(h.get(f"switch_speed_{unit}_s", float, given, low=1e-9, high=1e6)) or 0.05 * vmax
    zero = to_motor(h.get(f"zero_speed_{unit}_s", float, given, low=1e-9, high=1e6)) or 0.01 * vmax
    acc = to_motor(h.get(f"acceleration_{unit}_s2", float, given, low=1e-9, high=1e8)) or 0.1 * amax
    for key, value, most in (
        (f"switch_speed_{unit}_s", switch, vmax),
        (f"zero_speed_{unit}_s", zero, vmax),
        (f"acceleration_{unit}_s2", acc, amax),
    ):
        if value > most * (1 + 1e-9) and not limits_from_drive:
            raise h.error(key, "above the axis's own limit in limits")
    out = Homing(method, switch, zero, acc, h.get("timeout_s", float, 120.0, low=0.1, high=3600.0))
    h.done()
    return out


def _motor(sec: Section) -> tuple[float, float] | None:
    """``motor: {R_ohm, L_H}``: the winding, for drives that do not report it."""
    m = sec.section("motor", required=False)
    if not m.keys():
        m.done()
        return None
    motor = (m.get("R_ohm", float, low=1e-6, high=1e4), m.get("L_H", float, low=1e-9, high=10.0))
    m.done()
    return motor


def _timing(sec: Section) -> TimingLimits:
    """``master.timing``: when a wall-clock run counts as degraded."""
    d = TimingLimits()
    limits = TimingLimits(
        sec.get("max_late_pct", float, d.max_late_pct, low=0.0, high=100.0),
        sec.get("max_gap_periods", float, d.max_gap_periods, low=1.0, high=1e6),
        sec.get("max_missing_pct", float, d.max_missing_pct, low=0.0, high=100.0),
    )
    sec.done()
    return limits


def _merge(defaults: dict, node: dict) -> dict:
    merged = dict(defaults)
    for key, value in node.items():
        if isinstance(value, dict) and isinstance(merged.get(key), dict):
            merged[key] = _merge(merged[key], value)
        else:
            merged[key] = value
    return merged


def load_bus_config(path: str | Path) -> BusConfig:
    """Read and check a bus configuration (``bus.yml``).

    Parameters
    ----------
    path : str or Path
        The bus.yml file. Each node's EDS/DCF is read from the path it names (relative to the
        file), or from the vendor files shipped with drive-bridge.

    Returns
    -------
    BusConfig
        The checked configuration: the master's bus and timing, each node with its scaling,
        limits [SI, motor side], PDO mapping and drive profile.

    Raises
    ------
    ConfigError
        A missing file, a key that is missing, unknown or out of range, or an EDS/DCF that
        cannot be read; the message names the file and the key and says what to do.
    """
    path = Path(path)
    top = Section(path, "", load_yaml(path))
    options = top.section("options", required=False)
    dcf_path = options.get("dcf_path", str, None)
    # Lely's: the drives' consumer time of the master's heartbeat, in its periods (master's own, else this)
    multiplier = options.get("heartbeat_multiplier", float, HEARTBEAT_MULTIPLIER, low=1.5, high=100.0)
    options.get("retry_factor", (int, float), None)  # Lely's, for the master it generates
    options.done()
    m = top.section("master")
    notes: list[str] = []
    ros = bool(top.data.get("options")) or any(
        k in m.data for k in ("node_id", "driver", "package", "baudrate")
    )
    bitrate = m.get("bitrate", int, None, low=10_000, high=1_000_000)
    baud = m.get("baudrate", int, None, low=10, high=1000)  # Lely / ros2_canopen: kbit/s
    if baud is not None and bitrate is not None and baud * 1000 != bitrate:
        raise m.error("baudrate", f"{baud} kbit/s but master.bitrate is {bitrate} bit/s: give one")
    ignored = m.accept({"driver", "package"} | LELY_MASTER_KEYS)
    master = MasterConfig(
        interface=m.get("interface", str, None),
        channel=m.get("channel", (str, int), None),
        bitrate=bitrate if bitrate is not None else (baud * 1000 if baud else None),
        can_options=m.get("can_options", dict, {}),
        sync_period_s=m.get("sync_period", int, 2000, low=500, high=100_000) * 1e-6,
        heartbeat_timeout_s=m.get("heartbeat_consumer_ms", int, 300, low=10, high=65535) / 1000.0,
        sdo_timeout_s=m.get("sdo_timeout_s", float, 0.5, low=0.01, high=60.0),
        state_timeout_s=m.get("state_timeout_s", float, 1.0, low=0.01, high=60.0),
        tpdo_miss_limit=m.get("tpdo_miss_limit", int, None, low=1, high=10000),
        heartbeat_period_s=m.get("heartbeat_producer", int, 100, low=10, high=100) / 1000.0,
        heartbeat_multiplier=m.get("heartbeat_multiplier", float, multiplier, low=1.5, high=100.0),
        timing=_timing(m.section("timing", required=False)),
        node_id=m.get("node_id", int, None, low=1, high=127),
        streaming=m.get("streaming", str, "auto", choices=STREAMING_WAYS),
        stall_cover_s=m.get("stall_cover_ms", int, round(STALL_COVER_S * 1000), low=10, high=5000) / 1000.0,
        sync_producer=m.get("sync_producer", str, "auto", choices=("auto", "interface")),
    )
    m.done()
    if ignored:
        notes.append(
            f"master: {', '.join(sorted(ignored))} (ros2_canopen / Lely keys drive-bridge does not use)"
        )
    defaults = top.get("defaults", dict, {})
    entries = {}
    if "nodes" in top.data:
        nodes_sec = top.section("nodes")
        for axis in nodes_sec.keys():
            entries[str(axis)] = nodes_sec.get(axis, dict)
        nodes_sec.done()
    for key in list(top.data):  # Lely's / older ros2_canopen layout: slaves at the top level
        if (
            key not in TOP_KEYS
            and isinstance(top.data[key], dict)
            and ("node_id" in top.data[key] or "dcf" in top.data[key])
        ):
            entries[str(key)] = top.get(key, dict)
    if not entries:
        raise top.error("nodes", "no nodes configured")
    ros = ros or any(k in e for e in entries.values() for k in ("driver", "package"))
    nodes: dict[str, NodeConfig] = {}
    unused: set[str] = set()
    for axis, entry in entries.items():
        if ros:  # ros2_canopen's merge: defaults replace a node's own entries
            replaced = sorted(k for k in defaults if k in entry and entry[k] != defaults[k])
            if replaced:
                notes.append(
                    f"nodes.{axis}: {', '.join(replaced)} replaced by defaults (ros2_canopen's merge "
                    f"order; keep per-node keys out of defaults)"
                )
            merged = {**entry, **defaults}
        else:
            merged = _merge(defaults, entry)
        nodes[axis] = _node(path, axis, merged, dcf_path, unused, notes)
        period = merged.get("period")  # ros2_canopen: the node's setpoint period [ms]
        if period is not None and (
            not finite_number(period) or abs(period * 1e-3 - master.sync_period_s) > 1e-9
        ):
            raise Section(path, f"nodes.{axis}", merged).error(
                "period",
                f"{period!r} ms, but drive-bridge sends a setpoint with every SYNC, every "
                f"{master.sync_period_s * 1e3:g} ms (master.sync_period): give them alike",
            )
    unused.discard("period")
    if unused:
        notes.append(
            f"nodes: {', '.join(sorted(unused))} (ros2_canopen / Lely keys drive-bridge does not use)"
        )
    master = replace(master, notes=tuple(notes))
    ids = [n.node_id for n in nodes.values()]
    if len(set(ids)) != len(ids):
        raise top.error("nodes", f"node ids must be unique, got {ids}")
    if master.node_id in ids:
        raise m.error("node_id", f"{master.node_id} is also a node's")
    c = top.section("campaign", required=False)
    levels = lambda key, dflt: tuple(c.get(key, list, list(dflt)))  # noqa: E731
    campaign = CampaignConfig(
        velocity_levels=levels("velocity_levels", CampaignConfig.velocity_levels),
        acceleration_levels=levels("acceleration_levels", CampaignConfig.acceleration_levels),
        cycles=c.get("cycles", int, 25, low=1, high=10_000),
        max_axis_time_s=c.get("max_axis_time_s", float, 300.0, low=0.1, high=3600.0),
        move_fraction=c.get("move_fraction", float, 0.8, low=0.01, high=1.0),
        dwell_s=c.get("dwell_s", float, 0.05, low=0.0, high=60.0),
        together=c.get("together", bool, False),
        design=c.get("design", str, "paper", choices=DESIGNS),
        short_time_s=c.get("short_time_s", float, 30.0, low=5.0, high=600.0),
    )
    for key in ("velocity_levels", "acceleration_levels"):
        vals = getattr(campaign, key)
        if not vals or len(vals) > 20 or not all(finite_number(v) and 0 < v <= 1 for v in vals):
            raise c.error(key, f"must be a list of fractions of the limit in (0, 1], got {list(vals)!r}")
    c.done()
    a = top.section("acceptance", required=False)
    d = Acceptance()
    acceptance = Acceptance(
        min_phase_margin_deg=a.get("min_phase_margin_deg", float, d.min_phase_margin_deg, low=0.0, high=90.0),
        min_gain_margin_db=a.get("min_gain_margin_db", float, d.min_gain_margin_db, low=0.0, high=60.0),
        min_fe_improvement=a.get("min_fe_improvement", float, d.min_fe_improvement, low=0.0, high=1e6),
        max_rmse_over_noise=a.get("max_rmse_over_noise", float, d.max_rmse_over_noise, low=1.0, high=1e6),
        max_relative_std=a.get("max_relative_std", float, d.max_relative_std, low=0.0, high=10.0),
        require_consistent=a.get("require_consistent", bool, d.require_consistent),
    )
    a.done()
    top.done()
    log.debug(
        "%s: nodes %s, SYNC every %g ms, campaign %s",
        path,
        ", ".join(f"{a} ({n.node_id})" for a, n in nodes.items()),
        1e3 * master.sync_period_s,
        campaign.design,
    )
    return BusConfig(path=path, master=master, nodes=nodes, campaign=campaign, acceptance=acceptance)
