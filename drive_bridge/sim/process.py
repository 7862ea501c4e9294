"""Wall-clock simulation in a process of its own, on python-can's loopback multicast bus.

Real drives are other devices.  In one process, the drives' thread and the
master's threads take turns on one GIL and a drive now and then answers a SYNC
after the next one went out.  So the wall-clock simulation runs as a separate
process, the same :class:`~drive_bridge.sim.robot.SimRobot`, reached over
python-can's ``udp_multicast`` interface, which stamps every frame with the
kernel's reception time like a CAN controller does.
"""

from __future__ import annotations

import gc
import json
import select
import socket
import subprocess
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import IO, TYPE_CHECKING, cast

import can
import numpy as np

from ..cia.multicast import UDP_GROUP, LoopbackMulticastBus
from ..errors import BusError
from ..master.timing import lock_memory
from .kernel import Q

if TYPE_CHECKING:
    from .robot import SimRobot

GROUP = UDP_GROUP  # python-can's default IPv4 group; each run gets its own port
START_TIMEOUT_S = 120.0  # the child imports numpy/numba and loads the kernel


def free_port() -> int:
    """A UDP port free now.

    Returns
    -------
    int
        The port.
    """
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("", 0))
        return s.getsockname()[1]


class SimProcess:
    """The simulated robot of ``config_path`` running against the wall clock in a child process.

    The child prints ``ready`` once its drives are on the bus and stops when
    its standard input closes (so it also stops when this process dies).

    Parameters
    ----------
    config_path : str or Path
        The simulator's YAML.
    sync_period : float
        [s].
    eds : mapping of str to str or Path, optional
        Per axis, its drive's EDS/DCF.
    watch : str or Path, optional
        Where the child writes the plant as it moves (:class:`PlantWatch`; tests judge the axes on
        the wall clock by it).
    """

    def __init__(
        self,
        config_path: str | Path,
        sync_period: float,
        eds: Mapping[str, str | Path] | None = None,
        watch: str | Path | None = None,
    ):
        self.group, self.port = GROUP, free_port()
        self.bus = LoopbackMulticastBus(GROUP, self.port)  # the master's end, open before boot-up
        self.process = subprocess.Popen(
            [
                sys.executable,
                "-m",
                __name__,
                str(config_path),
                str(self.port),
                repr(sync_period),
                json.dumps({a: str(p) for a, p in (eds or {}).items()}),
                str(watch or ""),
            ],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        self._stdin, self._stdout = (
            cast(IO[str], self.process.stdin),
            cast(IO[str], self.process.stdout),
        )  # PIPEs
        ready = select.select([self._stdout], [], [], START_TIMEOUT_S)[0]
        if not ready or self._stdout.readline().strip() != "ready":
            self.shutdown()
            raise BusError(f"simulated drives did not start within {START_TIMEOUT_S:.0f} s")

    def shutdown(self) -> None:
        """Stop the child (its standard input closed), killed where it does not end."""
        if self.process.poll() is None:
            self._stdin.close()
            try:
                self.process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.process.kill()
        self._stdout.close()
        self.bus.shutdown()


WATCH_PERIOD_S = 0.005  # the plant watch's sample period [s of plant time]
WATCH_ROWS = 1 << 14  # rows of the watch kept in memory per block (82 s of plant time)


class PlantWatch:
    """``robot``'s plant as it moves, a row every :data:`WATCH_PERIOD_S` of its time: the wall-clock
    time it stands for [s, ``time.time()``'s], then per axis its position [rad] and its drive's CiA
    402 power state (:data:`~drive_bridge.cia.p402.STATE_BITS`'s keys).  The plant's own truth,
    beside anything a master reads from the drives.  Kept in memory while the drives run (nothing
    but a copy on their thread) and written to ``path`` by :meth:`close`.

    Parameters
    ----------
    robot : SimRobot
        The simulated robot, on the wall clock.
    path : Path
        The file (a header line names the columns).
    """

    def __init__(self, robot: SimRobot, path: Path):
        self.robot, self.path = robot, path
        self.names, self.drives = list(robot.drives), list(robot.drives.values())
        self.index = np.array([d.index for d in self.drives])
        self.blocks: list[np.ndarray] = []
        self.rows = 0
        self.due = robot.time
        robot.timers.append(self.sample)

    def sample(self, t: float) -> None:
        """The plant at plant time ``t``, where a row is due.

        Parameters
        ----------
        t : float
            [s].
        """
        if t < self.due:
            return
        self.due = t + WATCH_PERIOD_S
        if self.rows == len(self.blocks) * WATCH_ROWS:
            self.blocks.append(np.empty((WATCH_ROWS, 1 + 2 * len(self.drives))))
        row = self.blocks[-1][self.rows % WATCH_ROWS]
        row[0] = self.robot.wall_time(t)
        row[1::2] = self.robot.plant.state[self.index, Q]
        row[2::2] = [d.state for d in self.drives]
        self.rows += 1

    def close(self) -> None:
        """Write what was watched."""
        rows = (
            np.concatenate(self.blocks)[: self.rows]
            if self.blocks
            else np.empty((0, 1 + 2 * len(self.drives)))
        )
        header = "wall_s " + " ".join(f"{name}_rad {name}_state" for name in self.names)
        np.savetxt(
            self.path, rows, fmt=["%.6f"] + ["%.7f", "%d"] * len(self.drives), header=header, comments=""
        )


def serve(
    config_path: str | Path,
    bus: can.BusABC,
    sync_period: float,
    eds: dict[str, str],
    until: Callable[[], object],
    watch: str = "",
) -> None:
    """Run the simulated drives of ``config_path`` on ``bus`` against the wall clock; print
    ``ready`` once they are on the bus; ``until()`` returns when they are to stop.

    Parameters
    ----------
    config_path : str or Path
        The simulator's YAML.
    bus : can.BusABC
        The bus.
    sync_period : float
        [s].
    eds : dict of str to str
        Per axis, its drive's EDS/DCF.
    until : callable
        Returns when they are to stop.
    watch : str
        Where to write the plant as it moves (:class:`PlantWatch`); empty: nowhere.
    """
    from .robot import SimRobot
    from .robot_config import load_sim_config

    robot = SimRobot(load_sim_config(config_path), bus=bus, sync_period=sync_period, eds=eds)
    watched = PlantWatch(robot, Path(watch)) if watch else None
    # Out of the cycle collector's reach: a full collection walking three object dictionaries
    # stops the drives for tens of ms, longer than the master's missing-feedback limit.
    gc.collect()
    gc.freeze()
    lock_memory()  # where granted: no page fault holds the drives up
    robot.start_realtime()
    robot.power_on()
    print("ready", flush=True)
    try:
        until()
    finally:
        robot.shutdown()
        if watched is not None:
            watched.close()


def main(config_path: str, port: str, sync_period: str, eds: str = "{}", watch: str = "") -> None:
    """The child process: the drives on the UDP multicast bus until standard input closes.

    Parameters
    ----------
    config_path : str
        The simulator's YAML.
    port : str
        The UDP port.
    sync_period : str
        [s].
    eds : str
        JSON: per axis, its drive's EDS/DCF.
    watch : str
        Where to write the plant as it moves; empty: nowhere.
    """
    serve(
        config_path,
        LoopbackMulticastBus(GROUP, int(port), stamps="kernel"),
        float(sync_period),
        json.loads(eds),
        sys.stdin.read,
        watch,
    )  # until the master closes the pipe


if __name__ == "__main__":
    main(*sys.argv[1:])
