"""Fleet memory: every commissioning (and write, and identification when asked) kept in a
database, each drive compared with its own past and with its siblings.

The data flows as the package reads: a run's :mod:`.record` is kept through the :mod:`.outbox`
in the :mod:`.store` (SQLite by default, a PostgreSQL server by URL: :mod:`.location`; schema
by Alembic migrations), and :mod:`.compare` sets each drive against its past and its siblings;
:mod:`.since` is the commissioning report's "since last time".
"""

from __future__ import annotations

from .compare import Comparison, History, compare
from .outbox import Kept, keep, send
from .store import HistoryStore, HistoryUnavailable

__all__ = ["Comparison", "History", "HistoryStore", "HistoryUnavailable", "Kept", "compare", "keep", "send"]
