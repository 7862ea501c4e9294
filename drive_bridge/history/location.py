"""Where the history is kept: the database URL (``--db``, else ``DRIVE_BRIDGE_DB``, else a SQLite
file in the user's data directory), the local outbox beside that file, and the URL as it may be
shown (its password never)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import sqlalchemy as sa

from ..errors import UserError

ENV_DB = "DRIVE_BRIDGE_DB"
SQLITE_NAME = "history.sqlite"
OUTBOX = "outbox"


def data_dir() -> Path:
    """The user's data directory for drive-bridge: ``$XDG_DATA_HOME/drive-bridge`` (default
    ``~/.local/share/drive-bridge``), ``%LOCALAPPDATA%\\drive-bridge`` on Windows.

    Returns
    -------
    Path
        The directory (not made here).
    """
    if sys.platform == "win32" and os.environ.get("LOCALAPPDATA"):
        return Path(os.environ["LOCALAPPDATA"]) / "drive-bridge"
    base = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(base) / "drive-bridge"


def outbox_dir() -> Path:
    """Where records not yet in the database wait (it was unreachable), one JSON file each.

    Returns
    -------
    Path
        The outbox directory, in :func:`data_dir`.
    """
    return data_dir() / OUTBOX


def database_url(given: str | None = None) -> sa.URL:
    """The history database: ``given`` (``--db``), else ``DRIVE_BRIDGE_DB``, else the SQLite file
    in :func:`data_dir`.  ``postgresql://`` means the psycopg (3) driver, asked for TLS where the
    server offers it (``sslmode=prefer`` unless the URL says otherwise); its password may be in the
    URL, in ``PGPASSWORD`` or in the client's password file (``~/.pgpass``, ``PGPASSFILE``).

    Parameters
    ----------
    given : str, optional
        The URL ``--db`` gave.

    Returns
    -------
    sqlalchemy.URL
        The URL, its driver and TLS mode set.

    Raises
    ------
    UserError
        Not a database URL, or a database that is not SQLite or PostgreSQL.
    """
    text = given or os.environ.get(ENV_DB) or f"sqlite:///{data_dir() / SQLITE_NAME}"
    where = "--db" if given else (ENV_DB if os.environ.get(ENV_DB) else "the default")
    try:
        url = sa.make_url(text)
    except sa.exc.ArgumentError:
        raise UserError(
            f"{where}: not a database URL (sqlite:///PATH or postgresql://USER@HOST/DATABASE)"
        ) from None
    backend = url.get_backend_name()
    if backend == "postgresql":
        url = url.set(drivername="postgresql+psycopg")
        if "sslmode" not in url.query:
            url = url.update_query_dict({"sslmode": "prefer"})
    elif backend != "sqlite":
        raise UserError(
            f"{where}: {backend} databases are not supported (sqlite:///PATH or postgresql://...)"
        )
    return url


def shown(url: sa.URL) -> str:
    """The URL as a log line, a report or JSON may show it.

    Parameters
    ----------
    url : sqlalchemy.URL
        The database URL.

    Returns
    -------
    str
        The URL, the password masked.
    """
    return url.render_as_string(hide_password=True)


def secrets(url: sa.URL) -> list[str]:
    """What must never be shown.

    Parameters
    ----------
    url : sqlalchemy.URL
        The database URL.

    Returns
    -------
    list of str
        The password of the URL and of ``PGPASSWORD``, where set.
    """
    return [s for s in (url.password, os.environ.get("PGPASSWORD")) if s]


def redacted(text: str, url: sa.URL) -> str:
    """A text with every secret of a URL masked.

    Parameters
    ----------
    text : str
        A driver's error message.
    url : sqlalchemy.URL
        The database URL.

    Returns
    -------
    str
        The text, each secret replaced by ``***``.
    """
    for secret in secrets(url):
        text = text.replace(str(secret), "***")
    return text
