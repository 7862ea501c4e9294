"""The history database: opened (and its schema brought to this version by Alembic), records
added idempotently by run id, runs listed and read, parameter series selected for comparison."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import sqlalchemy as sa

from ..errors import DriveBridgeError, UserError
from ..outputs import hex32
from . import schema
from .location import data_dir, database_url, redacted, shown
from .record import IDENTITY, file_sha256, identity_number, numeric, problems

log = logging.getLogger(__name__)

MIGRATIONS = Path(__file__).parent / "migrations"
CONNECT_TIMEOUT_S = 5  # a server that does not answer: the record goes to the outbox, the run goes on
STATEMENT_TIMEOUT_S = 30  # ... nor one that answers the connection and then hangs
LAST_LOOKED_AT = 50  # an axis's newest commissionings looked through for one of a bus configuration


class HistoryUnavailable(DriveBridgeError):
    """The history database cannot be reached or used (its URL shown without the password)."""

    kind = "unavailable"


class RecordRefused(DriveBridgeError):
    """A record the history cannot keep for what it holds (its schema, or a value the database
    refuses), whatever the database's state: set aside, never retried as if the database were away."""

    kind = "user"


@dataclass
class ParameterRow:
    """One identified parameter of one axis of one run, with the run's time and the drive.

    Parameters
    ----------
    run_id : str
        The run.
    started : datetime
        When it started (UTC).
    simulated : bool
        A run on the simulated drives.
    axis : str
        The axis role.
    vendor_id, product_code, serial : int or None
        The drive's identity (0x1018:1, :2, :4); None where it was not read.
    name : str
        The parameter (J, c0, c1, ...).
    value : float
        Its value, SI.
    std : float or None
        Its std (None: not reported).
    unit : str or None
        Its unit.
    determined : bool
        Whether the data determined it (an undetermined value is never compared).
    """

    run_id: str
    started: datetime
    simulated: bool
    axis: str
    vendor_id: int | None
    product_code: int | None
    serial: int | None
    name: str
    value: float
    std: float | None
    unit: str | None
    determined: bool

    @property
    def drive_type(self) -> tuple[int | None, int | None]:
        """(vendor, product): the drive's type."""
        return self.vendor_id, self.product_code

    @property
    def drive(self) -> tuple[int | None, int | None, int | None]:
        """(vendor, product, serial): the drive itself."""
        return self.vendor_id, self.product_code, self.serial


def _time(text: str) -> datetime:
    return datetime.fromisoformat(text)


class HistoryStore:
    """The history database: every commissioning, write, identification and monitor window kept.

    Parameters
    ----------
    url : str or sqlalchemy.URL, optional
        The database (``--db``): a SQLAlchemy URL (SQLite, PostgreSQL); default
        :func:`~.location.database_url` (``DRIVE_BRIDGE_DB``, else the user's SQLite file).

    Raises
    ------
    HistoryUnavailable
        The database cannot be used (named, never with its password).
    """

    def __init__(self, url: str | sa.URL | None = None):
        self.url = url if isinstance(url, sa.URL) else database_url(url)
        args: dict[str, Any] = {}
        if self.url.get_backend_name() == "postgresql":
            args["connect_timeout"] = CONNECT_TIMEOUT_S
            args["options"] = f"-c statement_timeout={STATEMENT_TIMEOUT_S * 1000}"
        elif self.url.database and Path(self.url.database).parent == data_dir():
            data_dir().mkdir(
                parents=True, exist_ok=True
            )  # the default file (a file --db names needs its folder)
        try:
            self.engine = sa.create_engine(self.url, connect_args=args, poolclass=sa.pool.NullPool)
        except ModuleNotFoundError as exc:  # the driver of a server database
            raise HistoryUnavailable(
                f"history database {shown(self.url)}: its driver is not installed ({exc.name}); "
                f"pip install 'drive-bridge[postgresql]'"
            ) from None
        self._guard(self._migrate)

    @property
    def where(self) -> str:
        """The database as it may be shown: its URL without the password."""
        return shown(self.url)

    def _guard(self, work: Any, *args: Any) -> Any:
        """``work(*args)``, a database error turned into :class:`HistoryUnavailable` naming the
        database (never its password); one about what was sent (a value of the wrong type, a
        constraint) into :class:`RecordRefused`."""
        try:
            return work(*args)
        except (sa.exc.SQLAlchemyError, OSError) as exc:
            why = getattr(exc, "orig", None) or exc
            text = redacted(" ".join(str(why).split()), self.url)
            content = isinstance(exc, (sa.exc.DataError, sa.exc.IntegrityError)) or (
                isinstance(exc, sa.exc.StatementError) and not isinstance(exc, sa.exc.DBAPIError)
            )  # (a StatementError of its own: a value the column's type could not take)
            if content:
                raise RecordRefused(f"history database {self.where} refused the record: {text}") from None
            raise HistoryUnavailable(f"history database {self.where}: {text}") from None

    def _migrate(self) -> None:
        """Bring the schema to this version's revision (Alembic); refuse a database written by a
        newer drive-bridge."""
        from alembic import command
        from alembic.config import Config
        from alembic.runtime.migration import MigrationContext
        from alembic.script import ScriptDirectory

        cfg = Config()
        cfg.set_main_option("script_location", str(MIGRATIONS))
        script = ScriptDirectory.from_config(cfg)
        with self.engine.begin() as conn:
            current = MigrationContext.configure(conn).get_current_revision()
            if current is not None and current not in {s.revision for s in script.walk_revisions()}:
                raise HistoryUnavailable(
                    f"history database {self.where}: its schema revision {current} is newer "
                    f"than this drive-bridge knows (head {script.get_current_head()}); "
                    f"upgrade drive-bridge"
                )
            if current != script.get_current_head():
                cfg.attributes["connection"] = conn
                command.upgrade(cfg, "head")
                log.info("history database %s: schema at revision %s", self.where, script.get_current_head())

    def revision(self) -> str | None:
        """The database schema's revision.

        Returns
        -------
        str or None
            Alembic's revision id; None before the first migration.
        """
        from alembic.runtime.migration import MigrationContext

        with self.engine.connect() as conn:
            return MigrationContext.configure(conn).get_current_revision()

    def add(self, record: dict) -> bool:
        """Keep a run's record; adding a record twice never duplicates it.

        Parameters
        ----------
        record : dict
            The run's record (schema ``record``: :mod:`.record`).

        Returns
        -------
        bool
            False where the database holds it already (the same run id, updated as late or later).

        Raises
        ------
        RecordRefused
            A record that does not follow its schema, or whose content the database refuses.
        HistoryUnavailable
            The database cannot be used.
        """
        wrong = problems(record)
        if wrong:
            raise RecordRefused(f"the record does not follow its schema: {'; '.join(wrong)}")
        try:
            return bool(self._guard(self._add, record))
        except (KeyError, TypeError, ValueError) as exc:  # a field the schema check let through
            raise RecordRefused(f"the record could not be kept: {exc!r}") from None

    def _add(self, record: dict) -> bool:
        with self.engine.begin() as conn:
            held = conn.execute(
                sa.select(schema.runs.c.updated_at).where(schema.runs.c.run_id == record["run_id"])
            ).scalar()
            if held is not None and _aware(held) >= _time(record["updated"]):
                return False
            if held is not None:  # a resumed commissioning: its later record replaces the earlier
                for table in (schema.parameters, schema.axes, schema.runs):
                    conn.execute(table.delete().where(table.c.run_id == record["run_id"]))
            conn.execute(
                schema.runs.insert().values(
                    run_id=record["run_id"],
                    kind=record["kind"],
                    started_at=_time(record["started"]),
                    updated_at=_time(record["updated"]),
                    version=record["version"],
                    config_sha256=(record.get("config") or {}).get("sha256"),
                    out_dir=record.get("out"),
                    status=record.get("status"),
                    verdict=record.get("verdict"),
                    simulated=record["simulated"],
                    record=record,
                )
            )
            for a in record["axes"]:
                drive = a.get("drive") or {}
                conn.execute(
                    schema.axes.insert().values(
                        run_id=record["run_id"],
                        axis=a["axis"],
                        node_id=a.get("node_id"),
                        **{k: identity_number(drive.get(k)) for k in IDENTITY},
                        verdict=a.get("verdict"),
                        consistent=a.get("consistent"),
                        stored=a.get("stored"),
                    )
                )
                rows = [
                    {
                        "run_id": record["run_id"],
                        "axis": a["axis"],
                        "name": name,
                        "value": p["value"],
                        "std": p["std"],
                        "unit": p["unit"],
                        "determined": p["determined"],
                    }
                    for name, p in (a.get("parameters") or {}).items()
                    # numbers only: what an effect names (a variable, a source axis) stays in the
                    # record as it is
                    if numeric(p["value"])
                ]
                if rows:
                    conn.execute(schema.parameters.insert(), rows)
        return True

    def runs(
        self, limit: int | None = None, axis: str | None = None, serial: int | None = None
    ) -> list[dict]:
        """The runs kept, newest first.

        Parameters
        ----------
        limit : int, optional
            At most this many.
        axis : str, optional
            Only runs with this axis.
        serial : int, optional
            Only runs with the drive of this serial number.

        Returns
        -------
        list of dict
            Per run: id, kind, times, status, verdict, axes (with their drives' serials, hex), run
            directory.
        """
        return list(self._guard(self._runs, limit, axis, serial))

    def _runs(self, limit: int | None, axis: str | None, serial: int | None) -> list[dict]:
        query = sa.select(
            schema.runs.c.run_id,
            schema.runs.c.kind,
            schema.runs.c.started_at,
            schema.runs.c.status,
            schema.runs.c.verdict,
            schema.runs.c.simulated,
            schema.runs.c.out_dir,
            schema.runs.c.version,
        )
        if axis is not None or serial is not None:
            sel = sa.select(schema.axes.c.run_id)
            sel = sel.where(schema.axes.c.axis == axis) if axis is not None else sel
            sel = sel.where(schema.axes.c.serial == serial) if serial is not None else sel
            query = query.where(schema.runs.c.run_id.in_(sel))
        query = query.order_by(schema.runs.c.started_at.desc(), schema.runs.c.run_id).limit(limit)
        with self.engine.connect() as conn:
            rows = [dict(r._mapping) for r in conn.execute(query)]
            drives: dict[str, list[tuple[str, int | None]]] = {}
            ids = [r["run_id"] for r in rows]
            for row in conn.execute(
                sa.select(schema.axes.c.run_id, schema.axes.c.axis, schema.axes.c.serial)
                .where(schema.axes.c.run_id.in_(ids))
                .order_by(schema.axes.c.axis)
            ):
                drives.setdefault(row.run_id, []).append((row.axis, row.serial))
        for r in rows:
            r["started_at"] = _aware(r["started_at"]).isoformat()
            r["axes"] = [
                {"axis": a, "serial": None if s is None else hex32(s)} for a, s in drives.get(r["run_id"], [])
            ]
        return rows

    def last_commissioning(self, axis: str, node_id: int, config: Path, simulated: bool) -> dict | None:
        """The newest commissioning of an axis at a node under a bus configuration.

        Parameters
        ----------
        axis : str
            The axis.
        node_id : int
            Its node id.
        config : Path
            The bus configuration (the same path, or the same bytes).
        simulated : bool
            On the simulated drives, or real ones.

        Returns
        -------
        dict or None
            Its ``run_id``, ``started`` and the axis's entry of its record (drive identity,
            parameters); None where none is kept.
        """
        return self._guard(self._last_commissioning, axis, node_id, config, simulated)

    def _last_commissioning(self, axis: str, node_id: int, config: Path, simulated: bool) -> dict | None:
        path, sha = str(config.resolve()), file_sha256(config)
        r, a = schema.runs.c, schema.axes.c
        query = (
            sa.select(r.run_id, r.started_at, r.record)
            .where(
                r.kind == "commission",
                r.simulated == simulated,
                r.run_id.in_(sa.select(a.run_id).where(a.axis == axis, a.node_id == node_id)),
            )
            .order_by(r.started_at.desc(), r.run_id)
            .limit(LAST_LOOKED_AT)
        )
        with self.engine.connect() as conn:
            for row in conn.execute(query):
                cfg = row.record.get("config") or {}
                if cfg.get("path") == path or (sha is not None and cfg.get("sha256") == sha):
                    entry = next((x for x in row.record["axes"] if x.get("axis") == axis), None)
                    if entry is not None:
                        return {"run_id": row.run_id, "started": _aware(row.started_at), "axis": entry}
        return None

    def record(self, run: str) -> dict:
        """The record of one run.

        Parameters
        ----------
        run : str
            Its id, or a prefix of it no other run id shares.

        Returns
        -------
        dict
            The record as kept.

        Raises
        ------
        UserError
            No such run, or a prefix more than one run id shares.
        """
        rows = self._guard(self._records, run)
        if not rows:
            raise UserError(
                f"history database {self.where}: no run {run!r}; 'drive-bridge history list' shows the runs"
            )
        if len(rows) > 1:
            ids = ", ".join(r["run_id"] for r in rows)
            raise UserError(f"run {run!r} is the start of more than one run id ({ids}, ...); give more of it")
        return dict(rows[0])

    def _records(self, run: str) -> list[dict]:
        with self.engine.connect() as conn:
            return [
                r.record
                for r in conn.execute(
                    sa.select(schema.runs.c.record)
                    .where(schema.runs.c.run_id.startswith(run, autoescape=True))
                    .limit(2)
                )
            ]

    def parameters(self) -> list[ParameterRow]:
        """Every identified parameter of every run that has a drive identity.

        Returns
        -------
        list of ParameterRow
            Oldest run first.
        """
        return list(self._guard(self._parameters))

    def _parameters(self) -> list[ParameterRow]:
        r, a, p = schema.runs.c, schema.axes.c, schema.parameters.c
        query = (
            sa.select(
                r.run_id,
                r.started_at,
                r.simulated,
                a.axis,
                a.vendor_id,
                a.product_code,
                a.serial,
                p.name,
                p.value,
                p.std,
                p.unit,
                p.determined,
            )
            .select_from(
                schema.parameters.join(schema.axes, sa.and_(p.run_id == a.run_id, p.axis == a.axis)).join(
                    schema.runs, r.run_id == a.run_id
                )
            )
            .where(a.serial.is_not(None))  # a log identified alone names no drive: not compared
            .order_by(r.started_at, r.run_id)
        )
        with self.engine.connect() as conn:
            return [
                ParameterRow(
                    row.run_id,
                    _aware(row.started_at),
                    row.simulated,
                    row.axis,
                    row.vendor_id,
                    row.product_code,
                    row.serial,
                    row.name,
                    row.value,
                    row.std,
                    row.unit,
                    row.determined,
                )
                for row in conn.execute(query)
            ]

    def close(self) -> None:
        """Close the database's connections."""
        self.engine.dispose()


def _aware(t: datetime) -> datetime:
    """A time read back (SQLite gives it without its zone; every time kept is UTC)."""
    return t if t.tzinfo is not None else t.replace(tzinfo=timezone.utc)
