"""Whether the data determine J, c0 and c1: "cannot tell" as an answer.

A parameter is undetermined, with the reason, when the model explains too little of the
torque to vouch for any of its coefficients; when parts of the data give it values that differ
beyond their std and by more than ``SPREAD_MAX`` of it
(:func:`~drive_bridge.ident.identify.consistency`; a smaller disagreement stays a warning); when it
lies within ``T_MIN`` of its reported std of zero; or when it comes out negative beyond that,
which no plant has.  The regressor column it is most nearly collinear with (on a joint, also the
gravity the model may lack) is named where that is what hides it.  An undetermined parameter is
reported as such and never tuned with or written (:func:`~drive_bridge.tuning.tune.read_identify_json`
refuses it).
"""

from __future__ import annotations

import logging

import numpy as np

from .effects import Gravity
from .model import BASE, AxisModel, Errors
from .signals import Samples

log = logging.getLogger(__name__)

T_MIN = 3.0  # a parameter within this many of its std of zero is not determined
COLLINEAR = 0.9  # |correlation| of its column with another's above which that one is named
FIT_MAX = 0.5  # a model leaving more than this share of the torque (validation) vouches for nothing
SPREAD_MAX = 0.25  # parts of the data that disagree (beyond their std) by more than this share of the value


def undetermined(
    model: AxisModel,
    est: Samples,
    after: Errors,
    consistency: dict,
    cannot_tell: dict | None = None,
    std: dict[str, float] | None = None,
) -> dict[str, str]:
    """What the data do not determine of J, c0, c1, and why.

    Parameters
    ----------
    model : AxisModel
        The final model.
    est : Samples
        The estimation samples (its columns' collinearity is read there).
    after : Errors
        Its validation errors (a model that explains too little vouches for nothing).
    consistency : dict
        :func:`.identify.consistency`'s answer (parts of the data that disagree).
    cannot_tell : dict, optional
        What is undetermined whatever the std: what the motion itself cannot tell
        (:mod:`.coverage`), a J that depends on the band (:func:`.identify.band_dependence`).
    std : dict of str to float, optional
        The std of J, c0, c1 as reported [SI] (:class:`.uncertainty.Uncertainty`); default
        ``model.param_std_``.

    Returns
    -------
    dict of str to str
        Parameter -> why; absent where the data determine it.
    """
    out = dict(cannot_tell or {})
    if after.relative_error > FIT_MAX:
        reason = (
            f"the model leaves {after.relative_error:.0%} of the torque unexplained on the validation "
            f"samples: none of its coefficients can be vouched for"
        )
        return dict.fromkeys(BASE, reason)
    moved = (consistency or {}).get("moved", {})
    reported = model.param_std_ if std is None else std
    phi, names = model.design(est)[est.moving], list(model.coef_names)
    if est.rotary and not any(isinstance(e, Gravity) for e in model.effects):
        phi = np.column_stack([phi, Gravity().columns(est)[est.moving]])  # what a joint's weight would be
        names += ["a joint's gravity (cos q)", "a joint's gravity (sin q)"]
    for i, p in enumerate(BASE):
        if p in out:
            continue  # the motion cannot tell it: said so, whatever its std
        value, sd = model.params_[p], reported[p]
        spread = np.ptp(list(moved[p]["values"].values())) if p in moved else 0.0
        if spread > SPREAD_MAX * abs(value):
            m = moved[p]
            out[p] = (
                "the parts of the data disagree: "
                + ", ".join(f"{n} {v:.4g}" for n, v in m["values"].items())
                + f" ({m['sigmas']:.3g} std apart, a spread of {spread / abs(value) if value else np.inf:.0%})"
            )
        elif not abs(value) >= T_MIN * sd:
            out[p] = (
                f"{value:.4g} ± {sd:.2g} is within {abs(value) / sd if sd else 0.0:.2g} std of zero"
                + _collinear(phi, i, names)
            )
        elif value < 0:
            out[p] = (
                f"{value:.4g} ± {sd:.2g} comes out negative, which no plant has: it stands in for a term "
                f"the model lacks" + _collinear(phi, i, names)
            )
    for p, why in out.items():
        log.info("axis %s: %s undetermined: %s", est.axis, p, why)
    return out


def _collinear(phi: np.ndarray, i: int, names: list[str]) -> str:
    """What column ``i`` of the design is most nearly collinear with, where that is close."""
    best, r_best = None, 0.0
    for j in range(phi.shape[1]):
        if j == i or np.ptp(phi[:, j]) == 0 or np.ptp(phi[:, i]) == 0:
            continue
        r = float(np.corrcoef(phi[:, i], phi[:, j])[0, 1])
        if abs(r) > abs(r_best):
            best, r_best = names[j], r
    if best is None or abs(r_best) < COLLINEAR:
        return ""
    return f": its column is nearly collinear with {best}'s (correlation {r_best:+.3f}), and the data cannot tell them apart"
