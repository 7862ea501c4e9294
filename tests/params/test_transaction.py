"""The write transaction over two drives, failing in every phase in every way a real bus can:
the result never claims more than was read back, and a power cycle shows the stored set it names."""

from __future__ import annotations

import pytest

from drive_bridge.params.check import ValueRefused
from drive_bridge.params.write import write_all
from harness.write_faults import CASES, SIM, Fault, device, new_values

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("phase,kind", CASES, ids=[f"{p}-{k}" for p, k in CASES])
def test_every_phase_and_failure_ends_with_what_each_drive_holds_known(bench, tmp_path, phase, kind):
    b = bench()
    nodes = {a: b.nodes[a] for a in ("x", "y")}
    for node in nodes.values():
        node.sdo.RESPONSE_TIMEOUT = 0.05
    before = {a: device(n) for a, n in nodes.items()}
    values = {a: new_values(a) for a in nodes}
    fault = Fault(b.robot.drives["y"], phase, kind)
    b.robot.drives["y"].sdo_fault = fault
    results = write_all(nodes, SIM, values, backup_dir=tmp_path)
    b.robot.drives["y"].sdo_fault = None
    b.robot.drives["y"].online = True
    assert fault.fired and not any(r.ok for r in results.values())
    assert any(r.caused for r in results.values())
    if kind == "ctrl-c":
        assert all(r.interrupted == "Ctrl-C" for r in results.values())
    for a, r in results.items():
        assert r.ram in ("backup", "unchanged", "unknown") and r.stored_set in (
            "backup",
            "unchanged",
            "unknown",
            "new",
        )
        if r.ram in ("backup", "unchanged"):  # what it claims, it holds
            assert device(nodes[a]) == pytest.approx(before[a]), (a, r.ram, r.notes)
        else:
            assert r.notes, "an unknown state is explained"
        if phase == "backup":
            assert r.ram == "unchanged" and r.stored_set == "unchanged"
    for node in nodes.values():  # power cycle: the stored set it named
        node.nmt.send_command(0x81)
    b.link.clock.sleep(0.01)
    for a, r in results.items():
        if r.stored_set in ("unchanged", "backup"):
            assert device(nodes[a]) == pytest.approx(before[a]), (a, r.stored_set)
        elif r.stored_set == "new":
            assert device(nodes[a])["KpS"] == pytest.approx(values[a]["KpS"], rel=1e-6)


def test_a_store_refused_on_the_second_drive_stores_the_backup_again_on_the_first(bench):
    b = bench()
    nodes = {a: b.nodes[a] for a in ("x", "y")}
    before = {a: device(n) for a, n in nodes.items()}
    b.robot.drives["y"].abort_writes[(0x1010, 1)] = 0x08000020
    results = write_all(nodes, SIM, {a: new_values(a) for a in nodes})
    assert results["y"].caused and "store" in results["y"].error
    assert results["x"].ram == "backup" and results["x"].stored_set == "backup"
    assert any("stored again" in n for n in results["x"].notes)
    for node in nodes.values():
        node.nmt.send_command(0x81)
    b.link.clock.sleep(0.01)
    assert {a: device(n) for a, n in nodes.items()} == before


@pytest.mark.parametrize(
    "name,value,why",
    [
        ("KpS", 1e39, "not a finite number|overflows|outside"),
        ("ff_enable", float("nan"), "not a finite number"),
        ("J", 1e30, "outside the drive's range"),
        ("c1", -1.0, "must be ≥ 0"),
        ("KiS", float("inf"), "not a finite number"),
    ],
)
def test_a_value_the_drive_must_not_hold_is_refused_before_any_drive_is_written(bench, name, value, why):
    b = bench()
    nodes = {a: b.nodes[a] for a in ("x", "y")}
    before = {a: device(n) for a, n in nodes.items()}
    values = {"x": new_values("x"), "y": {**new_values("y"), name: value}}
    with pytest.raises(ValueRefused, match=why) as refused:
        write_all(nodes, SIM, values)
    assert "axis y" in str(refused.value) and name in str(refused.value)
    assert {a: device(n) for a, n in nodes.items()} == before  # not even x was touched


def test_write_json_says_what_a_store_made_permanent_beyond_the_backup(bench):
    """0x1010:1 stores every parameter: bring-up's PDO mapping and settings too, which a restore
    does not put back -- write.json says so instead of letting 'stored_set: backup' claim more."""
    from drive_bridge.params.write import write_parameters

    from .test_write import SIM, tuned_values

    b = bench()
    r = write_parameters(b.nodes["y"], SIM, tuned_values())
    assert r.ok and r.stored
    assert "PDO mapping" in r.store_scope and r.restore_covers.startswith("only the objects written")
    assert r.as_dict()["store_scope"] == r.store_scope and r.as_dict()["restore_covers"] == r.restore_covers


def test_a_failed_write_after_bring_up_leaves_the_stored_set_as_bring_up_found_it(bench, tmp_path):
    """0x1010:1 also stores bring-up's PDO mapping, heartbeat and limits. When the second drive's
    store fails, the first drive's backup is stored again with everything bring-up overwrote put
    back as bring-up found it (a power cycle shows the drive's own PDO mapping and settings), and
    bring-up's values are set again in RAM for the rest of the run; the backup file holds them."""
    import json

    from drive_bridge.cia.sdo import address, snapshot
    from drive_bridge.config import load_bus_config
    from drive_bridge.master.bringup import bring_up
    from harness.support import BUS_CONFIG

    b = bench()
    axes = bring_up(b.link, load_bus_config(BUS_CONFIG).only(["x", "y"]))
    node = axes["x"].node
    found = axes["x"].before
    keys = [address(k) for k in found]
    live = snapshot(node, "x", keys)
    changed = sorted(k for k in found if found[k] != live[k])
    assert {"0x1016:1", "0x607D:2", "0x1A00:1"} <= set(changed)  # heartbeat, limits, TPDO mapping
    b.robot.drives["y"].abort_writes[(0x1010, 1)] = 0x08000020
    results = write_all(
        {a: axes[a].node for a in ("x", "y")},
        SIM,
        {a: new_values(a) for a in ("x", "y")},
        backup_dir=tmp_path,
        settings_before={a: axes[a].before for a in ("x", "y")},
    )
    r = results["x"]
    assert (
        results["y"].caused
        and r.stored_set == "backup"
        and "as the drive held it when bring-up found it" in r.restore_covers
    )
    assert snapshot(node, "x", keys) == live  # RAM: bring-up's, as before
    assert json.loads((tmp_path / "x_backup.json").read_text())["settings_before_bring_up"] == found
    node.nmt.send_command(0x81)  # power cycle: the stored set
    b.link.clock.sleep(0.01)
    assert snapshot(node, "x", keys) == found
