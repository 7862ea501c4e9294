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
    """One sine of 0.15 rad, steady (the fade-in cut off): the acceleration is proportional to the
    swing, and so, nearly, is the gravity's cosine -- J·q̈ takes the gravity's slope and comes out
    -12 kg·m² with a std of 0.05. J is reported undetermined, naming the gravity it cannot be told
    from, in the CLI's text and identify.json, and tune refuses the axis instead of designing on
    it (before: the effects were dropped as unphysical and J printed as a number)."""
    cols = joint_log(J=J, gravity_Nm=G, sines=((0.15, 0.3),), duration_s=45.0, noise_Nm=1.0)
    steady = cols["time_s"] >= 5.0
    r = identify(write_log(tmp_path / "one.csv", {k: v[steady] for k, v in cols.items()}))
    why = r["j"].undetermined.get("J", "")
    assert "negative" in why and "collinear with a joint's gravity" in why, r["j"].undetermined
    doc = json.loads(as_json(r))
    assert doc["axes"]["j"]["identifiable"]["J"] is False and doc["axes"]["j"]["undetermined"]["J"] == why
    (tmp_path / "identify.json").write_text(json.dumps(doc))
    with pytest.raises(UserError, match="axis j: the identification could not determine J"):
        read_identify_json(tmp_path / "identify.json")


def test_a_clipped_torque_is_named_and_its_samples_left_out(tmp_path):
    """The logged torque saturates at 90 % of its peak (a logger's range; the drive's torque does
    not) on several percent of the rows: the level and share are said, those samples are not
    fitted, and J stays within 3 std (before: J 13 % low, 5.6 std, and four spurious effects)."""
    from drive_bridge.ident.report import summary
    clean = joint_log(J=J, gravity_Nm=G)
    clip = 0.9 * float(abs(clean["j_torque_Nm"]).max())
    r = identify(write_log(tmp_path / "clipped.csv", joint_log(J=J, gravity_Nm=G, clip_Nm=clip)))
    c = r["j"].sampling["torque_clipped"]
    assert c["levels"] == [round(clip, 3)] and c["share"] > 0.03
    assert "clipped at" in summary(r) and "were not fitted" in summary(r)
    p, sd = r["j"].model.params_, r["j"].model.param_std_
    assert abs(p["J"] - J) <= 3 * sd["J"] and [t.effect.name for t in r["j"].effects] == ["gravity"]


def test_a_torque_logged_with_the_opposite_sign_is_refused_with_the_way_out(tmp_path):
    """J, c0 and c1 all negative with a tiny std is no plant: the error says the sign conventions
    differ and names --torque-sign -1, which then gives the plant's values (before: negative
    values printed with a small std)."""
    from drive_bridge.cli import main
    path = write_log(tmp_path / "flipped.csv", joint_log(J=J, gravity_Nm=G, torque_sign=-1.0))
    with pytest.raises(UserError, match="opposite sign conventions.*--torque-sign -1"):
        identify(path)
    assert main(["identify", str(path), "--torque-sign", "-1", "--json"]) == 0
    r = identify(path, torque_sign=-1.0)["j"]
    assert abs(r.model.params_["J"] - J) <= 3 * r.model.param_std_["J"]


def test_two_ripples_at_different_periods_are_both_found(tmp_path):
    """A motor's torque ripple (6 per turn, 30 mNm) and a cogging (50 per turn, 20 mNm) on the
    independent closed-loop plant: both come out, each within 3 std of its amplitude and 1 % of
    its period, and nothing else is added (before: the cogging was averaged away by bins as wide
    as the fast passes' steps, and a spurious Stribeck term took its place)."""
    import numpy as np

    from .generator import closed_loop_log
    p1, p2 = 2 * np.pi / 6, 2 * np.pi / 50

    def ripples(q, v, a, t):
        return 0.03 * np.sin(2 * np.pi * q / p1) + 0.02 * np.sin(2 * np.pi * q / p2 + 0.5)
    r = identify(write_log(tmp_path / "ripples.csv", closed_loop_log(np.arange(30000) / 1000.0, extra=ripples)))["y"]
    assert sorted(t.effect.name for t in r.effects) == ["position_periodic", "position_periodic_2"]
    truth = {p1: 0.03, p2: 0.02}
    matched = {min(truth, key=lambda p: abs(t.params["period"] / p - 1)): t for t in r.effects}
    assert set(matched) == set(truth)
    for period, t in matched.items():
        assert abs(t.params["period"] / period - 1) < 0.01
        amplitude = f"{t.effect.name}.amplitude"
        assert abs(r.model.params_[amplitude] - truth[period]) <= 3 * r.model.param_std_[amplitude]


def test_friction_that_is_not_linear_in_velocity_says_over_which_speeds_c0_c1_hold(tmp_path):
    """A drag growing with the square of the speed on the independent plant: c0 and c1 come with
    the speeds they hold for, the slower and the faster half of the samples give them apart by
    more than 3 std, and their std is widened to cover half that difference (before: c0/c1 with
    a std that ignored how much the split depended on the speeds used)."""
    import numpy as np

    from .generator import closed_loop_log
    r = identify(write_log(tmp_path / "drag.csv", closed_loop_log(
        np.arange(30000) / 1000.0, extra=lambda q, v, a, t: 4e-6 * v * abs(v))))["y"]
    f = r.friction
    lo, hi = f["velocity_range"]
    assert 0 < lo < hi and not f["linear"] and f["sigmas"]
    for p in f["sigmas"]:
        assert r.model.param_std_[p] >= abs(f["slower"][p] - f["faster"][p]) / 2
    clean = identify(write_log(tmp_path / "clean.csv", closed_loop_log(np.arange(30000) / 1000.0)))["y"]
    assert clean.friction["linear"]


@pytest.mark.parametrize("acceleration", [1000.0, 5000.0])
def test_no_backlash_on_a_rigid_axis_moved_by_trapezoids(tmp_path, acceleration):
    """A rigid axis (no play) moved by trapezoids whose acceleration phases last 20 and 4 ms: no
    backlash is reported (before: at 4 ms it was -- the loop's ringing after each short step was
    taken for reversals of the transmitted torque; with other rests the filtered acceleration's
    swing across a cruise was too)."""
    from .generator import trapezoid_log
    r = identify(write_log(tmp_path / "trapezoids.csv", trapezoid_log(acceleration)))["y"]
    assert r.backlash is None, r.backlash
