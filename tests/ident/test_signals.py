"""The signals the regressor is made of: derivatives of the filtered position, the direction of
motion and the standstills an encoder shows, each against a signal built here with numpy."""

from __future__ import annotations

import numpy as np
import pytest

from drive_bridge.ident.signals import _delayed, count_step, derivative, direction, standing


@pytest.mark.parametrize("share", [0.02, 0.1, 0.2])
def test_derivative_is_exact_up_to_the_highest_cut_off(share):
    """A sine at up to 0.2 × the sample rate (the highest cut-off the fit uses): its derivative
    within 0.01 %, where a second-order central difference reads 24 % low at 0.2."""
    dt = 0.002
    t = np.arange(3000) * dt
    w = 2 * np.pi * share / dt
    d = derivative(np.sin(w * t), dt)[30:-30]
    assert np.max(np.abs(d - w * np.cos(w * t[30:-30]))) < 1e-4 * w


@pytest.mark.parametrize("share", [0.02, 0.1, 0.2])
@pytest.mark.parametrize("lag", [0.3, 0.5, 1.7])
def test_a_position_read_between_its_samples(share, lag):
    """A sine at up to 0.2 × the rate read ``lag`` samples earlier: within 1e-5 of its amplitude
    (a straight line between the samples reads it 1.2 % low at 0.05 ×, half a sample off), held
    at the ends."""
    k = np.arange(2000, dtype=float)
    x = np.sin(2 * np.pi * share * k)
    y = _delayed(x, lag)
    inner = slice(50, -50)
    assert np.max(np.abs(y[inner] - np.sin(2 * np.pi * share * (k[inner] - lag)))) < 1e-5
    assert y[0] == x[0]


def _encoder(q: np.ndarray, counts_per_rad: float = 10430.4) -> np.ndarray:
    return np.floor(q * counts_per_rad) / counts_per_rad


def test_an_encoder_standing_still_at_a_reversal_has_no_direction():
    """Forward, 40 samples stuck on one count, back: the direction is +1, then 0, then -1 -- not
    the filtered velocity's sign, which changes in the middle of the standstill."""
    t = np.arange(300) * 1e-3
    q = np.concatenate([np.linspace(0.0, 0.2, 130), np.full(40, 0.2), np.linspace(0.2, 0.0, 130)])
    q = _encoder(q + 1e-7)
    smeared = np.sign(0.2 - 0.5 * np.abs(t - 0.15) - 0.1)  # a sign that changes at t = 0.15 only
    d = direction(q, smeared)
    assert np.all(d[5:125] == 1) and np.all(d[135:165] == 0) and np.all(d[175:295] == -1)
    still = standing(q)
    assert still[135:165].all() and not still[:125].any() and not still[175:].any()


def test_a_position_that_is_no_encoders_keeps_the_filtered_direction():
    """A noisy (not quantised) position: nothing is standing, the direction is the filtered
    velocity's."""
    rng = np.random.default_rng(0)
    q = np.concatenate([np.linspace(0.0, 0.2, 100), np.full(40, 0.2)]) + 1e-6 * rng.standard_normal(140)
    qd = np.concatenate([np.ones(100), np.zeros(40)])
    assert np.array_equal(direction(q, qd), np.sign(qd))
    assert not standing(q).any()


def test_derivative_passes_nothing_above_0_3_of_the_rate():
    """What lies above the band a fit can use (an encoder's quantisation, 0.3-0.5 × the rate) is not
    lifted by ω² into the whole-band residual."""
    dt = 0.001
    t = np.arange(3000) * dt
    for share in (0.3, 0.4, 0.49):
        w = 2 * np.pi * share / dt
        assert np.max(np.abs(derivative(np.sin(w * t), dt)[30:-30])) < 1e-3 * w


def test_steps_below_the_floats_resolution_are_not_counts():
    """A position resampled through a spline where the axis stands at 0 moves by denormal steps
    (5e-324): no encoder count, and no quantisation noise to divide by (identify crashed with a
    ZeroDivisionError on such a log: a wall-clock record taken on its SYNC stamps)."""
    assert count_step(np.arange(1000) * 5e-324) is None
    assert count_step(np.round(np.cumsum(np.ones(1000)) * 0.25, 2)) == pytest.approx(0.25)
