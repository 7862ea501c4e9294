"""Watching a running machine: listen only, identify each window of production motion, keep
each axis's J, c0 and c1 in the history and name their drift.

The data flow as the package reads: :mod:`.layout` (what the drives publish, from bus.yml) →
:mod:`.listen` (frames to samples) → :mod:`.rolling` (the moving samples on disk) →
:mod:`.window` (a window identified) → :mod:`.drift` (set against the commissioning and the
recent windows) → :mod:`.watch` (the :class:`Monitor` that ties them) ← :mod:`.live` (a bus,
listen-only, reopened when lost) or :mod:`.simulated` (a simulated week of production).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .live import listen
from .watch import Monitor, Settings

__all__ = ["Monitor", "Settings", "listen", "simulated_week"]

if TYPE_CHECKING:
    from .simulated import simulated_week


def __getattr__(name: str) -> Any:
    """``simulated_week`` imported on first use, as :mod:`drive_bridge.commissioning` imports its
    names: it brings the simulator (numba and its compiled kernels), which a monitor listening on a
    real bus never needs."""
    if name == "simulated_week":
        value = getattr(importlib.import_module(".simulated", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
