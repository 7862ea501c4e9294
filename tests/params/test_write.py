"""The transactional parameter write on the simulated drives, and each vendor profile against its own EDS."""

from __future__ import annotations

import itertools
import json
from contextlib import contextmanager

import can
import canopen
import pytest
import yaml

from drive_bridge.cli import main
from drive_bridge.params.check import ValueRefused
from drive_bridge.params.profile import PROFILE_DIR, available, load_profile
from drive_bridge.params.read import sdo_variable
from drive_bridge.params.write import write_drives, write_parameters
from drive_bridge.resources import vendor_dir
from drive_bridge.tuning.design import design_gains
from harness.support import PAPER

pytestmark = pytest.mark.slow


SIM = load_profile("drive_bridge_servo")


MOTOR = dict(R=0.8, L=0.002)


_channels = itertools.count(1)


def tuned_values(axis="y") -> dict[str, float]:
    p = PAPER[axis]
    return {**design_gains(p["J"], p["c1"], **MOTOR).gains(), **p, "ff_enable": 1.0}


def read_all(node, names):
    """Device values of ``names`` as the drive holds them now."""
    return {n: sdo_variable(node, SIM.entries[n]).raw for n in names if n in SIM.entries}


# ---------------------------------------------------------------- transactional write
def test_write_verifies_then_stores(bench):
    b = bench()
    node, drive = b.nodes["y"], b.robot.drives["y"]
    values = tuned_values()
    r = write_parameters(node, SIM, values)
    assert r.ok and r.stored and all(w.verified for w in r.objects)
    assert read_all(node, ["KpS", "c1", "ff_enable"]) == pytest.approx(
        {"KpS": values["KpS"], "c1": values["c1"], "ff_enable": 1}, rel=1e-6
    )
    node.nmt.send_command(0x81)  # reset node: the stored set comes back
    b.link.clock.sleep(0.01)
    assert read_all(node, ["KpS"])["KpS"] == pytest.approx(values["KpS"], rel=1e-6)
    assert drive.online


def test_an_sdo_abort_restores_the_backup_and_stores_nothing(bench, tmp_path):
    b = bench()
    node, drive = b.nodes["y"], b.robot.drives["y"]
    before = read_all(node, list(tuned_values()))
    drive.abort_writes[(0x2001, 4)] = 0x06090030  # c1 refused: value range exceeded
    r = write_parameters(node, SIM, tuned_values(), backup_path=tmp_path / "y.json")
    assert not r.ok and not r.stored and r.restored
    assert "c1" in r.error and "0x2001:4" in r.error and "0x06090030" in r.error
    assert "Value range of parameter exceeded" in r.error
    assert read_all(node, list(tuned_values())) == before  # nothing half-written
    backup = json.loads((tmp_path / "y.json").read_text())
    assert {o["parameter"]: o["device"] for o in backup["objects"]} == before
    node.nmt.send_command(0x81)  # no 'save' was issued
    b.link.clock.sleep(0.01)
    assert read_all(node, ["KpS"])["KpS"] == pytest.approx(0.12, rel=1e-6)


def test_a_drive_that_drops_off_mid_write_leaves_its_stored_set(bench):
    b = bench()
    node, drive = b.nodes["y"], b.robot.drives["y"]
    write = drive.write

    def unplug_after_J(index, sub, value):
        write(index, sub, value)
        if (index, sub) == (0x2001, 2):
            drive.online = False  # gone before it answers

    drive.write = unplug_after_J
    r = write_parameters(node, SIM, tuned_values())
    assert (
        not r.ok
        and not r.stored
        and "no answer" in r.error
        and "writing J" in r.error
        and "0x2001:2" in r.error
    )
    assert any("no store was sent" in n for n in r.notes)
    assert r.ram == "unknown" and r.stored_set == "unchanged"  # it could not be read back: never "restored"
    drive.online = True
    drive.write = write
    node.nmt.send_command(0x81)  # power cycle: the stored set is the old one
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
    assert (
        main(["write", "--sim", "--params", str(bad), "--backup-dir", str(tmp_path)]) == 2
    )  # refused, not tried
    err = capsys.readouterr().err
    assert "ff_enable" in err and "before anything was written" in err


@contextmanager
def vendor_node(profile):
    """A node whose object dictionary is the vendor's own EDS/DCF (read in place), served by a
    canopen LocalNode on a private virtual bus: (local node, remote node)."""
    channel = f"vendor-{next(_channels)}"
    server, client = (
        canopen.Network(can.Bus(interface="virtual", channel=channel)),
        canopen.Network(can.Bus(interface="virtual", channel=channel)),
    )
    for network in (server, client):
        network.NOTIFIER_CYCLE = 0.05  # (its disconnect waits out one: canopen's 1 s, each test)
        network.connect()
    try:
        local = canopen.LocalNode(7, profile.object_dictionary(7))
        for e in profile.entries.values():  # files without defaults: start at 1
            var = local.object_dictionary.get_variable(e.index, e.sub)
            if var.default is None:
                local.set_data(e.index, e.sub, var.encode_raw(1 if e.is_integer else 1.0))
        server.add_node(local)
        remote = canopen.RemoteNode(7, profile.object_dictionary(7))
        client.add_node(remote)
        yield local, remote
    finally:
        server.disconnect()
        client.disconnect()


VENDORS = [n for n in available() if n != "drive_bridge_servo"]
needs_vendor_files = pytest.mark.skipif(not vendor_dir().exists(), reason="../shared/eds-vendor not present")


@needs_vendor_files
@pytest.mark.parametrize("name", VENDORS)
def test_vendor_profile_writes_and_reads_back(name):
    profile = load_profile(name).bind(0.2)  # a drive holding gains in current: its motor's kt
    with vendor_node(profile) as (local, remote):
        values = tuned_values()
        held = profile.drive_values(values)  # what the drive's controller holds
        r = write_parameters(remote, profile, values)
        assert r.ok, r.error
        assert {w.parameter for w in r.objects} == set(profile.entries) & set(held)
        assert set(r.unsupported) == set(held) - set(profile.entries)  # e.g. J, c0, c1: reported, not dropped
        for w in r.objects:
            e = profile.entries[w.parameter]
            raw = local.object_dictionary.get_variable(e.index, e.sub).decode_raw(
                local.get_data(e.index, e.sub)
            )
            assert raw == pytest.approx(w.new_device, rel=1e-6) and w.verified
        assert r.stored == (profile.save is not None and bool(r.objects))  # nothing written: no store


#: the vendor profiles that map gain objects (the iPOS maps none)
WITH_GAINS = [n for n in VENDORS if yaml.safe_load((PROFILE_DIR / f"{n}.yaml").read_text())["parameters"]]


@needs_vendor_files
@pytest.mark.parametrize("name", WITH_GAINS)
def test_a_scale_without_a_documented_source_is_written_only_when_allowed(name):
    profile = load_profile(name)
    unverified = [k for k, e in profile.entries.items() if not e.verified]
    assert unverified, f"{name}: every scale has a source now: give this test a profile that has none"
    values = {"y": tuned_values()}
    with vendor_node(profile) as (local, remote):
        kt = {"y": 0.2}  # a drive holding gains in current: its motor's kt
        with pytest.raises(ValueRefused, match="no documented source"):
            write_drives({"y": remote}, profile, values, backup_dir=None, force=True, torque_constants=kt)
        dry = write_drives(
            {"y": remote}, profile, values, backup_dir=None, dry_run=True, force=True, torque_constants=kt
        )
        assert dry.ok and dry.unverified_scales and not any(w.written for w in dry.results["y"].objects)
        done = write_drives(
            {"y": remote},
            profile,
            values,
            backup_dir=None,
            force=True,
            allow_unverified_scales=True,
            torque_constants=kt,
        )
        held = profile.drive_values(values["y"])
        assert done.ok and {u.split(" ")[0] for u in done.unverified_scales} == set(unverified) & set(held)
        assert done.as_dict()["unverified_scales"] == done.unverified_scales


def test_the_project_drive_scales_have_their_source():
    assert all(e.verified for e in SIM.entries.values())
