"""The history's databases: SQLite, and a real PostgreSQL server (TLS, password login) -- the one
.ci/run started (DRIVE_BRIDGE_TEST_POSTGRES), else one this worker starts from Debian's package
with tools/test_postgres.sh. Every test gets an empty database and an empty outbox."""

from __future__ import annotations

import os
import subprocess
import uuid

import pytest
import sqlalchemy as sa

from harness.paths import ROOT

SERVER = ROOT / "tools" / "test_postgres.sh"
WHY_NO_POSTGRES = "no PostgreSQL server: tools/test_postgres.sh could not start one ({})"


def no_server(exc: BaseException) -> None:
    """Skip for want of a server; fail where CI asks for one (DRIVE_BRIDGE_REQUIRE_POSTGRES)."""
    if os.environ.get("DRIVE_BRIDGE_REQUIRE_POSTGRES"):
        pytest.fail(WHY_NO_POSTGRES.format(exc))
    pytest.skip(WHY_NO_POSTGRES.format(exc))


def start_server() -> dict[str, str]:
    """A PostgreSQL server of its own: the environment tools/test_postgres.sh prints."""
    done = subprocess.run([str(SERVER), "start"], capture_output=True, text=True, timeout=120)
    if done.returncode:
        raise RuntimeError(done.stderr.strip() or f"exit {done.returncode}")
    env = {}
    for line in done.stdout.splitlines():
        name, _, value = line.removeprefix("export ").partition("=")
        env[name] = value.strip("'")
    return env


@pytest.fixture(scope="session")
def postgres():
    """(URL without password, password, data directory) of the server the tests use."""
    env = {k: v for k, v in os.environ.items() if k.startswith("DRIVE_BRIDGE_TEST_POSTGRES")}
    own = not env
    if own:
        try:
            env = start_server()
        except (RuntimeError, OSError, subprocess.TimeoutExpired) as exc:
            no_server(exc)
    yield (
        env["DRIVE_BRIDGE_TEST_POSTGRES"],
        env["DRIVE_BRIDGE_TEST_POSTGRES_PASSWORD"],
        env["DRIVE_BRIDGE_TEST_POSTGRES_DIR"],
    )
    if own:
        subprocess.run([str(SERVER), "remove", env["DRIVE_BRIDGE_TEST_POSTGRES_DIR"]], timeout=60)


def fresh_database(url: str, password: str) -> str:
    """A new empty database on the server of ``url`` (owned by its role); its URL."""
    base = sa.make_url(url).set(drivername="postgresql+psycopg", password=password)
    name = f"t_{uuid.uuid4().hex[:16]}"
    engine = sa.create_engine(base, isolation_level="AUTOCOMMIT")
    with engine.connect() as conn:
        conn.execute(sa.text(f'CREATE DATABASE "{name}"'))
    engine.dispose()
    return str(sa.make_url(url).set(database=name).render_as_string(hide_password=False))


@pytest.fixture(params=["sqlite", "postgresql"])
def db(request, tmp_path, monkeypatch):
    """An empty history database (its URL, no password in it: PostgreSQL's comes from PGPASSWORD)
    and an empty outbox."""
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    if request.param == "sqlite":
        return f"sqlite:///{tmp_path / 'history.sqlite'}"
    url, password, _ = request.getfixturevalue("postgres")
    monkeypatch.setenv("PGPASSWORD", password)
    return fresh_database(url, password)
