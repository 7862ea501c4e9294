"""``commission``: scan → bring-up → campaign → identify → tune → write → validate in one run,
every step's output kept in one directory, resumable, ending in ``summary.json`` and ``report.html``."""

from ..session import Options
from .run import STEPS, CommissionResult, commission

__all__ = ["STEPS", "CommissionResult", "Options", "commission"]
