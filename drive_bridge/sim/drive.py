"""One simulated CiA 402 servo drive: a CANopen slave on the robot's bus.

As canopen builds a node from its services, a drive is built from its own: the SDO server is
canopen's ``LocalNode``, its objects :mod:`.storage`'s, and beside them the NMT slave with the
heartbeat producer (:mod:`.nmt_slave`), the heartbeat consumer (:mod:`.heartbeats`), the
emergency producer (:mod:`.emergency`), the PDOs as the master maps them (:mod:`.pdo_map`; TPDOs
sent on SYNC, synchronous RPDOs applied on SYNC), its controller's objects (:mod:`.gain_objects`),
the motion it makes itself in PV (3), PP (1), homing (6) and quick stop (:mod:`.profile_motion`,
:mod:`.home_search`) and maxon's PVT buffer (:mod:`.pvt_buffer`).  This module holds what ties
them to the drive: the SDO hooks, the CiA 402 device control (:mod:`.state_machine`'s
transitions, the statusword), the modes it lists in 0x6502 (positions counted from home once it
has homed), the cyclic part -- following the master in CSP (8) and IP (7) with the safety
functions (following-error window, software position limits, loss of setpoint) -- and the actual
values.  The loops and the plant live in :mod:`.kernel`; this module converts between device
units and SI at its edge.

A drive is built from an EDS/DCF -- the project's own or a vendor's (:mod:`.vendors`) -- and
behaves as that drive: its object dictionary and identity, only the modes it lists, its
feedback objects and units, its gain objects turned into the same cascade loops through the
drive profile's scales, and no torque offset or store object where the file has none.

A drive knows the robot it sits in only through :class:`DriveHost` (as a
canopen node knows only its Network): the time, the SYNC period, a way to send
a frame, the robot's noise source, and a call when its RPDO routes change.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from functools import partial
from typing import Any, Protocol

import numpy as np
from canopen.objectdictionary import ODVariable
from canopen.sdo import SdoAbortedError

from ..cia.factor import OBJECTS as FACTOR_OBJECTS
from ..cia.factor import FactorGroup
from ..cia.objects import (
    ABORT_CONNECTION_OPTION,
    BUFFER_CLEAR,
    BUFFER_FILL,
    BUFFER_MAXIMUM,
    COB_ID_SYNC,
    CONTROLWORD,
    CYCLE_PERIOD,
    DEVICE_TYPE,
    ERROR_CODE,
    ERROR_FIELD,
    ERROR_REGISTER,
    FOLLOWING_ERROR_ACTUAL,
    FOLLOWING_ERROR_TIMEOUT,
    FOLLOWING_ERROR_WINDOW,
    HEARTBEAT_CONSUMER,
    HEARTBEAT_PRODUCER,
    IDENTITY_OBJECT,
    INTERPOLATION_DATA_CONFIGURATION,
    INTERPOLATION_SUB_MODE,
    INTERPOLATION_TIME_PERIOD,
    MAX_PROFILE_VELOCITY,
    MAX_TORQUE,
    MODES_OF_OPERATION,
    MODES_OF_OPERATION_DISPLAY,
    MOTOR_RATED_CURRENT,
    MOTOR_RATED_TORQUE,
    PDO_PARAMETERS_END,
    POSITION_ACTUAL,
    POSITION_ENCODER_RESOLUTION,
    PROFILE_ACCELERATION,
    PROFILE_DECELERATION,
    PROFILE_VELOCITY,
    QUICK_STOP_DECELERATION,
    QUICK_STOP_OPTION,
    RESTORE_DEFAULTS,
    RPDO_COMMUNICATION,
    SOFTWARE_POSITION_LIMIT,
    STATUSWORD,
    STORE_PARAMETERS,
    SUPPORTED_DRIVE_MODES,
    SYNC_COUNTER_OVERFLOW,
    TARGET_POSITION,
    TORQUE_ACTUAL,
    TORQUE_OFFSET,
    VELOCITY_ACTUAL,
    VELOCITY_OFFSET,
)
from ..cia.od import default, limits, load_od
from ..cia.p301 import (
    ERR_FOLLOWING,
    ERR_HEARTBEAT,
    ERR_PARAMETER,
    ERR_PDO_LENGTH,
    ERR_RPDO_TIMEOUT,
    ERR_SOFTWARE,
    MAX_SYNC_COUNTER,
    NMT_OPERATIONAL,
    NMT_PREOP,
    SYNC_PRODUCER,
)
from ..cia.p402 import (
    ABORT_DISABLE,
    ABORT_FAULT,
    ABORT_QUICK_STOP,
    CSP,
    CW_HALT_BIT,
    ENABLED,
    FAULT,
    FAULT_REACTION,
    HM,
    IP,
    PP,
    PV,
    QUICK_STOP,
    STATE_BITS,
    SW_FOLLOWING,
    SW_FOLLOWING_ERROR,
    SW_HOMING_ATTAINED,
    SW_HOMING_ERROR,
    SW_INTERNAL_LIMIT,
    SW_REMOTE,
    SW_SPEED_ZERO,
    SW_TARGET_REACHED,
    SW_VOLTAGE_ENABLED,
    SWITCH_ON_DISABLED,
    VOLTAGE_ENABLED,
)
from ..cia.pdo import PdoCodec
from ..cia.setpoint import IP_RECORD, PVT, SETPOINT_OBJECTS, position_of, supported_modes
from . import cyclic, kernel
from .adapters import local_node
from .emergency import EmcyProducer
from .gain_objects import GainObjects
from .heartbeats import HeartbeatConsumer
from .ip_fifo import IpFifo
from .nmt_slave import RESET_COMMUNICATION, NmtSlave
from .pdo_map import ABORT_RANGE, ABORT_STATE, PdoMapping
from .plant import Plant, whole_ticks
from .profile_motion import ProfileMotion
from .pvt_buffer import ERR_UNDERFLOW, PvtBuffer
from .pvt_buffer import RECORDS as PVT_RECORDS
from .robot_config import SimAxis
from .state_machine import next_state
from .storage import ObjectStorage
from .vendors import factory, spec_for

log = logging.getLogger(__name__)

IMPLEMENTED_MODES = (PP, PV, HM, IP, CSP)
SAVE_SIGNATURE = 0x65766173  # 'save'
#: option codes -> the first value CiA 402 reserves (negative values: the manufacturer's): the
#: quick stop option code 0x605A defines 0..8, the abort connection option 0x6007 0..3
RESERVED_FROM = {QUICK_STOP_OPTION: 9, ABORT_CONNECTION_OPTION: 4}
LOAD_SIGNATURE = 0x64616F6C  # 'load'

SETPOINT_TIMEOUT_PERIODS = 10  # CSP: no setpoint for this many interpolation periods -> fault

_MOTOR_OBJECTS = {1: "R", 2: "L", 3: "kt", 4: "vbus"}  # 0x2002 of the project's drive
DEVICE_TYPE_SERVO = 0x00020192  # CiA 402, servo drive


def plant_params(p: np.ndarray, axis: SimAxis, axis_names: list[str]) -> None:
    """Write the plant, motor and hidden effects of ``axis`` into its kernel parameter row ``p``.

    Parameters
    ----------
    p : numpy.ndarray
        The axis's parameter row (written in place).
    axis : SimAxis
        The axis.
    axis_names : list of str
        Every axis of the robot in row order (a cross-axis effect names its source).
    """
    m = axis.motor
    p[kernel.J], p[kernel.C0], p[kernel.C1], p[kernel.CP], p[kernel.D] = (
        axis.J,
        axis.c0,
        axis.c1,
        axis.cp,
        axis.D,
    )
    p[kernel.KT], p[kernel.R], p[kernel.L], p[kernel.VBUS] = m.kt, m.R, m.L, m.vbus
    p[kernel.CPL_SRC] = -1.0
    p[kernel.BRAKE] = 1.0 if axis.brake else 0.0
    p[kernel.END_LO], p[kernel.END_HI] = axis.end_stops_rad or (0.0, 0.0)
    for values in axis.effects.values():
        for name, value in values.items():
            p[getattr(kernel, name)] = float(axis_names.index(value)) if name == "CPL_SRC" else value


class DriveHost(Protocol):
    """What a simulated drive needs of the robot it sits in."""

    def send(self, cob_id: int, data: bytes) -> None:
        """Put a frame on the bus, stamped with the robot's clock.

        Parameters
        ----------
        cob_id : int
            Its COB-ID.
        data : bytes
            Its data.
        """

    def routes_changed(self) -> None:
        """The drive's RPDO COB-IDs changed."""

    def cycle_period_written(self, period_us: int) -> None:
        """0x1006 (or 0x60C2) written: the SYNC period [µs] the drives' loops lock to.

        Parameters
        ----------
        period_us : int
            [µs].
        """

    def sync_producer_written(self, drive: SimDrive, producing: bool) -> None:
        """0x1005 written on ``drive``: whether it produces SYNC (bit 30).

        Parameters
        ----------
        drive : SimDrive
            The drive written.
        producing : bool
            Bit 30.
        """


class _Held:
    """A drive attribute held in its row of the drive array (:mod:`.cyclic`), where the compiled
    SYNC path reads and writes it too."""

    def __init__(self, column: int, kind: type):
        self.column, self.kind = column, kind

    def __get__(self, drive: SimDrive, owner: type) -> Any:
        return self.kind(drive.drive_values.item(self.column))

    def __set__(self, drive: SimDrive, value: Any) -> None:
        drive.drive_values[self.column] = value


class SimDrive:
    """A servo drive of one axis in ``host``.

    Parameters
    ----------
    host : DriveHost
        The robot it sits in.
    index : int
        The axis's row in the plant's arrays (:meth:`.plant.Plant.rows`: state, param, demand, and
        the drive array of :mod:`.cyclic`, views of this axis's rows; the plant's clock and seeded
        noise are the drive's).
    axis : SimAxis
        The axis.
    eds_path : str
        The drive's EDS (its object dictionary).
    plant : Plant
        The plant's arrays, clock and noise.
    axis_names : list of str
        Every axis of the robot in row order (a cross-axis effect names its source).
    """

    pos_per_rad = _Held(cyclic.X_POS_PER_RAD, float)  # position unit per rad (motor side)
    vel_per_si = _Held(cyclic.X_VEL_PER_SI, float)  # velocity unit per rad/s
    origin_rad = _Held(cyclic.X_ORIGIN, float)  # the plant position the drive counts as 0 (homing)
    rated_torque = _Held(cyclic.X_RATED_TORQUE, float)  # [Nm] (0x6076)
    v_dem = _Held(cyclic.X_V_DEM, float)  # demand velocity of the current period [rad/s]
    setpoint_inc = _Held(cyclic.X_SETPOINT, int)  # the last CSP target / IP record position [increments]
    new_target = _Held(cyclic.X_NEW_TARGET, bool)  # a CSP target / IP record arrived since the last SYNC
    internal_limit = _Held(cyclic.X_LIMITED, bool)  # the demand held at a software position limit
    last_setpoint_time = _Held(cyclic.X_SETPOINT_TIME, float)
    setpoint_armed = _Held(cyclic.X_ARMED, bool)  # loss-of-setpoint watchdog armed (CSP streaming started)
    _last_count = _Held(cyclic.X_LAST_COUNT, int)  # encoder count and time of the last sample
    _last_sync_sample = _Held(cyclic.X_LAST_TIME, float)
    _velocity = _Held(cyclic.X_VELOCITY, int)  # the actual values as their objects hold them
    _torque_pm = _Held(cyclic.X_TORQUE_PM, int)
    _current = _Held(cyclic.X_CURRENT, int)
    _position_inc = _Held(cyclic.X_POSITION, int)

    def __init__(
        self, host: DriveHost, index: int, axis: SimAxis, eds_path: str, plant: Plant, axis_names: list[str]
    ):
        self.plant = plant
        self.plant_state, self.plant_param, self.plant_demand, self.drive_values = plant.rows(
            index
        )  # kernel and drive rows of this axis (views)
        self.abort_writes: dict[tuple[int, int], int] = {}  # injected SDO aborts, for tests
        #: injected faults, for tests: called as (kind "read" | "write", index, sub) before an SDO
        #: request is handled; it may raise (SdoAbortedError: the drive refuses), take the drive off
        #: the bus, or, for a read, return a value the drive answers instead of its own
        self.sdo_fault: Callable[[str, int, int], int | None] | None = None
        self.host = host
        self.index = index
        self.axis = axis
        self.axis_names = axis_names
        self.node_id = axis.node_id
        self.spec = spec_for(eds_path)
        #: its controller: loops, rates, factory gains, and the objects that hold its gains and model
        self.gains = GainObjects(self.spec.profile, axis.motor.kt, eds_path)
        # heartbeat and NMT run in simulation time here, not in canopen's timer thread
        self.node = local_node(axis.node_id, load_od(eds_path, axis.node_id), self._send)
        self.node.add_write_callback(self._on_sdo_write)
        self.node.add_read_callback(self._on_sdo_read)
        self.od = self.node.object_dictionary
        #: its objects' values, the measured ones read live, and the parameter set a reset restores
        self.objects = ObjectStorage(self.node, self._live_objects())
        self.pdos = PdoMapping(self.od, self.objects.get, self.objects.getter)
        encoder = self.od.get_variable(POSITION_ENCODER_RESOLUTION, 1)
        #: the encoder's increments per rad (what the kernel quantises the position with)
        if encoder is not None and encoder.default:
            self.inc_per_rad = (
                self.objects.get(POSITION_ENCODER_RESOLUTION, 1)
                / self.objects.get(POSITION_ENCODER_RESOLUTION, 2)
                / (2 * math.pi)
            )
        elif self.spec.increments_per_rev is not None:
            self.inc_per_rad = self.spec.increments_per_rev / (2 * math.pi)
        else:
            raise ValueError(
                f"{self.spec.profile}: neither its EDS/DCF (0x608F) nor the simulator's description "
                f"gives the encoder's increments per revolution"
            )
        self.pos_per_rad = self.vel_per_si = self.inc_per_rad
        self.modes = [m for m in supported_modes(self._supported_bits()) if m in IMPLEMENTED_MODES]
        self.online = True  # False: the drive has dropped off the bus
        #: interpolating PVT records on its own clock (the first one taken at a period start)
        self.pvt_running = False
        #: maxon's PVT input buffer, where the drive takes PVT records
        self.pvt: PvtBuffer | None = (
            PvtBuffer()
            if self.od.get_variable(*PVT) is not None
            and self.od.get_variable(INTERPOLATION_DATA_CONFIGURATION, BUFFER_CLEAR) is not None
            else None
        )
        #: the project drive's deep FIFO of 0x60C1:1 records (0x60C4:1 above one record)
        capacity = default(self.od, INTERPOLATION_DATA_CONFIGURATION, BUFFER_MAXIMUM) or 0
        self.fifo: IpFifo | None = IpFifo(int(capacity)) if self.pvt is None and capacity > 1 else None
        self._init_storage()
        self.objects.save()
        self._power_up()

    # ------------------------------------------------------------------ storage
    def _supported_bits(self) -> int:
        var = self.od.get_variable(SUPPORTED_DRIVE_MODES, 0)
        return (
            var.default if var is not None and var.default is not None else (self.spec.supported_modes or 0)
        )

    def _init_storage(self) -> None:
        """Factory state: zero, or the nearest value the file's limits allow, where the file gives
        no value (a vendor file leaves many out), the fixed values (identity, motor data), and the
        factory gains in the drive's units."""
        self.objects.clear()
        for obj in self.od.values():
            for var in obj.values() if hasattr(obj, "values") else [obj]:
                if (
                    var.default is None
                    and var.value is None
                    and var.readable
                    and var.data_type in var.STRUCT_TYPES
                    and var.index not in self.objects.live
                ):
                    lo, hi = limits(var)
                    value = max(0, lo) if lo is not None else 0
                    self.objects.set(var.index, var.subindex, min(value, hi) if hi is not None else value)
        self._init_storage_missing()
        m = self.axis.motor
        if MOTOR_RATED_TORQUE in self.od:
            self.objects.set(MOTOR_RATED_TORQUE, 0, round(m.rated_torque_Nm * 1000))  # mNm
        if MOTOR_RATED_CURRENT in self.od:
            self.objects.set(MOTOR_RATED_CURRENT, 0, round(m.rated_torque_Nm / m.kt * 1000))  # mA
        if encoder_var := self.od.get_variable(POSITION_ENCODER_RESOLUTION, 1):
            if not encoder_var.default:
                self.objects.set(POSITION_ENCODER_RESOLUTION, 1, round(self.inc_per_rad * 2 * math.pi))
                self.objects.set(POSITION_ENCODER_RESOLUTION, 2, 1)
        self._units()
        if not self.spec.factory_in_file:
            f = factory()
            for index, sub, value in self.gains.factory_values():
                self.objects.set(index, sub, value)
            for index, value in (
                (MAX_TORQUE, f.max_torque_permille),
                (FOLLOWING_ERROR_TIMEOUT, f.fe_timeout_ms),
                (QUICK_STOP_DECELERATION, f.quick_stop_rad_s2 * self.vel_per_si),
                (PROFILE_VELOCITY, f.profile_velocity_rad_s * self.vel_per_si),
                (PROFILE_ACCELERATION, f.profile_acceleration_rad_s2 * self.vel_per_si),
                (PROFILE_DECELERATION, f.profile_acceleration_rad_s2 * self.vel_per_si),
            ):
                if index in self.od:
                    self.objects.set(index, 0, round(value))
        if (saved := self.axis.saved_limits) is not None:  # the machine's commissioning, kept in the drive
            for (index, sub), value in (
                ((SOFTWARE_POSITION_LIMIT, 1), saved.stroke_rad[0] * self.pos_per_rad),
                ((SOFTWARE_POSITION_LIMIT, 2), saved.stroke_rad[1] * self.pos_per_rad),
                ((MAX_PROFILE_VELOCITY, 0), saved.max_velocity_rad_s * self.vel_per_si),
                ((PROFILE_ACCELERATION, 0), saved.acceleration_rad_s2 * self.vel_per_si),
                ((PROFILE_DECELERATION, 0), saved.acceleration_rad_s2 * self.vel_per_si),
            ):
                if self.od.get_variable(index, sub) is not None:
                    self.objects.set(index, sub, round(value))

    def _units(self) -> None:
        """Device units per rad and per rad/s from the factor group the drive holds (its EDS
        defaults until the master writes it); where its objects do not say, the encoder's
        increments and the velocity unit of :mod:`.vendors`."""
        group = FactorGroup.read(
            lambda i, s: self.objects.get(i, s) if self.od.get_variable(i, s) is not None else None
        )
        self.pos_per_rad = group.position_per_rad or self.inc_per_rad
        self.vel_per_si = group.velocity_per_rad_s or (
            60 / (2 * math.pi) if self.spec.velocity_unit == "rpm" else self.pos_per_rad
        )
        self.plant_param[kernel.FE_WINDOW] = (
            self.objects.get(FOLLOWING_ERROR_WINDOW) / self.pos_per_rad
        )  # the window is in position units

    def _power_up(self) -> None:
        """Reset application: load parameters from storage, state machine to start."""
        p, s = self.plant_param, self.plant_state
        plant_params(p, self.axis, self.axis_names)
        p[kernel.INC_PER_RAD] = self.inc_per_rad
        m = self.axis.motor
        self.rated_torque = self.objects.get_or(MOTOR_RATED_TORQUE, 0, m.rated_torque_Nm * 1000) / 1000.0
        self.rated_current_A = (
            self.objects.get_or(MOTOR_RATED_CURRENT, 0, m.rated_torque_Nm / m.kt * 1000) / 1000.0
        )
        self.drive_values[cyclic.X_CURRENT_UNIT] = (
            1e-3 if self.spec.current_unit == "mA" else self.rated_current_A / 1000.0
        )
        self.drive_values[cyclic.X_NOISE] = self.axis.torque_noise_Nm
        p[kernel.STRUCT] = (
            kernel.POSITION_PID if self.gains.controller.structure == "position_pid" else kernel.CASCADE
        )
        p[kernel.LOOP_DIV] = self.gains.loop_div
        self.gains.load(p, self.objects.get)
        p[kernel.TMAX] = (
            self.objects.get_or(MAX_TORQUE, 0, factory().max_torque_permille) / 1000.0 * self.rated_torque
        )
        self._units()
        self.state = SWITCH_ON_DISABLED
        #: its NMT state, boot-up and heartbeat producer
        self.nmt = NmtSlave(self.node_id, self._send, lambda: self.objects.get(HEARTBEAT_PRODUCER))
        self.controlword = 0
        self.mode = self.objects.get(MODES_OF_OPERATION)
        self.emcy = EmcyProducer(self.node_id, self._send)  # EMCY, 0x603F and 0x1003
        self.internal_limit = False
        self.new_target = False
        self.setpoint_inc = 0
        self.setpoint_armed = False
        self.last_setpoint_time = 0.0
        self.v_dem = 0.0
        self.origin_rad = 0.0
        #: the motion it makes itself (quick stop, halt, PV, PP, homing) and the bits that watch it
        self.profile = ProfileMotion(self)
        s[kernel.ENABLED] = 0.0
        self._last_count = math.floor(s[kernel.Q] * self.inc_per_rad)
        self._last_sync_sample = self._sampled_at = self.plant.time
        self._velocity = 0
        self.plant_demand[:] = 0.0
        self.plant_demand[kernel.P0] = self.plant_demand[kernel.P1] = self.plant_state[kernel.ENC] = (
            self._last_count / self.inc_per_rad
        )
        if self.pvt is not None:
            self.pvt.reset()
        self.pvt_running = False
        if self.fifo is not None:
            self.fifo.reset()
            self._fill_changed()
        self.pdos.reset()
        self.heartbeats = HeartbeatConsumer(partial(self.objects.get_or, fallback=None))
        self.host.routes_changed()  # (its RPDOs' and the heartbeats it consumes)
        self._refresh_actuals(noise=False)

    # ------------------------------------------------------------------ NMT
    def boot(self) -> None:
        """Initialisation done: the boot-up message, pre-operational."""
        self.nmt.boot(self.plant.time)

    def on_nmt(self, data: bytes) -> None:
        """An NMT command; a reset restores the stored parameters (reset communication: only
        those of the communication area 0x1000-0x1FFF) and boots the drive again.

        Parameters
        ----------
        data : bytes
            The NMT frame's data.
        """
        reset = self.nmt.command(data)
        if reset is None:
            return
        self.objects.restore(communication_only=reset == RESET_COMMUNICATION)
        self._init_storage_missing()
        self._power_up()
        self.boot()

    def _init_storage_missing(self) -> None:
        """What no parameter store holds: motor data, identity, device type, supported modes."""
        m = self.axis.motor
        if self.spec.factory_in_file:
            for sub, name in _MOTOR_OBJECTS.items():
                self.objects.set(0x2002, sub, getattr(m, name))
        info = self.od.device_information
        for sub, value in ((1, info.vendor_number), (2, info.product_number), (3, info.revision_number)):
            var = self.od.get_variable(IDENTITY_OBJECT, sub)
            if var is not None and var.default is None:
                self.objects.set(IDENTITY_OBJECT, sub, value or 0)
        self.objects.set(IDENTITY_OBJECT, 4, self.axis.serial)
        if default(self.od, DEVICE_TYPE) is None:
            self.objects.set(DEVICE_TYPE, 0, DEVICE_TYPE_SERVO)
        if SUPPORTED_DRIVE_MODES in self.od and default(self.od, SUPPORTED_DRIVE_MODES) is None:
            self.objects.set(SUPPORTED_DRIVE_MODES, 0, self.spec.supported_modes)
        if self.pvt is not None:  # maxon's EDS gives no size: the drive says it (0x60C4:1 and :2)
            for sub in (BUFFER_MAXIMUM, BUFFER_FILL):
                if self.od.get_variable(INTERPOLATION_DATA_CONFIGURATION, sub) is not None:
                    self.objects.set(INTERPOLATION_DATA_CONFIGURATION, sub, PVT_RECORDS)

    def heartbeat_due(self, now: float) -> None:
        """Its own heartbeat and its event-driven TPDOs, when due.

        Parameters
        ----------
        now : float
            The robot's time [s].
        """
        self.nmt.beat(now)
        if self.nmt.state == NMT_OPERATIONAL and self.pdos.events:
            self.refresh_actuals()
            for cob_id, data in self.pdos.event_frames(now):
                self._send(cob_id, data)

    # ------------------------------------------------------------------ heartbeat consumer
    def _consumers_changed(self) -> None:
        """0x1016 written: the nodes the drive watches, and the routes to its consumer."""
        self.heartbeats.configure()
        self.host.routes_changed()

    def on_heartbeat(self, node: int) -> None:
        """A heartbeat heard from a node its consumer watches (0x1016).

        Parameters
        ----------
        node : int
            The node.
        """
        self.heartbeats.heard(node, self.plant.time)

    def supervise(self, now: float) -> None:
        """A watched node silent for longer than its consumer time: EMCY 0x8130, the NMT state
        falls back to pre-operational (0x1029's default) and, in OPERATION ENABLED, the drive does
        what its abort connection option 0x6007 says (a drive without 0x6007 does nothing).

        Parameters
        ----------
        now : float
            The robot's time [s].
        """
        for _node in self.heartbeats.fallen_silent(now):
            if self.nmt.state == NMT_OPERATIONAL:
                self.nmt.state = NMT_PREOP
            self._connection_lost(ERR_HEARTBEAT, self.objects.get_or(ABORT_CONNECTION_OPTION, 0, 0))

    def _connection_lost(self, code: int, option: int) -> None:
        """EMCY ``code``; in OPERATION ENABLED, what the abort connection option says."""
        self.setpoint_armed = False
        if self.state == ENABLED and option == ABORT_FAULT:
            self.fault(code)  # (its EMCY carries the code)
            return
        self.emcy.send(code)
        if self.state != ENABLED:
            return
        if option == ABORT_DISABLE:
            self._go(SWITCH_ON_DISABLED)
        elif option == ABORT_QUICK_STOP:
            self._go(QUICK_STOP)

    # ------------------------------------------------------------------ SDO hooks
    def _on_sdo_read(self, index: int, subindex: int, od: ODVariable) -> int | None:
        if self.sdo_fault is not None:
            answer = self.sdo_fault("read", index, subindex)
            if answer is not None:
                return answer
        live = self.objects.live.get(index)
        if live is not None:
            if self.plant.time not in (self._last_sync_sample, self._sampled_at):  # once per instant
                self.refresh_actuals()
            return live()
        if index in (STORE_PARAMETERS, RESTORE_DEFAULTS) and subindex == 1:
            return 1  # device saves/restores on command
        if index == ERROR_FIELD:
            return self.emcy.field(subindex)
        return None

    def _on_sdo_write(self, index: int, subindex: int, od: ODVariable, data: bytes) -> None:
        if self.sdo_fault is not None:
            self.sdo_fault("write", index, subindex)
        code = self.abort_writes.get((index, subindex))
        if code is not None:
            raise SdoAbortedError(code)
        value = od.decode_raw(data)
        self.write(index, subindex, value)
        self.objects.written(index, subindex, value)
        if index in FACTOR_OBJECTS:  # new units: every position value is read anew
            self._units()
        elif index == HEARTBEAT_CONSUMER:
            self._consumers_changed()

    def write(self, index: int, sub: int, value: Any) -> None:
        """Apply a value written by SDO or RPDO; raise SdoAbortedError to refuse it.

        Parameters
        ----------
        index, sub : int
            The object.
        value : object
            The value, in device units.

        Raises
        ------
        SdoAbortedError
            The drive refuses it (with the abort code a real drive gives).
        """
        if RPDO_COMMUNICATION <= index <= PDO_PARAMETERS_END:
            self.pdos.check_write(index, sub, value)
            self.objects.set(index, sub, value)
            self._rebuild_pdos()
            return
        if index == CONTROLWORD:
            self._on_controlword(value)
        elif index in RESERVED_FROM:  # an option code whose value CiA 402 reserves
            if RESERVED_FROM[index] <= value:
                raise SdoAbortedError(ABORT_RANGE)
        elif index == MODES_OF_OPERATION:
            if value != 0 and value not in self.modes:
                raise SdoAbortedError(ABORT_RANGE)
            if value != self.mode and self.state == ENABLED:
                self._hold_position()
                if value == CSP:
                    self.mode = value
                    self._take_target()
            self.mode = value
        elif index == TORQUE_OFFSET:  # torque offset [per mille of rated torque]
            self.plant_demand[kernel.T_OFF] = value / 1000.0 * self.rated_torque
        elif index == VELOCITY_OFFSET:  # velocity offset [velocity unit]
            self.plant_demand[kernel.V_OFF] = value / self.vel_per_si
        elif (index, sub) == PVT and self.pvt is not None:  # maxon: into the buffer, taken one a period
            if (code := self.pvt.put(value)) is not None:
                self._buffer_error(code)
        elif index == INTERPOLATION_DATA_CONFIGURATION and sub == BUFFER_CLEAR and self.pvt is not None:
            self.pvt.control(value)
        elif index == INTERPOLATION_DATA_CONFIGURATION and sub == BUFFER_CLEAR and self.fifo is not None:
            self.fifo.control(value)
            self._fill_changed()
        elif (index, sub) == IP_RECORD and self.fifo is not None and self.fifo.enabled:
            if (code := self.fifo.put(value)) is not None:  # into the FIFO, taken one a period
                self.fault(code)
            self._fill_changed()
        elif (index, sub) in SETPOINT_OBJECTS:
            if SETPOINT_OBJECTS[(index, sub)] == self.mode:  # 0x607A in PP is read on the set-point edge
                self.setpoint_inc = position_of((index, sub), value)
                self.new_target = True
                self.last_setpoint_time = self.plant.time
                if self.following:
                    self.setpoint_armed = True
        elif self.gains.selects(index, sub):
            self.objects.written(index, sub, value)  # (stored after this call: the loops read it now)
            with self._bumpless():
                self.gains.load(self.plant_param, self.objects.get)
        elif (taken := self.gains.written(index, sub, value)) is not None:
            with self._bumpless():
                self.plant_param[taken[0]] = taken[1]
        elif index == HEARTBEAT_PRODUCER:
            self.nmt.heartbeat_time_written(self.plant.time, value)
        elif index == CYCLE_PERIOD:
            self.host.cycle_period_written(value)
        elif index == INTERPOLATION_TIME_PERIOD and sub in (1, 2):
            self._interpolation_period_written(sub, value)
        elif index == COB_ID_SYNC:
            self.host.sync_producer_written(self, bool(value & SYNC_PRODUCER))
        elif index == SYNC_COUNTER_OVERFLOW:  # CiA 301: only while no cycle period runs; 1 is not a value
            if self.objects.get_or(CYCLE_PERIOD, 0, 0):
                raise SdoAbortedError(ABORT_STATE)
            if value == 1 or value > MAX_SYNC_COUNTER:
                raise SdoAbortedError(ABORT_RANGE)
        elif index == FOLLOWING_ERROR_WINDOW:
            self.plant_param[kernel.FE_WINDOW] = value / self.pos_per_rad
        elif index == MAX_TORQUE:
            self.plant_param[kernel.TMAX] = value / 1000.0 * self.rated_torque
        elif index == STORE_PARAMETERS and sub == 1:
            if value != SAVE_SIGNATURE:
                raise SdoAbortedError(0x08000020)
            self.objects.save()
            return
        elif index == RESTORE_DEFAULTS and sub == 1:
            if value != LOAD_SIGNATURE:
                raise SdoAbortedError(0x08000020)
            self.objects.saved = {}
            return
        elif index == ERROR_FIELD and sub == 0:
            if value != 0:
                raise SdoAbortedError(ABORT_RANGE)
            self.emcy.history.clear()
            return

    # ------------------------------------------------------------------ PDOs
    def _rebuild_pdos(self) -> None:
        """Compile the codecs of every valid PDO and tell the robot the RPDO routes."""
        self.pdos.rebuild()
        self.host.routes_changed()

    @property
    def rpdos(self) -> dict[int, tuple[PdoCodec, int]]:
        """Its RPDOs as mapped: COB-ID -> (codec, transmission type)."""
        return self.pdos.rpdos

    def on_rpdo(self, cob_id: int, data: bytes) -> None:
        """An RPDO received (only in OPERATIONAL): an asynchronous one takes effect now, a
        synchronous one at the next SYNC.

        Parameters
        ----------
        cob_id : int
            Its COB-ID.
        data : bytes
            Its data.
        """
        if self.nmt.state != NMT_OPERATIONAL:
            return
        codec, ttype = self.rpdos[cob_id]
        if len(data) < codec.struct.size:
            self.emcy.send(ERR_PDO_LENGTH)  # CiA 301: not processed, length error
            return
        if ttype <= 240:
            self.pdos.pending.append((codec, data))  # synchronous: applied on the next SYNC
        else:
            self._apply_rpdo(codec, data)

    def _apply_rpdo(self, codec: PdoCodec, data: bytes) -> None:
        """The whole PDO taken before any of it acts: every value first, the controlword last (a new
        set-point takes the target of the same PDO).  A value the drive cannot take is not taken:
        an EMCY says so (parameter error) and the rest of the PDO is."""
        entries = list(zip(codec.entries, codec.spans, codec.struct.unpack_from(data)))
        for (index, sub), (lo, hi), value in sorted(entries, key=lambda entry: entry[0][0] == CONTROLWORD):
            try:
                self.write(index, sub, value)
            except SdoAbortedError:
                self.emcy.send(ERR_PARAMETER)
                continue
            self.objects.keep(index, sub, data[lo:hi], value)

    def internal_error(self) -> None:
        """A frame the drive's software could not handle (a bug of the simulator): the drive faults
        with EMCY 0x6100 and goes on serving, as a drive's firmware would."""
        log.exception("simulated drive %s: internal error", self.axis.name)
        if self.state == FAULT:
            self.emcy.send(ERR_SOFTWARE)
        else:
            self.fault(ERR_SOFTWARE)

    def send_tpdos(self) -> None:
        """A SYNC: the synchronous TPDOs due at it."""
        for cob_id, data in self.pdos.synchronous_frames():
            self._send(cob_id, data)

    # ------------------------------------------------------------------ CiA 402
    @property
    def statusword(self) -> int:
        """0x6041 as the drive shows it now.

        Returns
        -------
        int
            The statusword (its state, remote, voltage enabled, target reached, limits, ...).
        """
        sw = STATE_BITS[self.state] | SW_REMOTE
        if self.state in VOLTAGE_ENABLED:
            sw |= SW_VOLTAGE_ENABLED
        if self.profile.reached:
            sw |= SW_TARGET_REACHED
        if self.internal_limit:
            sw |= SW_INTERNAL_LIMIT
        if self.mode == HM:  # bit 12 homing attained, bit 13 homing error
            homing = self.profile.homing
            return (  # bit 10: at rest (not started, interrupted, or ended), as CiA 402 tables them
                (sw & ~SW_TARGET_REACHED)
                | (SW_TARGET_REACHED if self.state != ENABLED or homing.phase is None else 0)
                | (SW_HOMING_ATTAINED if homing.attained else 0)
                | (SW_HOMING_ERROR if homing.error else 0)
            )
        if self.mode == PV:  # bit 12: speed = 0 (0x606F for 0x6070); bit 13 (max slippage) unwatched
            return sw | (SW_SPEED_ZERO if self.profile.speed_zero() else 0)
        if self.following or (self.state == ENABLED and self.mode == PP and self.profile.acknowledged):
            sw |= SW_FOLLOWING  # CSP: follows the command value; IP: active; PP: set-point acknowledged
        if self.plant_state.item(kernel.FE_COUNT) > 0:
            sw |= SW_FOLLOWING_ERROR
        return sw

    @property
    def following(self) -> bool:
        """Enabled and taking the master's setpoints: CSP, or IP with interpolation enabled (bit 4)
        and its FIFO not run dry."""
        return self.state == ENABLED and (
            self.mode == CSP or (self.mode == IP and bool(self.controlword & 0x10) and not self.ran_dry)
        )

    @property
    def ran_dry(self) -> bool:
        """Interpolating, its FIFO ran dry: the planned stop (:mod:`.ip_fifo`)."""
        return self.fifo is not None and self.fifo.dry and self.mode == IP

    def _on_controlword(self, cw: int) -> None:
        if cw == self.controlword and cw in (0x0F, 0x1F) and self.state == ENABLED:
            return  # the streaming steady state
        new_setpoint = cw & 0x10 and not self.controlword & 0x10
        if not cw & 0x10:
            self.pvt_running = False
        if new_setpoint and self.fifo is not None:
            self.fifo.dry = False  # interpolation enabled again: the records take over
        previous, self.controlword = self.controlword, cw
        if self.state == FAULT:
            if next_state(FAULT, cw, previous, 0) != FAULT:  # fault reset
                self.state = SWITCH_ON_DISABLED
                self.emcy.reset()
            return
        self._go(next_state(self.state, cw, previous, self.objects.get_or(QUICK_STOP_OPTION, 0, 2)))
        if not cw & 0x10:
            self.profile.acknowledged = False  # the handshake: bit 12 follows bit 4 down
        if self.state == ENABLED and self.mode == PP and new_setpoint:
            self.profile.new_setpoint(cw)
        homing = self.profile.homing
        if self.state == ENABLED and self.mode == HM:
            if new_setpoint and not cw & CW_HALT_BIT:
                homing.start()
            elif not cw & 0x10 or cw & CW_HALT_BIT:
                homing.interrupt()  # bit 4 down or halt: homing interrupted, ramp to rest
        else:
            homing.phase = None  # left OPERATION ENABLED: no homing goes on

    def _go(self, state: int) -> None:
        if state == self.state:
            return
        if state == ENABLED:
            self.plant_state[kernel.ENABLED] = 1.0
            self.plant_state[kernel.V_INT] = self.plant_state[kernel.I_INT] = 0.0
            self._hold_position()
            self.setpoint_armed = False
            if self.mode == CSP:
                self._take_target()
        elif state != QUICK_STOP:
            self.plant_state[kernel.ENABLED] = 0.0
        self.profile.reached = False  # bit 10 belongs to the state it was set in
        log.debug(
            "simulated drive %s: state %d -> %d (mode %d)", self.axis.name, self.state, state, self.mode
        )
        self.state = state

    def _take_target(self) -> None:
        """CSP from now on: the demand is the target position 0x607A as it stands, wherever the
        axis is (a stale target makes it jump, as on a real drive)."""
        self.setpoint_inc = self.objects.get(TARGET_POSITION)
        self.plant_demand[kernel.P0] = self.plant_demand[kernel.P1] = self.within_limits(
            self._plant(self.setpoint_inc)
        )

    def _hold_position(self) -> None:
        self.plant_demand[kernel.P0] = self.plant_demand[kernel.P1] = self.plant_state[kernel.ENC]
        self.plant_demand[kernel.A_FF] = 0.0
        self.v_dem = 0.0
        self.new_target = False
        self.profile.hold()

    def fault(self, code: int) -> None:
        """Fault: power off through FAULT REACTION, and its EMCY (nothing where it is in FAULT).

        Parameters
        ----------
        code : int
            The EMCY error code.
        """
        if self.state == FAULT:
            return
        self.state = FAULT_REACTION
        self.plant_state[kernel.ENABLED] = 0.0
        self.state = FAULT
        self.setpoint_armed = False
        log.debug("simulated drive %s: FAULT 0x%04X", self.axis.name, code)
        self.emcy.fault(code)

    # ------------------------------------------------------------------ cyclic
    @property
    def internal_profile(self) -> bool:
        """True when the drive generates its own demand on its own clock: quick stop, PV, PP,
        homing, and maxon's PVT records while it interpolates (each lasts its own time, whatever
        the SYNCs do)."""
        return self.state == QUICK_STOP or (
            self.state == ENABLED and (self.mode in (PV, PP, HM) or (self.pvt_running and self.pvt_clock))
        )

    @property
    def pvt_clock(self) -> bool:
        """Interpolating maxon's PVT records (IP, bit 4 set): from the period start that takes the
        first record, on the drive's own clock (:attr:`pvt_running`)."""
        return self.pvt is not None and self.mode == IP and self.following

    @property
    def streaming(self) -> bool:
        """Following the master's stream in CSP with its controlword held at enable operation:
        the steady state whose SYNC :func:`.cyclic.steady_period` can run."""
        return (
            self.online
            and self.state == ENABLED
            and self.mode == CSP
            and self.controlword in (0x0F, 0x1F)
            and self.nmt.state == NMT_OPERATIONAL
            and self.pvt is None
        )

    def on_sync(self) -> None:
        """SYNC: send TPDOs with the values at this instant, then latch new setpoints."""
        self.sample_sync()
        self.start_period(self.pdos.pending)

    def sample_sync(self) -> None:
        """A SYNC received: the synchronous TPDOs, with the actual values at this instant."""
        if self.online and self.nmt.state == NMT_OPERATIONAL:
            self.refresh_actuals(sync=True)
            self.send_tpdos()

    def start_period(self, rpdos: list[tuple[PdoCodec, bytes]]) -> None:
        """A SYNC period starts: the synchronous RPDOs received for it (``rpdos``, emptied) take
        effect and the interpolation period's demand is set.

        Parameters
        ----------
        rpdos : list of (PdoCodec, bytes)
            The synchronous RPDOs received for it (emptied here).
        """
        if not self.online:
            rpdos.clear()
            return
        if self.nmt.state == NMT_OPERATIONAL:
            for codec, data in rpdos:
                self._apply_rpdo(codec, data)
        rpdos.clear()
        if not self.internal_profile:
            self.next_period()
        else:
            self.record_due()

    def record_due(self) -> None:
        """Interpolating PVT records: where the record's own time is over, the next one."""
        if self.pvt_clock and self.plant.tick0[self.index] >= self.plant.period_ticks[self.index]:
            self.next_period()
            self.plant.tick0[self.index] = 0

    def next_period(self) -> None:
        """Set the demand P0 -> P1 of the interpolation period that starts now."""
        d, T = self.plant_demand, self.plant.sync_period
        if self.state == ENABLED and self.ran_dry:
            self._planned_stop(T)
            return
        if self.following:
            record_s = None  # a PVT record's own time
            if self.fifo is not None and self.mode == IP:
                position = self.fifo.take()
                self._fill_changed()
                if position is None:  # dry: the planned stop starts
                    self.new_target = False
                    self._planned_stop(T)
                    return
                self.setpoint_inc, self.new_target = position, True
                self.last_setpoint_time = self.plant.time
            if self.pvt is not None and self.mode == IP:
                if (record := self.pvt.take()) is not None:
                    self.setpoint_inc, _, record_ms = record
                    self.new_target, record_s = True, record_ms / 1000.0
                    self.last_setpoint_time = self.plant.time
                    if not self.pvt_running:  # the first record: the rest on the drive's own clock
                        self.pvt_running = True
                        self.plant.tick0[self.index] = 0
                else:  # the buffer ran dry while interpolating
                    d[kernel.P0] = d[kernel.P1]
                    self.internal_limit = False
                    self._buffer_error(ERR_UNDERFLOW)
                    return
            # over the drive's interpolation time period (0x60C2); linear interpolation (IP
            # sub-mode 0) has no acceleration within a period
            cyclic.follow_period(
                d,
                self.drive_values,
                self._follow_period_s(record_s),
                *self.software_limits(),
                self.mode == IP and self.objects.get_or(INTERPOLATION_SUB_MODE, 0, 0) == 0,
            )
            return
        d[kernel.P0] = d.item(kernel.P1)
        self.plant.period_ticks[self.index] = self.plant.ticks_per_period  # its own profile's period
        v_old = self.v_dem
        self.internal_limit = False
        if self.profile.period(T):
            self._go(SWITCH_ON_DISABLED)  # the quick stop came to rest
        d[kernel.A_FF] = (self.v_dem - v_old) / T
        self.new_target = False

    @contextmanager
    def _bumpless(self) -> Iterator[None]:
        """Gains changed inside keep the torque the velocity integrator holds (KpS times its
        integral of KiS·e; a position PID's integrator holds torque already): a held axis does not
        sag or jump when new gains are written."""
        state, param = self.plant_state, self.plant_param
        gain = float(param[kernel.KPS])
        held = gain * float(state[kernel.V_INT])
        yield
        if (
            param[kernel.KPS] != gain
            and param[kernel.KPS] > 0
            and param[kernel.STRUCT] != kernel.POSITION_PID
        ):
            state[kernel.V_INT] = held / param[kernel.KPS]

    def _planned_stop(self, T: float) -> None:
        """A period of the planned stop after the FIFO ran dry: the demand velocity ramped down on
        the quick-stop deceleration 0x6085, then held."""
        d = self.plant_demand
        d[kernel.P0] = d.item(kernel.P1)
        self.plant.period_ticks[self.index] = self.plant.ticks_per_period
        v_old = self.v_dem
        deceleration = self.objects.get_or(
            QUICK_STOP_DECELERATION, 0, factory().quick_stop_rad_s2 * self.vel_per_si
        )
        self.profile.ramp(0.0, deceleration / self.vel_per_si, T)
        d[kernel.A_FF] = (self.v_dem - v_old) / T

    def _plant(self, position: int) -> float:
        """A position in the drive's units as the plant's [rad]: through the origin homing set."""
        return cyclic.plant_position(self.drive_values, position)

    def within_limits(self, position: float) -> float:
        """``position`` [rad, plant] inside the software position limits 0x607D.

        Parameters
        ----------
        position : float
            [rad, plant].

        Returns
        -------
        float
            The position held within the limits.
        """
        return cyclic.soft_limit(self.drive_values, position, *self.software_limits())

    def software_limits(self) -> tuple[int, int]:
        """0x607D: (min, max) [position unit]; no limits where min >= max.

        Returns
        -------
        (int, int)
            [position unit].
        """
        return self.objects.get(SOFTWARE_POSITION_LIMIT, 1), self.objects.get(SOFTWARE_POSITION_LIMIT, 2)

    def check_faults(self) -> None:
        """After the plant advanced: following error, loss of setpoint, and bits 10 and 12 as the
        axis moves (:meth:`.ProfileMotion.update_reached`)."""
        if self.state not in (ENABLED, QUICK_STOP):
            return
        self.profile.update_reached()
        over = self.plant_state.item(kernel.FE_COUNT)  # ticks outside the following error window
        if over > 0 and over >= self.following_error_ticks():
            self.fault(ERR_FOLLOWING)
        elif (
            self.setpoint_armed
            and self.following
            and self.plant.time - self.last_setpoint_time > self.setpoint_timeout()
        ):
            # the master's stream is gone: the drive's connection-abort reaction (a fault where
            # the drive has no 0x6007, or it is left at CiA 402's default)
            self._connection_lost(
                ERR_RPDO_TIMEOUT, self.objects.get_or(ABORT_CONNECTION_OPTION, 0, ABORT_FAULT)
            )

    def following_error_ticks(self) -> int:
        """Loop ticks outside the following error window that fault the drive (0x6066).

        Returns
        -------
        int
            At least one.
        """
        return max(
            1,
            round(
                self.objects.get_or(FOLLOWING_ERROR_TIMEOUT, 0, factory().fe_timeout_ms)
                / 1000.0
                / kernel.VELOCITY_TICK_S
            ),
        )

    def setpoint_timeout(self) -> float:
        """How long [s] the drive follows without a new setpoint before the stream counts as lost.

        Returns
        -------
        float
            [s].
        """
        return SETPOINT_TIMEOUT_PERIODS * self._interpolation_period() + 1e-9

    def _interpolation_period_written(self, sub: int, value: int) -> None:
        """0x60C2 written: the loops lock to value × 10^index as to a SYNC period (0x1006), the
        period a master that writes no 0x1006 still says; refused with an SDO abort where it is
        no whole number of loop ticks, or would change the loops' period while the drive is enabled."""
        mantissa = value if sub == 1 else self.objects.get(INTERPOLATION_TIME_PERIOD, 1)
        exponent = value if sub == 2 else self.objects.get(INTERPOLATION_TIME_PERIOD, 2)
        period = mantissa * 10.0**exponent
        ticks = whole_ticks(period)
        if not ticks:
            raise SdoAbortedError(ABORT_RANGE)
        if ticks == self.plant.ticks_per_period:
            return
        if self.state == ENABLED:
            raise SdoAbortedError(ABORT_STATE)
        self.host.cycle_period_written(round(period * 1e6))

    def _interpolation_period(self) -> float:
        """0x60C2 [s]: value × 10^index (the SYNC period where the drive has no such object)."""
        if self.od.get_variable(INTERPOLATION_TIME_PERIOD, 1) is None:
            return self.plant.sync_period
        return self.objects.get(INTERPOLATION_TIME_PERIOD, 1) * 10.0 ** self.objects.get(
            INTERPOLATION_TIME_PERIOD, 2
        )

    def interpolation_ticks(self) -> int:
        """The interpolation time period 0x60C2 in whole loop ticks (at least one).

        Returns
        -------
        int
            Loop ticks.
        """
        return max(1, round(self._interpolation_period() / kernel.VELOCITY_TICK_S))

    def _follow_period_s(self, record_s: float | None = None) -> float:
        """The interpolation period [s] that starts now, the plant told how many ticks: a PVT
        record's own time (``record_s``), else the drive's 0x60C2, whatever the SYNC period."""
        ticks = max(1, round(record_s / kernel.VELOCITY_TICK_S)) if record_s else self.interpolation_ticks()
        self.plant.period_ticks[self.index] = ticks
        return (
            self.plant.sync_period if ticks == self.plant.ticks_per_period else ticks * kernel.VELOCITY_TICK_S
        )

    def next_due(self) -> float:
        """The earliest time [s] its heartbeat or a watched node's silence needs it (inf: never).

        Returns
        -------
        float
            [s].
        """
        return min(self.nmt.next_due(), self.heartbeats.next_due())

    # ------------------------------------------------------------------ actual values
    def refresh_actuals(self, sync: bool = False) -> None:
        """Sample the measured values the drive reports (at a SYNC: ``sync``, the velocity its mean
        over the period).

        Parameters
        ----------
        sync : bool
            At a SYNC (the velocity its mean over the period).
        """
        self._refresh_actuals(noise=True, sync=sync)

    def _refresh_actuals(self, noise: bool, sync: bool = False) -> None:
        sample = self.plant.noise() if noise and self.drive_values.item(cyclic.X_NOISE) else 0.0
        self._sampled_at = self.plant.time
        cyclic.actual_values(
            self.plant_state, self.plant_param, self.drive_values, self.plant.time, sample, sync
        )
        if self.pvt is not None:  # 0x20C4:1 as of this sample (its other sub-indices are settings)
            self.objects.set(0x20C4, 1, self._buffer_status())

    def _live_objects(self) -> dict[int, Callable[[], int]]:
        """Objects whose value the drive measures or computes instead of storing."""
        current = {index: (lambda: self._current) for index in self.spec.current_objects}
        return current | {
            STATUSWORD: lambda: self.statusword,
            MODES_OF_OPERATION_DISPLAY: lambda: self.mode,
            POSITION_ACTUAL: lambda: self._position_inc,
            VELOCITY_ACTUAL: lambda: self._velocity,
            TORQUE_ACTUAL: lambda: self._torque_pm,
            FOLLOWING_ERROR_ACTUAL: lambda: round(self.plant_state[kernel.FERR] * self.pos_per_rad),
            ERROR_CODE: lambda: self.emcy.error_code,
            ERROR_REGISTER: lambda: 0x01 if self.state == FAULT else 0x00,
        }

    def _fill_changed(self) -> None:
        """0x60C4:2 follows the FIFO's fill."""
        if self.fifo is not None:
            self.objects.set(INTERPOLATION_DATA_CONFIGURATION, BUFFER_FILL, self.fifo.fill)

    def _buffer_error(self, code: int) -> None:
        """An underflow or overflow of the PVT buffer (latched in its status): 0x20C4:1 at once, and
        the trajectory aborted (a fault with EMCY ``code``)."""
        self.objects.set(0x20C4, 1, self._buffer_status())
        self.fault(code)

    def _buffer_status(self) -> int:
        """0x20C4:1, maxon's interpolation buffer status (sub-indices 2 and 3 the warning levels)."""
        if self.pvt is None:
            return 0
        return self.pvt.status(
            self.following, self.objects.get_or(0x20C4, 2, 4), self.objects.get_or(0x20C4, 3, 60)
        )

    def _send(self, cob_id: int, data: bytes) -> None:
        if self.online:
            self.host.send(cob_id, data)
