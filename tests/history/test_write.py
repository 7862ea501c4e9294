"""``write`` keeps what it wrote: each drive's identity, every object with old and new value and
whether it read back, and whether it was stored; a dry run and a refused write keep nothing."""

from __future__ import annotations

import json

import pytest

from drive_bridge.cli import main
from drive_bridge.history import HistoryStore
from drive_bridge.paper import TABLE_II
from drive_bridge.tuning.design import design_gains

MOTOR = {"R": 0.8, "L": 0.002}


def tune_json(tmp_path, **override) -> str:
    p = TABLE_II["y"]
    values = {**design_gains(p["J"], p["c1"], **MOTOR).gains(), **p, **override}
    path = tmp_path / "tune.json"
    path.write_text(json.dumps({"axes": {"y": {"parameters": values, "motor": MOTOR}}}))
    return str(path)


def test_a_write_is_kept_with_the_drive_the_objects_and_the_store(db, tmp_path, capsys):
    params = tune_json(tmp_path)
    args = ["write", "--sim", "--params", params, "--backup-dir", str(tmp_path / "b"), "--db", db]
    assert main(args + ["--dry-run"]) == 0
    absurd = tmp_path / "absurd"
    absurd.mkdir()
    assert main(args + ["--params", tune_json(absurd, KpS=1e30)]) == 2  # refused before writing
    assert HistoryStore(db).runs() == []
    capsys.readouterr()
    assert main(args + ["--json"]) == 0
    out = capsys.readouterr()
    assert json.loads(out.out)["ok"] and "history: run " in out.err
    [run] = HistoryStore(db).runs()
    rec = HistoryStore(db).record(run["run_id"])
    assert rec["kind"] == "write" and rec["status"] == "ok" and rec["simulated"] is True
    [y] = rec["axes"]
    assert y["axis"] == "y" and y["drive"]["serial"] == "0x000003EA" and y["stored"] is True
    written = {w["parameter"]: w for w in y["written"]}
    assert written["J"]["new"] == pytest.approx(TABLE_II["y"]["J"]) and all(
        w["verified"] for w in y["written"]
    )
    assert main(args + ["--no-history"]) == 0
    assert len(HistoryStore(db).runs()) == 1
