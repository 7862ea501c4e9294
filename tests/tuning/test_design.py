"""Model-based gain design: margins with python-control."""
from __future__ import annotations

import pytest

from drive_bridge.paper import TABLE_III
from drive_bridge.tuning.design import GM_MIN_DB, PM_MIN_DEG, design_gains, loop_margins

from ..support import PAPER


MOTOR = dict(R=0.8, L=0.002)


FACTORY = {"KpP": 150.0, "FwF": 1.0, "KpS": 0.12, "KiS": 20.0, "KpC": 12.566, "KiC": 400.0}


# ---------------------------------------------------------------- design
def test_design_meets_the_margins_where_the_factory_gains_do_not():
    for axis, p in PAPER.items():
        d = design_gains(p["J"], p["c1"], **MOTOR)
        assert d.velocity.ok() and d.position.ok(), (axis, d)
        assert d.velocity.phase_margin_deg >= PM_MIN_DEG and d.velocity.gain_margin_db >= GM_MIN_DB
        assert d.KiC == pytest.approx(MOTOR["R"] / MOTOR["L"]) and d.KpC == pytest.approx(MOTOR["L"] * 2 * 3.14159 * 1000, rel=1e-3)
    velocity, _ = loop_margins(PAPER["y"]["J"], PAPER["y"]["c1"], FACTORY, **MOTOR)
    assert velocity.gain_margin_db < GM_MIN_DB                       # scenario 1: 6.6 dB
    scenario3 = {**FACTORY, **{k: v for k, v in TABLE_III["scenario 3"].items() if k in FACTORY}}
    assert loop_margins(PAPER["y"]["J"], PAPER["y"]["c1"], scenario3, **MOTOR)[0].phase_margin_deg < 0  # unstable
