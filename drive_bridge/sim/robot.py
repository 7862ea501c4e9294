"""The simulated robot: its drives on one python-can bus, one clock for all.

Two clocks drive the same code:

* lockstep (:meth:`SimRobot.process`): each SYNC advances every drive by
  exactly one SYNC period before the drives answer it; nothing depends on the
  wall clock, so one configuration and seed give byte-identical feedback;
* wall clock (:meth:`SimRobot.start_realtime`): a thread advances the plant
  with real time and answers frames as they come, so a master that does not
  know it talks to a simulation sees drives that move on their own.
"""

from __future__ import annotations

import math
import os
import threading
import time
from collections.abc import Callable, Mapping
from pathlib import Path

import can

from ..cia.objects import CYCLE_PERIOD, SYNC_COUNTER_OVERFLOW
from ..cia.p301 import ERR_SYNC_LENGTH, NMT_STOPPED, SYNC_COB_ID
from ..cia.pdo import PdoCodec
from ..resources import PROJECT_EDS
from . import cyclic, kernel
from .adapters import FastVirtualBus
from .drive import SimDrive
from .plant import Plant, whole_ticks
from .robot_config import SimConfig
from .steady import SteadyStream

REPLY_DELAY_S = 50e-6  # wall clock: a drive's reply follows the frame it answers
IDLE_WAKE_S = 0.002  # wall clock: the drives' thread wakes on this grid between frames
#: wall clock: how much of a SYNC's phase error against the drives' loop grid one SYNC corrects
SYNC_LOCK_GAIN = 0.1
#: ... for errors within this fraction of a period (a late master's SYNC does not move the grid)
SYNC_LOCK_RANGE = 0.25
#: wall clock: how much of that error goes into the grid's period (the loop's integral part: a SYNC
#: producer whose period is not the drives' -- the kernel's broadcast manager re-arms its timer
#: after each SYNC, late by its wake-up every period -- is tracked, one grid period per SYNC)
SYNC_TRACK_GAIN = 0.01
#: ... up to this fraction of a period longer or shorter (the loop's pull-in range)
SYNC_TRACK_RANGE = 0.05
#: wall clock: after this long without SYNC [s] the next one sets the loop grid's phase at once
SYNC_RELOCK_S = 0.1


class SimRobot:
    """All simulated drives of one robot, answering on ``channel`` of the virtual bus.

    ``sync_period`` [s] is the SYNC period the drives interpolate over (0x60C2
    is written by the master; the kernel needs the tick count up front).  ``eds`` is the EDS/DCF
    every drive is built from, or one per axis name (the project's drive where an axis has none).

    Parameters
    ----------
    config : SimConfig
        The simulated robot.
    channel : str
        The virtual bus's channel.
    bus : can.BusABC, optional
        The bus to answer on (default: a virtual bus of its own on ``channel``).
    sync_period : float
        [s].
    eds : str, Path or mapping of str to str or Path
        The EDS/DCF of every drive, or one per axis.
    """

    def __init__(
        self,
        config: SimConfig,
        channel: str = "drive-bridge",
        *,
        bus: can.BusABC | None = None,
        sync_period: float = 0.002,
        eds: str | Path | Mapping[str, str | Path] = PROJECT_EDS,
    ):
        self.config = config
        self.plant = Plant(len(config.axes), sync_period, config.seed)
        self.bus = bus if bus is not None else FastVirtualBus(channel=channel, preserve_timestamps=True)
        # wall clock: the time of simulation time 0 [s]; the drives' grid (ticks into the period,
        # boundaries passed), the boundary of the last SYNC, when it came, the RPDOs armed by it
        self._t0 = 0.0
        self._bus_time = 0.0  # wall clock: the latest frame's stamp [s]
        self._phase = 0
        self._boundary = 0
        self._sync_tag = -2
        self._last_sync = -math.inf
        self._drift = 0.0  # [s] how much longer the SYNC producer's period is than the grid's own
        self._armed: list[list[tuple[PdoCodec, bytes]]] = [[] for _ in config.axes]
        self._stamp = lambda: self.plant.time  # lockstep: frames carry simulation time
        # compile (or load from numba's cache) now, not while a clock is running
        self.plant.advance(0)
        cyclic.compile_all()
        self._routes: dict[int, Callable[[bytes], None]] = {}
        #: called with the time after each advance (a lockstep master's heartbeat, in simulation time)
        self.timers: list[Callable[[float], None]] = []
        self.drives: dict[str, SimDrive] = {}  # filled before the first routes_changed() counts
        names = list(config.axes)
        for i, (name, axis) in enumerate(config.axes.items()):
            self.plant.state[i, kernel.Q] = axis.initial_position_rad
            path = eds.get(name, PROJECT_EDS) if isinstance(eds, Mapping) else eds
            self.drives[name] = SimDrive(self, i, axis, str(path), self.plant, names)
        #: lockstep: the drives' streaming SYNC compiled (None until laid out anew)
        self._steady: SteadyStream | None = None
        self.routes_changed()
        self._thread: threading.Thread | None = None
        self._running = False
        self._wall = False  # on the wall clock (clock_from called): a drive may produce SYNC
        self._producer: SimDrive | None = None  # the drive whose 0x1005 bit 30 is set
        self._counter = 0  # the last SYNC counter it sent

    @property
    def time(self) -> float:
        """The simulation time [s] (the plant's clock)."""
        return self.plant.time

    @property
    def sync_period(self) -> float:
        """The SYNC period the drives interpolate over [s]."""
        return self.plant.sync_period

    def cycle_period_written(self, period_us: int) -> None:
        """0x1006 or 0x60C2 written on a drive: the drives' loops lock to that SYNC period, as a drive's
        phase-locked loop does (one grid: the SYNC is the bus's), from the next SYNC on; 0 (no
        SYNC expected) and a period that is not a whole number of loop ticks leave it as it is.

        Parameters
        ----------
        period_us : int
            [µs].
        """
        ticks = whole_ticks(period_us / 1e6)
        if ticks is not None and ticks != self.plant.ticks_per_period:
            self.plant.set_sync_period(period_us / 1e6)
            self._phase = 0
            self._last_sync = -math.inf  # the next SYNC sets the grid's phase
            if self._steady is not None:
                self._steady.stale = True

    def sync_producer_written(self, drive: SimDrive, producing: bool) -> None:
        """:meth:`DriveHost.sync_producer_written`: on the wall clock, while its cycle period 0x1006
        is set, ``drive`` sends SYNC at each period boundary of the drives' grid (:meth:`_produce_sync`),
        with the counter 1..0x1019 where 0x1019 is 2 or more, starting at 1 (CiA 301); a stall of the
        drives' own process skips none: the boundaries it passes meanwhile each send theirs, in order.

        Parameters
        ----------
        drive : SimDrive
            The drive written.
        producing : bool
            Bit 30.
        """
        if producing:
            self._producer, self._counter = drive, 0
        elif self._producer is drive:
            self._producer = None

    def _producing(self) -> SimDrive | None:
        """The drive that sends SYNC now (on the wall clock, online, its cycle period set, not
        stopped), or None."""
        drive = self._producer
        if (
            drive is None
            or not self._wall
            or not drive.online
            or drive.nmt.state == NMT_STOPPED
            or not drive.objects.get_or(CYCLE_PERIOD, 0, 0)
        ):
            return None
        return drive

    def _produce_sync(self, drive: SimDrive) -> None:
        """The producer's SYNC at the boundary reached now: sent with its counter, and taken by every
        drive as a SYNC received on that boundary's tick (which starts the next period)."""
        overflow = drive.objects.get_or(SYNC_COUNTER_OVERFLOW, 0, 0)
        data = b""
        if overflow >= 2:
            self._counter = self._counter % overflow + 1
            data = bytes([self._counter])
        stamp = self._t0 + self.plant.time
        self._bus_time = max(self._bus_time, stamp)
        self.send(SYNC_COB_ID, data)
        self._sync_received(stamp)

    # ------------------------------------------------------------------ bus
    def power_on(self) -> None:
        """Every drive sends its boot-up message."""
        for drive in self.drives.values():
            drive.boot()

    def send(self, cob_id: int, data: bytes) -> None:
        """Put a drive's frame on the bus, stamped with the robot's clock.

        Parameters
        ----------
        cob_id : int
            Its COB-ID.
        data : bytes
            Its data.
        """
        self.bus.send(
            can.Message(arbitration_id=cob_id, data=data, is_extended_id=False, timestamp=self._stamp())
        )

    def routes_changed(self) -> None:
        """Rebuild the COB-ID -> handler table (after a PDO mapping change)."""
        routes: dict[int, Callable[[bytes], None]] = {0x000: self._on_nmt, SYNC_COB_ID: self._on_sync}
        watchers: dict[int, list[SimDrive]] = {}
        for drive in self.drives.values():
            routes[0x600 + drive.node_id] = self._sdo_handler(drive)
            for cob_id in drive.rpdos:
                routes[cob_id] = self._rpdo_handler(drive, cob_id)
            for node in drive.heartbeats.watched:
                watchers.setdefault(node, []).append(drive)
        for node, drives in watchers.items():
            routes[0x700 + node] = self._heartbeat_handler(node, drives)
        self._routes = routes
        #: the frames that leave the drives' streaming layout as it is: SYNC and synchronous RPDOs,
        #: and the heartbeats the drives watch (those move when a drive next has its own business)
        self._streamed = {SYNC_COB_ID} | {
            cob_id
            for drive in self.drives.values()
            for cob_id, (_, ttype) in drive.rpdos.items()
            if ttype <= 240
        }
        self._watched = {0x700 + node for node in watchers}
        self._steady = None

    @staticmethod
    def _sdo_handler(drive: SimDrive) -> Callable[[bytes], None]:
        def handle(data: bytes) -> None:
            # CiA 301: no SDO in Stopped; an SDO request is 8 bytes (a shorter frame is not one)
            if drive.online and drive.nmt.state != NMT_STOPPED and len(data) == 8:
                drive.node.sdo.on_request(0x600 + drive.node_id, data, 0.0)

        return handle

    @staticmethod
    def _rpdo_handler(drive: SimDrive, cob_id: int) -> Callable[[bytes], None]:
        def handle(data: bytes) -> None:
            if drive.online:
                try:
                    drive.on_rpdo(cob_id, data)
                except Exception:  # no value from the bus ends a drive's service
                    drive.internal_error()

        return handle

    @staticmethod
    def _heartbeat_handler(node: int, drives: list[SimDrive]) -> Callable[[bytes], None]:
        def handle(data: bytes) -> None:
            for drive in drives:
                if drive.online:
                    drive.on_heartbeat(node)

        return handle

    def dispatch(self, msg: can.Message) -> None:
        """Hand a frame to the drive (or drives) it is for; a frame outside the steady stream ends
        the compiled SYNC path's run.

        Parameters
        ----------
        msg : can.Message
            The frame.
        """
        handler = self._routes.get(msg.arbitration_id)
        if handler is not None and not msg.is_remote_frame:
            if msg.arbitration_id in self._watched:
                if self._steady is not None:
                    self._steady.stale = True
            elif msg.arbitration_id not in self._streamed:
                self._steady = None
            handler(bytes(msg.data))

    def _on_nmt(self, data: bytes) -> None:
        for drive in self.drives.values():
            if drive.online:
                try:
                    drive.on_nmt(data)
                except Exception:  # no value from the bus ends a drive's service
                    drive.internal_error()

    def _sync_length(self, data: bytes) -> None:
        """CiA 301: a SYNC consumer expects the counter byte where its 0x1019 is 2 or more, none
        otherwise; a SYNC of another length is answered with EMCY 0x8240 (and taken all the same)."""
        for drive in self.drives.values():
            if drive.online and drive.nmt.state != NMT_STOPPED:
                expected = 1 if drive.objects.get_or(SYNC_COUNTER_OVERFLOW, 0, 0) >= 2 else 0
                if len(data) != expected:
                    drive.emcy.send(ERR_SYNC_LENGTH)

    def _on_sync(self, data: bytes) -> None:
        # lockstep: the SYNC period passes now (on the wall clock SYNC is :meth:`_sync_received`'s);
        # a drive making its own profile off the SYNC's grid starts its periods on their own ticks
        self._sync_length(data)
        self._run_plant(self._through_profile_periods(self.plant.ticks_per_period))
        if self._steady is None and all(drive.streaming for drive in self.drives.values()):
            self._steady = SteadyStream(self.plant, list(self.drives.values()), self.send)
        if self._steady is not None and self._steady.period():
            self.plant.tick0[:] = 0  # every drive starts an interpolation period
            return
        self._supervise(boundary=True)
        for drive in self.drives.values():
            drive.on_sync()
            if not drive.internal_profile:  # a new interpolation period starts at SYNC
                self.plant.tick0[drive.index] = 0

    # ------------------------------------------------------------------ lockstep
    def process(self) -> None:
        """Handle every frame waiting on the bus, in order."""
        if isinstance(self.bus, FastVirtualBus):
            for msg in self.bus.drain():
                self.dispatch(msg)
        else:
            while (frame := self.bus.recv(0)) is not None:
                self.dispatch(frame)

    def idle(self, duration: float) -> None:
        """Lockstep: let ``duration`` seconds pass without SYNC (drives hold, heartbeats go out).

        Parameters
        ----------
        duration : float
            [s].
        """
        ticks = max(1, round(duration / kernel.VELOCITY_TICK_S))
        while ticks > 0:  # in SYNC-period steps so heartbeats go out on time
            step = min(ticks, self.plant.ticks_per_period)
            self.advance(step)
            ticks -= step

    # ------------------------------------------------------------------ plant
    def advance(self, n_ticks: int, boundary: bool = False) -> None:
        """Run loops and plant for ``n_ticks`` velocity-loop ticks, then faults and heartbeats; a drive
        that makes its own profile (quick stop, PV, PP, homing) starts its next period on the tick its
        period ends, however the ticks are asked for (its demand never waits a tick for it).

        Parameters
        ----------
        n_ticks : int
            Velocity-loop ticks.
        boundary : bool
            The ticks end on a period boundary of the SYNC grid (a PVT record due there is taken
            when the period starts, after the RPDOs that came for it).
        """
        self._run_plant(self._through_profile_periods(n_ticks))
        self._supervise(boundary)

    def _through_profile_periods(self, n_ticks: int) -> int:
        """Loops and plant through every end of a period of a drive making its own profile that falls
        before the end of the next ``n_ticks`` ticks, each followed by what the drives do then (its
        next period among it); the ticks left."""
        period_ticks, tick0 = self.plant.period_ticks, self.plant.tick0
        while n_ticks > 0:
            if n_ticks <= min(self.plant.ticks_per_period, int(period_ticks.min())) and not tick0.any():
                return n_ticks  # (every period starts now: none ends sooner)
            ends = [
                int(period_ticks[drive.index]) - int(tick0[drive.index])
                for drive in self.drives.values()
                if drive.internal_profile
            ]
            step = max(1, min(ends)) if ends else n_ticks
            if step >= n_ticks:
                return n_ticks
            self._run_plant(step)
            self._supervise()
            n_ticks -= step
        return n_ticks

    def _run_plant(self, n_ticks: int) -> None:
        """Loops and plant for ``n_ticks`` velocity-loop ticks, and the timers at the time reached."""
        self.plant.advance(n_ticks)
        for timer in self.timers:
            timer(self.plant.time)

    def _supervise(self, boundary: bool = False) -> None:
        """What the drives do between SYNCs: their own profiles' periods, watching the nodes they
        consume heartbeats of, their faults and their heartbeats.  On a ``boundary`` of the SYNC
        grid a PVT record due is left to the period's start (:meth:`.SimDrive.start_period`)."""
        if self._steady is not None:
            self._steady.stale = True
        for drive in self.drives.values():
            if (
                drive.internal_profile
                and self.plant.tick0[drive.index] >= self.plant.period_ticks[drive.index]
                and not (boundary and drive.pvt_clock)
            ):
                drive.next_period()
                self.plant.tick0[drive.index] = 0
            if drive.online:
                drive.supervise(self.plant.time)
            drive.check_faults()
            if drive.online:
                drive.heartbeat_due(self.plant.time)

    # ------------------------------------------------------------------ wall clock
    def start_realtime(self) -> None:
        """Run the drives against the wall clock in a background thread
        (in a process of its own: :mod:`drive_bridge.sim.process`)."""
        self._bus_time = time.time()  # frames leave REPLY_DELAY_S after what they answer
        self._stamp = lambda: self._bus_time + REPLY_DELAY_S
        self._running = True
        self._thread = threading.Thread(target=self._run_realtime, name="sim-drives", daemon=True)
        self._thread.start()

    def _run_realtime(self) -> None:
        try:  # the drives are hardware's stand-in: first in line for the CPU
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(60))
        except (AttributeError, OSError):
            pass  # not allowed here: they run at normal priority
        self.clock_from(time.time())
        wake = time.monotonic()
        while self._running:
            wake = self.serve(wake, time.time, time.monotonic)

    def serve(self, wake: float, wall: Callable[[], float], monotonic: Callable[[], float]) -> float:
        """Wall clock: one turn of the drives' loop -- wait for a frame until ``wake`` (on the
        ``monotonic`` clock), take every frame there is, run the plant up to now (on the ``wall``
        clock, the frames' stamps'); the next wake.

        Each frame is applied at the time it reached this process's socket (the kernel's stamp): the
        plant first runs up to it.  The time the drives then catch up to is read *before* the socket
        is drained -- also when the wait ended without a frame -- so a frame that waited in it while
        this process was held up (a stall of the simulator, not of the master) is applied at its own
        time and never found missing.  Between frames the plant catches up on an absolute grid of
        ``IDLE_WAKE_S`` (heartbeats, profiles, time-outs); a late wake-up takes the next point of the
        grid, never a burst.

        Parameters
        ----------
        wake : float
            The latest time to wait until [s, ``monotonic``'s].
        wall : callable
            The wall clock (the frames' stamps').
        monotonic : callable
            The monotonic clock.

        Returns
        -------
        float
            The next wake [s, ``monotonic``'s].
        """
        msg = self.bus.recv(timeout=max(0.0, wake - monotonic()))
        now = wall()
        if msg is None:  # the wait ended without one: any that came while this thread was held up since
            msg = self.bus.recv(0)
        while msg is not None:
            self.take(msg)
            msg = self.bus.recv(0)
        self.run_until(now)
        late = monotonic() - wake
        if late >= 0:
            wake += IDLE_WAKE_S * (1 + int(late // IDLE_WAKE_S))
        return wake

    def wall_time(self, t: float) -> float:
        """Wall clock: the time [s, ``time.time()``'s] simulation time ``t`` stands for.

        Parameters
        ----------
        t : float
            [s, simulation time].

        Returns
        -------
        float
            [s].
        """
        return self._t0 + t

    def clock_from(self, now: float) -> None:
        """Wall clock: the simulation time reached is the wall-clock time ``now`` [s].

        Parameters
        ----------
        now : float
            [s].
        """
        self._t0 = now - self.plant.time
        self._wall = True

    def take(self, msg: can.Message) -> None:
        """Wall clock: a frame received at ``msg.timestamp`` [s]; the loops run up to it first.

        Parameters
        ----------
        msg : can.Message
            The frame.
        """
        if msg.arbitration_id == SYNC_COB_ID and not msg.is_remote_frame:
            self._bus_time = max(self._bus_time, msg.timestamp)
            if self._producing() is None:  # (while a drive produces SYNC, another's is not taken)
                self._sync_length(bytes(msg.data))
                self._sync_received(msg.timestamp)
        else:  # (the loops first: what they send up to it is stamped with its own time)
            self.run_until(msg.timestamp)
            self._bus_time = max(self._bus_time, msg.timestamp)
            self.dispatch(msg)

    def run_until(self, now: float) -> None:
        """Wall clock: the loops and plant run up to ``now`` [s] (whole ticks).

        Parameters
        ----------
        now : float
            [s].
        """
        self._run_ticks(int((now - self._t0 - self.plant.time) / kernel.VELOCITY_TICK_S))

    # The drives' loops run on a grid of their own, locked to the SYNCs they receive as a drive's
    # phase-locked loop is: a SYNC period starts on the grid's period boundary, with the RPDOs that
    # came after the SYNC before it; the SYNC itself takes the actual values when it arrives.  A late
    # SYNC, or one the master skipped, does not shorten or stretch the drives' periods: the setpoints
    # of a period whose SYNC has not come yet take effect on time.

    def _run_ticks(self, n_ticks: int) -> None:
        """Loops and plant for ``n_ticks`` velocity-loop ticks, each period boundary in its place."""
        while n_ticks > 0:
            step = min(n_ticks, self.plant.ticks_per_period - self._phase)
            self.advance(step, boundary=self._phase + step == self.plant.ticks_per_period)
            n_ticks -= step
            self._phase += step
            if self._phase == self.plant.ticks_per_period:
                producer = self._producing()
                if producer is not None:
                    self._produce_sync(producer)  # (its period starts there)
                else:
                    self._next_boundary()
        self._bus_time = max(self._bus_time, self._t0 + self.plant.time)

    def _next_boundary(self) -> None:
        """The grid's next period boundary is here: its period starts."""
        self._phase, self._boundary = 0, self._boundary + 1
        self._period_starts()

    def _arm(self) -> None:
        """The RPDOs received since the last SYNC are the next period's."""
        for drive, armed in zip(self.drives.values(), self._armed):
            armed.extend(drive.pdos.pending)
            drive.pdos.pending.clear()

    def _sample(self) -> None:
        for drive in self.drives.values():
            drive.sample_sync()

    def _sync_received(self, stamp: float) -> None:
        """A SYNC received at ``stamp`` [s, wall clock]: its period's RPDOs armed, the actual values
        sampled on the tick it falls on, the grid's phase pulled towards it."""
        relock = stamp - self._last_sync > SYNC_RELOCK_S
        self._last_sync = stamp
        self.run_until(stamp)
        period = self.plant.ticks_per_period * kernel.VELOCITY_TICK_S
        since = (
            stamp - (self._t0 + self.plant.time) + self._phase * kernel.VELOCITY_TICK_S
        )  # since the last boundary
        if relock:  # the first SYNC after a pause sets the grid
            self._t0 = stamp - self.plant.time
        # a master's SYNC is late, never early, but for jitter: the SYNC of the boundary passed last
        # unless that one had its SYNC already
        early = self._sync_tag == self._boundary and not relock
        self._sync_tag = self._boundary + 1 if early or relock else self._boundary
        self._arm()
        if relock:
            self._sample()
            self._next_boundary()
            return
        nearest = round((stamp - self._t0 - self.plant.time) / kernel.VELOCITY_TICK_S)  # the tick it falls on
        to_boundary = self.plant.ticks_per_period - self._phase
        if early and nearest >= to_boundary:
            # on the boundary's tick: sampled before its period starts, as a SYNC is in lockstep
            self.advance(to_boundary, boundary=True)
            self._bus_time = max(self._bus_time, self._t0 + self.plant.time)
            self._sample()
            self._next_boundary()
            self._run_ticks(nearest - to_boundary)
        else:  # (a late SYNC's period began at the boundary passed: not the next)
            self._run_ticks(nearest if early else min(nearest, to_boundary - 1))
            self._sample()
        error = since - period if early else since  # [s] against its own boundary
        if abs(error) < SYNC_LOCK_RANGE * period:
            limit = SYNC_TRACK_RANGE * period
            self._drift = min(limit, max(-limit, self._drift + SYNC_TRACK_GAIN * error))
            self._t0 += SYNC_LOCK_GAIN * error
        self._t0 += self._drift  # the grid's next period as long as the producer's

    def _period_starts(self) -> None:
        """A period boundary of the drives' grid: the period of the SYNC received for it (or of the
        one before, the master's SYNC not here yet) starts with its RPDOs.  None: a drive following
        the master starts a period without a new setpoint (:func:`.cyclic.follow_period`: a substitute
        at the last velocity until its setpoint timeout), the others hold."""
        if self._sync_tag == self._boundary - 1:  # the SYNC late or skipped: its RPDOs are due
            self._arm()
        elif self._sync_tag != self._boundary:
            for drive in self.drives.values():
                if drive.online and drive.following and not drive.internal_profile:
                    drive.next_period()
                    self.plant.tick0[drive.index] = 0
                else:
                    drive.record_due()
            return
        for drive, armed in zip(self.drives.values(), self._armed):
            drive.start_period(armed)
            if not drive.internal_profile:
                self.plant.tick0[drive.index] = 0

    def shutdown(self) -> None:
        """Stop the drives' thread (where it runs) and close the bus."""
        self._running = False
        if self._thread is not None:
            self._thread.join(timeout=2)
        self.bus.shutdown()
