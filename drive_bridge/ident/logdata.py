"""Reading a measured log for identification: columns, checks, usable segments.

A log is a CSV with ``time_s`` and, per axis, ``<axis>_position_rad`` with
``<axis>_torque_Nm`` (rotary, motor side) or ``<axis>_position_m`` with
``<axis>_force_N`` (linear).  Other columns are ignored (``<axis>_valid`` = 0
marks a missing sample, as ``record`` writes it).  A record output directory
stands for its ``log.csv``.  Everything wrong with the file is a
:class:`~drive_bridge.errors.UserError` that says what and where; rows that
cannot be used (NaN runs, time gaps) split the log into segments and are
reported in :attr:`AxisLog.dropped`.

Time is what the stamps say (in drive-bridge's own records, ``sync_time_s``: when each row's
SYNC went out, a late one's included).  A step longer than ``GAP_FACTOR`` sample periods
(the median step) is a gap; between gaps, stamps that are not evenly spaced
(jitter beyond ``JITTER_TOLERANCE``) are resampled onto a uniform grid of the
median period, position and torque through the same cubic spline, so that
every later step sees evenly spaced samples that are true to their instants.
:attr:`Log.sampling` says what the stamps held and what was done.
"""

from __future__ import annotations

import io
import mmap
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

import numpy as np
from scipy.interpolate import CubicSpline

from ..errors import UserError
from ..forking import fork_map, processes
from ..logs import LOG_NAME, META_NAME, TRACE_NAME

KINDS = {
    "rad": ("rotary", "torque_Nm", {"position": "rad", "torque": "Nm"}),
    "m": ("linear", "force_N", {"position": "m", "torque": "N"}),
}
MAX_POSITION = 1e7  # rad | m: beyond this a value is a corrupt row, not a position
MAX_TORQUE = 1e7  # Nm | N
MIN_SEGMENT = 64  # samples: shorter finite runs are dropped (the filters need room)
GAP_FACTOR = 5.0  # a time step longer than this many median periods is a gap
MAX_FILLED = 5  # samples: a shorter run of missing samples is filled, not a cut (the filters
# would cut far more at each edge than the run holds)
MIN_PARALLEL_BYTES = 8_000_000  # a CSV this large is parsed in parts, one process per core
JITTER_TOLERANCE = 1e-3  # steps within this fraction of the median period count as evenly spaced


@dataclass
class AxisLog:
    """One axis of a log on the log's time base.

    Parameters
    ----------
    name : str
        The axis.
    kind : {"rotary", "linear"}
        What its position is.
    units : dict of str to str
        The units of its position and torque, as the log's columns name them.
    q : numpy.ndarray
        Position [rad | m].
    tau : numpy.ndarray
        Torque [Nm | N].
    segments : list of (int, int)
        [start, stop) row ranges that are usable.
    dropped : list of str
        Samples the log could not give, and why.
    demand : numpy.ndarray, optional
        The position demand, where the log has it [rad | m].
    filled : numpy.ndarray, optional
        True where a short run of missing samples was filled.
    """

    name: str
    kind: str
    units: dict[str, str]
    q: np.ndarray
    tau: np.ndarray
    segments: list[tuple[int, int]]
    dropped: list[str] = field(default_factory=list)
    demand: np.ndarray | None = None
    filled: np.ndarray | None = None


@dataclass
class Log:
    """A log, read and checked (:func:`read_log`).

    Parameters
    ----------
    path : Path
        The CSV file.
    t : numpy.ndarray
        Time [s], evenly spaced within segments (see ``sampling``).
    dt : float
        The median sample period [s].
    axes : dict of str to AxisLog
        Its axes.
    sampling : dict
        What the time stamps held: period, jitter, gaps, and whether the log was resampled.
    speeds : dict
        Each axis's filtered speed over a segment, by (axis, start, stop, cut-off), for the part
        of the segment identification filters (a cache: :meth:`.signals.Parallel._active`).
    """

    path: Path
    t: np.ndarray
    dt: float
    axes: dict[str, AxisLog]
    sampling: dict = field(default_factory=dict)
    speeds: dict = field(default_factory=dict, repr=False)


def _csv_path(path: Path) -> Path:
    if path.is_dir():
        meta = path / META_NAME
        if meta.is_file() and "status: running" in meta.read_text(encoding="utf-8", errors="replace"):
            raise UserError(
                f"{path}: the recording never ended (meta.yaml status 'running': the process was "
                f"killed); rebuild what it recorded with: drive-bridge decode {path / TRACE_NAME}"
            )
        if not (path / LOG_NAME).exists():
            raise UserError(
                f"{path}: a directory, but it holds no {LOG_NAME} (give a record output "
                f"directory or a CSV file)"
            )
        return path / LOG_NAME
    if not path.exists():
        raise UserError(f"{path}: no such file")
    return path


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of the True runs of ``mask``."""
    edges = np.flatnonzero(np.diff(np.concatenate(([0], mask.view(np.int8), [0]))))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def _short_holes(finite: np.ndarray, gaps: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of the runs of missing samples no longer than ``MAX_FILLED``, with a finite
    sample on either side and no time gap at or around them."""
    gap_rows = set((np.asarray(gaps) + 1).tolist())
    return [
        (a, b)
        for a, b in _runs(~finite)
        if b - a <= MAX_FILLED and a > 0 and b < len(finite) and not gap_rows & set(range(a, b + 1))
    ]


def _describe(runs: list[tuple[int, int]], t: np.ndarray, limit: int = 3) -> str:
    parts = [f"rows {a + 2}-{b + 1} (t = {t[a]:.3f}-{t[b - 1]:.3f} s)" for a, b in runs[:limit]]
    return ", ".join(parts) + (f" and {len(runs) - limit} more" if len(runs) > limit else "")


def _rows(path: Path) -> np.ndarray:
    """The CSV's rows under its header as numbers: numpy's parser, over parts of a large file in
    processes of their own (:func:`.workers.fork_map`: the same numbers), each writing its rows
    into one table the processes share (nothing large is sent back, nothing held twice); where a
    part does not parse, the whole file again here, so that the error names its row."""
    size = path.stat().st_size
    count = processes() if size >= MIN_PARALLEL_BYTES else 1
    if count > 1:
        with open(path, "rb") as f:
            columns = f.readline().count(b",") + 1
            cuts = [f.tell()]
            for k in range(1, count):
                f.seek(max(cuts[-1], cuts[0] + k * (size - cuts[0]) // count))
                f.readline()  # the part ends where a line does
                cuts.append(f.tell())
            cuts.append(size)
            spans = [(a, b) for a, b in zip(cuts, cuts[1:]) if b > a]
            lines = [_lines(f, a, b) for a, b in spans]  # at most this many rows each (blank lines: fewer)
        firsts = np.cumsum([0] + lines).tolist()  # each part's first row in the table
        table = np.frombuffer(mmap.mmap(-1, max(1, firsts[-1] * columns * 8)), dtype=float)
        table = table[: firsts[-1] * columns].reshape(firsts[-1], columns)
        try:
            got = fork_map(
                _parse_part, [(a, b, first) for (a, b), first in zip(spans, firsts)], count, (path, table)
            )
        except Exception:  # noqa: BLE001 -- any part that fails: the whole file says why, below
            pass
        else:
            if got == lines:
                return table  # every part filled its rows up to the next one's
            return np.concatenate([table[first : first + n] for n, first in zip(got, firsts)])
    return _parse_rows(path, None)


def _lines(f: BinaryIO, start: int, end: int, chunk: int = 1 << 22) -> int:
    """The lines of ``f`` between the byte offsets (the last one counts without its newline)."""
    f.seek(start)
    lines, last = 0, b""
    for at in range(start, end, chunk):
        block = f.read(min(chunk, end - at))
        lines += block.count(b"\n")
        last = block[-1:]
    return lines + (last != b"\n")


def _parse_part(shared: tuple[Path, np.ndarray], span: tuple[int, int, int]) -> int:
    """Parse the rows between the byte offsets ``span[:2]`` into the shared table from its row
    ``span[2]`` on; how many there were."""
    path, table = shared
    rows = _parse_rows(path, span[:2])
    if rows.size and rows.shape[1] != table.shape[1]:
        raise ValueError(f"{rows.shape[1]} columns under a header of {table.shape[1]}")
    table[span[2] : span[2] + len(rows)] = rows
    return len(rows)


def _parse_rows(path: Path, span: tuple[int, int] | None) -> np.ndarray:
    """The rows of the CSV between the byte offsets ``span`` (None: every row under its header)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # numpy's "input contained no data": said by the caller
        if span is None:
            return np.loadtxt(path, delimiter=",", skiprows=1, dtype=float, ndmin=2)
        with open(path, "rb") as f:
            f.seek(span[0])
            text = f.read(span[1] - span[0])
        return np.loadtxt(io.BytesIO(text), delimiter=",", dtype=float, ndmin=2)


def read_log(path: str | Path) -> Log:
    """Read and check a log (the format: the module's docstring).

    Parameters
    ----------
    path : str or Path
        The CSV file, or a record directory holding ``log.csv``.

    Returns
    -------
    Log
        The log, its axes and what its time stamps held.

    Raises
    ------
    UserError
        A file that cannot be read as a log, named with what to do.
    """
    path = _csv_path(Path(path))
    try:
        with open(path, encoding="utf-8") as f:
            header = f.readline().strip().split(",")
        data = _rows(path)
    except (OSError, UnicodeDecodeError, ValueError, IndexError) as exc:
        raise UserError(f"{path}: not a readable CSV log ({exc})") from exc
    if "time_s" not in header:
        raise UserError(f"{path}: no time_s column (columns: {', '.join(header[:8])}...)")
    if data.shape[0] < 2 or data.shape[1] != len(header):
        raise UserError(
            f"{path}: {data.shape[0]} data rows of {data.shape[1]} columns under a header of "
            f"{len(header)}: not a log"
        )
    col = {name: data[:, i] for i, name in enumerate(header)}
    t = col["time_s"]
    if not np.all(np.isfinite(t)):
        bad = int(np.flatnonzero(~np.isfinite(t))[0])
        raise UserError(f"{path}: time_s is not a number at row {bad + 2}")
    if "sync_time_s" in col:
        # drive-bridge's own record: each row was sampled at its SYNC, and a late SYNC's row stands
        # for a later instant than its period's: the SYNC's stamp is the row's time where it has one
        stamped = np.where(np.isfinite(col["sync_time_s"]), col["sync_time_s"], t)
        if np.all(np.diff(stamped) > 0):
            t = stamped
    dt_all = np.diff(t)
    if np.any(dt_all <= 0):
        bad = int(np.flatnonzero(dt_all <= 0)[0])
        raise UserError(
            f"{path}: time_s does not increase at row {bad + 3} "
            f"(t = {t[bad]:.6f} then {t[bad + 1]:.6f}); sort the log or fix its time base"
        )
    dt = float(np.median(dt_all))
    for name in [n for n in header if n.endswith("_valid")]:  # a missing sample is missing data, in
        invalid = col[name] == 0  # every column of its axis (in place:
        if invalid.any():  # the table is this function's own)
            for other in header:
                if other.startswith(name[: -len("valid")]) and other != name:
                    col[other][invalid] = np.nan
    col, t, gaps, sampling = _uniform_time(col, t, dt)
    axes = {}
    for name in header:
        m = re.fullmatch(r"(.+)_position_(rad|m)", name)
        if not m:
            continue
        axis, unit = m.groups()
        kind, tau_suffix, units = KINDS[unit]
        tau_name = f"{axis}_{tau_suffix}"
        if tau_name not in col:
            raise UserError(f"{path}: axis {axis!r} has {name} but no {tau_name} column")
        q, tau = col[name].copy(), col[tau_name].copy()
        for what, values, limit in ((name, q, MAX_POSITION), (tau_name, tau, MAX_TORQUE)):
            wild = np.flatnonzero(np.abs(values) > limit)
            if len(wild):
                raise UserError(
                    f"{path}: {what} = {values[wild[0]]:.6g} at row {wild[0] + 2} is not a plausible "
                    f"value (|x| > {limit:g}); fix or cut the log"
                )
        dropped = []
        finite = np.isfinite(q) & np.isfinite(tau)
        short = _short_holes(finite, gaps)
        filled: np.ndarray | None = None
        if short:
            filled = np.zeros(len(q), dtype=bool)
            for a, b in short:
                filled[a:b] = True
            for values in (q, tau):
                values[filled] = CubicSpline(t[finite], values[finite])(t[filled])
            finite |= filled
            dropped.append(
                f"filled, not dropped: {int(filled.sum())} samples missing in {len(short)} run(s) of at "
                f"most {MAX_FILLED} (a late master's skipped periods, say), by a cubic spline through "
                f"their neighbours for the filters; the samples within one cut-off period of them are "
                f"not fitted: {_describe(short, t)}"
            )
        nan_runs = _runs(~finite)
        if nan_runs:
            dropped.append(
                f"{int((~finite).sum())} samples without a value in {len(nan_runs)} run(s): "
                f"{_describe(nan_runs, t)}"
            )
        usable = finite.copy()
        usable[gaps + 1] = False  # a segment never spans a time gap
        if len(gaps):
            dropped.append(
                f"time gaps split the log at {len(gaps)} place(s): {_describe([(g, g + 2) for g in gaps], t)}"
            )
        segments = []
        for a, b in _runs(usable):
            if b - a >= MIN_SEGMENT:
                segments.append((a, b))
            else:
                dropped.append(f"{b - a} samples at {_describe([(a, b)], t)}: too short a run to filter")
        if not segments:
            raise UserError(
                f"{path}: axis {axis!r}: no run of {MIN_SEGMENT} or more consecutive samples "
                f"with position and torque"
            )
        if not np.nanmax(tau) > np.nanmin(tau):
            raise UserError(
                f"{path}: axis {axis!r}: {tau_name} never changes ({np.nanmax(tau):g}): no torque was "
                f"logged; check the TPDO mapping of the torque object"
            )
        demand = col.get(f"{axis}_position_demand_{unit}")
        axes[axis] = AxisLog(
            axis,
            kind,
            units,
            q,
            tau,
            segments,
            dropped,
            None if demand is None or not np.isfinite(demand).any() else demand.copy(),
            filled,
        )
    if not axes:
        raise UserError(
            f"{path}: no axis found: expected <axis>_position_rad with <axis>_torque_Nm, or "
            f"<axis>_position_m with <axis>_force_N"
        )
    return Log(path, np.array(t), dt, axes, sampling)  # a copy: a column's view would keep the whole table


def _uniform_time(
    col: dict[str, np.ndarray], t: np.ndarray, dt: float
) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, dict]:
    """The columns on evenly spaced instants: as they are where the stamps are (within
    ``JITTER_TOLERANCE``), else resampled per gap-free span onto t0 + k·dt (cubic spline, every
    column alike; a sample next to a missing value stays missing).  Returns the columns, the
    time, the rows after which a gap lies, and the sampling report."""
    steps = np.diff(t)
    gap = steps > GAP_FACTOR * dt
    inner = steps[~gap]
    deviation = float(np.max(np.abs(inner - dt))) if len(inner) else 0.0
    sampling = {
        "period_s": dt,
        "jitter_std_s": float(np.std(inner)) if len(inner) else 0.0,
        "max_step_deviation_s": deviation,
        "gaps": int(gap.sum()),
        "resampled": False,
    }
    if deviation <= JITTER_TOLERANCE * dt:
        return col, t, np.flatnonzero(gap), sampling
    sampling["resampled"] = True
    cuts = (np.flatnonzero(gap) + 1).tolist()
    spans = list(zip([0] + cuts, cuts + [len(t)]))
    grids: list[np.ndarray] = []
    gap_rows: list[int] = []
    out: dict[str, list[np.ndarray]] = {name: [] for name in col}
    for a, b in spans:
        grid = t[a] + np.arange(int(np.floor((t[b - 1] - t[a]) / dt + 1e-9)) + 1) * dt
        if grids:
            gap_rows.append(sum(len(g) for g in grids) - 1)
        grids.append(grid)
        for name, values in col.items():
            out[name].append(_resample(t[a:b], values[a:b], grid))
    new_t = np.concatenate(grids)
    new = {name: np.concatenate(parts) for name, parts in out.items()}
    new["time_s"] = new_t
    return new, new_t, np.asarray(gap_rows, dtype=int), sampling


def _resample(t: np.ndarray, values: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """``values`` at ``t`` onto ``grid`` by a cubic spline through the finite samples; a grid
    instant between two samples of which one is missing is missing too."""
    finite = np.isfinite(values)
    if finite.sum() < 4:
        return np.interp(grid, t, np.where(finite, values, np.nan))
    out = CubicSpline(t[finite], values[finite])(grid)
    right = np.clip(np.searchsorted(t, grid, side="left"), 0, len(t) - 1)
    left = np.clip(right - 1, 0, len(t) - 1)
    out[~(finite[left] & finite[right])] = np.nan
    return out
