"""The axis model τ = J·q̈ + c1·q̇ + c0·sign(q̇) + Σ effects, as an estimator.

``AxisModel(effects).fit(samples)`` solves the least-squares problem of the
paper (eq. 2–3) on the moving samples, with the filtered torque as the
observation; fitted values end in ``_`` (scikit-learn style), and only ``fit``
sets them.  ``AxisModel(effects, method="ga", seed=...)`` fits the same
structure with differential evolution (the paper's genetic algorithm).  The
covariance of the coefficients is heteroskedasticity- and autocorrelation-consistent
(batch means over the residual's correlation length): coloured or non-Gaussian residuals, and structure the model leaves
in them, widen it instead of hiding behind the white-noise formula σ²(ΦᵀΦ)⁻¹.
:func:`extend` adds an effect: its nonlinear parameters first, then every
coefficient again.  Units follow the axis: J [kg·m² | kg], c1 [Nm·s/rad |
N·s/m], c0 [Nm | N].
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import fft

from . import evolution
from .effects import Effect
from .signals import Samples, Signals, derivative

BASE = ("J", "c1", "c0")
JACKKNIFE_BLOCKS = 10  # stretches of the log in time for the delete-one-block jackknife (AxisModel)
JACKKNIFE_BEYOND = 2.0  # ... which replaces the HAC std where larger by this factor: a 10-block jackknife's
# own scatter (~25 %) is no evidence of structure, nor is a campaign whose blocks
# differ (the paper's runs its speeds one after the other: 1.5x on the simulated
# Y axis's c0 and c1, no structure); twice the HAC std is


def base_columns(s: Samples) -> np.ndarray:
    """The rigid model's regressor columns.

    Parameters
    ----------
    s : Samples
        The samples.

    Returns
    -------
    numpy.ndarray
        n × 3: q̈, q̇ and sign(q̇) (filtered as the torque), for J, c1 and c0.
    """
    return np.column_stack((s.qdd, s.qd, s.sgn))


class AxisModel:
    """Base rigid-body model plus ``effects`` (fitted ones: their nonlinear parameters learned),
    fitted by least squares (``method="lse"``) or differential evolution (``"ga"``, seeded).

    As scikit-learn's estimators: the settings are given here, and the fitted values (``coef_``,
    ``cov_``, ``sigma_``, ...) are set by :meth:`fit` alone.

    Parameters
    ----------
    effects : sequence of Effect
        The effects beside J, c1, c0 (fitted ones: their nonlinear parameters learned).
    method : {"lse", "ga"}
        Least squares, or differential evolution (the paper's genetic algorithm) on the same cost.
    seed : int
        Seed of the differential evolution (the same seed, the same numbers).
    jackknife_blocks : int
        With more than 0, the fit's covariance is widened to the delete-one-block jackknife over
        that many stretches of the log in time where that is larger (:data:`JACKKNIFE_BEYOND`); 0:
        the least-squares (HAC) covariance.
    condition_number : bool
        Compute ``cond_`` (a singular value decomposition of the regressor matrix: a fifth of a
        fit's time); False where nobody reads it (the tracing's candidates, the jackknife's parts).

    Attributes
    ----------
    coef_ : numpy.ndarray
        The coefficients, in :attr:`coef_names` order: J [kg·m² | kg], c1 [Nm·s/rad | N·s/m],
        c0 [Nm | N], then each effect's.
    cov_ : numpy.ndarray
        Their covariance (HAC; widened by the jackknife where asked for).
    sigma_ : float
        The residual's std [Nm | N].
    cond_ : float or None
        The condition number of the regressor matrix (None: made with ``condition_number=False``).
    sse_ : float
        The sum of squared residuals [Nm² | N²].
    relative_error_ : float
        ||residual|| / ||filtered torque|| on the fitted samples (the paper's measure).
    """

    METHODS = ("lse", "ga")

    def __init__(
        self,
        effects: list[Effect] | tuple[Effect, ...] = (),
        method: str = "lse",
        seed: int = 0,
        jackknife_blocks: int = 0,
        condition_number: bool = True,
    ):
        if method not in self.METHODS:
            raise ValueError(f"method must be one of {self.METHODS}, got {method!r}")
        self.effects = list(effects)
        self.method = method
        self.seed = seed
        self.jackknife_blocks = jackknife_blocks
        self.condition_number = condition_number

    def with_effect(self, effect: Effect) -> AxisModel:
        """The same model, unfitted, with one more effect.

        Parameters
        ----------
        effect : Effect
            The effect to add.

        Returns
        -------
        AxisModel
            A new, unfitted model with the same settings.
        """
        return AxisModel(
            self.effects + [effect], self.method, self.seed, self.jackknife_blocks, self.condition_number
        )

    def design(self, s: Samples, logged: bool = False) -> np.ndarray:
        """The regressor matrix.

        Parameters
        ----------
        s : Samples
            The samples.
        logged : bool
            Every column filtered as the torque as logged, not as the filtered torque the fit
            uses (the base columns are smooth: the same either way).

        Returns
        -------
        numpy.ndarray
            n × len(:attr:`coef_names`), SI.
        """
        return np.column_stack([base_columns(s)] + [e.columns(s, logged) for e in self.effects])

    @property
    def coef_names(self) -> list[str]:
        """The coefficients' names: J, c1, c0, then ``<effect>.<coefficient>`` for each effect."""
        return list(BASE) + [f"{e.name}.{c}" for e in self.effects for c in e.coef_names]

    def fit(self, s: Samples) -> AxisModel:
        """Fit every coefficient on the moving samples.

        ``cov_``, ``sigma_`` and ``cond_`` are those of the least-squares problem (with ``"ga"``
        too: differential evolution gives no covariance), ``cov_`` widened by the jackknife where
        ``jackknife_blocks`` says (``jackknife_``: the ratio jackknife / HAC std per coefficient,
        ones without it).

        Parameters
        ----------
        s : Samples
            The samples (:func:`.signals.prepare`); only the moving ones are fitted.

        Returns
        -------
        AxisModel
            This model, fitted.
        """
        rows = np.flatnonzero(s.moving)  # (rows taken by index: a boolean mask's copy is 5x slower)
        phi, y = self.design(s).take(rows, axis=0), s.tau_f[rows]
        scale = np.sqrt(np.mean(phi**2, axis=0))
        scale[scale == 0] = 1.0
        scaled = phi / scale
        coef, *_ = np.linalg.lstsq(scaled, y, rcond=None)
        coef = coef / scale
        n, p = phi.shape
        resid = y - phi @ coef
        self.sigma_ = float(np.sqrt(float(resid @ resid) / max(1, n - p)))  # residual std
        gram_inv = np.linalg.pinv(scaled.T @ scaled) / np.outer(scale, scale)
        self.cov_ = hac_covariance(phi, resid, gram_inv, n - p)
        self.cond_ = float(np.linalg.cond(phi)) if self.condition_number else None
        self.converged_ = True  # "ga": whether the search converged before its generation limit
        if self.method == "ga":
            result = _differential_evolution(phi, y, coef, self.cov_, self.seed)
            coef, self.converged_ = result.x, bool(result.success)
            resid = y - phi @ coef
        self.coef_ = coef
        self.n_samples_ = n
        self.sse_ = float(resid @ resid)
        self.relative_error_ = float(np.linalg.norm(resid) / np.linalg.norm(y))  # paper / EMPS measure
        self.jackknife_ = np.ones(len(coef))
        if self.jackknife_blocks:
            self._widen(s, self.jackknife_blocks)
        return self

    def _widen(self, s: Samples, blocks: int) -> None:
        """Widen ``cov_`` to the delete-one-block jackknife over ``blocks`` stretches of ``s`` in
        time (equal counts of moving samples) wherever that is larger by ``JACKKNIFE_BEYOND``,
        keeping the correlations:
        the HAC estimate sees coloured noise and heteroskedasticity, the jackknife also a
        structure the model lacks that changes over the log (heating, a payload, a stroke
        covered unevenly)."""
        order = np.minimum(np.cumsum(s.moving) * blocks // max(1, int(s.moving.sum())), blocks - 1)
        coefs = []
        for b in range(blocks):
            part = s.take(order != b)
            if part.moving.sum() > 3 * len(self.coef_):
                coefs.append(AxisModel(self.effects, seed=self.seed, condition_number=False).fit(part).coef_)
        if len(coefs) < 3:
            return
        c = np.array(coefs)
        k = len(c)
        jack = np.sqrt((k - 1) / k * np.sum((c - c.mean(axis=0)) ** 2, axis=0))
        hac = np.sqrt(np.maximum(np.diag(self.cov_), 1e-300))
        self.jackknife_ = jack / hac
        scale = np.where(self.jackknife_ > JACKKNIFE_BEYOND, self.jackknife_, 1.0)
        self.cov_ = self.cov_ * np.outer(scale, scale)

    def predict(self, s: Samples, logged: bool = False) -> np.ndarray:
        """The torque the model predicts.

        Parameters
        ----------
        s : Samples
            The samples.
        logged : bool
            The torque as logged, not the filtered torque.

        Returns
        -------
        numpy.ndarray
            The torque at each sample [Nm | N].
        """
        return self.design(s, logged) @ self.coef_

    # ---------------------------------------------------------------- reading the fit
    def _blocks(self) -> Iterator[tuple[Effect, slice]]:
        i = len(BASE)
        for e in self.effects:
            k = len(e.coef_names)
            yield e, slice(i, i + k)
            i += k

    @property
    def params_(self) -> dict[str, Any]:
        """J, c0, c1 and every effect's parameters (``<effect>.<name>``: numbers, and the names
        that say what an effect is, as a cross-axis coupling's source)."""
        out: dict[str, Any] = {
            "J": float(self.coef_[0]),
            "c0": float(self.coef_[2]),
            "c1": float(self.coef_[1]),
        }
        for e, sl in self._blocks():
            for k, v in e.params(self.coef_[sl]).items():
                out[f"{e.name}.{k}"] = v
        return out

    @property
    def param_std_(self) -> dict[str, float]:
        """The std of J, c0, c1 and of every effect's parameters (``<effect>.<name>``), SI."""
        return self.std_of(self.cov_)

    def std_of(self, cov: np.ndarray) -> dict[str, float]:
        """The std of J, c0, c1 and of every effect's parameters from a covariance of the fitted
        coefficients (``cov_`` gives :attr:`param_std_`; an identification's reported one,
        :class:`.uncertainty.Uncertainty`).

        Parameters
        ----------
        cov : numpy.ndarray
            The coefficients' covariance (``coef_names`` order) [SI²].

        Returns
        -------
        dict of str to float
            Name -> std [SI].
        """
        sd = std_from_cov(cov)
        out = {"J": float(sd[0]), "c0": float(sd[2]), "c1": float(sd[1])}
        for e, sl in self._blocks():
            for k, v in e.param_std(self.coef_[sl], cov[sl, sl]).items():
                out[f"{e.name}.{k}"] = v
        return out

    def _coef_of(self, effect: Effect) -> np.ndarray:
        for e, sl in self._blocks():
            if e is effect:
                return self.coef_[sl]
        raise KeyError(effect)

    def effect_term(self, effect: Effect, s: Samples) -> np.ndarray:
        """The torque one of the model's effects contributes to the prediction.

        Parameters
        ----------
        effect : Effect
            One of the model's effects.
        s : Samples
            The samples.

        Returns
        -------
        numpy.ndarray
            Its torque at each sample [Nm | N], filtered as the fit's.
        """
        return effect.columns(s, False) @ self._coef_of(effect)

    def effect_params(self, effect: Effect) -> dict:
        """One effect's physical parameters from the fitted coefficients.

        Parameters
        ----------
        effect : Effect
            One of the model's effects.

        Returns
        -------
        dict
            Its parameters by name (amplitude, period, ...; SI).
        """
        return effect.params(self._coef_of(effect))


def std_from_cov(cov: np.ndarray) -> np.ndarray:
    """The std of each coefficient from their covariance (a negative variance, rounding's: 0).

    Parameters
    ----------
    cov : numpy.ndarray
        The coefficients' covariance, p × p [SI²].

    Returns
    -------
    numpy.ndarray
        p std [SI].
    """
    return np.sqrt(np.maximum(np.diag(cov), 0.0))


DIRECT_LAGS = 64  # hac_lags: lags of the autocorrelation summed directly, beyond them by FFT


def hac_lags(resid: np.ndarray) -> int:
    """Correlation length of a residual.

    Parameters
    ----------
    resid : numpy.ndarray
        The residual, in time order.

    Returns
    -------
    int
        [samples] the Newey-West (1994) rule 4·(n/100)^(2/9), or longer while its autocorrelation
        stays above the white-noise band 2/√n (at most n/10).
    """
    n = len(resid)
    rule = int(4 * (n / 100) ** (2 / 9))
    r = resid - resid.mean()
    power = float(r @ r)
    if power <= 0:
        return rule
    cap = max(1, n // 10)
    band = 2 / np.sqrt(n) * power
    for lag in range(1, min(cap, DIRECT_LAGS) + 1):  # the correlation is short: the first lags directly
        if float(r[:-lag] @ r[lag:]) <= band:
            return min(max(rule, lag), cap)
    size = fft.next_fast_len(2 * n - 1, real=True)  # no wrap-around; a length pocketfft is fast at
    spectrum = fft.rfft(r, size)
    acf = fft.irfft(spectrum.real**2 + spectrum.imag**2, size)[:n]
    below = np.flatnonzero(acf[1 : cap + 1] <= band)
    lag = int(below[0]) + 1 if len(below) else cap
    return min(max(rule, lag), cap)


def hac_covariance(phi: np.ndarray, resid: np.ndarray, gram_inv: np.ndarray, dof: int) -> np.ndarray:
    """Autocorrelation- and heteroskedasticity-consistent sandwich covariance of least-squares
    coefficients: the long-run covariance of the scores φ·e by batch means over blocks as long
    as the residual's correlation length (one sample: White's estimator), with the small-sample
    factor n/dof.

    Parameters
    ----------
    phi : numpy.ndarray
        The regressors, n × p.
    resid : numpy.ndarray
        The residual, n, in time order.
    gram_inv : numpy.ndarray
        (φᵀφ)⁻¹, p × p.
    dof : int
        The residual's degrees of freedom, n - p.

    Returns
    -------
    numpy.ndarray
        The coefficients' covariance, p × p.
    """
    n, p = phi.shape
    u = phi * resid[:, None]
    b = hac_lags(resid) + 1
    full = n // b
    blocks = u[: full * b].reshape(full, b, p).sum(axis=1)
    tail = u[full * b :].sum(axis=0)
    meat = blocks.T @ blocks + np.outer(tail, tail)
    return gram_inv @ meat @ gram_inv * (n / max(1, dof))


MAX_DELAY_SAMPLES = 3.0  # a torque delay estimated beyond this many log samples is no plain delay


class _TorqueRate(Effect):
    """One more model column, not an effect of the library: the torque's rate of change,
    negated, at the log's rate (``dt`` [s]) and filtered as the torque is; its coefficient is
    the torque's delay [s] (:func:`torque_delay`)."""

    name, depends_on, coef_names = "torque_rate", "time", ("delay_s",)

    def __init__(self, dt: float):
        self.dt = dt

    def _columns(self, s: Signals) -> np.ndarray:
        return -derivative(s.tau, self.dt)[:, None]


def torque_delay(model: AxisModel, s: Samples, dt: float) -> tuple[float, float]:
    """Delay [s] of the logged torque behind the logged position, and its (HAC) std.

    A drive that reports the current averaged since its last report, or filtered, or sampled
    at another instant than the position, logs a torque that lags the position; the model
    then fits J·q̈ against a torque that comes later, and anything fast in it (cogging at speed)
    against the wrong phase.  ``model``'s columns are fitted again with one more, the filtered
    torque's derivative: τ_f(t) ≈ τ_f(t + d) − d·τ̇_f(t), so d comes out of the same least
    squares, to first order (d ≪ the period of the cut-off), beyond the alignment ``s`` already
    has.  Estimated with the model's effects in it: a structure the columns lack (cogging at
    speed) biases it, so it is estimated again as effects are added.  An estimate beyond
    ±``MAX_DELAY_SAMPLES`` log samples is no plain delay (a compliant transmission or a filter
    shifts the phase too): the caller leaves it alone.

    Parameters
    ----------
    model : AxisModel
        The model so far (its effects are fitted again with the torque's rate beside them).
    s : Samples
        The samples, as aligned so far.
    dt : float
        The log's sample period [s].

    Returns
    -------
    delay : float
        The delay [s] beyond the alignment ``s`` has.
    std : float
        Its std [s] (HAC).
    """
    lead = AxisModel(model.effects + [_TorqueRate(dt)], seed=model.seed).fit(s)
    coef, cov = lead.coef_, lead.cov_
    return float(coef[-1]), float(np.sqrt(max(cov[-1, -1], 0.0)))


@dataclass
class Errors:
    """Errors of a model on one set of samples (moving samples only).

    Parameters
    ----------
    rmse : float
        RMS of the measured torque as logged minus the predicted [Nm | N].
    torque_rms : float
        RMS of the measured torque on the same samples [Nm | N].
    relative_error : float
        ||filtered torque - predicted|| / ||filtered torque|| (the paper's measure, EMPS's).
    samples : int
        How many samples.
    """

    rmse: float
    torque_rms: float
    relative_error: float
    samples: int


def errors(model: AxisModel, s: Samples) -> Errors:
    """A model's errors on a set of samples.

    Parameters
    ----------
    model : AxisModel
        A fitted model.
    s : Samples
        The samples (only the moving ones count).

    Returns
    -------
    Errors
        The RMS error of the torque as logged, the torque's RMS, the relative error of the
        filtered torque, and the count.
    """
    m = s.moving
    pred, logged = model.predict(s)[m], model.predict(s, logged=True)[m]
    tau, tau_f = s.tau[m], s.tau_f[m]
    return Errors(
        float(np.sqrt(np.mean((tau - logged) ** 2))),
        float(np.sqrt(np.mean(tau**2))),
        float(np.linalg.norm(tau_f - pred) / np.linalg.norm(tau_f)),
        int(m.sum()),
    )


def extend(model: AxisModel, effect: Effect, s: Samples) -> AxisModel:
    """A model with one more effect, fitted: the effect's nonlinear parameters learned with every
    column of the model solved inside (seeded with the model's seed), then every coefficient
    refitted together.

    Parameters
    ----------
    model : AxisModel
        The fitted model.
    effect : Effect
        The effect to add (its nonlinear parameters are learned here).
    s : Samples
        The samples.

    Returns
    -------
    AxisModel
        A new model with ``model``'s settings, fitted.
    """
    rows = np.flatnonzero(s.moving)
    effect.fit(s.take(rows), model.design(s).take(rows, axis=0), s.tau_f[rows], seed=model.seed)
    return model.with_effect(effect).fit(s)


def _differential_evolution(
    phi: np.ndarray, y: np.ndarray, centre: np.ndarray, cov: np.ndarray, seed: int
) -> evolution.OptimizeResult:
    """Every coefficient by differential evolution around the least-squares estimate ``centre``.

    The search box is ``centre`` ± max(50 %, 10 std) per coefficient; the cost is the same sum
    of squared torque errors, evaluated from the Gram matrix so each generation costs O(p²),
    not O(n).  The result's ``success`` says whether it converged within its generation limit.
    """
    gram, b, yy = phi.T @ phi, phi.T @ y, float(y @ y)
    half = np.maximum(0.5 * np.abs(centre), 10 * std_from_cov(cov)) + 1e-12
    lo, hi = centre - half, centre + half

    def sse(theta: np.ndarray) -> np.ndarray:  # theta: (p, S) population
        return yy - 2 * b @ theta + np.einsum("is,ij,js->s", theta, gram, theta)

    return evolution.differential_evolution(
        sse, list(zip(lo, hi)), seed, popsize=30, maxiter=400, tol=1e-10, polish=False
    )
