"""The CLI around a machine: absurd values refused before anything is written, signals and
faults that end in a quick stop with the data kept, damaged files that are said to be damaged."""

from __future__ import annotations

import json
import os
import signal

import pytest
import yaml

from drive_bridge.cli import main
from drive_bridge.interrupts import Terminated, deferred, handled
from drive_bridge.paper import TABLE_II, TABLE_III
from drive_bridge.tuning.design import design_gains
from harness.support import read_csv

pytestmark = pytest.mark.slow

MOTOR = {"R": 0.8, "L": 0.002}


def tune_json(tmp_path, **override) -> str:
    p = TABLE_II["y"]
    values = {**design_gains(p["J"], p["c1"], **MOTOR).gains(), **p, "ff_enable": 1.0, **override}
    path = tmp_path / "tune.json"
    path.write_text(json.dumps({"axes": {"y": {"parameters": values, "motor": MOTOR}}}))
    return str(path)


@pytest.mark.parametrize(
    "override,what",
    [
        ({"KpS": 1e30}, "KpS"),
        ({"J": 1e30}, "J"),
        ({"c0": -1.0}, "c0"),
        ({"periodic_period": 0.0, "periodic_amplitude": 0.03}, "periodic"),
        ({"KiS": 1e39}, "KiS"),
    ],
)
def test_absurd_parameters_are_refused_before_anything_is_written(tmp_path, capsys, override, what):
    assert (
        main(
            [
                "write",
                "--sim",
                "--params",
                tune_json(tmp_path, **override),
                "--backup-dir",
                str(tmp_path / "b"),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert what in err and "before anything was written" in err and "Traceback" not in err
    assert not (tmp_path / "b").exists()


def test_an_unknown_axis_in_tune_json_is_an_error(tmp_path, capsys):
    path = tmp_path / "tune.json"
    path.write_text(json.dumps({"axes": {"w": {"parameters": {"KpS": 0.1}}}}))
    assert main(["write", "--sim", "--params", str(path)]) == 2
    assert "axis 'w' is not in" in capsys.readouterr().err


def test_gains_below_the_margin_floor_need_force_which_is_recorded(tmp_path, capsys):
    unstable = {k: v for k, v in TABLE_III["scenario 3"].items() if k != "ff_enable"}  # PM < 0 on the plant
    params = tune_json(tmp_path, **unstable)
    assert main(["write", "--sim", "--params", params, "--backup-dir", str(tmp_path / "b")]) == 2
    assert "below the floor of 30° / 4 dB" in capsys.readouterr().err
    assert (
        main(["write", "--sim", "--params", params, "--backup-dir", str(tmp_path / "b"), "--force", "--json"])
        == 0
    )
    doc = json.loads(capsys.readouterr().out)
    assert doc["ok"] and doc["forced"] and "velocity loop PM" in doc["forced"][0]
    assert doc["margins"]["y"]["velocity"]["ok"] is False


def test_tune_refuses_a_model_that_is_not_physical(tmp_path, capsys):
    path = tmp_path / "identify.json"
    path.write_text(json.dumps({"axes": {"y": {"params": {"J": -1e-4, "c0": 0.3, "c1": 5e-4}}}}))
    assert (
        main(
            [
                "tune",
                "--ident",
                str(path),
                "--offline",
                "--motor-R",
                "0.8",
                "--motor-L",
                "0.002",
                "--out",
                str(tmp_path / "t.json"),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert "axis y" in err and "J = -0.0001" in err and not (tmp_path / "t.json").exists()


def test_sigterm_in_motion_is_a_quick_stop_with_the_data_kept(tmp_path, capsys, monkeypatch):
    """What a service manager or `timeout` sends, in the middle of a campaign: sent once the
    campaign has streamed a second of motion (its progress hook), whatever the machine's load (a
    timer's 2 s fell into bring-up beside two CPU-bound loops: exit 130, nothing moving yet)."""
    from drive_bridge.progress import CampaignProgress

    out = tmp_path / "rec"
    shown = CampaignProgress.__call__
    sent = []

    def progress(self, k):
        if k >= 500 and not sent:
            sent.append(k)
            os.kill(os.getpid(), signal.SIGTERM)
        shown(self, k)

    monkeypatch.setattr(CampaignProgress, "__call__", progress)
    code = main(["record", "--sim", "--axes", "y,z", "--together", "--out", str(out)])
    assert sent and code == 4
    err = capsys.readouterr().err
    assert "interrupted by SIGTERM" in err and "Traceback" not in err
    meta = yaml.safe_load((out / "meta.yaml").read_text())
    assert meta["status"] == "aborted" and "SIGTERM" in meta["abort"]["reason"]
    names, data = read_csv(out / "log.csv")
    assert 0 < len(data) == meta["counts"]["cycles_sent"] < meta["counts"]["cycles_planned"]


def test_signals_are_held_while_a_restore_must_finish():
    with handled():
        with pytest.raises(Terminated) as stop:
            with deferred():
                os.kill(os.getpid(), signal.SIGTERM)
                held = "still running"  # the block is not cut short
        assert held == "still running" and stop.value.name == "SIGTERM"


def test_a_recording_that_never_ended_is_not_taken_for_a_log(tmp_path, capsys):
    (tmp_path / "meta.yaml").write_text("status: running\n")
    (tmp_path / "log.csv").write_text("time_s,y_position_rad,y_torque_Nm\n0,0,0\n")
    assert main(["identify", str(tmp_path)]) == 2
    assert "never ended" in capsys.readouterr().err


def test_a_cut_short_trace_decodes_what_it_holds_and_says_so(tmp_path, capsys):
    out = tmp_path / "rec"
    assert main(["record", "--sim", "--quick", "--axes", "y", "--out", str(out)]) == 0
    trace = (out / "trace.blf").read_bytes()
    (out / "trace.blf").write_bytes(trace[: len(trace) // 2])
    capsys.readouterr()
    assert main(["decode", str(out / "trace.blf"), "--out", str(tmp_path / "part.csv")]) == 2
    err = capsys.readouterr().err
    assert ("damaged" in err or "cut short" in err) and "rows before it are in" in err
    names, data = read_csv(tmp_path / "part.csv")
    assert 0 < len(data) < len(read_csv(out / "log.csv")[1])


def test_a_fault_during_validate_stops_everything_and_resets_nothing(tmp_path, capsys):
    sim = tmp_path / "sim.yaml"
    sim.write_text(
        "seed: 1\naxes:\n  y: {node_id: 2, serial: 2, plant: {J: 0.0001, c0: 0.323, c1: 0.0005},\n"
        "      effects: {load: {torque_Nm: 6.0}}}\n"
    )
    out = tmp_path / "val"
    code = main(
        [
            "validate",
            "--sim",
            "--sim-config",
            str(sim),
            "--params",
            tune_json(tmp_path),
            "--config",
            str(_only_y(tmp_path)),
            "--out",
            str(out),
        ]
    )
    err = capsys.readouterr().err
    assert code == 4 and "motion stopped" in err and "Traceback" not in err
    runs = json.loads((out / "validate.json").read_text())["runs"]
    assert len(runs) == 1 and runs[0]["aborted"]  # nothing moved again after the fault


def _only_y(tmp_path):
    from harness.support import bus_yml_beside

    cfg = bus_yml_beside(tmp_path)
    doc = yaml.safe_load(cfg.read_text())
    doc["nodes"] = {"y": doc["nodes"]["y"]}
    cfg.write_text(yaml.safe_dump(doc))
    return cfg


MOVING = [
    ["record"],
    ["commission"],
    ["validate", "--params", "TUNE"],
    ["tune", "--ident", "IDENT", "--experiment"],
    ["jog", "y", "--by", "0.01"],
]


def _moving_argv(tmp_path, command):
    ident = tmp_path / "identify.json"
    ident.write_text(json.dumps({"axes": {"y": {"params": dict(TABLE_II["y"])}}}))
    out = {"record": "out", "commission": "out", "tune": "t.json", "validate": "val"}.get(command[0])
    return [{"TUNE": tune_json(tmp_path), "IDENT": str(ident)}.get(c, c) for c in command] + (
        ["--out", str(tmp_path / out)] if out else []
    )


@pytest.mark.parametrize("command", MOVING)
def test_every_moving_command_has_a_dry_run_that_plans_and_moves_nothing(tmp_path, capsys, command):
    """--dry-run: the plan of every motion the command would run, from where the axes stand,
    checked against the limits; then it stops (no log, no tune or validate result written)."""
    assert (
        main(_moving_argv(tmp_path, command) + ["--sim", "--dry-run", "--config", str(_only_y(tmp_path))])
        == 0
    )
    out = capsys.readouterr().out
    assert "y: from " in out and "peaks" in out and "(limits" in out and "bus load" in out
    assert out.rstrip().endswith(
        "dry run: nothing was written that changes a drive's behaviour, nothing moved"
    )
    assert not [
        p
        for p in ("out/log.csv", "out/summary.json", "t.json", "val/validate.json")
        if (tmp_path / p).exists()
    ]


@pytest.mark.parametrize("command", MOVING)
def test_a_real_bus_moves_only_when_a_person_confirms(tmp_path, capsys, monkeypatch, command):
    """Without a terminal and without --yes, every command that moves a real machine is refused
    before anything is written (nothing on the bus: the configured channel stays silent); at a
    terminal, only 'yes' goes on."""
    import can

    channel = f"real-{command[0]}"
    listener = can.Bus(interface="virtual", channel=channel)
    argv = _moving_argv(tmp_path, command) + ["-i", "virtual", "-c", channel]
    try:
        assert main(argv) == 2
        assert "--yes" in capsys.readouterr().err
        assert listener.recv(0.05) is None  # not one frame
        monkeypatch.setattr("sys.stdin.isatty", lambda: True)
        monkeypatch.setattr("builtins.input", lambda prompt: "no")
        assert main(argv) == 3 and "no answer from" in capsys.readouterr().err  # (no drive on this bus)
        frames = []  # the question comes with the plan, read first
        while (msg := listener.recv(0.05)) is not None:
            frames.append(msg)
        assert frames and all(
            0x601 <= m.arbitration_id <= 0x67F and m.data[0] == 0x40 for m in frames
        )  # reads
    finally:
        listener.shutdown()


def test_validate_refuses_an_unstable_scenario_unless_forced(tmp_path, capsys):
    """Every gain set validate writes passes write's gate on the identified model: the paper's
    scenario 3 (a phase margin below zero on this plant) is refused by default, naming the margin;
    --force runs it."""
    args = [
        "validate",
        "--sim",
        "--params",
        tune_json(tmp_path),
        "--config",
        str(_only_y(tmp_path)),
        "--json",
    ]
    assert main(args + ["--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    assert "scenario 3 refused: axis y: velocity loop PM" in err and "--force" in err
    doc = json.loads((tmp_path / "a" / "validate.json").read_text())
    assert "scenario 3" in doc["refused"] and "scenario 3" not in {r["scenario"] for r in doc["runs"]}
    assert {"scenario 1", "tuned + model feed-forward"} <= {r["scenario"] for r in doc["runs"]}
    code = main(args + ["--out", str(tmp_path / "b"), "--force"])
    doc = json.loads((tmp_path / "b" / "validate.json").read_text())
    assert "scenario 3" in {r["scenario"] for r in doc["runs"]} and doc["refused"] == {}
    assert code in (0, 4)  # forced onto the drive, an unstable loop may end in a stop


def test_jog_moves_one_axis_slowly_inside_its_stroke_and_holds_it(tmp_path, capsys):
    """jog: Z up from the end stop it rests on, at 10 % of its limits, and held there powered; a
    jog past the stroke is refused before anything moves; --dry-run moves nothing."""
    assert main(["jog", "z", "--sim", "--to", "0.05"]) == 0
    out, err = capsys.readouterr()
    assert "z at 0.05 m" in out and "axis z: powered, holding its position" in out
    assert "peaks 0.023 m/s, 0.46 m/s²" in err  # 10 % of 0.23 m/s and (ramped) 5 m/s²
    assert main(["jog", "z", "--sim", "--by", "0.3"]) == 2
    assert "outside the stroke" in capsys.readouterr().err
    assert main(["jog", "y", "--sim", "--by", "0.01", "--dry-run"]) == 0
    assert (
        "dry run: nothing was written that changes a drive's behaviour, nothing moved"
        in capsys.readouterr().out
    )
    assert main(["jog", "y", "--sim", "--by", "0.01", "--speed", "5"]) == 2  # above the axis's 0.23 m/s
