"""Residual tracing: find what the model lacks, add it, refit, repeat until nothing is left.

Each round fits every candidate of the effect library (see
:func:`~drive_bridge.ident.effects.candidates`) together with the model so
far, all parameters at once, on the estimation samples, and scores it on the
validation samples by the drop of the log sum of squared errors per added
parameter (the quantity AIC and BIC weigh against parameter count; per
parameter, so a simpler explanation of the same residual comes first).  The
errors used to choose are those of the filtered torque, which the model
predicts; the torque as logged adds measurement noise that no model can
follow (reported beside: RMSE on the logged torque).  The best candidate is
added when it is significant:

* partial F-test of the nested models on the estimation samples, p < ``P_VALUE``, and
* validation error (filtered torque) down by at least ``MIN_GAIN`` (relative): the
  F-test alone flags effects far too small to matter on long logs whose
  residual samples are correlated.

A spline (a shape no named effect has) must cut the validation error by ``SPLINE_GAIN``; it
replaces the best named effect where its error is that much lower, except in a round where a
named effect of its own shape (variable and form) passes: the named one comes first, as a
spline in the signed velocity would otherwise take Stribeck friction, a direction asymmetry
and part of c1 in one.

Tracing stops when no candidate passes; effects whose joint fit leaves J, c0 or c1
unphysical (negative) are taken back, the last added first.  Structure left in the final residual
that no effect explains is reported by what it depends on: the share of the
validation residual's variance explained by its mean in bins of each variable
(correlation ratio η², one-way ANOVA), and by a dominant frequency.  Each
variable is tested on the residual as it is (``form: even``: the same torque in
both directions, as gravity or cogging) and on the residual times the direction
of motion (``form: odd``: a torque against the motion, as friction that changes
along the stroke or with the load, which the raw residual averages away).  The
list is ordered by the strength of the evidence (the ANOVA F statistic; a spectral peak,
which mostly reflects the pace of the moves, comes last), and a
variable an added effect already depends on is named with that effect and what
of the residual remains.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import stats

from .dependence import dependences
from .effects import Effect, PositionPeriodic, Spline, candidates, shape_of
from .identifiable import T_MIN
from .model import AxisModel, Errors, errors, extend
from .signals import Samples
from .spectra import welch

log = logging.getLogger(__name__)

P_VALUE = 1e-3
MIN_GAIN = 0.01
SPLINE_GAIN = 0.05  # a spline (many coefficients, no physics) must cut the validation error 5 %
MAX_EFFECTS = 6
UNEXPLAINED_SHARE = 0.05  # report a dependence that explains this share of the residual variance


@dataclass
class TracedEffect:
    """One effect the tracing added, and why.

    Parameters
    ----------
    effect : Effect
        The effect, its nonlinear parameters learned.
    params : dict
        Its parameters in the final model (all parameters refitted together), SI.
    rmse_before, rmse_after : float
        The validation RMSE on the logged torque before and after it was added [Nm | N].
    relative_error_before, relative_error_after : float
        The validation relative error on the filtered torque (the paper's measure), likewise.
    f_stat, p_value : float
        The partial F-test of the model with it against the model without.
    share : float
        The share of the residual variance (estimation) it explains.
    model_params : dict
        Every parameter of the model once this effect was added.
    fit_relative_error : float
        The relative error on the estimation samples once it was added.
    evidence : str
        Why it was added, in words, once the final fit is known.
    """

    effect: Effect
    params: dict
    rmse_before: float
    rmse_after: float
    relative_error_before: float
    relative_error_after: float
    f_stat: float
    p_value: float
    share: float
    model_params: dict
    fit_relative_error: float
    evidence: str = ""


def f_test(small: AxisModel, big: AxisModel) -> tuple[float, float]:
    """The partial F-test of two nested models.

    Parameters
    ----------
    small : AxisModel
        The fitted model without the added terms.
    big : AxisModel
        The fitted model with them, on the same samples.

    Returns
    -------
    f : float
        The partial F statistic.
    p : float
        Its p-value.
    """
    k = len(big.coef_) - len(small.coef_)
    dof = big.n_samples_ - len(big.coef_)
    f = ((small.sse_ - big.sse_) / k) / (big.sse_ / dof) if big.sse_ > 0 else np.inf
    return float(f), float(stats.f.sf(f, k, dof))


FORM_WORDS = {
    "even": "the same in both directions",
    "odd": "against the motion: friction-like",
    "inertial": "in proportion to the acceleration: an inertia that changes along the stroke",
}
MOVED = 0.1  # a parameter that moved by this share since its effect was added is said so


def _evidence(t: TracedEffect) -> str:
    """Why ``t`` was added, with its parameters as the final fit has them (the table's values) and
    what they were when it was added where the effects added after it moved them."""
    e = t.effect
    what = (
        f"a smooth torque in {e.variable} no named effect describes ({len(e.coef_names)}-coefficient spline, "
        + FORM_WORDS[e.form]
        + ")"
        if isinstance(e, Spline)
        else _named_evidence(e, t.params)
    )
    added = {k: t.model_params.get(f"{e.name}.{k}") for k in t.params}
    moved = (
        []
        if isinstance(e, Spline)
        else [
            f"{k} {now:+.4g}"
            for k, v in t.params.items()
            if isinstance(v, float) and isinstance(now := added[k], float) and abs(v - now) > MOVED * abs(now)
        ]
    )
    since = (
        f" (when it was added: {', '.join(moved)}; the effects added after it took part of that)"
        if moved
        else ""
    )
    return (
        f"{what}{since}; explains {t.share:.0%} of the residual variance (F = {t.f_stat:.3g}); validation "
        f"RMSE {t.rmse_before:.4g} -> {t.rmse_after:.4g}, relative error "
        f"{t.relative_error_before:.2%} -> {t.relative_error_after:.2%}"
    )


def _named_evidence(e: Effect, params: dict) -> str:
    return {
        "offset": lambda: (
            f"a constant torque {params['offset']:+.4g}: a load (gravity on a vertical axis), a "
            f"measurement offset, or the constant part of a Coulomb friction that differs between the "
            f"directions ((c0 + dc0·s)·s = c0·s + dc0): the torque alone cannot tell them apart"
        ),
        "gravity": lambda: (
            f"a weight on the joint: {params['amplitude']:.4g} at most, where the arm is horizontal "
            f"(angle {params['angle']:+.3g} rad), one period per turn"
        ),
        "position_linear": lambda: f"residual slope over position {params['cp']:+.4g}",
        "position_periodic": lambda: (
            f"residual periodic in position, period {params['period']:.4g}, "
            f"amplitude {params['amplitude']:.3g}"
        ),
        "stribeck": lambda: f"residual rises near standstill below {params['velocity']:.3g}/s",
        "direction_asymmetry": lambda: (
            "residual differs with the direction of motion "
            f"(dc1 {params['dc1']:+.3g}" + (f", dc0 {params['dc0']:+.3g})" if "dc0" in params else ")")
        ),
        "cross_axis": lambda: (
            f"residual follows axis {params['source']} ({params['form']}), "
            f"coefficient {params['coefficient']:+.3g}"
        ),
        "drift": lambda: (
            f"Coulomb friction changes over time, time constant {params['time_constant_s']:.3g} s"
        ),
    }["position_periodic" if isinstance(e, PositionPeriodic) else e.name]()


def trace(
    est: Samples,
    val: Samples,
    seed: int,
    realign: Callable[[AxisModel], tuple[Samples, Samples] | None] | None = None,
) -> tuple[AxisModel, AxisModel, list[TracedEffect]]:
    """Base model, final model, and the effects added on the way (in order); ``seed`` seeds
    the search of every effect's nonlinear parameters.  ``realign(model)``, asked after the base
    fit and after each added effect, may return new estimation and validation samples (the
    torque aligned with the position anew): the model is refitted on them and tracing goes on.

    Parameters
    ----------
    est : Samples
        The estimation samples.
    val : Samples
        The validation samples.
    seed : int
        Seed of every effect's search.
    realign : callable, optional
        Given the model so far, new (estimation, validation) samples, or None to keep them.

    Returns
    -------
    base : AxisModel
        The rigid model, fitted on the final samples.
    model : AxisModel
        The final model (made without its condition number, as every model the tracing fits).
    traced : list of TracedEffect
        The effects added, in order.
    """
    # (the tracing's models go without the condition number: nobody reads it of them)
    model, traced = AxisModel(seed=seed, condition_number=False).fit(est), []
    est, val, model = _realigned(realign, model, est, val)
    err = errors(model, val)
    for _ in range(MAX_EFFECTS):
        resid = est.tau_f - model.predict(est)
        best = spline = None
        # shapes a named effect adds significantly this round: no spline of one is made (it would take
        # the named effect's place); the named candidates come first
        named: set[tuple[str, str]] = set()
        for cand in candidates(model.effects, est, resid, named):
            try:
                fitted = extend(model, cand, est)
            except np.linalg.LinAlgError:
                continue  # the candidate's columns leave the problem singular
            if (
                not np.all(np.isfinite(fitted.coef_))
                or fitted.sse_ >= model.sse_
                or hides_inertia(model, fitted)
            ):
                continue
            new_err = errors(fitted, val)
            if new_err.relative_error <= 0 or (
                isinstance(cand, Spline) and new_err.relative_error > (1 - SPLINE_GAIN) * err.relative_error
            ):
                continue  # a spline must earn its many coefficients
            if not isinstance(cand, Spline) and _accepted(f_test(model, fitted)[1], err, new_err):
                named.add(shape_of(cand))
            score = 2 * np.log(err.relative_error / new_err.relative_error) / len(cand.coef_names)
            if best is None or score > best[0]:
                best = (score, fitted, new_err, cand)
            if isinstance(cand, Spline) and (
                spline is None or new_err.relative_error < spline[2].relative_error
            ):
                spline = (score, fitted, new_err, cand)
        if best is None:
            break
        if spline is not None and spline[2].relative_error < (1 - SPLINE_GAIN) * best[2].relative_error:
            best = spline  # the named effect does not fit as well: the shape the data hold
        _, fitted, new_err, cand = best
        f, p = f_test(model, fitted)
        if not _accepted(p, err, new_err):
            log.debug(
                "best candidate %s not accepted: p = %.3g, validation error %.4g -> %.4g",
                cand.name,
                p,
                err.relative_error,
                new_err.relative_error,
            )
            break
        log.info(
            "effect %s added: p = %.3g, validation error %.4g -> %.4g",
            cand.name,
            p,
            err.relative_error,
            new_err.relative_error,
        )
        share = 1.0 - fitted.sse_ / model.sse_
        params = fitted.effect_params(cand)
        traced.append(
            TracedEffect(
                cand,
                params,
                err.rmse,
                new_err.rmse,
                err.relative_error,
                new_err.relative_error,
                f,
                p,
                share,
                fitted.params_,
                fitted.relative_error_,
            )
        )
        est, val, model = _realigned(realign, fitted, est, val)
        err = new_err if model is fitted else errors(model, val)
    while traced and not physical(model):  # effects that bought their fit with a negative friction go
        log.info("effect %s removed: the model with it is not physical", traced[-1].effect.name)
        traced.pop()  # again, last first (a base model stays as it is)
        model = AxisModel([t.effect for t in traced], seed=seed, condition_number=False).fit(est)
    for t in traced:  # every effect's parameters as the final joint fit has them
        t.params = model.effect_params(t.effect)
        t.evidence = _evidence(t)
    return AxisModel(seed=seed).fit(est), model, traced


def hides_inertia(model: AxisModel, fitted: AxisModel) -> bool:
    """Whether an added effect leaves J undetermined where the model without it determined it: a
    term the data cannot tell from J·q̈ (on a near-sinusoidal motion a gravity or a spline over
    position is nearly proportional to the acceleration) would take the inertia with it.

    Parameters
    ----------
    model : AxisModel
        The fitted model without the effect.
    fitted : AxisModel
        The fitted model with it.

    Returns
    -------
    bool
        J determined (beyond ``T_MIN`` std) in ``model`` and not in ``fitted``.
    """

    def determined(m: AxisModel) -> bool:
        return abs(m.params_["J"]) >= T_MIN * m.param_std_["J"]

    return determined(model) and not determined(fitted)


def _accepted(p_value: float, err: Errors, new_err: Errors) -> bool:
    """Whether an effect earns its place: significant (``p_value`` of the partial F-test of the
    model with it against the model without), and the validation error down by ``MIN_GAIN``."""
    return p_value < P_VALUE and new_err.relative_error <= (1 - MIN_GAIN) * err.relative_error


def _realigned(
    realign: Callable[[AxisModel], tuple[Samples, Samples] | None] | None,
    model: AxisModel,
    est: Samples,
    val: Samples,
) -> tuple[Samples, Samples, AxisModel]:
    """The samples ``realign(model)`` gives, and ``model`` refitted on them (as they were, and
    ``model`` itself, when it gives none)."""
    new = realign(model) if realign else None
    if new is None:
        return est, val, model
    return (
        new[0],
        new[1],
        AxisModel(model.effects, seed=model.seed, condition_number=model.condition_number).fit(new[0]),
    )


def physical(model: AxisModel) -> bool:
    """No friction (c0, c1) negative beyond ``T_MIN`` of its std: an effect does not buy its fit
    with a friction that drives the motion.  A value within its std of zero is one the data do
    not determine, and an inertia that comes out negative stands in for a term the model lacks:
    :mod:`.identifiable` says so of either, and the effects stay.

    Parameters
    ----------
    model : AxisModel
        A fitted model.

    Returns
    -------
    bool
        Neither c0 nor c1 negative beyond ``T_MIN`` of its std.
    """
    p, sd = model.params_, model.param_std_
    return all(p[k] > -T_MIN * sd[k] for k in ("c0", "c1"))


def unexplained(model: AxisModel, s: Samples, rate_hz: float) -> list[dict]:
    """What the residual on ``s`` still depends on (see the module docstring): per entry
    ``depends_on``, ``form`` (even | odd), ``fraction`` of the residual variance, ``evidence``
    (F statistic), and ``after`` (the added effects that depend on it already) where any does.

    Parameters
    ----------
    model : AxisModel
        The final model.
    s : Samples
        The samples whose residual (torque as logged) is read: the validation samples.
    rate_hz : float
        Their sample rate [Hz] (for a dominant frequency).

    Returns
    -------
    list of dict
        By the strength of the evidence; a spectral peak last.
    """
    m = s.moving
    residual = s.tau - model.predict(s, logged=True)
    r = residual[m]
    total = float(np.mean(r**2))
    added: dict[str, list[str]] = {}
    for e in model.effects:
        added.setdefault(e.depends_on, []).append(e.name)
    out = []
    if total > 0 and r.mean() ** 2 / total >= UNEXPLAINED_SHARE:
        n = len(r)
        f = n * r.mean() ** 2 / max(float(np.var(r)), 1e-300)
        out.append(
            {
                "depends_on": "constant",
                "form": "even",
                "fraction": round(float(r.mean() ** 2 / total), 4),
                "evidence": round(float(f), 1),
            }
        )
    out += dependences(s, residual, UNEXPLAINED_SHARE, P_VALUE)
    if len(r) >= 256:
        f, pxx = welch(r - r.mean(), rate_hz, 256)
        peak = int(np.argmax(pxx[1:])) + 1
        band = float(pxx[max(1, peak - 1) : peak + 2].sum() / pxx[1:].sum())
        if band >= 0.25:
            out.append(
                {
                    "depends_on": "frequency",
                    "form": "even",
                    "fraction": round(band, 4),
                    "frequency_hz": float(f[peak]),
                    "evidence": None,
                }
            )
    for d in out:
        if d["depends_on"] in added:
            d["after"] = added[d["depends_on"]]
    # by evidence; a spectral peak last: it mostly reflects the pace of the moves
    return sorted(out, key=lambda d: -(d["evidence"] if d["evidence"] is not None else -1.0))


def describe_unexplained(d: dict) -> str:
    """One entry of :func:`unexplained` in words.

    Parameters
    ----------
    d : dict
        The entry (a dependence, a resonance, a transient after reversals).

    Returns
    -------
    str
        What the residual depends on, how much of it, and what it likely is.
    """
    what = {
        "even": "the residual",
        "odd": "the residual times the direction of motion (a torque against the motion, friction-like)",
        "inertial": "the residual times the acceleration (an inertia that changes along the stroke)",
    }[d.get("form", "even")]
    if d.get("kind") == "resonance" and d.get("mains"):
        return (
            f"a narrow peak at {d['frequency_hz']:.3g} Hz holds {d['fraction']:.0%} of the residual over the "
            f"log's whole band: the mains frequency or its double, more likely electrical pickup in the torque "
            f"measurement than a mechanical mode"
        )
    if d.get("kind") == "resonance":
        moved = (
            f"; the cut-off was moved from {d['cutoff_moved_from_hz']:.3g} Hz below it"
            if d.get("cutoff_moved_from_hz")
            else f"; the cut-off stays at {d['cutoff_kept_hz']:.3g} Hz: {d['why_kept']}"
            if d.get("cutoff_kept_hz")
            else ""
        )
        return (
            f"a resonance at {d['frequency_hz']:.3g} Hz (damping ratio ≈ {d['damping']:.2g}) holds "
            f"{d['fraction']:.0%} of the residual over the log's whole band: a compliant transmission the "
            f"rigid model lacks{moved}"
        )
    if d.get("kind") == "standstill_friction":
        return (
            f"the residual gathers {d['ratio']:.2g}× its usual power about {d['delay_ms']:.3g} ms after each "
            f"reversal of the velocity ({d['events']} of them; {d['fraction']:.0%} of the residual over the "
            f"log's whole band): friction at standstill the model lacks (breakaway, Stribeck friction or "
            f"stick-slip) at speeds below those fitted ({d['fitted_from']:.3g}/s and up), not play"
        )
    if d.get("kind") == "backlash":
        return (
            f"the residual gathers {d['ratio']:.2g}× its usual power about {d['delay_ms']:.3g} ms after each "
            f"{d['depends_on'].replace('_', ' ')} ({d['events']} of them; {d['fraction']:.0%} of the residual "
            f"over the log's whole band): backlash or an impact in the transmission, which the rigid model "
            f"lacks"
        )
    text = f"{what} depends on {d['depends_on']}"
    if "frequency_hz" in d:
        text += f" (a peak at {d['frequency_hz']:.3g} Hz)"
    text += f": {d['fraction']:.0%} of its variance"
    if d.get("after"):
        text += f", what remains after {', '.join(d['after'])}"
    return text
