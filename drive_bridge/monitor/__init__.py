"""Watching a running machine: listen only, identify each window of production motion, keep
each axis's J, c0 and c1 in the history and name their drift.

The data flow as the package reads: :mod:`.layout` (what the drives publish, from bus.yml) →
:mod:`.listen` (frames to samples) → :mod:`.rolling` (the moving samples on disk) →
:mod:`.window` (a window identified) → :mod:`.drift` (set against the commissioning and the
recent windows) → :mod:`.watch` (the :class:`Monitor` that ties them) ← :mod:`.live` (a bus,
listen-only, reopened when lost) or :mod:`.simulated` (a simulated week of production).
"""

from __future__ import annotations

from typing import Any

from .live import listen
from .watch import Monitor, Settings

__all__ = ["Monitor", "Settings", "listen", "simulated_week"]


def __getattr__(name: str) -> Any:
    """``simulated_week`` imported when asked for: it brings the simulator (numba and its compiled
    kernels), which a monitor listening on a real bus never needs."""
    if name == "simulated_week":
        from .simulated import simulated_week

        return simulated_week
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
