"""Identification that stays honest on a joint it never saw: a rotary joint's gravity named as
gravity, an inertia no other term may take, and "cannot tell" where the data cannot tell -- on a
gravity-loaded joint of its own (tests/ident/generator.py: joint_log), not drive_bridge.sim."""
from __future__ import annotations

import json

import pytest

from drive_bridge.errors import UserError
from drive_bridge.ident.identify import identify
from drive_bridge.ident.report import as_json
from drive_bridge.sim.plantlog import write_log
from drive_bridge.tuning.tune import read_identify_json

from .generator import joint_log

J, G = 2.0, 60.0


def test_a_joints_gravity_is_named_and_leaves_the_inertia_to_j(tmp_path):
    """Two sines at 0.25 and 0.7 Hz around an arm 57° below horizontal: gravity comes out as one
    term (a·cos q + b·sin q) with its amplitude, J and gravity each within 3 std of the plant, and
    no term in the joint's own acceleration (before: an offset, a slope and a spline over
    position rebuilt the cosine, and no gravity was named)."""
    r = identify(write_log(tmp_path / "joint.csv", joint_log(J=J, gravity_Nm=G)))["j"]
    names = [t.effect.name for t in r.effects]
    assert "gravity" in names and not any("acceleration" in n for n in names), names
    p, sd = r.model.params_, r.model.param_std_
    assert abs(p["J"] - J) <= 3 * sd["J"] and sd["J"] < 0.1 * J
    assert abs(p["gravity.a_cos"] - G) <= 3 * sd["gravity.a_cos"] and abs(p["gravity.b_sin"]) <= 3 * sd["gravity.b_sin"]
    assert r.undetermined == {}


def test_a_motion_that_cannot_tell_inertia_from_gravity_says_so_and_tune_refuses_it(tmp_path):
    """One sine: the acceleration is proportional to the position's swing, and J·q̈ and the
    gravity's cosine are nearly one column. J is reported undetermined with what it cannot be told
    from -- in the CLI's text and identify.json -- and tune refuses the axis instead of designing
    on it (before: J printed as a number, the model used)."""
    r = identify(write_log(tmp_path / "one.csv", joint_log(J=J, gravity_Nm=G, sines=((0.8, 0.3),))))
    why = r["j"].undetermined.get("J", "")
    assert "collinear with gravity" in why, r["j"].undetermined
    doc = json.loads(as_json(r))
    assert doc["axes"]["j"]["identifiable"]["J"] is False and doc["axes"]["j"]["undetermined"]["J"] == why
    (tmp_path / "identify.json").write_text(json.dumps(doc))
    with pytest.raises(UserError, match="axis j: the identification could not determine J"):
        read_identify_json(tmp_path / "identify.json")
