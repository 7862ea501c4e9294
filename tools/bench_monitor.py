"""Benchmark: the monitor on the wall clock.  The simulated drives in a process of their own on
udp_multicast, drive-bridge's master streaming a shift of pick-and-place to them (its cyclic
engine in a process of its own), and, listening beside them, the monitor (windows identified in
its worker process) and a plain python-can listener that only counts SYNCs -- the floor of what
this machine delivers to a listener, measured in the same run.

    python tools/bench_monitor.py [--shift-s 60] [--window-s 12] [--load idle|loaded]

Per run: SYNCs the master sent, the plain listener saw and the monitor saw; rows without a
complete sample; windows closed and how many determined J, c0 and c1.  ``loaded``: two
CPU-bound processes beside it.  The monitor is as good as the machine where it sees every SYNC
the plain listener sees.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from drive_bridge.cia.buses import open_bus
from drive_bridge.cia.p301 import SYNC_COB_ID
from drive_bridge.config import load_bus_config
from drive_bridge.connect import open_link
from drive_bridge.master.bringup import bring_up
from drive_bridge.master.homing import home
from drive_bridge.monitor import Monitor, Settings, listen
from drive_bridge.monitor.listen import Chunk
from drive_bridge.production import run_shift
from drive_bridge.resources import DEFAULT_BUS_CONFIG


def run(shift_s: float, window_s: float) -> dict:
    config = load_bus_config(DEFAULT_BUS_CONFIG)
    events: list[dict] = []
    monitor = Monitor(
        config,
        Path(tempfile.mkdtemp(prefix="bench-monitor-")),
        Settings(window_s=window_s, history=False),
        events.append,
        background=True,
    )
    rows = {"rows": 0, "incomplete": 0}
    add = monitor.add

    def counted(chunk: Chunk) -> None:
        valid = chunk.values[:, chunk.columns.index(f"{chunk.axis}_valid")]
        rows["rows"] += len(valid)
        rows["incomplete"] += int((valid == 0).sum())
        add(chunk)

    monitor.listener.on_chunk = counted
    plain = {"syncs": 0}
    stop = threading.Event()
    with open_link(config, sim=True, realtime=True) as link:
        drives = link.simulator  # type: ignore[attr-defined]

        def bus():
            return open_bus("udp_multicast", drives.group, None, {"port": drives.port})

        def count() -> None:
            b = bus()
            while not stop.is_set():
                msg = b.recv(0.1)
                if msg is not None and msg.arbitration_id == SYNC_COB_ID:
                    plain["syncs"] += 1
            b.shutdown()

        listener = threading.Thread(
            target=lambda: listen(monitor, config, lambda _: None, opener=bus, stop=stop)
        )
        counter = threading.Thread(target=count)
        axes = bring_up(link, config)
        home(link, axes, config)
        listener.start()
        counter.start()
        time.sleep(0.5)
        shift = run_shift(link, config, axes, shift_s, seed=5)
        time.sleep(1.0)
        stop.set()
        counter.join()
        listener.join()
    windows = [e for e in events if e["event"] == "window"]
    return {
        "syncs_sent": shift.cycles_sent,
        "plain_listener_syncs": plain["syncs"],
        "monitor_syncs": monitor.listener.syncs,
        "rows": rows["rows"],
        "rows_incomplete": rows["incomplete"],
        "windows": len(windows),
        "windows_determined": sum(w["determined"] for w in windows),
        "why_not": [f"{w['axis']}: {w['why']}" for w in windows if not w["determined"]],
        "aborted": None if shift.aborted is None else str(shift.aborted),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shift-s", type=float, default=60.0)
    parser.add_argument("--window-s", type=float, default=12.0)
    parser.add_argument("--load", choices=("idle", "loaded"), default="idle")
    args = parser.parse_args()
    hogs = []
    if args.load == "loaded":
        hogs = [subprocess.Popen([sys.executable, "-c", "while 1: pass"]) for _ in range(2)]
    try:
        print(json.dumps({"load": args.load, **run(args.shift_s, args.window_s)}, indent=1))
    finally:
        for h in hogs:
            h.kill()


if __name__ == "__main__":
    main()
