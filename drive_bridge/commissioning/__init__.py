"""``commission``: scan → bring-up → campaign → identify → tune → write → validate in one run,
every step's output kept in one directory, resumable, ending in ``summary.json`` and ``report.html``.

The names are imported on first use (the report pulls identification's in): the command line
builds its parser from the step names alone."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__all__ = ["STEPS", "CommissionResult", "Options", "commission"]

if TYPE_CHECKING:
    from ..session import Options
    from .run import STEPS, CommissionResult, commission


def __getattr__(name: str) -> Any:
    if name in __all__:  # (Options is run's too: it imports it from the session)
        value = getattr(importlib.import_module(".run", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
