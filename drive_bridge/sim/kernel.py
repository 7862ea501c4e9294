"""Compiled cascade loops and plant of the simulated axes.

One call advances every axis by a number of velocity-loop ticks (2 kHz); each
tick runs the position P + velocity feed-forward and velocity PI loops once and
the current PI loop with the RL motor and the mechanical plant
``CURRENT_SUBSTEPS`` times (8 kHz).  Everything is SI, motor side: rad, rad/s,
Nm, A, V.  State and parameters are rows of float64 arrays indexed by the
constants below, so the loops compile once with numba and run without Python
objects in between.

Plant, per axis (``sign`` = direction of motion)::

    J*dv/dt = kt*i - load(q, t, other axes) - friction(v)
    load     = cp*q + D + load_Nm + A_per*sin(2*pi*q/period + phase)
    friction = (c1*wear1 + dc1*sign)*v + (c0*drift(t)*wear0 + dc0*sign + cpl*q_src + S*exp(-(v/vs)^2))*sign
    wear0    = 1 + W0*distance,  wear1 = 1 + W1*distance  (distance: the motor's travel [rad])

with stiction at rest: the axis stays stopped while the driving torque is
within the breakaway friction, and stops when its velocity crosses zero.  A compliant
transmission (``TM_SHARE`` > 0) hangs that share of J on the motor through a spring-damper
(``TM_K`` [Nm/rad], ``TM_D`` [Nm·s/rad]): the motor (encoder, friction, load torque) keeps
J·(1 − share) and also carries the spring's torque k·twist + d·(v − v_load); ``TWIST`` is the
motor's angle less the load's (zero at power-on: the spring unloaded).  With the power stage
off, an axis with a holding brake (``BRAKE`` = 1) stands still; one without is moved by its load
alone (a vertical axis whose load exceeds its friction falls).  Mechanical end stops
``END_LO`` < ``END_HI`` (where set) stop the axis dead.

Drive, per axis: its position and velocity loops run every ``LOOP_DIV``-th tick (a 1 kHz drive: 2),
as the cascade above or (``STRUCT`` = ``POSITION_PID``) as a position PID on the following error
whose D acts on its rate (demand velocity less measured) and whose output, with the velocity and
acceleration feed-forward ``PID_FFV``·v + ``PID_FFA``·a, is the torque command.  The position demand between two CSP setpoints is the parabola
through the last three (``A_FF`` is their second difference), so velocity and
acceleration demand are exact for a constant acceleration.  The velocity
feed-forward is the demand half a tick back, the instant the backward-difference
velocity refers to.  With the model feed-forward on, the torque command adds::

    J*a + (c1 + dc1*s)*v + (c0 + dc0*s)*s + offset + cp*p + A*sin(2*pi*p/period + phase)

of the demand (s = its direction), and the velocity integrator restarts from
zero when a move starts: the model, not a torque the integrator was left
holding against stiction, carries the axis.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

CURRENT_SUBSTEPS = 4  # current-loop ticks per velocity-loop tick (8 kHz / 2 kHz)
VELOCITY_TICK_S = 0.0005  # velocity / position loop period

# --- state columns -------------------------------------------------------------------
(
    Q,
    V,
    I,  # noqa: E741 (the motor current, as the equations write it)
    I_INT,
    V_INT,
    ENC,
    VMEAS,
    TCMD,
    PDEM,
    VDEM,
    FERR,
    FE_COUNT,
    T,
    ENABLED,
    I_SUM,
    I_COUNT,
    TWIST,
    V_LOAD,
    TICKS,
    DISTANCE,
) = range(20)
N_STATE = 20

# --- parameter columns ---------------------------------------------------------------
(
    J,
    C0,
    C1,
    CP,
    D,
    KT,
    R,
    L,
    VBUS,
    TMAX,
    INC_PER_RAD,
    KPP,
    FWF,
    KPS,
    KIS,
    KPC,
    KIC,
    FF_EN,
    FF_J,
    FF_C0,
    FF_C1,
    FF_OFF,
    FF_CP,
    FF_DC0,
    FF_DC1,
    FF_PER_AMP,
    FF_PER_PERIOD,
    FF_PER_PHASE,
    LOAD,
    PER_AMP,
    PER_PERIOD,
    PER_PHASE,
    STR_AMP,
    STR_VEL,
    ASYM_DC0,
    ASYM_DC1,
    CPL_SRC,
    CPL_COEF,
    DRIFT_FRAC,
    DRIFT_TAU,
    FE_WINDOW,
    BRAKE,
    END_LO,
    END_HI,
    TM_SHARE,
    TM_K,
    TM_D,
    STRUCT,
    LOOP_DIV,
    PID_P,
    PID_I,
    PID_D,
    PID_FFV,
    PID_FFA,
    WEAR_C0,
    WEAR_C1,
) = range(56)
N_PARAM = 56
CASCADE, POSITION_PID = 0.0, 1.0  # STRUCT: the controller structure the drive runs

# --- demand columns (one row per axis, set once per SYNC period) ----------------------
P0, P1, A_FF, V_OFF, T_OFF = range(5)
N_DEMAND = 5


@njit("float64(float64[::1])", cache=True)
def mean_current(state_row: np.ndarray) -> float:
    """Current [A] averaged since the last call (what a drive reports as actual torque/current
    is filtered over its report period, not one sample of the 8 kHz loop), then restart.

    Parameters
    ----------
    state_row : numpy.ndarray
        The axis's state row (its sum and count restarted).

    Returns
    -------
    float
        [A].
    """
    n = state_row[I_COUNT]
    mean = state_row[I_SUM] / n if n > 0 else state_row[I]
    state_row[I_SUM] = 0.0
    state_row[I_COUNT] = 0.0
    return mean


@njit(cache=True)
def _sign(x: float) -> float:
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    return 0.0


@njit(cache=True, nogil=True)
def advance(
    state: np.ndarray,
    param: np.ndarray,
    demand: np.ndarray,
    tick0: np.ndarray,
    n_ticks: int,
    period_ticks: np.ndarray,
) -> None:
    """Advance all axes by ``n_ticks`` velocity-loop ticks.

    ``tick0[a]`` is the number of ticks axis ``a`` has already done in the
    current interpolation period (counted on by ``n_ticks`` here); the position demand moves from
    ``P0`` to ``P1`` over ``period_ticks[a]`` ticks (its interpolation period, 0x60C2) and holds
    at ``P1`` after.

    Parameters
    ----------
    state, param, demand : numpy.ndarray
        One row per axis.
    tick0 : numpy.ndarray
        Per axis, the ticks done in its interpolation period.
    n_ticks : int
        Velocity-loop ticks.
    period_ticks : numpy.ndarray
        Per axis, its interpolation period in ticks.
    """
    n_axes = state.shape[0]
    dt_c = VELOCITY_TICK_S / CURRENT_SUBSTEPS
    for k in range(n_ticks):
        # ---------------- position + velocity loops (2 kHz / LOOP_DIV) ----------------
        for a in range(n_axes):
            s = state[a]
            p = param[a]
            d = demand[a]
            div = p[LOOP_DIV]
            s[TICKS] += 1.0
            if s[TICKS] < div:
                continue  # between two ticks of a slower loop: the command holds
            s[TICKS] = 0.0
            dt_v = VELOCITY_TICK_S * div
            inc = p[INC_PER_RAD]
            enc = math.floor(s[Q] * inc) / inc
            s[VMEAS] = (enc - s[ENC]) / dt_v
            s[ENC] = enc
            # demand at the instant the encoder is read (the start of this tick)
            frac = (tick0[a] + k) / period_ticks[a]
            period = period_ticks[a] * VELOCITY_TICK_S
            if frac >= 1.0:  # no new setpoint yet: hold the last one
                p_d, v_d, a_d = d[P1], 0.0, 0.0
            else:  # the parabola through the last three setpoints
                a_d = d[A_FF]
                tau = frac * period
                v0 = (d[P1] - d[P0]) / period - 0.5 * a_d * period
                p_d = d[P0] + (v0 + 0.5 * a_d * tau) * tau
                v_d = v0 + a_d * tau
            if p[FF_EN] != 0.0 and s[VDEM] == 0.0 and v_d != 0.0:
                s[V_INT] = 0.0  # motion starts: the model, not the integrator, carries the torque
            s[PDEM] = p_d
            s[VDEM] = v_d
            if s[ENABLED] == 0.0:
                s[V_INT] = 0.0
                s[TCMD] = 0.0
                s[FERR] = 0.0
                s[FE_COUNT] = 0.0
                continue
            ferr = p_d - enc
            s[FERR] = ferr
            if abs(ferr) > p[FE_WINDOW]:
                s[FE_COUNT] += 1.0
            else:
                s[FE_COUNT] = 0.0
            # velocity demand half a tick back: the instant the backward-difference velocity is of
            v_back = v_d - 0.5 * dt_v * a_d
            t_ff = d[T_OFF]
            if p[FF_EN] != 0.0:
                sg = _sign(v_d)
                t_ff += (
                    p[FF_J] * a_d
                    + (p[FF_C1] + p[FF_DC1] * sg) * v_d
                    + (p[FF_C0] + p[FF_DC0] * sg) * sg
                    + p[FF_OFF]
                    + p[FF_CP] * p_d
                )
                if p[FF_PER_PERIOD] > 0.0:
                    t_ff += p[FF_PER_AMP] * math.sin(2.0 * math.pi * p_d / p[FF_PER_PERIOD] + p[FF_PER_PHASE])
            if p[STRUCT] == POSITION_PID:
                integ = s[V_INT] + p[PID_I] * ferr * dt_v
                t_cmd = (
                    p[PID_P] * ferr
                    + integ
                    + p[PID_D] * (v_back + d[V_OFF] - s[VMEAS])
                    + p[PID_FFV] * v_d
                    + p[PID_FFA] * a_d
                    + t_ff
                )
            else:
                e_v = p[FWF] * v_back + p[KPP] * ferr + d[V_OFF] - s[VMEAS]
                integ = s[V_INT] + p[KIS] * e_v * dt_v
                t_cmd = p[KPS] * (e_v + integ) + t_ff
            if t_cmd > p[TMAX]:
                t_cmd = p[TMAX]
            elif t_cmd < -p[TMAX]:
                t_cmd = -p[TMAX]
            else:
                s[V_INT] = integ  # anti-windup: integrate only when not saturated
            s[TCMD] = t_cmd
        # ---------------- current loop, motor and mechanics (8 kHz) ----------------
        for _ in range(CURRENT_SUBSTEPS):
            for a in range(n_axes):
                s = state[a]
                p = param[a]
                if s[ENABLED] == 0.0:  # power stage off: no current; the brake, if any, holds
                    s[I] = 0.0
                    s[I_INT] = 0.0
                    if p[BRAKE] != 0.0:
                        s[V] = 0.0
                    continue
                kt = p[KT]
                e_i = s[TCMD] / kt - s[I]
                integ = s[I_INT] + p[KIC] * e_i * dt_c
                u = p[KPC] * (e_i + integ)
                if u > p[VBUS]:
                    u = p[VBUS]
                elif u < -p[VBUS]:
                    u = -p[VBUS]
                else:
                    s[I_INT] = integ
                decay = math.exp(-p[R] * dt_c / p[L])
                s[I] = s[I] * decay + (1.0 - decay) * (u - kt * s[V]) / p[R]
                s[I_SUM] += s[I]  # the drive reports the current averaged since its last report
                s[I_COUNT] += 1.0
            for a in range(n_axes):
                s = state[a]
                p = param[a]
                if s[ENABLED] == 0.0 and p[BRAKE] != 0.0:
                    continue
                q = s[Q]
                v = s[V]
                t_now = s[T]
                load = p[CP] * q + p[D] + p[LOAD]
                if p[PER_PERIOD] > 0.0:
                    load += p[PER_AMP] * math.sin(2.0 * math.pi * q / p[PER_PERIOD] + p[PER_PHASE])
                c0 = p[C0]
                if p[DRIFT_TAU] > 0.0:
                    c0 *= 1.0 + p[DRIFT_FRAC] * math.exp(-t_now / p[DRIFT_TAU])
                c1 = p[C1]
                if p[WEAR_C0] != 0.0 or p[WEAR_C1] != 0.0:  # friction that rises with the travel
                    c0 *= 1.0 + p[WEAR_C0] * s[DISTANCE]
                    c1 *= 1.0 + p[WEAR_C1] * s[DISTANCE]
                src = int(p[CPL_SRC])
                if src >= 0:
                    c0 += p[CPL_COEF] * state[src, Q]
                j_motor = p[J]
                if p[TM_SHARE] > 0.0:  # the load on its spring-damper
                    spring = p[TM_K] * s[TWIST] + p[TM_D] * (v - s[V_LOAD])
                    s[V_LOAD] += spring / (p[J] * p[TM_SHARE]) * dt_c
                    s[TWIST] += (v - s[V_LOAD]) * dt_c
                    load += spring
                    j_motor = p[J] * (1.0 - p[TM_SHARE])
                net = p[KT] * s[I] - load
                if v == 0.0:
                    sg = _sign(net)
                    breakaway = c0 + p[ASYM_DC0] * sg + p[STR_AMP]
                    if abs(net) <= breakaway:
                        continue
                    v_new = (net - breakaway * sg) / j_motor * dt_c
                else:
                    sg = _sign(v)
                    c0_dir = c0 + p[ASYM_DC0] * sg
                    if p[STR_VEL] > 0.0:
                        c0_dir += p[STR_AMP] * math.exp(-((v / p[STR_VEL]) ** 2))
                    friction = (c1 + p[ASYM_DC1] * sg) * v + c0_dir * sg
                    v_new = v + (net - friction) / j_motor * dt_c
                    if v_new * v < 0.0:  # crossed zero within the step: stick
                        v_new = 0.0
                q_new = q + 0.5 * (v + v_new) * dt_c
                if p[END_LO] < p[END_HI]:  # a mechanical end stop: the axis stops dead there
                    if q_new < p[END_LO]:
                        q_new = p[END_LO]
                        v_new = 0.0
                    elif q_new > p[END_HI]:
                        q_new = p[END_HI]
                        v_new = 0.0
                s[DISTANCE] += abs(q_new - q)
                s[Q] = q_new
                s[V] = v_new
        for a in range(n_axes):
            state[a, T] += VELOCITY_TICK_S
    for a in range(n_axes):
        tick0[a] += n_ticks


@njit(cache=True, nogil=True)
def follow(
    state: np.ndarray,
    param: np.ndarray,
    demand: np.ndarray,
    targets: np.ndarray,
    offsets: np.ndarray,
    n_ticks: int,
    period_ticks: np.ndarray,
    position: np.ndarray,
    current: np.ndarray,
) -> None:
    """Every axis through one SYNC period of ``n_ticks`` ticks per row of ``targets`` (position
    setpoints [rad], rows x axes) and ``offsets`` (torque offsets [Nm]), as a drive in CSP takes
    them: at each SYNC the position and the mean current since the last (into the rows of
    ``position`` and ``current``) are sampled, then the new setpoint starts its interpolation
    period (:func:`advance`, whose arithmetic is the same called from here: a bus-free log, one
    Python call per period before, is this loop's).

    Parameters
    ----------
    state, param, demand : numpy.ndarray
        One row per axis.
    targets : numpy.ndarray
        Position setpoints [rad], rows × axes.
    offsets : numpy.ndarray
        Torque offsets [Nm], rows × axes.
    n_ticks : int
        Velocity-loop ticks per period.
    period_ticks : numpy.ndarray
        Per axis, its interpolation period in ticks.
    position, current : numpy.ndarray
        Rows × axes, written: sampled at each SYNC.
    """
    n_axes = state.shape[0]
    tick0 = np.zeros(n_axes, dtype=np.int64)
    for k in range(targets.shape[0]):
        for a in range(n_axes):
            position[k, a] = state[a, Q]
        for a in range(n_axes):
            current[k, a] = mean_current(state[a])
        for a in range(n_axes):
            demand[a, P0] = demand[a, P1]
            demand[a, P1] = targets[k, a]
            demand[a, T_OFF] = offsets[k, a]
            tick0[a] = 0
        advance(state, param, demand, tick0, n_ticks, period_ticks)


def new_arrays(n_axes: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Zeroed (state, param, demand) arrays for ``n_axes`` axes.

    Parameters
    ----------
    n_axes : int
        The axes.

    Returns
    -------
    state, param, demand : numpy.ndarray
        One row per axis.
    """
    state = np.zeros((n_axes, N_STATE))
    param = np.zeros((n_axes, N_PARAM))
    param[:, CPL_SRC] = -1.0
    param[:, BRAKE] = 1.0
    param[:, LOOP_DIV] = 1.0
    demand = np.zeros((n_axes, N_DEMAND))
    return state, param, demand
