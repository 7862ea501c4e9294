"""The residual's spectra estimate what scipy.signal's Welch estimates do, segment for segment."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from drive_bridge.ident.spectra import csd, welch


@pytest.mark.parametrize(("samples", "nperseg"), [(256, 256), (1000, 255), (5001, 512), (100_003, 256)])
def test_welch_and_csd_are_scipys_estimates(samples, nperseg):
    """A drifting, coloured signal and one that shares part of it: the same frequencies, and each
    bin within rounding of scipy's (one segment, odd and even segment lengths, a partial last
    segment left out as scipy leaves it)."""
    rng = np.random.default_rng(samples)
    x = signal.lfilter([1.0], [1.0, -0.9], rng.normal(size=samples)) + np.linspace(0.0, 3.0, samples)
    y = 0.5 * x + rng.normal(size=samples)
    f, pxx = welch(x, 500.0, nperseg)
    f_scipy, pxx_scipy = signal.welch(x, fs=500.0, nperseg=nperseg)
    assert np.array_equal(f, f_scipy) and pxx.dtype == pxx_scipy.dtype
    np.testing.assert_allclose(pxx, pxx_scipy, rtol=1e-10, atol=1e-13 * pxx_scipy.max())
    f, pxy = csd(x, y, 500.0, nperseg)
    f_scipy, pxy_scipy = signal.csd(x, y, fs=500.0, nperseg=nperseg)
    assert np.array_equal(f, f_scipy) and pxy.dtype == pxy_scipy.dtype
    np.testing.assert_allclose(pxy, pxy_scipy, rtol=1e-10, atol=1e-13 * np.abs(pxy_scipy).max())


def test_a_signal_shorter_than_a_segment_is_refused():
    with pytest.raises(ValueError, match="shorter than one segment"):
        welch(np.zeros(100), 500.0, 256)
    with pytest.raises(ValueError, match="different lengths"):
        csd(np.zeros(300), np.zeros(301), 500.0, 256)
