"""Identification from logs: signals, least squares and GA, effects, residual tracing."""

from .identify import AxisResult, identify

__all__ = ["AxisResult", "identify"]
