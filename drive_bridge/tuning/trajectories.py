"""Reference trajectories for validation (not the excitation profiles), motor side [rad].

``point_to_point``: every axis moves centre → −40 % → +40 % → centre of its
stroke at 80 % of its velocity and acceleration limits, with 0.4 s of rest
after each move (overshoot and settling are measured there).
``path``: a closed 3-D path through the corners of a box like the paper's
Fig. 7; the axes move together on each edge, all arriving at once (the
slowest axis at 60 % of its limits sets the edge's duration).
"""

from __future__ import annotations

import math

import numpy as np

from ..config import Limits
from ..master.campaign import trapezoid

REST_S = 0.4
PTP_LEVEL, PATH_LEVEL = 0.8, 0.6
PTP_STOPS = (-0.4, 0.4, 0.0)  # fractions of the half stroke around the centre
PATH_CORNERS = ((-0.3, -0.3, 0.0), (0.3, -0.3, 0.3), (0.3, 0.3, 0.0), (-0.3, 0.3, 0.3), (-0.3, -0.3, 0.0))


def _centre_half(lim: Limits) -> tuple[float, float]:
    return 0.5 * (lim.position_min + lim.position_max), 0.5 * (lim.position_max - lim.position_min)


def point_to_point(
    limits: dict[str, Limits], period: float
) -> tuple[dict[str, np.ndarray], dict[str, list[tuple[int, float, float]]]]:
    """The point-to-point reference: every axis centre → −40 % → +40 % → centre at 80 % of its
    limits, 0.4 s of rest after each move.

    Parameters
    ----------
    limits : dict of str to Limits
        Per axis, its limits.
    period : float
        The SYNC period [s].

    Returns
    -------
    demand : dict of str to numpy.ndarray
        Per axis, its positions per period [rad].
    moves : dict of str to list of (int, float, float)
        Per axis, its moves as (row where the move's demand ends, start, target) [rad].
    """
    rest = round(REST_S / period)
    out, moves = {}, {}
    for a, lim in limits.items():
        c, h = _centre_half(lim)
        pos, pieces, n, marks = c, [np.full(rest, c)], rest, []
        for f in PTP_STOPS:
            target = c + f * h
            move = trapezoid(
                pos, target, PTP_LEVEL * lim.max_velocity, PTP_LEVEL * lim.max_acceleration, period
            )
            pieces += [move, np.full(rest, target)]
            n += len(move)
            marks.append((n, pos, target))
            pos = target
            n += rest
        out[a], moves[a] = np.concatenate(pieces), marks
    n = max(len(v) for v in out.values())
    return {a: np.concatenate([v, np.full(n - len(v), v[-1])]) for a, v in out.items()}, moves


def path(limits: dict[str, Limits], period: float) -> dict[str, np.ndarray]:
    """The path reference: a closed 3-D path through the corners of a box like the paper's Fig. 7,
    the axes together on each edge (the slowest at 60 % of its limits sets the edge's duration).

    Parameters
    ----------
    limits : dict of str to Limits
        Per axis, its limits.
    period : float
        The SYNC period [s].

    Returns
    -------
    dict of str to numpy.ndarray
        Per axis, its positions per period [rad].
    """
    axes = list(limits)
    corners = [
        [_centre_half(limits[a])[0] + f[i % 3] * _centre_half(limits[a])[1] for i, a in enumerate(axes)]
        for f in PATH_CORNERS
    ]
    rest = round(REST_S / period)
    cols = [[np.full(rest, corners[0][i])] for i in range(len(axes))]
    for p0, p1 in zip(corners, corners[1:]):
        # the slowest axis on this edge sets the duration; the others follow the same shape
        times = []
        for i, a in enumerate(axes):
            d = abs(p1[i] - p0[i])
            lim = limits[a]
            v, acc = PATH_LEVEL * lim.max_velocity, PATH_LEVEL * lim.max_acceleration
            v = min(v, math.sqrt(d * acc)) if d else v
            times.append(d / v + v / acc if d else 0.0)
        lead = int(np.argmax(times))
        per_stroke = 1.0 / max(abs(p1[lead] - p0[lead]), 1e-12)  # the lead axis's stroke: 1
        lead_limits = limits[axes[lead]]
        shape = trapezoid(
            0.0,
            1.0,
            per_stroke * (PATH_LEVEL * lead_limits.max_velocity),
            per_stroke * (PATH_LEVEL * lead_limits.max_acceleration),
            period,
        )
        for i in range(len(axes)):
            cols[i].append(p0[i] + (p1[i] - p0[i]) * shape)
            cols[i].append(np.full(rest // 2, p1[i]))
    return {a: np.concatenate(cols[i]) for i, a in enumerate(axes)}
