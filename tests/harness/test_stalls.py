"""The stall injector (harness/stalls.py): the master's main process and its engine's stopped
together for the length asked, at random moments; the simulated drives' process never."""

from __future__ import annotations

import json
import subprocess
import sys
import time

import numpy as np
import pytest

from harness.stalls import injector

pytestmark = [pytest.mark.realtime, pytest.mark.slow]

#: a process that notes the wall-clock time every millisecond for 3 s; its command line names the
#: role it plays (the engine's module, the drives' module)
TICKER = """
import sys, time
with open(sys.argv[1], "w") as out:
    t0 = time.time()
    while time.time() - t0 < 3.0:
        out.write(f"{time.time()}\\n")
        time.sleep(0.001)
"""
#: the master: starts an "engine" and a "drives" ticker and ticks itself
MASTER = """
import subprocess, sys
ticker, folder = sys.argv[1], sys.argv[2]
kids = [
    subprocess.Popen([sys.executable, "-c", ticker, folder + "/engine.txt", "drive_bridge.master.coprocess"]),
    subprocess.Popen([sys.executable, "-c", ticker, folder + "/drives.txt", "drive_bridge.sim.process"]),
]
exec(ticker.replace("sys.argv[1]", "folder + '/master.txt'"))
for kid in kids:
    kid.wait()
"""


def notes_within(path, began: float, lasted: float) -> int:
    """A ticker's notes inside a stall (its first and last 10 ms left out)."""
    t = np.loadtxt(path)
    return int(np.count_nonzero((t > began + 0.01) & (t < began + lasted - 0.01)))


def test_the_master_and_its_engine_stop_together_and_the_drives_never(tmp_path):
    master = subprocess.Popen([sys.executable, "-c", MASTER, TICKER, str(tmp_path)])
    time.sleep(0.3)  # its children started
    log = tmp_path / "stalls.jsonl"
    stalls = injector(master.pid, 0.1, 0.5, seed=3, log=log)
    try:
        master.wait(timeout=30)
    finally:
        stalls.terminate()
        stalls.wait()
    made = [json.loads(line) for line in log.read_text().splitlines()]
    assert len(made) >= 2
    assert all(0.1 <= s["lasted_s"] < 0.15 for s in made)
    assert all(len(s["pids"]) == 2 and s["pids"][0] == master.pid for s in made)  # the master, its engine
    for s in made:
        for role in ("master", "engine"):
            assert notes_within(tmp_path / f"{role}.txt", s["began"], s["lasted_s"]) == 0, (role, s)
        assert notes_within(tmp_path / "drives.txt", s["began"], s["lasted_s"]) > 0, s  # never stopped
