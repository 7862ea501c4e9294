"""An independent closed-loop plant for identification tests: none of ``drive_bridge.sim``.

A rigid axis J·q̈ = τ − c1·q̇ − c0·sign(q̇) − extra(q, q̇, q̈, t) (sticking at rest while the
net torque stays within c0) under a PI velocity / P
position cascade tracking a sum of sines, integrated with semi-implicit Euler at ``fs_int``,
sampled at the instants a logger stamped (``stamps``), position quantised to the encoder,
torque to 1 mNm, with seeded Gaussian noise.  SI, motor side.  The loop is compiled (numba; a
test's ``extra`` torque with it, as a C callback): the same numbers as the plain Python loop it
replaced, bit for bit, in a tenth of the time.
"""

from __future__ import annotations

import functools

import numpy as np
from numba import cfunc, njit, types

#: the signature of ``extra``: (q [rad], q̇ [rad/s], q̈ demanded [rad/s²], t [s]) -> torque [Nm]
EXTRA = types.float64(types.float64, types.float64, types.float64, types.float64)


def _none(q: float, v: float, a: float, t: float) -> float:
    return 0.0


@functools.cache
def _compiled(extra):
    """``extra`` (a Python function of plain arithmetic and numpy ufuncs) compiled for the loop
    (once per function: most logs have none, and each compilation took 26 ms)."""
    return cfunc(EXTRA)(extra if extra is not None else _none)


@njit(cache=True)
def _integrate(
    t, q_ref, v_ref, a_ref, T, J0, c0, c1, kp, kv, ki, extra, payload, coupled, J_l, k_s, d_s, lash
):
    """The cascade and the plant, semi-implicit Euler at every instant of ``t``: position and torque."""
    n = len(t)
    q = np.empty(n)
    tau = np.empty(n)
    qk, vk, integ = q_ref[0], v_ref[0], 0.0
    ql, vl = qk, vk
    for k in range(n):
        J = payload[1] if t[k] >= payload[0] else J0
        e_v = kp * (q_ref[k] - qk) + v_ref[k] - vk
        integ += ki * e_v * T
        u = kv * (e_v + integ)
        drive = u - extra(qk, vk, a_ref[k], t[k])
        if coupled:  # the load's reaction through the coupling
            twist = qk - ql
            twist = np.sign(twist) * max(0.0, abs(twist) - lash / 2)
            f_c = k_s * twist + (d_s * (vk - vl) if twist != 0.0 else 0.0)
            vl += T * f_c / J_l
            ql += vl * T
            drive -= f_c
        if vk == 0.0 and abs(drive) <= c0:
            pass  # stuck
        else:
            s_dir = np.sign(vk) if vk != 0.0 else np.sign(drive)
            v_new = vk + T / J * (drive - c1 * vk - c0 * s_dir)
            vk = 0.0 if vk != 0.0 and v_new * vk < 0 else v_new  # crossed zero: sticks
        qk += vk * T
        q[k], tau[k] = qk, u
    return q, tau


def closed_loop_log(
    stamps: np.ndarray,
    *,
    J: float = 1e-4,
    c0: float = 0.3,
    c1: float = 5e-4,
    extra=None,
    noise_Nm: float = 0.004,
    increments_per_rev: int = 2**16,
    seed: int = 0,
    fs_int: float = 10_000.0,
    payload: tuple[float, float] | None = None,
    coupling: tuple[float, float, float, float] | None = None,
    torque_lag_s: float = 0.0,
    multisine_hz: tuple[float, float] | None = None,
    drift_rad_s: float = 0.0,
) -> dict[str, np.ndarray]:
    """Columns ``time_s`` (the stamps), ``y_position_rad``, ``y_torque_Nm``; ``payload`` = (time [s],
    inertia after it [kg·m²]): a payload change during the log; ``coupling`` = (load inertia
    [kg·m²], mode frequency [Hz], damping ratio, backlash [rad]): the load hangs on the motor
    (inertia ``J``, which the friction acts on) through a spring-damper with a dead zone of
    ± backlash/2; the encoder reads the motor; ``torque_lag_s``: the torque logged is the one
    that held that long before its stamp (a drive reporting a delayed or averaged current);
    ``multisine_hz`` = (lowest, highest): the reference also carries a Schroeder-phased multisine
    over that band (every 0.25 Hz, 0.2 rad/s each), and the log its ``y_position_demand_rad``;
    ``drift_rad_s``: the reference also runs on at that speed (above 32 rad/s: it never turns back)."""
    T = 1.0 / fs_int
    n = int(np.ceil(stamps[-1] / T)) + 2
    t = np.arange(n) * T
    w1, w2 = 2 * np.pi * 0.4, 2 * np.pi * 1.1
    q_ref = 6.0 * np.sin(w1 * t) + 2.5 * np.sin(w2 * t + 0.3)
    v_ref = 6.0 * w1 * np.cos(w1 * t) + 2.5 * w2 * np.cos(w2 * t + 0.3)
    a_ref = -6.0 * w1**2 * np.sin(w1 * t) - 2.5 * w2**2 * np.sin(w2 * t + 0.3)
    q_ref, v_ref = q_ref + drift_rad_s * t, v_ref + drift_rad_s
    if multisine_hz is not None:
        freqs = np.arange(multisine_hz[0], multisine_hz[1] + 1e-9, 0.25)
        phases = -np.pi * np.arange(len(freqs)) ** 2 / len(freqs)
        for f_k, ph in zip(freqs, phases):
            w = 2 * np.pi * f_k
            amp = 0.2 / w  # 0.2 rad/s of velocity per line
            sine = np.sin(w * t + ph)
            q_ref = q_ref + amp * sine
            v_ref = v_ref + amp * w * np.cos(w * t + ph)
            a_ref = a_ref - amp * w * w * sine
    kp, kv, ki = 60.0, 0.08, 25.0
    J_l, f_mode, zeta, lash = coupling if coupling is not None else (1.0, 0.0, 0.0, 0.0)
    J_eff = J * J_l / (J + J_l)
    k_s = (2 * np.pi * f_mode) ** 2 * J_eff
    d_s = 2 * zeta * np.sqrt(k_s * J_eff)
    after = (float(payload[0]), float(payload[1])) if payload is not None else (np.inf, J)
    q, tau = _integrate(
        t,
        q_ref,
        v_ref,
        a_ref,
        T,
        J,
        c0,
        c1,
        kp,
        kv,
        ki,
        _compiled(extra),
        after,
        coupling is not None,
        J_l,
        k_s,
        d_s,
        lash,
    )
    rng = np.random.default_rng(seed)
    q_s = np.interp(stamps, t, q)
    tau_s = np.interp(stamps - torque_lag_s, t, tau) + noise_Nm * rng.standard_normal(len(stamps))
    inc = increments_per_rev / (2 * np.pi)
    out = {"time_s": stamps, "y_position_rad": np.floor(q_s * inc) / inc, "y_torque_Nm": np.round(tau_s, 3)}
    if multisine_hz is not None:
        out["y_position_demand_rad"] = np.interp(stamps, t, q_ref)
    return out


def jittered(rate_hz: float, duration_s: float, jitter_s: float, seed: int = 1) -> np.ndarray:
    """Stamps of a logger at ``rate_hz`` whose time stamps wander ±``jitter_s`` around the grid."""
    grid = np.arange(int(duration_s * rate_hz)) / rate_hz
    return grid + np.random.default_rng(seed).uniform(-jitter_s, jitter_s, len(grid))


def irregular(rate_hz: float, duration_s: float, lo_s: float, hi_s: float, seed: int = 2) -> np.ndarray:
    """Stamps of a logger that writes when it can: steps mostly near 1/rate, now and then up to ``hi_s``."""
    rng = np.random.default_rng(seed)
    steps = np.where(
        rng.random(int(duration_s * rate_hz)) < 0.02,
        rng.uniform(2 / rate_hz, hi_s, int(duration_s * rate_hz)),
        rng.uniform(lo_s, 1.3 / rate_hz, int(duration_s * rate_hz)),
    )
    t = np.cumsum(steps)
    return t[t < duration_s]


def averaged_torque_log(
    duration_s: float,
    period_s: float = 0.002,
    *,
    J: float = 1e-4,
    c0: float = 0.3,
    c1: float = 5e-4,
    accel: float = 3000.0,
    noise_Nm: float = 0.002,
    seed: int = 0,
    fs_int: float = 32_000.0,
) -> dict[str, np.ndarray]:
    """An axis made to follow trapezoidal moves (acceleration ±``accel`` for 0.1 s, then
    0.3 s at speed, each second), its torque J·q̈ + c1·q̇ + c0·sign(q̇) computed at
    ``fs_int`` and logged as a drive that reports its current averaged since the last report
    does: the mean over each period, stamped with the period's end, when the position is read
    (no quantisation of the position; Gaussian torque noise)."""
    T = 1.0 / fs_int
    sub = int(round(period_s * fs_int))
    n = int(round(duration_s / period_s)) * sub
    t = np.arange(1, n + 1) * T
    phase = t % 1.0
    a = np.select([phase < 0.1, phase < 0.4, phase < 0.6, phase < 0.9], [accel, 0.0, -accel, 0.0], accel)
    v = np.cumsum(a) * T
    v -= v.mean()
    tau = J * a + c1 * v + c0 * np.sign(v)
    q = np.cumsum(v) * T
    ends = np.arange(sub - 1, n, sub)
    noise = noise_Nm * np.random.default_rng(seed).standard_normal(len(ends))
    return {
        "time_s": t[ends],
        "y_position_rad": q[ends],
        "y_torque_Nm": tau.reshape(-1, sub).mean(axis=1) + noise,
    }


def joint_log(
    duration_s: float = 40.0,
    rate_hz: float = 200.0,
    *,
    J: float = 2.0,
    c0: float = 5.0,
    c1: float = 3.0,
    gravity_Nm: float = 60.0,
    centre_rad: float = -1.0,
    sines: tuple[tuple[float, float], ...] = ((0.6, 0.25), (0.3, 0.7)),
    noise_Nm: float = 0.2,
    seed: int = 0,
    clip_Nm: float | None = None,
    torque_sign: float = 1.0,
    fs_int: float = 5_000.0,
) -> dict[str, np.ndarray]:
    """A gravity-loaded rotary joint (a robot's shoulder: angle 0 with the arm horizontal), its own
    plant, not ``closed_loop_log``'s: J·q̈ = τ − c1·q̇ − c0·sign(q̇) − G·cos q under a PD position
    loop with the reference's inverse dynamics fed forward, tracking ``sines`` ((amplitude [rad],
    frequency [Hz]), ...) around ``centre_rad``.  Columns ``time_s``, ``j_position_rad`` (a 1e-4 rad
    grid), ``j_torque_Nm`` (noise, rounded to 1 mNm, clipped at ± ``clip_Nm`` as a logger's range or
    a current report that saturates while the drive's torque does not, times ``torque_sign``)."""
    T = 1.0 / fs_int
    t = np.arange(int(duration_s * fs_int)) * T
    ramp = 0.5 * (1 - np.cos(np.pi * np.minimum(t / 4.0, 1.0)))  # fade the motion in over 4 s
    q_ref = centre_rad + ramp * sum(a * np.sin(2 * np.pi * f * t) for a, f in sines)
    v_ref, a_ref = np.gradient(q_ref, T), np.gradient(np.gradient(q_ref, T), T)
    wn = 2 * np.pi * 15.0
    kp, kd = J * wn**2, 2 * 0.7 * J * wn
    q, tau = _joint(q_ref, v_ref, a_ref, T, J, c0, c1, gravity_Nm, kp, kd)
    stamps = np.arange(int(duration_s * rate_hz)) / rate_hz
    rng = np.random.default_rng(seed)
    tau_s = np.interp(stamps, t, tau) + noise_Nm * rng.standard_normal(len(stamps))
    if clip_Nm is not None:
        tau_s = np.clip(tau_s, -clip_Nm, clip_Nm)
    return {
        "time_s": stamps,
        "j_position_rad": np.round(np.interp(stamps, t, q), 4),
        "j_torque_Nm": torque_sign * np.round(tau_s, 3),
    }


def trapezoid_log(
    acceleration: float,
    *,
    velocity: float = 20.0,
    stroke: float = 3.0,
    duration_s: float = 30.0,
    J: float = 1e-4,
    c0: float = 0.3,
    c1: float = 5e-4,
    noise_Nm: float = 0.004,
    seed: int = 0,
    fs_int: float = 10_000.0,
) -> dict[str, np.ndarray]:
    """A rigid axis moved back and forth between ± ``stroke`` [rad] by trapezoids at ``velocity``
    [rad/s] and ``acceleration`` [rad/s²] with 0.3 s of rest at each end (a short acceleration
    phase at a high ``acceleration``), under the same PI velocity / P position cascade as
    ``closed_loop_log`` with the inertia's torque fed forward; logged at 1 kHz like it."""
    T = 1.0 / fs_int
    rest = np.full(int(0.3 * fs_int), 0.0)
    pieces, n = [rest - stroke], int(duration_s * fs_int)
    while sum(len(p) for p in pieces) < n:
        for a, b in ((-stroke, stroke), (stroke, -stroke)):
            pieces += [_move(a, b, velocity, acceleration, T), rest + b]
    q_ref = np.concatenate(pieces)[:n]
    v_ref = np.gradient(q_ref, T)
    a_ref = np.gradient(v_ref, T)
    q, tau = _trapezoid(q_ref, v_ref, a_ref, T, J, c0, c1, n, J)
    return _logged(np.arange(n) * T, q, tau, duration_s, noise_Nm, seed)


def campaign_log(
    *,
    max_velocity: float = 10.47,
    max_acceleration: float = 523.6,
    stroke: float = 12.0,
    fractions: tuple[float, ...] = (0.2, 0.4, 0.8),
    level_s: float = 8.0,
    J: float = 8.9e-5,
    c0: float = 0.22,
    c1: float = 3.1e-4,
    payload: tuple[float, float] | None = None,
    noise_Nm: float = 0.004,
    rate_hz: float = 500.0,
    seed: int = 0,
    fs_int: float = 10_000.0,
) -> dict[str, np.ndarray]:
    """A rigid axis through the paper's excitation, written here from its description (not
    ``drive_bridge.master.campaign``): for each velocity fraction, each acceleration fraction of
    ``max_velocity`` / ``max_acceleration``, ``level_s`` of trapezoids back and forth over
    ± ``stroke`` [rad] with 0.2 s of rest at each end; the cascade and plant of ``trapezoid_log``;
    ``payload`` = (time [s], inertia after it): a payload added part-way.  Logged at ``rate_hz`` as
    a SYNC-driven log is: the encoder's 2¹⁶ counts a turn, the torque with seeded noise, 1 mNm."""
    T = 1.0 / fs_int
    rest = int(0.2 * fs_int)
    pieces, here = [np.full(rest, -stroke)], -stroke
    for vf in fractions:
        for af in fractions:
            v, a, spent = vf * max_velocity, af * max_acceleration, 0
            while spent < level_s * fs_int:
                there = -here
                move = _move(here, there, v, a, T)
                pieces += [move, np.full(rest, there)]
                spent += len(move) + rest
                here = there
    q_ref = np.concatenate(pieces)
    v_ref = np.gradient(q_ref, T)
    a_ref = np.gradient(v_ref, T)
    n = len(q_ref)
    change, J_after = (int(payload[0] * fs_int), payload[1]) if payload is not None else (n, J)
    q, tau = _trapezoid(q_ref, v_ref, a_ref, T, J, c0, c1, change, J_after)
    return _logged(np.arange(n) * T, q, tau, (n - 1) * T, noise_Nm, seed, rate_hz)


def _move(p0: float, p1: float, v: float, a: float, T: float) -> np.ndarray:
    """A trapezoid (a triangle where the distance is short) from ``p0`` to ``p1``, sampled every ``T``."""
    dist = abs(p1 - p0)
    v = min(v, np.sqrt(dist * a))
    t_acc, t_end = v / a, dist / v + v / a
    t = np.arange(1, int(np.ceil(t_end / T)) + 1) * T
    t = np.minimum(t, t_end)
    s = np.where(
        t < t_acc,
        0.5 * a * t**2,
        np.where(t <= dist / v, 0.5 * a * t_acc**2 + v * (t - t_acc), dist - 0.5 * a * (t_end - t) ** 2),
    )
    return p0 + np.sign(p1 - p0) * s


def two_mass_log(
    duration_s: float = 40.0,
    *,
    J_motor: float = 0.6e-4,
    J_load: float = 0.4e-4,
    locked_hz: float = 45.0,
    zeta: float = 0.02,
    c0: float = 0.3,
    c1: float = 5e-4,
    velocity_loop_hz: float = 150.0,
    noise_Nm: float = 0.004,
    seed: int = 0,
    fs_int: float = 20_000.0,
) -> dict[str, np.ndarray]:
    """A motor driving a load through a lightly damped spring, its velocity loop stiff: a PI on the
    motor's velocity whose crossover ``velocity_loop_hz`` lies far above the mode, so the motor is
    held and the load rings against it at its locked-motor frequency ``locked_hz`` (√(k/J_load)/2π,
    damping ratio ``zeta``); a P position loop at an eighth of that, tracking three sines (0.3, 0.9,
    2.3 Hz) faded in over 2 s.  Friction c1·q̇ + c0·sign(q̇) acts on the motor, which sticks while
    the net torque stays within c0.  Its own structure and reference, not ``closed_loop_log``'s.
    Columns as ``closed_loop_log``'s, logged at 1 kHz (the encoder's 2¹⁶ counts a turn)."""
    T = 1.0 / fs_int
    k = (2 * np.pi * locked_hz) ** 2 * J_load
    d = 2 * zeta * np.sqrt(k * J_load)
    n = int(duration_s * fs_int)
    t = np.arange(n) * T
    fade = 0.5 * (1 - np.cos(np.pi * np.minimum(t / 2.0, 1.0)))
    q_ref = fade * sum(
        a * np.sin(2 * np.pi * f * t + i) for i, (a, f) in enumerate(((5.0, 0.3), (2.0, 0.9), (0.6, 2.3)))
    )
    v_ref = np.gradient(q_ref, T)
    wc = 2 * np.pi * velocity_loop_hz
    kv, ti, kp = J_motor * wc, 4 / wc, wc / 8
    q, tau = _two_mass(q_ref, v_ref, T, kp, kv, ti, k, d, J_motor, J_load, c0, c1)
    return _logged(t, q, tau, duration_s, noise_Nm, seed)


def _logged(
    t: np.ndarray,
    q: np.ndarray,
    tau: np.ndarray,
    duration_s: float,
    noise_Nm: float,
    seed: int,
    rate_hz: float = 1000.0,
) -> dict[str, np.ndarray]:
    """A plant's position and torque at the instants ``t`` [s], logged at ``rate_hz`` as
    closed_loop_log's are: the encoder's 2¹⁶ counts a turn, the torque with seeded noise rounded
    to 1 mNm."""
    stamps = np.arange(int(duration_s * rate_hz)) / rate_hz
    rng = np.random.default_rng(seed)
    inc = 2**16 / (2 * np.pi)
    return {
        "time_s": stamps,
        "y_position_rad": np.floor(np.interp(stamps, t, q) * inc) / inc,
        "y_torque_Nm": np.round(np.interp(stamps, t, tau) + noise_Nm * rng.standard_normal(len(stamps)), 3),
    }


# The loops of the plants above, compiled as closed_loop_log's is (the same numbers as the plain
# Python loops they replaced, bit for bit)


@njit(cache=True)
def _joint(q_ref, v_ref, a_ref, T, J, c0, c1, gravity_Nm, kp, kd):
    """joint_log's plant under its PD loop with the inverse dynamics fed forward: position, torque."""
    n = len(q_ref)
    q, tau = np.empty(n), np.empty(n)
    qk, vk = q_ref[0], 0.0
    for k in range(n):
        u = (
            J * a_ref[k]
            + c1 * v_ref[k]
            + c0 * np.sign(v_ref[k])
            + gravity_Nm * np.cos(q_ref[k])
            + kp * (q_ref[k] - qk)
            + kd * (v_ref[k] - vk)
        )
        acc = (u - c1 * vk - c0 * np.sign(vk) - gravity_Nm * np.cos(qk)) / J
        vk += acc * T
        qk += vk * T
        q[k], tau[k] = qk, u
    return q, tau


@njit(cache=True)
def _trapezoid(q_ref, v_ref, a_ref, T, J, c0, c1, change, J_after):
    """trapezoid_log's rigid axis under its cascade with the inertia ``J`` fed forward, the plant's
    inertia ``J_after`` from sample ``change`` on: position, torque."""
    n = len(q_ref)
    q, tau = np.empty(n), np.empty(n)
    qk, vk, integ = q_ref[0], 0.0, 0.0
    for k in range(n):
        e_v = 60.0 * (q_ref[k] - qk) + v_ref[k] - vk
        integ += 25.0 * e_v * T
        u = 0.08 * (e_v + integ) + J * a_ref[k]
        J_k = J if k < change else J_after
        if not (vk == 0.0 and abs(u) <= c0):
            s_dir = np.sign(vk) if vk != 0.0 else np.sign(u)
            v_new = vk + T / J_k * (u - c1 * vk - c0 * s_dir)
            vk = 0.0 if vk != 0.0 and v_new * vk < 0 else v_new
        qk += vk * T
        q[k], tau[k] = qk, u
    return q, tau


@njit(cache=True)
def _two_mass(q_ref, v_ref, T, kp, kv, ti, k, d, J_motor, J_load, c0, c1):
    """two_mass_log's motor, spring and load under the stiff velocity PI: motor position, torque."""
    n = len(q_ref)
    qm = vm = ql = vl = integ = 0.0
    q, tau = np.empty(n), np.empty(n)
    for i in range(n):
        e = kp * (q_ref[i] - qm) + v_ref[i] - vm
        integ += e * T / ti
        u = kv * (e + integ)
        spring = k * (qm - ql) + d * (vm - vl)
        vl += T * spring / J_load
        ql += T * vl
        net = u - spring
        if not (vm == 0.0 and abs(net) <= c0):
            v_new = vm + T / J_motor * (net - c1 * vm - c0 * (np.sign(vm) if vm != 0.0 else np.sign(net)))
            vm = 0.0 if vm != 0.0 and v_new * vm < 0 else v_new
        qm += T * vm
        q[i], tau[i] = qm, u
    return q, tau
