"""OpenBLAS's thread count: one while a command of drive-bridge's runs (:func:`drive_bridge.cli.main`)
and while :func:`drive_bridge.ident.identify` runs, as in every forked worker.

numpy's and scipy's wheels each load an OpenBLAS of their own, which starts a thread per core.
After a call large enough to be shared out (a least squares of tens of thousands of rows, the
product of such a matrix with itself) its threads wait for the next one spinning, on every core.
drive-bridge's matrices are tall and narrow (n × 3 to 20) or small (a drive's loops): a second
thread gains next to nothing, and its spinning takes the core from whatever else runs -- the
other axis's process, the simulated drives, the master's cyclic process, another test.  The full
paper campaign's log identified one axis after the other: 20.4-21.2 s of CPU with OpenBLAS's own
two threads, 12.8-13.9 s with one, the same wall clock; the test suite, 719 s of CPU (408 s) against
603 s (363 s), the same hour (2026-11-28, 2 cores).

Where a loaded OpenBLAS names no function to read or set its count (another BLAS library: nothing
known to set), nothing is changed.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import threading
from collections.abc import Callable, Iterator

#: (read, set) of the thread count, as numpy's and scipy's wheels and a plain OpenBLAS name them
THREAD_COUNT = (
    ("scipy_openblas_get_num_threads64_", "scipy_openblas_set_num_threads64_"),
    ("scipy_openblas_get_num_threads", "scipy_openblas_set_num_threads"),
    ("openblas_get_num_threads64_", "openblas_set_num_threads64_"),
    ("openblas_get_num_threads", "openblas_set_num_threads"),
)

#: what a newly loaded OpenBLAS reads its thread count from
ENVIRONMENT = "OPENBLAS_NUM_THREADS"

_lock = threading.Lock()
_held = 0  # the one_thread contexts open in this process
_before: list[tuple[Callable[[int], None], int]] = []  # each library's setter and its count before
_environment: str | None = None  # OPENBLAS_NUM_THREADS before


def thread_counts() -> list[tuple[Callable[[], int], Callable[[int], None]]]:
    """The thread count's (read, set) functions of every OpenBLAS this process has loaded.

    Returns
    -------
    list of (callable, callable)
        Per library, the function that reads its count and the one that sets it; empty where one
        of the libraries names neither pair known here (or where /proc cannot say what is loaded).
    """
    try:
        with open("/proc/self/maps", encoding="utf-8", errors="replace") as f:  # Linux
            paths = sorted({line.split()[-1] for line in f if "openblas" in line.lower() and "/" in line})
    except OSError:
        return []
    out = []
    for path in paths:
        lib = ctypes.CDLL(path)
        found = [
            (getattr(lib, get), getattr(lib, put))
            for get, put in THREAD_COUNT
            if hasattr(lib, get) and hasattr(lib, put)
        ]
        if not found:
            return []
        out.append(found[0])
    return out


def set_one_thread() -> None:
    """Every loaded OpenBLAS with one thread, for good (a process forked to compute its part)."""
    for _, put in thread_counts():
        put(1)


@contextlib.contextmanager
def one_thread() -> Iterator[None]:
    """Every loaded OpenBLAS with one thread inside, and one loaded inside starting with one
    (``OPENBLAS_NUM_THREADS``, where the environment does not set it already); the counts before
    and the environment restored after the last of the contexts open at once (threads of one
    process may each open one) closes.  A library first loaded inside keeps its one thread.

    Yields
    ------
    None
    """
    global _held, _before, _environment
    with _lock:
        if not _held:
            _before = [(put, int(get())) for get, put in thread_counts()]
            for put, _ in _before:
                put(1)
            _environment = os.environ.get(ENVIRONMENT)
            os.environ.setdefault(ENVIRONMENT, "1")
        _held += 1
    try:
        yield
    finally:
        with _lock:
            _held -= 1
            if not _held:
                for put, count in _before:
                    put(count)
                _before = []
                if _environment is None:
                    os.environ.pop(ENVIRONMENT, None)
