"""Model-based gain design: margins with python-control."""

from __future__ import annotations

import pytest

from drive_bridge.paper import TABLE_III
from drive_bridge.params.cascade import GM_MIN_DB, PM_MIN_DEG, loop_margins
from drive_bridge.tuning.design import design_gains
from harness.support import PAPER

MOTOR = dict(R=0.8, L=0.002)


FACTORY = {"KpP": 150.0, "FwF": 1.0, "KpS": 0.12, "KiS": 20.0, "KpC": 12.566, "KiC": 400.0}


# ---------------------------------------------------------------- design
def test_design_meets_the_margins_where_the_factory_gains_do_not():
    for axis, p in PAPER.items():
        d = design_gains(p["J"], p["c1"], **MOTOR)
        assert d.velocity.ok() and d.position.ok(), (axis, d)
        assert d.velocity.phase_margin_deg >= PM_MIN_DEG and d.velocity.gain_margin_db >= GM_MIN_DB
        assert d.KiC == pytest.approx(MOTOR["R"] / MOTOR["L"]) and d.KpC == pytest.approx(
            MOTOR["L"] * 2 * 3.14159 * 1000, rel=1e-3
        )
    velocity, _ = loop_margins(PAPER["y"]["J"], PAPER["y"]["c1"], FACTORY, **MOTOR)
    assert velocity.gain_margin_db < GM_MIN_DB  # scenario 1: 6.6 dB
    scenario3 = {**FACTORY, **{k: v for k, v in TABLE_III["scenario 3"].items() if k in FACTORY}}
    assert (
        loop_margins(PAPER["y"]["J"], PAPER["y"]["c1"], scenario3, **MOTOR)[0].phase_margin_deg < 0
    )  # unstable


def test_effects_no_drive_parameter_carries_are_reported_not_dropped(tmp_path):
    """tune.json names, per axis, the traced effects that neither the drive's model objects nor the
    master's feed-forward can carry (Stribeck, a spline...), instead of dropping them silently."""
    import json

    from drive_bridge.tuning.tune import read_identify_json, unwritable_effects

    path = tmp_path / "identify.json"
    path.write_text(
        json.dumps(
            {
                "axes": {
                    "y": {
                        "params": {
                            "J": 1e-4,
                            "c0": 0.3,
                            "c1": 5e-4,
                            "offset.offset": 0.02,
                            "stribeck.amplitude": 0.05,
                            "stribeck.velocity": 10.0,
                            "spline_odd_position.b1": 0.01,
                            "spline_odd_position.form": "odd",
                        },
                        "effects": [
                            {"name": "offset"},
                            {"name": "stribeck"},
                            {"name": "spline_odd_position"},
                        ],
                    }
                }
            }
        )
    )
    assert unwritable_effects(path) == {"y": ["stribeck", "spline_odd_position"]}
    assert read_identify_json(path)["y"] == {"J": 1e-4, "c0": 0.3, "c1": 5e-4, "offset": 0.02}
