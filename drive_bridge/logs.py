"""Record output: ``log.csv`` (SI, one row per SYNC), ``meta.yaml`` and the raw CAN trace.

The CSV is made from a :class:`~drive_bridge.master.recording.Recording` in
device units through the axis scaling; :func:`decode_trace` refills the same
Recording from the trace and the PDO layout in meta.yaml, so decoding gives
the same CSV as the live run.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING

import can
import numpy as np
import yaml

from .cia.objects import (
    CURRENT_ACTUAL,
    FOLLOWING_ERROR_ACTUAL,
    INTERPOLATION_DATA_CONFIGURATION,
    MODES_OF_OPERATION_DISPLAY,
    POSITION_ACTUAL,
    STATUSWORD,
    SYNC_COUNTER_OVERFLOW,
    TORQUE_ACTUAL,
    VELOCITY_ACTUAL,
    torque_object,
)
from .cia.p301 import SYNC_COB_ID
from .cia.p402 import MODE_NAMES
from .cia.pdo import PdoCodec
from .errors import UserError
from .outputs import hex_object, write_table, write_text
from .units import Scaling
from .yamlconf import load_yaml

if TYPE_CHECKING:  # the master is not imported to read a log (identification does)
    from .master.bringup import AxisLink
    from .master.recording import Recording

LOG_NAME, META_NAME, TRACE_NAME = "log.csv", "meta.yaml", "trace.blf"

#: TPDO object -> (column suffix, converter name on Scaling or None for raw integers, format;
#: integers as %.0f so that a missing sample can be written as nan)
_COLUMNS: dict[int, tuple[str, str | None, str]] = {  # object: column suffix, Scaling method, format
    POSITION_ACTUAL: ("position_rad", "position_from_device", "%.9g"),
    VELOCITY_ACTUAL: ("velocity_rad_s", "velocity_from_device", "%.9g"),
    TORQUE_ACTUAL: ("torque_Nm", "torque_from_device", "%.6g"),
    STATUSWORD: ("statusword", None, "%.0f"),
    FOLLOWING_ERROR_ACTUAL: ("following_error_rad", "position_from_device", "%.9g"),
    CURRENT_ACTUAL: ("current_permille", None, "%.0f"),
    MODES_OF_OPERATION_DISPLAY: ("mode_display", None, "%.0f"),
    0x20C4: ("ip_buffer_status", None, "%.0f"),  # maxon's interpolation buffer status (0x20C4:1)
    INTERPOLATION_DATA_CONFIGURATION: ("ip_buffer_fill", None, "%.0f"),  # records in the FIFO (0x60C4:2)
}


def since_start(sync_time: np.ndarray, period: float) -> np.ndarray:
    """Each row's SYNC stamp [s] from the plan's first period on the SYNCs' own schedule: the first
    row that had a SYNC, less its rows × ``period`` (a wall-clock master late at the plan's start
    skipped its first periods: before, every row of such a log read NaN), rounded to the µs.

    Parameters
    ----------
    sync_time : numpy.ndarray
        Per row, its SYNC's stamp [s] (NaN: no SYNC in that period).
    period : float
        The SYNC period [s].

    Returns
    -------
    numpy.ndarray
        [s], NaN where there was no SYNC.
    """
    seen = np.flatnonzero(np.isfinite(sync_time))
    origin = float(sync_time[seen[0]]) - seen[0] * period if len(seen) else 0.0
    return np.round(sync_time - origin, 6)


def _codec_meta(codecs: list[PdoCodec]) -> list[dict]:
    return [c.as_dict() for c in codecs]


def _codecs(entries: list[dict]) -> list[PdoCodec]:
    return [PdoCodec.from_dict(e) for e in entries]


def to_table(
    rec: Recording, scaling: dict[str, Scaling], period: float
) -> tuple[list[str], np.ndarray, list[str]]:
    """Columns, values and formats of log.csv; missing samples are NaN with ``<axis>_valid`` = 0.

    Parameters
    ----------
    rec : Recording
        The recording.
    scaling : dict of str to Scaling
        Per axis, its units.
    period : float
        The SYNC period [s].

    Returns
    -------
    names : list of str
        The columns.
    values : numpy.ndarray
        Rows × columns, SI.
    fmts : list of str
        A %-format per column.
    """
    n = len(rec.raw)
    # each column made when it is written into the table (a list of them all, stacked, held the
    # campaign's table twice: 70 MB more at the main job's peak)
    spec: list[tuple[str, str, Callable[[], np.ndarray]]] = [
        ("time_s", "%.6f", lambda: np.arange(n) * period),
        ("sync_time_s", "%.6f", lambda: since_start(rec.sync_time, period)),
    ]
    for ai, axis in enumerate(rec.axes):
        sc = scaling[axis]
        valid = rec.valid(axis)
        indices = [i for a, i in rec.columns if a == axis]
        order = list(_COLUMNS)
        torque = torque_object(sc.torque_feedback, sc.torque_index)
        for index in sorted(indices, key=lambda i: order.index(TORQUE_ACTUAL if i == torque else i)):
            suffix, conv, fmt = (
                ("torque_Nm", "torque_from_feedback", "%.6g") if index == torque else _COLUMNS[index]
            )  # the axis's torque: from what the drive reports
            spec.append(
                (
                    f"{axis}_{suffix}",
                    fmt,
                    partial(
                        _logged,
                        rec.raw[:, rec.column(axis, index)],
                        getattr(sc, conv) if conv else None,
                        valid,
                    ),
                )
            )
            if index == POSITION_ACTUAL:  # (NaN in a period without a SYNC: no setpoint was taken)
                spec.append(
                    (
                        f"{axis}_position_demand_rad",
                        "%.9g",
                        partial(_demanded, sc, rec.demand[:, ai], rec.sync_time),
                    )
                )
        spec.append((f"{axis}_valid", "%.0f", partial(valid.astype, float)))
    values = np.empty((n, len(spec)))
    for j, (_, _, make) in enumerate(spec if n else []):
        values[:, j] = make()
    return [name for name, _, _ in spec], values, [fmt for _, fmt, _ in spec]


def _demanded(sc: Scaling, demand: np.ndarray, sync_time: np.ndarray) -> np.ndarray:
    """The position demand [SI] of each row, NaN where the row's period had no SYNC."""
    return np.where(np.isfinite(sync_time), sc.position_from_device(demand), np.nan)


def _logged(
    raw: np.ndarray, convert: Callable[[np.ndarray], np.ndarray] | None, valid: np.ndarray
) -> np.ndarray:
    """A logged object's column in SI (``convert``: from device units), NaN where the sample is missing."""
    return np.where(valid, convert(raw) if convert else raw.astype(float), np.nan)


def write_csv(path: Path, rec: Recording, scaling: dict[str, Scaling], period: float) -> None:
    """log.csv of a recording (:func:`to_table`, :func:`~drive_bridge.outputs.write_table`).

    Parameters
    ----------
    path : Path
        The file.
    rec : Recording
        The recording.
    scaling : dict of str to Scaling
        Per axis, its units.
    period : float
        The SYNC period [s].
    """
    write_table(path, *to_table(rec, scaling, period))


def write_meta(path: Path, meta: dict) -> None:
    """meta.yaml, complete or not at all.

    Parameters
    ----------
    path : Path
        The file.
    meta : dict
        Its content.
    """
    write_text(path, meta_text(meta))


def meta_text(meta: dict) -> str:
    """meta.yaml's content (YAML, in the dict's order).

    Parameters
    ----------
    meta : dict
        The content.

    Returns
    -------
    str
        The YAML text.
    """
    return yaml.safe_dump(meta, sort_keys=False)


def layout_meta(axes: dict[str, AxisLink]) -> dict:
    """Per axis: scaling, the operating mode streamed in and the PDO layout (what decode needs to
    rebuild the log).

    Parameters
    ----------
    axes : dict of str to AxisLink
        The brought-up axes.

    Returns
    -------
    dict
        Per axis: node id, identity, scaling, mode, setpoint object and its PDOs.
    """
    out = {}
    for name, ax in axes.items():
        sc = ax.cfg.scaling
        out[name] = {
            "node_id": ax.cfg.node_id,
            "identity": ax.identity,
            "scaling": {
                "increments_per_rev": sc.increments_per_rev,
                "rated_torque_Nm": sc.rated_torque_Nm,
                "torque_feedback": sc.torque_feedback,
                "current_per_unit_A": sc.current_per_unit_A,
                "torque_constant_Nm_per_A": sc.torque_constant_Nm_per_A,
                "torque_index": sc.torque_index,
                "torque_per_unit_Nm": sc.torque_per_unit_Nm,
                "feed_m_per_rev": sc.feed_m_per_rev,
                "velocity_unit": sc.velocity_unit,
                "velocity_units_per_rad_s": sc.velocity_units_per_rad_s,
            },
            "units": ax.units,
            "drive_limits": ax.drive_limits,
            "operating_mode": {
                "mode": ax.mode,
                "name": MODE_NAMES.get(ax.mode, str(ax.mode)),
                "setpoint_object": f"0x{ax.setpoint[0]:04X}:{ax.setpoint[1]}",
            },
            "rpdo": _codec_meta(ax.rpdos),
            "tpdo": _codec_meta(ax.tpdos),
        }
    return out


def _replay(trace: Path, rec: Recording, rpdo_ids: set[int], overflow: int) -> str | None:
    """The frames of one trace into ``rec``: its SYNCs from the first RPDO on, each with its count
    (a gap: SYNCs lost); what is wrong with the trace, or None."""
    handlers = rec.handlers()
    frames, last, started, count = 0, None, False, 0
    try:
        with can.LogReader(str(trace)) as reader:
            for msg in reader:
                started = started or msg.arbitration_id in rpdo_ids
                if msg.arbitration_id == SYNC_COB_ID:
                    if started:
                        lost = (msg.data[0] - count - 1) % overflow if overflow and count and msg.data else 0
                        count = msg.data[0] if overflow and msg.data else 0
                        rec.on_sync(msg.timestamp, lost)
                else:
                    handler = handlers.get(msg.arbitration_id)
                    if handler is not None:
                        handler(msg.arbitration_id, msg.data, msg.timestamp)
                frames, last = frames + 1, msg.timestamp
    except Exception as exc:  # python-can's readers raise many kinds on a damaged file
        where = f"after {frames} frames" + (f" (t = {last:.6f} s)" if last is not None else "")
        return f"the trace {trace.name} is damaged {where}: {type(exc).__name__}: {exc}"
    return None


def decode_trace(
    trace: Path, meta_path: Path | None = None
) -> tuple[list[str], np.ndarray, list[str], dict, str | None]:
    """Rebuild the log table from a raw trace and the meta.yaml beside it.

    A damaged or cut-short trace gives the rows before the damage and, last, what is wrong
    with it (None for a whole trace).

    Parameters
    ----------
    trace : Path
        The trace (BLF, ASC, ...: what python-can reads).
    meta_path : Path, optional
        Its meta.yaml; default the one beside it.

    Returns
    -------
    names : list of str
        The columns.
    values : numpy.ndarray
        The rows.
    fmts : list of str
        A %-format per column.
    meta : dict
        meta.yaml.
    problem : str or None
        What is wrong with the trace.

    Raises
    ------
    UserError
        No trace, no meta.yaml, or a meta.yaml drive-bridge did not write.
    """
    from .master.recording import Recording

    trace = Path(trace)
    meta_path = Path(meta_path) if meta_path else trace.with_name(META_NAME)
    if not trace.is_file():
        raise UserError(f"{trace}: trace file not found")
    if not meta_path.is_file():
        raise UserError(
            f"{meta_path}: not found; decode needs the meta.yaml written with the trace (give it with --meta)"
        )
    meta = load_yaml(meta_path)
    try:
        axes = meta["axes"]
        period = float(meta["sync_period_s"])
        counts = meta["counts"]
        sent = int(counts.get("cycles_sent", counts["cycles_planned"]))
        if not 0 <= sent <= 10**8 or not period > 0:
            raise ValueError("counts or sync_period_s out of range")
        tpdos = {a: _codecs(v["tpdo"]) for a, v in axes.items()}
        rpdos = {a: _codecs(v["rpdo"]) for a, v in axes.items()}
        for codec in [c for cs in (*tpdos.values(), *rpdos.values()) for c in cs]:
            if (
                codec.struct.size > 8
                or len(codec.spans) != len(codec.entries)
                or not 0 < codec.cob_id < 0x800
            ):
                raise ValueError(f"PDO 0x{codec.cob_id:X}: its format does not fit its objects")
        scaling = {a: Scaling(**v["scaling"]) for a, v in axes.items()}
        unknown = [
            i
            for a, cs in tpdos.items()
            for c in cs
            for i in c.objects
            if i not in _COLUMNS and i != torque_object(scaling[a].torque_feedback, scaling[a].torque_index)
        ]
        if unknown:
            raise ValueError(f"TPDO object 0x{unknown[0]:04X} is not one the log has a column for")
        rec = Recording(tpdos, rpdos, sent)
        rec.skip_syncs = int(counts.get("sync_before_plan", 0))
        # periods a late master sent no SYNC in (the rows after them are those of their own time)
        rec.skipped = {
            int(r) for r in ((meta.get("timing") or {}).get("engine") or {}).get("rows_skipped") or []
        }
        for sc in scaling.values():
            if not (sc.increments_per_rev > 0 and sc.rated_torque_Nm > 0):
                raise ValueError("scaling must be positive")
    except (
        KeyError,
        TypeError,
        ValueError,
        AttributeError,
        struct.error,
        UnicodeDecodeError,
        yaml.YAMLError,
    ) as exc:
        raise UserError(f"{meta_path}: not a drive-bridge record meta.yaml (missing or bad {exc})") from exc
    # the run's SYNCs (the master's, or a drive's) are those after the first RPDO: the cyclic engine
    # sends one before it takes the first SYNC it counts (a producing drive's earlier ones are not)
    rpdo_ids = {c.cob_id for cs in rpdos.values() for c in cs}
    # each SYNC's count (0x1019 on every node): a gap is SYNCs lost, their periods rows without one
    overflows = {
        int((v.get("drive_limits") or {}).get(hex_object(SYNC_COUNTER_OVERFLOW, 0), 0)) for v in axes.values()
    }
    overflow = overflows.pop() if len(overflows) == 1 else 0
    problem = _replay(trace, rec, rpdo_ids, overflow)
    rec.truncate()  # (the plan's last periods without a SYNC are rows: meta.yaml names them)
    try:
        repeats = [
            (
                trace.with_name(Path(str(r["trace"])).name),
                int(r["from_row"]),
                int(r["approach_rows"]),
                int(r["cycles_sent"]),
                int(r["sync_before_plan"]),
                {int(k) for k in r.get("rows_skipped") or []},
            )
            for r in meta.get("repeats") or []
        ]
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise UserError(f"{meta_path}: not a drive-bridge record meta.yaml (bad repeats: {exc})") from exc
    for path, from_row, approach, cycles, before, skipped in repeats:  # segments streamed again
        if problem is not None:
            break
        again = Recording(tpdos, rpdos, cycles)
        again.skip_syncs, again.skipped = before, skipped
        problem = _replay(path, again, rpdo_ids, overflow) if path.is_file() else f"{path}: not found"
        again.truncate()
        rec.resume(from_row, again, approach)
    if problem is None and rec.rows < sent and meta.get("status") != "running":
        problem = f"the trace holds {rec.rows} of the {sent} SYNC cycles meta.yaml counts: it was cut short"
    if problem is None and meta.get("status") == "running":
        problem = (
            f"the recording never ended (meta.yaml status 'running': the process was killed); "
            f"{rec.rows} SYNC cycles decoded"
        )
    names, values, fmts = to_table(rec, scaling, period)
    return names, values, fmts, meta, problem
