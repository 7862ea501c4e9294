"""Resonance in what the rigid model leaves: a lightly damped mode of a compliant transmission.

The model is fitted below the cut-off; a mode above it does not show in the fitted samples,
but it moves the torque the drive logs.  So the residual is looked at over the whole band of
the log: the fitted model predicts the torque from the log's samples with only a light
low-pass (0.4 × the sample rate), and the Welch spectrum of the residual while moving is
searched above the motion's band for a peak that stands well above its neighbourhood and holds
a real share of the residual power.  A mode rings at its own frequency whatever the speed; a
torque periodic in position (cogging, a belt's teeth) shows at speed / period.  So the peak must
stand at the same frequency in the slower and in the faster moving samples (speeds 15-55 % and
65-100 % of the top speed; without enough of both there is no telling, and no mode is reported):
at least ``PROMINENCE`` / 4 above its neighbourhood in each and ``PROMINENCE`` / 2 in one.  A mode
behind a stiff velocity loop is excited by the reversals more than at speed and stands out less
in the faster samples; a cogging at another speed's frequency does not stand out there at all.  Its
damping ratio is estimated from the half-power bandwidth, ζ ≈ (f₂ − f₁) / (2 f₀).  A peak at
the mains frequency or its double (50, 60, 100, 120 Hz ± 1 Hz) is named as likely electrical
pickup (``mains: true``), not as a mode.  SI: Hz.
"""

from __future__ import annotations

import numpy as np

from .signals import WIDE_BAND, Samples, Settings
from .spectra import welch

ABOVE_MOTION = 5.0  # a mode lies above this many motion bandwidths (below: the pace of the moves)
PROMINENCE = 8.0  # its peak stands this many times above the residual's median level around it
MIN_SHARE = 0.05  # ... and holds this share of the residual power (in its half-power band)
RESOLUTION_HZ = 0.25  # Welch frequency resolution aimed at
SAME_FREQUENCY = 0.1  # the slow and the fast group's peaks lie within this fraction of each other
SPEED_GROUPS = ((0.15, 0.55), (0.65, 1.01))  # slow and fast moving samples, × the top speed
MAINS_HZ = (50.0, 60.0, 100.0, 120.0)  # ± 1 Hz: electrical pickup rather than a mode


def find_mode(s: Samples, resid: np.ndarray, settings: Settings) -> dict | None:
    """The dominant resonance in the whole-band residual.

    Parameters
    ----------
    s : Samples
        The whole-band samples (:func:`~.signals.whole_band`).
    resid : numpy.ndarray
        The residual at them [Nm | N].
    settings : Settings
        How they were made (their rate).

    Returns
    -------
    dict or None
        ``frequency_hz``, ``damping`` (ratio), ``share`` of the residual power, prominence, and
        whether it is the mains frequency; None when there is none.
    """
    fs = settings.rate_hz
    r = resid[s.moving]
    speed = np.abs(s.qd) / max(float(np.max(np.abs(s.qd))), 1e-300)
    groups = tuple(s.moving & (speed >= lo) & (speed < hi) for lo, hi in SPEED_GROUPS)
    shortest = min(int(g.sum()) for g in groups)
    if shortest < 1024:
        return None
    nper = _segment(fs, shortest)
    f, pxx = _welch(r, fs, nper)
    band = (f > ABOVE_MOTION * settings.motion_bandwidth_hz) & (f < WIDE_BAND * fs)
    if band.sum() < 8:
        return None
    k = int(np.argmax(np.where(band, pxx, 0.0)))
    around = band & (np.abs(f - f[k]) < max(0.5 * f[k], 10 * (f[1] - f[0])))
    near = band & (np.abs(f - f[k]) <= SAME_FREQUENCY * f[k])
    stands = [
        ph[near].max() / np.median(ph[around])  # how it stands out in each speed group
        for _, ph in (_welch(resid[group], fs, nper) for group in groups)
    ]
    if min(stands) < PROMINENCE / 4 or max(stands) < PROMINENCE / 2:
        return None  # it moves with the speed: not a mode
    level = float(np.median(pxx[around]))
    prominence = float(pxx[k] / level) if level > 0 else np.inf
    half = pxx[k] / 2
    lo = k
    while lo > 0 and pxx[lo - 1] > half:
        lo -= 1
    hi = k
    while hi < len(f) - 1 and pxx[hi + 1] > half:
        hi += 1
    share = float(pxx[max(lo, 1) : hi + 1].sum() / pxx[1:].sum())
    if prominence < PROMINENCE or share < MIN_SHARE:
        return None
    width = max(f[min(hi + 1, len(f) - 1)] - f[max(lo - 1, 0)] - (f[1] - f[0]), f[1] - f[0])
    return {
        "frequency_hz": round(float(f[k]), 2),
        "damping": round(float(width / (2 * f[k])), 4),
        "share": round(share, 3),
        "prominence": round(prominence, 1),
        "mains": bool(any(abs(f[k] - m) <= 1.0 for m in MAINS_HZ)),
    }


def _segment(fs: float, n: int) -> int:
    """Welch segment length for about ``RESOLUTION_HZ``, at most a quarter of ``n`` samples."""
    nper = int(2 ** np.ceil(np.log2(fs / RESOLUTION_HZ)))
    while nper > 256 and nper > n // 4:
        nper //= 2
    return nper


def _welch(r: np.ndarray, fs: float, nper: int) -> tuple[np.ndarray, np.ndarray]:
    return welch(r - r.mean(), fs, nper)
