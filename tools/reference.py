"""Reference workloads the benchmarks measure in the same run, so that their speeds can be given
as ratios that another machine (or this one on another day: its speed moves by up to 2x) can
compare.

pump: a plain python-can exchange, single thread, no canopen, no physics: per 2 ms cycle the
master sends SYNC and 3 RPDOs, the drives' side (a second Bus on the same virtual channel)
receives them and sends 6 TPDOs, which the master receives and decodes with struct -- the frames
a 3-axis campaign puts on the bus per cycle.  Its speed [x real time] is what the bus itself
allows in Python here.

least_squares: the paper's identification done plainly on the same log -- a zero-phase
Butterworth on each axis' torque and a 3-column least squares (J, c1, c0) -- the floor under
drive-bridge's identification.
"""

from __future__ import annotations

import contextlib
import itertools
import statistics
import struct
import subprocess
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import can
import numpy as np
from scipy import signal

PERIOD_S = 0.002
_channels = itertools.count()


def pump(cycles: int = 20000, axes: int = 3) -> float:
    """Speed of the plain python-can pump [x real time at 2 ms per cycle]."""
    channel = f"reference-pump-{next(_channels)}"
    master = can.Bus(interface="virtual", channel=channel)
    drives = can.Bus(interface="virtual", channel=channel)
    rpdo = struct.Struct("<Hi")  # controlword, target position
    tpdo = (struct.Struct("<Hi"), struct.Struct("<ih"))  # statusword, position; velocity, torque
    try:
        sync = can.Message(arbitration_id=0x80, data=b"", is_extended_id=False)
        t0 = time.perf_counter()
        for k in range(cycles):
            master.send(sync)
            for a in range(axes):
                master.send(
                    can.Message(arbitration_id=0x201 + a, data=rpdo.pack(0x1F, k), is_extended_id=False)
                )
            for _ in range(axes + 1):
                drives.recv(timeout=0)
            for a in range(axes):
                drives.send(
                    can.Message(arbitration_id=0x181 + a, data=tpdo[0].pack(0x1237, k), is_extended_id=False)
                )
                drives.send(
                    can.Message(arbitration_id=0x281 + a, data=tpdo[1].pack(k, 7), is_extended_id=False)
                )
            for _ in range(2 * axes):
                msg = master.recv(timeout=0)
                tpdo[msg.arbitration_id >> 8 == 2].unpack(msg.data)
        wall = time.perf_counter() - t0
    finally:
        master.shutdown()
        drives.shutdown()
    return cycles * PERIOD_S / wall


def pumps(runs: int = 3) -> float:
    """The pump's speed [x real time]: the median of ``runs`` after one to warm up (the first run of a
    process is up to 1.5x slower here, and single runs scatter by 20 %)."""
    pump(2000)
    return statistics.median(pump() for _ in range(runs))


@contextlib.contextmanager
def worktree(root: Path, revision: str) -> Iterator[Path]:
    """A checkout of git ``revision`` of the repository at ``root``, removed afterwards."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "against"
        subprocess.run(
            ["git", "-C", str(root), "worktree", "add", "--detach", "-f", str(path), revision],
            check=True,
            capture_output=True,
        )
        try:
            yield path
        finally:
            subprocess.run(
                ["git", "-C", str(root), "worktree", "remove", "--force", str(path)], capture_output=True
            )


def stamp() -> str:
    """When and where: the date and this machine's processor and core count."""
    import os
    import platform

    return f"{time.strftime('%Y-%m-%d')}, {platform.machine()} {os.cpu_count()} cores, Python {platform.python_version()}"


def least_squares(t: np.ndarray, q: np.ndarray, tau: np.ndarray, cutoff_hz: float = 30.0) -> float:
    """Wall time [s] of the plain identification of one axis (filter, derivatives, 3-column lstsq)."""
    t0 = time.perf_counter()
    dt = float(np.median(np.diff(t)))
    sos = signal.butter(4, cutoff_hz * 2 * dt, output="sos")
    qf, tf = signal.sosfiltfilt(sos, q), signal.sosfiltfilt(sos, tau)
    qd = np.gradient(qf, dt)
    qdd = np.gradient(qd, dt)
    phi = np.column_stack((qdd, qd, np.sign(qd)))
    np.linalg.lstsq(phi, tf, rcond=None)
    return time.perf_counter() - t0


if __name__ == "__main__":
    print(stamp())
    print(f"pump: {pump():.1f}x real time (3 RPDOs + SYNC out, 6 TPDOs back and decoded per 2 ms cycle)")
