"""Compiled SYNC work of the simulated drives: what a drive does each period besides its loops.

A drive's CiA 402 values that change every period -- its actual values as the objects hold
them, its demand velocity, the newest setpoint and the watchdog's time -- are a row of a float64
array (the columns ``X_*``), as the loops' state is in :mod:`.kernel`: the Python drive
(:mod:`.drive`) reads and writes them through attributes, and the functions here, compiled
with numba, work on them directly.  :func:`actual_values` and :func:`follow_period` are the one
implementation both use; :func:`steady_period` is the whole SYNC of every drive in the
streaming steady state (:class:`~drive_bridge.sim.steady.SteadyStream` decides when), in one
call: the fault checks, actual values, TPDO bytes, the setpoints the RPDOs brought and the
next interpolation period.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .kernel import A_FF, FE_COUNT, FERR, INC_PER_RAD, KT, P0, P1, VMEAS, Q, mean_current, new_arrays

# --- drive columns: what a drive's CiA 402 side holds between SYNCs (one row per axis) ---
(
    X_POS_PER_RAD,
    X_VEL_PER_SI,
    X_ORIGIN,
    X_RATED_TORQUE,
    X_CURRENT_UNIT,
    X_NOISE,
    X_LAST_COUNT,
    X_LAST_TIME,
    X_VELOCITY,
    X_TORQUE_PM,
    X_CURRENT,
    X_POSITION,
    X_V_DEM,
    X_SETPOINT,
    X_NEW_TARGET,
    X_LIMITED,
    X_SETPOINT_TIME,
    X_ARMED,
) = range(18)
N_DRIVE = 18


@njit("void(float64[::1], float64[::1], float64[::1], float64, float64, boolean)", cache=True)
def actual_values(s: np.ndarray, p: np.ndarray, x: np.ndarray, now: float, noise: float, sync: bool) -> None:
    """Sample what a drive reports at ``now`` [s] into its drive row ``x``: position [position
    unit, counted from its origin], velocity [velocity unit: at a SYNC (``sync``) from the encoder
    counts since the SYNC before, the mean over the period; between SYNCs the velocity loop's own
    measurement, whoever asked before], torque [per mille of rated, its measurement noise ``x[X_NOISE]`` · ``noise``
    added] and current [its current unit], each rounded and clamped as the drive's object holds it.

    Parameters
    ----------
    s : numpy.ndarray
        The axis's kernel state row.
    p : numpy.ndarray
        Its kernel parameter row.
    x : numpy.ndarray
        Its drive row (written).
    now : float
        [s].
    noise : float
        A standard-normal sample.
    sync : bool
        At a SYNC.
    """
    inc = p[INC_PER_RAD]
    count = math.floor(s[Q] * inc)
    if not sync:
        x[X_VELOCITY] = round(s[VMEAS] * x[X_VEL_PER_SI])
    else:
        dt = now - x[X_LAST_TIME]
        if dt > 0:
            x[X_VELOCITY] = round((count - x[X_LAST_COUNT]) / dt / inc * x[X_VEL_PER_SI])
        x[X_LAST_COUNT] = count
        x[X_LAST_TIME] = now
    current = mean_current(s)
    torque = p[KT] * current
    if x[X_NOISE] != 0.0:
        torque += x[X_NOISE] * noise
    x[X_TORQUE_PM] = max(-32768, min(32767, round(torque / x[X_RATED_TORQUE] * 1000)))
    x[X_CURRENT] = max(-32768, min(32767, round(current / x[X_CURRENT_UNIT])))
    count -= round(x[X_ORIGIN] * inc)  # as the drive counts since homing
    pos = x[X_POS_PER_RAD]
    position = count if pos == inc else round(count / inc * pos)
    x[X_POSITION] = max(-2147483648, min(2147483647, position))


@njit("float64(float64[::1], float64)", cache=True)
def plant_position(x: np.ndarray, position: float) -> float:
    """A position in the drive's unit as the plant's [rad]: through the origin homing set.

    Parameters
    ----------
    x : numpy.ndarray
        The drive row (its units, its origin).
    position : float
        [position unit].

    Returns
    -------
    float
        [rad, plant].
    """
    return position / x[X_POS_PER_RAD] + x[X_ORIGIN]


@njit("float64(float64[::1], float64, float64, float64)", cache=True)
def soft_limit(x: np.ndarray, position: float, lo: float, hi: float) -> float:
    """``position`` [rad, plant] inside the software position limits ``lo`` < ``hi`` [position
    unit] (none where ``lo`` >= ``hi``); ``x[X_LIMITED]`` set when it had to be moved.

    Parameters
    ----------
    x : numpy.ndarray
        The drive row.
    position : float
        [rad, plant].
    lo, hi : float
        The limits [position unit].

    Returns
    -------
    float
        The position within them [rad, plant].
    """
    if lo >= hi:
        return position
    lo, hi = plant_position(x, lo), plant_position(x, hi)
    if position < lo or position > hi:
        x[X_LIMITED] = 1.0
        return min(max(position, lo), hi)
    return position


@njit("void(float64[::1], float64[::1], float64, float64, float64, boolean)", cache=True)
def follow_period(d: np.ndarray, x: np.ndarray, T: float, lo: float, hi: float, linear: bool) -> None:
    """The interpolation period that starts now, following the master (CSP, IP): the demand
    moves from where it is to the newest setpoint ``x[X_SETPOINT]`` [position unit] inside the
    software limits (``lo``, ``hi``); over ``T`` [s], with the acceleration feed-forward of the
    velocity change (none for linear interpolation).  A period without a new setpoint (its SYNC or
    RPDO missing) goes on at the last period's velocity, a substitute setpoint as drives make them
    (SEW's FCB19 extrapolates at constant speed) until the setpoint timeout stops the drive.

    Parameters
    ----------
    d : numpy.ndarray
        The axis's demand row (written).
    x : numpy.ndarray
        Its drive row.
    T : float
        The period [s].
    lo, hi : float
        The software limits [position unit].
    linear : bool
        Linear interpolation (no acceleration feed-forward).
    """
    p0 = d[P1]
    d[P0] = p0
    v_old = x[X_V_DEM]
    x[X_LIMITED] = 0.0
    if x[X_NEW_TARGET] != 0.0:
        p1 = soft_limit(x, plant_position(x, x[X_SETPOINT]), lo, hi)
    else:
        p1 = soft_limit(x, p0 + v_old * T, lo, hi)
    d[P1] = p1
    x[X_V_DEM] = (p1 - p0) / T
    d[A_FF] = 0.0 if linear else (x[X_V_DEM] - v_old) / T
    x[X_NEW_TARGET] = 0.0


# --- steady_period's tables ------------------------------------------------------------------
#: per axis: software limits [position unit], following-error ticks that fault, setpoint
#: timeout [s], statusword without bits 11 and 13, and the setpoint the RPDOs brought this period
(A_LO, A_HI, A_FE_TICKS, A_TIMEOUT, A_STATUS, A_SETPOINT, A_HAS_SETPOINT) = range(7)
N_AXIS = 7
#: per mapped TPDO entry, in the drives' order: axis, what it carries, its value where constant,
#: the TPDO (row of ``out``), byte offset, size [bytes] and the range its type holds
(E_AXIS, E_SOURCE, E_CONST, E_ROW, E_OFFSET, E_SIZE, E_MIN, E_MAX) = range(8)
N_ENTRY = 8
(SRC_STATUSWORD, SRC_POSITION, SRC_VELOCITY, SRC_TORQUE, SRC_CURRENT, SRC_FOLLOWING_ERROR, SRC_CONST) = range(
    7
)
#: steady_period's answers other than the noise index
SLOW, OUT_OF_RANGE = -1, -2


@njit(cache=True)
def _entry_value(src: int, a: int, state: np.ndarray, x: np.ndarray, axes: np.ndarray, const: int) -> int:
    if src == SRC_STATUSWORD:
        sw = int(axes[a, A_STATUS])
        if x[X_LIMITED] != 0.0:
            sw |= 0x0800
        if state[a, FE_COUNT] > 0:
            sw |= 0x2000
        return sw
    if src == SRC_POSITION:
        return int(x[X_POSITION])
    if src == SRC_VELOCITY:
        return int(x[X_VELOCITY])
    if src == SRC_TORQUE:
        return int(x[X_TORQUE_PM])
    if src == SRC_CURRENT:
        return int(x[X_CURRENT])
    if src == SRC_FOLLOWING_ERROR:
        return round(state[a, FERR] * x[X_POS_PER_RAD])
    return const


@njit(cache=True)
def steady_period(
    state: np.ndarray,
    param: np.ndarray,
    demand: np.ndarray,
    drive: np.ndarray,
    axes: np.ndarray,
    entries: np.ndarray,
    noise: np.ndarray,
    noise_i: int,
    now: float,
    T: float,
    out: np.ndarray,
) -> int:
    """One SYNC at ``now`` [s] of every drive, all following in CSP: each samples its actual
    values (drawing its torque noise from ``noise`` at ``noise_i``), packs its TPDOs into the rows
    of ``out`` as ``entries`` lay them out, takes the setpoint ``axes`` carries and starts the
    interpolation period of ``T`` [s].  Returns the next noise index, or ``SLOW`` before changing
    anything where a drive faults this period (following error, lost setpoints) -- the Python
    drive does that -- or ``OUT_OF_RANGE`` where a value does not fit its TPDO entry.

    Parameters
    ----------
    state, param, demand, drive : numpy.ndarray
        The plant's and drives' rows.
    axes : numpy.ndarray
        Per axis, what the compiled path needs of it.
    entries : numpy.ndarray
        The TPDO entries' layout.
    noise : numpy.ndarray
        The noise samples drawn ahead.
    noise_i : int
        The first unused one.
    now : float
        [s].
    T : float
        The period [s].
    out : numpy.ndarray
        The TPDO frames' bytes (written).

    Returns
    -------
    int
        The next noise index, ``SLOW`` or ``OUT_OF_RANGE``.
    """
    n = state.shape[0]
    for a in range(n):
        over = state[a, FE_COUNT]
        if over > 0 and over >= axes[a, A_FE_TICKS]:
            return SLOW
        if drive[a, X_ARMED] != 0.0 and now - drive[a, X_SETPOINT_TIME] > axes[a, A_TIMEOUT]:
            return SLOW
    e = 0
    for a in range(n):
        x = drive[a]
        sample = 0.0
        if x[X_NOISE] != 0.0:
            sample = noise[noise_i]
            noise_i += 1
        actual_values(state[a], param[a], x, now, sample, True)
        while e < entries.shape[0] and entries[e, E_AXIS] == a:
            value = _entry_value(entries[e, E_SOURCE], a, state, x, axes, entries[e, E_CONST])
            if value < entries[e, E_MIN] or value > entries[e, E_MAX]:
                return OUT_OF_RANGE
            row, offset = entries[e, E_ROW], entries[e, E_OFFSET]
            for b in range(entries[e, E_SIZE]):
                out[row, offset + b] = (value >> (8 * b)) & 0xFF
            e += 1
        if axes[a, A_HAS_SETPOINT] != 0.0:
            x[X_SETPOINT] = axes[a, A_SETPOINT]
            x[X_NEW_TARGET] = 1.0
            x[X_SETPOINT_TIME] = now
            x[X_ARMED] = 1.0
        follow_period(demand[a], x, T, axes[a, A_LO], axes[a, A_HI], False)
    return noise_i


def compile_all() -> None:
    """Compile (or load from numba's cache) :func:`steady_period` now, not while a clock runs (the
    others are compiled for their one signature when imported)."""
    state, param, demand = new_arrays(1)
    drive = np.zeros((1, N_DRIVE))
    param[0, INC_PER_RAD] = drive[0, X_POS_PER_RAD] = drive[0, X_RATED_TORQUE] = drive[0, X_CURRENT_UNIT] = (
        1.0
    )
    steady_period(
        state,
        param,
        demand,
        drive,
        np.zeros((1, N_AXIS)),
        np.zeros((0, N_ENTRY), dtype=np.int64),
        np.zeros(1),
        0,
        0.0,
        1.0,
        np.zeros((1, 8), dtype=np.uint8),
    )
