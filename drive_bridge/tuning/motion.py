"""Running a demand on brought-up axes and getting SI arrays back (for validation and experiments)."""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..config import BusConfig
from ..errors import MotionAborted, RanDry
from ..logs import to_table
from ..master.bringup import AxisLink
from ..master.buffered import MAX_REPEATS
from ..master.campaign import APPROACH_LEVEL, Plan, Segment, approach_move, check_plan
from ..master.homing import home
from ..master.link import Link
from ..master.stream import stream
from ..master.supervision import VelocityGuard
from ..master.timing import Timing
from ..recorder import stream_supervision
from .feedforward import MasterFeedForward

log = logging.getLogger(__name__)


@dataclass
class Motion:
    """One run, approach move excluded (:func:`run`).

    Parameters
    ----------
    t : numpy.ndarray
        The SYNC instants [s].
    position, velocity, torque : dict of str to numpy.ndarray
        Per axis, measured at each SYNC [rad, rad/s, Nm].
    demand : dict of str to numpy.ndarray
        Per axis, the setpoint the drive was following then [rad].
    aborted : MotionAborted or None
        What stopped the run, where something did (the axes were stopped and held).
    timing : Timing
        The run's timing (late cycles, gaps, what was granted the engine).
    """

    t: np.ndarray
    position: dict[str, np.ndarray]
    velocity: dict[str, np.ndarray]
    torque: dict[str, np.ndarray]
    demand: dict[str, np.ndarray]
    aborted: MotionAborted | None
    timing: Timing


def plan(
    config: BusConfig,
    axes: dict[str, AxisLink],
    demand: dict[str, np.ndarray],
    start: dict[str, float],
    *,
    kind: str = "trajectory",
    level: float = 1.0,
    feedforward: dict[str, MasterFeedForward] | None = None,
    approach_level: float = APPROACH_LEVEL,
    torque_offset: dict[str, np.ndarray] | None = None,
) -> tuple[Plan, int]:
    """The plan :func:`run` streams from ``start`` (axis -> position [rad]): the approach to the
    first setpoint of ``demand`` at ``approach_level`` of the limits, 0.2 s settling there, then the
    demand; checked against the axes' limits (UserError before anything moves). And the number of
    cycles before the demand.

    Parameters
    ----------
    config : BusConfig
        The bus configuration (the SYNC period).
    axes : dict of str to AxisLink
        The brought-up axes (their limits).
    demand : dict of str to numpy.ndarray
        Per axis, its positions per SYNC [rad].
    start : dict of str to float
        Per axis, where it stands [rad].
    kind : str
        What the demand is, for the progress line.
    level : float
        The demand's share of the limits, for the progress line.
    feedforward : dict of str to MasterFeedForward, optional
        Per axis, what the master sends with every setpoint, the approach included.
    approach_level : float
        The approach's share of the limits.
    torque_offset : dict of str to numpy.ndarray, optional
        Per axis, [Nm] per setpoint of ``demand``, sent as torque offset 0x60B2 with the demand's
        setpoints, beside any ``feedforward``.

    Returns
    -------
    plan : Plan
        The plan.
    before : int
        The cycles before the demand (approach and settling).

    Raises
    ------
    UserError
        A demand outside the axes' limits, before anything moves.
    """
    period = config.master.sync_period_s
    names = list(demand)
    limits = {a: axes[a].cfg.limits for a in names}
    approach = {
        a: approach_move(limits[a], start[a], float(demand[a][0]), period, approach_level) for a in names
    }
    n_app = max(len(v) for v in approach.values()) + round(0.2 / period)  # then settle
    cols = [
        np.concatenate([approach[a], np.full(n_app - len(approach[a]), float(demand[a][0])), demand[a]])
        for a in names
    ]  # the approach ends at the first setpoint, then holds it
    out = Plan(
        names,
        np.column_stack(cols),
        [
            Segment("approach", tuple(names), approach_level, approach_level, 0, 0, n_app),
            Segment(kind, tuple(names), level, level, 0, n_app, n_app + len(demand[names[0]])),
        ],
        period,
        limits=limits,
    )
    if feedforward:
        offsets = [
            feedforward[a].offsets(out.demand[:, i], period)
            if a in feedforward
            else (np.zeros(len(out.demand)),) * 2
            for i, a in enumerate(names)
        ]
        out.torque_ff_Nm = np.column_stack([t for t, _ in offsets])
        out.velocity_ff_rad_s = np.column_stack([v for _, v in offsets])
    if torque_offset:
        added = np.zeros_like(out.demand)
        for i, a in enumerate(names):
            added[n_app:, i] = torque_offset.get(a, 0.0)
        out.torque_ff_Nm = added if out.torque_ff_Nm is None else out.torque_ff_Nm + added
    check_plan(out, limits)
    return out, n_app


def run(
    config: BusConfig,
    link: Link,
    axes: dict[str, AxisLink],
    demand: dict[str, np.ndarray],
    *,
    guard: VelocityGuard | None = None,
    on_plan: Callable[[Plan], Callable[[int], None] | None] | None = None,
    kind: str = "trajectory",
    level: float = 1.0,
    feedforward: dict[str, MasterFeedForward] | None = None,
    approach_level: float = APPROACH_LEVEL,
    torque_offset: dict[str, np.ndarray] | None = None,
) -> Motion:
    """Stream :func:`plan` from where the axes stand, homed first where they home
    (:mod:`~drive_bridge.master.homing`) (``demand``: axis -> positions per SYNC
    [rad]); ``guard`` sees each cycle's measured velocities and may stop the run.
    ``on_plan`` may return a progress callback (as in ``record``); ``kind`` and ``level`` (fraction
    of the limits) label the demand's segment for it.  ``feedforward`` (per axis) is the model
    feed-forward the master sends with every setpoint, the approach included; ``torque_offset``
    (per axis, per setpoint of ``demand`` [Nm]) is added to it over the demand.

    Parameters
    ----------
    config : BusConfig
        The bus configuration.
    link : Link
        The link to the drives.
    axes : dict of str to AxisLink
        The brought-up axes.
    demand : dict of str to numpy.ndarray
        Per axis, its positions per SYNC [rad].
    guard : VelocityGuard, optional
        Sees each cycle's measured velocities and may stop the run.
    on_plan : callable, optional
        Given the plan, may return a progress callback.
    kind : str
        What the demand is, for the progress line.
    level : float
        The demand's share of the limits, for the progress line.
    feedforward : dict of str to MasterFeedForward, optional
        Per axis, the model feed-forward the master sends.
    approach_level : float
        The approach's share of the limits.
    torque_offset : dict of str to numpy.ndarray, optional
        Per axis, [Nm] per setpoint of ``demand``.

    Returns
    -------
    Motion
        What was measured, the approach excluded, and what stopped the run if anything did.

    Raises
    ------
    UserError
        A demand outside the axes' limits, before anything moves.
    """
    period = config.master.sync_period_s
    names = list(demand)
    home(link, {a: axes[a] for a in names}, config)  # reference: home, before the first motion
    m = config.master
    for repeat in range(MAX_REPEATS + 1):  # a FIFO run dry (its planned stop): the whole run again
        plan_, n_app = plan(
            config,
            axes,
            demand,
            {a: axes[a].position_rad() for a in names},
            kind=kind,
            level=level,
            feedforward=feedforward,
            approach_level=approach_level,
            torque_offset=torque_offset,
        )
        progress = on_plan(plan_) if on_plan and not repeat else None
        result = stream(
            link,
            {a: axes[a] for a in names},
            plan_,
            supervision=stream_supervision(config, {a: axes[a] for a in names}),
            progress=progress,
            timing_limits=m.timing,
            sync_producer=m.sync_producer,
            guard=guard,
        )
        if not isinstance(result.aborted, RanDry) or repeat == MAX_REPEATS:
            break
        log.warning("%s; the %s runs again from where the axes stopped", result.aborted, kind)
    names_, values, _ = to_table(result.recording, {a: axes[a].cfg.scaling for a in names}, period)
    col = {n: values[:, i] for i, n in enumerate(names_)}
    rows = slice(n_app, max(n_app, len(values)))
    get = lambda suffix: {a: col[f"{a}_{suffix}"][rows] for a in names}  # noqa: E731
    # the setpoint a SYNC's sample was following: the one sent before the previous SYNC
    dem = {a: col[f"{a}_position_demand_rad"][n_app - 1 : max(n_app - 1, len(values) - 1)] for a in names}
    return Motion(
        col["time_s"][rows] - n_app * period,
        get("position_rad"),
        get("velocity_rad_s"),
        get("torque_Nm"),
        dem,
        result.aborted,
        result.timing,
    )
