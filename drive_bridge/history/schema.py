"""The history database's tables (SQLAlchemy Core): one row per run, per axis of a run, per
identified parameter of an axis.  The Alembic migrations in ``migrations/`` create and change
them; the schema's version is Alembic's revision in the database's ``alembic_version`` table."""

from __future__ import annotations

import sqlalchemy as sa

metadata = sa.MetaData()

#: one commissioning, write, identification or monitored window; ``record`` is the whole record document
#: (:mod:`.record`), the columns beside it what lists and comparisons select on
runs = sa.Table(
    "runs",
    metadata,
    sa.Column("run_id", sa.String(32), primary_key=True),
    sa.Column("kind", sa.String(16), nullable=False),  # commission, write, identify, monitor
    sa.Column("started_at", sa.DateTime(timezone=True), nullable=False),
    sa.Column("updated_at", sa.DateTime(timezone=True), nullable=False),
    sa.Column("version", sa.String(32), nullable=False),  # drive-bridge's
    sa.Column("config_sha256", sa.String(64)),  # the bus configuration's bytes
    sa.Column("out_dir", sa.Text),
    sa.Column("status", sa.String(16)),
    sa.Column("verdict", sa.String(16)),
    sa.Column("simulated", sa.Boolean, nullable=False),
    sa.Column("record", sa.JSON, nullable=False),
)

#: an axis of a run and the drive that moved it (0x1018; unknown for a log identified alone)
axes = sa.Table(
    "axes",
    metadata,
    sa.Column("run_id", sa.String(32), sa.ForeignKey("runs.run_id", ondelete="CASCADE"), primary_key=True),
    sa.Column("axis", sa.String(64), primary_key=True),
    sa.Column("node_id", sa.Integer),
    sa.Column("vendor_id", sa.BigInteger),
    sa.Column("product_code", sa.BigInteger),
    sa.Column("revision", sa.BigInteger),
    sa.Column("serial", sa.BigInteger),
    sa.Column("verdict", sa.String(16)),
    sa.Column("consistent", sa.Boolean),
    sa.Column("stored", sa.Boolean),
    sa.Index("ix_axes_drive", "vendor_id", "product_code", "serial"),
)

#: an identified parameter of an axis of a run: value and std in SI (motor side), ``determined``
#: false where the identification said the data do not determine it
parameters = sa.Table(
    "parameters",
    metadata,
    sa.Column("run_id", sa.String(32), primary_key=True),
    sa.Column("axis", sa.String(64), primary_key=True),
    sa.Column("name", sa.String(128), primary_key=True),
    sa.Column("value", sa.Float, nullable=False),
    sa.Column("std", sa.Float),
    sa.Column("unit", sa.String(32)),
    sa.Column("determined", sa.Boolean, nullable=False),
    sa.ForeignKeyConstraint(["run_id", "axis"], ["axes.run_id", "axes.axis"], ondelete="CASCADE"),
)
