"""Credentials stay secret and connections use TLS, against the real PostgreSQL server (TLS on,
password logins only over TLS): the password, given in the URL, PGPASSWORD or a password file,
never appears in output, logs, JSON, the run directory or the outbox -- reached or not."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import sqlalchemy as sa

from drive_bridge.cli import main
from drive_bridge.history import HistoryStore
from drive_bridge.history.location import data_dir


def with_password(url: str, password: str) -> str:
    return sa.make_url(url).set(password=password).render_as_string(hide_password=False)


def everything_written(*folders: Path) -> str:
    return "".join(
        p.read_text(errors="replace")
        for f in folders
        if f.exists()
        for p in f.rglob("*")
        if p.is_file() and p.suffix != ".sqlite"
    )


@pytest.mark.parametrize("reachable", [True, False])
def test_a_password_in_the_url_never_appears(postgres, tmp_path, monkeypatch, capfd, reachable):
    url, password, _ = postgres
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    monkeypatch.delenv("PGPASSWORD", raising=False)
    target = with_password(
        url if reachable else sa.make_url(url).set(port=1).render_as_string(False), password
    )
    out = tmp_path / "run"
    code = main(
        [
            "-vv",
            "commission",
            "--sim",
            "--quick",
            "--steps",
            "scan",
            "--out",
            str(out),
            "--db",
            target,
            "--json",
        ]
    )
    assert code == 0
    written = capfd.readouterr()
    assert password not in written.out + written.err + everything_written(out, data_dir())
    assert ":***@" in written.err
    assert main(["history", "list", "--db", target, "--json"]) == (0 if reachable else 7)
    written = capfd.readouterr()
    assert password not in written.out + written.err
    if reachable:
        assert list((data_dir() / "outbox").glob("*.json")) == []
    else:
        assert "port 1 failed" in written.err and len(list((data_dir() / "outbox").glob("*.json"))) == 1


def test_the_password_from_a_password_file_and_the_connection_encrypted(postgres, tmp_path, monkeypatch):
    url, password, _ = postgres
    monkeypatch.delenv("PGPASSWORD", raising=False)
    u = sa.make_url(url)
    pgpass = tmp_path / "pgpass"
    pgpass.write_text(f"{u.host}:{u.port}:*:{u.username}:{password}\n")
    pgpass.chmod(0o600)
    monkeypatch.setenv("PGPASSFILE", str(pgpass))
    store = HistoryStore(url)
    with store.engine.connect() as conn:
        ssl = conn.execute(sa.text("SELECT ssl, version FROM pg_stat_ssl WHERE pid = pg_backend_pid()")).one()
    assert ssl.ssl is True and ssl.version.startswith("TLS")
    assert "sslmode=prefer" in store.where and password not in store.where


def test_without_a_password_the_server_refuses_and_says_so(postgres, monkeypatch, capsys):
    url, _, _ = postgres
    monkeypatch.delenv("PGPASSWORD", raising=False)
    monkeypatch.setenv("PGPASSFILE", os.devnull)
    assert main(["history", "list", "--db", url]) == 7
    err = capsys.readouterr().err
    assert err.startswith("drive-bridge: error: history database postgresql+psycopg://drivebridge@")
    assert "password" in err and "Traceback" not in err
