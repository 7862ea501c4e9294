"""The effect contract, run over every effect of the library (scikit-learn's estimator checks
show the idea): constructor parameters kept as given, nonlinear parameters learned by ``fit``
only and ending in ``_``, columns of the declared shape, seeded fits reproducible, and each
nonlinear parameter found again on samples made here with a known value."""

from __future__ import annotations

import numpy as np
import pytest

from drive_bridge.ident.effects import (
    CrossAxis,
    Drift,
    Effect,
    NotFittedError,
    PositionPeriodic,
    Stribeck,
    candidates,
)
from drive_bridge.ident.model import AxisModel, base_columns, extend
from drive_bridge.ident.signals import Samples


def samples(seed: int = 0, n: int = 4000) -> Samples:
    """A back-and-forth sweep of a rotary joint with two speeds and an other axis "w" moving
    meanwhile (no plant: the tests set the torque)."""
    t = np.arange(n) * 0.002
    q = 3.0 * np.sin(2 * np.pi * 0.25 * t) + 0.4 * np.sin(2 * np.pi * 1.1 * t)
    qd, qdd = np.gradient(q, t), np.gradient(np.gradient(q, t), t)
    w = np.cos(2 * np.pi * 0.1 * t)
    noise = np.random.default_rng(seed).normal(0, 1e-3, n)
    tau = 1e-4 * qdd + 5e-4 * qd + 0.3 * np.sign(qd) + noise
    return Samples(
        "y",
        t,
        q,
        qd,
        qdd,
        np.sign(qd),
        tau,
        tau,
        np.abs(qd) > 0.05,
        {"w": (w, np.gradient(w, t), np.gradient(np.gradient(w, t), t))},
        rotary=True,
    )


S = samples()
#: one unfitted example of each effect, as the tracer offers it
EXAMPLES = {
    type(e): e
    for e in candidates([], S, S.tau - S.tau.mean())
    if not isinstance(e, CrossAxis) or e.form == "position_friction"
}


def every_effect():
    return list(EXAMPLES.values())


def test_the_tracer_offers_every_effect_of_the_library():
    library = {c for c in Effect.__subclasses__() if c.__module__ == Effect.__module__}
    assert set(EXAMPLES) == library


def fitted(effect: Effect, seed: int = 0) -> Effect:
    m = S.moving
    return effect.fit(S.take(m), base_columns(S)[m], S.tau_f[m], seed=seed)


@pytest.mark.parametrize("effect", every_effect(), ids=lambda e: type(e).__name__)
def test_parameters_are_kept_and_fitted_values_end_in_underscore(effect):
    params = effect.get_params()
    clone = type(effect)(**params)
    assert clone.get_params() == params and repr(clone) == repr(effect)
    if effect.nonlinear:
        with pytest.raises(NotFittedError):
            clone.columns(S)
    before = set(vars(clone))
    fitted(clone)
    assert clone.get_params() == params  # fit never changes what was given
    learned = set(vars(clone)) - before
    assert learned == {k + "_" for k in clone.nonlinear}
    for k in clone.nonlinear:
        lo, hi = clone.bounds()[k]
        assert lo <= getattr(clone, k + "_") <= hi
    cols = clone.columns(S)
    assert cols.shape == (len(S), len(clone.coef_names)) and np.all(np.isfinite(cols))
    assert isinstance(clone.depends_on, str) and clone.depends_on


@pytest.mark.parametrize("effect", every_effect(), ids=lambda e: type(e).__name__)
def test_a_seeded_fit_is_reproducible_and_params_name_every_coefficient(effect):
    a, b = fitted(type(effect)(**effect.get_params()), 5), fitted(type(effect)(**effect.get_params()), 5)
    assert {k: v for k, v in vars(a).items() if k.endswith("_")} == {
        k: v for k, v in vars(b).items() if k.endswith("_")
    }
    model = extend(AxisModel(seed=5).fit(S), type(effect)(**effect.get_params()), S)
    names = set(model.params_) - {"J", "c0", "c1"}
    assert names and all(n.startswith(effect.name + ".") for n in names)
    assert set(model.param_std_) <= set(model.params_)


@pytest.mark.parametrize(
    "effect,column,truth",
    [
        (PositionPeriodic(1.05), lambda s: 0.03 * np.sin(2 * np.pi * s.q / 1.0 + 0.4), {"period": 1.0}),
        (
            Stribeck(0.5, low=0.05, high=3.0),
            lambda s: 0.05 * np.exp(-((s.qd / 0.8) ** 2)) * np.sign(s.qd),
            {"velocity": 0.8},
        ),
        (
            Drift(1.0, low=0.1, high=20.0),
            lambda s: 0.08 * np.exp(-s.t / 2.5) * np.sign(s.qd),
            {"time_constant": 2.5},
        ),
    ],
)
def test_fit_finds_the_nonlinear_parameter_it_was_made_with(effect, column, truth):
    s = samples(seed=1)
    s.tau_f = s.tau = s.tau + column(s)
    model = extend(AxisModel().fit(s), effect, s)
    for k, v in truth.items():
        assert getattr(effect, k + "_") == pytest.approx(v, rel=0.03), k
    assert model.sigma_ < 1.5e-3  # down to the noise
