"""Identification from logs: signals, least squares and GA, effects, residual tracing.

``identify`` and ``AxisResult`` are imported on first use, as the package root's names are: a
module that needs one constant of identification's (the effects a drive's model holds) does not
load scipy's signal processing with it."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__all__ = ["AxisResult", "identify"]

if TYPE_CHECKING:
    from .identify import AxisResult, identify


def __getattr__(name: str) -> Any:
    if name in __all__:
        value = getattr(importlib.import_module(".identify", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
