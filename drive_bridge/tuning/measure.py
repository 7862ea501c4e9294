"""The measure step: each axis's frequency response through its drive (:mod:`drive_bridge.ident.frf`).

One axis after the other sweeps ``SWEEP_SHARE`` of its stroke at a constant speed, centred,
while the master sends the periodic torque offset (0x60B2, ``OFFSET_SHARE`` of the drive's rated
torque RMS) with its setpoints.  For the run the drive holds the soft measurement gains
(:func:`~drive_bridge.tuning.design.measurement_gains`: KpP, KpS, KiS, written to RAM, not stored);
its own gains are written back whatever ends the run.  The response is computed from the positions
and from the offsets as the drive received them (in its units), with the controller the drive
holds as read back.  SI: rad, rad/s, Nm.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

import numpy as np

from ..cia.objects import TORQUE_OFFSET
from ..config import BusConfig, TimingLimits
from ..errors import DriveRefused, UserError
from ..ident.frf import PERIOD_SAMPLES, PERIODS, Frf, excitation, measure
from ..master.bringup import AxisLink
from ..master.campaign import Plan
from ..master.link import Link
from ..outputs import stamped
from ..params.cascade import controller
from ..params.controller import GAINS
from ..params.profile import SELECT, Profile
from ..params.read import read_parameters
from ..params.write import write_parameters
from . import motion
from .design import measurement_gains

log = logging.getLogger(__name__)

SWEEP_SHARE = 0.8  # of the stroke, centred
OFFSET_SHARE = 0.04  # RMS torque offset, × the drive's rated torque
SOFT = ("KpP", "KpS", "KiS")


def sweep(ax: AxisLink, period: float) -> tuple[np.ndarray, slice, float]:
    """The position demand [rad] of the measurement on ``ax``: from rest up to a constant speed at
    half the axis's acceleration limit, ``PERIODS`` periods of the excitation at that speed, and
    back to rest, over ``SWEEP_SHARE`` of the stroke, centred.

    Parameters
    ----------
    ax : AxisLink
        The axis (its limits).
    period : float
        The SYNC period [s].

    Returns
    -------
    demand : numpy.ndarray
        The position demand [rad].
    steady : slice
        The setpoints of the constant part.
    speed : float
        The constant speed [rad/s].
    """
    lim = ax.cfg.limits
    n = PERIOD_SAMPLES * PERIODS
    span = SWEEP_SHARE * (lim.position_max - lim.position_min)
    acc = 0.5 * lim.max_acceleration
    T = n * period  # speed · T + speed² / acc = span
    speed = min((-T + np.sqrt(T * T + 4 * span / acc)) * acc / 2, lim.max_velocity)
    ramp = int(np.ceil(speed / acc / period))
    acc = speed / (ramp * period)
    t = np.arange(1, ramp + 1) * period
    up = 0.5 * acc * t**2
    start = 0.5 * (lim.position_min + lim.position_max) - (speed * T + speed * ramp * period) / 2
    steady = up[-1] + speed * period * np.arange(1, n + 1)
    down = steady[-1] + speed * t - 0.5 * acc * t**2
    return start + np.concatenate((up, steady, down)), slice(ramp, ramp + n), float(speed)


def offset_of(ax: AxisLink, period: float, steady: slice, length: int) -> np.ndarray:
    """The torque offset per setpoint of a demand: the excitation over the steady part, nothing
    before or after.

    Parameters
    ----------
    ax : AxisLink
        The axis (its units and rated torque).
    period : float
        The SYNC period [s].
    steady : slice
        The setpoints of the constant part.
    length : int
        The demand's length.

    Returns
    -------
    numpy.ndarray
        [Nm] per setpoint, as the drive's units carry it.
    """
    sc = ax.cfg.scaling
    u = np.zeros(length)
    u[steady] = np.tile(excitation(1.0 / period, OFFSET_SHARE * sc.rated_torque_Nm), PERIODS)
    return sc.torque_from_device(sc.torque_to_device(u))


def unmeasurable(ax: AxisLink, profile: Profile) -> str | None:
    """Why an axis's response cannot be measured.

    Parameters
    ----------
    ax : AxisLink
        The brought-up axis (its RPDOs must carry the torque offset 0x60B2).
    profile : Profile
        Its drive's profile (it must hold the measurement's soft gains).

    Returns
    -------
    str or None
        Why; None: it can.
    """
    if TORQUE_OFFSET not in {i for c in ax.rpdos for i in c.objects}:
        return "the torque offset 0x60B2 is not in its RPDO mapping (map it in the node's rpdo in bus.yml)"
    missing = [g for g in profile.controller.drive_names(SOFT) if g not in profile.entries]
    if missing:
        return f"the {profile.drive} profile has no object for {', '.join(missing)} (the measurement's soft gains)"
    return None


def measure_axes(
    config: BusConfig,
    link: Link,
    axes: dict[str, AxisLink],
    profile: Profile,
    inertia: dict[str, float],
    on_plan: Callable[[Plan], Callable[[int], None] | None] | None = None,
) -> tuple[dict[str, Frf], dict[str, str]]:
    """The frequency response of each axis of ``axes`` that can be measured (``inertia``: its
    identified J, for the soft gains; ``on_plan``: :func:`~drive_bridge.tuning.motion.run`'s
    progress hook), and why each other one was not.

    Parameters
    ----------
    config : BusConfig
        The bus configuration.
    link : Link
        The link to the drives.
    axes : dict of str to AxisLink
        The brought-up axes.
    profile : Profile
        Their drive's profile.
    inertia : dict of str to float
        Per axis, its identified J [kg·m²], for the soft gains.
    on_plan : callable, optional
        :func:`~drive_bridge.tuning.motion.run`'s progress hook.

    Returns
    -------
    frfs : dict of str to Frf
        Per axis measured, its response.
    skipped : dict of str to str
        Per axis not measured, why.
    """
    period = config.master.sync_period_s
    skipped = {a: why for a, ax in axes.items() if (why := unmeasurable(ax, profile))}
    out = {}
    for a, ax in axes.items():
        if a in skipped:
            continue
        demand, steady, speed = sweep(ax, period)
        u = offset_of(ax, period, steady, len(demand))
        bound = profile.for_axis(ax)
        own = read_parameters(ax.node, bound, list(GAINS))  # the whole set: a drive may switch gain objects
        soft = {k: v for k, v in own.items() if k != SELECT} | measurement_gains(inertia[a], 1.0 / period)
        try:
            result = write_parameters(ax.node, bound, soft, store=False)
            if not result.ok:
                raise DriveRefused(f"axis {a}: the measurement's gains: {result.error}")
            held = read_parameters(ax.node, bound, list(SOFT))
            log.info(
                "axis %s: frequency response at %.3g rad/s with %s",
                a,
                speed,
                ", ".join(f"{g} {v:.4g}" for g, v in held.items()),
            )
            m = motion.run(
                config,
                link,
                {a: ax},
                {a: demand},
                kind="frequency response",
                torque_offset={a: u},
                on_plan=on_plan,
            )
        finally:
            write_parameters(ax.node, bound, own, store=False)
        if m.aborted is not None:
            raise m.aborted
        q = m.position[a][steady]
        if len(q) < steady.stop - steady.start:
            raise DriveRefused(f"axis {a}: position samples missing during the frequency response")
        filled = int(np.count_nonzero(~np.isfinite(q)))
        q = _filled(a, q, config.master.timing)
        if np.any(np.diff(q[PERIOD_SAMPLES:]) * np.sign(speed) < 0):
            raise UserError(
                f"axis {a}: the axis went back during the frequency response (the torque offset "
                f"outweighed the sweep at {speed:.3g} rad/s): friction changed side and the response "
                f"is not the plant's; a longer stroke in the limits, or leave the measure step out"
            )
        out[a] = measure(q, u[steady], 1.0 / period, controller(held, profile.controller.timing.tick_s))
        out[a].filled, out[a].late = filled, int(m.timing.engine.get("setpoints_late", 0) or 0)
    return out, skipped


def _filled(axis: str, position: np.ndarray, limits: TimingLimits) -> np.ndarray:
    """The sweep's positions with the samples a late master's skipped periods left out filled in
    linearly, where they stay within the run's timing limits (no run longer than the largest SYNC gap
    allowed, no more than the share of missing samples allowed); DriveRefused past them."""
    missing = ~np.isfinite(position)
    if not missing.any():
        return position
    edges = np.flatnonzero(np.diff(np.r_[0, missing.astype(np.int8), 0]))
    longest = int(np.max(edges[1::2] - edges[::2]))
    share = float(missing.mean() * 100)
    if longest >= limits.max_gap_periods or share > limits.max_missing_pct:
        raise DriveRefused(
            f"axis {axis}: position samples missing during the frequency response ({int(missing.sum())}, "
            f"up to {longest} in a row: past master.timing's limits)"
        )
    log.warning(
        "axis %s: %d position samples of the frequency response missing (late SYNCs), filled in linearly",
        axis,
        int(missing.sum()),
    )
    index = np.arange(len(position))
    out = position.copy()
    out[missing] = np.interp(index[missing], index[~missing], position[~missing])
    return out


def measure_plans(
    config: BusConfig, axes: dict[str, AxisLink], profile: Profile, start: dict[str, float]
) -> list:
    """Each axis's measurement, one after the other, for the preview.

    Parameters
    ----------
    config : BusConfig
        The bus configuration.
    axes : dict of str to AxisLink
        The brought-up axes.
    profile : Profile
        Their drive's profile.
    start : dict of str to float
        Where each axis starts [rad].

    Returns
    -------
    list of (str, Plan)
        Per axis that can be measured, a title and its plan (one that cannot does not move).
    """
    period = config.master.sync_period_s
    out = []
    for a, ax in axes.items():
        if unmeasurable(ax, profile):
            continue
        demand, steady, speed = sweep(ax, period)
        out.append(
            (
                f"measure {a}: frequency response, {speed:.3g} rad/s sweep with a torque-offset multisine "
                f"({OFFSET_SHARE:.0%} of rated torque RMS)",
                motion.plan(
                    config,
                    {a: ax},
                    {a: demand},
                    {a: start[a]},
                    kind="frequency response",
                    torque_offset={a: offset_of(ax, period, steady, len(demand))},
                )[0],
            )
        )
        start = {**start, a: float(demand[-1])}
    return out


def frf_doc(frfs: dict[str, Frf], skipped: dict[str, str]) -> dict:
    """frf.json's document.

    Parameters
    ----------
    frfs : dict of str to Frf
        Per axis measured, its response.
    skipped : dict of str to str
        Per axis not measured, why.

    Returns
    -------
    dict
        ``axes``: per axis measured its response (:meth:`Frf.as_json`); ``not_measured``: per
        other axis why; stamped (schema ``frf``).
    """
    return stamped("frf", {"axes": {a: f.as_json() for a, f in frfs.items()}, "not_measured": skipped})
