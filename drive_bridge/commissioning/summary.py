"""``summary.json``: what a pipeline reads after ``commission``, built from the run directory.

Top level: ``status`` (``ok``: every step completed; ``failed``: ``failed`` names the step
and reason; ``partial``: a subset ran and succeeded; ``degraded``: every step completed but a
wall-clock run missed its timing limits, named in ``timing_degraded``), ``steps`` with durations [s],
``versions``.  Per axis: the identified parameters and effects (the fields of
``identify --json``; its ``validation`` is ``identify_validation`` here), the paper's
values beside them, gains before/after with their margins, validation following error
RMS and max [rad], overshoot [%], settling [s] and model torque RMSE [Nm] (at the torque's lag
[cycles], and between the demand's acceleration steps) before/after per trajectory, and every
object written with ``verified``.
"""

from __future__ import annotations

import json
import platform
from importlib import metadata
from pathlib import Path

from ..config import BusConfig
from ..errors import UserError
from ..logs import META_NAME
from ..outputs import stamped
from ..paper import TABLE_II
from ..params.profile import DEFAULT_PROFILE
from ..session import Options
from ..version import __version__
from ..yamlconf import load_yaml
from . import steps as step_functions
from .verdict import verdict

PACKAGES = ("python-can", "canopen", "numpy", "scipy", "control", "matplotlib", "numba", "PyYAML")
IDENTIFY_FIELDS = (
    "units",
    "params",
    "param_std",
    "effects",
    "rmse_before",
    "rmse_after",
    "torque_rms",
    "noise_floor",
    "relative_error_before",
    "relative_error_after",
    "unexplained",
    "ga",
    "consistency",
)


def versions() -> dict[str, str]:
    """The versions summary.json records: drive-bridge's, Python's and its libraries'.

    Returns
    -------
    dict of str to str
        Name -> version (``not installed`` where a package is missing).
    """
    out = {"drive-bridge": __version__, "python": platform.python_version()}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def _load(out: Path, name: str) -> dict | None:
    try:
        return json.loads((out / name).read_text())
    except (OSError, ValueError):
        return None


def _paper(axis: str, params: dict) -> dict | None:
    if axis not in TABLE_II:
        return None
    return {
        k: {
            "paper": v,
            "identified": params.get(k),
            "deviation_pct": None if params.get(k) is None else (params[k] - v) / v * 100,
        }
        for k, v in TABLE_II[axis].items()
    }


def _validation(runs: list[dict], axis: str) -> dict:
    by = {(r["scenario"], r["trajectory"]): r for r in runs if axis in r["axes"]}
    out = {}
    for traj in ("point_to_point", "path"):
        b, a = by.get(("before", traj)), by.get(("after", traj))
        if a is None:
            continue
        ma, mb = a["axes"][axis], b and b["axes"][axis]
        out[traj] = {
            "fe_rms_before": mb and mb["fe_rms"],
            "fe_rms_after": ma["fe_rms"],
            "improvement": (mb["fe_rms"] / ma["fe_rms"]) if mb and ma["fe_rms"] else None,
            "fe_max_before": mb and mb["fe_max"],
            "fe_max_after": ma["fe_max"],
            "overshoot_pct_before": mb and mb["overshoot_pct"],
            "overshoot_pct_after": ma["overshoot_pct"],
            "settling_s_before": mb and mb["settling_s"],
            "settling_s_after": ma["settling_s"],
            "torque_rmse_before": mb and mb["torque_rmse"],
            "torque_rmse_after": ma["torque_rmse"],
            "torque_rmse_between_steps_before": mb and mb.get("torque_rmse_between_steps"),
            "torque_rmse_between_steps_after": ma.get("torque_rmse_between_steps"),
            "torque_lag_cycles_before": mb and mb.get("torque_lag_cycles"),
            "torque_lag_cycles_after": ma.get("torque_lag_cycles"),
            "aborted": a["aborted"] or (b and b["aborted"]),
            "feedforward": a.get("feedforward", {}).get(axis),
        }
    return out


def _written(w: dict) -> list[dict]:
    return [
        {
            "parameter": o["parameter"],
            "object": o["object"],
            "unit": o["unit"],
            "old": o["old_si"],
            "new": o["new_si"],
            "old_device": o["old_device"],
            "new_device": o["new_device"],
            "verified": o["verified"],
        }
        for o in w["objects"]
    ]


def _meta(out: Path) -> dict:
    """The campaign's meta.yaml (the mode each axis streamed in), or nothing."""
    path = out / step_functions.OUTPUT["campaign"] / META_NAME
    try:
        return load_yaml(path) if path.is_file() else {}
    except UserError:
        return {}


def history_record(out: Path, state: dict, summary: dict, config: BusConfig, simulated: bool) -> dict:
    """The history's record of the commissioning in ``out`` (whatever steps ran), from its summary,
    its scan (the drives' identities) and its identification (what the data left undetermined).

    Parameters
    ----------
    out : Path
        The run directory.
    state : dict
        The run's state (its id, when it started, what failed).
    summary : dict
        summary.json.
    config : BusConfig
        The bus configuration.
    simulated : bool
        A run on the simulated drives.

    Returns
    -------
    dict
        The record (schema ``record``).
    """
    from ..history.record import following_error, identified, identity, record

    found = (_load(out, step_functions.OUTPUT["scan"]) or {}).get("found", {})
    ident = (_load(out, step_functions.IDENTIFY_JSON) or {}).get("axes", {})
    verdicts = summary["verdict"]["axes"]
    axes = []
    for a, s in summary["axes"].items():
        entry: dict = {
            "axis": a,
            "node_id": (found.get(a) or {}).get("node_id"),
            "drive": identity(found.get(a)),
            "verdict": verdicts.get(a, {}).get("verdict"),
        }
        if a in ident:
            entry.update(identified(ident[a]))
        if "gains_after" in s:
            entry.update(
                {
                    "gains_before": s["gains_before"],
                    "gains_after": s["gains_after"],
                    "margins_before": s["margins_before"],
                    "margins_after": s["margins"],
                }
            )
        if s.get("validation"):
            entry["following_error"] = following_error(s["validation"])
        if "written" in s:
            entry.update({"written": s["written"], "stored": s["stored"], "unsupported": s["unsupported"]})
        axes.append(entry)
    return record(
        "commission",
        state["run_id"],
        state["started"],
        axes,
        config=config.path,
        out=out,
        status=summary["status"],
        verdict=summary["verdict"]["overall"],
        simulated=simulated,
        failed=summary.get("failed"),
    )


def build_summary(out: Path, state: dict, config: BusConfig, options: Options) -> dict:
    """summary.json of the commissioning in ``out``, whatever steps ran.

    Parameters
    ----------
    out : Path
        The run directory.
    state : dict
        The run's state (steps completed, their durations, what failed).
    config : BusConfig
        The bus configuration.
    options : Options
        How it ran.

    Returns
    -------
    dict
        Steps, per axis what each step found, the verdict, versions (schema ``summary``).
    """
    failed = state.get("failed")
    completed = state["completed"]
    steps = [
        {
            "name": s,
            "status": "failed"
            if failed and failed["step"] == s
            else ("done" if s in completed else "not run"),
            "duration_s": state["durations_s"].get(s),
        }
        for s in step_functions.STEP_FUNCTIONS
    ]
    status = (
        "failed"
        if failed
        else ("ok" if all(s in completed for s in step_functions.STEP_FUNCTIONS) else "partial")
    )
    timing = [d for reasons in (state.get("timing_degraded") or {}).values() for d in reasons]
    if status == "ok" and timing:
        status = "degraded"
    ident = (_load(out, step_functions.IDENTIFY_JSON) or {}).get("axes", {})
    tune = (_load(out, step_functions.OUTPUT["tune"]) or {}).get("axes", {})
    write = (_load(out, step_functions.WRITE_JSON) or {}).get("axes", {})
    runs = (_load(out, step_functions.VALIDATE_JSON) or {}).get("runs", [])
    meta = _meta(out)
    axes = {}
    for a in config.nodes:
        entry: dict = {}
        if a in meta.get("axes", {}):
            entry["operating_mode"] = meta["axes"][a].get("operating_mode")
        if a in ident:
            entry.update({k: ident[a].get(k) for k in IDENTIFY_FIELDS})
            entry["identify_validation"] = ident[a].get("validation")
            entry["paper"] = _paper(a, ident[a]["params"])
        if a in tune:
            t = tune[a]
            entry.update(
                {
                    "gains_before": t["gains_before"],
                    "gains_after": t["gains"],
                    "margins": t["margins"],
                    "margins_before": t["margins_before"],
                    "parameters_written": t["parameters"],
                }
            )
        if runs:
            entry["validation"] = _validation(runs, a)
        if a in write:
            entry["written"] = _written(write[a])
            entry["unsupported"] = write[a]["unsupported"]
            entry["stored"] = write[a]["stored"]
        axes[a] = entry
    return stamped(
        "summary",
        {
            "verdict": verdict(axes, config.acceptance),
            "status": status,
            "failed": failed,
            "timing_degraded": timing,
            "steps": steps,
            "duration_s": sum(s["duration_s"] or 0.0 for s in steps),
            "versions": versions(),
            "config": str(config.path),
            "simulated": options.sim,
            "profile": options.profile or config.profile or DEFAULT_PROFILE,
            "out": str(out),
            "axes": axes,
        },
    )
