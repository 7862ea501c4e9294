"""Running the commissioning steps in order: resume, subsets, failures, summary and report.

The run directory holds ``state.json`` (steps completed, their durations, the failure if
any). A rerun with the same directory resumes after the last completed step unless
``restart``; ``steps`` runs a subset. Whatever happens, ``summary.json`` and ``report.html``
are written from what is on disk, and the result carries the exit code: 0 only when every
step succeeded, 2 a user mistake, 3 a bus or drive problem, 4 motion stopped (fault or
Ctrl-C, axes quick-stopped), 130 interrupted outside motion, 1 an internal error (its
traceback in ``error.log``).
"""

from __future__ import annotations

import json
import logging
import shutil
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..config import BusConfig
from ..errors import EXIT_CODES, DriveBridgeError, MotionAborted, UserError, exit_code
from ..master.link import Link
from ..outputs import write_json
from ..progress import StepReporter
from ..session import Options, Session
from . import steps as step_functions
from .report import FIGURES, REPORT, REPORT_MD, write_report
from .summary import build_summary, history_record
from .verdict import headline

log = logging.getLogger(__name__)

STEPS = tuple(step_functions.STEP_FUNCTIONS)
UNCOMMITTED = ("scan", "bringup")  # steps after which nothing moved, was identified or written
STATE = "state.json"
SUMMARY = "summary.json"
ERROR_LOG = "error.log"
WHAT = {
    "scan": "find the configured drives on the bus",
    "bringup": "configure the drives, read their parameters as they are",
    "campaign": "excitation campaign, every axis (the robot moves)",
    "identify": "J, c0, c1 and residual tracing",
    "measure": "each axis's frequency response through its drive: a slow sweep with a torque-offset "
    "multisine, soft gains (the robot moves)",
    "tune": "gains from the identified models, margins",
    "write": "transactional write: backup, write, verify, store",
    "validate": "reference trajectories, before vs after (the robot moves)",
}


@dataclass
class CommissionResult:
    """How a commissioning ended (:func:`commission`).

    Parameters
    ----------
    status : {"ok", "failed", "partial"}
        "partial": a subset of the steps ran, and ended well.
    exit_code : int
        The command's exit code (:data:`drive_bridge.errors.EXIT_TABLE`).
    failed_step : str or None
        The step that failed; None where none did.
    reason : str or None
        Why it failed, in words.
    ran : list of str
        The steps this run was to run, in order (a resumed run: those that were left).
    out : Path
        The run directory (summary.json, report.html, each step's files).
    summary : dict
        summary.json as written.
    """

    status: str
    exit_code: int
    failed_step: str | None
    reason: str | None
    ran: list[str]
    out: Path
    summary: dict = field(repr=False)

    @property
    def ok(self) -> bool:
        """Whether every step asked for ran to its end (``status == "ok"``)."""
        return self.status == "ok"


def _state(out: Path, config: BusConfig, restart: bool) -> dict:
    from ..history.record import new_run_id, now

    path = out / STATE
    fresh: dict[str, Any] = {
        "config": str(config.path.resolve()),
        "completed": [],
        "durations_s": {},
        "failed": None,
        "run_id": new_run_id(),
        "started": now(),
    }
    if restart or not path.exists():
        return fresh
    try:
        state = json.loads(path.read_text())
        state["completed"], state["durations_s"]
    except (ValueError, KeyError, TypeError) as exc:
        raise UserError(f"{path}: unreadable; use --restart to start over") from exc
    if state.get("config") != fresh["config"]:
        raise UserError(
            f"{out} holds a run with {state.get('config')}, not {fresh['config']}; "
            f"use --restart to start over there, or another --out"
        )
    state.setdefault("run_id", fresh["run_id"])  # a run directory of a drive-bridge before the history
    state.setdefault("started", fresh["started"])
    return state


def _clear(out: Path) -> None:
    """Remove a previous run's outputs (only the names this tool writes)."""
    loops = [p.name for p in out.glob(step_functions.LOOPS.format(axis="*"))]
    for name in [
        *step_functions.OUTPUT.values(),
        STATE,
        SUMMARY,
        REPORT,
        REPORT_MD,
        FIGURES,
        ERROR_LOG,
        *loops,
    ]:
        p = out / name
        if p.is_dir():
            shutil.rmtree(p)
        elif p.exists():
            p.unlink()


def commission(
    config: BusConfig,
    out: str | Path,
    options: Options | None = None,
    *,
    steps: list[str] | None = None,
    restart: bool = False,
    reporter: StepReporter | None = None,
    link: Link | None = None,
) -> CommissionResult:
    """Run the commissioning steps of ``config`` with every output in ``out``.

    scan → bring-up → campaign → identify → measure → tune → write → validate, each step's
    output kept in ``out`` (resumable), ending in ``summary.json`` and ``report.html``.

    Parameters
    ----------
    config : BusConfig
        The bus configuration (:func:`drive_bridge.load_bus_config`).
    out : str or Path
        The run directory (made where missing).
    options : Options, optional
        How to reach the drives and what to run with (default :class:`Options`: the configured
        bus, the project's drive profile).
    steps : list of str, optional
        Run only these (names from :data:`STEPS`), in pipeline order; default: resume after
        the last completed step recorded in ``out``.
    restart : bool
        Start again from the first step, whatever ``out`` holds.
    reporter : StepReporter, optional
        Told as each step starts and ends (the command's progress lines).
    link : Link, optional
        An open link to use; default: open the configured bus, or the simulated robot with
        ``options.sim``.

    Returns
    -------
    CommissionResult
        How it ended (``status``, ``exit_code``), the failed step and why, the verdict.

    Raises
    ------
    UserError
        An unknown step name. A problem on the bus or in the data never raises: the result
        says which step failed and why.
    """
    options = options or Options()
    out = Path(out)
    unknown = [s for s in steps or [] if s not in STEPS]
    if unknown:
        raise UserError(f"--steps: unknown step {', '.join(unknown)} (steps: {', '.join(STEPS)})")
    if restart:
        _clear(out)
    out.mkdir(parents=True, exist_ok=True)
    state = _state(out, config, restart)
    if steps is not None:
        todo = [s for s in STEPS if s in steps]
    else:
        done = [STEPS.index(s) for s in state["completed"] if s in STEPS]
        todo = list(STEPS[max(done) + 1 :]) if done else list(STEPS)
    reporter = reporter or StepReporter(list(STEPS))
    if not todo:
        reporter.note(f"every step is already completed in {out}; --restart to commission again")
    state["failed"] = None
    code = 0
    failure: dict[str, str] | None = None  # the step that stopped the run, and why
    with Session(config, options, link) as session:
        ctx = step_functions.Context(session, out, reporter)
        for step in todo:
            reporter.start(step, WHAT[step])
            log.info("step %s: %s", step, WHAT[step])
            ctx.degraded = []
            # a step that runs again is not completed until it ends well, nor is any step after it:
            # their inputs are about to change
            state["completed"] = [s for s in state["completed"] if STEPS.index(s) < STEPS.index(step)]
            _save(out, state)
            t0 = time.perf_counter()
            try:
                line = step_functions.STEP_FUNCTIONS[step](ctx)
            except (Exception, KeyboardInterrupt) as exc:  # every failure ends the run with a report
                code, reason = _failure(exc, out)
                failure = {"step": step, "reason": reason}
                state["failed"] = failure
                state["durations_s"][step] = time.perf_counter() - t0
                log.warning("step %s failed after %.1f s: %s", step, state["durations_s"][step], reason)
                reporter.failed(step, state["durations_s"][step], reason)
                _save(out, state)
                break
            state["durations_s"][step] = time.perf_counter() - t0
            state["completed"] = [s for s in STEPS if s in state["completed"] or s == step]
            state.setdefault("timing_degraded", {})[step] = (
                ctx.degraded
            )  # this run of the step replaces the last
            _save(out, state)
            log.info("step %s done in %.1f s: %s", step, state["durations_s"][step], line)
            reporter.done(step, state["durations_s"][step], line)
        holding = session.holding()
    summary = build_summary(out, state, config, options)
    # a run that stopped before anything moved, was identified or was written is no commissioning
    stopped_early = (
        failure is not None
        and failure["step"] in UNCOMMITTED
        and all(s in UNCOMMITTED for s in state["completed"])
    )
    if failure is not None and stopped_early:
        reporter.note(f"verdict: INCOMPLETE: stopped in {failure['step']}: {failure['reason']}")
    else:
        reporter.note(f"verdict: {headline(summary['verdict'])}")
    if failure is None and summary["verdict"]["overall"] == "FAIL":
        code = EXIT_CODES["not_accepted"]
        reporter.note(f"the commissioning completed but did not pass its acceptance criteria (exit {code})")
    elif failure is None and summary["status"] == "degraded":
        code = EXIT_CODES["degraded"]
        reporter.note(
            f"WARNING: timing degraded ({'; '.join(summary['timing_degraded'])}); the data are kept "
            f"(exit {code})"
        )
    if options.history and stopped_early:
        reporter.note("history: nothing kept (the run reached no drive's motion, model or parameters)")
    elif options.history:
        summary["history"] = _keep(out, state, summary, config, options, reporter)
        if summary["history"]["interrupted"] and code == 0:
            code = EXIT_CODES["interrupted"]
    write_json(out / SUMMARY, summary)
    write_report(out, summary, options.figures)
    if failure is not None:
        reporter.note(
            f"stopped in step {failure['step']}. Everything recorded so far is in {out}; "
            f"{resume_hint(state, steps is not None)} (--restart to start over)."
        )
    reporter.note(f"summary: {out / SUMMARY}; report: {out / REPORT} (and {REPORT_MD})")
    for axis, how in holding.items():  # last: what the person beside the machine must know
        reporter.note(f"axis {axis}: {how}")
    return CommissionResult(
        summary["status"],
        code,
        None if failure is None else failure["step"],
        None if failure is None else failure["reason"],
        todo,
        out,
        summary,
    )


def _keep(
    out: Path, state: dict, summary: dict, config: BusConfig, options: Options, reporter: StepReporter
) -> dict:
    """Keep the run in the history (one record per run directory: a resumed run replaces it) and
    compare its drives with their past and their siblings: ``summary.json``'s ``history``."""
    from ..history import keep
    from ..history.since import since_last_time

    record = history_record(out, state, summary, config, options.sim)
    kept = keep(record, options.db)
    reporter.note(kept.line())
    history = since_last_time(record, kept, options.db)
    for entry in history["axes"].values():
        for words in entry["named"]:
            reporter.note(f"since last time: {words}")
    return history


def resume_hint(state: dict, subset: bool) -> str:
    """What a rerun does: a plain rerun resumes after the last completed step.

    Parameters
    ----------
    state : dict
        The run directory's state (its ``completed`` steps).
    subset : bool
        The run was asked for some of the steps (``--steps``).

    Returns
    -------
    str
        The command to give, in words, and the step it resumes at.
    """
    done = [STEPS.index(s) for s in state["completed"] if s in STEPS]
    at = STEPS[max(done) + 1] if done and max(done) + 1 < len(STEPS) else (None if done else STEPS[0])
    again = "run the same command again without --steps" if subset else "run the same command again"
    return f"{again} to resume at step {at}" if at else f"{again}: every step is completed"


def _failure(exc: BaseException, out: Path) -> tuple[int, str]:
    if isinstance(exc, MotionAborted):
        return exc.exit_code, f"motion stopped: {exc}; every axis was quick-stopped"
    if isinstance(exc, DriveBridgeError):
        return exc.exit_code, str(exc)
    if isinstance(exc, KeyboardInterrupt):
        return exit_code(exc), "interrupted by the user (Ctrl-C)"
    (out / ERROR_LOG).write_text("".join(traceback.format_exception(exc)))
    return exit_code(exc), f"internal error {type(exc).__name__}: {exc} (traceback in {out / ERROR_LOG})"


def _save(out: Path, state: dict) -> None:
    write_json(out / STATE, state)
