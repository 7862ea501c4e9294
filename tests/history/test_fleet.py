"""Acceptance: a simulated fleet. Four simulated machines of one type -- the simulated robot's X
(belt) and Y (ball screw) axes, their drives' serials differing -- each commissioned twice (the
quick campaign and identification: the steps that measure), machine B's Y friction rising between
its visits: ``history compare`` names that axis of that drive and no other, on SQLite and on
PostgreSQL; B's second commissioning report says so under "since last time"."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from drive_bridge.cli import main
from drive_bridge.history import HistoryStore
from drive_bridge.sim.robot_config import DEFAULT_CONFIG
from harness.support import BUS_CONFIG, EDS, follows_schema

pytestmark = pytest.mark.slow

#: machine -> the Y axis's Coulomb friction [Nm] at each visit (the plant's 0.323, and B's rising 30 %)
FLEET = {"A": (0.323, 0.323), "B": (0.323, 0.42), "C": (0.323, 0.323), "D": (0.323, 0.323)}
AXES = ("x", "y")
STEPS = "scan,bringup,campaign,identify"


def serials(robot: str) -> dict[str, int]:
    n = "ABCD".index(robot) + 1
    return {a: 10000 * n + i for i, a in enumerate(AXES, 1)}


def bus_config(tmp: Path) -> Path:
    """The shipped bus.yml without Z."""
    doc = yaml.safe_load(BUS_CONFIG.read_text())
    doc["defaults"]["dcf"] = str(EDS)
    doc["nodes"] = {a: doc["nodes"][a] for a in AXES}
    path = tmp / "bus.yml"
    path.write_text(yaml.safe_dump(doc))
    return path


def robot_config(tmp: Path, robot: str, visit: int, c0_y: float) -> Path:
    doc = yaml.safe_load(DEFAULT_CONFIG.read_text())
    doc["seed"] = 100 * "ABCD".index(robot) + visit  # each visit its own measurement noise
    doc["axes"] = {a: doc["axes"][a] for a in AXES}
    for a, serial in serials(robot).items():
        doc["axes"][a]["serial"] = serial
    doc["axes"]["y"]["plant"]["c0"] = c0_y
    path = tmp / f"robot_{robot}_{visit}.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    """Every robot's visits commissioned in turn, each kept in one SQLite history."""
    tmp = tmp_path_factory.mktemp("fleet")
    db = f"sqlite:///{tmp / 'fleet.sqlite'}"
    config = bus_config(tmp)
    runs = {}
    for visit in range(max(map(len, FLEET.values()))):
        for robot, c0 in FLEET.items():
            if visit < len(c0):
                out = tmp / f"{robot}{visit}"
                sim = robot_config(tmp, robot, visit, c0[visit])
                code = main(
                    [
                        "-q",
                        "commission",
                        "--config",
                        str(config),
                        "--sim",
                        "--sim-config",
                        str(sim),
                        "--quick",
                        "--steps",
                        STEPS,
                        "--out",
                        str(out),
                        "--db",
                        db,
                    ]
                    # the figures only where a test looks at them: B's second report
                    + ([] if (robot, visit) == ("B", 1) else ["--no-figures"])
                )
                assert code == 0
                runs[robot, visit] = out
    return db, runs


def test_every_commissioning_is_kept_once_with_its_drives(fleet, capsys):
    db, runs = fleet
    assert main(["history", "list", "--db", db, "--json"]) == 0
    listed = follows_schema(json.loads(capsys.readouterr().out), "history")["runs"]
    assert sorted(Path(r["out_dir"]) for r in listed) == sorted(p.resolve() for p in runs.values())
    assert [r["out_dir"] for r in listed] == [
        str(p.resolve()) for p in reversed(runs.values())
    ]  # newest first
    b1 = next(r for r in listed if r["out_dir"] == str(runs["B", 1].resolve()))
    assert b1["axes"] == [{"axis": a, "serial": f"0x{s:08X}"} for a, s in serials("B").items()]
    assert main(["history", "list", "--db", db, "--drive", str(serials("A")["y"])]) == 0
    assert capsys.readouterr().out.count(" commission ") == 2


def test_history_compare_names_the_rising_axis_of_that_drive_and_no_other(fleet, db, capsys):
    """The fleet's records kept in a fresh database of each kind; compared there."""
    source = HistoryStore(fleet[0])
    target = HistoryStore(db)
    for run in reversed(source.runs()):
        assert target.add(source.record(run["run_id"]))
    assert main(["history", "compare", "--db", db, "--json"]) == 0
    doc = follows_schema(json.loads(capsys.readouterr().out), "history")
    named = [c for c in doc["comparisons"] if c["named"]]
    assert {(c["serial"], c["axis"]) for c in named} == {(f"0x{serials('B')['y']:08X}", "y")}
    c0 = next(c for c in named if c["parameter"] == "c0")
    assert c0["changed"] and c0["stands_out"] and c0["siblings"] == 3
    assert c0["relative"] == pytest.approx(0.30, abs=0.04)
    assert c0["words"].startswith(f"serial {serials('B')['y']}, axis y: c0 +")
    assert main(["history", "compare", "--db", db, "--axis", "x"]) == 0
    assert capsys.readouterr().out.startswith("no drive changed beyond noise and the threshold")
    assert main(["history", "compare", "--db", db, "--drive", str(serials("B")["y"])]) == 0
    text = capsys.readouterr().out
    assert text.startswith("changed (") and f"serial {serials('B')['y']}, axis y: c0 +" in text


def test_the_second_commissioning_report_says_what_changed_since_last_time(fleet):
    _, runs = fleet
    summary = follows_schema(json.loads((runs["B", 1] / "summary.json").read_text()), "summary")
    history = summary["history"]
    assert history["kept"] and set(history["axes"]) == {"x", "y"}
    assert any(
        w.startswith(f"serial {serials('B')['y']}, axis y: c0 +") for w in history["axes"]["y"]["named"]
    )
    assert history["axes"]["x"]["named"] == []
    assert [p["value"] for p in history["axes"]["y"]["series"]["c0"]] == pytest.approx(
        [0.323, 0.42], rel=0.03
    )
    report = (runs["B", 1] / "report.md").read_text()
    assert report.count("## Since last time") == 2 and "**Changed:** serial 20002, axis y: c0 +" in report
    assert (runs["B", 1] / "figures" / "history_y.png").stat().st_size > 10_000
    first = json.loads((runs["A", 0] / "summary.json").read_text())["history"]
    assert first["kept"] and first["axes"] == {}  # a first commissioning, no siblings yet: no section
    assert "Since last time" not in (runs["A", 0] / "report.md").read_text()


def test_show_prints_a_run_in_full(fleet, capsys):
    db, runs = fleet
    run_id = json.loads((runs["B", 1] / "summary.json").read_text())["history"]["run_id"]
    assert main(["history", "show", run_id[:8], "--db", db]) == 0
    text = capsys.readouterr().out
    assert text.startswith(f"run {run_id}: commission ") and f"serial {serials('B')['y']}" in text
    assert "axis y (node 2, vendor 0x00000DB1 product 0x00000402" in text and "c0 " in text
    assert main(["history", "show", run_id, "--db", db, "--json"]) == 0
    rec = follows_schema(json.loads(capsys.readouterr().out), "history")["run"]
    assert [a["drive"]["serial"] for a in rec["axes"]] == [f"0x{s:08X}" for s in serials("B").values()]


def test_identify_keeps_its_identification_when_asked(fleet, tmp_path, capsys):
    db, runs = fleet
    args = [
        "identify",
        str(runs["B", 1] / "campaign"),
        "--axis",
        "y",
        "--db",
        f"sqlite:///{tmp_path / 'h.sqlite'}",
    ]
    assert main(args) == 0
    assert "history:" not in capsys.readouterr().err  # not asked: nothing kept
    assert main(args + ["--history"]) == 0
    assert "history: run " in capsys.readouterr().err
    [run] = HistoryStore(f"sqlite:///{tmp_path / 'h.sqlite'}").runs()
    rec = HistoryStore(f"sqlite:///{tmp_path / 'h.sqlite'}").record(run["run_id"])
    assert rec["kind"] == "identify" and [a["axis"] for a in rec["axes"]] == ["y"]
    assert rec["axes"][0]["drive"] is None  # a log does not say which drive it came from
    assert rec["axes"][0]["parameters"]["c0"]["value"] == pytest.approx(0.42, rel=0.03)
