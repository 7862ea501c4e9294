"""The paper's gain-raising procedure on the simulated drive."""

from __future__ import annotations

import pytest

from drive_bridge.config import load_bus_config
from drive_bridge.connect import open_link
from drive_bridge.master.bringup import bring_up
from drive_bridge.params.profile import load_profile
from drive_bridge.tuning.design import design_gains
from drive_bridge.tuning.experiment import run_experiment
from harness.support import BUS_CONFIG, PAPER

pytestmark = pytest.mark.slow


SIM = load_profile("drive_bridge_servo")


MOTOR = dict(R=0.8, L=0.002)


def test_paper_procedure_finds_the_stability_edge_and_restores_the_drive():
    config = load_bus_config(BUS_CONFIG).only(["y"])
    with open_link(config, sim=True) as link:
        axes = bring_up(link, config)
        window = axes["y"].node.sdo[0x6065].raw
        result = run_experiment(config, link, axes, "y", SIM, 0.12)
        assert axes["y"].node.sdo[0x6065].raw == window
        assert axes["y"].node.sdo[0x2000][3].raw == pytest.approx(0.12)
    # the sampled loop (2 kHz, hold + backward-difference velocity) of an inertia J is stable for
    # KpS < 2·J/T; the current loop's lag brings the edge below that
    assert result.KpS is not None and 0.2 < result.KpS < 2 * PAPER["y"]["J"] / 0.5e-3
    assert any(s.oscillating for s in result.steps) and not result.steps[-1].oscillating
    design = design_gains(PAPER["y"]["J"], PAPER["y"]["c1"], **MOTOR)
    assert design.KpS < result.KpS  # the design keeps its margins


def test_every_gain_the_experiment_tries_passes_the_gain_gate():
    """With the gate write uses (margins on the identified model), the raising ends before the
    first gain below the floor, which never reaches the drive; a refused first gain ends the
    experiment before anything is written."""
    from drive_bridge.params.check import ValueRefused, screen

    config = load_bus_config(BUS_CONFIG).only(["y"])
    model = {k: PAPER["y"][k] for k in ("J", "c0", "c1")}
    before = {"KpP": 150.0, "KpS": 0.12, "KiS": 20.0, "KpC": 12.566}

    def admit(kps):
        return screen(
            {"y": SIM},
            {"y": {**model, **before, "KpS": kps}},
            {"y": MOTOR["L"]},
            allow_unverified_scales=True,
        )[1]

    with open_link(config, sim=True) as link:
        axes = bring_up(link, config)
        result = run_experiment(config, link, axes, "y", SIM, 0.12, admit)
        assert result.gated and "velocity loop PM" in result.gated and "below the floor" in result.gated
        assert all(admit(s.KpS) is None for s in result.steps)
        assert admit(result.steps[-1].KpS * 1.5) is not None and result.KpS == result.steps[-1].KpS
        with pytest.raises(ValueRefused, match="before anything was written"):
            run_experiment(config, link, axes, "y", SIM, 0.5, admit)
        assert axes["y"].node.sdo[0x2000][3].raw == pytest.approx(0.12)
