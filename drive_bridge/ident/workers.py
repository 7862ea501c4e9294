"""Work on a large log shared out to processes, one per core: its axes identified side by side,
its CSV parsed in parts.

Each axis's identification is independent of the others' and single-threaded Python and numpy,
so the axes of a large log go to worker processes forked from this one: they find the log where
it is (nothing is sent), and send back the result without the signals it was filtered from,
which the caller's log gives again (:meth:`.signals.Parallel.__getstate__`).  Results are the
same as one axis after the other: every random search takes its seed.

Each worker runs OpenBLAS with one thread: with its own two threads in each of two workers the
run took three times as long.  Where that cannot be set (another BLAS library), where this
process runs other threads (a fork copies only the calling one: a lock another thread holds
would never be released in the child), in a daemon process (a pool's worker may not start
processes) and for a small log, the work is done here, one part after the other.
"""
from __future__ import annotations

import ctypes
import multiprocessing
import os
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import TYPE_CHECKING, Any

from ..errors import UserError

if TYPE_CHECKING:
    from .logdata import Log

#: a log of fewer rows times axes is identified one axis after the other: starting the workers
#: costs more than they save
MIN_PARALLEL_SAMPLES = 500_000
#: the functions that set OpenBLAS's thread count, as numpy's and scipy's wheels name them
BLAS_THREADS = ("scipy_openblas_set_num_threads64_", "scipy_openblas_set_num_threads",
                "openblas_set_num_threads64_", "openblas_set_num_threads")

_shared: Any = None         # what the forked processes of fork_map find where it is


def processes() -> int:
    """How many processes work may be shared out to here: one per core, or the environment's
    ``DRIVE_BRIDGE_WORKERS`` (1: none); 1 where this process may not fork (see the module)."""
    given = os.environ.get("DRIVE_BRIDGE_WORKERS")
    try:
        cap = int(given) if given else os.cpu_count() or 1
    except ValueError:
        raise UserError(f"DRIVE_BRIDGE_WORKERS={given!r}: give a number of processes (1: none)") from None
    if (cap < 2 or multiprocessing.current_process().daemon or threading.active_count() > 1
            or not _blas_setters()):
        return 1
    return cap


def workers(log: Log, axes: list[str]) -> int:
    """How many processes identify ``axes`` of ``log`` (1: here, one after the other): one per
    axis up to :func:`processes`; for a small log only where ``DRIVE_BRIDGE_WORKERS`` asks."""
    if len(axes) < 2 or (not os.environ.get("DRIVE_BRIDGE_WORKERS")
                         and len(log.t) * len(axes) < MIN_PARALLEL_SAMPLES):
        return 1
    return min(len(axes), processes())


def fork_map(func: Callable[[Any, Any], Any], items: Sequence[Any], count: int, shared: Any = None) -> list[Any]:
    """``func(shared, item)`` for each of ``items``, in their order: here, one after the other,
    where ``count`` is 1; else in ``count`` processes forked from this one, each with one BLAS
    thread, which find ``shared`` where it is (only ``func`` and the items are sent, by pickle)."""
    if count < 2:
        return [func(shared, item) for item in items]
    global _shared
    _shared = shared
    try:
        with ProcessPoolExecutor(count, mp_context=multiprocessing.get_context("fork"),
                                 initializer=_one_blas_thread) as pool:
            return list(pool.map(_call, [(func, item) for item in items]))
    finally:
        _shared = None


def _blas_setters() -> list[Callable[[int], None]]:
    """The thread-count setters of every OpenBLAS this process has loaded (numpy's and scipy's);
    none where one of them has no setter known here."""
    try:
        with open("/proc/self/maps", encoding="utf-8", errors="replace") as f:     # Linux
            paths = sorted({line.split()[-1] for line in f if "openblas" in line.lower() and "/" in line})
    except OSError:
        return []
    setters = []
    for path in paths:
        lib = ctypes.CDLL(path)
        found = [getattr(lib, name) for name in BLAS_THREADS if hasattr(lib, name)]
        if not found:
            return []
        setters.append(found[0])
    return setters


def _one_blas_thread() -> None:
    for setter in _blas_setters():
        setter(1)


def _call(task: tuple[Callable[[Any, Any], Any], Any]) -> Any:
    func, item = task
    return func(_shared, item)
