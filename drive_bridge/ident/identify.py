"""``identify``: from a log to each axis's model, with the residual traced (Python API).

results = identify("out/record", seed=0)
results["y"].model.params_, results["y"].after.rmse
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy import optimize, stats

from ..blas import one_thread
from ..errors import UserError
from ..forking import fork_map, processes
from .coverage import what_the_motion_tells
from .effects import DRIVE_EFFECTS, Effect, Gravity, Offset
from .frf import log_response
from .identifiable import SPREAD_MAX, T_MIN, undetermined
from .logdata import Log, read_log
from .model import (
    BASE,
    JACKKNIFE_BEYOND,
    JACKKNIFE_BLOCKS,
    MAX_DELAY_SAMPLES,
    AxisModel,
    Errors,
    errors,
    torque_delay,
)
from .resonance import find_mode
from .reversal import find_reversal_transient
from .signals import (
    FilterTooNarrow,
    Samples,
    Settings,
    choose_settings,
    clipped_levels,
    noise_floor,
    prepare,
    whole_band,
)
from .trace import MIN_GAIN, TracedEffect, trace, unexplained
from .uncertainty import Uncertainty

logger = logging.getLogger(__name__)

HOLDOUT_BLOCKS, HOLDOUT_EVERY = 10, 3  # without --validate: blocks 3, 6, 9 of 10 (by moving samples)
MIN_CUTOFF_BANDWIDTHS = 3.0  # a cut-off moved below a mode stays at least this many motion bandwidths
DELAY_SIGMAS = 3.0  # a torque delay estimated beyond this many std is aligned (model.torque_delay)
MAX_REALIGNMENTS = 3  # ... at most this many times while the tracing adds effects
CONSISTENT_SIGMAS = 3.0  # the slower and faster half's c0 or c1 differing by more: friction not linear
#: the consistency check's rate of flagging parts of the data that do hold one J, c0 and c1, over
#: the whole family of comparisons (measured: tools/bench_identify.py consistency)
FALSE_ALARM_RATE = 0.01
DETECTION_POWER = 0.95  # the consistency check states the step in J, c0, c1 it flags this often
DEGENERATE = 30.0  # a part whose refit has a J, c0 or c1 std this many times the whole fit's is degenerate,
#: a log of fewer rows times axes is identified one axis after the other: starting the workers
#: costs more than they save
MIN_PARALLEL_SAMPLES = 500_000
DEGENERATE_COND = 1e8  # ... as is one whose (column-scaled) regressors have a condition number above this


@dataclass
class GeneticFit:
    """The paper's genetic algorithm (differential evolution) on the final model's structure and
    the same cost.

    Parameters
    ----------
    coef : numpy.ndarray
        Its coefficients (``AxisModel.coef_names`` order, SI); where it did not converge before its
        generation limit, where the search stood.
    errors : Errors
        Its errors on the validation samples.
    converged : bool
        Whether the search converged before its generation limit.
    std_from_lse : float
        How far it lies from the least-squares minimum, at most, in the least-squares std (0
        where every std is 0).
    """

    coef: np.ndarray
    errors: Errors
    converged: bool
    std_from_lse: float

    @classmethod
    def of(cls, fitted: AxisModel, lse: Uncertainty, val: Samples) -> GeneticFit:
        """The GA's model set beside the least-squares one.

        Parameters
        ----------
        fitted : AxisModel
            The model fitted with ``method="ga"``.
        lse : Uncertainty
            The same structure fitted by least squares, with its std as reported.
        val : Samples
            The validation samples.

        Returns
        -------
        GeneticFit
            The GA's coefficients, errors on ``val`` and distance from ``lse``.
        """
        std = lse.coef_std
        ok = std > 0
        far = float(np.max(np.abs(fitted.coef_ - lse.model.coef_)[ok] / std[ok])) if ok.any() else 0.0
        return cls(fitted.coef_, errors(fitted, val), fitted.converged_, far)


@dataclass
class DriveFit:
    """What is written to a drive where the model has effects no drive model carries
    (effects.DRIVE_EFFECTS).

    Parameters
    ----------
    model : AxisModel
        The model refitted with only the effects a drive holds (the best values within that
        structure); or, where that refit leaves J, c0 or c1 undetermined, the full model.
    errors : Errors
        Its validation errors.
    param_std : dict of str to float
        The std of its parameters as reported [SI] (the full model's: the identification's).
    note : str, optional
        Why the full model is written, where it is.
    """

    model: AxisModel
    errors: Errors
    param_std: dict[str, float]
    note: str | None = None


@dataclass
class Diagnostics:
    """What the log and the fit tell beside the model, each apart from it (scikit-learn's rule:
    the estimator holds its fit, not the verdicts on it).

    Parameters
    ----------
    noise_floor : float
        The torque's noise the log allows no model to go below [Nm | N].
    unexplained : list of dict
        What the residual still depends on (:func:`.trace.unexplained`, a resonance, a transient
        after reversals).
    dropped : list of str
        Samples the log could not give, and why.
    sampling : dict
        What the log's time stamps held (``Log.sampling``), the torque's delay and clipping.
    consistency : dict
        J, c0, c1 refitted on parts of the data (:func:`consistency`).
    friction : dict
        The speeds c0 and c1 hold for, and whether they depend on which (:func:`friction_range`).
    resonance : dict, optional
        A resonance in the whole-band residual (:func:`.resonance.find_mode`), and the cut-off it
        moved from.
    backlash : dict, optional
        Residual energy concentrated after torque reversals (:mod:`.reversal`).
    motion : dict
        What the motion covers and which of c0, c1 it cannot determine
        (:func:`.coverage.what_the_motion_tells`).
    band : dict
        J refitted in half the band (:func:`band_dependence`): the band it holds across, or why not.
    undetermined : dict of str to str
        J, c0, c1 the data do not determine, and why (:func:`.identifiable.undetermined`).
    response : dict, optional
        The plant's torque -> velocity response read from the log (:func:`.frf.log_response`), for
        reference.
    """

    noise_floor: float
    unexplained: list[dict]
    dropped: list[str]
    sampling: dict
    consistency: dict
    friction: dict
    resonance: dict | None = None
    backlash: dict | None = None
    motion: dict = field(default_factory=dict)
    band: dict = field(default_factory=dict)
    undetermined: dict[str, str] = field(default_factory=dict)
    response: dict | None = None


@dataclass
class AxisResult:
    """One axis identified (:func:`identify`).

    Parameters
    ----------
    axis : str
        The axis.
    kind : {"rotary", "linear"}
        What its position is: an angle [rad] or a length [m].
    units : dict of str to str
        The units of its position, velocity, torque and parameters.
    settings : Settings
        How the samples were made: cut-off [Hz], decimation, rate [Hz], torque delay [s].
    validation : str
        Which samples validate, in words.
    est, val : Samples
        The estimation and validation samples.
    base : AxisModel
        The rigid model J·q̈ + c1·q̇ + c0·sign(q̇).
    model : AxisModel
        The final model: the base and the effects traced, its std from the jackknife too.
    uncertainty : Uncertainty
        The std of the model's parameters as reported: the model's, widened apart from it where
        the runs, the friction's speeds or the jackknife show it larger (:attr:`param_std`).
    effects : list of TracedEffect
        The effects traced, in the order they were added, each with its evidence.
    before, after : Errors
        The base and the final model's errors on the validation samples.
    ga : GeneticFit
        The genetic algorithm beside the least squares.
    diagnostics : Diagnostics
        What the log and the fit tell beside the model.
    drive : DriveFit, optional
        What is written to the drive where it differs from the model (None where the model's
        effects are all ones a drive holds).
    """

    axis: str
    kind: str
    units: dict[str, str]
    settings: Settings
    validation: str
    est: Samples
    val: Samples
    base: AxisModel
    model: AxisModel
    uncertainty: Uncertainty
    effects: list[TracedEffect]
    before: Errors
    after: Errors
    ga: GeneticFit
    diagnostics: Diagnostics
    drive: DriveFit | None = None

    @property
    def param_std(self) -> dict[str, float]:
        """The std of J, c0, c1 and every effect's parameters as reported (:attr:`uncertainty`) [SI]."""
        return self.uncertainty.param_std

    def attach(self, log: Log) -> None:
        """Give the samples back the log they were made of (a result from a worker process comes
        without it: :meth:`.signals.Parallel.__getstate__`).

        Parameters
        ----------
        log : Log
            The log identified.
        """
        for s in (self.est, self.val):
            if s.source is not None:
                s.source.log = log

    def as_json(self) -> dict:
        """The result as identify.json holds it per axis.

        Returns
        -------
        dict
            The axis in schema ``identify``: parameters and their std, errors before and after,
            the effects, the GA, the diagnostics, what is undetermined and why.
        """
        diagnostics = self.diagnostics
        drive = self.drive or DriveFit(self.model, self.after, self.param_std)
        return {
            "units": self.units,
            "samples": int(self.est.moving.sum()),
            "params": self.model.params_,
            "param_std": self.param_std,
            "uncertainty": {
                "method": "HAC (batch means over the residual's correlation length), widened to the "
                f"delete-one-block jackknife over {JACKKNIFE_BLOCKS} stretches in time where that is "
                f"{JACKKNIFE_BEYOND:g} times larger (where no two parts of the data could be compared: "
                f"wherever it is larger, consistency.inflated)",
                "jackknife_over_hac": {
                    k: round(float(self.model.jackknife_[i]), 3) for i, k in enumerate(("J", "c1", "c0"))
                },
            },
            "rmse_before": self.before.rmse,
            "rmse_after": self.after.rmse,
            "torque_rms": self.after.torque_rms,
            "noise_floor": diagnostics.noise_floor,
            "relative_error_before": self.before.relative_error,
            "relative_error_after": self.after.relative_error,
            "fit_relative_error_before": self.base.relative_error_,
            "fit_relative_error_after": self.model.relative_error_,
            "effects": [
                {
                    "name": t.effect.name,
                    "depends_on": t.effect.depends_on,
                    "params": t.params,
                    "rmse_after": t.rmse_after,
                    "relative_error_after": t.relative_error_after,
                    "fit_relative_error_after": t.fit_relative_error,
                    "model_params": t.model_params,
                    "evidence": t.evidence,
                }
                for t in self.effects
            ],
            "unexplained": diagnostics.unexplained,
            "validation": self.validation,
            "validation_samples": self.after.samples,
            "condition_number": self.model.cond_,
            "residual_std": self.model.sigma_,
            "ga": {
                "params": dict(zip(self.model.coef_names, map(float, self.ga.coef))),
                "rmse": self.ga.errors.rmse,
                "converged": self.ga.converged,
                "std_from_lse": self.ga.std_from_lse,
            },
            "settings": {
                "cutoff_hz": self.settings.cutoff_hz,
                "decimation": self.settings.decimation,
                "rate_hz": self.settings.rate_hz,
            },
            "dropped": diagnostics.dropped,
            "sampling": diagnostics.sampling,
            "consistency": diagnostics.consistency,
            "friction": diagnostics.friction,
            "drive_params": drive.model.params_,
            "drive_param_std": drive.param_std,
            "drive_rmse": drive.errors.rmse,
            "drive_note": drive.note,
            "motion": diagnostics.motion,
            "band": diagnostics.band,
            "identifiable": {p: p not in diagnostics.undetermined for p in ("J", "c0", "c1")},
            "undetermined": diagnostics.undetermined,
            "resonance": diagnostics.resonance,
            "backlash": diagnostics.backlash,
            "response": diagnostics.response,
        }


def _holdout(s: Samples) -> tuple[Samples, Samples, str]:
    order = np.cumsum(s.moving) * HOLDOUT_BLOCKS // max(1, s.moving.sum())
    block = np.minimum(order, HOLDOUT_BLOCKS - 1)
    held = (block % HOLDOUT_EVERY) == HOLDOUT_EVERY - 1
    spans = []
    for b in sorted(set(block[held].tolist())):
        t = s.t[(block == b) & s.moving]
        if len(t):
            spans.append(f"{t[0]:.1f}-{t[-1]:.1f} s")
    return (
        s.take(~held),
        s.take(held),
        f"held out of the same log: blocks {', '.join(str(b + 1) for b in sorted(set(block[held].tolist())))} "
        f"of {HOLDOUT_BLOCKS} by moving samples (t = {', '.join(spans)})",
    )


def refit_part(
    reported: Uncertainty, part: Samples, jackknife_blocks: int = 0
) -> tuple[AxisModel | None, str | None]:
    """A model's effects refitted on a part of the data.

    Parameters
    ----------
    reported : Uncertainty
        The fitted model (its effects' nonlinear parameters are kept) and its std as reported.
    part : Samples
        The part of the data.
    jackknife_blocks : int
        With more than 0, the refit's ``jackknife_`` holds the delete-one-block jackknife over
        that many stretches of the part, beside its HAC covariance.

    Returns
    -------
    fit : AxisModel or None
        The refit; None where the part cannot carry the model or is too short.
    why : str or None
        Why it cannot: its J, c0 or c1 std over ``DEGENERATE`` times the whole fit's, or its
        column-scaled regressors dependent beyond ``DEGENERATE_COND``; None where it can, or is
        merely too short.
    """
    model = reported.model
    if part.moving.sum() <= 3 * len(model.coef_):
        return None, None
    fit = AxisModel(model.effects, seed=model.seed, jackknife_blocks=jackknife_blocks).fit(part)
    phi = fit.design(part)[part.moving]
    scale = np.sqrt(np.mean(phi**2, axis=0))
    cond = float(np.linalg.cond(phi / np.where(scale > 0, scale, 1.0)))
    whole = reported.param_std
    wide = [p for p in ("J", "c0", "c1") if not fit.param_std_[p] <= DEGENERATE * whole[p]]
    if not wide and cond <= DEGENERATE_COND:
        return fit, None
    return None, (
        "its refit leaves "
        + (
            f"{', '.join(wide)} with a std over {DEGENERATE:g} times the whole fit's"
            if wide
            else f"the model's columns dependent (condition number {cond:.2g})"
        )
        + ": this part does not determine the model's terms"
    )


def _base_covariance(fit: AxisModel) -> np.ndarray:
    """The covariance of a part's J, c1, c0 (:data:`.model.BASE` order) for setting it against
    other parts: HAC, each std widened to the part's own delete-one-block jackknife wherever that
    is larger (the HAC alone, on trapezoids, flagged 28 % of clean runs)."""
    ratio = np.asarray(fit.jackknife_[: len(BASE)], dtype=float)
    # cov_ already carries the ratios above JACKKNIFE_BEYOND; the rest are applied here
    scale = np.where((ratio > 1.0) & (ratio <= JACKKNIFE_BEYOND), ratio, 1.0)
    return fit.cov_[: len(BASE), : len(BASE)] * np.outer(scale, scale)


def _same_values(
    estimates: dict[str, tuple[np.ndarray, np.ndarray]], unit: np.ndarray
) -> tuple[dict, dict[str, float]]:
    """The chi-squared test that every part holds one and the same J, c1, c0: each part's
    difference from their pooled (inverse-covariance-weighted) value in its own covariance,
    summed, on 3·(parts − 1) degrees of freedom; and per parameter the same on its own.

    ``estimates`` maps each part to (J, c1, c0) and their covariance; ``unit`` is the scale each
    parameter is compared in (the whole fit's std: the sums are then well conditioned)."""
    values = {n: v / unit for n, (v, _) in estimates.items()}
    infos = {n: np.linalg.pinv(c / np.outer(unit, unit)) for n, (_, c) in estimates.items()}
    pooled = np.linalg.lstsq(sum(infos.values()), sum(infos[n] @ values[n] for n in values), rcond=None)[0]
    statistic = float(sum((values[n] - pooled) @ infos[n] @ (values[n] - pooled) for n in values))
    dof = len(BASE) * (len(values) - 1)
    each = {}
    for i, p in enumerate(BASE):
        weights = {n: 1.0 / (c[i, i] / unit[i] ** 2) for n, (_, c) in estimates.items() if c[i, i] > 0}
        if len(weights) < 2:  # no two parts with a std for it: nothing to set against
            each[p] = 1.0
            continue
        mean = sum(weights[n] * values[n][i] for n in weights) / sum(weights.values())
        part_stat = float(sum(weights[n] * (values[n][i] - mean) ** 2 for n in weights))
        each[p] = float(stats.chi2.sf(part_stat, len(weights) - 1))
    return {"chi2": round(statistic, 2), "dof": dof, "p_value": float(stats.chi2.sf(statistic, dof))}, each


def _detectable_steps(estimates: dict, dof: int, reported: Uncertainty) -> dict:
    """The step in J, c0 and c1 between the estimation halves the test flags with probability
    ``DETECTION_POWER`` (the halves' std alone; the validation part only adds to it): the
    noncentrality the chi-squared test on ``dof`` degrees of freedom needs at
    ``FALSE_ALARM_RATE``, over the halves' combined variance.  Relative to the reported value."""
    critical = stats.chi2.isf(FALSE_ALARM_RATE, dof)
    needed = optimize.brentq(lambda nc: stats.ncx2.sf(critical, dof, nc) - DETECTION_POWER, 1e-6, 1e4)
    first, second = estimates["first half"][1], estimates["second half"][1]
    out = {}
    for i, p in enumerate(BASE):
        step = float(np.sqrt(needed * (first[i, i] + second[i, i])))
        value = abs(reported.model.params_[p])
        out[p] = round(step / value, 4) if value else None
    return out


def consistency(reported: Uncertainty, est: Samples, val: Samples, second_run: bool = False) -> dict:
    """Whether J, c0 and c1 hold throughout the data: the final model's coefficients refitted (its
    effects' nonlinear parameters kept) on the first and second half in time of the estimation
    samples and on the validation samples, and one test over all of them that the parts hold the
    same three values -- a chi-squared test in the parameters' covariance (each part's HAC, widened
    to its own delete-one-block jackknife where that is larger), flagging a plant whose J, c0 and
    c1 do hold at a rate of ``FALSE_ALARM_RATE`` for the whole family of comparisons.
    ``consistent: false`` names each parameter that moved (its own test beyond the rate; where
    none alone is, the nearest), its value per part and by how many std the furthest two lie apart
    (a payload change, a warm-up, a structure the model lacks).

    With ``second_run`` (the validation samples are a run of their own, ``--validate``), the
    whole estimation fit and the validation refit are two answers to one question: where a
    parameter differs between them by more than their combined std, its reported std is
    widened to cover half the difference (``between_runs``: both values, by how many std, the std
    before and after); whether they differ beyond chance is the test's, the validation run being
    one of its parts.

    Parameters
    ----------
    reported : Uncertainty
        The final model's std as reported (widened here where the runs disagree, or by the
        jackknife where no two parts can be compared).
    est : Samples
        The estimation samples (split in time at their moving samples' median).
    val : Samples
        The validation samples.
    second_run : bool
        The validation samples are a run of their own (``--validate``).

    Returns
    -------
    dict
        ``consistent`` (None where no two parts could be compared), ``parts``, ``moved``,
        ``degenerate``, ``test`` (``chi2``, ``dof``, ``p_value``, ``false_alarm_rate``; ``detects``,
        the step between the halves flagged ``detection_power`` of the time, relative);
        ``between_runs`` with a second run; ``not_run`` and ``inflated`` (the jackknife's
        widening) where no two parts could be compared.
    """
    moving_t = est.t[est.moving]
    split = float(np.median(moving_t)) if len(moving_t) else 0.0
    parts = {
        "first half": est.take(est.t < split),
        "second half": est.take(est.t >= split),
        "validation": val,
    }
    fits, degenerate = {}, {}
    for name, part in parts.items():
        fit, why = refit_part(reported, part, JACKKNIFE_BLOCKS)
        if fit is not None:
            fits[name] = fit
        elif why:  # the part cannot carry the model: named, not compared
            degenerate[name] = why
    moved: dict = {}
    out: dict = {"consistent": True, "parts": list(fits), "moved": moved, "degenerate": degenerate}
    if len(fits) >= 2:
        estimates = {n: (f.coef_[: len(BASE)], _base_covariance(f)) for n, f in fits.items()}
        unit = np.array([max(reported.param_std[p], 1e-300) for p in BASE])
        test, p_each = _same_values(estimates, unit)
        out["test"] = {**test, "false_alarm_rate": FALSE_ALARM_RATE}
        if {"first half", "second half"} <= set(estimates):
            out["test"]["detects"] = _detectable_steps(estimates, test["dof"], reported)
            out["test"]["detection_power"] = DETECTION_POWER
        if test["p_value"] < FALSE_ALARM_RATE:
            named = [p for p in BASE if p_each[p] < FALSE_ALARM_RATE] or [min(BASE, key=p_each.__getitem__)]
            for p in named:
                i = BASE.index(p)
                std = {n: float(np.sqrt(c[i, i])) for n, (_, c) in estimates.items()}
                sigmas, a, b = max(
                    (abs(fits[a].params_[p] - fits[b].params_[p]) / np.hypot(std[a], std[b]), a, b)
                    for a in fits
                    for b in fits
                    if a < b and np.hypot(std[a], std[b]) > 0
                )
                moved[p] = {
                    "values": {n: f.params_[p] for n, f in fits.items()},
                    "sigmas": round(float(sigmas), 1),
                    "between": [a, b],
                    "p_value": p_each[p],
                }
            out["consistent"] = False
    runs = _between_runs(reported, fits["validation"]) if second_run and "validation" in fits else None
    if runs is not None:
        out["between_runs"] = runs
    if len(fits) < 2 and runs is None:  # nothing set against anything: said, the jackknife's std
        out["consistent"] = None
        out["not_run"] = (
            f"{'only the ' + next(iter(fits)) if fits else 'no part'} of the data carries the model on "
            f"its own ({', '.join(degenerate) or 'the others'}: see degenerate), so no two parts could "
            f"be compared"
        )
        out["inflated"] = _jackknife_inflation(reported)
    return out


def _jackknife_inflation(reported: Uncertainty) -> dict:
    """J, c0, c1 whose delete-one-block jackknife std is larger than the HAC std but short of the
    factor that widens it anyway (:data:`.model.JACKKNIFE_BEYOND`): widened to the jackknife's,
    with the std before and after -- the one check of the std left where the parts of the data
    cannot be compared."""
    out = {}
    for p in ("J", "c0", "c1"):
        ratio = float(reported.model.jackknife_[BASE.index(p)])
        std = reported.param_std[p]
        if 1.0 < ratio <= JACKKNIFE_BEYOND and std > 0:
            reported.widen(p, 2 * std * np.sqrt(ratio**2 - 1))
            out[p] = {
                "jackknife_over_hac": round(ratio, 3),
                "std_before": std,
                "std_after": reported.param_std[p],
            }
    return out


def _reason(exc: Exception, axis: str) -> str:
    """What a refusal of ``axis`` says, without the log and axis it names."""
    return str(exc).split(f"axis {axis!r}: ", 1)[-1]


def _between_runs(reported: Uncertainty, other: AxisModel) -> dict:
    """J, c0, c1 of the estimation run's model (``reported``) against ``other`` (the validation
    run's refit): each that differs beyond their combined std has its reported std widened by half
    the difference (in quadrature)."""
    out = {}
    for p in ("J", "c0", "c1"):
        a, b = reported.model.params_[p], other.params_[p]
        sa, sb = reported.param_std[p], other.param_std_[p]
        combined = float(np.hypot(sa, sb))
        if not combined or abs(a - b) <= combined:
            continue
        reported.widen(p, a - b)
        out[p] = {
            "estimation": a,
            "validation": b,
            "sigmas": round(float(abs(a - b) / combined), 1),
            "std_before": sa,
            "std_after": reported.param_std[p],
        }
    return out


def friction_range(reported: Uncertainty, est: Samples) -> dict:
    """The speeds c0 and c1 hold for (5th to 95th percentile of |q̇| while moving), and whether
    they depend on which: the model refitted on the slower and on the faster half of the moving
    samples.  Where c0 or c1 differ between the halves by more than ``CONSISTENT_SIGMAS`` combined
    std, friction is not linear in velocity over the range: the reported std of c0 and c1 is widened
    by half the difference (the split depends on the speeds used), and ``linear`` is False.

    Parameters
    ----------
    reported : Uncertainty
        The final model's std as reported (of c0 and c1 widened here where the halves differ).
    est : Samples
        The estimation samples.

    Returns
    -------
    dict
        ``velocity_range`` [rad/s | m/s], ``linear``; the halves' c0 and c1 (``slower``,
        ``faster``) and by how many std they differ (``sigmas``) where both halves could be fitted.
    """
    speed = np.abs(est.qd)
    moving = speed[est.moving]
    low, high = (float(x) for x in np.percentile(moving, [5, 95]))
    split = float(np.median(moving))
    out = {"velocity_range": [low, high], "linear": True}
    fits = {
        name: refit_part(reported, part)[0]
        for name, part in (("slower", est.take(speed < split)), ("faster", est.take(speed >= split)))
    }
    halves = {name: fit for name, fit in fits.items() if fit is not None}
    if len(halves) < 2:
        return out
    slow, fast = halves["slower"], halves["faster"]
    out.update({n: {p: f.params_[p] for p in ("c0", "c1")} for n, f in halves.items()})
    widen = {}
    for p in ("c0", "c1"):
        gap = abs(slow.params_[p] - fast.params_[p])
        if gap > CONSISTENT_SIGMAS * np.hypot(slow.param_std_[p], fast.param_std_[p]):
            widen[p] = round(float(gap / np.hypot(slow.param_std_[p], fast.param_std_[p])), 1)
            reported.widen(p, gap)
    if widen:
        out.update(linear=False, sigmas=widen)
    return out


def band_dependence(log: Log, axis: str, result: AxisResult) -> dict:
    """J refitted with the final model (its effects' nonlinear parameters kept) on the log filtered
    at half the cut-off: a J that differs between the two bands by more than ``CONSISTENT_SIGMAS``
    of their combined std and by more than ``SPREAD_MAX`` of its value (as parts of the data must,
    :mod:`.identifiable`: a long clean log's std is so small that a filter's 0.3 % is 3 std) depends
    on the band the fit uses (a mode, a torque delay, a term the model lacks between them) and gets
    ``why`` with both values, the range it lies in at best.
    Not checked where half the cut-off would cut into the motion itself, or the log holds too
    little there (said in ``not_checked``).

    Parameters
    ----------
    log : Log
        The log identified.
    axis : str
        The axis.
    result : AxisResult
        Its identification.

    Returns
    -------
    dict
        ``cutoff_hz``, ``half_hz``, ``J_half``, ``sigmas``, ``relative``, and ``why`` where J depends
        on the band; or ``not_checked`` and why.
    """
    settings = result.settings
    half = replace(settings, cutoff_hz=settings.cutoff_hz / 2, edge=2 * settings.edge)
    floor = MIN_CUTOFF_BANDWIDTHS * settings.motion_bandwidth_hz
    if half.cutoff_hz < floor <= settings.cutoff_hz:  # (a cut-off held below that floor by the
        # log's rate says the motion's bandwidth was read off noise: checked all the same)
        return {"not_checked": f"half the cut-off, {half.cutoff_hz:.3g} Hz, would cut into the motion"}
    try:
        fit, why = refit_part(result.uncertainty, prepare(log, axis, half))
    except FilterTooNarrow as exc:
        return {"not_checked": _reason(exc, axis)}
    if fit is None:
        return {"not_checked": why or "too few samples in half the band"}
    j, sj = result.model.params_["J"], result.param_std["J"]
    j2, sj2 = fit.params_["J"], fit.param_std_["J"]
    combined = float(np.hypot(sj, sj2))
    sigmas = abs(j - j2) / combined if combined else 0.0
    spread = abs(j - j2) / max(abs(j), abs(j2)) if j or j2 else 0.0
    out = {
        "cutoff_hz": settings.cutoff_hz,
        "half_hz": half.cutoff_hz,
        "J_half": j2,
        "sigmas": round(sigmas, 1),
        "relative": round(spread, 4),
    }
    if sigmas > CONSISTENT_SIGMAS and spread > SPREAD_MAX:
        low, high = sorted((j, j2))
        out["why"] = (
            f"J depends on the band the fit uses: {j:.4g} at {settings.cutoff_hz:.3g} Hz, {j2:.4g} at "
            f"{half.cutoff_hz:.3g} Hz ({sigmas:.2g} std apart), so at best it lies in {low:.4g} .. {high:.4g} "
            f"(a mode, a torque delay or a term the model lacks between the two bands)"
        )
    return out


def identify_axis(
    log: Log,
    axis: str,
    val_log: Log | None = None,
    *,
    seed: int = 0,
    cutoff_hz: float | None = None,
    decimation: int | None = None,
    torque_delay_s: float | None = None,
) -> AxisResult:
    """Identify one axis of a log (:func:`identify` does it for each).

    A resonance close enough above the cut-off to bias the rigid fit moves the cut-off below it
    (unless the cut-off was given), and the result says so; backlash or impacts at torque
    reversal are reported (:mod:`.reversal`).

    Parameters
    ----------
    log : Log
        The log (:func:`.logdata.read_log`).
    axis : str
        The axis.
    val_log : Log, optional
        A second run to validate on; default blocks held out of ``log``.
    seed : int
        Seed of the searches (the same seed, the same numbers).
    cutoff_hz : float, optional
        The low-pass cut-off [Hz]; default chosen from the motion's bandwidth.
    decimation : int, optional
        The decimation factor; default chosen with the cut-off.
    torque_delay_s : float, optional
        The logged torque's delay behind the position [s]; None: estimated.

    Returns
    -------
    AxisResult
        The models, effects, errors and diagnostics.

    Raises
    ------
    UserError
        An axis the log cannot identify, and why.
    """
    given = None if torque_delay_s is None else (float(torque_delay_s), "given")
    result = _identify_axis(log, axis, val_log, seed, cutoff_hz, decimation, given)
    wide = whole_band(log, axis, result.settings)
    mode = find_mode(wide, wide.tau_f - result.model.predict(wide), result.settings)
    if mode is not None:
        settings = result.settings
        below = mode["frequency_hz"] / 2
        if (
            cutoff_hz is None
            and not mode["mains"]
            and mode["frequency_hz"] < 2 * settings.cutoff_hz
            and below < settings.cutoff_hz
            and below >= MIN_CUTOFF_BANDWIDTHS * settings.motion_bandwidth_hz
        ):
            try:
                moved = _identify_axis(
                    log,
                    axis,
                    val_log,
                    seed,
                    below,
                    None,
                    given
                    or (0.0, "not estimated: the resonance shifts the torque's phase by more than a delay"),
                )
            except FilterTooNarrow as exc:  # below the mode the log holds too little: the band stays
                mode = {
                    **mode,
                    "cutoff_kept_hz": round(settings.cutoff_hz, 2),
                    "why_kept": f"at {below:.3g} Hz, below the mode, {_reason(exc, axis)}: the fit "
                    "keeps the band above it, the mode inside",
                }
            else:
                result = moved
                mode = {**mode, "cutoff_moved_from_hz": round(settings.cutoff_hz, 2)}
                if result.settings.torque_delay_s != settings.torque_delay_s:
                    wide = whole_band(log, axis, result.settings)  # the positions as the new fit reads them
        result.diagnostics.resonance = mode
        result.diagnostics.unexplained.append(
            {
                "depends_on": "frequency",
                "form": "even",
                "kind": "resonance",
                "fraction": mode["share"],
                "frequency_hz": mode["frequency_hz"],
                "damping": mode["damping"],
                "mains": mode["mains"],
                "evidence": None,
                **{
                    k: v
                    for k, v in mode.items()
                    if k in ("cutoff_moved_from_hz", "cutoff_kept_hz", "why_kept")
                },
            }
        )
    levels = clipped_levels(log.axes[axis].tau)
    if levels:
        result.diagnostics.sampling["torque_clipped"] = {
            "levels": levels,
            "share": round(float(np.isin(log.axes[axis].tau, levels).mean()), 4),
        }
    _check_sign(log, axis, result.uncertainty, result.est)
    diagnostics = result.diagnostics
    diagnostics.motion = what_the_motion_tells(result.est, result.units["position"])
    diagnostics.band = band_dependence(log, axis, result)
    diagnostics.undetermined = undetermined(
        result.model,
        result.est,
        result.after,
        diagnostics.consistency,
        {
            **diagnostics.motion["cannot_tell"],
            **({"J": diagnostics.band["why"]} if "why" in diagnostics.band else {}),
        },
        result.param_std,
    )
    _refit_for_the_drive(result, seed)
    J, c1 = result.model.params_["J"], result.model.params_["c1"]
    predicted = result.model.predict(wide)
    demand = log.axes[axis].demand
    diagnostics.response = log_response(
        wide.t,
        wide.qd,
        wide.tau_f - (predicted - J * wide.qdd - c1 * wide.qd),
        J,
        c1,
        None if demand is None else np.interp(wide.t, log.t, demand),
    )
    found = find_reversal_transient(wide, wide.tau_f - predicted, predicted, result.settings, seed)
    if found is not None:
        standstill = found["reversal"] == "velocity"
        if not standstill:
            diagnostics.backlash = found
        diagnostics.unexplained.append(
            {
                "depends_on": f"{found['reversal']}_reversal",
                "form": "odd" if standstill else "even",
                "kind": "standstill_friction" if standstill else "backlash",
                "fraction": found["share"],
                "evidence": None,
                **{k: found[k] for k in ("delay_ms", "ratio", "events")},
                **(
                    {"fitted_from": round(diagnostics.friction["velocity_range"][0], 4)} if standstill else {}
                ),
            }
        )
    return result


def _refit_for_the_drive(result: AxisResult, seed: int) -> None:
    """Where the model has effects no drive model carries, its refit with only those a drive holds
    (``result.drive``) -- or, where that refit leaves J, c0 or c1 undetermined, the full model with
    why its values are written (``result.drive.note``)."""
    held = [e for e in result.model.effects if e.name in DRIVE_EFFECTS]
    if len(held) == len(result.model.effects):
        return
    drive = AxisModel(held, seed=seed, jackknife_blocks=JACKKNIFE_BLOCKS).fit(result.est)
    drive_errors = errors(drive, result.val)
    lost = undetermined(drive, result.est, drive_errors, {})
    if lost:  # the drive's structure cannot hold this machine
        left = ", ".join(e.name for e in result.model.effects if e not in held)
        result.drive = DriveFit(
            result.model,
            result.after,
            result.param_std,
            f"refitted without {left}, which no drive model holds, the model leaves "
            f"{', '.join(lost)} undetermined: the full model's values are what is written",
        )
    else:
        result.drive = DriveFit(drive, drive_errors, drive.param_std_)


def _check_sign(log: Log, axis: str, reported: Uncertainty, est: Samples) -> None:
    """UserError where the inertia and a friction come out negative beyond their std -- in the
    final model, or in the base model with the load a joint may carry (an offset; on a rotary
    joint its gravity), which the tracer may have dropped as unphysical: the torque and the
    position were logged with opposite sign conventions (no plant has a negative inertia and a
    friction that drives the motion)."""
    load: list[Effect] = [Offset(), Gravity()] if est.rotary else [Offset()]
    loaded = AxisModel(load, seed=reported.model.seed).fit(est)
    for m, sd in ((reported.model, reported.param_std), (loaded, loaded.param_std_)):
        p = m.params_
        if p["J"] < -T_MIN * sd["J"] and (p["c0"] < -T_MIN * sd["c0"] or p["c1"] < -T_MIN * sd["c1"]):
            raise UserError(
                f"{log.path}: axis {axis}: J {p['J']:.4g}, c0 {p['c0']:.4g} and c1 {p['c1']:.4g} come "
                f"out negative: the torque and the position have opposite sign conventions? Give "
                f"--torque-sign -1 (identify) to read the torque the other way round"
            )


def _identify_axis(
    log: Log,
    axis: str,
    val_log: Log | None,
    seed: int,
    cutoff_hz: float | None,
    decimation: int | None,
    delay: tuple[float, str] | None = None,
) -> AxisResult:
    """One identification.  ``delay``: the torque's delay [s] behind the position and why it is
    that (``given``, not estimated because ...); None: estimated with the model as the tracing
    builds it (:func:`.model.torque_delay`), and where the torque is significantly late and
    aligning the positions with it lowers the validation error of the torque as logged (by
    ``MIN_GAIN``, as an effect must), they are aligned and the tracing goes on with them."""
    if val_log is not None and axis not in val_log.axes:
        raise UserError(
            f"{val_log.path}: the validation log has no axis {axis!r} (it has {', '.join(val_log.axes)})"
        )
    chosen = choose_settings(log, axis, cutoff_hz, decimation)

    def aligned(d: float) -> tuple[Settings, Settings, Samples, Samples, str]:
        settings = replace(chosen, torque_delay_s=d)
        samples = prepare(log, axis, settings)
        if val_log is None:
            return (settings, settings) + _holdout(samples)
        vs = settings
        if abs(val_log.dt - log.dt) > 1e-9:
            vs = replace(choose_settings(val_log, axis, settings.cutoff_hz), torque_delay_s=d)
        return settings, vs, samples, prepare(val_log, axis, vs), f"the validation log {val_log.path}"

    current = aligned(delay[0] if delay else 0.0)
    moves = 0
    timing: dict[str, Any] = {"torque_delay_source": delay[1] if delay else "estimated"}

    def realign(model: AxisModel) -> tuple[Samples, Samples] | None:
        nonlocal current, moves
        if delay is not None or moves >= MAX_REALIGNMENTS:
            return None
        settings, _, est, val, _ = current
        d, std = torque_delay(model, est, log.dt)  # beyond the alignment made so far
        total = settings.torque_delay_s + d
        timing.update(torque_delay_estimate_ms=round(1e3 * total, 4), torque_delay_std_ms=round(1e3 * std, 4))
        if abs(total) > MAX_DELAY_SAMPLES * log.dt:
            timing["torque_delay_note"] = (
                f"estimated beyond {MAX_DELAY_SAMPLES:g} log samples: no plain "
                f"delay (a compliance or a filter), left as it was"
            )
            return None
        if abs(d) <= DELAY_SIGMAS * std:
            return None
        moves += 1
        candidate = aligned(total)
        refit = AxisModel(model.effects, seed=seed, condition_number=False).fit(candidate[2])
        if errors(refit, candidate[3]).rmse > (1 - MIN_GAIN) * errors(model, val).rmse:
            timing["torque_delay_note"] = (
                f"aligning the positions with it did not lower the validation "
                f"error of the torque as logged by {MIN_GAIN:.0%}: left as it was"
            )
            return None
        timing.pop("torque_delay_note", None)
        current = candidate
        return candidate[2], candidate[3]

    settings, vs, est, val, how = current
    base, model, traced = trace(est, val, seed, realign)
    settings, vs, est, val, how = current
    model = AxisModel(model.effects, model.method, model.seed, JACKKNIFE_BLOCKS).fit(
        est
    )  # its std from the jackknife too
    reported = Uncertainty(model)
    agreement = consistency(reported, est, val, second_run=val_log is not None)
    friction = friction_range(reported, est)
    floor = noise_floor(val_log, axis, vs) if val_log is not None else noise_floor(log, axis, settings)
    ga_model = AxisModel(model.effects, method="ga", seed=seed).fit(est)
    logger.info(
        "axis %s: %s; effects %s; cut-off %.3g Hz, torque delay %.3g ms",
        axis,
        ", ".join(f"{k} {v:.6g}" for k, v in model.params_.items() if k in ("J", "c0", "c1")),
        ", ".join(t.effect.name for t in traced) or "none",
        settings.cutoff_hz,
        1e3 * settings.torque_delay_s,
    )
    return AxisResult(
        axis,
        log.axes[axis].kind,
        log.axes[axis].units,
        settings,
        how,
        est,
        val,
        base,
        model,
        reported,
        traced,
        errors(base, val),
        errors(model, val),
        GeneticFit.of(ga_model, reported, val),
        Diagnostics(
            floor,
            unexplained(model, val, settings.rate_hz / settings.decimation),
            list(log.axes[axis].dropped),
            {
                **log.sampling,
                "torque_delay_ms": round(1e3 * settings.torque_delay_s, 4),
                "torque_aligned": settings.torque_delay_s != 0.0,
                **timing,
            },
            agreement,
            friction,
        ),
    )


def workers(log: Log, axes: list[str]) -> int:
    """How many processes identify the axes of a log.

    Parameters
    ----------
    log : Log
        The log.
    axes : list of str
        The axes to identify.

    Returns
    -------
    int
        One per axis up to :func:`~drive_bridge.forking.processes`; for a small log (fewer than
        :data:`MIN_PARALLEL_SAMPLES` rows × axes) 1 -- here, one after the other -- unless
        ``DRIVE_BRIDGE_WORKERS`` asks.
    """
    if len(axes) < 2 or (
        not os.environ.get("DRIVE_BRIDGE_WORKERS") and len(log.t) * len(axes) < MIN_PARALLEL_SAMPLES
    ):
        return 1
    return min(len(axes), processes())


def identify(
    path: str | Path,
    validate: str | Path | None = None,
    axes: list[str] | None = None,
    *,
    seed: int = 0,
    cutoff_hz: float | None = None,
    decimation: int | None = None,
    progress: Callable[[str], object] | None = None,
    torque_delay_s: float | None = None,
    torque_sign: float = 1.0,
) -> dict[str, AxisResult]:
    """Identify J, c0 and c1 of every axis of a log, and the effects its residual shows.

    The rigid model J·q̈ + c1·q̇ + c0·sign(q̇) = τ is fitted by least squares and a genetic
    algorithm on filtered, decimated samples; the residual is traced to effects the model
    lacks (each kept only where it improves the validation error); what the data cannot
    determine is said, not printed with a small std.
    OpenBLAS computes with one thread meanwhile, its count restored after
    (:func:`drive_bridge.blas.one_thread`).

    Parameters
    ----------
    path : str or Path
        The log (CSV: ``time_s``, per axis ``<axis>_position_rad`` [rad] and
        ``<axis>_torque_Nm`` [Nm], motor side), or a run directory with ``log.csv``.
    validate : str or Path, optional
        A second log of the same axes to validate on; default: blocks held out of ``path``.
    axes : list of str, optional
        The axes to identify; default every axis of the log.
    seed : int
        Seed of the genetic algorithm (the same seed, the same numbers).
    cutoff_hz : float, optional
        The low-pass cut-off [Hz]; default chosen from the motion's bandwidth.
    decimation : int, optional
        The decimation factor; default chosen with the cut-off.
    progress : callable, optional
        Called with a line of text as each axis advances.
    torque_delay_s : float, optional
        The logged torque's delay behind the position [s]; None: estimated from the log.
    torque_sign : {1.0, -1.0}
        -1: the torque was logged with the opposite sign convention to the position.

    Returns
    -------
    dict of str to AxisResult
        Per axis: the fitted model (``model.params_``) and the std as reported (``param_std``), the effects
        added, the validation errors before and after, and what is undetermined.

    Raises
    ------
    UserError
        A log that cannot be read or has no such axis, or settings out of range.
    """
    with one_thread():  # (its own threads spin between calls: :mod:`drive_bridge.blas`)
        log = read_log(path)
        val_log = read_log(validate) if validate else None
        if torque_sign not in (1.0, -1.0):
            raise UserError(f"--torque-sign must be 1 or -1, got {torque_sign:g}")
        for lg in (log, val_log) if val_log is not None else (log,):
            for ax in lg.axes.values():
                ax.tau = torque_sign * ax.tau
        names = axes or list(log.axes)
        for a in names:
            if a not in log.axes:
                raise UserError(f"{log.path}: no axis {a!r} in the log (it has {', '.join(log.axes)})")
        options = {
            "seed": seed,
            "cutoff_hz": cutoff_hz,
            "decimation": decimation,
            "torque_delay_s": torque_delay_s,
        }
        count = workers(log, names)
        if count > 1 and progress:  # side by side: every axis starts now
            for a in names:
                progress(a)
        outcomes = dict(
            zip(
                names,
                fork_map(_outcome, names, count, (log, val_log, options, progress if count == 1 else None)),
            )
        )
        results = {a: r for a, (status, r) in outcomes.items() if status == "ok"}
        if count > 1:
            for r in results.values():
                r.attach(log)
        failed = [UserError(message) for status, message in outcomes.values() if status == "error"]
        if failed and (axes or not results):  # asked for by name: its problem is the answer
            raise failed[0]
        for error in failed:  # the others answered: this one is said, not lost
            logger.warning("%s", error)
        return results


def _outcome(
    shared: tuple[Log, Log | None, dict[str, Any], Callable[[str], object] | None], axis: str
) -> tuple[str, Any]:
    """("ok", :func:`identify_axis`'s result) or ("error", why the log cannot give it: a UserError's
    message, a log that cannot determine the model said so); ``progress(axis)`` first, where given."""
    log, val_log, options, progress = shared
    if progress:
        progress(axis)
    try:
        try:
            return "ok", identify_axis(log, axis, val_log, **options)
        except (np.linalg.LinAlgError, ValueError, FloatingPointError) as exc:
            raise UserError(
                f"{log.path}: axis {axis!r}: the log does not determine the model ({exc}); it "
                f"needs motion at several speeds and accelerations in both directions"
            ) from exc
    except UserError as exc:
        return "error", str(exc)
