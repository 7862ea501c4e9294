"""The axes of one log identified side by side, one process per core.

Each axis's identification is independent of the others' and single-threaded Python and
numpy, so the axes of a large log go to worker processes forked from this one: they find the
log where it is (nothing is sent), and send back the result without the signals it was
filtered from, which the caller's log gives again (:meth:`.signals.Parallel.__getstate__`).
Results are the same as one axis after the other: every random search takes its seed.

Each worker runs OpenBLAS with one thread: with its own two threads in each of two workers the
run took three times as long.  Where that cannot be set (another BLAS library), where this
process runs other threads (a fork copies only the calling one: a lock another thread holds
would never be released in the child), in a daemon process (a pool's worker may not start
processes) and for a small log, the axes are identified one after the other here.
"""
from __future__ import annotations

import ctypes
import multiprocessing
import os
import threading
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from typing import Any

from ..errors import InternalError, UserError
from .logdata import Log

#: a log of fewer rows times axes is identified one axis after the other: starting the workers
#: costs more than they save
MIN_PARALLEL_SAMPLES = 500_000
#: the functions that set OpenBLAS's thread count, as numpy's and scipy's wheels name them
BLAS_THREADS = ("scipy_openblas_set_num_threads64_", "scipy_openblas_set_num_threads",
                "openblas_set_num_threads64_", "openblas_set_num_threads")

_shared: tuple[Log, Log | None] | None = None      # the log and validation log the workers read


def workers(log: Log, axes: list[str]) -> int:
    """How many processes identify ``axes`` of ``log`` (1: here, one after the other): one per
    axis up to the cores, or up to the environment's ``DRIVE_BRIDGE_WORKERS`` (then whatever the
    log's size; 1: never in parallel)."""
    given = os.environ.get("DRIVE_BRIDGE_WORKERS")
    try:
        cap = int(given) if given else os.cpu_count() or 1
    except ValueError:
        raise UserError(f"DRIVE_BRIDGE_WORKERS={given!r}: give a number of processes (1: none)") from None
    small = not given and len(log.t) * len(axes) < MIN_PARALLEL_SAMPLES
    if (cap < 2 or len(axes) < 2 or small or multiprocessing.current_process().daemon
            or threading.active_count() > 1 or not _blas_setters()):
        return 1
    return min(len(axes), cap)


def map_axes(run: Callable[..., Any], log: Log, val_log: Log | None, axes: list[str], count: int,
             **kwargs: Any) -> dict[str, tuple[str, Any]]:
    """``run(log, axis, val_log, **kwargs)`` for each of ``axes`` in ``count`` forked processes:
    per axis ("ok", its result with ``log`` attached again) or ("error", a UserError's message)."""
    global _shared
    _shared = (log, val_log)
    try:
        with ProcessPoolExecutor(count, mp_context=multiprocessing.get_context("fork"),
                                 initializer=_one_blas_thread) as pool:
            futures = {a: pool.submit(_run, run, a, kwargs) for a in axes}
            out = {a: f.result() for a, f in futures.items()}
    finally:
        _shared = None
    for status, result in out.values():
        if status == "ok":
            result.attach(log)
    return out


def _blas_setters() -> list[Callable[[int], None]]:
    """The thread-count setters of every OpenBLAS this process has loaded (numpy's and scipy's);
    none where one of them has no setter known here."""
    with open("/proc/self/maps", encoding="utf-8", errors="replace") as f:
        paths = sorted({line.split()[-1] for line in f if "openblas" in line.lower() and "/" in line})
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


def _run(run: Callable[..., Any], axis: str, kwargs: dict[str, Any]) -> tuple[str, Any]:
    if _shared is None:
        raise InternalError("a worker without its log")
    log, val_log = _shared
    try:
        return "ok", run(log, axis, val_log, **kwargs)
    except UserError as exc:
        return "error", str(exc)
