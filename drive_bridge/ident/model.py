"""The axis model τ = J·q̈ + c1·q̇ + c0·sign(q̇) + Σ effects, as an estimator.

``AxisModel(effects).fit(samples)`` solves the least-squares problem of the
paper (eq. 2–3) on the moving samples, with the filtered torque as the
observation; fitted values end in ``_`` (scikit-learn style).  ``fit_ga``
fits the same structure with differential evolution (the paper's genetic
algorithm), seeded.  Units follow the axis: J [kg·m² | kg], c1 [Nm·s/rad |
N·s/m], c0 [Nm | N].
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import optimize

from .effects import Effect
from .signals import Samples

BASE = ("J", "c1", "c0")


def base_columns(s: Samples) -> np.ndarray:
    return np.column_stack((s.qdd, s.qd, s.sgn))


class AxisModel:
    """Base rigid-body model plus ``effects``; see the module docstring."""

    def __init__(self, effects: list[Effect] | tuple[Effect, ...] = ()):
        self.effects = list(effects)

    def with_effect(self, effect: Effect) -> "AxisModel":
        return AxisModel(self.effects + [effect])

    def design(self, s: Samples) -> np.ndarray:
        return np.column_stack([base_columns(s)] + [e.columns(s) for e in self.effects])

    @property
    def coef_names(self) -> list[str]:
        return list(BASE) + [f"{e.name}.{c}" for e in self.effects for c in e.coef_names]

    def fit(self, s: Samples) -> "AxisModel":
        m = s.moving
        phi, y = self.design(s)[m], s.tau_f[m]
        scale = np.sqrt(np.mean(phi ** 2, axis=0))
        scale[scale == 0] = 1.0
        coef, *_ = np.linalg.lstsq(phi / scale, y, rcond=None)
        self.coef_ = coef / scale
        resid = y - phi @ self.coef_
        n, p = phi.shape
        self.n_samples_ = n
        self.sse_ = float(resid @ resid)
        self.sigma_ = float(np.sqrt(self.sse_ / max(1, n - p)))           # residual std
        gram_inv = np.linalg.pinv((phi / scale).T @ (phi / scale)) / np.outer(scale, scale)
        self.cov_ = self.sigma_ ** 2 * gram_inv
        self.cond_ = float(np.linalg.cond(phi))
        self.relative_error_ = float(np.linalg.norm(resid) / np.linalg.norm(y))   # paper / EMPS measure
        return self

    def predict(self, s: Samples) -> np.ndarray:
        return self.design(s) @ self.coef_

    # ---------------------------------------------------------------- reading the fit
    def _blocks(self):
        i = len(BASE)
        for e in self.effects:
            k = len(e.coef_names)
            yield e, slice(i, i + k)
            i += k

    @property
    def params_(self) -> dict[str, float]:
        """J, c0, c1 and every effect's parameters (``<effect>.<name>``)."""
        out = {"J": float(self.coef_[0]), "c0": float(self.coef_[2]), "c1": float(self.coef_[1])}
        for e, sl in self._blocks():
            for k, v in e.params(self.coef_[sl]).items():
                out[f"{e.name}.{k}"] = v
        return out

    @property
    def param_std_(self) -> dict[str, float]:
        sd = np.sqrt(np.diag(self.cov_))
        out = {"J": float(sd[0]), "c0": float(sd[2]), "c1": float(sd[1])}
        for e, sl in self._blocks():
            for k, v in e.param_std(self.coef_[sl], self.cov_[sl, sl]).items():
                out[f"{e.name}.{k}"] = v
        return out

    def effect_params(self, effect: Effect) -> dict:
        for e, sl in self._blocks():
            if e is effect:
                return e.params(self.coef_[sl])
        raise KeyError(effect)


@dataclass
class Errors:
    """Errors of a model on one set of samples (moving samples only)."""

    rmse: float                 # measured torque as logged minus predicted [Nm | N]
    torque_rms: float           # RMS of the measured torque on the same samples
    relative_error: float       # ||filtered torque - predicted|| / ||filtered torque|| (paper, EMPS)
    samples: int


def errors(model: AxisModel, s: Samples) -> Errors:
    m = s.moving
    pred = model.predict(s)[m]
    tau, tau_f = s.tau[m], s.tau_f[m]
    return Errors(float(np.sqrt(np.mean((tau - pred) ** 2))), float(np.sqrt(np.mean(tau ** 2))),
                  float(np.linalg.norm(tau_f - pred) / np.linalg.norm(tau_f)), int(m.sum()))


def tune(model: AxisModel, effect: Effect, s: Samples, seed: int) -> AxisModel:
    """Tune ``effect``'s nonlinear parameters (differential evolution, seeded) with every linear
    parameter solved by least squares inside (variable projection); return the fitted model."""
    candidate = model.with_effect(effect)
    if not effect.bounds:
        return candidate.fit(s)
    m = s.moving
    base = model.design(s)[m]
    y = s.tau_f[m]
    scale = np.sqrt(np.mean(base ** 2, axis=0))
    scale[scale == 0] = 1.0
    q, _ = np.linalg.qr(base / scale)                 # project the fixed columns out once
    y_perp = y - q @ (q.T @ y)
    keys = list(effect.bounds)
    sub = s.take(m)

    def sse(x):
        effect.hyper.update(zip(keys, x))
        extra = effect.columns(sub)
        extra = extra - q @ (q.T @ extra)
        coef, *_ = np.linalg.lstsq(extra, y_perp, rcond=None)
        r = y_perp - extra @ coef
        return float(r @ r)

    result = optimize.differential_evolution(sse, [effect.bounds[k] for k in keys], seed=seed,
                                             popsize=8, maxiter=25, tol=1e-6, polish=True)
    effect.hyper.update(zip(keys, result.x))
    return candidate.fit(s)


def fit_ga(model: AxisModel, s: Samples, seed: int) -> np.ndarray:
    """Every linear coefficient of ``model`` (fitted) again by differential evolution.

    The search box is the least-squares estimate ± max(50 %, 10 std) per
    coefficient; the cost is the same sum of squared torque errors, evaluated
    from the Gram matrix so each generation costs O(p²), not O(n).
    """
    m = s.moving
    phi, y = model.design(s)[m], s.tau_f[m]
    gram, b, yy = phi.T @ phi, phi.T @ y, float(y @ y)
    centre = model.coef_
    half = np.maximum(0.5 * np.abs(centre), 10 * np.sqrt(np.diag(model.cov_))) + 1e-12
    lo, hi = centre - half, centre + half

    def sse(theta):                                    # theta: (p, S) population
        return yy - 2 * b @ theta + np.einsum("is,ij,js->s", theta, gram, theta)

    result = optimize.differential_evolution(sse, list(zip(lo, hi)), seed=seed, vectorized=True,
                                             popsize=30, maxiter=400, tol=1e-10, polish=False, updating="deferred")
    return result.x
