"""What a residual depends on: the correlation ratio η² of its means in bins of a variable
(one-way ANOVA), on the residual as it is (``even``), times the direction of motion (``odd``: a
torque against the motion, friction-like) and, over the position, times the acceleration
(``inertial``: an inertia that changes along the stroke).  Shared by the residual tracing (which
effects to try) and its report (what is left unexplained)."""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import stats

from .signals import Samples, Signals

BINS = 20


def bins(x: np.ndarray) -> np.ndarray | None:
    """The bin of each sample of a variable, binned at its quantiles (``BINS`` bins).

    Parameters
    ----------
    x : numpy.ndarray
        The variable.

    Returns
    -------
    numpy.ndarray or None
        Each sample's bin; None where the variable's values give fewer than two bins.
    """
    edges = np.unique(np.quantile(x, np.linspace(0, 1, BINS + 1)))
    if len(edges) < 3:
        return None
    return np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)


def eta2(idx: np.ndarray | None, r: np.ndarray) -> tuple[float, float, float]:
    """How much of a residual its mean in bins of a variable explains (one-way ANOVA).

    Parameters
    ----------
    idx : numpy.ndarray or None
        The variable's bin at each sample (:func:`bins`).
    r : numpy.ndarray
        The residual at the same samples.

    Returns
    -------
    share : float
        The share of var(r) explained (η²).
    p : float
        The ANOVA p-value.
    f : float
        The F statistic.
    """
    if idx is None:
        return 0.0, 1.0, 0.0
    counts = np.bincount(idx)
    means = np.bincount(idx, r) / np.maximum(counts, 1)
    between = float(np.sum(counts * (means - r.mean()) ** 2))
    total = float(np.sum((r - r.mean()) ** 2))
    k, n = int(np.count_nonzero(counts)), len(r)
    if total == 0 or k < 2 or n <= k:
        return 0.0, 1.0, 0.0
    f = (between / (k - 1)) / max((total - between) / (n - k), 1e-300)
    return between / total, float(stats.f.sf(f, k - 1, n - k)), float(f)


def variables(s: Signals) -> dict[str, np.ndarray]:
    """The candidate variables of a residual.

    Parameters
    ----------
    s : Samples or Channels
        The signals.

    Returns
    -------
    dict of str to numpy.ndarray
        Position, velocity, acceleration, |acceleration| (the transmitted inertial torque's size),
        time, direction, and the other axes' position, velocity and acceleration
        (``<axis>_position``, ...).
    """
    out = {
        "position": s.q,
        "velocity": s.qd,
        "acceleration": s.qdd,
        "abs_acceleration": np.abs(s.qdd),
        "time": s.t,
        "direction": np.sign(s.qd),
    }
    for o, (q, qd, qdd) in s.others.items():
        out.update({f"{o}_position": q, f"{o}_velocity": qd, f"{o}_acceleration": qdd})
    return out


def dependences(s: Samples, residual: np.ndarray, min_share: float, p_value: float) -> list[dict]:
    """What a residual depends on, on the moving samples.

    Parameters
    ----------
    s : Samples
        The samples.
    residual : numpy.ndarray
        The residual at them [Nm | N].
    min_share : float
        The share of the residual variance a dependence must explain ...
    p_value : float
        ... at an ANOVA p-value below this.

    Returns
    -------
    list of dict
        Per variable that passes, the strongest of its forms (even, odd; over position also
        inertial): ``depends_on``, ``form``, ``fraction``, ``evidence`` (F).
    """
    m = s.moving
    r = residual[m]
    direction = np.sign(s.qd[m])
    accel = s.qdd[m] / max(float(np.sqrt(np.mean(s.qdd[m] ** 2))), 1e-300)
    out = []
    for name, x in variables(s).items():
        found: list[dict[str, Any]] = []
        idx = bins(x[m])  # (binned once: the forms share the variable's bins)
        for form, resid in (("even", r), ("odd", r * direction), ("inertial", r * accel)):
            if form == "odd" and name in ("direction", "velocity"):
                continue  # sign(q̇)·r over q̇ or its sign: the even test sees it already
            if form == "inertial" and name != "position":
                continue  # an inertia changes with where the load is, not with speed
            share, p, f = eta2(idx, resid)
            if share >= min_share and p < p_value:
                found.append(
                    {"depends_on": name, "form": form, "fraction": round(share, 4), "evidence": round(f, 1)}
                )
        if found:
            out.append(max(found, key=lambda d: d["evidence"]))
    return out
