"""Alembic migrations of the history database (run by :func:`drive_bridge.history.store.open_store`)."""
