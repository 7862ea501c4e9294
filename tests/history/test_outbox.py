"""A history in which no record blocks the others: a record the database cannot keep for what it
holds is set aside with the reason (``history sync`` names it, ``history rejected`` lists it) and
the records behind it are sent; an effect's parameter that is a name (a spline's ``variable``) is
kept as what it is; "unreachable" is said only of a database that is -- on SQLite and PostgreSQL."""

from __future__ import annotations

import json

import pytest

from drive_bridge.cli import main
from drive_bridge.history import HistoryStore
from drive_bridge.history.location import outbox_dir
from drive_bridge.history.outbox import keep
from harness.support import follows_schema

from .records import axis, day, nominal, record


def _waiting(doc: dict, db: str) -> None:
    """``doc`` in the outbox, for the database ``db``, as keep() leaves a record it could not send."""
    outbox_dir().mkdir(parents=True, exist_ok=True)
    shown = HistoryStore(db).where
    (outbox_dir() / f"{doc['run_id']}.json").write_text(json.dumps({"database": shown, "record": doc}))


def test_a_record_refused_for_its_content_is_set_aside_and_every_other_is_sent(db, capsys):
    spline = record(day(1), [axis("y", 0x11, nominal())])
    spline["axes"][0]["parameters"]["spline_even_position.variable"] = {
        "value": "position",  # what the effect depends on: a name, not a number
        "std": None,
        "unit": "",
        "determined": True,
    }
    broken = record(day(2), [axis("y", 0x12, nominal())])
    broken["axes"][0]["parameters"]["c0"]["std"] = "0.0016"  # a std that is not a number
    later = [record(day(3 + i), [axis("y", 0x13 + i, nominal())]) for i in range(3)]
    for doc in (spline, broken, *later):
        _waiting(doc, db)
    assert main(["history", "sync", "--db", db, "--json"]) == 2  # a record was not kept: said
    out = follows_schema(json.loads(capsys.readouterr().out), "history")
    assert sorted(out["sent"]) == sorted(d["run_id"] for d in (spline, *later))  # nothing waits behind it
    assert [r["run_id"] for r in out["rejected"]] == [broken["run_id"]] and out["failed"] is None
    assert "axis y: parameter c0: std '0.0016' is not a number" in out["rejected"][0]["reason"]
    assert not list(outbox_dir().glob("*.json"))
    # the spline's variable kept as what it is; the numbers compared as before
    store = HistoryStore(db)
    kept = store.record(spline["run_id"])
    assert kept["axes"][0]["parameters"]["spline_even_position.variable"]["value"] == "position"
    assert {p.name for p in store.parameters() if p.run_id == spline["run_id"]} == {"J", "c0", "c1"}
    assert main(["history", "rejected", "--json"]) == 0
    listed = follows_schema(json.loads(capsys.readouterr().out), "history")["rejected"]
    assert [r["run_id"] for r in listed] == [broken["run_id"]] and "not a number" in listed[0]["reason"]
    assert main(["history", "sync", "--db", db]) == 0  # nothing waits: nothing to say but that
    assert "0 record(s) sent" in capsys.readouterr().err


def test_a_refused_record_is_never_called_unreachable(db, capsys):
    """keep() of a record the database refuses: not "unreachable", the reason named, set aside."""
    broken = record(day(1), [axis("y", 0x21, nominal())])
    broken["axes"][0]["parameters"]["J"]["determined"] = "yes"
    kept = keep(broken, db)
    assert not kept.stored and kept.refused
    assert "unreachable" not in kept.line() and "determined 'yes'" in kept.line()
    assert "history rejected" in kept.line()
    assert kept.outbox is not None and kept.outbox.exists()
    assert keep(record(day(2), [axis("y", 0x22, nominal())]), db).stored  # the next one is kept


@pytest.mark.parametrize("db", ["sqlite"], indirect=True)
def test_an_unreachable_database_is_still_unreachable(db, tmp_path):
    gone = f"sqlite:///{tmp_path / 'no-such-folder' / 'h.sqlite'}"
    kept = keep(record(day(1), [axis("y", 0x31, nominal())]), gone)
    assert not kept.stored and not kept.refused and "unreachable" in kept.line()
