"""A production to watch: pick-and-place moves of every axis, streamed one setpoint per SYNC as a
production controller streams them -- not the identification campaign, and with nothing of it
known to whoever listens (:mod:`drive_bridge.monitor`).

Each axis goes from station to station: a station drawn anywhere in the middle
:data:`STROKE_USED` of its stroke, each move at a level of its limits drawn from
:data:`LEVELS` (an S-curve within the jerk limit, :func:`.master.campaign.approach_move`),
then a dwell drawn from :data:`DWELL_S` -- as picking parts from a tray and placing them on a
conveyor varies position, speed and pause.  Everything is motor side SI (rad, rad/s, rad/s²).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import BusConfig, Limits
from .errors import MotionAborted
from .master.bringup import AxisLink
from .master.campaign import Plan, Segment, approach_move, check_plan
from .master.link import Link
from .master.stream import stream
from .recorder import stream_supervision

STROKE_USED = 0.8  # the stations lie in this middle share of each axis's stroke
LEVELS = (0.2, 0.8)  # each move at a level of the axis's velocity and acceleration limits in this range
DWELL_S = (0.05, 0.3)  # the pause at a station [s]


def pick_and_place(
    limits: dict[str, Limits], start: dict[str, float], period: float, duration_s: float, seed: int
) -> Plan:
    """At least ``duration_s`` [s] of pick-and-place for the axes of ``limits`` from the positions
    ``start`` [rad], sampled every ``period`` [s]; the stations, levels and dwells drawn from
    ``seed``.  Checked against ``limits`` (a move outside them raises :class:`UserError`).

    Parameters
    ----------
    limits : dict of str to Limits
        Per axis, its limits.
    start : dict of str to float
        Per axis, where it stands [rad].
    period : float
        The SYNC period [s].
    duration_s : float
        At least this long [s].
    seed : int
        Seed of the stations, levels and dwells.

    Returns
    -------
    Plan
        The plan.

    Raises
    ------
    UserError
        A move outside the limits.
    """
    rng = np.random.default_rng(seed)
    n = max(1, round(duration_s / period))
    columns = []
    for axis, lim in limits.items():
        centre = 0.5 * (lim.position_min + lim.position_max)
        half = 0.5 * STROKE_USED * (lim.position_max - lim.position_min)
        parts, here, length = [], start[axis], 0
        while length < n:
            target = float(rng.uniform(centre - half, centre + half))
            move = approach_move(lim, here, target, period, level=float(rng.uniform(*LEVELS)))
            dwell = np.full(max(1, round(rng.uniform(*DWELL_S) / period)), target)
            parts += [move, dwell]
            length += len(move) + len(dwell)
            here = target
        columns.append(np.concatenate(parts))
    # the shift lasts until the last axis's last move has ended (none is cut mid-move); the others
    # wait at their last station
    n = max(len(c) for c in columns)
    columns = [np.concatenate([c, np.full(n - len(c), c[-1])]) for c in columns]
    axes = list(limits)
    plan = Plan(
        axes,
        np.column_stack(columns),
        [Segment("production", tuple(axes), LEVELS[1], LEVELS[1], 0, 0, n)],
        period,
        limits=dict(limits),
    )
    check_plan(plan, limits)
    return plan


@dataclass
class Shift:
    """One shift of production: the plan streamed and how it ended.

    Parameters
    ----------
    plan : Plan
        The plan streamed.
    cycles_sent : int
        Its rows sent.
    aborted : MotionAborted or None
        What stopped it, where something did.
    """

    plan: Plan
    cycles_sent: int
    aborted: MotionAborted | None


def run_shift(
    link: Link, config: BusConfig, axes: dict[str, AxisLink], duration_s: float, seed: int
) -> Shift:
    """Stream ``duration_s`` [s] of pick-and-place to the drives ``axes`` (brought up and
    homed) from where they stand; the axes are held at its end as every stream holds them.

    Parameters
    ----------
    link : Link
        The link to the drives.
    config : BusConfig
        The bus configuration.
    axes : dict of str to AxisLink
        The brought-up axes.
    duration_s : float
        How long [s].
    seed : int
        Seed of the pick-and-place.

    Returns
    -------
    Shift
        The plan and how it ended.
    """
    start = {name: ax.position_rad() for name, ax in axes.items()}
    plan = pick_and_place(
        {n: a.cfg.limits for n, a in axes.items()}, start, config.master.sync_period_s, duration_s, seed
    )
    result = stream(
        link,
        axes,
        plan,
        supervision=stream_supervision(config, axes),
        timing_limits=config.master.timing,
        sync_producer=config.master.sync_producer,
    )
    return Shift(plan, result.cycles_sent, result.aborted)
