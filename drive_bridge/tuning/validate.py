"""Validation on reference trajectories: following error, overshoot, settling, model torque.

Each scenario (a set of parameters per axis: gains, model feed-forward) is
written to the drives without storing it, then the point-to-point moves and
the 3-D path are run; the metrics come from the logged feedback.  Following
error = setpoint − measured position [rad]; overshoot [%] and settling time
[s] (into ±2 % of the move) after each point-to-point move; the model torque
RMSE compares the measured torque with J·a + c1·v + c0·sign(v) (+ offset, cp,
dc0, dc1, position-periodic ripple) of the setpoint trajectory while it moves
(at rest the axis holds with whatever static friction gives) [Nm].

A scenario's model feed-forward runs in the drive where the drive profile has model objects,
else from the master (:mod:`.feedforward`: torque offset 0x60B2 with each setpoint); each run
records which, per axis, and why an axis had none.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Collection
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..config import BusConfig, Limits
from ..errors import DriveRefused, MotionAborted
from ..master.bringup import AxisLink
from ..master.campaign import Plan
from ..master.link import Link
from ..outputs import stamped, write_json
from ..params.check import ValueRefused, check_set
from ..params.profile import Profile
from ..params.read import read_parameters
from ..params.write import write_parameters
from . import motion, trajectories
from .feedforward import MODEL, MasterFeedForward, model_torque, route

log = logging.getLogger(__name__)

SETTLE_BAND = 0.02
MAX_TORQUE_LAG = 3  # cycles the logged torque may lag the demand it answers (setpoint -> SYNC -> TPDO)
STEP_GUARD = 2  # cycles either side of a change of the demand's acceleration ...
STEP_SHARE = 0.1  # ... a change of at least this share of the largest one


@dataclass
class AxisMetrics:
    """One axis on one run; following error [rad], settling [s], torque [Nm].  The model torque is
    compared with the logged torque ``torque_lag_cycles`` later: the whole-cycle delay (0 to
    :data:`MAX_TORQUE_LAG`) from a setpoint to the torque that answers it that fits the run best.
    ``torque_rmse_between_steps`` leaves out the samples around the demand's acceleration steps,
    where a sub-cycle timing difference dominates the error.

    Parameters
    ----------
    fe_rms, fe_max : float
        The following error's RMS and largest magnitude [rad].
    overshoot_pct : float or None
        The largest overshoot of a point-to-point move [% of the move]; None on the path.
    settling_s : float or None
        The longest settling into ``SETTLE_BAND`` of a move [s]; None on the path.
    torque_rmse : float
        The model torque's RMS error against the logged torque [Nm].
    torque_rms : float
        The logged torque's RMS [Nm].
    torque_lag_cycles : int, optional
        The lag the RMS error is taken at [SYNC cycles].
    torque_rmse_between_steps : float, optional
        The RMS error away from the acceleration steps [Nm].
    """

    fe_rms: float
    fe_max: float
    overshoot_pct: float | None
    settling_s: float | None
    torque_rmse: float
    torque_rms: float
    torque_lag_cycles: int | None = None
    torque_rmse_between_steps: float | None = None


@dataclass
class Run:
    """One scenario on one reference trajectory.

    Parameters
    ----------
    scenario : str
        The scenario (factory, tuned, ...).
    trajectory : str
        The reference trajectory (point_to_point, path).
    axes : dict of str to AxisMetrics
        Per axis, what was measured.
    aborted : str or None
        What stopped the run, where something did.
    motion : Motion, optional
        The logged run, for the plots.
    feedforward : dict of str to str
        Per axis, how the model feed-forward ran ("drive", "master: ...", "none: why").
    """

    scenario: str
    trajectory: str
    axes: dict[str, AxisMetrics]
    aborted: str | None
    motion: motion.Motion | None = field(default=None, repr=False)
    feedforward: dict[str, str] = field(default_factory=dict)

    def as_dict(self) -> dict:
        """The run as validate.json holds it.

        Returns
        -------
        dict
            Scenario, trajectory, what stopped it, per axis its metrics, the feed-forward and the
            run's timing.
        """
        return {
            "scenario": self.scenario,
            "trajectory": self.trajectory,
            "aborted": self.aborted,
            "axes": {a: asdict(m) for a, m in self.axes.items()},
            "feedforward": self.feedforward,
            "timing": None if self.motion is None else self.motion.timing.as_dict(),
        }


def metrics(
    m: motion.Motion,
    model: dict[str, dict[str, float]],
    period: float,
    moves: dict[str, list[tuple[int, float, float]]] | None,
) -> dict[str, AxisMetrics]:
    """What one run shows per axis.

    Parameters
    ----------
    m : Motion
        The logged run.
    model : dict of str to dict
        Per axis, the model whose torque the logged torque is compared with (SI).
    period : float
        The SYNC period [s].
    moves : dict of str to list of (int, float, float), optional
        Per axis, the point-to-point moves overshoot and settling are measured on (None: the
        path).

    Returns
    -------
    dict of str to AxisMetrics
        Per axis (NaN where the run stopped before the trajectory began).
    """
    out = {}
    rest = round(trajectories.REST_S / period)
    for a in m.position:
        fe = m.demand[a] - m.position[a]
        ok = np.isfinite(fe)
        if not ok.any():  # stopped before the trajectory began: nothing to measure
            nan = float("nan")
            out[a] = AxisMetrics(nan, nan, None, None, nan, nan)
            continue
        over = settle = None
        if moves:
            overs, settles = [], []
            for end, start, target in moves[a]:
                window = m.position[a][end : end + rest]
                dist = abs(target - start)
                if dist == 0 or len(window) < rest or not np.all(np.isfinite(window)):
                    continue
                overs.append(
                    max(0.0, float(np.max((window - target) * np.sign(target - start)))) / dist * 100
                )
                outside = np.flatnonzero(np.abs(window - target) > SETTLE_BAND * dist)
                settles.append(0.0 if len(outside) == 0 else (outside[-1] + 1) * period)
            over = max(overs) if overs else None
            settle = max(settles) if settles else None
        out[a] = AxisMetrics(
            float(np.sqrt(np.mean(fe[ok] ** 2))),
            float(np.max(np.abs(fe[ok]))),
            over,
            settle,
            *_torque_error(model.get(a, {}), m.demand[a], m.torque[a], ok, period),
        )
    return out


def _torque_error(
    model: dict[str, float], demand: np.ndarray, torque: np.ndarray, ok: np.ndarray, period: float
) -> tuple[float, float, int | None, float | None]:
    """Model torque RMSE [Nm], torque RMS [Nm], the lag [cycles] the RMSE is taken at, and the
    RMSE between the acceleration steps, over the moving samples (at rest: stiction)."""
    pred = model_torque(model, demand, period)
    okt = ok & np.isfinite(torque) & (np.abs(np.gradient(demand)) > 0)
    if not okt.any():
        okt = ok & np.isfinite(torque)
    jerk = np.abs(np.diff(np.gradient(np.gradient(demand)), prepend=0.0))
    steps = jerk > STEP_SHARE * jerk.max()  # the corners of the velocity profile
    near = np.convolve(steps, np.ones(2 * STEP_GUARD + 1 + MAX_TORQUE_LAG), "same") > 0
    best = None
    for lag in range(MAX_TORQUE_LAG + 1):
        p = np.concatenate([np.full(lag, np.nan), pred[: len(pred) - lag]])
        use = okt & np.isfinite(p)
        if not use.any():
            continue
        rmse = float(np.sqrt(np.mean((torque[use] - p[use]) ** 2)))
        if best is None or rmse < best[0]:
            between = use & ~near
            best = (
                rmse,
                lag,
                float(np.sqrt(np.mean((torque[between] - p[between]) ** 2))) if between.any() else None,
            )
    rms = float(np.sqrt(np.mean(torque[okt] ** 2)))
    if best is None:
        return float("nan"), rms, None, None
    return best[0], rms, best[1], best[2]


def reference_demands(
    limits: dict[str, Limits], period: float
) -> list[tuple[str, dict[str, np.ndarray], dict | None, float]]:
    """What each scenario runs, in order.

    Parameters
    ----------
    limits : dict of str to Limits
        Per axis, its limits.
    period : float
        The SYNC period [s].

    Returns
    -------
    list of (str, dict, dict or None, float)
        Per reference trajectory: its name, per axis its demand [rad] per SYNC, the moves
        overshoot and settling are measured on, and the share of the limits it runs at.
    """
    ptp, moves = trajectories.point_to_point(limits, period)
    return [
        ("point_to_point", ptp, moves, trajectories.PTP_LEVEL),
        ("path", trajectories.path(limits, period), None, trajectories.PATH_LEVEL),
    ]


def validate(
    config: BusConfig,
    link: Link,
    axes: dict[str, AxisLink],
    profile: Profile,
    scenarios: dict[str, dict[str, dict[str, float]]],
    model: dict[str, dict[str, float]],
    *,
    on_plan: Callable[[Plan], Callable[[int], None] | None] | None = None,
    master_feedforward: Collection[str] = frozenset(),
) -> list[Run]:
    """Run every scenario (name -> axis -> parameter values) on both reference trajectories.

    ``model`` (axis -> J, c0, c1, ...) predicts the torque the metrics compare with; ``on_plan``
    may return a progress callback for each run (as in ``record``).  Each parameter set is
    written without storing it; a scenario's model runs in the drive where the profile can write
    it, else from the master, and from the master in the scenarios named in
    ``master_feedforward`` (the drive's own model feed-forward then off).

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
    scenarios : dict of str to dict
        Scenario name -> axis -> parameter values (SI).
    model : dict of str to dict
        Per axis, J, c0, c1, ... (SI).
    on_plan : callable, optional
        May return a progress callback for each run.
    master_feedforward : collection of str
        The scenarios whose model feed-forward the master sends.

    Returns
    -------
    list of Run
        Every scenario on both trajectories, in order; a stopped run last (the runs after it did
        not move).
    """
    period = config.master.sync_period_s
    demands = reference_demands({a: axes[a].cfg.limits for a in axes}, period)
    runs = []
    for name, values in scenarios.items():
        ff: dict[str, MasterFeedForward] = {}
        how: dict[str, str] = {}
        for a, v in values.items():
            way = route(
                axes[a], profile, {k: x for k, x in v.items() if k in MODEL}, name in master_feedforward
            )
            if isinstance(way, MasterFeedForward):
                ff[a] = way
                v = {k: x for k, x in v.items() if k not in MODEL and k != "ff_enable"}
                if "ff_enable" in profile.entries:
                    v["ff_enable"] = 0  # the drive's own model off: the master's runs
            how[a] = way.describe() if isinstance(way, MasterFeedForward) else way
            res = write_parameters(axes[a].node, profile.for_axis(axes[a]), v, store=False)
            if not res.ok:
                raise DriveRefused(f"scenario {name}, axis {a}: {res.error}")
        for traj, demand, marks, level in demands:
            log.info(
                "scenario %s, %s: the model feed-forward %s",
                name,
                traj,
                "; ".join(f"{a} {h}" for a, h in how.items()),
            )
            m = motion.run(
                config, link, axes, demand, on_plan=on_plan, kind=traj, level=level, feedforward=ff
            )
            runs.append(
                Run(
                    name,
                    traj,
                    metrics(m, model, period, marks),
                    None if m.aborted is None else str(m.aborted),
                    m,
                    how,
                )
            )
            if m.aborted is not None:
                return runs  # stopped: no fault is reset and nothing moves again by itself
    return runs


VALIDATE_JSON, TRACES = "validate.json", "traces.npz"


def run_scenarios(
    config: BusConfig,
    link: Link,
    axes: dict[str, AxisLink],
    profile: Profile,
    scenarios: dict[str, dict[str, dict[str, float]]],
    model: dict[str, dict[str, float]],
    *,
    out_dir: str | Path | None = None,
    on_plan: Callable[[Plan], Callable[[int], None] | None] | None = None,
    master_feedforward: Collection[str] = frozenset(),
    refused: dict[str, str] | None = None,
) -> list[Run]:
    """The validate step: :func:`validate` with the drives left holding the parameters they had
    before (every parameter a scenario sets, read first and written back, not stored), and,
    with ``out_dir``, ``validate.json`` and the logged runs (``traces.npz``) kept there.
    A stopped run is in the result (see :func:`stopped`); the runs after it did not move.
    ``refused``: the scenarios the gain gate kept from the drives, and why (into validate.json).

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
    scenarios : dict of str to dict
        Scenario name -> axis -> parameter values (SI).
    model : dict of str to dict
        Per axis, J, c0, c1, ... (SI).
    out_dir : str or Path, optional
        Where validate.json and traces.npz are kept.
    on_plan : callable, optional
        May return a progress callback for each run.
    master_feedforward : collection of str
        The scenarios whose model feed-forward the master sends.
    refused : dict of str to str, optional
        The scenarios the gain gate kept from the drives, and why.

    Returns
    -------
    list of Run
        As :func:`validate`.
    """
    bound = {a: profile.for_axis(ax) for a, ax in axes.items()}  # each drive's, with its motor
    problems = [
        f"scenario {name}, axis {a}: {p}"
        for name, values in scenarios.items()
        for a, v in values.items()
        for p in check_set(bound[a], axes[a].node.object_dictionary, bound[a].drive_values(v))
    ]
    if problems:
        raise ValueRefused("refused before anything moved: " + "; ".join(problems))
    names = sorted({k for values in scenarios.values() for v in values.values() for k in v} | {"ff_enable"})
    held = {a: read_parameters(ax.node, bound[a], names) for a, ax in axes.items()}
    try:
        runs = validate(
            config,
            link,
            axes,
            profile,
            scenarios,
            model,
            on_plan=on_plan,
            master_feedforward=master_feedforward,
        )
    finally:
        for a, ax in axes.items():  # what the drive held, as it held it: not checked again
            write_parameters(ax.node, bound[a], held[a], store=False, check=False)
    if out_dir is not None:
        out = Path(out_dir)
        write_json(out / VALIDATE_JSON, validate_doc(runs, refused))
        traces: dict[str, Any] = {}  # arrays by name (numpy's keywords: "allow_pickle" is not one)
        for r in runs:
            m = r.motion
            if m is None:
                continue
            for a in m.position:
                key = f"{r.scenario}/{r.trajectory}/{a}"
                traces[key + "/t"] = m.t
                traces[key + "/position"], traces[key + "/demand"] = m.position[a], m.demand[a]
                traces[key + "/torque"] = m.torque[a]
        np.savez_compressed(out / TRACES, **traces)
    return runs


def validate_doc(runs: list[Run], refused: dict[str, str] | None = None) -> dict:
    """validate.json's and ``validate --json``'s document.

    Parameters
    ----------
    runs : list of Run
        The runs.
    refused : dict of str to str, optional
        The scenarios refused before anything moved, and why.

    Returns
    -------
    dict
        The runs and the refused scenarios, stamped (schema ``validate``).
    """
    return stamped("validate", {"runs": [r.as_dict() for r in runs], "refused": refused or {}})


def degraded(runs: list[Run]) -> list[str]:
    """Why wall-clock runs missed their timing limits.

    Parameters
    ----------
    runs : list of Run
        The runs.

    Returns
    -------
    list of str
        One per degraded run, with why (empty: none was).
    """
    return [
        f"{r.scenario}, {r.trajectory}: {'; '.join(r.motion.timing.reasons)}"
        for r in runs
        if r.motion is not None and r.motion.timing.degraded
    ]


def stopped(runs: list[Run]) -> MotionAborted | None:
    """The stop of the first run that was stopped, as the error to end the command with.

    Parameters
    ----------
    runs : list of Run
        The runs.

    Returns
    -------
    MotionAborted or None
        None where no run was stopped.
    """
    aborted = next((r for r in runs if r.aborted), None)
    if aborted is None:
        return None
    return MotionAborted(f"validation ({aborted.scenario}, {aborted.trajectory}): {aborted.aborted}")
