"""Drift named as history compare measures a change: beyond 3 combined std and 10 % of the
reference, in two windows in a row, named once with the window it began in; back within the
noise said once; noise, however many windows, never named."""

from __future__ import annotations

import numpy as np

from drive_bridge.monitor.drift import AxisDrift, Reference, judge
from drive_bridge.monitor.window import Window

HOUR = 3600.0
START = 1.8e9


def window(k: int, c0: float, j: float = 1e-4, c1: float = 5e-4, std: float = 0.002) -> Window:
    values = {
        "J": {"value": j, "std": j * 0.01, "unit": "kg·m²", "determined": True},
        "c0": {"value": c0, "std": std, "unit": "Nm", "determined": True},
        "c1": {"value": c1, "std": c1 * 0.02, "unit": "Nm·s/rad", "determined": True},
    }
    return Window("x", START + k * HOUR, START + k * HOUR + 600, 600.0, values=values)


def reference() -> AxisDrift:
    return AxisDrift(Reference({"J": (1e-4, 1e-6), "c0": (0.30, 0.002), "c1": (5e-4, 1e-5)}, "commissioning"))


def test_noise_is_never_named():
    state = reference()
    rng = np.random.default_rng(1)
    for k in range(200):
        assert judge(state, window(k, 0.30 + rng.normal(0, 0.002)), "0x000003E9") == []


def test_one_odd_window_names_nothing_two_in_a_row_name_it_once_with_its_start():
    state = reference()
    assert judge(state, window(0, 0.30), None) == []
    assert judge(state, window(1, 0.36), None) == []  # +20 %, once
    assert judge(state, window(2, 0.30), None) == []  # back: nothing was named
    assert judge(state, window(3, 0.35), None) == []
    (named,) = judge(state, window(4, 0.36), "0x000003E9")
    assert named["event"] == "drift" and named["parameter"] == "c0" and named["axis"] == "x"
    assert named["since"].startswith("2027-01-15T11:00")  # window 3, where it began
    assert named["relative"] == (0.36 - 0.30) / 0.30 and named["sigmas"] > 20
    assert "serial 0x000003E9, axis x: c0 +20 %" in named["words"]
    assert "against the commissioning" in named["words"]
    assert judge(state, window(5, 0.37), None) == []  # named once, not every window
    (back,) = judge(state, window(6, 0.301), None)
    assert back["event"] == "back" and "back within the noise" in back["words"]


def test_significant_but_small_is_not_named():
    state = reference()
    for k in range(5):  # +5 %: many std, less than the 10 % a change must be
        assert judge(state, window(k, 0.315, std=0.0001), None) == []


def test_without_a_commissioning_the_first_window_is_the_reference():
    state = AxisDrift()
    assert judge(state, window(0, 0.30), None) == []
    assert state.reference is not None and state.reference.source.startswith("first monitored window")
    judge(state, window(1, 0.40), None)
    (named,) = judge(state, window(2, 0.40), None)
    assert named["reference"] == 0.30 and "drive of unknown serial" in named["words"]


def test_the_state_survives_a_restart():
    state = reference()
    judge(state, window(0, 0.36), None)
    again = AxisDrift.from_dict(state.as_dict())
    (named,) = judge(again, window(1, 0.36), None)
    assert named["since"].startswith("2027-01-15T08:00")
