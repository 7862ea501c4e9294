"""The monitor: frames in, windows identified, records kept, drift named.

:class:`Monitor` takes frames (from a bus, :func:`listen`; or from a simulated production,
:mod:`.simulated`), keeps each axis's moving samples in the rolling log, and closes an axis's
window once it holds ``window_s`` of motion or spans ``max_span_s``: identified where the data
determine J, c0 and c1 (a history record of kind ``monitor``, set against the drive's last
commissioning and recent windows), said why not where they do not.  Everything it needs to
resume -- the rolling log, each window's start, the drift state -- lives in its directory.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..config import BusConfig
from ..history.record import new_run_id, record
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


@dataclass
class Settings:
    """How the monitor windows and keeps: moving time per window [s], the longest span of one
    [s], the seed of the identification's evolutionary fits, the history database (None: the
    default; ``history`` False: nothing kept) and whether the machine is the simulated one."""

    window_s: float = WINDOW_S
    max_span_s: float = MAX_SPAN_S
    seed: int = 0
    db: str | None = None
    history: bool = True
    simulated: bool = False


@dataclass
class Drive:
    """What the monitor knows of an axis's drive without asking it: the identity and parameters
    of its last commissioning under this bus configuration (kept in the history), if any."""

    node_id: int
    identity: dict[str, str] | None = None
    commissioned: str | None = None  # "commissioning <run id> of <time>"
    parameters: dict[str, dict[str, Any]] = field(default_factory=dict)

    @property
    def serial(self) -> str | None:
        return (self.identity or {}).get("serial")


class Monitor:
    """Listens to the axes of ``config``, keeps its state in ``directory``; ``emit`` gets each
    window and each drift as a JSON-ready dict (``event``: ``window`` or ``drift`` or ``back``)."""

    def __init__(self, config: BusConfig, directory: Path, settings: Settings, emit: Callable[[dict], None]):
        self.config = config
        self.directory = Path(directory)
        self.settings = settings
        self.emit = emit
        self.layout = Layout.of(config)
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
        self._look_up_drives()

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
                drive.commissioned = (
                    f"commissioning {found['run_id'][:8]} of {found['started'].isoformat()[:16]}"
                )
                drive.parameters = entry.get("parameters") or {}
                params = drive.parameters
                if self.drift[axis].reference is None and all(
                    (params.get(n) or {}).get("determined") for n in PARAMETERS
                ):
                    self.drift[axis].reference = Reference(
                        {n: (params[n]["value"], params[n]["std"] or 0.0) for n in PARAMETERS},
                        drive.commissioned,
                    )
        except HistoryUnavailable as exc:
            log.warning("history: %s; the first windows are the reference", exc)
        finally:
            store.close()

    # --- frames and chunks -----------------------------------------------------------------
    def frame(self, can_id: int, data: bytes | bytearray, timestamp: float) -> None:
        """One frame seen on the bus at ``timestamp`` [s since the epoch]."""
        self.listener.frame(can_id, data, timestamp)

    def tick(self, now_s: float) -> None:
        """Time passes (``now_s``, on the frames' clock): samples of a machine that stopped are
        handed on, and a window that spans its longest is closed."""
        self.listener.idle(now_s)
        for axis, opened in self.opened.items():
            if opened is not None and now_s - opened >= self.settings.max_span_s:
                self.close(axis, now_s)

    def add(self, chunk: Chunk) -> None:
        """An axis's samples of a stretch of SYNCs (the listener's chunks)."""
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
    def close(self, axis: str, until: float) -> Window:
        """Close ``axis``'s open window at ``until`` [s]: identify it, keep it, name any drift."""
        rolling = self.logs[axis]
        opened = self.opened[axis]
        first = opened if opened is not None else (rolling.first or until)
        moving = rolling.moving_s
        if rolling.chunks and moving > 0:
            path = self.directory / "window.csv"
            rolling.window(path)
            window = identify_window(path, axis, first, rolling.last or until, moving, self.settings.seed)
            path.unlink(missing_ok=True)
        else:
            window = standing(axis, first, until, moving)
        with deferred():  # the window is kept, its chunks dropped and the state saved together
            events = self._keep(window)
            rolling.drop()
            self.opened[axis] = None
            self.save()
        self.closed[axis] += 1
        self.emit({"event": "window", **window.as_dict(), "kept": events.pop(0)})
        for e in events:
            self.emit(e)
        return window

    def _keep(self, window: Window) -> list[Any]:
        """The window's record kept (where its values are determined) and the drift it shows:
        [where it was kept (or None), drift events...]."""
        if window.values is None:
            return [None]
        drive = self.drives[window.axis]
        events = judge(self.drift[window.axis], window, drive.serial)
        kept = None
        if self.settings.history:
            from ..history import keep

            entry = {
                "axis": window.axis,
                "node_id": drive.node_id,
                "drive": drive.identity,
                "window": {"from": when(window.first), "to": when(window.last), "moving_s": window.moving_s},
                "parameters": window.values,
                "effects": [e["name"] for e in (window.ident or {}).get("effects") or []],
                "undetermined": {},
                "rmse_before": (window.ident or {}).get("rmse_before"),
                "rmse_after": (window.ident or {}).get("rmse_after"),
            }
            doc = record(
                "monitor",
                new_run_id(),
                when(window.first),
                [entry],
                config=self.config.path,
                out=self.directory,
                status="ok",
                verdict=None,
                simulated=self.settings.simulated,
            )
            result = keep(doc, self.settings.db)
            kept = {"run_id": doc["run_id"], "stored": result.stored, "where": result.line()}
        return [kept, *events]

    def stop(self) -> None:
        """Hand the samples in memory to the rolling log and keep the state (Ctrl-C, SIGTERM, end)."""
        self.listener.flush()
        self.save()
