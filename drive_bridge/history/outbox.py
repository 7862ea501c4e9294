"""Nothing lost when the database is away: every record is first written to the local outbox (one
JSON file per run id, beside the default database in the user's data directory), then sent; it
leaves the outbox once the database holds it.  ``history sync`` sends what waits; a record sent
twice is kept once (:meth:`~.store.HistoryStore.add` is idempotent by run id).  A record refused
for what it holds (:class:`~.store.RecordRefused`) is set aside in ``rejected/`` with the reason
(``history rejected`` lists them): it never blocks the records behind it."""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field
from pathlib import Path

import sqlalchemy as sa

from ..outputs import write_text
from .location import database_url, outbox_dir, shown
from .record import now
from .store import HistoryStore, HistoryUnavailable, RecordRefused

log = logging.getLogger(__name__)


@dataclass
class Kept:
    """Where a record went: into the database, or into the outbox (and why).

    Parameters
    ----------
    run_id : str
        The run.
    database : str
        The database's URL, its password masked.
    stored : bool
        The database holds it.
    reason : str, optional
        Why it waits in the outbox.
    outbox : Path, optional
        Its file there.
    sent_from_outbox : list of str
        Earlier records sent with it.
    interrupted : bool
        Ctrl-C while it was sent: the record waits in the outbox.
    refused : bool
        Refused for its content: set aside in the outbox's ``rejected/``.
    """

    run_id: str
    database: str
    stored: bool
    reason: str | None = None
    outbox: Path | None = None
    sent_from_outbox: list[str] = field(default_factory=list)
    interrupted: bool = False
    refused: bool = False

    def line(self) -> str:
        """Where the record went, in one line for the command's output.

        Returns
        -------
        str
            Kept in the database, set aside and why, or waiting in the outbox and what sends it.
        """
        if self.stored:
            extra = (
                f" (and {len(self.sent_from_outbox)} earlier record(s) from the outbox)"
                if self.sent_from_outbox
                else ""
            )
            return f"history: run {self.run_id} kept in {self.database}{extra}"
        if self.refused:
            return (
                f"history: run {self.run_id} was not kept: {self.reason}; set aside in {self.outbox} "
                f"('drive-bridge history rejected' lists what was set aside)"
            )
        return (
            f"history: the database is unreachable ({self.reason}); run {self.run_id} waits in "
            f"{self.outbox}: 'drive-bridge history sync' sends it"
        )


def _entry(path: Path) -> dict | None:
    try:
        doc = json.loads(path.read_text())
        doc["record"]["run_id"], doc["database"]
        return doc
    except (OSError, ValueError, KeyError, TypeError):
        log.warning("history outbox: %s is unreadable; left where it is", path)
        return None


def waiting(url: sa.URL | None = None) -> list[tuple[Path, dict]]:
    """The outbox's entries, oldest first.

    Parameters
    ----------
    url : sqlalchemy.URL, optional
        Only those for this database.

    Returns
    -------
    list of (Path, dict)
        Each entry's file and its content (the record and its database).
    """
    paths = (
        sorted(outbox_dir().glob("*.json"), key=lambda p: p.stat().st_mtime) if outbox_dir().is_dir() else []
    )
    entries = [(p, e) for p in paths if (e := _entry(p)) is not None]
    return [(p, e) for p, e in entries if url is None or e["database"] == shown(url)]


def keep(record: dict, db: str | None = None) -> Kept:
    """Keep ``record`` in the history database ``db`` (default :func:`~.location.database_url`),
    through the outbox; never raises for the database, nor for Ctrl-C while sending: the result
    says where the record is.

    Parameters
    ----------
    record : dict
        The run's record (schema ``record``).
    db : str, optional
        The database URL (``--db``).

    Returns
    -------
    Kept
        Where the record went.
    """
    url = database_url(db)
    path = outbox_dir() / f"{record['run_id']}.json"
    write_text(path, json.dumps({"database": shown(url), "record": record}, indent=1))
    try:
        store = HistoryStore(url)
        try:
            sent = send(store)
        finally:
            store.close()
    except HistoryUnavailable as exc:
        log.info("%s", exc)
        return Kept(record["run_id"], shown(url), False, str(exc).split(": ", 1)[-1], path)
    except KeyboardInterrupt:
        return Kept(
            record["run_id"],
            shown(url),
            False,
            "interrupted (Ctrl-C) while it was sent",
            path,
            interrupted=True,
        )
    refused = dict(sent.rejected)
    if record["run_id"] in refused:
        return Kept(
            record["run_id"],
            shown(url),
            False,
            refused[record["run_id"]],
            rejected_dir() / path.name,
            refused=True,
        )
    if record["run_id"] not in sent.sent + sent.already:
        return Kept(record["run_id"], shown(url), False, sent.failed or "not sent", path)
    return Kept(
        record["run_id"], shown(url), True, sent_from_outbox=[r for r in sent.sent if r != record["run_id"]]
    )


@dataclass
class Sent:
    """What sending the outbox did (:func:`send`).

    Parameters
    ----------
    sent : list of str
        Run ids the database did not hold before.
    already : list of str
        Run ids it held already (a retry).
    failed : str, optional
        Why sending stopped.
    left : int
        Entries still waiting for this database.
    rejected : list of (str, str)
        (run id, why) of the records set aside.
    """

    sent: list[str] = field(default_factory=list)
    already: list[str] = field(default_factory=list)
    failed: str | None = None
    left: int = 0
    rejected: list[tuple[str, str]] = field(default_factory=list)


def rejected_dir() -> Path:
    """Where records refused for their content are set aside, each with the reason.

    Returns
    -------
    Path
        ``rejected/`` in the outbox.
    """
    return outbox_dir() / "rejected"


def send(store: HistoryStore) -> Sent:
    """Send the outbox's entries for ``store``'s database, oldest first; each leaves the outbox
    once the database holds it, or is set aside in :func:`rejected_dir` where it is refused for
    what it holds (the others go on).  Stops at the first failure of the database itself (it went
    away again).

    Parameters
    ----------
    store : HistoryStore
        The database.

    Returns
    -------
    Sent
        What was sent, held already, set aside, and what is left.
    """
    out = Sent()
    entries = waiting(store.url)
    for i, (path, entry) in enumerate(entries):
        run_id = entry["record"]["run_id"]
        try:
            (out.sent if store.add(entry["record"]) else out.already).append(run_id)
        except RecordRefused as exc:
            why = str(exc)
            log.warning("history: run %s set aside: %s", run_id, why)
            write_text(
                rejected_dir() / path.name, json.dumps({**entry, "reason": why, "set_aside": now()}, indent=1)
            )
            out.rejected.append((run_id, why))
        except HistoryUnavailable as exc:
            out.failed, out.left = str(exc).split(": ", 1)[-1], len(entries) - i
            break
        path.unlink(missing_ok=True)
    return out


def rejected() -> list[dict]:
    """The records set aside.

    Returns
    -------
    list of dict
        Oldest first: ``run_id``, ``database``, ``reason``, ``set_aside`` (when) and ``path``.
    """
    folder = rejected_dir()
    paths = sorted(folder.glob("*.json"), key=lambda p: p.stat().st_mtime) if folder.is_dir() else []
    out = []
    for path in paths:
        try:
            doc = json.loads(path.read_text())
            run_id = doc["record"]["run_id"]
        except (OSError, ValueError, KeyError, TypeError):
            run_id, doc = path.stem, {}
        out.append(
            {
                "run_id": run_id,
                "database": doc.get("database"),
                "reason": doc.get("reason", "unreadable"),
                "set_aside": doc.get("set_aside"),
                "path": str(path),
            }
        )
    return out
