"""matplotlib as the figures the tool writes use it: the Agg backend (files, no display).

:func:`pyplot` before work is forked out (:func:`drive_bridge.forking.fork_map`) lets every
process drawing a figure find matplotlib imported, instead of each importing it again.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

from .forking import fork_map, processes


def pyplot() -> ModuleType:
    """``matplotlib.pyplot`` on the Agg backend.

    Returns
    -------
    module
        ``matplotlib.pyplot``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save(fig: Any, path: Path) -> Path:
    """``fig`` as a PNG at ``path`` (its folder made), then closed: the report figures' resolution.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    path : Path
        The PNG.

    Returns
    -------
    Path
        The PNG.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80)
    pyplot().close(fig)
    return path


def side_by_side(draw: Callable[[Any, Any], Any], items: Sequence[Any], shared: Any) -> list[Any]:
    """``draw(shared, item)`` for each of ``items``, in processes of their own where work is shared
    out (one per item up to :func:`~drive_bridge.forking.processes`), matplotlib imported first.

    Parameters
    ----------
    draw : callable
        ``draw(shared, item)``.
    items : sequence
        The items.
    shared : object
        What every call shares (found where it is by a forked process).

    Returns
    -------
    list
        ``draw``'s results, in the items' order.
    """
    pyplot()
    return fork_map(draw, items, min(len(items), processes()), shared)
