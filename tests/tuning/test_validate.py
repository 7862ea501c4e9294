"""Validation on the reference trajectories: the tuned set against Table III, ripple compensation."""

from __future__ import annotations

import pytest

from drive_bridge.config import load_bus_config
from drive_bridge.connect import open_link
from drive_bridge.master.bringup import bring_up
from drive_bridge.paper import TABLE_III
from drive_bridge.params.profile import load_profile
from drive_bridge.sim import kernel
from drive_bridge.tuning.design import design_gains
from drive_bridge.tuning.tune import model_from_identify
from drive_bridge.tuning.validate import validate
from harness.support import BUS_CONFIG, PAPER

from ..params.test_write import tuned_values

pytestmark = pytest.mark.slow


SIM = load_profile("drive_bridge_servo")


MOTOR = dict(R=0.8, L=0.002)


# ---------------------------------------------------------------- on the drive
def test_tuned_set_beats_table_iii_on_reference_trajectories():
    config = load_bus_config(BUS_CONFIG).only(["y"])
    model = {"y": dict(PAPER["y"])}
    scenarios = {
        "scenario 1": {"y": dict(TABLE_III["scenario 1"])},
        "scenario 3": {"y": dict(TABLE_III["scenario 3"])},
        "tuned": {"y": tuned_values()},
    }
    with open_link(config, sim=True, sim_config=None) as link:
        link.robot.config.axes["y"].effects = {}
        axes = bring_up(link, config)
        runs = validate(config, link, axes, SIM, scenarios, model)
    fe = {(r.scenario, r.trajectory): r.axes["y"].fe_rms for r in runs}
    assert all(r.aborted is None for r in runs)
    for traj in ("point_to_point", "path"):  # the target: 5x the best
        assert fe[("tuned", traj)] < min(fe[("scenario 1", traj)], fe[("scenario 3", traj)]) / 5, fe
    ptp = {r.scenario: r.axes["y"] for r in runs if r.trajectory == "point_to_point"}
    assert ptp["tuned"].overshoot_pct < 1.0 and ptp["tuned"].settling_s < 0.1
    assert ptp["tuned"].torque_rmse < 0.25 * ptp["tuned"].torque_rms  # the model predicts the torque


def test_ripple_compensation_from_the_traced_effect():
    """X's belt ripple (a hidden plant effect): the drive's position-periodic feed-forward, fed
    with identify's position_periodic terms, takes it out of the following error."""
    config = load_bus_config(BUS_CONFIG).only(["x"])
    with open_link(config, sim=True) as link:
        ripple = link.robot.config.axes["x"].effects["position_periodic"]
        traced = model_from_identify(
            {
                **PAPER["x"],
                "position_periodic.amplitude": ripple["PER_AMP"],
                "position_periodic.period": ripple["PER_PERIOD"],
                "position_periodic.phase": ripple["PER_PHASE"],
            }
        )
        base = {**design_gains(PAPER["x"]["J"], PAPER["x"]["c1"], **MOTOR).gains(), "ff_enable": 1.0}
        scenarios = {
            "J, c0, c1": {"x": {**base, **PAPER["x"], "periodic_period": 0.0}},
            "+ ripple": {"x": {**base, **traced}},
        }
        axes = bring_up(link, config)
        runs = validate(config, link, axes, SIM, scenarios, {"x": traced})
    fe = {(r.scenario, r.trajectory): r.axes["x"].fe_rms for r in runs}
    for traj in ("point_to_point", "path"):
        assert fe[("+ ripple", traj)] < fe[("J, c0, c1", traj)] / 3, fe


# ---------------------------------------------------------------- from the master
def test_master_feedforward_reaches_the_drives_own_on_the_same_trajectories():
    """The project's drive with its model feed-forward off, the master sending the model torque
    as torque offset 0x60B2 (less what the velocity loop holds when a move starts): within 1.5x
    the following error of the drive's own feed-forward, and far below the gains alone."""
    config = load_bus_config(BUS_CONFIG).only(["y"])
    model = {"y": dict(PAPER["y"])}
    tuned = tuned_values()
    gains_only = {k: v for k, v in tuned.items() if k not in model["y"]} | {"ff_enable": 0.0}
    scenarios = {"gains only": {"y": gains_only}, "drive": {"y": tuned}, "master": {"y": tuned}}
    with open_link(config, sim=True, sim_config=None) as link:
        link.robot.config.axes["y"].effects = {}
        axes = bring_up(link, config)
        runs = validate(config, link, axes, SIM, scenarios, model, master_feedforward={"master"})
        drive = link.robot.drives["y"]
    assert all(r.aborted is None for r in runs)
    how = {r.scenario: r.feedforward["y"] for r in runs}
    assert how["drive"] == "drive" and how["master"] == "master: torque offset 0x60B2"
    fe = {(r.scenario, r.trajectory): r.axes["y"].fe_rms for r in runs}
    for traj in ("point_to_point", "path"):
        assert fe[("master", traj)] <= 1.5 * fe[("drive", traj)], fe
        assert fe[("master", traj)] < fe[("gains only", traj)] / 4, fe
    assert drive.plant_param[kernel.FF_EN] == 0.0  # the last scenario ran with the drive's own model off


def test_master_feedforward_offsets_follow_the_interpolation_segment():
    """One setpoint opens one segment: the offset is the model at its middle (exact for a parabola)."""
    import numpy as np

    from drive_bridge.tuning.feedforward import MasterFeedForward

    T, acc = 0.002, 40.0
    t = np.arange(200) * T
    demand = 0.5 * acc * t**2
    torque, velocity = MasterFeedForward({"J": 1e-4, "c0": 0.3, "c1": 5e-4}, True, True).offsets(demand, T)
    v_mid = acc * (t[2:] - T / 2)
    np.testing.assert_allclose(velocity[2:], v_mid, rtol=1e-9)
    np.testing.assert_allclose(torque[2:], 1e-4 * acc + 5e-4 * v_mid + 0.3, rtol=1e-9)


def test_feedforward_route_follows_what_the_drive_has():
    """In the drive where the profile writes a model; from the master through the offsets the RPDOs
    map (velocity offset only without a drive velocity feed-forward); else none, saying why."""
    from types import SimpleNamespace as NS

    from drive_bridge.tuning.feedforward import MasterFeedForward, route

    model = {"J": 1e-4, "c0": 0.3, "c1": 5e-4}

    def axis(mapped, in_eds=(0x60B2,)):
        return NS(rpdos=[NS(objects=tuple(mapped))], cfg=NS(od=set(in_eds)))

    from drive_bridge.params.controller import Controller

    gains = NS(entries={"KpS": 1, "FwF": 1}, controller=Controller())
    no_fwf = NS(entries={"KpS": 1}, controller=Controller())
    assert route(axis([0x6040, 0x607A, 0x60B2]), SIM, model) == "drive"
    assert route(axis([0x6040, 0x607A, 0x60B2]), gains, model) == MasterFeedForward(model, True, False)
    assert route(axis([0x6040, 0x607A, 0x60B1]), no_fwf, model) == MasterFeedForward(model, False, True)
    assert route(axis([0x6040, 0x607A, 0x60B1]), gains, model).startswith(
        "none: the torque offset 0x60B2 is not"
    )
    assert route(axis([0x6040, 0x60C1], in_eds=()), gains, model).startswith("none: the drive has neither")
    assert route(axis([0x6040, 0x607A, 0x60B2]), gains, {}).startswith("none: no model")
