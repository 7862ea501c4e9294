"""An axis enabled without a jump, stopped, and held: the target a CSP drive takes on enable set
to where the axis stands, a quick stop that ends when every axis stands still (SDO only where its
feedback is gone), and how each axis is held once the motion is over (``holding: enabled``: powered
at its position; ``brake``: switched off onto its brake)."""

from __future__ import annotations

import canopen

from ..cia.objects import (
    BUFFER_CLEAR,
    CONTROLWORD,
    INTERPOLATION_DATA_CONFIGURATION,
    POSITION_ACTUAL,
    STATUSWORD,
    TARGET_POSITION,
    VELOCITY_ACTUAL,
)
from ..cia.p402 import (
    CSP,
    CW_HALT,
    CW_QUICK_STOP,
    IP,
    PP,
    state_name,
)
from ..cia.setpoint import PVT
from ..config import HOLD_TOLERANCE_RAD
from ..errors import MotionAborted
from .bringup import AxisLink
from .link import Link

STANDSTILL = 0.002  # quick stop complete below this fraction of the axis's max velocity ...


STANDSTILL_MIN_RAD_S = 0.05  # ... or below this, whichever is larger (encoder differencing noise)


def at_rest(ax: AxisLink, statusword: int, velocity: int) -> bool:
    """Out of OPERATION ENABLED (quick stop active, switched off or faulted) and its measured
    velocity [device units] within ``STANDSTILL`` of its limit (or ``STANDSTILL_MIN_RAD_S``).

    Parameters
    ----------
    ax : AxisLink
        The axis.
    statusword : int
        Its statusword.
    velocity : int
        Its velocity actual [device units].

    Returns
    -------
    bool
        Whether it is at rest.
    """
    speed = abs(float(ax.cfg.scaling.velocity_from_device(velocity)))
    return state_name(statusword) != "OPERATION ENABLED" and speed <= max(
        STANDSTILL * ax.cfg.limits.max_velocity, STANDSTILL_MIN_RAD_S
    )


def on_brake(ax: AxisLink) -> bool:
    """Whether the axis is held by its brake (``holding: brake``) rather than powered.

    Parameters
    ----------
    ax : AxisLink
        The axis.

    Returns
    -------
    bool
        Held by its brake.
    """
    return ax.cfg.drive_limits is not None and ax.cfg.drive_limits.holding == "brake"


def quick_stop(link: Link, axes: dict[str, AxisLink], timeout: float) -> list[str]:
    """Quick stop every axis by SDO, then wait until each stands still (the fallback where an axis's
    cyclic feedback is gone, and for a master that no longer streams).

    An axis stands still when a fresh read shows it out of OPERATION ENABLED (quick stop active,
    switched off or faulted) and its measured velocity (0x606C) within ``STANDSTILL`` of its
    limit on two reads in a row: never a statusword bit left from an earlier stop, and a drive
    that switched off while its axis coasts is waited for too.

    Parameters
    ----------
    link : Link
        The link to the drives.
    axes : dict of str to AxisLink
        The axes.
    timeout : float
        How long each may take to stand still [s].

    Returns
    -------
    list of str
        The problems seen (empty: every axis stands still).
    """
    problems = []
    for name, ax in axes.items():
        try:
            ax.node.sdo[CONTROLWORD].raw = CW_QUICK_STOP
        except (canopen.SdoCommunicationError, canopen.SdoAbortedError) as exc:
            problems.append(f"axis {name}: quick stop not confirmed ({exc})")
    deadline = link.clock.now() + timeout
    pending = {n for n in axes if not any(p.startswith(f"axis {n}:") for p in problems)}
    still = dict.fromkeys(pending, 0)
    speed = {}
    while pending and link.clock.now() < deadline:
        for name in list(pending):
            ax = axes[name]
            try:
                sw, velocity = ax.node.sdo[STATUSWORD].raw, ax.node.sdo[VELOCITY_ACTUAL].raw
            except (canopen.SdoCommunicationError, canopen.SdoAbortedError):
                continue
            speed[name] = abs(float(ax.cfg.scaling.velocity_from_device(velocity)))
            still[name] = still[name] + 1 if at_rest(ax, sw, velocity) else 0
            if still[name] >= 2:
                pending.discard(name)
        if pending:
            link.clock.sleep(0.01)
    problems.extend(
        f"axis {n}: still moving ({speed.get(n, float('nan')):.3g} rad/s) {timeout} s after quick stop"
        for n in sorted(pending)
    )
    return problems


def prepare_enable(ax: AxisLink, target: int) -> None:
    """Before SYNC starts: a fault reset (SDO), a record buffer emptied of whatever an earlier run
    left in it (IP with 0x60C4), the axis checked to stand at the plan's start (CSP and IP: the first
    setpoint must not make it jump) and, in CSP, the target position set to where it stands (a drive
    that takes 0x607A on enable), then the operating mode.

    Parameters
    ----------
    ax : AxisLink
        The axis.
    target : int
        Where it stands [increments].
    """
    ax.drive.reset_fault()
    if ax.mode == IP and (
        ax.streaming.buffered
        or (ax.setpoint == PVT and INTERPOLATION_DATA_CONFIGURATION in ax.node.object_dictionary)
    ):
        try:
            ax.node.sdo[INTERPOLATION_DATA_CONFIGURATION][BUFFER_CLEAR].raw = 0
            ax.node.sdo[INTERPOLATION_DATA_CONFIGURATION][BUFFER_CLEAR].raw = 1
        except (canopen.SdoCommunicationError, canopen.SdoAbortedError) as exc:
            raise MotionAborted(
                f"clearing the interpolation buffer (0x60C4:6) failed ({exc}); nothing was enabled", ax.name
            ) from exc
    if ax.mode in (CSP, IP):  # (the first setpoint, a target or a record, is the plan's start)
        try:
            actual = ax.node.sdo[POSITION_ACTUAL].raw
            tolerance = max(1, round(ax.cfg.following_error_window_rad * ax.cfg.scaling.inc_per_rad / 2))
            if abs(actual - target) > tolerance:
                raise MotionAborted(
                    f"the axis stands at {actual} (0x6064), not at the plan's start {target}: it "
                    f"moved since the plan was made; nothing was enabled",
                    ax.name,
                )
            if ax.mode == CSP:
                ax.node.sdo[TARGET_POSITION].raw = actual
        except (canopen.SdoCommunicationError, canopen.SdoAbortedError) as exc:
            raise MotionAborted(
                f"setting the target position 0x607A to the actual position before enabling "
                f"failed ({exc}); nothing was enabled",
                ax.name,
            ) from exc
    ax.drive.set_mode(ax.mode)


SETTLE_S = 1.0  # how long a held axis is given to stand still before where it stands is taken
WATCH_S = 0.3  # how long a held axis is watched once a gain set is written, before it is stored
HELD = ("OPERATION ENABLED", "QUICK STOP ACTIVE")  # the states an axis held ``enabled`` is powered in


class HeldAxes:
    """The axes held powered now (not on their brake; enabled or in quick stop) and where each
    stands once it stands still: :meth:`strayed` says whether one has since left its hold
    tolerance or its power (a gain set that does not hold its load, written while it holds).

    Parameters
    ----------
    axes : dict of str to AxisLink
        The brought-up axes; those that do not answer are left out.
    """

    def __init__(self, axes: dict[str, AxisLink]):
        self.axes: dict[str, AxisLink] = {}
        self.at: dict[str, float] = {}
        for name, ax in axes.items():
            if on_brake(ax):
                continue
            try:
                if ax.drive.state() in HELD:
                    self.axes[name] = ax
            except (canopen.SdoCommunicationError, canopen.SdoAbortedError):
                continue
        still = dict.fromkeys(self.axes, 0)
        if self.axes:  # where each stands once it stands still (what ended before may still settle)
            clock = next(iter(self.axes.values())).drive.clock
            deadline = clock.now() + SETTLE_S
            while min(still.values()) < 2 and clock.now() < deadline:
                for name, ax in self.axes.items():
                    speed = abs(float(ax.cfg.scaling.velocity_from_device(ax.node.sdo[VELOCITY_ACTUAL].raw)))
                    still[name] = still[name] + 1 if speed <= STANDSTILL_MIN_RAD_S else 0
                clock.sleep(0.01)
        self.at = {name: ax.position_rad() for name, ax in self.axes.items()}

    def strayed(self) -> str | None:
        """The first held axis that left its power or its hold tolerance within :data:`WATCH_S` of
        being asked (a gain set that cannot carry the load shows over the time its loops take: a
        28x-soft set written to the simulated Z had let it sag 11 mrad 19 ms on, and faulted it
        about 120 ms on), in words.

        Returns
        -------
        str or None
            What it did; None where each held throughout.
        """
        if not self.axes:
            return None
        clock = next(iter(self.axes.values())).drive.clock
        deadline = clock.now() + WATCH_S
        while True:
            for name, ax in self.axes.items():
                tolerance = ax.cfg.drive_limits.hold_tolerance if ax.cfg.drive_limits else HOLD_TOLERANCE_RAD
                state, moved = ax.drive.state(), abs(ax.position_rad() - self.at[name])
                if state not in HELD:
                    return f"axis {name}: held powered before, {state} now"
                if moved > tolerance:
                    return (
                        f"axis {name}: left the position it was held at by {moved:.3g} rad (hold tolerance "
                        f"{tolerance:g} rad): the new gains do not hold its load"
                    )
            if clock.now() >= deadline:
                return None
            clock.sleep(0.01)


def hold_powered(axes: dict[str, AxisLink]) -> list[str]:
    """Every axis held ``enabled`` that is not powered now powered and held where it stands, in
    profile position with halt (a drive takes no target then).

    Parameters
    ----------
    axes : dict of str to AxisLink
        The brought-up axes.

    Returns
    -------
    list of str
        What was done, or why an axis could not be held (in FAULT: left for a person; no profile
        position), in words.
    """
    said = []
    for name, ax in axes.items():
        if on_brake(ax):
            continue
        state = ax.drive.state()
        if state in HELD:
            continue
        if state == "FAULT":
            said.append(f"axis {name}: in FAULT, not held powered: clear the fault at the drive")
        elif PP not in ax.modes:
            said.append(f"axis {name}: its drive has no profile position: not held powered between motions")
        else:
            ax.drive.set_mode(PP)
            ax.drive.enable("powering it to hold it", CW_HALT)
            said.append(f"axis {name}: powered and held where it stands ({ax.position_rad():.4f} rad)")
    return said


def holding_of(ax: AxisLink, state: str | None) -> str:
    """How an axis in CiA 402 ``state`` is held, in words, for the command's last lines.

    Parameters
    ----------
    ax : AxisLink
        The axis.
    state : str or None
        Its CiA 402 state (None: not known).

    Returns
    -------
    str
        How it is held.
    """
    if state in ("SWITCH ON DISABLED", "READY TO SWITCH ON", "SWITCHED ON"):
        return "switched off, on its brake" if on_brake(ax) else "switched off: NOT HELD"
    if state == "OPERATION ENABLED":
        return "powered, holding its position (profile position, halt)"
    if state == "QUICK STOP ACTIVE":
        return "powered, holding its position (quick stop active)"
    return f"in {state or 'an unknown state'}"
