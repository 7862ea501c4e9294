"""The verdict on a commissioning: does each axis meet what an engineer signs off on?

Criteria per axis, with the field's usual defaults (``acceptance`` in bus.yml overrides them):

* FAIL where unmet — the loops as written: velocity and position loop phase margin ≥ 45°,
  gain margin ≥ 8 dB; the following error on every validation trajectory at least
  ``min_fe_improvement`` times smaller than with the factory set;
* WARN where unmet — the model: final validation torque RMSE within ``max_rmse_over_noise``
  times the noise floor; relative std of J, c0 and c1 below ``max_relative_std``; the
  identification consistent between parts of the data.

An axis is FAIL if a FAIL criterion is unmet, else WARN if a WARN criterion is, else PASS; a
criterion whose data the run did not produce (a step not run) is listed as not evaluated, and
an axis with one is INCOMPLETE unless it already failed.  The overall verdict is the worst axis's.
"""

from __future__ import annotations

from typing import Any

from ..config import Acceptance

ORDER = ("PASS", "WARN", "INCOMPLETE", "FAIL")


def _criterion(name: str, severity: str, value: Any, limit: Any, ok: bool | None, unit: str = "") -> dict:
    return {"criterion": name, "severity": severity, "value": value, "limit": limit, "unit": unit, "met": ok}


def axis_criteria(entry: dict, acc: Acceptance) -> list[dict]:
    """The criteria of one axis of summary.json, each met, unmet or None (not evaluated).

    Parameters
    ----------
    entry : dict
        The axis in summary.json.
    acc : Acceptance
        What the verdict checks.

    Returns
    -------
    list of dict
        Per criterion: ``criterion`` (its name), ``severity``, ``value``, ``limit``, ``unit``, ``met``.
    """
    out = []
    margins = entry.get("margins") or {}
    for loop in ("velocity", "position"):
        m = margins.get(loop) or {}
        pm, gm = m.get("phase_margin_deg"), m.get("gain_margin_db")
        out.append(
            _criterion(
                f"{loop} loop phase margin",
                "FAIL",
                pm,
                f"≥ {acc.min_phase_margin_deg:g}",
                None if pm is None else pm >= acc.min_phase_margin_deg,
                "°",
            )
        )
        out.append(
            _criterion(
                f"{loop} loop gain margin",
                "FAIL",
                gm,
                f"≥ {acc.min_gain_margin_db:g}",
                None if gm is None else gm >= acc.min_gain_margin_db,
                "dB",
            )
        )
    validation = entry.get("validation") or {}
    if not validation:
        out.append(
            _criterion(
                "following error improvement", "FAIL", None, f"≥ {acc.min_fe_improvement:g}×", None, "×"
            )
        )
    for traj, v in validation.items():
        before, after = v.get("fe_rms_before"), v.get("fe_rms_after")
        ratio = before / after if before and after else None
        out.append(
            _criterion(
                f"following error improvement ({traj.replace('_', ' ')})",
                "FAIL",
                ratio,
                f"≥ {acc.min_fe_improvement:g}×",
                None if ratio is None else ratio >= acc.min_fe_improvement,
                "×",
            )
        )
    rmse, floor = entry.get("rmse_after"), entry.get("noise_floor")
    ratio = rmse / floor if rmse is not None and floor else None
    out.append(
        _criterion(
            "model torque RMSE over the noise floor",
            "WARN",
            ratio,
            f"≤ {acc.max_rmse_over_noise:g}×",
            None if ratio is None else ratio <= acc.max_rmse_over_noise,
            "×",
        )
    )
    params, std = entry.get("params") or {}, entry.get("param_std") or {}
    for p in ("J", "c0", "c1"):
        rel = abs(std[p] / params[p]) if p in std and params.get(p) else None
        out.append(
            _criterion(
                f"relative std of {p}",
                "WARN",
                rel,
                f"≤ {acc.max_relative_std:.0%}",
                None if rel is None else rel <= acc.max_relative_std,
                "",
            )
        )
    if acc.require_consistent:
        c = entry.get("consistency")
        rate = ((c or {}).get("test") or {}).get("false_alarm_rate")
        out.append(
            _criterion(
                "identification consistent between parts of the data"
                + (f" (a test flagging {rate:.0%} of consistent axes)" if rate else ""),
                "WARN",
                None if c is None else c.get("consistent"),
                True,
                None if c is None or c.get("consistent") is None else bool(c["consistent"]),
            )
        )
    return out


def axis_verdict(criteria: list[dict]) -> str:
    """One axis's verdict from its criteria.

    Parameters
    ----------
    criteria : list of dict
        :func:`axis_criteria`'s answer.

    Returns
    -------
    {"PASS", "WARN", "FAIL", "INCOMPLETE"}
        FAIL where a FAIL criterion is unmet, else INCOMPLETE where one was not evaluated, else WARN
        where a WARN criterion is unmet, else PASS.
    """
    if any(c["met"] is False and c["severity"] == "FAIL" for c in criteria):
        return "FAIL"
    if any(c["met"] is None for c in criteria):
        return "INCOMPLETE"
    return "WARN" if any(c["met"] is False for c in criteria) else "PASS"


def verdict(axes: dict[str, dict], acc: Acceptance) -> dict:
    """``{"overall": …, "axes": {axis: {"verdict", "unmet", "not_evaluated", "criteria"}}, "acceptance"}``.

    Parameters
    ----------
    axes : dict of str to dict
        Per axis, its entry in summary.json.
    acc : Acceptance
        What the verdict checks.

    Returns
    -------
    dict
        As above.
    """
    out = {}
    for a, entry in axes.items():
        criteria = axis_criteria(entry, acc)
        out[a] = {
            "verdict": axis_verdict(criteria),
            "unmet": [describe(c) for c in criteria if c["met"] is False],
            "not_evaluated": [c["criterion"] for c in criteria if c["met"] is None],
            "criteria": criteria,
        }
    overall = max((v["verdict"] for v in out.values()), key=ORDER.index, default="INCOMPLETE")
    return {"overall": overall, "axes": out, "acceptance": vars(acc)}


def describe(c: dict) -> str:
    """An unmet criterion in words: name, value, limit.

    Parameters
    ----------
    c : dict
        The criterion.

    Returns
    -------
    str
        The words.
    """
    v = c["value"]
    if isinstance(v, bool):
        return f"{c['criterion']}: no"
    unit = c["unit"]
    if not isinstance(v, float):
        shown = str(v)
    elif c["criterion"].startswith("relative std"):  # a fraction, shown in per cent as its limit is
        shown = f"{v * 100:.3g} %"
    else:
        shown = f"{v:.3g}" + ("×" if unit == "×" else f" {unit}" if unit else "")
    return f"{c['criterion']} {shown} (needs {c['limit']}{f' {unit}' if unit not in ('', '×') else ''})"


def reasons(x: dict) -> str:
    """Why one axis has its verdict: the criteria it misses, else those not evaluated ("" for PASS).

    Parameters
    ----------
    x : dict
        The axis's verdict entry.

    Returns
    -------
    str
        The reasons.
    """
    return "; ".join(x["unmet"]) or (
        f"not evaluated: {', '.join(x['not_evaluated'])}" if x["not_evaluated"] else ""
    )


def headline(v: dict) -> str:
    """One line: the overall verdict and each axis's, with what it misses.

    Parameters
    ----------
    v : dict
        :func:`verdict`'s answer.

    Returns
    -------
    str
        The line.
    """
    return f"{v['overall']}: " + ", ".join(
        f"{a} {x['verdict']}" + (f" ({why})" if (why := reasons(x)) else "") for a, x in v["axes"].items()
    )
