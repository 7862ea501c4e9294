"""The record of one run as the history keeps it: a JSON document built from what the run left
(a write's outcome, an identification's results; a commissioning's from its run directory,
:func:`drive_bridge.commissioning.summary.history_record`), with the run id that makes keeping it
idempotent.

Parameters are SI, motor side, each with its std and whether the data determined it; drive
identities are 0x1018's fields as hex strings.  Nothing in a record comes from the database URL: a record never
holds a password.
"""

from __future__ import annotations

import hashlib
import uuid
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from ..outputs import hex32
from ..version import __version__

SCHEMA = "drive-bridge/history-record"
SCHEMA_VERSION = 1
IDENTITY = ("vendor_id", "product_code", "revision", "serial")


#: what a record keeps: a commissioning, a write, an identification of a log, a monitored window
KINDS = ("commission", "write", "identify", "monitor")


def new_run_id() -> str:
    """A new run's id.

    Returns
    -------
    str
        32 hex digits (a random UUID).
    """
    return uuid.uuid4().hex


def now() -> str:
    """The time of day as records keep it: UTC, ISO 8601, to the millisecond (two runs a second
    apart, or less, keep their order).

    Returns
    -------
    str
        Now.
    """
    return datetime.now(timezone.utc).isoformat(timespec="milliseconds")


def file_sha256(path: str | Path) -> str | None:
    """A file's SHA-256.

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    str or None
        Its digest in hex; None where it cannot be read.
    """
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError:
        return None


def identity(found: dict | None) -> dict[str, str] | None:
    """0x1018's fields of a scan result's entry (hex strings) or a bring-up's (numbers), as records
    keep them: hex strings ("0x000003EA"), as every output of drive-bridge writes identities.

    Parameters
    ----------
    found : dict or None
        The identity as the scan or bring-up read it.

    Returns
    -------
    dict of str to str or None
        Each 0x1018 field it has, in hex; None without one.
    """
    if not found:
        return None
    return {
        k: hex32(int(found[k], 16) if isinstance(found[k], str) else int(found[k]))
        for k in IDENTITY
        if k in found
    }


def identity_number(value: str | None) -> int | None:
    """An identity field of a record as a number (the database's columns).

    Parameters
    ----------
    value : str or None
        The field, in hex.

    Returns
    -------
    int or None
        Its number; None where it has none.
    """
    return None if value is None else int(value, 16)


def _parameters(ident: dict) -> dict[str, dict[str, Any]]:
    """An identify.json axis's parameters: value, std, unit, determined."""
    from ..ident.presentation import unit

    kind = "rotary" if (ident.get("units") or {}).get("position", "rad") == "rad" else "linear"
    std = ident.get("param_std") or {}
    undetermined = ident.get("undetermined") or {}
    return {
        name: {
            "value": value,
            "std": std.get(name),
            "unit": unit(name, kind),
            "determined": name not in undetermined and std.get(name) is not None,
        }
        for name, value in (ident.get("params") or {}).items()
        if value is not None
    }


def identified(ident: dict) -> dict[str, Any]:
    """What an axis of identify.json adds to the record.

    Parameters
    ----------
    ident : dict
        The axis in identify.json.

    Returns
    -------
    dict
        Its parameters (with std and whether determined), effects, what is undetermined,
        consistency, the errors before and after and the noise floor.
    """
    return {
        "parameters": _parameters(ident),
        "effects": [e["name"] for e in ident.get("effects") or []],
        "undetermined": ident.get("undetermined") or {},
        "consistent": (ident.get("consistency") or {}).get("consistent"),
        "rmse_before": ident.get("rmse_before"),
        "rmse_after": ident.get("rmse_after"),
        "noise_floor": ident.get("noise_floor"),
    }


def following_error(validation: dict) -> dict[str, dict[str, Any]]:
    """The following error before and after, per reference trajectory, as the record keeps it.

    Parameters
    ----------
    validation : dict
        An axis's validation in the summary, per trajectory.

    Returns
    -------
    dict of str to dict
        Per trajectory, ``fe_rms_before``, ``fe_rms_after``, ``fe_max_before``, ``fe_max_after``
        [rad].
    """
    return {
        traj: {k: v.get(k) for k in ("fe_rms_before", "fe_rms_after", "fe_max_before", "fe_max_after")}
        for traj, v in validation.items()
    }


def record(
    kind: str,
    run_id: str,
    started: str,
    axes: list[dict],
    *,
    config: str | Path | None,
    out: str | Path | None,
    status: str | None,
    verdict: str | None,
    simulated: bool,
    failed: dict | None = None,
) -> dict:
    """A record document; ``updated`` is now (a later record of the same run replaces an earlier one).

    Parameters
    ----------
    kind : {"commission", "write", "identify", "monitor"}
        What ran.
    run_id : str
        The run.
    started : str
        When it started (:func:`now`'s form).
    axes : list of dict
        Per axis, its drive identity and what the run found or wrote.
    config : str or Path, optional
        The bus configuration (its path and SHA-256 are kept).
    out : str or Path, optional
        The run directory.
    status : str, optional
        How it ended.
    verdict : str, optional
        Its verdict (PASS, WARN, FAIL, INCOMPLETE).
    simulated : bool
        A run on the simulated drives.
    failed : dict, optional
        The step that failed, and why.

    Returns
    -------
    dict
        The record (schema ``record``, version :data:`SCHEMA_VERSION`).
    """
    return {
        "schema": SCHEMA,
        "schema_version": SCHEMA_VERSION,
        "run_id": run_id,
        "kind": kind,
        "started": started,
        "updated": now(),
        "version": __version__,
        "config": None
        if config is None
        else {"path": str(Path(config).resolve()), "sha256": file_sha256(config)},
        "out": None if out is None else str(Path(out).resolve()),
        "status": status,
        "verdict": verdict,
        "simulated": simulated,
        "failed": failed,
        "axes": axes,
    }


def write_record(
    run_id: str,
    started: str,
    outcome: dict,
    identities: dict[str, dict],
    config_path: Path,
    simulated: bool,
    out: str | Path | None,
) -> dict:
    """The record of a ``write``: what was written and read back, and stored, per drive.

    Parameters
    ----------
    run_id : str
        The run.
    started : str
        When it started.
    outcome : dict
        The write result's JSON document (:meth:`.write.WriteOutcome.as_dict`).
    identities : dict of str to dict
        Per axis, its drive's identity.
    config_path : Path
        The bus configuration.
    simulated : bool
        A run on the simulated drives.
    out : str or Path, optional
        Where its output is.

    Returns
    -------
    dict
        The record.
    """
    axes = []
    for a, w in outcome["axes"].items():
        axes.append(
            {
                "axis": a,
                "node_id": w["node_id"],
                "drive": identity(identities.get(a)),
                "written": [
                    {
                        "parameter": o["parameter"],
                        "object": o["object"],
                        "unit": o["unit"],
                        "old": o["old_si"],
                        "new": o["new_si"],
                        "verified": o["verified"],
                    }
                    for o in w["objects"]
                ],
                "stored": w["stored"],
                "unsupported": w["unsupported"],
                "dry_run": w["dry_run"],
                "margins_after": outcome.get("margins", {}).get(a),
            }
        )
    return record(
        "write",
        run_id,
        started,
        axes,
        config=config_path,
        out=out,
        status="ok" if outcome["ok"] else "failed",
        verdict=None,
        simulated=simulated,
    )


def identify_record(run_id: str, started: str, doc: dict, source: str | Path, out: str | Path | None) -> dict:
    """The record of an ``identify`` of a log; no drive identity.

    Parameters
    ----------
    run_id : str
        The run.
    started : str
        When it started.
    doc : dict
        Its identify.json.
    source : str or Path
        The log identified.
    out : str or Path, optional
        Where its output is.

    Returns
    -------
    dict
        The record.
    """
    axes = [
        {"axis": a, "node_id": None, "drive": None, "source": str(Path(source).resolve()), **identified(r)}
        for a, r in doc["axes"].items()
    ]
    return record(
        "identify", run_id, started, axes, config=None, out=out, status="ok", verdict=None, simulated=False
    )


def numeric(value: Any) -> bool:
    """Whether a parameter value is one the history compares.

    Parameters
    ----------
    value : object
        The value.

    Returns
    -------
    bool
        A number (not a name an effect holds, nor a bool).
    """
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def problems(record: Any) -> list[str]:
    """What in ``record`` does not follow the record's schema (:data:`SCHEMA`, version
    :data:`SCHEMA_VERSION`), in words naming the key; empty where it does.  A parameter's value
    may be a number or what an effect names (a string, a list): only numbers are compared.

    Parameters
    ----------
    record : object
        The record.

    Returns
    -------
    list of str
        What does not follow, each naming the key.
    """
    if not isinstance(record, dict):
        return ["the record is not a JSON object"]
    out = []
    if record.get("schema") != SCHEMA or record.get("schema_version") != SCHEMA_VERSION:
        out.append(f"schema: {record.get('schema')!r} version {record.get('schema_version')!r}")
    run_id = record.get("run_id")
    if not isinstance(run_id, str) or not 0 < len(run_id) <= 32:
        out.append(f"run_id: {run_id!r} (a text of 1 to 32 characters)")
    if record.get("kind") not in KINDS:
        out.append(f"kind: {record.get('kind')!r}")
    for key in ("started", "updated"):
        try:
            datetime.fromisoformat(record[key])
        except (KeyError, TypeError, ValueError):
            out.append(f"{key}: {record.get(key)!r} (an ISO 8601 time)")
    if not isinstance(record.get("version"), str):
        out.append(f"version: {record.get('version')!r}")
    if not isinstance(record.get("simulated"), bool):
        out.append(f"simulated: {record.get('simulated')!r} (true or false)")
    axes = record.get("axes")
    if not isinstance(axes, list):
        return [*out, "axes: not a list"]
    for i, axis in enumerate(axes):
        name = axis.get("axis") if isinstance(axis, dict) else None
        if not isinstance(name, str) or not name:
            out.append(f"axes[{i}]: no axis name")
            continue
        drive = axis.get("drive") or {}
        for key in IDENTITY:
            try:
                identity_number(drive.get(key))
            except (TypeError, ValueError, AttributeError):
                out.append(f"axis {name}: drive {key} {drive.get(key)!r} (hex)")
        for pname, p in (axis.get("parameters") or {}).items():
            if not isinstance(p, dict) or "value" not in p:
                out.append(f"axis {name}: parameter {pname}: no value")
                continue
            if p.get("std") is not None and not numeric(p["std"]):
                out.append(f"axis {name}: parameter {pname}: std {p['std']!r} is not a number")
            if numeric(p["value"]) and not isinstance(p.get("determined"), bool):
                out.append(f"axis {name}: parameter {pname}: determined {p.get('determined')!r}")
    return out
