"""The commissioning steps. Each takes the run's :class:`Context`, calls the same core function
as its command on its own (scan, record, identify, tune, write, validate), keeps its output in
the run directory and returns one line for the person watching; a problem raises a
:class:`~drive_bridge.errors.DriveBridgeError` with the data so far already on disk."""

from __future__ import annotations

import json
from pathlib import Path

from ..errors import UserError
from ..figures import side_by_side
from ..master.bringup import AxisLink, check_scan
from ..master.bringup import scan as scan_bus
from ..master.hold import HeldAxes, hold_powered
from ..outputs import stamped, write_json
from ..params.read import drive_state
from ..params.write import raise_for_failure, write_drives
from ..progress import StepReporter
from ..session import Session
from ..tuning import tune as gain_tuning
from ..tuning import validate as validation
from ..tuning.tune import (
    drive_model,
    read_frf_json,
    read_identify_json,
    read_resonances,
    read_tune_json,
    tune_doc,
    unwritable_effects,
)
from ..tuning.validate import degraded, run_scenarios, stopped

#: where each step keeps its output, relative to the run directory
OUTPUT = {
    "scan": "scan.json",
    "bringup": "bringup.json",
    "campaign": "campaign",
    "identify": "identify",
    "measure": "frf.json",
    "tune": "tune.json",
    "write": "write",
    "validate": "validate",
}
IDENTIFY_JSON = "identify/identify.json"
WRITE_JSON = "write/write.json"
VALIDATE_JSON = f"{OUTPUT['validate']}/{validation.VALIDATE_JSON}"
TRACES = f"{OUTPUT['validate']}/{validation.TRACES}"
LOOPS = "loops_{axis}.png"  # the tune step's loop pictures, per axis


class Context:
    """What the steps share: the session with the drives, the run directory and the reporter.

    Parameters
    ----------
    session : Session
        The drives, reached as the options say.
    out : Path
        The run directory.
    reporter : StepReporter
        Where progress goes.
    """

    def __init__(self, session: Session, out: Path, reporter: StepReporter):
        self.session, self.out, self.reporter = session, out, reporter
        self.config, self.options = session.config, session.options
        self.degraded: list[str] = []  # the running step's wall-clock runs past their timing limits
        self._held = False

    @property
    def axes(self) -> dict[str, AxisLink]:
        """The session's drives, brought up (:meth:`brought_up`)."""
        return self.brought_up()

    def brought_up(self) -> dict[str, AxisLink]:
        """The session's drives brought up; the first time, every axis without a brake is powered
        and held where it stands, from then to the run's end (:func:`~drive_bridge.master.hold.hold_powered`,
        said).

        Returns
        -------
        dict of str to AxisLink
            The axes.
        """
        axes = self.session.axes
        if not self._held:
            self._held = True
            for line in hold_powered(axes):
                self.reporter.note(line)
        return axes

    def require(self, name: str) -> Path:
        """A previous step's output; a clear error naming the step to run when it is missing.

        Parameters
        ----------
        name : str
            Its path in the run directory (``tune.json``, ``identify/identify.json``).

        Returns
        -------
        Path
            The file.

        Raises
        ------
        UserError
            It is missing: the step that makes it is named.
        """
        path = self.out / name
        if not path.exists():
            step = next(s for s, o in OUTPUT.items() if name == o or name.startswith(o + "/"))
            raise UserError(f"{path} is missing: run the {step} step first (--steps {step})")
        return path

    def read_json(self, name: str) -> dict:
        """A previous step's JSON output.

        Parameters
        ----------
        name : str
            Its path in the run directory.

        Returns
        -------
        dict
            The document.

        Raises
        ------
        UserError
            Missing (the step to run is named) or not readable JSON.
        """
        path = self.require(name)
        try:
            return json.loads(path.read_text())
        except ValueError as exc:
            raise UserError(f"{path}: not valid JSON ({exc}); rerun with --restart") from exc


def scan(ctx: Context) -> str:
    """The scan step: the configured nodes found on the bus, their identities checked (scan.json).

    Parameters
    ----------
    ctx : Context
        The run's session, directory and reporter.

    Returns
    -------
    str
        What it found or did, in one line for the reporter.
    """
    config = ctx.config
    result = scan_bus(ctx.session.link, config)
    write_json(ctx.out / OUTPUT["scan"], result.as_dict(config))
    check_scan(result, config)
    extra = f"; not configured, left alone: nodes {result.unexpected}" if result.unexpected else ""
    extra += "".join(
        f"; identity of {a} ACCEPTED although it differs: {why}"
        for a, why in result.identity_accepted.items()
    )
    return (
        f"{len(result.found)} node(s): "
        + ", ".join(f"{a} = node {n.node_id}" for a, n in config.nodes.items())
        + extra
    )


def bringup(ctx: Context) -> str:
    """The bring-up step: PDO mapping, heartbeat, limits written, the drives' state read (bringup.json).

    Parameters
    ----------
    ctx : Context
        The run's session, directory and reporter.

    Returns
    -------
    str
        What it found or did, in one line for the reporter.
    """
    profile = ctx.session.profile
    axes = ctx.axes
    state = drive_state(axes, profile, ctx.options.motor)
    for a, ax in axes.items():
        state[a]["process_data"] = ax.process_data()
    write_json(
        ctx.out / OUTPUT["bringup"],
        stamped("bringup", {"profile": profile.name, "drive": profile.drive, "axes": state}),
    )
    return (
        f"{len(axes)} drive(s) configured (PDO mapping, heartbeat, limits); the {len(profile.entries)} "
        f"parameters of profile {profile.name} read as the set before commissioning"
    )


def campaign(ctx: Context) -> str:
    """The campaign step: the excitation campaign streamed to every axis and recorded (the robot moves).

    Parameters
    ----------
    ctx : Context
        The run's session, directory and reporter.

    Returns
    -------
    str
        What it found or did, in one line for the reporter.
    """
    from ..recorder import record

    ctx.brought_up()  # an axis without a brake held before the campaign brings the drives up again
    # brought up once more inside the campaign's trace (the bringup step's writes, the same again),
    # so that it holds bring-up, streaming and stop as a capture from the bus's opening would
    result = record(ctx.config, ctx.session.link, ctx.out / OUTPUT["campaign"], on_plan=ctx.reporter.motion)
    ctx.reporter.end_motion()
    if result.aborted is not None:
        raise result.aborted
    if result.timing.degraded:
        ctx.degraded.append("campaign: " + "; ".join(result.timing.reasons))
    missing = sum(result.missing.values())
    late = (
        f", {result.timing.late_cycles_pct:.3g} % late cycles, largest SYNC gap "
        f"{result.timing.max_sync_gap_ms:.3g} ms"
        if result.timing.clock == "wall"
        else ""
    )
    return (
        f"{result.plan.duration:.1f} s of motion on {', '.join(result.plan.axes)} "
        f"({len(result.plan.segments)} segments), {missing} samples missing, bus load {result.bus_load}{late}"
        + (f"; {result.repeated()}" if result.repeats else "")
        + (" -- TIMING DEGRADED" if result.timing.degraded else "")
    )


def identify(ctx: Context) -> str:
    """The identify step: J, c0, c1 and the traced effects from the campaign's log (identify/).

    Parameters
    ----------
    ctx : Context
        The run's session, directory and reporter.

    Returns
    -------
    str
        What it found or did, in one line for the reporter.
    """
    from ..ident import identify as identify_log
    from ..ident.presentation import write_report

    source = ctx.require(OUTPUT["campaign"])
    results = identify_log(source, seed=ctx.options.seed, progress=lambda a: ctx.reporter.note(f"axis {a}"))
    write_report(results, ctx.out / OUTPUT["identify"], str(source), ctx.options.figures)
    return "; ".join(
        f"{a}: J {r.model.params_['J']:.4g}, "
        + (" + ".join(t.effect.name for t in r.effects) or "no effect")
        + f", RMSE {r.before.rmse:.3g} → "
        f"{r.after.rmse:.3g} {r.units['torque']}"
        for a, r in results.items()
    )


def measure(ctx: Context) -> str:
    """The measure step: each axis's frequency response through its drive (frf.json; the robot moves).

    Parameters
    ----------
    ctx : Context
        The run's session, directory and reporter.

    Returns
    -------
    str
        What it found or did, in one line for the reporter.
    """
    from ..tuning.measure import frf_doc, measure_axes

    models = read_identify_json(ctx.require(IDENTIFY_JSON))
    axes = {a: ax for a, ax in ctx.axes.items() if a in models}
    try:
        frfs, skipped = measure_axes(
            ctx.config,
            ctx.session.link,
            axes,
            ctx.session.profile,
            {a: models[a]["J"] for a in axes},
            on_plan=ctx.reporter.motion,
        )
    finally:
        ctx.reporter.end_motion()
    skipped |= {a: "not identified (see the identify step)" for a in ctx.axes if a not in models}
    write_json(ctx.out / OUTPUT["measure"], frf_doc(frfs, skipped))
    return "; ".join(
        [
            f"{a}: {int(f.reliable().sum())} bins from {f.frequency_hz[f.reliable()].min():.3g} to "
            f"{f.frequency_hz[f.reliable()].max():.3g} Hz"
            for a, f in frfs.items()
        ]
        + [f"{a}: not measured, tuned on the model alone: {why}" for a, why in skipped.items()]
    )


def _measured(ctx: Context) -> dict | None:
    """The axes' measured responses, where the measure step ran."""
    path = ctx.out / OUTPUT["measure"]
    return read_frf_json(path) if path.exists() else None


def tune(ctx: Context) -> str:
    """The tune step: gains from the identified models, their margins (tune.json).

    Parameters
    ----------
    ctx : Context
        The run's session, directory and reporter.

    Returns
    -------
    str
        What it found or did, in one line for the reporter.
    """
    models = read_identify_json(ctx.require(IDENTIFY_JSON))
    state = ctx.read_json(OUTPUT["bringup"])["axes"]
    missing = [a for a in ctx.config.nodes if a not in state]
    if missing:
        raise UserError(f"axis {missing[0]}: not in {ctx.out / OUTPUT['bringup']}; rerun the bringup step")
    frfs = _measured(ctx) or {}
    profile = ctx.session.profile
    doc = tune_doc(
        gain_tuning.tune(
            models,
            {a: state[a] for a in ctx.config.nodes},
            frfs,
            profile.controller,
            read_resonances(ctx.require(IDENTIFY_JSON)),
            profile.drive,
        ),
        unwritable_effects(ctx.require(IDENTIFY_JSON)),
    )
    write_json(ctx.out / OUTPUT["tune"], doc)
    if ctx.options.figures:
        side_by_side(_loop_figure, list(doc["axes"]), (ctx.out, doc, frfs, profile.controller.timing.tick_s))
    else:  # no figure of an earlier run's gains is left beside these
        for a in doc["axes"]:
            (ctx.out / LOOPS.format(axis=a)).unlink(missing_ok=True)
    return "; ".join(
        f"{a}: KpS {d['gains_before'].get('KpS', float('nan')):.3g} → {d['gains']['KpS']:.3g}, "
        f"KpP {d['gains']['KpP']:.0f}, PM {d['margins']['velocity']['phase_margin_deg']:.1f}°, "
        f"GM {d['margins']['velocity']['gain_margin_db']:.1f} dB"
        + (f", not writable: {', '.join(d['not_writable'])}" if d["not_writable"] else "")
        + _measured_response(d.get("measured_response"))
        for a, d in doc["axes"].items()
    )


def _measured_response(record: dict | None) -> str:
    """How the tune step's line says the measured response was set aside (nothing where it was used
    or not measured)."""
    if not record:
        return ""
    if record["used"]:
        return (
            f"; designed on the measured response although {record['departs']}"
            if record.get("departs")
            else ""
        )
    return f"; MEASURED RESPONSE SUSPECT, gains from the model alone: {record['suspect']}"


def _loop_figure(shared: tuple[Path, dict, dict, float], a: str) -> None:
    from ..tuning.loops import loop_figure

    out, doc, frfs, tick_s = shared
    d = doc["axes"][a]
    loop_figure(
        d["model"]["J"],
        d["model"]["c1"],
        d["gains_before"] or None,
        d["gains"],
        d["motor"]["L"],
        out / LOOPS.format(axis=a),
        f"axis {a}: loops on the identified model"
        + (" (lines) and on the measured plant (points)" if a in frfs else ""),
        frfs.get(a),
        tick_s,
    )


def write(ctx: Context) -> str:
    """The write step: the tuned set written in one transaction, read back, stored (write/).

    Parameters
    ----------
    ctx : Context
        The run's session, directory and reporter.

    Returns
    -------
    str
        What it found or did, in one line for the reporter.
    """
    tuned = read_tune_json(ctx.require(OUTPUT["tune"])).only(ctx.config)
    # brought up (PDO mapping, heartbeat, limits; drives stay disabled): what is stored and what
    # the DCF reads back is the whole commissioning, not the gains alone
    axes = {a: ctx.axes[a] for a in tuned.parameters}
    out, o = ctx.out / OUTPUT["write"], ctx.options
    # the gains keep their margins on the responses they were designed on, not on one set aside
    set_aside = {
        a
        for a, d in ctx.read_json(OUTPUT["tune"])["axes"].items()
        if not (d.get("measured_response") or {}).get("used", True)
    }
    designed_on = {a: f for a, f in (_measured(ctx) or {}).items() if a not in set_aside}
    held = HeldAxes(ctx.axes)  # an axis held powered must still stand once the set is written
    outcome = write_drives(
        {a: ax.node for a, ax in axes.items()},
        ctx.session.profile,
        tuned.parameters,
        backup_dir=out,
        dcf_dir=out,
        inductance=tuned.inductance,
        force=o.force,
        pm_floor=o.pm_floor,
        gm_floor=o.gm_floor,
        allow_unverified_scales=o.writes_unverified,
        bitrate=ctx.config.master.nominal_bitrate,
        settings_before={a: ax.before for a, ax in axes.items()},
        frf=designed_on,
        torque_constants=ctx.config.torque_constants,
        strayed=held.strayed,
    )
    write_json(ctx.out / WRITE_JSON, outcome.as_dict())
    raise_for_failure(outcome, out)
    results = outcome.results
    n = sum(len(r.objects) for r in results.values())
    if n == 0:
        return (
            f"nothing written: the {ctx.session.profile.drive} profile maps none of the tuned parameters "
            f"to an object of the drive (set the gains of tune.json with the vendor's own tool)"
        )
    stored = (
        "stored (0x1010 'save')"
        if all(r.stored for r in results.values())
        else "not stored (no store object)"
    )
    forced = f"; FORCED: {'; '.join(outcome.forced)}" if outcome.forced else ""
    return (
        f"{n} objects written and verified on {len(results)} drive(s), {stored}; DCFs and backups in "
        f"{OUTPUT['write']}/{forced}"
    )


def validate(ctx: Context) -> str:
    """The validate step: the reference trajectories before and after (validate/; the robot moves).

    Parameters
    ----------
    ctx : Context
        The run's session, directory and reporter.

    Returns
    -------
    str
        What it found or did, in one line for the reporter.
    """
    params = read_tune_json(ctx.require(OUTPUT["tune"])).only(ctx.config).parameters
    before = {a: v["parameters_before"] for a, v in ctx.read_json(OUTPUT["bringup"])["axes"].items()}
    scenarios = {"before": {a: before[a] for a in params}, "after": params}
    model = {a: drive_model(p) for a, p in params.items()}
    axes = {a: ctx.axes[a] for a in params}
    try:
        runs = run_scenarios(
            ctx.config,
            ctx.session.link,
            axes,
            ctx.session.profile,
            scenarios,
            model,
            out_dir=ctx.out / OUTPUT["validate"],
            on_plan=ctx.reporter.motion,
        )
    finally:
        ctx.reporter.end_motion()
    stop = stopped(runs)
    if stop is not None:
        raise stop
    ctx.degraded += [f"validate: {d}" for d in degraded(runs)]
    fe = {(r.scenario, r.trajectory, a): m.fe_rms for r in runs for a, m in r.axes.items()}
    ways = sorted({way for r in runs if r.scenario == "after" for way in r.feedforward.values()})
    return (
        "model feed-forward "
        + " / ".join(ways)
        + "; "
        + "; ".join(
            f"{a}: FE RMS "
            + ", ".join(
                f"{t.replace('_', '-')} {fe[('before', t, a)] * 1e3:.3g} → {fe[('after', t, a)] * 1e3:.3g} mrad"
                for t in ("point_to_point", "path")
            )
            for a in params
        )
    )


STEP_FUNCTIONS = {
    "scan": scan,
    "bringup": bringup,
    "campaign": campaign,
    "identify": identify,
    "measure": measure,
    "tune": tune,
    "write": write,
    "validate": validate,
}
