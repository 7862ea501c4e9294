"""The short campaign (``campaign: {design: short}``, ``--campaign short``): a multisine per axis
designed for the identification, inside every limit before anything moves, and what it
identifies on the simulated robot."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import yaml

from drive_bridge.cli import main
from drive_bridge.config import load_bus_config
from drive_bridge.errors import UserError
from drive_bridge.ident import identify
from drive_bridge.master.campaign import build_plan, resume_plan
from drive_bridge.resources import DEFAULT_BUS_CONFIG
from harness.support import PAPER, bus_yml_beside, quick_config

pytestmark = pytest.mark.slow

PERIOD = 0.002


def _limits(jerk_share: float | None = None):
    cfg = load_bus_config(DEFAULT_BUS_CONFIG)
    limits = {a: n.limits for a, n in cfg.nodes.items()}
    if jerk_share is not None:  # a jerk limit: this share of amax² / vmax (a sine at the corner)
        limits = {
            a: replace(lim, max_jerk=jerk_share * lim.max_acceleration**2 / lim.max_velocity)
            for a, lim in limits.items()
        }
    return cfg, limits


@pytest.mark.parametrize("jerk_share", [None, 1.0], ids=["no jerk limit", "jerk limit"])
def test_the_short_campaign_stays_inside_every_limit(jerk_share):
    cfg, limits = _limits(jerk_share)
    start = {"x": 1.0, "y": -20.0, "z": 5.0}
    plan = build_plan(replace(cfg.campaign, design="short"), limits, start, PERIOD)
    again = build_plan(replace(cfg.campaign, design="short"), limits, start, PERIOD)
    assert np.array_equal(plan.demand, again.demand)  # designed from a seed: the same plan
    for i, a in enumerate(plan.axes):
        lim, q = limits[a], plan.demand[:, i]
        moving = [s for s in plan.segments if a in s.axes]
        assert sum(s.end - s.start for s in moving) * PERIOD <= cfg.campaign.short_time_s + 1e-9
        v, acc, jerk = (np.abs(np.diff(q, k)) / PERIOD**k for k in (1, 2, 3))
        assert lim.position_min <= q.min() and q.max() <= lim.position_max
        assert v.max() <= lim.max_velocity and acc.max() <= lim.max_acceleration
        if lim.max_jerk is not None:
            assert jerk.max() <= lim.max_jerk
        assert acc.max() > 0.2 * lim.max_acceleration and v.max() > 0.5 * lim.max_velocity  # it excites
        half = 0.5 * (lim.position_max - lim.position_min) * cfg.campaign.move_fraction
        centre = 0.5 * (lim.position_max + lim.position_min)
        assert q.max() - centre > 0.85 * half and centre - q.min() > 0.85 * half  # the whole stroke
        assert q[0] == pytest.approx(start[a], abs=1e-3) and q[-1] == pytest.approx(start[a])  # from and back


@pytest.mark.parametrize("design", ["short", "paper"])
def test_a_segment_resumed_from_where_the_axes_stopped_is_the_plans_rest_after_an_approach(design):
    """A segment streamed again (its FIFO ran dry mid-way): an approach inside the limits from where
    each axis stands to where the plan stands at rest at the segment's start (or the row before its
    first move, where the segment begins a row into it), then the plan's rows from there,
    unchanged, with the segments in the resumed plan's rows; for every segment of the plan."""
    cfg, limits = _limits()
    start = {"x": 1.0, "y": -20.0, "z": 5.0}
    plan = build_plan(replace(cfg.campaign, design=design), limits, start, PERIOD)
    for segment in plan.segments[1:]:
        here = {
            a: float(plan.demand[(segment.start + segment.end) // 2, i]) + 0.1
            for i, a in enumerate(plan.axes)
        }
        resumed, approach, begin = resume_plan(plan, segment, here)  # (inside the limits, or it raises)
        assert begin <= segment.start and np.array_equal(plan.demand[begin], plan.demand[begin - 1])
        assert approach > 0 and resumed.segments[0].kind == "approach" and resumed.segments[0].end == approach
        assert np.allclose(resumed.demand[0], [here[a] for a in plan.axes], atol=1e-6)
        assert np.array_equal(resumed.demand[approach:], plan.demand[begin:])
        assert [(s.kind, s.end - s.start) for s in resumed.segments[1:]] == [
            (s.kind, s.end - (begin if s is segment else s.start))
            for s in plan.segments[plan.segments.index(segment) :]
        ]
        for i, a in enumerate(plan.axes):
            q = resumed.demand[: approach + 3, i]  # the approach, and the plan's first move from rest
            v, acc = (np.abs(np.diff(q, k)) / PERIOD**k for k in (1, 2))
            assert v.max() <= limits[a].max_velocity and acc.max() <= limits[a].max_acceleration * (1 + 1e-9)
    segment = plan.segments[len(plan.segments) // 2]
    rest = resume_plan(plan, segment, here)[2]  # standing where it resumes: no approach
    same, none, begin = resume_plan(
        plan, segment, {a: float(plan.demand[rest, i]) for i, a in enumerate(plan.axes)}
    )
    assert none == 0 and begin == rest and np.array_equal(same.demand, plan.demand[begin:])


def test_the_quick_campaign_resumed_at_a_segment_that_begins_in_its_move_stays_inside_the_limits():
    """The quick campaign's z: two of its levels begin a row into their first move (7.5 rad/s at
    their second row); streamed again, the approach ends where that move starts from rest, not at
    the moving row (3770 rad/s² there against z's 3142: the repeat was refused, exit 2)."""
    config = quick_config().only(["z"])
    limits = {"z": config.nodes["z"].limits}
    plan = build_plan(config.campaign, limits, {"z": -75.0}, PERIOD)
    moving = [s for s in plan.segments[1:] if plan.demand[s.start, 0] != plan.demand[s.start - 1, 0]]
    assert moving, "the quick campaign no longer has a segment that begins in its move"
    for segment in moving:
        here = {"z": float(plan.demand[segment.start, 0]) + 0.5}
        resumed, approach, begin = resume_plan(plan, segment, here)
        assert begin < segment.start and np.array_equal(resumed.demand[approach:], plan.demand[begin:])


def test_limits_no_multisine_can_cover_the_stroke_in_are_a_clear_refusal():
    cfg, limits = _limits()
    slow = {a: replace(lim, max_velocity=lim.max_velocity / 50) for a, lim in limits.items()}
    with pytest.raises(UserError, match=r"axis x: no multisine covers the stroke.*short_time_s more time"):
        build_plan(
            replace(cfg.campaign, design="short", short_time_s=10), slow, dict.fromkeys(slow, 0.0), PERIOD
        )


def test_a_jerk_limit_refuses_the_papers_trapezoids_before_anything_moves():
    cfg, limits = _limits(1.0)
    with pytest.raises(UserError, match="jerk.*campaign design: short keeps the jerk limit"):
        build_plan(cfg.campaign, limits, dict.fromkeys(limits, 0.0), PERIOD)


def test_the_design_is_a_bus_yml_key_and_a_command_option(tmp_path, capsys):
    bad = bus_yml_beside(tmp_path, "design: paper", "design: shortest")
    assert main(["record", "--sim", "--config", str(bad), "--out", str(tmp_path / "o")]) == 2
    assert "campaign.design" in capsys.readouterr().err and not (tmp_path / "o" / "log.csv").exists()
    with pytest.raises(SystemExit):
        main(["record", "--sim", "--campaign", "shortest", "--out", str(tmp_path / "o")])


def test_the_short_campaign_finds_what_the_full_one_finds(tmp_path):
    """On the shipped simulated robot, 30 s of motion per axis: every effect the full paper
    campaign finds (X belt ripple; Y offset, position-proportional load, direction asymmetry;
    Z gravity), J within 2 %, c0 within 1 % and Y, Z's c1 within 5 % of the plant's."""
    assert main(["record", "--sim", "--campaign", "short", "--out", str(tmp_path)]) == 0
    meta = yaml.safe_load((tmp_path / "meta.yaml").read_text())
    assert meta["campaign"]["design"] == "short"
    results = identify(tmp_path / "log.csv")
    found = {a: [t.effect.name for t in r.effects] for a, r in results.items()}
    assert found == {
        "x": ["position_periodic"],
        "y": ["offset", "position_linear", "direction_asymmetry"],
        "z": ["offset"],
    }
    for a, r in results.items():
        p = r.model.params_
        assert p["J"] == pytest.approx(PAPER[a]["J"], rel=0.02) and p["c0"] == pytest.approx(
            PAPER[a]["c0"], rel=0.01
        )
        if a != "x":  # the slow belt axis: 8 rad/s at most, c1·q̇ below the noise
            assert p["c1"] == pytest.approx(PAPER[a]["c1"], rel=0.05)


@pytest.mark.parametrize("design", ["paper", "short"])
def test_the_move_to_the_start_ramps_its_acceleration_from_wherever_the_axis_stands(design):
    """Without a jerk limit too: no acceleration step when motion starts (the Z axis rests on its end stop)."""
    from drive_bridge.master.campaign import APPROACH_LEVEL, APPROACH_RAMP_S

    cfg, limits = _limits()
    start = {a: lim.position_min for a, lim in limits.items()}
    plan = build_plan(
        replace(cfg.campaign.quick(), design=design, short_time_s=30.0, move_fraction=0.3),
        limits,
        start,
        PERIOD,
    )
    for seg in (s for s in plan.segments if s.kind in ("approach", "return")):
        for ax in seg.axes:
            i = plan.axes.index(ax)
            before = plan.demand[seg.start - 1, i] if seg.start else start[ax]  # at rest before it
            p = np.concatenate([np.full(3, before), plan.demand[seg.start : seg.end, i]])
            jerk = np.abs(np.diff(p, 3)) / PERIOD**3
            bound = APPROACH_LEVEL * limits[ax].max_acceleration / APPROACH_RAMP_S
            assert jerk.max() <= 1.05 * bound, (ax, seg.kind, jerk.max() / bound)
