"""Benchmark: the simulated drives alone.

    python tools/bench_sim.py

1. kernel: the cascade loops and plant of 3 axes (current loop 8 kHz, velocity and position
   loops 2 kHz) advanced one SYNC period (2 ms) per call, as the lockstep clock does;
2. bus: the 3 drives on python-can's virtual bus in lockstep, answering each SYNC with their
   TPDOs (2 per axis) after one RPDO per axis, the frames counted on a second bus.
Prints real-time factors.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from drive_bridge.sim import kernel  # noqa: E402
from drive_bridge.sim.adapters import FastVirtualBus  # noqa: E402
from drive_bridge.sim.robot import SimRobot  # noqa: E402
from drive_bridge.sim.robot_config import DEFAULT_CONFIG, load_sim_config  # noqa: E402
from tools.reference import pump, stamp  # noqa: E402

PERIOD = 0.002


def plant_kernel(seconds: float = 60.0) -> float:
    robot = SimRobot(load_sim_config(DEFAULT_CONFIG), "bench-kernel")
    robot.plant.state[:, kernel.ENABLED] = 1.0
    n = round(seconds / PERIOD)
    demand = np.sin(np.arange(n) * PERIOD * 2 * np.pi) * 5.0
    tick0 = np.zeros(3, dtype=np.int64)
    kernel.advance(
        robot.plant.state, robot.plant.param, robot.plant.demand, tick0, 1, np.full(3, 4, dtype=np.int64)
    )
    t0 = time.perf_counter()
    for k in range(1, n):
        robot.plant.demand[:, kernel.P0] = demand[k - 1]
        robot.plant.demand[:, kernel.P1] = demand[k]
        tick0[:] = 0
        kernel.advance(
            robot.plant.state, robot.plant.param, robot.plant.demand, tick0, 4, np.full(3, 4, dtype=np.int64)
        )
    wall = time.perf_counter() - t0
    robot.shutdown()
    return seconds / wall


def bus(seconds: float = 60.0) -> float:
    robot = SimRobot(load_sim_config(DEFAULT_CONFIG), "bench-bus")
    master = FastVirtualBus(channel="bench-bus", preserve_timestamps=True)
    master.direct = robot.bus.direct = True  # one thread: frames handed over as the lockstep link does
    import struct

    import can

    hold = {}
    for name, drive in robot.drives.items():  # NMT start, enable CSP (SDO-free shortcut)
        drive.on_nmt(bytes([1, 0]))
        drive.mode = 8
        load = robot.config.axes[name].effects.get("load", {}).get("LOAD", 0.0)
        drive.write(0x60B2, 0, round(load / drive.rated_torque * 1000))  # Z's weight held, as the master does
        drive.refresh_actuals()
        hold[drive.node_id] = drive._position_inc
        drive.write(0x607A, 0, hold[drive.node_id])  # the target preloaded where the axis stands
        for cw in (6, 7, 15):
            drive.write(0x6040, 0, cw)
    robot.process()
    n = round(seconds / PERIOD)
    frames = 0
    t0 = time.perf_counter()
    for _ in range(n):
        for drive in robot.drives.values():
            master.send(
                can.Message(
                    arbitration_id=0x200 + drive.node_id,
                    is_extended_id=False,
                    data=struct.pack("<Hi", 0x0F, hold[drive.node_id]),
                    timestamp=robot.time,
                )
            )
        master.send(can.Message(arbitration_id=0x80, data=b"", is_extended_id=False, timestamp=robot.time))
        robot.process()
        frames += sum(1 for _ in master.drain())
    wall = time.perf_counter() - t0
    master.shutdown()
    robot.shutdown()
    assert frames == 3 * n, frames  # default mapping: TPDO1 per axis, no EMCY
    return seconds / wall


if __name__ == "__main__":
    print(stamp())
    ref = pump()
    print(f"plain python-can pump (tools/reference.py): {ref:.1f}x real time")
    k = plant_kernel()
    print(f"kernel (3 axes, 8 kHz / 2 kHz): {k:.0f}x real time ({k / ref:.1f}x the pump)")
    b = bus()
    print(
        f"drives on the virtual bus, lockstep, answering SYNC: {b:.1f}x real time ({b / ref:.2f}x the pump)"
    )
