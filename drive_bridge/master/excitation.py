"""The short campaign: one periodic multisine per axis, designed for the identification.

Per axis a sum of ``HARMONICS`` sines at harmonics of one fundamental (whole periods; the
fundamental traverses the stroke at ``TRAVERSE`` of the velocity limit, as the paper's moves do),
spread geometrically from the stroke-covering fundamental to ``REACH`` times the frequency where a
sine at the velocity limit reaches the acceleration limit (so both limits are used), faded in and
out over ``FADE_S`` (a quintic smoothstep) so that it starts and ends at rest at the centre of the stroke.  Its amplitudes
and phases are chosen by a seeded random search for the largest information about the model's
parameters -- D-optimality: log det(ΦᵀΦ/N) of the regressor Φ = [q̈, q̇, sign(q̇), 1, q] (J, c1,
c0, an offset, a position-proportional load) -- among signals that cover the stroke (the position
reaches ``COVERAGE`` of the half-range on both sides: cogging, gravity and springs along the whole
stroke) and cross zero velocity both ways.  Each candidate is scaled to the largest amplitude
the axis limits allow (position, velocity, acceleration and, where configured, jerk, each at
``MARGIN`` of its limit, from the sampled profile's own differences): designed inside the limits,
never clipped.  Units motor side SI: rad, rad/s, rad/s², rad/s³.
"""

from __future__ import annotations

import numpy as np

from ..config import Limits

HARMONICS = 10  # sines, geometrically spaced from the fundamental to REACH
REACH = 1.5  # x the frequency amax / vmax, where a sine at the velocity limit reaches the acceleration limit
TRAVERSE = 0.4  # the fundamental: a traverse of the stroke at this share of the velocity limit
FADE_S = 1.0
MARGIN = 0.9
COVERAGE = 0.9
CANDIDATES = 400


def _fade(n: int, fade: int) -> np.ndarray:
    """1 inside, rising from 0 over ``fade`` samples at the start and falling at the end as the
    quintic smoothstep (no step in velocity or acceleration at rest: a finite jerk)."""
    w = np.ones(n)
    if fade > 0:
        x = np.arange(fade) / fade
        ramp = x**3 * (10 - 15 * x + 6 * x**2)
        w[:fade], w[n - fade :] = ramp, ramp[::-1]
    return w


def _derivatives(shape: np.ndarray, period: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Velocity, acceleration and jerk as the plan check sees them: differences of the samples,
    with the rest before and after the excitation."""
    q = np.concatenate([np.zeros(3), shape, np.zeros(3)])
    return np.diff(q) / period, np.diff(q, 2) / period**2, np.diff(q, 3) / period**3


def _scale(shape: np.ndarray, lim: Limits, half: float, period: float) -> float:
    """The largest factor for ``shape`` (a deviation from the centre) inside every limit."""
    v, a, j = _derivatives(shape, period)
    bounds = [
        half / np.max(np.abs(shape)),
        MARGIN * lim.max_velocity / np.max(np.abs(v)),
        MARGIN * lim.max_acceleration / np.max(np.abs(a)),
    ]
    if lim.max_jerk is not None:
        bounds.append(MARGIN * lim.max_jerk / np.max(np.abs(j)))
    return float(min(bounds))


def _information(q: np.ndarray, period: float) -> float:
    """log det(ΦᵀΦ/N) of Φ = [q̈, q̇, sign(q̇), 1, q] along ``q``."""
    v = np.gradient(q, period)
    phi = np.column_stack((np.gradient(v, period), v, np.sign(v), np.ones_like(q), q))
    sign, logdet = np.linalg.slogdet(phi.T @ phi / len(q))
    return float(logdet) if sign > 0 else -np.inf


def design_axis(
    lim: Limits, duration_s: float, period: float, move_fraction: float, seed: int = 0
) -> np.ndarray:
    """Positions [rad] at t = period, 2·period, ... of ``duration_s``: the designed excitation,
    from and back to the centre of the stroke, at rest at both ends.

    Parameters
    ----------
    lim : Limits
        The axis's limits.
    duration_s : float
        How long [s].
    period : float
        The SYNC period [s].
    move_fraction : float
        The share of the stroke it moves over.
    seed : int
        Seed of the multisine's phases.

    Returns
    -------
    numpy.ndarray
        The positions [rad].

    Raises
    ------
    ValueError
        No multisine covers the stroke within these limits.
    """
    centre = 0.5 * (lim.position_min + lim.position_max)
    half = 0.5 * (lim.position_max - lim.position_min) * move_fraction
    n = int(round(duration_s / period))
    fade = int(round(min(FADE_S, duration_s / 6) / period))
    t = np.arange(1, n + 1) * period
    periods = max(1, int(n * period * TRAVERSE * lim.max_velocity / (4 * half)))
    w0 = 2 * np.pi * periods / (n * period)
    window = _fade(n, fade)
    top = max(HARMONICS, REACH * lim.max_acceleration / lim.max_velocity / w0)
    k = np.unique(np.round(np.geomspace(1, top, HARMONICS)))
    rng = np.random.default_rng(seed)
    arg = np.outer(t, k * w0)
    sines, cosines = window[:, None] * np.sin(arg), window[:, None] * np.cos(arg)
    best, best_info = None, -np.inf
    for _ in range(CANDIDATES):
        amp = rng.dirichlet(np.full(len(k), 0.5)) / k ** rng.uniform(0.5, 2.0)
        phase = rng.uniform(0, 2 * np.pi, len(k))
        shape = sines @ (amp * np.cos(phase)) + cosines @ (amp * np.sin(phase))  # Σ amp·sin(kω0t + φ)
        shape = shape * _scale(shape, lim, half, period)
        if min(shape.max(), -shape.min()) < COVERAGE * half:
            continue  # the stroke not covered both ways
        info = _information(centre + shape, period)
        if info > best_info:
            best, best_info = shape, info
    if best is None:
        raise ValueError("no multisine covers the stroke within these limits")
    return centre + best
