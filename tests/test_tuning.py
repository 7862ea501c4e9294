"""Tuning, parameter write and validation, on the virtual bus against the simulated drives."""
from __future__ import annotations

import itertools
import json

import can
import canopen
import pytest

from conftest import BUS_CONFIG, PAPER, clean_config
from drive_bridge.cli import main
from drive_bridge.connect import open_link
from drive_bridge.config import load_bus_config
from drive_bridge.master.bringup import bring_up
from drive_bridge.params.profile import available, load_profile, vendor_dir
from drive_bridge.params.write import write_parameters
from drive_bridge.paper import TABLE_III
from drive_bridge.tuning.tune import model_from_identify
from drive_bridge.tuning.design import GM_MIN_DB, PM_MIN_DEG, design_gains, loop_margins
from drive_bridge.tuning.experiment import run_experiment
from drive_bridge.tuning.validate import validate

SIM = load_profile("drive_bridge_servo")
MOTOR = dict(R=0.8, L=0.002)
FACTORY = {"KpP": 150.0, "FwF": 1.0, "KpS": 0.12, "KiS": 20.0, "KpC": 12.566, "KiC": 400.0}
_channels = itertools.count(1)


def tuned_values(axis="y") -> dict[str, float]:
    p = PAPER[axis]
    return {**design_gains(p["J"], p["c1"], **MOTOR).gains(), **p, "ff_enable": 1.0}


def read_all(node, names):
    r = write_parameters(node, SIM, dict.fromkeys(names, 1.0), dry_run=True)
    return {w.parameter: w.old_device for w in r.objects}


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


# ---------------------------------------------------------------- transactional write
def test_write_verifies_then_stores(bench):
    b = bench()
    node, drive = b.nodes["y"], b.robot.drives["y"]
    values = tuned_values()
    r = write_parameters(node, SIM, values)
    assert r.ok and r.stored and all(w.verified for w in r.objects)
    assert read_all(node, ["KpS", "c1", "ff_enable"]) == pytest.approx(
        {"KpS": values["KpS"], "c1": values["c1"], "ff_enable": 1}, rel=1e-6)
    node.nmt.send_command(0x81)                                      # reset node: the stored set comes back
    b.link.clock.sleep(0.01)
    assert read_all(node, ["KpS"])["KpS"] == pytest.approx(values["KpS"], rel=1e-6)
    assert drive.online


def test_an_sdo_abort_restores_the_backup_and_stores_nothing(bench, tmp_path):
    b = bench()
    node, drive = b.nodes["y"], b.robot.drives["y"]
    before = read_all(node, list(tuned_values()))
    drive.abort_writes[(0x2001, 4)] = 0x06090030                     # c1 refused: value range exceeded
    r = write_parameters(node, SIM, tuned_values(), backup_path=tmp_path / "y.json")
    assert not r.ok and not r.stored and r.restored
    assert "c1" in r.error and "0x2001:4" in r.error and "0x06090030" in r.error
    assert "Value range of parameter exceeded" in r.error
    assert read_all(node, list(tuned_values())) == before            # nothing half-written
    backup = json.loads((tmp_path / "y.json").read_text())
    assert {o["parameter"]: o["device"] for o in backup["objects"]} == before
    node.nmt.send_command(0x81)                                      # no 'save' was issued
    b.link.clock.sleep(0.01)
    assert read_all(node, ["KpS"])["KpS"] == pytest.approx(0.12, rel=1e-6)


def test_a_drive_that_drops_off_mid_write_leaves_its_stored_set(bench):
    b = bench()
    node, drive = b.nodes["y"], b.robot.drives["y"]
    write = drive._write

    def unplug_after_J(index, sub, value):
        write(index, sub, value)
        if (index, sub) == (0x2001, 2):
            drive.online = False                                     # gone before it answers
    drive._write = unplug_after_J
    r = write_parameters(node, SIM, tuned_values())
    assert not r.ok and not r.stored and "no answer" in r.error and "c0" in r.error and "0x2001:3" in r.error
    assert any("no store was issued" in n for n in r.notes)
    drive.online = True
    drive._write = write
    node.nmt.send_command(0x81)                                      # power cycle: the stored set is the old one
    b.link.clock.sleep(0.01)
    assert read_all(node, ["KpS", "J"]) == pytest.approx({"KpS": 0.12, "J": 0.0})


def test_dry_run_writes_nothing(bench):
    b = bench()
    node = b.nodes["y"]
    before = read_all(node, list(tuned_values()))
    r = write_parameters(node, SIM, tuned_values(), dry_run=True)
    assert r.ok and r.dry_run and not r.stored and not any(w.written for w in r.objects)
    assert {w.parameter: (w.old_si, w.new_si) for w in r.objects}["KpS"][0] == pytest.approx(0.12)
    assert read_all(node, list(tuned_values())) == before


def test_cli_write_dry_run_and_failure_exit_codes(tmp_path, capsys):
    params = tmp_path / "tune.json"
    params.write_text(json.dumps({"axes": {"y": {"parameters": tuned_values()}}}))
    assert main(["write", "--sim", "--params", str(params), "--dry-run", "--backup-dir", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "dry run, nothing written" in out and "KpS" in out and "Nm·s/rad" in out and "0.12 ->" in out
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"axes": {"y": {"parameters": {**tuned_values(), "ff_enable": 7.0}}}}))
    assert main(["write", "--sim", "--params", str(bad), "--backup-dir", str(tmp_path)]) == 3
    assert "ff_enable" in capsys.readouterr().err


@pytest.mark.skipif(not vendor_dir().exists(), reason="../shared/eds-vendor not present")
@pytest.mark.parametrize("name", [n for n in available() if n != "drive_bridge_servo"])
def test_vendor_profile_writes_and_reads_back(name):
    """A simulated node whose object dictionary is the vendor's own EDS/DCF, read in place."""
    profile = load_profile(name)
    channel = f"vendor-{next(_channels)}"
    server, client = canopen.Network(can.Bus(interface="virtual", channel=channel)), \
        canopen.Network(can.Bus(interface="virtual", channel=channel))
    server.connect()
    client.connect()
    try:
        local = canopen.LocalNode(7, profile.object_dictionary(7))
        for e in profile.entries.values():                        # files without defaults: start at 1
            var = profile.variable(local.object_dictionary, e)
            if var.default is None:
                local.set_data(e.index, e.sub, var.encode_raw(1 if e.is_integer else 1.0))
        server.add_node(local)
        remote = canopen.RemoteNode(7, profile.object_dictionary(7))
        client.add_node(remote)
        values = tuned_values()
        r = write_parameters(remote, profile, values)
        assert r.ok, r.error
        assert {w.parameter for w in r.objects} == set(profile.entries) - {"ff_enable"} & set(values) | \
            (set(profile.entries) & set(values))
        assert set(r.unsupported) == set(values) - set(profile.entries)   # e.g. J, c0, c1: reported, not dropped
        for w in r.objects:
            e = profile.entries[w.parameter]
            raw = profile.variable(local.object_dictionary, e).decode_raw(local.get_data(e.index, e.sub))
            assert raw == pytest.approx(w.new_device, rel=1e-6) and w.verified
        assert r.stored == (profile.save is not None)
    finally:
        server.disconnect()
        client.disconnect()


# ---------------------------------------------------------------- on the drive
def test_tuned_set_beats_table_iii_on_reference_trajectories():
    config = load_bus_config(BUS_CONFIG).only(["y"])
    model = {"y": dict(PAPER["y"])}
    scenarios = {"scenario 1": {"y": dict(TABLE_III["scenario 1"])},
                 "scenario 3": {"y": dict(TABLE_III["scenario 3"])},
                 "tuned": {"y": tuned_values()}}
    with open_link(config, sim=True, sim_config=None) as link:
        link.robot.config.axes["y"].effects = {}
        axes = bring_up(link, config)
        runs = validate(config, link, axes, SIM, scenarios, model)
    fe = {(r.scenario, r.trajectory): r.axes["y"].fe_rms for r in runs}
    assert all(r.aborted is None for r in runs)
    for traj in ("point_to_point", "path"):                          # the target: 5x the best
        assert fe[("tuned", traj)] < min(fe[("scenario 1", traj)], fe[("scenario 3", traj)]) / 5, fe
    ptp = {r.scenario: r.axes["y"] for r in runs if r.trajectory == "point_to_point"}
    assert ptp["tuned"].overshoot_pct < 1.0 and ptp["tuned"].settling_s < 0.1
    assert ptp["tuned"].torque_rmse < 0.25 * ptp["tuned"].torque_rms   # the model predicts the torque


def test_ripple_compensation_from_the_traced_effect():
    """X's belt ripple (a hidden plant effect): the drive's position-periodic feed-forward, fed
    with identify's position_periodic terms, takes it out of the following error."""
    config = load_bus_config(BUS_CONFIG).only(["x"])
    with open_link(config, sim=True) as link:
        ripple = link.robot.config.axes["x"].effects["position_periodic"]
        traced = model_from_identify({**PAPER["x"], "position_periodic.amplitude": ripple["PER_AMP"],
                                      "position_periodic.period": ripple["PER_PERIOD"],
                                      "position_periodic.phase": ripple["PER_PHASE"]})
        base = {**design_gains(PAPER["x"]["J"], PAPER["x"]["c1"], **MOTOR).gains(), "ff_enable": 1.0}
        scenarios = {"J, c0, c1": {"x": {**base, **PAPER["x"], "periodic_period": 0.0}},
                     "+ ripple": {"x": {**base, **traced}}}
        axes = bring_up(link, config)
        runs = validate(config, link, axes, SIM, scenarios, {"x": traced})
    fe = {(r.scenario, r.trajectory): r.axes["x"].fe_rms for r in runs}
    for traj in ("point_to_point", "path"):
        assert fe[("+ ripple", traj)] < fe[("J, c0, c1", traj)] / 3, fe


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
    assert design.KpS < result.KpS                                     # the design keeps its margins
