"""Welch's power spectral density of a residual, every segment detrended and transformed at once.

``scipy.signal.welch`` (scipy 1.17) gives the same estimate, but through ``ShortTimeFFT``, which
detrends and transforms one segment at a time in Python: for the few hundred segments of an
identification's residual that loop, not the transforms, was most of its time.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy import fft, signal


def welch(x: np.ndarray, fs: float, nperseg: int) -> tuple[np.ndarray, np.ndarray]:
    """Welch's one-sided power spectral density of ``x``, as ``scipy.signal.welch(x, fs=fs,
    nperseg=nperseg)`` estimates it: Hann segments overlapping by half, each less its mean, the
    periodograms averaged.

    Parameters
    ----------
    x : numpy.ndarray
        The signal [unit], 1-D, at least ``nperseg`` samples.
    fs : float
        Its sample rate [Hz].
    nperseg : int
        The segment's length [samples].

    Returns
    -------
    f : numpy.ndarray
        The frequencies [Hz], 0 .. ``fs`` / 2.
    pxx : numpy.ndarray
        The power spectral density at them [unit² / Hz].

    Raises
    ------
    ValueError
        ``x`` is shorter than one segment.
    """
    f, pxx = csd(x, x, fs, nperseg)
    return f, pxx.real


def csd(x: np.ndarray, y: np.ndarray, fs: float, nperseg: int) -> tuple[np.ndarray, np.ndarray]:
    """The one-sided cross power spectral density of ``x`` and ``y``, as ``scipy.signal.csd(x, y,
    fs=fs, nperseg=nperseg)`` estimates it (as :func:`welch`: conj(X) Y averaged).

    Parameters
    ----------
    x, y : numpy.ndarray
        The signals [unit_x], [unit_y], 1-D, of one length, at least ``nperseg`` samples.
    fs : float
        Their sample rate [Hz].
    nperseg : int
        The segment's length [samples].

    Returns
    -------
    f : numpy.ndarray
        The frequencies [Hz], 0 .. ``fs`` / 2.
    pxy : numpy.ndarray
        The cross power spectral density at them [unit_x unit_y / Hz], complex.

    Raises
    ------
    ValueError
        The signals are shorter than one segment, or of different lengths.
    """
    if len(x) != len(y):
        raise ValueError(f"signals of different lengths ({len(x)} and {len(y)} samples)")
    if len(x) < nperseg:
        raise ValueError(f"{len(x)} samples are shorter than one segment of {nperseg}")
    window = signal.get_window("hann", nperseg)
    transform_x = _transforms(x, window)
    transform_y = transform_x if y is x else _transforms(y, window)
    pxy = (np.conj(transform_x) * transform_y).mean(axis=0) / (fs * float(np.sum(window * window)))
    pxy[1 : None if nperseg % 2 else -1] *= 2  # one-sided: the power of the negative frequencies
    return fft.rfftfreq(nperseg, 1 / fs), pxy


def _transforms(x: np.ndarray, window: np.ndarray) -> np.ndarray:
    """Each segment's transform (one a row): overlapping by half, less its mean, windowed."""
    nperseg = len(window)
    segments = sliding_window_view(np.asarray(x, dtype=float), nperseg)[:: nperseg - nperseg // 2]
    return fft.rfft((segments - segments.mean(axis=1, keepdims=True)) * window, axis=1)
