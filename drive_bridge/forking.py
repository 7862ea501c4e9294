"""Work shared out to processes forked from this one, one per core: the axes of a large log
identified side by side, its CSV parsed in parts, figures drawn side by side.

Each part is independent of the others and single-threaded Python and numpy, so it goes to a
worker process forked from this one: the worker finds what it works on where it is (nothing is
sent but the function and the item), and results are the same as one part after the other.

Each worker runs OpenBLAS with one thread: with its own two threads in each of two workers the
run took three times as long.  Where that cannot be set (another BLAS library), where this
process runs other threads (a fork copies only the calling one: a lock another thread holds
would never be released in the child), in a daemon process (a pool's worker may not start
processes) and for a small job, the work is done here, one part after the other.
"""

from __future__ import annotations

import multiprocessing
import os
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any

from .blas import set_one_thread, thread_counts
from .errors import UserError

_shared: Any = None  # what the forked processes of fork_map find where it is


def processes() -> int:
    """How many processes work may be shared out to here: one per core, or the environment's
    ``DRIVE_BRIDGE_WORKERS`` (1: none); 1 where this process may not fork (see the module).

    Returns
    -------
    int
        The count.

    Raises
    ------
    UserError
        ``DRIVE_BRIDGE_WORKERS`` is not a number.
    """
    given = os.environ.get("DRIVE_BRIDGE_WORKERS")
    try:
        cap = int(given) if given else os.cpu_count() or 1
    except ValueError:
        raise UserError(f"DRIVE_BRIDGE_WORKERS={given!r}: give a number of processes (1: none)") from None
    if (
        cap < 2
        or multiprocessing.current_process().daemon
        or threading.active_count() > 1
        or not thread_counts()
    ):
        return 1
    return cap


def fork_map(
    func: Callable[[Any, Any], Any], items: Sequence[Any], count: int, shared: Any = None
) -> list[Any]:
    """``func(shared, item)`` for each of ``items``, in their order: here, one after the other,
    where ``count`` is 1; else in ``count`` processes forked from this one, each with one BLAS
    thread, which find ``shared`` where it is (only ``func`` and the items are sent, by pickle).

    Parameters
    ----------
    func : callable
        ``func(shared, item)``.
    items : sequence
        The items.
    count : int
        The processes.
    shared : object
        What every call shares.

    Returns
    -------
    list
        ``func``'s results, in the items' order.
    """
    if count < 2:
        return [func(shared, item) for item in items]
    global _shared
    _shared = shared
    try:
        with ProcessPoolExecutor(
            count, mp_context=multiprocessing.get_context("fork"), initializer=set_one_thread
        ) as pool:
            return list(pool.map(_call, [(func, item) for item in items]))
    finally:
        _shared = None


def _call(task: tuple[Callable[[Any, Any], Any], Any]) -> Any:
    func, item = task
    return func(_shared, item)
