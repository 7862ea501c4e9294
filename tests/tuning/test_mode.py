"""A mode of the transmission in the design (tune.tune_axis): no drive profile names a filter object,
so a mode identification reports and no measured response covers keeps the velocity crossover at
most a third of its frequency, and says so; a peak where the drive's own loop rings with its gains
before is named as that loop, not capped; a measured response that covers the mode leaves it to
the margins measured on it."""

from __future__ import annotations

import pytest

from drive_bridge.tuning.tune import MODE_SHARE, tune_axis

MODEL = {"J": 1e-4, "c0": 0.3, "c1": 5e-4}
FACTORY = {"KpP": 150.0, "FwF": 1.0, "KpS": 0.12, "KiS": 20.0, "KpC": 12.566, "KiC": 400.0}


def test_an_identified_mode_caps_the_velocity_crossover():
    free = tune_axis("y", MODEL, 0.8, 0.002, {})
    assert free.mode is None and free.design.velocity.crossover_hz > 100
    capped = tune_axis(
        "y", MODEL, 0.8, 0.002, {}, resonance={"frequency_hz": 150.0, "damping": 0.02, "mains": False}
    )
    assert capped.mode["source"] == "identification" and capped.mode["filter"] is None
    assert capped.mode["crossover_cap_hz"] == pytest.approx(MODE_SHARE * 150.0)
    assert capped.design.velocity.crossover_hz <= MODE_SHARE * 150.0 * 1.01
    assert "no notch or low-pass filter object" in capped.mode["handling"]
    doc = capped.as_dict()
    assert doc["mode"] == capped.mode and doc["controller"]["structure"] == "cascade"


def test_mains_pickup_is_not_a_mode():
    t = tune_axis(
        "y", MODEL, 0.8, 0.002, {}, resonance={"frequency_hz": 50.0, "damping": 0.01, "mains": True}
    )
    assert t.mode is None


def test_a_peak_where_the_drives_own_loop_rings_is_that_loop():
    """The factory set at half the rate (1 kHz) amplifies 6 dB near 130 Hz on the rigid plant: a
    peak identified there is its ringing; the same peak at 30 Hz, where that loop does not ring,
    is a mode."""
    from drive_bridge.params.controller import Controller

    slow = Controller("cascade", {"position": 1000.0, "velocity": 1000.0, "current": 8000.0})
    before = {**FACTORY, "KpP": 75.0, "KpS": 0.06, "KiS": 10.0}
    ringing = tune_axis(
        "y",
        MODEL,
        0.8,
        0.002,
        before,
        controller=slow,
        resonance={"frequency_hz": 130.0, "damping": 0.05, "mains": False},
    )
    assert ringing.mode["crossover_cap_hz"] is None and "loop ringing" in ringing.mode["handling"]
    mode = tune_axis(
        "y",
        MODEL,
        0.8,
        0.002,
        before,
        controller=slow,
        resonance={"frequency_hz": 30.0, "damping": 0.05, "mains": False},
    )
    assert mode.mode["crossover_cap_hz"] == pytest.approx(10.0)
