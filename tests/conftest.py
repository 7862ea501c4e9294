"""Fixtures: simulated robots on private virtual-bus channels, in lockstep (helpers in support.py)."""

from __future__ import annotations

import atexit
import gc
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

# Bytecode, and pytest's rewritten test modules, are cached in __pycache__ (git ignores it) even
# where PYTHONDONTWRITEBYTECODE is set, as container images set it: without the cache each worker
# compiled the package and rewrote every test module anew at each run (6.0 s of collection where
# the cache makes it 3.5), and each drive-bridge process a test starts compiled the package again;
# `pytest -m "not slow"` took 29.2-30.6 s here, 24.2-24.5 s with it (2026-11-27). Set before any
# module of the package is imported (the test modules import them as they are collected).
sys.dont_write_bytecode = False

# The simulator and its helpers are imported where a fixture uses them, not here: pytest-xdist's
# controlling process, which runs no test, loads this file too, and importing them (numba's
# kernels, scipy) cost it 1.3 of its 2.8 s of CPU in every run (2026-11-29).
from harness.paths import ROOT, VENDOR_EDS  # noqa: E402

if TYPE_CHECKING:
    from drive_bridge.sim.robot_config import SimConfig
    from harness.support import Bench

os.environ.setdefault("DRIVE_BRIDGE_VENDOR_EDS", str(VENDOR_EDS))  # vendor files, read in place
# every run the tests commission is kept in a history database of the tests', never the user's
os.environ["XDG_DATA_HOME"] = tempfile.mkdtemp(prefix="drive-bridge-tests-")
atexit.register(shutil.rmtree, os.environ["XDG_DATA_HOME"], ignore_errors=True)  # (left in /tmp before)
os.environ.pop("DRIVE_BRIDGE_DB", None)


@pytest.hookimpl(optionalhook=True)  # xdist's hook: without xdist (-p no:xdist) there is none
def pytest_xdist_auto_num_workers(config: pytest.Config) -> int:
    """``-n auto``: a worker per core, and one more. The suite waits as well as computes -- the
    wall-clock tests on their drives' processes and on the bus, others on the tools they run -- and
    a worker waiting holds its core idle: on this 2-core machine three workers took 204 s where two
    took 216-220 s, and beside two CPU-bound loops 353 s where two took 407 s (2026-11-27)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return cores + 1


def pytest_configure(config: pytest.Config) -> None:
    """On a fresh checkout, before pytest-xdist starts its workers: the simulator's compiled kernels
    made once, by a quick recording in a process of its own, for every worker and every process a
    test starts to load from numba's cache (``drive_bridge/sim/__pycache__``).  Without it each of
    them compiled the kernels itself, 2 s of CPU apiece, until one had written them: the suite's first
    run on a clone took 125 s where the next took 114 s (2026-11-29).  Where the cache holds them,
    nothing runs."""
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None):
        return  # a worker, or a run in one process (it compiles them once anyway)
    version = f"py{sys.version_info.major}{sys.version_info.minor}"
    if any((ROOT / "drive_bridge" / "sim" / "__pycache__").glob(f"*.{version}.nbi")):
        return
    env = {name: value for name, value in os.environ.items() if name != "PYTHONDONTWRITEBYTECODE"}
    with tempfile.TemporaryDirectory() as tmp:  # (what it records is not kept; a failure shows in the tests)
        command = [sys.executable, "-m", "drive_bridge", "record", "--sim", "--quick", "--out", f"{tmp}/run"]
        subprocess.run(command, cwd=ROOT, env=env, capture_output=True, timeout=600, check=False)


#: each test file's time in the last run measured with ``pytest --store-durations`` [s, wall, beside
#: the other workers], for the order the files are handed out in
DURATIONS = Path(__file__).with_name("durations.json")


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--store-durations",
        action="store_true",
        help=f"write each test file's time in this run to {DURATIONS.name} (the order files are run in)",
    )


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The longest test files first, by their times in tests/durations.json; a file not in it as long
    as the median file of its kind (slow, or not).  xdist hands a worker a whole file at a time (each
    file's module fixtures are built once), in this order (``--no-loadscope-reorder``,
    pyproject.toml): a long file left to start late ran on alone after the others were done, and
    files that wait (on drives' processes, on the wall clock) coming one after another left cores idle
    together.  Longest first, every worker takes its next file until the last, short ones, even out
    the end (the orders measured: docs/benchmarks.md)."""
    known = _stored_durations()
    slow = {_file_of(item.nodeid) for item in items if item.get_closest_marker("slow")}
    files = list(dict.fromkeys(_file_of(item.nodeid) for item in items))  # (in their collected order)

    def median(kind: bool) -> float:
        times = [known[f] for f in files if f in known and (f in slow) == kind]
        return statistics.median(times) if times else float(kind)

    guess = {True: median(True), False: median(False)}
    duration = {f: known.get(f, guess[f in slow]) for f in files}
    items.sort(key=lambda item: -duration[_file_of(item.nodeid)])  # (a stable sort: each file's order kept)


def _file_of(nodeid: str) -> str:
    """A test's file, as its node id names it (relative to the repository): the durations' key."""
    return nodeid.split("::", 1)[0]


def _stored_durations() -> dict[str, float]:
    return json.loads(DURATIONS.read_text()) if DURATIONS.is_file() else {}


_durations: dict[str, float] = {}


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    """(``--store-durations``) Each test's setup, call and teardown, added to its file's time."""
    path = _file_of(report.nodeid)
    _durations[path] = _durations.get(path, 0.0) + report.duration


def pytest_collection_finish(session: pytest.Session) -> None:
    """Once every test module is imported: what the imports made (250 000 objects and more: the
    package, numpy, scipy, matplotlib, canopen, pytest's own) is kept out of the cycle collector's
    reach, and its youngest generation is collected every 10 000 allocations instead of 700.  A
    worker runs for minutes, and each full collection went through all of it again: 60-75 of them
    a run, 0.2-0.5 s each, 15-18 s of the suite's CPU; 7 s with this (2026-11-29).  The collector
    still frees every cycle the tests make; a drive-bridge process keeps Python's own settings."""
    gc.collect()
    gc.freeze()
    gc.set_threshold(10_000, 10, 10)


@pytest.fixture(autouse=True, scope="module")
def _history_of_the_module(tmp_path_factory):
    """A history (and outbox) of each test file's own: a commissioning in one file is no drive's
    past in another (the module's fixtures run in it)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("XDG_DATA_HOME", str(tmp_path_factory.mktemp("data")))
        yield


@pytest.fixture(autouse=True)
def _history_of_the_test(tmp_path_factory, monkeypatch):
    """... and of each test: only what a test commissions itself is in its history."""
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path_factory.mktemp("data")))


@pytest.fixture
def bench():
    from harness.support import Bench, clean_config

    benches = []

    def make(config: SimConfig | None = None) -> Bench:
        b = Bench(config or clean_config())
        benches.append(b)
        return b

    yield make
    for b in benches:
        b.close()


@pytest.fixture(autouse=True)
def _close_benches():
    """Benches a test opened without the fixture are closed after it."""
    yield
    from harness.support import Bench

    for b in list(Bench.open):
        b.close()


@pytest.fixture
def shipped_sim_config():
    from drive_bridge.sim.robot_config import DEFAULT_CONFIG, load_sim_config

    return load_sim_config(DEFAULT_CONFIG)


#: what a skip for missing shared data says (every such skip's reason names the folder)
SHARED = "../shared"


def _shared_skips(reporter) -> list:
    """The skip reports of tests that wanted ``../shared``."""
    return [r for r in (reporter.stats.get("skipped", []) if reporter else []) if SHARED in str(r.longrepr)]


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    skipped = _shared_skips(terminalreporter)
    if skipped:
        terminalreporter.write_line(
            f"{len(skipped)} test(s) skipped: {SHARED} (the vendor files and real logs) is "
            f"not beside the repository",
            yellow=True,
        )


def pytest_sessionfinish(session, exitstatus):
    """With DRIVE_BRIDGE_REQUIRE_SHARED set (CI, where ../shared is beside the clone), a test
    skipped for want of it fails the run.  With ``--store-durations``, the files' times written
    (by the process that saw every test's report: xdist's controller, or the one process)."""
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    if os.environ.get("DRIVE_BRIDGE_REQUIRE_SHARED") and _shared_skips(reporter):
        session.exitstatus = pytest.ExitCode.TESTS_FAILED
    if session.config.getoption("store_durations") and not hasattr(session.config, "workerinput"):
        # a part run: the other files' times kept, those of files no longer there dropped
        times = {**_stored_durations(), **{path: round(seconds, 1) for path, seconds in _durations.items()}}
        kept = {path: times[path] for path in sorted(times) if (ROOT / path).is_file()}
        DURATIONS.write_text(json.dumps(kept, indent=1) + "\n")
