"""Supervision of a streamed plan: the limits the cyclic engine judges the drives by (taken from
what bring-up wrote to them: the SYNC period, the heartbeat consumer time, the drive profile's
setpoint-loss timeout), a run's own velocity guard, heartbeats, and why the engine stopped, in
words (an EMCY, a drive's interpolation buffer, a late master)."""

from __future__ import annotations

from dataclasses import dataclass

import canopen

from ..cia.p301 import MASTER_LOSS, emcy_text
from ..cia.setpoint import PVT_BUFFER_STATUS
from ..errors import GuardStop, Interrupted, MotionAborted, RanDry
from .bringup import AxisLink
from .engine import (
    Outcome,
    Supervision,
)

#: the drive profile's setpoint-loss timeout is unknown: a drive is taken to stop on the master's
#: heartbeat alone, within the consumer time bring-up wrote (0x1016:1)
NO_TIMEOUT = None


@dataclass(frozen=True)
class VelocityGuard:
    """A run's own limit on each axis's measured velocity [rad/s]: beyond it the run stops.

    Parameters
    ----------
    limits : dict of str to float
        Per axis, its limit [rad/s].
    """

    limits: dict[str, float]

    def reason(self, axis: str, velocity: float) -> str:
        """Why the guard stopped the run, in words.

        Parameters
        ----------
        axis : str
            The axis.
        velocity : float
            Its measured velocity [rad/s].

        Returns
        -------
        str
            The words.
        """
        return f"axis {axis}: velocity {velocity:.3g} rad/s beyond the guard {self.limits[axis]:.3g} rad/s: stopped"


def supervision_for(
    axes: dict[str, AxisLink],
    period: float,
    *,
    heartbeat_timeout: float,
    state_timeout: float,
    setpoint_timeout: float | None = NO_TIMEOUT,
    miss_limit: int | None = None,
    setpoint_source: str = "",
) -> Supervision:
    """The time limits a stream is judged by, from what bring-up wrote into the drives and read back:
    the SYNC period (0x1006), the synchronous window (0x1007, else the period), the master's
    heartbeat consumer time (0x1016:1); and the drives' own setpoint-loss timeout where their
    profile names one (``setpoint_timeout`` [s]).  A drive's feedback may be missing as long as a
    drive waits for the master's setpoints before it stops on its own: the setpoint-loss timeout,
    else the heartbeat consumer time.  ``miss_limit`` (bus.yml ``master.tpdo_miss_limit``) sets it
    to that many periods instead.

    Parameters
    ----------
    axes : dict of str to AxisLink
        The brought-up axes (what was read back).
    period : float
        The SYNC period [s].
    heartbeat_timeout : float
        The master's heartbeat consumer time [s].
    state_timeout : float
        How long a state change is waited for [s].
    setpoint_timeout : float, optional
        The drives' setpoint-loss timeout [s], where their profile names one.
    miss_limit : int, optional
        Periods of missing feedback before a stop.
    setpoint_source : str
        Where the setpoint timeout comes from.

    Returns
    -------
    Supervision
        The limits and their sources.
    """
    sources = {"period": "master.sync_period (0x1006 written)"}
    windows = [ax.drive_limits.get("0x1007:0") for ax in axes.values()]
    window = min((w for w in windows if w), default=None)
    if window:
        sources["window"] = "0x1007, as the drives hold it"
    else:
        sources["window"] = "the SYNC period (no synchronous window 0x1007 written)"
    consumers = [ax.drive_limits.get("0x1016:1") for ax in axes.values()]
    consumer_ms = min((c & 0xFFFF for c in consumers if c), default=None)
    drive_stops = setpoint_timeout
    if drive_stops is None:
        drive_stops = (consumer_ms / 1000.0) if consumer_ms else heartbeat_timeout
        sources["setpoint_timeout"] = (
            (
                "the master's heartbeat consumer time the drives hold (0x1016:1): their "
                "profile names no setpoint-loss timeout"
            )
            if consumer_ms
            else "master.heartbeat_consumer_ms (no consumer time written, no setpoint-loss timeout in the profile)"
        )
    else:
        sources["setpoint_timeout"] = setpoint_source or "the drive profile's setpoint-loss timeout"
    if miss_limit is not None:
        feedback = miss_limit * period
        sources["feedback_timeout"] = f"master.tpdo_miss_limit: {miss_limit} periods"
    else:
        feedback = drive_stops
        sources["feedback_timeout"] = "as long as the drives wait for setpoints (setpoint timeout)"
    sources["heartbeat_timeout"] = "master.heartbeat_consumer_ms"
    return Supervision(
        period,
        (window / 1e6) if window else period,
        feedback,
        drive_stops,
        heartbeat_timeout,
        state_timeout,
        max(state_timeout, 2.0),
        sources,
    )


def stop_reason(
    outcome: Outcome, axes: dict[str, AxisLink], supervision: Supervision, guard: VelocityGuard | None
) -> MotionAborted | None:
    """Why the engine stopped, in words (None: it did not).

    Parameters
    ----------
    outcome : Outcome
        How the run ended.
    axes : dict of str to AxisLink
        The axes.
    supervision : Supervision
        The limits it was judged by.
    guard : VelocityGuard or None
        The run's velocity guard.

    Returns
    -------
    MotionAborted or None
        The error the run ends with.
    """
    if outcome.abort is None:
        return None
    reason = _stop_reason(outcome, axes, supervision, guard)
    axis = outcome.abort[1]
    if (
        isinstance(reason, MotionAborted)
        and axis in axes
        and axes[axis].sync_producer
        and outcome.abort[0] in KEEPER_LOST
    ):
        return MotionAborted(
            f"{reason.reason}; it kept time for the bus (the SYNC producer): the SYNCs stopped with it, "
            "and the other drives took no new set-point after them",
            axis,
            reason.emcy,
        )
    return reason


#: the engine's stop kinds that say a drive is gone (a drive in fault still sends its SYNCs)
KEEPER_LOST = ("heartbeat", "silent")


def _stop_reason(
    outcome: Outcome, axes: dict[str, AxisLink], supervision: Supervision, guard: VelocityGuard | None
) -> MotionAborted | None:
    """:func:`stop_reason` before the time keeper is named."""
    assert outcome.abort is not None
    kind, axis, detail, code = outcome.abort
    if kind == "interrupt":
        return Interrupted(signal=detail or "Ctrl-C")
    if kind == "emcy" and axis is not None and code is not None:
        gap = outcome.largest_sync_gap_ms
        if code in MASTER_LOSS and gap >= supervision.setpoint_timeout_s * 1e3:
            return MotionAborted(
                f"the master was late: its SYNCs stopped for {gap:.0f} ms, longer than the drives wait for "
                f"setpoints ({supervision.setpoint_timeout_s * 1e3:.0f} ms); the drive stopped on its own "
                f"({emcy_text(code)}, EMCY 0x{code:04X})",
                axis,
                code,
            )
        buffer = (
            _buffer_cause(axes[axis])
            if any(i == PVT_BUFFER_STATUS[0] for c in axes[axis].tpdos for i in c.objects)
            else None
        )
        return buffer or MotionAborted(f"drive sent {emcy_text(code)} (EMCY 0x{code:04X})", axis, code)
    if kind == "silent":
        return MotionAborted(f"no TPDO: {detail}", axis)
    if kind == "dry" and axis is not None:
        cover = axes[axis].streaming.depth * supervision.period_s
        return RanDry(
            f"its interpolation FIFO ran dry (at row {detail}): this host was away longer than the "
            f"{cover * 1e3:.0f} ms of records kept ahead (master.stall_cover_ms); the drive made a planned "
            f"stop and holds, no fault",
            axis,
            int(detail),
        )
    if kind == "guard" and axis is not None and guard is not None:
        return GuardStop(guard.reason(axis, float(axes[axis].cfg.scaling.velocity_from_device(int(detail)))))
    if kind == "buffer" and axis is not None:
        return _buffer_status_error(axis, int(detail, 16)) or MotionAborted(detail, axis)
    if kind == "heartbeat":
        return MotionAborted(f"heartbeat lost (none for {detail} s)", axis)
    if kind == "bus":
        return MotionAborted(
            f"the CAN interface reported {detail} error frame(s) (bus errors, error passive or "
            f"bus-off: check wiring, termination and bitrate)"
        )
    return MotionAborted(detail, axis)


#: maxon's interpolation buffer status 0x20C4:1: error bits (each aborts the drive's trajectory)
#: (EPOS Application Note "Interpolation Position Mode", Dec 2008, p. 13)
BUFFER_ERRORS = {
    0x0100: "its interpolation buffer ran empty (underflow: a record came late or not at all)",
    0x0200: "its interpolation buffer overflowed (more records than it takes)",
    0x0400: "an interpolated velocity above its maximal profile velocity 0x607F",
    0x0800: "an interpolated acceleration above its maximal profile acceleration 0x60C5",
}


def _buffer_status_error(axis: str, status: int) -> MotionAborted | None:
    for bit, what in BUFFER_ERRORS.items():
        if status & bit:
            return MotionAborted(f"the drive reports {what} (0x20C4:1 = 0x{status:04X})", axis)
    return None


def _buffer_cause(ax: AxisLink) -> MotionAborted | None:
    """After an EMCY, the interpolation buffer status read by SDO: an error there is the cause."""
    try:
        return _buffer_status_error(ax.name, ax.node.sdo[PVT_BUFFER_STATUS[0]][PVT_BUFFER_STATUS[1]].raw)
    except (canopen.SdoCommunicationError, canopen.SdoAbortedError):
        return None


def check_heartbeats(
    axes: dict[str, AxisLink], names: list[str], now: float, timeout: float
) -> MotionAborted | None:
    """The first of ``names`` whose drive's heartbeat has been silent longer than ``timeout`` [s].

    Parameters
    ----------
    axes : dict of str to AxisLink
        The axes (their last heartbeat).
    names : list of str
        The axes to check.
    now : float
        Now [s, the link's clock].
    timeout : float
        [s].

    Returns
    -------
    MotionAborted or None
        The stop, naming that axis.
    """
    for name in names:
        last = axes[name].last_heartbeat
        if last is not None and now - last > timeout:
            return MotionAborted(f"heartbeat lost (none for {now - last:.3f} s)", name)
    return None
