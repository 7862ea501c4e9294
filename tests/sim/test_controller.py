"""The controller structures a simulated drive runs (kernel ``STRUCT``, ``LOOP_DIV``) and the
profile's conversion between them (params/controller.py): a position PID written as the cascade's
equivalent follows a move as that cascade does, at the drive's own loop rate."""

from __future__ import annotations

import numpy as np
import pytest

from drive_bridge.params.controller import Controller
from drive_bridge.sim import kernel
from drive_bridge.sim.drive import plant_params
from drive_bridge.sim.gain_objects import GAIN_PARAMS, PID_PARAMS
from harness.support import clean_config

PID = Controller("position_pid", {"position": 1000.0, "velocity": None, "current": 8000.0})
CASCADE = {"KpP": 198.0, "FwF": 1.0, "KpS": 0.046, "KiS": 77.0, "KpC": 12.566, "KiC": 400.0}


def test_a_pid_is_the_cascade_and_back():
    drive = PID.to_drive({**CASCADE, "J": 1e-4, "c1": 5e-4, "c0": 0.3})
    assert drive["PidD"] == CASCADE["KpS"] and drive["PidFFa"] == 1e-4 and drive["PidFFv"] == 5e-4
    assert drive["PidP"] == pytest.approx(0.046 * (198 + 77)) and drive["PidI"] == pytest.approx(
        0.046 * 77 * 198
    )
    assert drive["c0"] == 0.3 and not {"KpP", "KpS", "KiS", "FwF", "J", "c1"} & set(drive)
    back = PID.from_drive(drive)
    for k in ("KpP", "KpS", "KiS", "FwF", "KpC", "KiC"):
        assert back[k] == pytest.approx(CASCADE[k], rel=1e-9), k
    assert PID.timing.tick_s == 1e-3


@pytest.mark.parametrize("values, why", [({"KpS": 0.1}, "together"), ({**CASCADE, "FwF": 0.8}, "FwF = 1")])
def test_a_set_the_pid_cannot_hold_is_refused(values, why):
    with pytest.raises(Exception, match=why):
        PID.to_drive(values)


def _follow(struct: float, gains: dict[str, float]) -> np.ndarray:
    """Following error [rad] of the simulated Y axis at a 1 kHz loop over a smooth 0.4 s move."""
    axis = clean_config().axes["y"]
    state, param, demand = kernel.new_arrays(1)
    p = param[0]
    plant_params(p, axis, ["y"])
    p[kernel.INC_PER_RAD] = 2**20 / (2 * np.pi)
    p[kernel.TMAX], p[kernel.FE_WINDOW], p[kernel.STRUCT], p[kernel.LOOP_DIV] = 5.0, 1e9, struct, 2.0
    cols = {**GAIN_PARAMS, **PID_PARAMS}  # the simulated drive's map: gain -> kernel column
    for k, v in gains.items():
        p[cols[k]] = v
    state[0, kernel.ENABLED] = 1.0
    t = np.arange(0, 0.6, 0.002)
    target = 20.0 * (1 - np.cos(np.pi * np.clip(t / 0.4, 0, 1))) / 2
    fe = []
    tick0 = np.zeros(1, dtype=np.int64)
    for k, x in enumerate(target):
        demand[0, kernel.P0], demand[0, kernel.P1] = demand[0, kernel.P1], x
        demand[0, kernel.A_FF] = (x - 2 * target[k - 1] + target[k - 2]) / 0.002**2 if k >= 2 else 0.0
        tick0[:] = 0
        kernel.advance(state, param, demand, tick0, 4, np.full(1, 4))
        fe.append(x - state[0, kernel.Q])
    return np.array(fe)


def test_the_kernel_runs_the_pid_as_the_cascade_it_was_written_from():
    cascade = _follow(kernel.CASCADE, CASCADE)
    pid = _follow(kernel.POSITION_PID, {k: v for k, v in PID.to_drive(CASCADE).items()})
    rms = np.sqrt(np.mean(cascade**2))
    assert 1e-4 < rms < 0.05  # it moved and followed
    assert np.sqrt(np.mean((pid - cascade) ** 2)) < 0.05 * rms


def test_a_1_khz_loop_holds_its_command_between_its_ticks():
    state, param, demand = kernel.new_arrays(1)
    plant_params(param[0], clean_config().axes["y"], ["y"])
    param[0, kernel.INC_PER_RAD], param[0, kernel.TMAX], param[0, kernel.FE_WINDOW] = 1e5, 5.0, 1e9
    param[0, kernel.LOOP_DIV], param[0, kernel.PID_P], param[0, kernel.STRUCT] = 2.0, 1.0, kernel.POSITION_PID
    state[0, kernel.ENABLED] = 1.0
    commands = []
    for k in range(8):
        demand[0, kernel.P0] = demand[0, kernel.P1] = 0.01 * (k + 1)  # a new demand every 2 kHz tick
        kernel.advance(state, param, demand, np.zeros(1, dtype=np.int64), 1, np.full(1, 4))
        commands.append(state[0, kernel.TCMD])
    assert all(commands[i] == commands[i + 1] for i in (1, 3, 5))  # held between its ticks
    assert all(commands[i] != commands[i + 1] for i in (0, 2, 4, 6))  # new on each of its ticks
