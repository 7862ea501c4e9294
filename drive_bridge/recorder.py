"""``record``: bring up the drives, run the excitation campaign, write log.csv, meta.yaml, trace."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .config import BusConfig
from .errors import MotionAborted, RanDry
from .interrupts import deferred
from .logs import LOG_NAME, META_NAME, TRACE_NAME, layout_meta, meta_text, write_csv, write_meta
from .master.bringup import AxisLink, bring_up
from .master.buffered import MAX_REPEATS
from .master.busload import BusLoad, check_bus_load
from .master.campaign import Plan, build_plan, resume_plan
from .master.engine import Supervision
from .master.homing import home
from .master.link import Link, TraceRecorder
from .master.stream import stream
from .master.supervision import supervision_for
from .master.timing import Timing, measure
from .outputs import stamped, write_text
from .params.profile import setpoint_timeout_for
from .version import __version__

ENABLING = -999_999_999  # meta.yaml's sync_before_plan while the drives are being enabled

log = logging.getLogger(__name__)


@dataclass
class RecordResult:
    """A campaign recorded (:func:`record`).

    Parameters
    ----------
    out_dir : Path
        Where log.csv, meta.yaml and trace.blf are.
    plan : Plan
        The campaign streamed.
    cycles_sent : int
        The plan's rows sent.
    samples : dict of str to int
        Per axis, the rows with a complete sample.
    missing : dict of str to int
        Per axis, the rows without.
    aborted : MotionAborted or None
        What stopped the motion, where something did.
    bus_load : str
        The bus load, in words.
    wall_time_s : float
        How long it took [s].
    timing : Timing
        The run's timing.
    holding : dict of str to str, optional
        Per axis, how it is held after the motion.
    repeats : list of dict
        The segments streamed again after a FIFO ran dry: which, from which row, why, the
        approach's rows and the repeat's own trace (meta.yaml's ``repeats``).
    """

    out_dir: Path
    plan: Plan
    cycles_sent: int
    samples: dict[str, int]
    missing: dict[str, int]
    aborted: MotionAborted | None
    bus_load: str
    wall_time_s: float
    timing: Timing
    holding: dict[str, str] | None = None
    repeats: list[dict] = field(default_factory=list)

    def repeated(self) -> str:
        """The segments streamed again, in words ("": none).

        Returns
        -------
        str
            One clause per repeat.
        """
        return "; ".join(
            f"segment {r['segment']} ({self.plan.segments[r['segment']].kind}) streamed again from row "
            f"{r['from_row']}: axis {r['ran_dry']['axis']}'s FIFO ran dry at row {r['ran_dry']['row']}"
            for r in self.repeats
        )

    @property
    def ok(self) -> bool:
        """The motion ran to its end."""
        return self.aborted is None

    def as_dict(self) -> dict:
        """The result as ``record --json`` prints it.

        Returns
        -------
        dict
            Files, per axis samples and missing, times, bus load, timing, what stopped it, how the
            axes are held (schema ``record``).
        """
        return stamped(
            "record",
            {
                "out": str(self.out_dir),
                "files": ["log.csv", "meta.yaml", "trace.blf", *(r["trace"] for r in self.repeats)],
                "axes": {a: {"samples": self.samples[a], "missing": self.missing[a]} for a in self.plan.axes},
                "motion_s": self.plan.duration,
                "cycles_sent": self.cycles_sent,
                "bus_load": self.bus_load,
                "wall_time_s": self.wall_time_s,
                "timing": self.timing.as_dict(),
                "aborted": None if self.aborted is None else str(self.aborted),
                "holding": self.holding,
                "repeats": self.repeats,
            },
        )


def stream_supervision(config: BusConfig, axes: dict[str, AxisLink]) -> Supervision:
    """The limits a stream of ``axes`` is judged by: what bring-up wrote into the drives, the drive
    profile's setpoint-loss timeout for their EDS/DCF, bus.yml's master section.

    Parameters
    ----------
    config : BusConfig
        The bus configuration.
    axes : dict of str to AxisLink
        The brought-up axes.

    Returns
    -------
    Supervision
        The limits (feedback and setpoint timeouts, heartbeat timeout) and their sources.
    """
    m, period = config.master, config.master.sync_period_s
    timeout, source = setpoint_timeout_for([ax.cfg.dcf for ax in axes.values()], period)
    return supervision_for(
        axes,
        period,
        heartbeat_timeout=m.heartbeat_timeout_s,
        state_timeout=m.state_timeout_s,
        setpoint_timeout=timeout,
        setpoint_source=source,
        miss_limit=m.tpdo_miss_limit,
    )


def record(
    config: BusConfig,
    link: Link,
    out_dir: str | Path,
    *,
    on_plan: Callable[[Plan], Callable[[int], None] | None] | None = None,
    axes: dict[str, AxisLink] | None = None,
) -> RecordResult:
    """Run the campaign of ``config`` over ``link``; files go to ``out_dir``.

    ``on_plan`` receives the checked plan before anything moves and may return a
    progress callback; ``axes`` are drives already brought up (default: bring them
    up here).  Data recorded before a fault is always written.

    Parameters
    ----------
    config : BusConfig
        The bus configuration (the campaign).
    link : Link
        The link to the drives.
    out_dir : str or Path
        Where the files go.
    on_plan : callable, optional
        Given the plan, may return a progress callback.
    axes : dict of str to AxisLink, optional
        The brought-up axes.

    Returns
    -------
    RecordResult
        What was recorded, and what stopped the motion if anything did.

    Raises
    ------
    UserError
        A stream the bus cannot carry (its load at the bitrate), before anything moves.
    """
    t_start = time.perf_counter()
    load = check_bus_load(config)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    traces = [TraceRecorder(out / TRACE_NAME, background=link.threaded, epoch=link.epoch)]
    link.add_trace(traces[0])  # from here: bring-up (when done here), streaming and stop

    def next_trace(name: str) -> None:  # a repeated segment's stream goes into a trace of its own
        link.remove_trace(traces[-1])
        traces[-1].stop()
        traces.append(TraceRecorder(out / name, background=link.threaded, epoch=link.epoch))
        link.add_trace(traces[-1])

    try:
        return _record(config, link, out, load, t_start, on_plan, axes, next_trace)
    finally:
        link.remove_trace(traces[-1])
        traces[-1].stop()


def _record(
    config: BusConfig,
    link: Link,
    out: Path,
    load: BusLoad,
    t_start: float,
    on_plan: Callable[[Plan], Callable[[int], None] | None] | None,
    axes: dict[str, AxisLink] | None,
    next_trace: Callable[[str], None],
) -> RecordResult:
    axes = axes or bring_up(link, config)
    home(link, axes, config)  # reference: home -- before the plan starts where it left them
    start = {name: ax.position_rad() for name, ax in axes.items()}
    plan = build_plan(
        config.campaign, {n: a.cfg.limits for n, a in axes.items()}, start, config.master.sync_period_s
    )
    progress = on_plan(plan) if on_plan else None
    meta: dict[str, Any] = {
        "drive_bridge_version": __version__,
        "config_file": str(config.path.resolve()),
        "sync_period_s": plan.period,
        "bus_load": load.describe(),
        "campaign": {k: (list(v) if isinstance(v, tuple) else v) for k, v in vars(config.campaign).items()},
        "axes": layout_meta({a: axes[a] for a in plan.axes}),
        "segments": [s.as_dict(plan.period) for s in plan.segments],
        "counts": {"cycles_planned": len(plan.demand)},
        "status": "running",  # until the run ends: a killed run's trace still decodes with this
        "trace": TRACE_NAME,
    }
    write_meta(out / META_NAME, meta)
    log.info(
        "campaign planned: %s, %d segments, %.1f s of motion",
        ", ".join(plan.axes),
        len(plan.segments),
        plan.duration,
    )

    # decode skips the SYNCs that enabled the drives: meta.yaml says how many as soon as streaming
    # starts. The drives then follow and watch for setpoints (10 periods: 20 ms) -- no time for YAML
    # (26 ms for a quick campaign's meta): it is dumped now, the count put in when it is known
    meta["counts"]["sync_before_plan"] = ENABLING
    starting = meta_text(meta)

    def started(enable_cycles: int) -> None:
        meta["counts"]["sync_before_plan"] = enable_cycles
        write_text(
            out / META_NAME,
            starting.replace(f"sync_before_plan: {ENABLING}\n", f"sync_before_plan: {enable_cycles}\n", 1),
        )

    supervision = stream_supervision(config, {a: axes[a] for a in plan.axes})
    result = stream(
        link,
        axes,
        plan,
        supervision=supervision,
        progress=progress,
        timing_limits=config.master.timing,
        sync_producer=config.master.sync_producer,
        on_start=started,
    )
    rec, timing, sent, first = result.recording, result.timing, result.cycles_sent, result.sync_before_plan
    repeats: list[dict] = []
    failure: BaseException | None = None  # what ended the repeats early: raised once the data is written
    try:
        # a FIFO run dry (the master away longer than the records ahead cover): the drives made a
        # planned stop and hold; the segment it happened in is marked and streamed again from its start
        while isinstance(result.aborted, RanDry) and len(repeats) < MAX_REPEATS:
            row = result.aborted.row  # as a row of the plan (a repeat's rows follow its approach)
            if repeats:
                row = repeats[-1]["from_row"] + max(0, row - repeats[-1]["approach_rows"])
            segment = next(s for s in plan.segments if s.end > row)
            here = {a: axes[a].position_rad() for a in plan.axes}
            resumed, approach, begin = resume_plan(plan, segment, here)
            name = f"trace-repeat{len(repeats) + 1}.blf"
            log.warning(
                "%s; segment %d (%s, rows %d-%d) is streamed again from row %d after an approach of %d rows",
                result.aborted,
                plan.segments.index(segment),
                segment.kind,
                segment.start,
                segment.end,
                begin,
                approach,
            )
            dry = {"axis": result.aborted.axis, "row": row, "reason": result.aborted.reason}
            next_trace(name)
            result = stream(
                link,
                axes,
                resumed,
                supervision=supervision,
                progress=None if progress is None else _shifted(progress, begin, approach),
                timing_limits=config.master.timing,
                sync_producer=config.master.sync_producer,
            )
            repeats.append(
                {
                    "segment": plan.segments.index(segment),
                    "ran_dry": dry,
                    "from_row": begin,
                    "approach_rows": approach,
                    "trace": name,
                    "sync_before_plan": result.sync_before_plan,
                    "cycles_sent": result.cycles_sent,
                    "rows_skipped": sorted(result.recording.skipped),
                }
            )
            rec.resume(begin, result.recording, approach)
            sent = len(rec.raw)
    except BaseException as exc:  # noqa: BLE001 - the rows so far are written before it goes on up
        failure = exc
    missing = rec.missing()
    if repeats:  # the timing of the rows kept; rows_skipped: the first stream's (each repeat has its own)
        engine = timing.engine
        timing = measure(
            rec.sync_time,
            plan.period,
            missing,
            wall=link.threaded,
            priority=timing.priority,
            limits=config.master.timing,
            joins=tuple(r["from_row"] for r in repeats),
        )
        timing.engine = engine
    samples = {a: int(len(rec.raw) - missing[a]) for a in plan.axes}
    meta["counts"].update(
        {
            "cycles_sent": sent,
            "samples_received": samples,
            "samples_missing": missing,
            "sync_before_plan": first,
        }
    )
    meta["holding"] = result.holding
    meta["status"] = "ok" if result.aborted is None else "aborted"
    meta["timing"] = timing.as_dict()
    if repeats:
        meta["repeats"] = repeats
    if result.aborted is not None:
        meta["abort"] = {"axis": result.aborted.axis, "reason": result.aborted.reason}
    if failure is not None:
        meta["status"] = "aborted"
        meta["abort"] = {"axis": None, "reason": f"repeating a segment: {type(failure).__name__}: {failure}"}
    with deferred():  # the data so far is written whole before a signal ends the command
        write_csv(out / LOG_NAME, rec, {n: axes[n].cfg.scaling for n in plan.axes}, plan.period)
        write_meta(out / META_NAME, meta)
    if failure is not None:
        raise failure
    return RecordResult(
        out,
        plan,
        sent,
        samples,
        missing,
        result.aborted,
        load.describe(),
        time.perf_counter() - t_start,
        timing,
        result.holding,
        repeats,
    )


def _shifted(progress: Callable[[int], None], start: int, approach: int) -> Callable[[int], None]:
    """A repeat's progress as rows of the plan: its approach holds at the segment's start."""
    return lambda rows: progress(start + max(0, rows - approach))
