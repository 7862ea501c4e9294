"""The first schema: runs, their axes and identified parameters.

Revision ID: 0001
Revises:
Create Date: 2026-11-26
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "runs",
        sa.Column("run_id", sa.String(32), primary_key=True),
        sa.Column("kind", sa.String(16), nullable=False),
        sa.Column("started_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("updated_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("version", sa.String(32), nullable=False),
        sa.Column("config_sha256", sa.String(64)),
        sa.Column("out_dir", sa.Text),
        sa.Column("status", sa.String(16)),
        sa.Column("verdict", sa.String(16)),
        sa.Column("simulated", sa.Boolean, nullable=False),
        sa.Column("record", sa.JSON, nullable=False),
    )
    op.create_table(
        "axes",
        sa.Column(
            "run_id", sa.String(32), sa.ForeignKey("runs.run_id", ondelete="CASCADE"), primary_key=True
        ),
        sa.Column("axis", sa.String(64), primary_key=True),
        sa.Column("node_id", sa.Integer),
        sa.Column("vendor_id", sa.BigInteger),
        sa.Column("product_code", sa.BigInteger),
        sa.Column("revision", sa.BigInteger),
        sa.Column("serial", sa.BigInteger),
        sa.Column("verdict", sa.String(16)),
        sa.Column("consistent", sa.Boolean),
        sa.Column("stored", sa.Boolean),
    )
    op.create_index("ix_axes_drive", "axes", ["vendor_id", "product_code", "serial"])
    op.create_table(
        "parameters",
        sa.Column("run_id", sa.String(32), primary_key=True),
        sa.Column("axis", sa.String(64), primary_key=True),
        sa.Column("name", sa.String(128), primary_key=True),
        sa.Column("value", sa.Float, nullable=False),
        sa.Column("std", sa.Float),
        sa.Column("unit", sa.String(32)),
        sa.Column("determined", sa.Boolean, nullable=False),
        sa.ForeignKeyConstraint(["run_id", "axis"], ["axes.run_id", "axes.axis"], ondelete="CASCADE"),
    )


def downgrade() -> None:
    op.drop_table("parameters")
    op.drop_table("axes")
    op.drop_table("runs")
