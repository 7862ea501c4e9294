"""The history database on SQLite and on a real PostgreSQL server: schema by Alembic, records kept
once by run id, a later record of the same run replacing the earlier, lists and reads."""

from __future__ import annotations

import pytest
import sqlalchemy as sa

from drive_bridge.errors import UserError
from drive_bridge.history import HistoryStore, HistoryUnavailable
from drive_bridge.history.store import MIGRATIONS

from .records import axis, day, nominal, record


def count(store: HistoryStore, table: str) -> int:
    with store.engine.connect() as conn:
        return conn.execute(sa.text(f"SELECT count(*) FROM {table}")).scalar()


def test_the_schema_is_alembics_head_revision(db):
    from alembic.config import Config
    from alembic.script import ScriptDirectory

    cfg = Config()
    cfg.set_main_option("script_location", str(MIGRATIONS))
    store = HistoryStore(db)
    assert store.revision() == ScriptDirectory.from_config(cfg).get_current_head() == "0001"
    assert set(sa.inspect(store.engine).get_table_names()) == {
        "alembic_version",
        "runs",
        "axes",
        "parameters",
    }
    assert HistoryStore(db).revision() == "0001"  # opened again: nothing to migrate


def test_a_database_of_a_newer_drive_bridge_is_refused_not_written(db):
    store = HistoryStore(db)
    with store.engine.begin() as conn:
        conn.execute(sa.text("UPDATE alembic_version SET version_num = '0099'"))
    with pytest.raises(HistoryUnavailable, match="revision 0099 is newer .* upgrade drive-bridge"):
        HistoryStore(db)


def test_a_record_is_kept_once_and_a_later_one_of_the_same_run_replaces_it(db):
    store = HistoryStore(db)
    first = record(day(0), [axis("y", 1002, nominal())], run_id="a" * 32)
    assert store.add(first) is True
    assert store.add(first) is False  # a retry: nothing duplicated
    assert (count(store, "runs"), count(store, "axes"), count(store, "parameters")) == (1, 1, 3)
    resumed = record(
        day(0), [axis("y", 1002, nominal(1.2)), axis("z", 1003, nominal())], run_id="a" * 32, updated=day(0.1)
    )
    assert store.add(resumed) is True
    assert store.add(first) is False  # an older copy never overwrites the newer
    assert (count(store, "runs"), count(store, "axes"), count(store, "parameters")) == (1, 2, 6)
    assert store.record("aaaa")["axes"][0]["parameters"]["c0"]["value"] == pytest.approx(0.323 * 1.2)


def test_runs_are_listed_newest_first_and_filtered_by_axis_and_drive(db):
    store = HistoryStore(db)
    for n, serial in enumerate((11, 12, 11)):
        store.add(
            record(day(n), [axis("y", serial, nominal()), axis("x", 100 + n, nominal())], run_id=f"{n:032d}")
        )
    assert [r["run_id"][-1] for r in store.runs()] == ["2", "1", "0"]
    assert [r["run_id"][-1] for r in store.runs(serial=11)] == ["2", "0"]
    assert [r["run_id"][-1] for r in store.runs(axis="x", serial=101)] == ["1"]
    assert store.runs(limit=1)[0]["axes"] == [
        {"axis": "x", "serial": "0x00000066"},
        {"axis": "y", "serial": "0x0000000B"},
    ]
    assert store.runs()[0]["started_at"].startswith("2026-03-04T08:00")


def test_show_names_a_missing_or_ambiguous_run(db):
    store = HistoryStore(db)
    store.add(record(day(0), [axis("y", 1, nominal())], run_id="ab" + "0" * 30))
    store.add(record(day(1), [axis("y", 1, nominal())], run_id="ac" + "0" * 30))
    with pytest.raises(UserError, match="no run 'ff'"):
        store.record("ff")
    with pytest.raises(UserError, match="more than one run id"):
        store.record("a")
    assert store.record("ac")["run_id"].startswith("ac")


def test_parameters_come_back_with_drive_time_and_whether_determined(db):
    store = HistoryStore(db)
    store.add(record(day(3), [axis("y", 0xFFFFFFFF, {**nominal(), "c1": (1e-6, 1e-3, False)})]))
    rows = {r.name: r for r in store.parameters()}
    assert rows["c1"].determined is False and rows["c0"].determined is True
    assert rows["c0"].serial == 0xFFFFFFFF  # an unsigned 32-bit serial fits
    assert rows["J"].started == day(3)
