"""What the motion can tell, said before the fit: the directions the axis moved in, how often it
reversed, the range of its speeds and accelerations -- and which of c0 and c1 that motion cannot
determine, whatever the fit's std says.

* **One direction only** (the other holds less than ``ONE_WAY_SHARE`` of the moving samples):
  sign(q̇) is the same constant throughout, so c0·sign(q̇) is collinear with the offset -- any
  constant torque (a bias, the mean of a cogging, a load) -- and c0 is undetermined.
* **One speed, or speeds in a narrow band** (the 90th percentile of |q̇| less than ``NARROW_BAND``
  times the 10th): c1·q̇ is then nearly c1·v̄·sign(q̇), collinear with c0 and the offset, and c1 is
  undetermined.

J needs acceleration, which the std already judges: the acceleration range is said here for the
reader (a constant-speed log has none to speak of).
"""

from __future__ import annotations

import numpy as np

from .signals import Samples

ONE_WAY_SHARE = 0.05  # the other direction below this share of the moving samples: one direction
NARROW_BAND = 1.5  # p90/p10 of the moving speeds below this: one speed, as far as c1 is concerned


def what_the_motion_tells(est: Samples, unit: str) -> dict:
    """What the motion of the fitted samples covers, and what it cannot determine.

    Parameters
    ----------
    est : Samples
        The estimation samples (their moving ones).
    unit : str
        The axis's position unit, rad or m.

    Returns
    -------
    dict
        ``directions`` (share of the moving samples each way), ``reversals`` (changes of
        direction between moving samples), ``speed`` (p10, p50, p90, max of |q̇|) and
        ``acceleration`` (p90, max of |q̈|) in ``unit``/s and ``unit``/s², and ``cannot_tell``:
        c0 / c1 -> why the motion does not determine it (absent where it may).
    """
    velocity = est.qd[est.moving]
    if not len(velocity):
        return {"directions": {}, "reversals": 0, "cannot_tell": {}}
    speed, acceleration = np.abs(velocity), np.abs(est.qdd[est.moving])
    positive = float(np.mean(velocity > 0))
    p10, p50, p90 = (float(v) for v in np.percentile(speed, (10, 50, 90)))
    cannot_tell: dict[str, str] = {}
    out = {
        "directions": {"positive": round(positive, 4), "negative": round(1 - positive, 4)},
        "reversals": int(np.count_nonzero(np.diff(np.sign(velocity)))),
        "speed": {"p10": p10, "p50": p50, "p90": p90, "max": float(speed.max()), "unit": f"{unit}/s"},
        "acceleration": {
            "p90": float(np.percentile(acceleration, 90)),
            "max": float(acceleration.max()),
            "unit": f"{unit}/s²",
        },
        "cannot_tell": cannot_tell,
    }
    if min(positive, 1 - positive) < ONE_WAY_SHARE:
        way = "positive" if positive > 0.5 else "negative"
        cannot_tell["c0"] = (
            f"the axis moves in one direction only ({way}, {max(positive, 1 - positive):.1%} of the "
            f"moving samples): sign(q̇) is a constant, so c0 is collinear with the offset (any constant "
            f"torque: a bias, the mean of a cogging) and the data cannot tell them apart"
        )
    if p10 > 0 and p90 / p10 < NARROW_BAND:
        cannot_tell["c1"] = (
            f"the speeds lie in a narrow band ({p10:.4g} .. {p90:.4g} {unit}/s, 10th to 90th "
            f"percentile): c1·q̇ is then nearly a constant times sign(q̇), collinear with c0 and the "
            f"offset, and the data cannot tell them apart"
        )
    return out


def motion_text(motion: dict) -> str:
    """What the motion covers and what it cannot tell, in one line.

    Parameters
    ----------
    motion : dict
        :func:`what_the_motion_tells`'s answer.

    Returns
    -------
    str
        The line.
    """
    d = motion.get("directions")
    if not d:
        return "motion: none fitted"
    ways = "both directions" if min(d.values()) >= ONE_WAY_SHARE else "one direction only"
    s, a = motion["speed"], motion["acceleration"]
    text = (
        f"motion: {ways} ({d['positive']:.0%} positive), {motion['reversals']} reversals, speed "
        f"{s['p10']:.4g} .. {s['p90']:.4g} {s['unit']} (10th to 90th percentile, max {s['max']:.4g}), "
        f"acceleration up to {a['max']:.4g} {a['unit']}"
    )
    cannot = motion["cannot_tell"]
    return text + (f"; it cannot determine {', '.join(cannot)}" if cannot else "")
