"""OpenBLAS held at one thread while drive-bridge identifies, its count restored after."""

from __future__ import annotations

import os
import threading

import numpy as np
import pytest
import scipy.linalg  # noqa: F401 -- scipy's own OpenBLAS loaded beside numpy's

from drive_bridge import blas
from drive_bridge.ident import identify
from drive_bridge.sim.plantlog import write_log


def counts() -> list[int]:
    return [int(get()) for get, _ in blas.thread_counts()]


@pytest.fixture
def openblas():
    """Every loaded OpenBLAS at two threads (whatever OPENBLAS_NUM_THREADS started it with), set back after."""
    found = blas.thread_counts()
    if not found:
        pytest.skip("no OpenBLAS whose thread count can be set is loaded here (another BLAS library)")
    suite = counts()
    for _, put in found:
        put(2)
    before = counts()
    assert before == [2] * len(found)
    yield before
    assert counts() == before, "a test left OpenBLAS's thread count changed"
    for (_, put), count in zip(found, suite):
        put(count)


def test_one_thread_inside_and_the_count_before_after_the_last_context_closes(openblas):
    """Both wheels' libraries (numpy's and scipy's) at one thread inside; two threads of the
    process each in a context: the count comes back only when the second closes."""
    assert len(openblas) == 2  # numpy's and scipy's, as their wheels ship them
    first_in, second_in, first_out = threading.Event(), threading.Event(), threading.Event()
    seen = {}

    def second() -> None:
        first_in.wait()
        with blas.one_thread():
            second_in.set()
            first_out.wait()
            seen["after the first closed"] = counts()
        seen["after both closed"] = counts()

    worker = threading.Thread(target=second)
    worker.start()
    with blas.one_thread():
        seen["inside"] = counts()
        first_in.set()
        second_in.wait()
    first_out.set()
    worker.join()
    assert seen["inside"] == [1, 1]
    assert seen["after the first closed"] == [1, 1]
    assert seen["after both closed"] == openblas


def test_identify_computes_with_one_thread_and_leaves_the_count_as_it_was(openblas, tmp_path):
    """Read while it works (its progress is called inside), and after."""
    from harness.plants import closed_loop_log

    log = write_log(tmp_path / "log.csv", closed_loop_log(np.arange(20000) / 1000))
    during = []
    identify(log, seed=0, progress=lambda line: during.append(counts()))
    assert during and all(c == [1] * len(openblas) for c in during)


def test_a_command_runs_with_one_thread_and_leaves_the_count_and_the_environment_as_they_were(
    openblas, monkeypatch
):
    """What a command computes, and what it loads (a library started inside reads the
    environment), with one thread; afterwards the counts and OPENBLAS_NUM_THREADS as before."""
    from drive_bridge import cli

    monkeypatch.delenv(blas.ENVIRONMENT, raising=False)
    seen = {}

    def command(args) -> int:
        seen.update(counts=counts(), environment=os.environ.get(blas.ENVIRONMENT))
        return 0

    monkeypatch.setattr(cli, "_command", command)
    assert cli.main(["identify", "log.csv"]) == 0
    assert seen == {"counts": [1] * len(openblas), "environment": "1"}
    assert blas.ENVIRONMENT not in os.environ
