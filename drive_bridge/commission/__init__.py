"""``commission``: scan → bring-up → campaign → identify → tune → write → validate in one run,
every step's output kept in one directory, resumable, ending in ``summary.json`` and ``report.html``."""
from .run import STEPS, CommissionResult, Options, commission

__all__ = ["STEPS", "CommissionResult", "Options", "commission"]
