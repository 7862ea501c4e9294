"""What got worse after commissioning is named with its values and the reason the data give."""

from __future__ import annotations

from drive_bridge.commissioning.worse import worse


def _val(**kw) -> dict:
    v = {
        "fe_rms_before": 4e-3,
        "fe_rms_after": 1e-4,
        "fe_max_before": 2e-2,
        "fe_max_after": 1e-3,
        "overshoot_pct_before": 0.0,
        "overshoot_pct_after": 0.0,
        "settling_s_before": 0.0,
        "settling_s_after": 0.0,
        "torque_rmse_before": 0.022,
        "torque_rmse_after": 0.020,
        "torque_rmse_between_steps_before": 0.004,
        "torque_rmse_between_steps_after": 0.004,
        "torque_lag_cycles_after": 1,
    }
    return {**v, **kw}


def test_nothing_worse_says_nothing():
    assert worse({"validation": {"path": _val()}}) == []


def test_a_torque_error_at_the_steps_is_explained_and_one_between_them_is_not_excused():
    at_steps = worse({"validation": {"point_to_point": _val(torque_rmse_after=0.025)}})
    assert (
        len(at_steps) == 1
        and "22 → 25 mNm" in at_steps[0]
        and "between them the error is 4 → 4 mNm" in at_steps[0]
    )
    assert "the model is no worse" in at_steps[0]
    between = worse(
        {"validation": {"path": _val(torque_rmse_after=0.03, torque_rmse_between_steps_after=0.009)}}
    )
    assert "less well with the new gains" in between[0] and "no worse" not in between[0]


def test_following_error_overshoot_and_settling_that_rose_are_named():
    notes = worse(
        {
            "gains_before": {"KpP": 150.0},
            "gains_after": {"KpP": 349.0},
            "validation": {
                "point_to_point": _val(fe_max_after=0.03, overshoot_pct_after=0.5, settling_s_after=0.04)
            },
        }
    )
    assert any("largest following error 20 → 30 mrad" in n for n in notes)
    assert any("overshoot 0 → 0.5 %" in n and "KpP 150 → 349 1/s" in n for n in notes)
    assert any("settling into ±2 % 0 → 40 ms" in n for n in notes)
