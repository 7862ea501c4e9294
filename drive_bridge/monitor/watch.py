"""The monitor: frames in, windows identified, records kept, drift named.

:class:`Monitor` takes frames (from a bus, :func:`listen`; or from a simulated production,
:mod:`.simulated`), keeps each axis's moving samples in the rolling log, and closes an axis's
window once it holds ``window_s`` of motion or spans ``max_span_s``: identified where the data
determine J, c0 and c1 (a history record of kind ``monitor``, set against the drive's last
commissioning and recent windows), said why not where they do not.  Everything it needs to
resume -- the rolling log, each window's start, the drift state -- lives in its directory.
"""

from __future__ import annotations

import fcntl
import json
import logging
import multiprocessing
import os
from collections.abc import Callable
from concurrent import futures
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import IO

from ..config import BusConfig
from ..errors import UserError
from ..history.record import identified, new_run_id, record
from ..interrupts import deferred
from ..outputs import write_text
from .drift import AxisDrift, Reference, judge
from .layout import Layout
from .listen import Chunk, Listener
from .rolling import RollingLog
from .window import PARAMETERS, Window, identify_window, standing, when

log = logging.getLogger(__name__)

WINDOW_S = 600.0  # a window closes with this much motion of its axis [s] ...
MAX_SPAN_S = 3600.0  # ... or once it spans this long [s], whatever it holds
STATE_NAME = "state.json"
LOCK_NAME = "lock"  # held by the monitor using the directory (its process id inside)
CLOSING = "closing"  # closed windows' logs until they are identified and kept


@dataclass
class Settings:
    """How the monitor windows and keeps: moving time per window [s], the longest span of one
    [s], the seed of the identification's evolutionary fits, the history database (None: the
    default; ``history`` False: nothing kept) and whether the machine is the simulated one.

    Parameters
    ----------
    window_s : float
        Moving time per window [s].
    max_span_s : float
        The longest span of one window [s].
    seed : int
        Seed of the identification's evolutionary fits.
    db : str, optional
        The history database (None: the default).
    history : bool
        Keep the windows in it.
    simulated : bool
        The machine is the simulated one.
    """

    window_s: float = WINDOW_S
    max_span_s: float = MAX_SPAN_S
    seed: int = 0
    db: str | None = None
    history: bool = True
    simulated: bool = False


@dataclass
class Drive:
    """What the monitor knows of an axis's drive without asking it: its node, and the identity
    its last commissioning under this bus configuration found (kept in the history), if any.

    Parameters
    ----------
    node_id : int
        Its node id.
    identity : dict of str to str, optional
        The identity its last commissioning found (hex).
    """

    node_id: int
    identity: dict[str, str] | None = None

    @property
    def serial(self) -> str | None:
        """Its serial number (hex), where its last commissioning found one."""
        return (self.identity or {}).get("serial")


@dataclass
class Job:
    """A closed window to identify: the axis, its first and last time stamp [s], its moving time
    [s], its log, the seed, and what keeping it needs (None: not kept).

    Parameters
    ----------
    axis : str
        The axis.
    first, last : float
        Its first and last time stamp [s since the epoch].
    moving_s : float
        Its moving time [s].
    log : Path
        Its log.
    seed : int
        The identification's seed.
    keeping : dict or None
        What keeping it needs (None: not kept).
    """

    axis: str
    first: float
    last: float
    moving_s: float
    log: Path
    seed: int
    keeping: dict | None

    def as_dict(self) -> dict:
        """The job as the monitor's state file holds it.

        Returns
        -------
        dict
            Every field, the log's path as text.
        """
        return {**asdict(self), "log": str(self.log)}

    @classmethod
    def from_dict(cls, d: dict) -> Job:
        """:meth:`as_dict` read back.

        Parameters
        ----------
        d : dict
            The dict.

        Returns
        -------
        Job
            The job.
        """
        return cls(**{**d, "log": Path(d["log"])})


def work(job: Job) -> tuple[Window, dict | None]:
    """Identify ``job``'s window and keep it where its values are determined (in a worker process
    while the monitor listens on; nothing here touches the monitor's state).

    Parameters
    ----------
    job : Job
        The window.

    Returns
    -------
    window : Window
        What it gave.
    kept : dict or None
        Where its record went (``run_id``, ``stored``, ``where`` in words); None where nothing is
        kept (no values, or no history).
    """
    if job.moving_s > 0 and job.log.is_file():
        try:
            window = identify_window(job.log, job.axis, job.first, job.last, job.moving_s, job.seed)
        except Exception as exc:  # a defect on one window's data must not stop weeks of listening
            why = f"not identified: a defect of drive-bridge ({type(exc).__name__}: {exc}); the log was {job.log.name}"
            window = Window(job.axis, job.first, job.last, job.moving_s, why=why)
    else:
        window = standing(job.axis, job.first, job.last, job.moving_s)
    if window.values is None or job.keeping is None:
        return window, None
    from ..history import keep

    k = job.keeping
    entry = {
        "axis": window.axis,
        "node_id": k["node_id"],
        "drive": k["drive"],
        "window": {"from": when(window.first), "to": when(window.last), "moving_s": window.moving_s},
        **identified(window.ident or {}),  # what an identification adds to a record, as identify's
    }
    doc = record(
        "monitor",
        new_run_id(),
        when(window.first),
        [entry],
        config=k["config"],
        out=k["out"],
        status="ok",
        verdict=None,
        simulated=k["simulated"],
    )
    result = keep(doc, k["db"])
    window.ident = None  # (not sent back: the record holds what is kept)
    return window, {"run_id": doc["run_id"], "stored": result.stored, "where": result.line()}


def _lock(directory: Path) -> IO[str]:
    """``directory`` (made where missing) locked for this monitor while the returned file is open:
    two monitors on one directory would each resume the other's windows."""
    directory.mkdir(parents=True, exist_ok=True)
    f = open(directory / LOCK_NAME, "a+", encoding="utf-8")  # noqa: SIM115 -- held open while it runs
    try:
        fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        f.seek(0)
        holder = f.read().strip() or "unknown"
        f.close()
        raise UserError(
            f"{directory}: another monitor uses this directory (process {holder}); stop it, or give "
            f"this one another --dir"
        ) from None
    f.seek(0)
    f.truncate()
    f.write(str(os.getpid()))
    f.flush()
    return f


class Monitor:
    """Listens to the axes of ``config``, keeps its state in ``directory``; ``emit`` gets each
    window and each drift as a JSON-ready dict (``event``: ``window`` or ``drift`` or ``back``).
    With ``background``, windows are identified in a worker process (a live bus: the listening
    never waits for an identification or the history database).

    Parameters
    ----------
    config : BusConfig
        The bus configuration (the axes' PDOs).
    directory : Path
        Where its state, rolling logs and events are kept.
    settings : Settings
        How it windows and keeps.
    emit : callable
        Gets each event as a JSON-ready dict.
    background : bool
        Identify windows in a worker process.
    """

    def __init__(
        self,
        config: BusConfig,
        directory: Path,
        settings: Settings,
        emit: Callable[[dict], None],
        background: bool = False,
    ):
        self.config = config
        self.directory = Path(directory)
        self.settings = settings
        self.emit = emit
        self.layout = Layout.of(config)
        self._lock = _lock(self.directory)
        self.logs = {a: RollingLog(self.directory / "rolling" / a, a) for a in self.layout.tpdos}
        self.drives = {a: Drive(n.node_id) for a, n in config.nodes.items()}
        state = self._load_state()
        self.drift = {a: AxisDrift.from_dict((state.get("drift") or {}).get(a) or {}) for a in self.logs}
        #: per axis, the time stamp its open window starts at (None until a SYNC is seen)
        self.opened: dict[str, float | None] = {a: (state.get("opened") or {}).get(a) for a in self.logs}
        #: windows closed since the start, per axis (the windows themselves are not kept: weeks of
        #: them would fill the memory; each went to ``emit`` and, where determined, to the history)
        self.closed: dict[str, int] = dict.fromkeys(self.logs, 0)
        self.listener = Listener(self.layout, self.add)
        self.background = background
        self._pool: ProcessPoolExecutor | None = None
        self._pending: list[tuple[Job, futures.Future]] = []
        self._look_up_drives()
        self._resume_closing()

    # --- state -----------------------------------------------------------------------------
    def _load_state(self) -> dict:
        path = self.directory / STATE_NAME
        if not path.is_file():
            return {}
        try:
            return dict(json.loads(path.read_text(encoding="utf-8")))
        except (OSError, ValueError, TypeError) as exc:
            log.warning("%s: unreadable (%s): starting afresh", path, exc)
            return {}

    def save(self) -> None:
        """Keep what a restart resumes from (written whole or not at all)."""
        state = {"opened": self.opened, "drift": {a: d.as_dict() for a, d in self.drift.items()}}
        write_text(self.directory / STATE_NAME, json.dumps(state, indent=1))

    def _look_up_drives(self) -> None:
        """The drives' identities and references from their last commissioning in the history."""
        if not self.settings.history:
            return
        from ..history.store import HistoryStore, HistoryUnavailable

        try:
            store = HistoryStore(self.settings.db)
        except HistoryUnavailable as exc:
            log.warning("history: %s; the first windows are the reference", exc)
            return
        try:
            for axis, drive in self.drives.items():
                found = store.last_commissioning(
                    axis, drive.node_id, self.config.path, self.settings.simulated
                )
                if found is None:
                    continue
                entry = found["axis"]
                drive.identity = entry.get("drive")
                params = entry.get("parameters") or {}
                if self.drift[axis].reference is None and all(
                    (params.get(n) or {}).get("determined") for n in PARAMETERS
                ):
                    self.drift[axis].reference = Reference(
                        {n: (params[n]["value"], params[n]["std"] or 0.0) for n in PARAMETERS},
                        f"commissioning {found['run_id'][:8]} of {found['started'].isoformat()[:16]}",
                    )
        except HistoryUnavailable as exc:
            log.warning("history: %s; the first windows are the reference", exc)
        finally:
            store.close()

    # --- frames and chunks -----------------------------------------------------------------
    def frame(self, can_id: int, data: bytes | bytearray, timestamp: float) -> None:
        """One frame seen on the bus at ``timestamp`` [s since the epoch].

        Parameters
        ----------
        can_id : int
            Its COB-ID.
        data : bytes or bytearray
            Its data.
        timestamp : float
            [s since the epoch].
        """
        self.listener.frame(can_id, data, timestamp)

    def tick(self, now_s: float) -> None:
        """Time passes (``now_s``, on the frames' clock): samples of a machine that stopped are
        handed on, and a window that spans its longest is closed.

        Parameters
        ----------
        now_s : float
            Now [s, on the frames' clock].
        """
        self.listener.idle(now_s)
        self.collect()
        for axis, opened in self.opened.items():
            if opened is not None and now_s - opened >= self.settings.max_span_s:
                self.close(axis, now_s)

    def add(self, chunk: Chunk) -> None:
        """An axis's samples of a stretch of SYNCs (the listener's chunks).

        Parameters
        ----------
        chunk : Chunk
            The samples.
        """
        axis = chunk.axis
        first = float(chunk.time[0])
        opened = self.opened[axis]
        if opened is not None and first - opened >= self.settings.max_span_s:
            self.close(axis, first)  # the machine stood (or the monitor was away) past the span
            opened = None
        if opened is None:
            self.opened[axis] = first
        self.logs[axis].add(chunk)
        if self.logs[axis].moving_s >= self.settings.window_s:
            self.close(axis, float(chunk.time[-1]))

    # --- windows -----------------------------------------------------------------------------
    def close(self, axis: str, until: float) -> None:
        """Close ``axis``'s open window at ``until`` [s]: its samples become one log in
        ``closing/``, identified and kept (:func:`work`) here or, with ``background``, in a worker
        process while the listening goes on (:meth:`collect` finishes it).

        Parameters
        ----------
        axis : str
            The axis.
        until : float
            [s since the epoch].
        """
        rolling = self.logs[axis]
        opened = self.opened[axis]
        first = opened if opened is not None else (rolling.first or until)
        closing = self.directory / CLOSING
        closing.mkdir(exist_ok=True)
        job = Job(
            axis,
            first,
            rolling.last or until,
            rolling.moving_s,
            closing / f"{axis}-{round(first * 1e6)}.csv",
            self.settings.seed,
            self._keeping(axis),
        )
        with deferred():  # the window's log and its job written, its chunks dropped, together
            if rolling.chunks and job.moving_s > 0:
                rolling.window(job.log)
            write_text(job.log.with_suffix(".json"), json.dumps(job.as_dict()))
            rolling.drop()
            self.opened[axis] = None
            self.save()
        self._submit(job)

    def _keeping(self, axis: str) -> dict | None:
        """What keeping a window of ``axis`` needs (None: nothing is kept)."""
        if not self.settings.history:
            return None
        drive = self.drives[axis]
        return {
            "node_id": drive.node_id,
            "drive": drive.identity,
            "config": str(self.config.path),
            "out": str(self.directory),
            "simulated": self.settings.simulated,
            "db": self.settings.db,
        }

    def _submit(self, job: Job) -> None:
        if not self.background:
            self._finish(job, *work(job))
            return
        if self._pool is None:
            # spawned, not forked: this process runs the listening thread
            self._pool = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"))
        self._pending.append((job, self._pool.submit(work, job)))

    def collect(self, wait: float = 0.0) -> None:
        """Finish the windows whose work is done (waiting up to ``wait`` [s] for the rest).

        Parameters
        ----------
        wait : float
            [s].
        """
        if wait and self._pending:
            futures.wait([f for _, f in self._pending], timeout=wait)
        for job, future in [(j, f) for j, f in self._pending if f.done()]:
            self._pending.remove((job, future))
            try:
                window, kept = future.result()
            except Exception as exc:  # a worker gone (killed, out of memory): the job waits on disk
                log.warning(
                    "axis %s: the window's identification failed (%s); retried at the next start",
                    job.axis,
                    exc,
                )
                continue
            self._finish(job, window, kept)

    def _finish(self, job: Job, window: Window, kept: dict | None) -> None:
        """The window identified (and kept): its drift judged, said, its files dropped."""
        drive = self.drives[job.axis]
        events = [] if window.values is None else judge(self.drift[job.axis], window, drive.serial)
        with deferred():
            job.log.unlink(missing_ok=True)
            job.log.with_suffix(".json").unlink(missing_ok=True)
            self.save()
        self.closed[job.axis] += 1
        self.emit({"event": "window", **window.as_dict(), "kept": kept})
        for e in events:
            self.emit(e)

    def _resume_closing(self) -> None:
        """Windows closed before a restart and not yet finished: identified again."""
        for path in sorted((self.directory / CLOSING).glob("*.json")):
            try:
                job = Job.from_dict(json.loads(path.read_text(encoding="utf-8")))
            except (OSError, ValueError, KeyError, TypeError) as exc:
                log.warning("%s: unreadable (%s): that window is lost", path, exc)
                path.unlink()
                continue
            if job.axis in self.logs:
                self._submit(job)

    def stop(self, wait: float = 60.0) -> None:
        """Hand the samples in memory to the rolling log, finish the windows being identified
        (waiting up to ``wait`` [s]; the others are identified at the next start) and keep the
        state (Ctrl-C, SIGTERM, the end).

        Parameters
        ----------
        wait : float
            [s].
        """
        self.listener.flush()
        self.collect(wait)
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None
        self.save()
        self.release()

    def release(self) -> None:
        """Let another monitor use the directory (as the end of this process does)."""
        self._lock.close()
