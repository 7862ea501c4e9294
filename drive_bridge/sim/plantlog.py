"""Logs straight from the simulated plant, without a bus: fast data for identification tests.

The axes follow a position demand in CSP (linear interpolation per SYNC
period) through the same compiled cascade and plant as the simulated drives,
with the factory gains of the project's drive (its EDS defaults); the log has the columns and the
quantisation of ``record``'s log.csv: encoder increments, torque in per mille
of rated torque, seeded measurement noise.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..outputs import write_table
from . import kernel
from .drive import plant_params
from .gain_objects import GAIN_PARAMS
from .robot_config import SimConfig
from .vendors import factory

INC_PER_REV = 2**20


def plant_log(
    config: SimConfig,
    demand: dict[str, np.ndarray],
    period: float = 0.002,
    torque_offset: dict[str, np.ndarray] | None = None,
    gains: dict[str, dict[str, float]] | None = None,
) -> dict[str, np.ndarray]:
    """The simulated plant and its drives' loops following a demand, bus-free, as a log.

    Parameters
    ----------
    config : SimConfig
        The simulated robot (:func:`~drive_bridge.sim.robot_config.load_sim_config`).
    demand : dict of str to numpy.ndarray
        Per axis, its position demand [rad] each period; axes without one hold their start
        position.
    period : float
        The period [s] (a SYNC's).
    torque_offset : dict of str to numpy.ndarray, optional
        Per axis, a torque [Nm] each period added to the torque command, as 0x60B2 is.
    gains : dict of str to dict, optional
        Per axis, the drive's gains (SI); else the factory's.

    Returns
    -------
    dict of str to numpy.ndarray
        The log's columns: ``time_s`` and per axis ``<axis>_position_rad``,
        ``<axis>_position_demand_rad`` and ``<axis>_torque_Nm``.
    """
    names = list(config.axes)
    n = len(next(iter(demand.values())))
    state, param, dem = kernel.new_arrays(len(names))
    inc_per_rad = INC_PER_REV / (2 * math.pi)
    rng = np.random.default_rng(config.seed)
    targets = np.zeros((n, len(names)))
    offsets = np.zeros((n, len(names)))
    for i, (name, axis) in enumerate(config.axes.items()):
        plant_params(param[i], axis, names)
        param[i, kernel.INC_PER_RAD] = inc_per_rad
        for gain, col in GAIN_PARAMS.items():
            param[i, col] = (gains or {}).get(name, factory().gains)[gain]
        param[i, kernel.TMAX] = factory().max_torque_permille / 1000.0 * axis.motor.rated_torque_Nm
        param[i, kernel.FE_WINDOW] = 1e9
        targets[:, i] = demand.get(name, np.zeros(n))
        offsets[:, i] = (torque_offset or {}).get(name, np.zeros(n))
        state[i, kernel.Q] = state[i, kernel.ENC] = dem[i, kernel.P0] = dem[i, kernel.P1] = targets[0, i]
        state[i, kernel.ENABLED] = 1.0
    ticks = round(period / kernel.VELOCITY_TICK_S)
    period_ticks = np.full(len(names), ticks, dtype=np.int64)  # interpolation over each SYNC period
    q = np.empty((n, len(names)))
    current = np.empty((n, len(names)))
    kernel.follow(state, param, dem, targets, offsets, ticks, period_ticks, q, current)  # sampled at SYNC
    cols = {"time_s": np.arange(n) * period}
    for i, (name, axis) in enumerate(config.axes.items()):
        rated = axis.motor.rated_torque_Nm
        torque = axis.motor.kt * current[:, i] + axis.torque_noise_Nm * rng.standard_normal(n)
        cols[f"{name}_position_rad"] = np.floor(q[:, i] * inc_per_rad) / inc_per_rad
        cols[f"{name}_position_demand_rad"] = targets[:, i]
        cols[f"{name}_torque_Nm"] = np.round(torque / rated * 1000) * rated / 1000
    return cols


def write_log(path: str | Path, cols: dict[str, np.ndarray]) -> Path:
    """Write columns as a log CSV (the format ``identify`` reads).

    Parameters
    ----------
    path : str or Path
        The file to write.
    cols : dict of str to numpy.ndarray
        The columns by name, as :func:`plant_log` gives them.

    Returns
    -------
    Path
        The file written.
    """
    return write_table(path, list(cols), np.column_stack(list(cols.values())), ["%.9g"] * len(cols))
