"""The axis model as an estimator (`drive_bridge/ident/model.py`)."""

from __future__ import annotations

import numpy as np

from drive_bridge.ident.effects import Offset, PositionLinear
from drive_bridge.ident.model import AxisModel, extend

from .test_effects import samples


def test_a_fit_without_its_condition_number_is_the_same_fit():
    """``condition_number=False`` (the tracing's candidates) leaves out only ``cond_``: every other fitted
    value is the same number; with it, ``cond_`` is the condition number of the moving samples'
    regressor matrix."""
    s = samples(seed=3)
    effects = [Offset(), PositionLinear()]
    full = AxisModel(effects, seed=1).fit(s)
    bare = AxisModel(effects, seed=1, condition_number=False).fit(s)
    assert bare.cond_ is None
    assert full.cond_ == np.linalg.cond(full.design(s)[s.moving])
    fitted = {k: v for k, v in vars(full).items() if k.endswith("_") and k != "cond_"}
    assert fitted.keys() == {k for k in vars(bare) if k.endswith("_") and k != "cond_"}
    for k, v in fitted.items():
        assert np.array_equal(v, getattr(bare, k)), k


def test_an_extended_model_is_fitted_as_the_model_with_the_effect():
    """:func:`extend` learns nothing here (an effect without nonlinear parameters): its model is the
    one made with the effect from the start, with the model's settings, fitted alike."""
    s = samples(seed=4)
    for condition_number in (True, False):
        base = AxisModel([Offset()], seed=2, condition_number=condition_number).fit(s)
        grown = extend(base, PositionLinear(), s)
        direct = AxisModel([Offset(), PositionLinear()], seed=2, condition_number=condition_number).fit(s)
        assert [e.name for e in grown.effects] == ["offset", "position_linear"]
        assert grown.cond_ == direct.cond_ and (grown.cond_ is None) is not condition_number
        assert np.array_equal(grown.coef_, direct.coef_) and np.array_equal(grown.cov_, direct.cov_)
