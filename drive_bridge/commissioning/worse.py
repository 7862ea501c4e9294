"""What is worse after commissioning than with the factory set, and why: each figure of the
validation that rose (model torque error, following error, overshoot, settling), named with its
values and the reason the data give, for the report.  Nothing here changes a verdict."""

from __future__ import annotations

RISE = 1.05  # a figure counts as worse when it rises by more than this factor ...
OVERSHOOT_PP = 0.01  # ... or, for overshoot, by more than this many percentage points


def _torque(traj: str, v: dict) -> str:
    b, a = v["torque_rmse_before"] * 1e3, v["torque_rmse_after"] * 1e3
    bb, ba = v.get("torque_rmse_between_steps_before"), v.get("torque_rmse_between_steps_after")
    head = f"{traj}: model torque RMSE {b:.3g} → {a:.3g} mNm"
    if bb is None or ba is None:
        return head + "."
    between = f"{bb * 1e3:.3g} → {ba * 1e3:.3g} mNm"
    if ba <= bb * RISE:
        lag = v.get("torque_lag_cycles_after")
        return (
            f"{head}; the rise is all at the demand's acceleration steps, between them the error is {between}. "
            f"With the model feed-forward the drive's torque steps with the demand (within {lag} "
            f"cycle{'s' if lag != 1 else ''}) where the factory set's rose over several, so a step the "
            f"prediction places a fraction of a cycle off weighs more: the model is no worse."
        )
    return (
        f"{head}, and between the demand's acceleration steps {between}: the model describes this trajectory "
        f"less well with the new gains (the torque now shows effects the identification did not see on the "
        f"campaign); see the traced effects."
    )


def worse(a: dict) -> list[str]:
    """Sentences, one per figure of the axis summary ``a``'s validation that got worse.

    Parameters
    ----------
    a : dict
        The axis in summary.json.

    Returns
    -------
    list of str
        The sentences (empty: nothing got worse).
    """
    notes = []
    gb, ga = a.get("gains_before") or {}, a.get("gains_after") or {}
    for traj, v in (a.get("validation") or {}).items():
        name = traj.replace("_", "-")
        # (a run that stopped has no 'after': nothing to compare)
        if (
            v.get("torque_rmse_before")
            and (v.get("torque_rmse_after") or 0.0) > v["torque_rmse_before"] * RISE
        ):
            notes.append(_torque(name, v))
        for key, what in (("fe_rms", "following error RMS"), ("fe_max", "largest following error")):
            if v.get(f"{key}_before") and (v.get(f"{key}_after") or 0.0) > v[f"{key}_before"] * RISE:
                notes.append(
                    f"{name}: {what} {v[f'{key}_before'] * 1e3:.3g} → {v[f'{key}_after'] * 1e3:.3g} mrad: "
                    f"the new gains follow this trajectory worse than the factory set (the verdict says "
                    f"whether that fails the axis)."
                )
        ob, oa = v.get("overshoot_pct_before"), v.get("overshoot_pct_after")
        if ob is not None and oa is not None and oa > ob + OVERSHOOT_PP:
            notes.append(
                f"{name}: overshoot {ob:.2g} → {oa:.2g} % of the move: the position loop is stiffer (KpP "
                f"{gb.get('KpP', float('nan')):.4g} → {ga.get('KpP', float('nan')):.4g} 1/s) with the "
                f"feed-forward on; the overshoot stays this small share of the move."
            )
        sb, sa = v.get("settling_s_before"), v.get("settling_s_after")
        if sb is not None and sa is not None and sa > sb * RISE and sa - sb > 1e-3:
            notes.append(f"{name}: settling into ±2 % {sb * 1e3:.0f} → {sa * 1e3:.0f} ms after the moves.")
    return notes
