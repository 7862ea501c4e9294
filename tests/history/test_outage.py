"""Acceptance: the database stopped in the middle of a commissioning. The commissioning completes,
its record waits in the outbox, and ``history sync`` later adds exactly one record -- on SQLite
(its folder taken away) and on a PostgreSQL server of the test's own (stopped with pg_ctl)."""

from __future__ import annotations

import json
import subprocess
from dataclasses import replace

import pytest
import sqlalchemy as sa

from drive_bridge.cli import main
from drive_bridge.commissioning import Options, commission
from drive_bridge.config import load_bus_config
from drive_bridge.history import HistoryStore
from drive_bridge.history.location import outbox_dir
from drive_bridge.progress import StepReporter
from harness.support import BUS_CONFIG

from .conftest import SERVER, fresh_database, no_server, start_server
from .records import axis, day, nominal, record

pytestmark = pytest.mark.slow


class Outage:
    """A database that can be stopped and started again."""

    def __init__(self, url: str, stop, start):
        self.url, self.stop, self.start = url, stop, start


@pytest.fixture(params=["sqlite", "postgresql"])
def outage(request, tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    if request.param == "sqlite":
        folder, away = tmp_path / "db", tmp_path / "db-away"
        folder.mkdir()
        yield Outage(
            f"sqlite:///{folder / 'history.sqlite'}", lambda: folder.rename(away), lambda: away.rename(folder)
        )
        return
    try:  # a server of the test's own: stopping it disturbs no other test
        env = start_server()
    except (RuntimeError, OSError, subprocess.TimeoutExpired) as exc:
        no_server(exc)
    where = env["DRIVE_BRIDGE_TEST_POSTGRES_DIR"]
    monkeypatch.setenv("PGPASSWORD", env["DRIVE_BRIDGE_TEST_POSTGRES_PASSWORD"])
    url = fresh_database(env["DRIVE_BRIDGE_TEST_POSTGRES"], env["DRIVE_BRIDGE_TEST_POSTGRES_PASSWORD"])
    yield Outage(
        url,
        lambda: subprocess.run([str(SERVER), "stop", where], check=True, timeout=60),
        lambda: subprocess.run([str(SERVER), "restart", where], check=True, timeout=60),
    )
    subprocess.run([str(SERVER), "remove", where], timeout=60)


class StopsTheDatabase(StepReporter):
    """Progress as usual; the database is stopped when the campaign starts."""

    def __init__(self, outage: Outage):
        super().__init__(["scan", "bringup", "campaign"])
        self.outage = outage

    def start(self, step: str, what: str) -> None:
        if step == "campaign":
            self.outage.stop()
        super().start(step, what)


def runs(url: str) -> int:
    store = HistoryStore(url)
    with store.engine.connect() as conn:
        return conn.execute(sa.text("SELECT count(*) FROM runs")).scalar()


def test_the_commissioning_completes_and_history_sync_adds_exactly_one_record(outage, tmp_path, capsys):
    HistoryStore(outage.url).add(record(day(0), [axis("y", 1002, nominal())]))  # the database was up
    config = load_bus_config(BUS_CONFIG)
    config = replace(config, campaign=config.campaign.quick())
    result = commission(
        config,
        tmp_path / "run",
        Options(sim=True, db=outage.url, figures=False),
        steps=["scan", "bringup", "campaign"],
        reporter=StopsTheDatabase(outage),
    )
    assert result.exit_code == 0 and result.failed_step is None
    history = result.summary["history"]
    assert history["kept"] is False and history["reason"]
    waiting = list(outbox_dir().glob("*.json"))
    assert [p.stem for p in waiting] == [history["run_id"]]
    assert "waits in" in (tmp_path / "run" / "report.md").read_text()
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["history"]["outbox"] == str(waiting[0])
    assert "history sync" in capsys.readouterr().err

    assert main(["history", "sync", "--db", outage.url]) == 7  # still away: nothing lost, nothing sent
    assert list(outbox_dir().glob("*.json")) == waiting

    outage.start()
    assert main(["history", "sync", "--db", outage.url]) == 0
    assert runs(outage.url) == 2
    assert list(outbox_dir().glob("*.json")) == []
    assert main(["history", "sync", "--db", outage.url]) == 0  # again: nothing to send, nothing doubled
    assert runs(outage.url) == 2
    kept = HistoryStore(outage.url).record(history["run_id"])
    assert kept["out"] == str((tmp_path / "run").resolve()) and [a["axis"] for a in kept["axes"]] == [
        "x",
        "y",
        "z",
    ]
    assert [a["drive"]["serial"] for a in kept["axes"]] == ["0x000003E9", "0x000003EA", "0x000003EB"]


def test_ctrl_c_while_the_record_is_sent_keeps_it_in_the_outbox_and_the_report_written(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))

    def interrupted(self, record):
        raise KeyboardInterrupt

    monkeypatch.setattr(HistoryStore, "add", interrupted)
    config = load_bus_config(BUS_CONFIG)
    result = commission(
        config, tmp_path / "run", Options(sim=True, db=f"sqlite:///{tmp_path / 'h.sqlite'}"), steps=["scan"]
    )
    assert result.exit_code == 130
    history = json.loads((tmp_path / "run" / "summary.json").read_text())["history"]
    assert history["interrupted"] and not history["kept"]
    assert [p.stem for p in outbox_dir().glob("*.json")] == [history["run_id"]]
    assert (tmp_path / "run" / "report.html").exists()
