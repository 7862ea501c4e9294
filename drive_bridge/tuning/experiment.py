"""The paper's experimental tuning, automated and guarded, on the drive.

A velocity square wave between 0 and 10 % of the axis's maximum velocity
(edges at its maximum acceleration, as a CSP position profile) is run with the
velocity gain KpS raised by 50 % per step until the logged velocity
oscillates, then lowered by 10 % per step until it no longer does.
Oscillation: on the flat parts of the square wave (after a settling time), the
RMS of the velocity error exceeds ``OSCILLATION_RATIO`` of the step height.
Every gain passes the gain gate first (as ``write`` and ``validate``'s do): the
raising ends at the first gain whose loop margins on the identified model fall
below the floor, unless forced.  Guards: the drive's following-error window is
tightened to ``FE_GUARD_RAD`` for the experiment (the drive faults before the
axis wanders), and a
velocity beyond ``VELOCITY_GUARD`` × the highest demanded speed stops the run at once;
the original window and gain are written back at the end.  Those two stops are
the procedure's own (the fault is reset and the gain lowered); any other stop --
an EMCY of another kind, a lost heartbeat, missing feedback, Ctrl-C, SIGTERM --
ends the experiment as a motion stop.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import numpy as np

from ..cia.objects import FOLLOWING_ERROR_WINDOW
from ..cia.p301 import ERR_FOLLOWING
from ..config import BusConfig, Limits
from ..errors import DriveRefused, GuardStop, MotionAborted, UserError
from ..master.bringup import AxisLink
from ..master.campaign import APPROACH_LEVEL
from ..master.link import Link
from ..master.supervision import VelocityGuard
from ..params.check import ValueRefused
from ..params.controller import GAINS
from ..params.profile import SELECT, Profile
from ..params.read import read_parameters
from ..params.write import write_parameters
from . import motion

log = logging.getLogger(__name__)

STEP_FRACTION = 0.10
HALF_PERIOD_S = 0.15
CYCLES = 2
RAISE, LOWER = 1.5, 0.9
OSCILLATION_RATIO = 0.05
SETTLE_S = 0.05
VELOCITY_GUARD = 3.0
FE_GUARD_RAD = 0.05
MAX_STEPS = 12
RECOVER_S = 0.5


@dataclass
class Step:
    """One gain of the experiment, as it ran.

    Parameters
    ----------
    KpS : float
        The velocity gain [Nm·s/rad].
    oscillation : float
        The RMS velocity error on the flat parts over the step height.
    oscillating : bool
        Beyond ``OSCILLATION_RATIO``.
    aborted : str or None
        The procedure's own stop that ended it (following error, velocity guard), where one did.
    """

    KpS: float
    oscillation: float
    oscillating: bool
    aborted: str | None


@dataclass
class ExperimentResult:
    """The experiment on one axis (:func:`run_experiment`).

    Parameters
    ----------
    axis : str
        The axis.
    KpS : float or None
        The last velocity gain without oscillation [Nm·s/rad]; None: none.
    steps : list of Step
        Every gain tried, in order.
    gated : str, optional
        Why the raising stopped before the velocity oscillated: the next gain the gate refused.
    """

    axis: str
    KpS: float | None
    steps: list[Step] = field(default_factory=list)
    gated: str | None = None

    def as_dict(self) -> dict:
        """The experiment as tune.json holds it.

        Returns
        -------
        dict
            Every field, the steps as dicts.
        """
        return asdict(self)


def square_wave(v_step: float, a_max: float, period: float, start: float) -> tuple[np.ndarray, np.ndarray]:
    """The velocity square wave, as a position demand.

    Parameters
    ----------
    v_step : float
        The step height [rad/s].
    a_max : float
        The edges' acceleration [rad/s²].
    period : float
        The SYNC period [s].
    start : float
        Where it starts [rad].

    Returns
    -------
    position : numpy.ndarray
        The position demand [rad] per period.
    velocity : numpy.ndarray
        The velocity demand [rad/s] per period.
    """
    n_half = round(HALF_PERIOD_S / period)
    ramp = max(1, int(np.ceil(v_step / a_max / period)))  # edges at the acceleration limit
    k = np.arange(1, n_half + 1)
    one = np.concatenate([np.minimum(k / ramp, 1.0), np.maximum(1.0 - k / ramp, 0.0)])
    vel = np.tile(one, CYCLES) * v_step
    return start + (np.cumsum(vel) - vel) * period, vel  # p[k] = start + T·Σ_{j<k} v[j]


def _oscillation(m: motion.Motion, axis: str, vel: np.ndarray, period: float, v_step: float) -> float:
    n_half = round(HALF_PERIOD_S / period)
    settle = round(SETTLE_S / period)
    err = []
    for k in range(2 * CYCLES):
        flat = slice(k * n_half + settle, (k + 1) * n_half)
        e = m.velocity[axis][flat] - vel[flat]
        err.append(e[np.isfinite(e)] - np.nanmean(e))
    e = np.concatenate(err)
    return float(np.sqrt(np.mean(e**2)) / v_step) if e.size else float("inf")


def demand_of(lim: Limits, period: float) -> tuple[np.ndarray, np.ndarray, float]:
    """What each step of the experiment runs on an axis.

    Parameters
    ----------
    lim : Limits
        The axis's limits.
    period : float
        The SYNC period [s].

    Returns
    -------
    position : numpy.ndarray
        The square wave's position demand [rad] around the stroke's centre.
    velocity : numpy.ndarray
        Its velocity demand [rad/s].
    v_step : float
        The step height [rad/s].
    """
    v_step = STEP_FRACTION * lim.max_velocity
    centre = 0.5 * (lim.position_min + lim.position_max)
    demand, vel = square_wave(
        v_step, lim.max_acceleration, period, centre - 0.5 * v_step * HALF_PERIOD_S * CYCLES
    )
    return demand, vel, v_step


def check_start(axis: str, start_KpS: float, admit: Callable[[float], str | None] | None) -> None:
    """Refuse, before anything is written, a first gain the gate refuses.

    Parameters
    ----------
    axis : str
        The axis (named in the error).
    start_KpS : float
        The experiment's first velocity gain [Nm·s/rad].
    admit : callable or None
        ``admit(KpS)``: why a gain must not reach the drive (None: it may); None: no gate.

    Raises
    ------
    ValueRefused
        The gate refuses it.
    """
    if admit is not None and (why := admit(start_KpS)):
        raise ValueRefused(
            f"axis {axis}: the experiment's first gain KpS = {start_KpS:.5g} is refused before "
            f"anything was written: {why}"
        )


def run_experiment(
    config: BusConfig,
    link: Link,
    axes: dict[str, AxisLink],
    axis: str,
    profile: Profile,
    start_KpS: float,
    admit: Callable[[float], str | None] | None = None,
) -> ExperimentResult:
    """The procedure on ``axis`` from ``start_KpS``. ``admit(KpS)`` says why a gain must not reach
    the drive (the gain gate, :func:`~drive_bridge.params.check.screen`; None: it may): a start it
    refuses raises ValueRefused before anything is written, a raise it refuses ends the raising
    there (``ExperimentResult.gated``); without ``admit`` every gain the ranges allow is tried.

    Parameters
    ----------
    config : BusConfig
        The bus configuration.
    link : Link
        The link to the drives.
    axes : dict of str to AxisLink
        The brought-up axes.
    axis : str
        The axis to run it on.
    profile : Profile
        Its drive's profile (where the gains are written).
    start_KpS : float
        The first velocity gain [Nm·s/rad].
    admit : callable, optional
        The gain gate.

    Returns
    -------
    ExperimentResult
        Every gain tried and the last one without oscillation.

    Raises
    ------
    UserError
        A drive that runs no velocity loop of its own (not a cascade).
    ValueRefused
        The gate refuses the first gain.
    DriveRefused
        A gain the drive does not take.
    MotionAborted
        A stop that is not the procedure's own (the axes are stopped and held).
    """
    ax = axes[axis]
    if profile.controller.structure != "cascade":
        raise UserError(
            f"axis {axis}: the paper's procedure raises the velocity loop's KpS; the {profile.drive} "
            f"runs a {profile.controller.structure.replace('_', ' ')} in its streaming mode (tune "
            f"without --experiment)"
        )
    lim = ax.cfg.limits
    period = config.master.sync_period_s
    demand, vel, v_step = demand_of(lim, period)
    check_start(axis, start_KpS, admit)
    inc = ax.cfg.scaling.inc_per_rad
    window = ax.node.sdo[FOLLOWING_ERROR_WINDOW].raw
    original: dict[str, float] | None = None  # the gains before, read before anything moves
    result = ExperimentResult(axis, None)
    ax.node.sdo[FOLLOWING_ERROR_WINDOW].raw = round(FE_GUARD_RAD * inc)

    v_limit = VELOCITY_GUARD * max(v_step, APPROACH_LEVEL * lim.max_velocity)  # the approach runs at 20 %

    guard = VelocityGuard({axis: v_limit})

    def trial(kps: float) -> Step:
        res = write_parameters(ax.node, profile, {**running, "KpS": kps}, store=False)
        if not res.ok:
            raise DriveRefused(f"axis {axis}: {res.error}")
        m = motion.run(config, link, {axis: ax}, {axis: demand}, guard=guard)
        if m.aborted is not None and not _expected(m.aborted):
            raise m.aborted  # a fault of the machine, not of the gain: stop here
        if m.aborted is not None:
            ax.drive.reset_fault()  # the experiment's own guard or its tightened window
            step = Step(kps, float("inf"), True, str(m.aborted))
            recover()
        else:
            osc = _oscillation(m, axis, vel, period, v_step)
            step = Step(kps, osc, osc > OSCILLATION_RATIO, None)
        log.info(
            "axis %s: KpS %.5g: %s",
            axis,
            kps,
            step.aborted
            or f"velocity error {osc:.3g} of the step" + (" (oscillating)" if step.oscillating else ""),
        )
        result.steps.append(step)
        return step

    def _expected(stop: MotionAborted) -> bool:
        """The stops the procedure provokes: its velocity guard, or the following-error fault of
        its tightened window on the axis under test."""
        return isinstance(stop, GuardStop) or (stop.axis == axis and stop.emcy == ERR_FOLLOWING)

    def recover() -> None:
        """After a stop: settle the axis where it stands with the gain it had before the experiment."""
        if original is not None:
            write_parameters(ax.node, profile, original, store=False)
        here = ax.position_rad()
        motion.run(config, link, {axis: ax}, {axis: np.full(round(RECOVER_S / period), here)})

    try:
        original = read_parameters(
            ax.node, profile, list(GAINS)
        )  # the whole set: a drive may switch gain objects
        running = {k: v for k, v in original.items() if k != SELECT}
        kps = start_KpS
        step = trial(kps)
        while not step.oscillating and len(result.steps) < MAX_STEPS:
            if admit is not None and (why := admit(kps * RAISE)):
                result.gated = f"KpS = {kps * RAISE:.5g} not tried: {why}"
                log.info("axis %s: %s", axis, result.gated)
                break
            kps *= RAISE
            step = trial(kps)
        while step.oscillating and len(result.steps) < MAX_STEPS:
            kps *= LOWER
            step = trial(kps)
        if not step.oscillating:
            result.KpS = kps
    finally:
        ax.node.sdo[FOLLOWING_ERROR_WINDOW].raw = window
        if original is not None:
            write_parameters(ax.node, profile, original, store=False)
    return result
