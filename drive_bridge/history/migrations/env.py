"""Alembic's environment: migrations run on the connection :mod:`drive_bridge.history.store` passes."""

from __future__ import annotations

from alembic import context

from drive_bridge.history.schema import metadata

connection = context.config.attributes["connection"]
context.configure(connection=connection, target_metadata=metadata)
with context.begin_transaction():
    context.run_migrations()
