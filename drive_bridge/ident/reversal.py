"""Backlash and impacts at torque reversal, in what the rigid model leaves -- told from friction
at standstill, which gathers at the velocity's reversals instead.

Where a transmission has play, the torque it carries changing sign opens the gap: the motor
crosses it without the load and the load is struck when it closes.  The rigid model sees
neither; its residual gathers energy a short, fairly constant time after each reversal.  The
whole-band residual (:func:`~.signals.whole_band`) while moving is averaged over time bins
after each reversal of the torque the transmission carries — the inertial torque J·q̈
(friction on the motor side) or the model's whole torque (friction on the load side), each
smoothed at the fit's cut-off and counted when it swings past ``HYSTERESIS`` of its range.
Any abrupt change of acceleration leaves a transient in the residual too (the loops' lag), so
the reference is not the residual elsewhere but the same profile after control instants: the
same signal crossing ``CONTROL_LEVEL`` of its range without changing sign (an acceleration
starting or ending, as sharp as a reversal but with no gap to cross).  A swing that dwells at
zero (a trapezoid's cruise between its acceleration and its deceleration) is no reversal: the
load is carried by friction in between; nor is a loop's ringing after a short, sharp
acceleration step (it swings less than ``HYSTERESIS``) -- on a rigid axis moved by trapezoids
both read as play.  The largest ratio of
the reversal profile to the control profile over the bins is compared with the same statistic
for ``PERMUTATIONS`` random relabellings of reversals and controls (seeded): play is reported
only where the reversals beat every relabelling, stand ``MIN_RATIO`` above the controls and
the excess holds ``MIN_SHARE`` of the residual power.

Friction at standstill that the fitted samples do not reach (breakaway, Stribeck friction below
the speeds fitted, stick-slip) leaves its transient at each reversal of the *velocity*, not of
the transmitted torque; on a motion whose velocity reverses near an acceleration extreme it is
still found after acceleration reversals, a quarter period later.  So the velocity's reversals
are tested alike -- with two more conditions: the residual there acts against the motion
(friction: its mean times the direction of motion, over each reversal's bins, above zero by
``AGAINST_T`` standard errors; a step of the Coulomb column a sample early or late, as an averaged
torque makes, leaves a residual with the motion instead), and it does so on the way into each
reversal as on the way out (friction at low speed acts on both sides of a standstill; a mode the
reversal excites, or an impact, only follows it) -- and whichever reversal holds the larger
excess names the cause.  SI: s, the axis's torque unit.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import signal

from .signals import FILTER_ORDER, Samples, Settings

HYSTERESIS = 0.15  # a reversal swings from below -15 % to above +15 % of the signal's range (or back):
# a loop's ringing after a short, sharp acceleration step swings less
MIN_EVENTS = 20  # fewer reversals while moving: no telling
BINS = 8  # time bins after a reversal, over half the median time between reversals
LONGEST_S = 0.25  # ... and at most this long in all
CONTROL_LEVEL = 0.3  # control instants: crossings of ±30 % of the signal's range
PERMUTATIONS = 200  # relabellings of reversals and controls: the statistic's null distribution
MIN_RATIO = 1.5  # the peak bin's mean residual power after reversals over that after controls
MIN_SHARE = 0.05  # the share of the residual power in excess near the peak
STANDSTILL_SHARE = 0.1  # ... after the velocity's reversals: a rigid model fitted while moving leaves some
# there on any axis that sticks (0.06 on the simulated Y), Stribeck friction more
AGAINST_T = 5.0  # ... and acts against the motion by this many standard errors over the reversals


def reversals(
    x: np.ndarray, moving: np.ndarray, hysteresis: float = HYSTERESIS
) -> tuple[np.ndarray, np.ndarray]:
    """Where a signal reverses: crosses zero on its way from below -h to above +h or back.

    Parameters
    ----------
    x : numpy.ndarray
        The signal (an acceleration, a torque, a velocity).
    moving : numpy.ndarray
        Where the axis moves: reversals elsewhere are not kept.
    hysteresis : float
        h as a share of max |x|.

    Returns
    -------
    index : numpy.ndarray
        The samples where each reversal crosses zero.
    took : numpy.ndarray
        How many samples each swing took from one threshold to the other.
    """
    h = hysteresis * float(np.max(np.abs(x)))
    state = np.where(x > h, 1, np.where(x < -h, -1, 0))
    idx = np.flatnonzero(state)
    if len(idx) < 2:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    swings = idx[1:][state[idx[1:]] != state[idx[:-1]]]  # first sample past the far threshold
    prior = idx[:-1][state[idx[1:]] != state[idx[:-1]]]  # last sample past the near one
    ev = np.array([a + int(np.argmin(np.abs(x[a : b + 1]))) for a, b in zip(prior, swings)], dtype=int)
    took = (swings - prior).astype(int)
    keep = moving[ev] if len(ev) else np.zeros(0, dtype=bool)
    return ev[keep], took[keep]


def crossings(x: np.ndarray, level: float) -> np.ndarray:
    """Where a signal crosses a level.

    Parameters
    ----------
    x : numpy.ndarray
        The signal.
    level : float
        The level.

    Returns
    -------
    numpy.ndarray
        The indices just past each crossing, either way.
    """
    above = x > level
    return np.flatnonzero(above[1:] != above[:-1]) + 1


def _windows(
    power: np.ndarray, count: np.ndarray, ev: np.ndarray, width: int
) -> tuple[np.ndarray, np.ndarray]:
    """Sum of the residual power and the number of moving samples in each of BINS bins of
    ``width`` samples after each instant ``ev`` (events × BINS; cumulative sums)."""
    n = len(power) - 1
    starts = np.minimum(ev[:, None] + np.arange(BINS) * width, n)
    ends = np.minimum(starts + width, n)
    return power[ends] - power[starts], count[ends] - count[starts]


def _ratio(p: np.ndarray, c: np.ndarray, is_rev: np.ndarray) -> np.ndarray:
    """Per bin: mean residual power after the reversals over the mean after the controls."""
    rev = p[is_rev].sum(0) / np.maximum(c[is_rev].sum(0), 1)
    ctl = p[~is_rev].sum(0) / np.maximum(c[~is_rev].sum(0), 1)
    return rev / np.maximum(ctl, 1e-300)


def _against(resid: np.ndarray, s: Samples, ev: np.ndarray, width: int) -> float:
    """How many standard errors (over the instants ``ev``) the residual times the direction of motion,
    averaged over the moving samples of the ``width`` after each instant, stands above zero."""
    against = np.where(s.moving, resid * np.sign(s.qd), np.nan)
    means = [np.nanmean(against[e : e + width]) for e in ev[ev >= 0] if s.moving[e : e + width].any()]
    if len(means) < 2:
        return 0.0
    spread = float(np.std(means, ddof=1))
    return float(np.mean(means)) / spread * np.sqrt(len(means)) if spread > 0 else 0.0


def find_reversal_transient(
    s: Samples, resid: np.ndarray, predicted: np.ndarray, settings: Settings, seed: int = 0
) -> dict | None:
    """Residual energy concentrated after reversals beyond what equally sharp changes without
    reversal leave: which reversal (``acceleration``: the inertial torque, ``torque``: the
    model's -- backlash; ``velocity``: friction at standstill).

    Parameters
    ----------
    s : Samples
        The whole-band samples.
    resid : numpy.ndarray
        The residual at them [Nm | N].
    predicted : numpy.ndarray
        The model's torque at them [Nm | N].
    settings : Settings
        How the fitted samples were made (the cut-off the reversals are read at).
    seed : int
        Seed of the controls: equally sharp changes without reversal, drawn at random.

    Returns
    -------
    dict or None
        ``reversal``, the delay of the peak [ms] (``delay_ms``), its ``ratio`` to the controls,
        the ``share`` of the residual power in excess, the number of reversals (``events``); None
        when there is none.
    """
    m = s.moving
    power = np.concatenate(([0.0], np.cumsum(np.where(m, resid**2, 0.0))))
    count = np.concatenate(([0], np.cumsum(m)))
    if count[-1] == 0 or power[-1] <= 0:
        return None
    sos = signal.butter(FILTER_ORDER, settings.cutoff_hz, fs=settings.rate_hz, output="sos")
    rng = np.random.default_rng(seed)
    found: list[dict[str, Any]] = []
    for name, x in (("acceleration", s.qdd), ("torque", predicted), ("velocity", s.qd)):
        xf = signal.sosfiltfilt(sos, x)
        ev, took = reversals(xf, m if name != "velocity" else np.ones_like(m))  # (the velocity's: at rest)
        if len(ev) < MIN_EVENTS:
            continue
        gap = float(np.median(np.diff(ev)))
        width = max(1, int(min(gap / 2, LONGEST_S * settings.rate_hz) // BINS))
        ev = ev[took <= BINS * width]  # a swing that dwells at zero (a trapezoid's cruise) is two
        if len(ev) < MIN_EVENTS:  # steps with the load carried by friction between: no reversal
            continue
        level = CONTROL_LEVEL * float(np.max(np.abs(xf)))
        ctl = np.concatenate((crossings(xf, level), crossings(xf, -level)))
        near = np.searchsorted(ev, ctl)
        clear = (np.abs(ctl - ev[np.minimum(near, len(ev) - 1)]) > width) & (
            np.abs(ctl - ev[np.maximum(near - 1, 0)]) > width
        )  # (a reversal's impact in a control's
        # window only hides play, never fakes it)
        ctl = ctl[clear & m[ctl]]
        if len(ctl) < MIN_EVENTS:
            continue
        p, c = _windows(power, count, np.concatenate((ev, ctl)), width)
        is_rev = np.arange(len(p)) < len(ev)
        ratio = _ratio(p, c, is_rev)
        null = max(float(np.max(_ratio(p, c, rng.permutation(is_rev)))) for _ in range(PERMUTATIONS))
        k = int(np.argmax(ratio))
        ctl_level = p[~is_rev, k].sum() / max(c[~is_rev, k].sum(), 1)
        excess = (p[is_rev, k].sum() - ctl_level * c[is_rev, k].sum()) / power[-1]
        if name == "velocity" and (
            excess < STANDSTILL_SHARE
            or min(_against(resid, s, ev + side * BINS * width, BINS * width) for side in (-1, 0)) < AGAINST_T
        ):
            continue
        if ratio[k] > null and ratio[k] >= MIN_RATIO and excess >= MIN_SHARE:
            found.append(
                {
                    "reversal": name,
                    "delay_ms": round(1e3 * (k + 0.5) * width / settings.rate_hz, 1),
                    "ratio": round(float(ratio[k]), 2),
                    "share": round(float(excess), 3),
                    "events": int(len(ev)),
                }
            )
    return max(found, key=lambda d: d["share"]) if found else None
