"""The excitation campaign: the paper's forward and backward trapezoidal moves at
velocity x acceleration levels of each axis' limits (``design: paper``, the reference), or a
short multisine per axis designed for the identification (``design: short``,
:mod:`.excitation`); sampled once per SYNC.

Everything is motor side SI (rad, rad/s, rad/s², rad/s³); the plan is checked against
the axis limits before anything moves, and a profile outside them is refused.
"""

from __future__ import annotations

import logging
import math
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from ..config import CampaignConfig, Limits
from ..errors import UserError

log = logging.getLogger(__name__)

APPROACH_LEVEL = 0.2  # approach and return moves run at 20 % of the limits
APPROACH_RAMP_S = 0.05  # ... and their acceleration ramps over this long where no jerk limit is set
MIN_EXCITATION_CYCLES = 600  # the short campaign's multisine needs at least this long


@dataclass(frozen=True)
class Segment:
    """A span of SYNC cycles [start, end) with one velocity / acceleration level.

    Parameters
    ----------
    kind : {"approach", "level", "return"}
        What it is.
    axes : tuple of str
        The axes that move in it.
    velocity_fraction, acceleration_fraction : float
        Its level, as shares of the limits.
    cycles : int
        Complete forward and backward cycles (0 for an approach or return).
    start, end : int
        Its plan rows [start, end).
    """

    kind: str
    axes: tuple[str, ...]
    velocity_fraction: float
    acceleration_fraction: float
    cycles: int
    start: int
    end: int

    def as_dict(self, period: float) -> dict:
        """The segment as meta.yaml holds it.

        Parameters
        ----------
        period : float
            The SYNC period [s].

        Returns
        -------
        dict
            Every field, and ``start_s``, ``end_s`` [s].
        """
        d = asdict(self)
        d["axes"] = list(self.axes)
        d["start_s"] = round(self.start * period, 6)
        d["end_s"] = round(self.end * period, 6)
        return d


@dataclass
class Plan:
    """What a stream sends, one row per SYNC.

    Parameters
    ----------
    axes : list of str
        The axes, in the demand's column order.
    demand : numpy.ndarray
        (n_cycles, n_axes) position demand [rad].
    segments : list of Segment
        Its spans of one level each.
    period : float
        The SYNC period [s].
    torque_ff_Nm, velocity_ff_rad_s : numpy.ndarray, optional
        Feed-forward the master sends with each setpoint, (n_cycles, n_axes), as torque offset
        0x60B2 [Nm] and velocity offset 0x60B1 [rad/s] where the RPDOs map them (None: zero
        offsets).
    limits : dict of str to Limits
        The limits of each axis the plan was checked against (as bring-up found them).
    """

    axes: list[str]
    demand: np.ndarray
    segments: list[Segment]
    period: float
    torque_ff_Nm: np.ndarray | None = None
    velocity_ff_rad_s: np.ndarray | None = None
    limits: dict[str, Limits] = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """How long it runs [s]."""
        return len(self.demand) * self.period


def trapezoid(p0: float, p1: float, v: float, a: float, period: float) -> np.ndarray:
    """Positions at t = period, 2*period, ... of a trapezoidal (or triangular) move.

    Parameters
    ----------
    p0, p1 : float
        From, to [rad].
    v : float
        Peak velocity [rad/s].
    a : float
        Acceleration [rad/s²].
    period : float
        The SYNC period [s].

    Returns
    -------
    numpy.ndarray
        The positions [rad], ending at ``p1``.
    """
    dist = abs(p1 - p0)
    if dist == 0.0:
        return np.empty(0)
    v = min(v, math.sqrt(dist * a))  # triangular when the plateau vanishes
    t_acc = v / a
    total = dist / v + t_acc
    t = np.arange(1, math.ceil(total / period - 1e-9) + 1) * period
    t = np.minimum(t, total)
    s = np.where(
        t < t_acc,
        0.5 * a * t**2,
        np.where(t <= total - t_acc, 0.5 * a * t_acc**2 + v * (t - t_acc), dist - 0.5 * a * (total - t) ** 2),
    )
    return p0 + math.copysign(1.0, p1 - p0) * s


def _cycle(lo: float, hi: float, v: float, a: float, dwell: int, period: float) -> np.ndarray:
    fwd = trapezoid(lo, hi, v, a, period)
    back = trapezoid(hi, lo, v, a, period)
    return np.concatenate([fwd, np.full(dwell, hi), back, np.full(dwell, lo)])


def _allocate(cycle_times: list[float], wanted: int, budget: float) -> list[int]:
    """Cycles per level: ``wanted`` each if the budget allows, else a fair share (at least 1)."""
    order = sorted(range(len(cycle_times)), key=lambda i: cycle_times[i])
    counts = [0] * len(cycle_times)
    left = budget
    for rank, i in enumerate(order):
        share = left / (len(order) - rank)
        counts[i] = max(1, min(wanted, int(share // cycle_times[i])))
        left -= counts[i] * cycle_times[i]
    return counts


def build_plan(
    cfg: CampaignConfig, limits: dict[str, Limits], start: dict[str, float], period: float
) -> Plan:
    """Plan of the whole campaign for the axes in ``limits``, from positions ``start`` [rad].

    Parameters
    ----------
    cfg : CampaignConfig
        The campaign.
    limits : dict of str to Limits
        Per axis, its limits.
    start : dict of str to float
        Per axis, where it stands [rad].
    period : float
        The SYNC period [s].

    Returns
    -------
    Plan
        The plan.

    Raises
    ------
    UserError
        The short design with too little time for its excitation, or an axis it cannot excite
        within its limits.
    """
    if cfg.design == "short":
        return short_plan(cfg, limits, start, period)
    axes = list(limits)
    dwell = round(cfg.dwell_s / period)
    levels = [(v, a) for v in cfg.velocity_levels for a in cfg.acceleration_levels]
    ends = {}
    for ax, lim in limits.items():
        centre = 0.5 * (lim.position_min + lim.position_max)
        half = 0.5 * (lim.position_max - lim.position_min) * cfg.move_fraction
        ends[ax] = (centre - half, centre + half)

    def level_cycle(ax: str, vf: float, af: float) -> np.ndarray:
        lim = limits[ax]
        return _cycle(*ends[ax], vf * lim.max_velocity, af * lim.max_acceleration, dwell, period)

    def approach(ax: str, p0: float, p1: float) -> np.ndarray:
        return approach_move(limits[ax], p0, p1, period)

    # cycles per level and axis, within the per-axis time cap (approach and return included)
    counts = {}
    for ax in axes:
        travel = (
            len(approach(ax, start[ax], ends[ax][0])) + len(approach(ax, ends[ax][0], start[ax]))
        ) * period
        times = [len(level_cycle(ax, v, a)) * period for v, a in levels]
        counts[ax] = _allocate(times, cfg.cycles, cfg.max_axis_time_s - travel)

    seq = _Sequence(axes, start, period)
    for group in [axes] if cfg.together else [[ax] for ax in axes]:
        seq.add(
            "approach",
            group,
            {ax: approach(ax, seq.pos[ax], ends[ax][0]) for ax in group},
            APPROACH_LEVEL,
            APPROACH_LEVEL,
        )
        for li, (vf, af) in enumerate(levels):
            pieces = {ax: np.tile(level_cycle(ax, vf, af), counts[ax][li]) for ax in group}
            seq.add("level", group, pieces, vf, af, min(counts[ax][li] for ax in group))
        seq.add(
            "return",
            group,
            {ax: approach(ax, seq.pos[ax], start[ax]) for ax in group},
            APPROACH_LEVEL,
            APPROACH_LEVEL,
        )
    return seq.plan(limits)


class _Sequence:
    """Pieces of motion laid one after the other, each a segment of the plan; an axis without a
    piece in a segment holds its position."""

    def __init__(self, axes: list[str], start: dict[str, float], period: float):
        self.axes, self.pos, self.period = axes, dict(start), period
        self.columns: dict[str, list[np.ndarray]] = {ax: [] for ax in axes}
        self.segments: list[Segment] = []
        self.n = 0

    def add(
        self,
        kind: str,
        group: list[str],
        pieces: dict[str, np.ndarray],
        vf: float,
        af: float,
        cycles: int = 0,
    ) -> None:
        length = max(len(p) for p in pieces.values())
        if length == 0:
            return
        for ax in self.axes:
            piece = pieces.get(ax, np.empty(0))
            if len(piece):
                self.pos[ax] = float(piece[-1])
            self.columns[ax].append(np.concatenate([piece, np.full(length - len(piece), self.pos[ax])]))
        self.segments.append(Segment(kind, tuple(group), vf, af, cycles, self.n, self.n + length))
        self.n += length

    def plan(self, limits: dict[str, Limits]) -> Plan:
        """The plan, checked against ``limits``."""
        demand = np.column_stack([np.concatenate(self.columns[ax]) for ax in self.axes])
        plan = Plan(self.axes, demand, self.segments, self.period, limits=dict(limits))
        check_plan(plan, limits)
        return plan


def short_plan(
    cfg: CampaignConfig, limits: dict[str, Limits], start: dict[str, float], period: float
) -> Plan:
    """The short campaign: per axis (or all at once with ``together``) an approach to the centre
    of the stroke, the designed multisine, and the return, within ``short_time_s`` per axis.

    Parameters
    ----------
    cfg : CampaignConfig
        The campaign.
    limits : dict of str to Limits
        Per axis, its limits.
    start : dict of str to float
        Per axis, where it stands [rad].
    period : float
        The SYNC period [s].

    Returns
    -------
    Plan
        The plan.

    Raises
    ------
    UserError
        The short design with too little time for its excitation, or an axis it cannot excite
        within its limits.
    """
    from .excitation import MARGIN, design_axis

    axes = list(limits)
    seq = _Sequence(axes, start, period)
    for group in [axes] if cfg.together else [[ax] for ax in axes]:
        centre = {ax: 0.5 * (limits[ax].position_min + limits[ax].position_max) for ax in group}
        travel = {ax: approach_move(limits[ax], seq.pos[ax], centre[ax], period) for ax in group}
        back = {ax: approach_move(limits[ax], centre[ax], start[ax], period) for ax in group}
        moving = max(len(travel[ax]) + len(back[ax]) for ax in group) * period
        excite = cfg.short_time_s - moving
        if excite < MIN_EXCITATION_CYCLES * period:
            raise UserError(
                f"campaign.short_time_s {cfg.short_time_s:g} s leaves {excite:.1f} s of excitation "
                f"after the moves to and from the centre of the stroke; give it more time"
            )
        excitation = {}
        for i, ax in enumerate(group):
            try:
                excitation[ax] = design_axis(limits[ax], excite, period, cfg.move_fraction, seed=i)
            except ValueError as exc:
                raise UserError(
                    f"axis {ax}: {exc} in {excite:.1f} s of excitation; nothing was moved. Give "
                    f"campaign.short_time_s more time, lower campaign.move_fraction, or use the "
                    f"paper's campaign (design: paper)"
                ) from exc
        seq.add("approach", group, travel, APPROACH_LEVEL, APPROACH_LEVEL)
        seq.add("excitation", group, excitation, MARGIN, MARGIN)
        seq.add("return", group, back, APPROACH_LEVEL, APPROACH_LEVEL)
    return seq.plan(limits)


def approach_move(
    lim: Limits, p0: float, p1: float, period: float, level: float = APPROACH_LEVEL
) -> np.ndarray:
    """A move at ``level`` of the limits (the approach level by default) from wherever the axis
    stands: a trapezoid whose positions are smoothed so that the acceleration ramps (an S-curve of
    the same travel) within the jerk limit where one is set, else over ``APPROACH_RAMP_S``: no
    acceleration step at the start of motion.

    Parameters
    ----------
    lim : Limits
        The axis's limits.
    p0, p1 : float
        From, to [rad].
    period : float
        The SYNC period [s].
    level : float
        The share of the limits.

    Returns
    -------
    numpy.ndarray
        The positions [rad].
    """
    move = trapezoid(p0, p1, level * lim.max_velocity, level * lim.max_acceleration, period)
    if len(move) == 0:
        return move
    ramp_s = APPROACH_RAMP_S if lim.max_jerk is None else 1.25 * lim.max_acceleration / lim.max_jerk
    ramp = max(1, int(np.ceil(ramp_s / period)))  # 1.25: room for sampling
    padded = np.concatenate([np.full(ramp, p0), move, np.full(ramp, p1)])
    return np.convolve(padded, np.ones(ramp) / ramp, "valid")


def resume_plan(plan: Plan, segment: Segment, here: dict[str, float]) -> tuple[Plan, int, int]:
    """The rest of ``plan`` from ``segment`` on, after an approach from where the axes stand to where
    the plan stands at rest at or before the segment's start (a segment repeated after a planned
    stop; a segment may begin a row into its first move); checked against the plan's limits.

    Parameters
    ----------
    plan : Plan
        The plan (its ``limits`` set, as :func:`build_plan` sets them).
    segment : Segment
        The segment it goes on from.
    here : dict of str to float
        Per axis, where it stands [rad].

    Returns
    -------
    plan : Plan
        The approach, then the plan's rows from ``begin``; its segments in its own rows.
    approach : int
        The approach's rows (the plan's row ``begin`` is the resumed plan's row ``approach``).
    begin : int
        The plan's row it resumes at: the segment's start, or the row before its first move.
    """
    begin = segment.start
    while begin > 0 and np.any(plan.demand[begin] != plan.demand[begin - 1]):
        begin -= 1  # into the move: back to where it starts from rest
    seq = _Sequence(plan.axes, here, plan.period)
    seq.add(
        "approach",
        plan.axes,
        {
            a: approach_move(plan.limits[a], here[a], float(plan.demand[begin, i]), plan.period)
            for i, a in enumerate(plan.axes)
        },
        APPROACH_LEVEL,
        APPROACH_LEVEL,
    )
    lead = seq.n
    for s in plan.segments[plan.segments.index(segment) :]:  # the plan's own rows, segment by segment
        first = begin if s is segment else s.start
        pieces = {a: plan.demand[first : s.end, i] for i, a in enumerate(plan.axes)}
        seq.add(s.kind, list(s.axes), pieces, s.velocity_fraction, s.acceleration_fraction, s.cycles)

    def after(values: np.ndarray | None) -> np.ndarray | None:
        return None if values is None else np.vstack([np.zeros((lead, len(plan.axes))), values[begin:]])

    resumed = seq.plan(plan.limits)  # (checked against them)
    return (
        replace(
            resumed, torque_ff_Nm=after(plan.torque_ff_Nm), velocity_ff_rad_s=after(plan.velocity_ff_rad_s)
        ),
        lead,
        begin,
    )


def plan_summary(plan: Plan, limits: dict[str, Limits]) -> dict[str, dict]:
    """Per axis what the plan does, motor side SI: where it starts, the span it covers, its peak
    velocity, acceleration and jerk, and the limits it stays inside; the plan's duration [s].

    Parameters
    ----------
    plan : Plan
        The plan.
    limits : dict of str to Limits
        Per axis, its limits.

    Returns
    -------
    dict of str to dict
        Per axis what it does; ``duration_s``.
    """
    T = plan.period
    out = {}
    for i, ax in enumerate(plan.axes):
        p, lim = plan.demand[:, i], limits[ax]
        peak = [float(np.max(np.abs(np.diff(p, k)))) / T**k if len(p) > k else 0.0 for k in (1, 2, 3)]
        out[ax] = {
            "start_rad": float(p[0]),
            "min_rad": float(p.min()),
            "max_rad": float(p.max()),
            "peak_velocity_rad_s": peak[0],
            "peak_acceleration_rad_s2": peak[1],
            "peak_jerk_rad_s3": peak[2],
            "limits": {
                "stroke_rad": [lim.position_min, lim.position_max],
                "max_velocity_rad_s": lim.max_velocity,
                "max_acceleration_rad_s2": lim.max_acceleration,
                "max_jerk_rad_s3": lim.max_jerk,
            },
            "duration_s": plan.duration,
        }
    return out


def check_plan(plan: Plan, limits: dict[str, Limits], tolerance: float = 1e-6) -> None:
    """Refuse a plan that leaves the stroke or exceeds velocity, acceleration or (where
    configured) jerk limits.

    Parameters
    ----------
    plan : Plan
        The plan.
    limits : dict of str to Limits
        Per axis, its limits.
    tolerance : float
        A relative margin for rounding.

    Raises
    ------
    UserError
        The first limit it breaks, naming the axis.
    """
    T = plan.period
    for i, ax in enumerate(plan.axes):
        lim = limits[ax]
        p = plan.demand[:, i]
        lo, hi = p.min(), p.max()
        if lo < lim.position_min - tolerance or hi > lim.position_max + tolerance:
            raise UserError(
                f"axis {ax}: the profile spans {lo:.4f} .. {hi:.4f} rad, outside the stroke "
                f"{lim.position_min:.4f} .. {lim.position_max:.4f} rad; nothing was moved. "
                f"Move the axis inside its stroke or correct limits.stroke in the bus config."
            )
        v = np.abs(np.diff(p)) / T
        if v.size and v.max() > lim.max_velocity * (1 + 1e-6):
            raise UserError(
                f"axis {ax}: the profile reaches {v.max():.4g} rad/s, above the limit "
                f"{lim.max_velocity:.4g} rad/s; nothing was moved."
            )
        acc = np.abs(np.diff(p, 2)) / T**2
        if acc.size and acc.max() > lim.max_acceleration * (1 + 1e-3):
            raise UserError(
                f"axis {ax}: the profile reaches {acc.max():.4g} rad/s², above the limit "
                f"{lim.max_acceleration:.4g} rad/s²; nothing was moved."
            )
        jerk = np.abs(np.diff(p, 3)) / T**3
        if lim.max_jerk is not None and jerk.size and jerk.max() > lim.max_jerk * (1 + 1e-3):
            raise UserError(
                f"axis {ax}: the profile reaches a jerk of {jerk.max():.4g} rad/s³, above the limit "
                f"{lim.max_jerk:.4g} rad/s³; nothing was moved"
                + (
                    " (the paper's trapezoids step the acceleration: campaign design: short keeps "
                    "the jerk limit)"
                    if any(s.kind == "level" for s in plan.segments)
                    else ""
                )
                + "."
            )
        log.debug(
            "axis %s: the plan spans %.4f .. %.4f rad, peaks %.4g rad/s, %.4g rad/s²: inside its limits",
            ax,
            lo,
            hi,
            v.max() if v.size else 0.0,
            acc.max() if acc.size else 0.0,
        )
