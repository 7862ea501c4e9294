"""matplotlib as the figures the tool writes use it: the Agg backend (files, no display).

:func:`pyplot` before work is forked out (:func:`drive_bridge.ident.workers.fork_map`) lets every
process drawing a figure find matplotlib imported, instead of each importing it again.
"""
from __future__ import annotations

from types import ModuleType


def pyplot() -> ModuleType:
    """``matplotlib.pyplot`` on the Agg backend."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt
