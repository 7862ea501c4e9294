"""Backlash and impacts at torque reversal, in what the rigid model leaves.

Where a transmission has play, the torque it carries changing sign opens the gap: the motor
crosses it without the load and the load is struck when it closes.  The rigid model sees
neither; its residual gathers its energy a short, fairly constant time after each reversal.
So the whole-band residual (:func:`~.signals.whole_band`) while moving is averaged over time
bins after each reversal of the torque the transmission carries — the inertial torque J·q̈
(friction on the motor side) or the model's whole torque (friction on the load side), each
smoothed at the fit's cut-off and counted only when it swings past ``HYSTERESIS`` of its range
— and the bin with the most energy is compared with the same statistic after as many instants
drawn at random while moving (``SHIFTS`` draws, seeded): an effect is reported only where it
beats every shift, stands ``MIN_RATIO`` above the level elsewhere and holds ``MIN_SHARE`` of
the residual power.  SI: s, the axis's torque unit.
"""
from __future__ import annotations

import numpy as np
from scipy import signal

from .signals import FILTER_ORDER, Samples, Settings

HYSTERESIS = 0.05       # a reversal swings from below -5 % to above +5 % of the signal's range (or back)
MIN_EVENTS = 20         # fewer reversals while moving: no telling
BINS = 8                # time bins after a reversal, over half the median time between reversals
LONGEST_S = 0.25        # ... and at most this long in all
SHIFTS = 200            # draws of random instants while moving: the statistic's null distribution
MIN_RATIO = 1.5         # the peak bin's mean residual power over the mean while moving
MIN_SHARE = 0.05        # the share of the residual power in excess near the peak


def reversals(x: np.ndarray, moving: np.ndarray, hysteresis: float = HYSTERESIS) -> np.ndarray:
    """Indices where ``x`` crosses zero on its way from below -h to above +h or back
    (h = ``hysteresis`` × max |x|), kept where the axis moves."""
    h = hysteresis * float(np.max(np.abs(x)))
    state = np.where(x > h, 1, np.where(x < -h, -1, 0))
    idx = np.flatnonzero(state)
    if len(idx) < 2:
        return np.zeros(0, dtype=int)
    swings = idx[1:][state[idx[1:]] != state[idx[:-1]]]          # first sample past the far threshold
    prior = idx[:-1][state[idx[1:]] != state[idx[:-1]]]          # last sample past the near one
    ev = np.array([a + int(np.argmin(np.abs(x[a:b + 1]))) for a, b in zip(prior, swings)], dtype=int)
    return ev[moving[ev]] if len(ev) else ev


def _profile(power: np.ndarray, count: np.ndarray, ev: np.ndarray, width: int) -> np.ndarray:
    """Mean of ``power`` over the samples ``count`` marks in each of BINS bins of ``width``
    samples after the reversals ``ev`` (cumulative sums: O(events × bins))."""
    n = len(power) - 1
    starts = np.minimum(ev[:, None] + np.arange(BINS) * width, n)
    ends = np.minimum(starts + width, n)
    c = (count[ends] - count[starts]).sum(axis=0)
    return (power[ends] - power[starts]).sum(axis=0) / np.maximum(c, 1)


def find_backlash(s: Samples, resid: np.ndarray, predicted: np.ndarray, settings: Settings,
                  seed: int = 0) -> dict | None:
    """Residual energy concentrated after torque reversals: which reversal (``acceleration``: the
    inertial torque, ``torque``: the model's), the delay of the peak [ms], its ratio to the level
    elsewhere, the share of the residual power in excess, the number of reversals; None when
    there is none."""
    m = s.moving
    power = np.concatenate(([0.0], np.cumsum(np.where(m, resid ** 2, 0.0))))
    count = np.concatenate(([0], np.cumsum(m)))
    if count[-1] == 0 or power[-1] <= 0:
        return None
    level = power[-1] / count[-1]
    sos = signal.butter(FILTER_ORDER, settings.cutoff_hz, fs=settings.rate_hz, output="sos")
    rng = np.random.default_rng(seed)
    found = []
    for name, x in (("acceleration", s.qdd), ("torque", predicted)):
        ev = reversals(signal.sosfiltfilt(sos, x), m)
        if len(ev) < MIN_EVENTS:
            continue
        gap = float(np.median(np.diff(ev)))
        width = max(1, int(min(gap / 2, LONGEST_S * settings.rate_hz) // BINS))
        prof = _profile(power, count, ev, width) / level
        anywhere = np.flatnonzero(m)
        null = max(float(np.max(_profile(power, count, np.sort(rng.choice(anywhere, len(ev))), width))) / level
                   for _ in range(SHIFTS))
        k = int(np.argmax(prof))
        near = [b for b in (k - 1, k, k + 1) if 0 <= b < BINS and prof[b] > 1.0]
        excess = sum((prof[b] - 1.0) * width for b in near) * len(ev) / count[-1]
        if prof[k] > null and prof[k] >= MIN_RATIO and excess >= MIN_SHARE:
            found.append({"reversal": name, "delay_ms": round(1e3 * (k + 0.5) * width / settings.rate_hz, 1),
                          "ratio": round(float(prof[k]), 2), "share": round(float(excess), 3),
                          "events": int(len(ev))})
    return max(found, key=lambda d: d["share"]) if found else None
