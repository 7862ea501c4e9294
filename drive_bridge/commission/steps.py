"""The commissioning steps. Each takes the run's :class:`Context`, keeps its output in the run
directory and returns one line for the person watching; a problem raises (UserError, BusError,
MotionAborted) with the data so far already on disk."""
from __future__ import annotations

import json
from contextlib import ExitStack
from pathlib import Path

import numpy as np

from ..config import BusConfig
from ..connect import open_link
from ..errors import BusError, MotionAborted, UserError
from ..master.bringup import bring_up, check_scan, scan as scan_bus
from ..params.profile import Profile
from ..params.write import export_dcf, read_parameters, write_all, write_parameters
from ..progress import StepReporter
from ..tuning.tune import GAINS, drive_model, motor_data, read_identify_json, read_tune_json, tune_axis

#: where each step keeps its output, relative to the run directory
OUTPUT = {"scan": "scan.json", "bringup": "bringup.json", "campaign": "campaign", "identify": "identify",
          "tune": "tune.json", "write": "write", "validate": "validate"}
IDENTIFY_JSON = "identify/identify.json"
WRITE_JSON = "write/write.json"
VALIDATE_JSON = "validate/validate.json"
TRACES = "validate/traces.npz"


class Context:
    """What the steps share: configuration, run directory, options, and the bus link and
    brought-up drives, opened on first use and closed with ``stack``."""

    def __init__(self, config: BusConfig, out: Path, options, profile: Profile, stack: ExitStack,
                 reporter: StepReporter, link=None):
        self.config, self.out, self.options, self.profile = config, out, options, profile
        self.stack, self.reporter = stack, reporter
        self._link, self._axes = link, None

    @property
    def link(self):
        if self._link is None:
            o = self.options
            self._link = self.stack.enter_context(open_link(self.config, o.sim, o.realtime, o.sim_config))
        return self._link

    @property
    def axes(self):
        if self._axes is None:
            self._axes = bring_up(self.link, self.config)
        return self._axes

    def require(self, name: str) -> Path:
        """A previous step's output; a clear error naming the step to run when it is missing."""
        path = self.out / name
        if not path.exists():
            step = next(s for s, o in OUTPUT.items() if name == o or name.startswith(o + "/"))
            raise UserError(f"{path} is missing: run the {step} step first (--steps {step})")
        return path

    def read_json(self, name: str) -> dict:
        path = self.require(name)
        try:
            return json.loads(path.read_text())
        except ValueError as exc:
            raise UserError(f"{path}: not valid JSON ({exc}); rerun with --restart") from None

    def write_json(self, name: str, doc) -> None:
        path = self.out / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(doc, indent=1, default=float))


def scan(ctx: Context) -> str:
    result = scan_bus(ctx.link, ctx.config)
    by_id = {n.node_id: a for a, n in ctx.config.nodes.items()}
    ctx.write_json(OUTPUT["scan"], {"found": {by_id.get(i, str(i)): {"node_id": i, **ident}
                                              for i, ident in result.found.items()},
                                    "missing": result.missing, "unexpected": result.unexpected,
                                    "wrong_type": result.wrong_type})
    check_scan(result, ctx.config)
    extra = f"; not configured, left alone: nodes {result.unexpected}" if result.unexpected else ""
    return f"{len(result.found)} node(s): " + ", ".join(
        f"{a} = node {n.node_id}" for a, n in ctx.config.nodes.items()) + extra


def bringup(ctx: Context) -> str:
    axes, o = ctx.axes, ctx.options
    doc = {"profile": ctx.profile.name, "drive": ctx.profile.drive, "axes": {}}
    for a, ax in axes.items():
        missing = [e.where() for e in ctx.profile.entries.values() if e.index not in ax.node.object_dictionary]
        if missing:
            raise UserError(f"axis {a}: {ax.cfg.dcf} has no object {', '.join(missing)} of the drive profile "
                            f"{ctx.profile.path}; choose the profile of this drive (--profile)")
        R, L = motor_data(ax.node, *(o.motor or (None, None)))
        doc["axes"][a] = {"node_id": ax.cfg.node_id, "identity": ax.identity, "motor": {"R": R, "L": L},
                          "parameters_before": read_parameters(ax.node, ctx.profile)}
    ctx.write_json(OUTPUT["bringup"], doc)
    return (f"{len(axes)} drive(s) configured (PDO mapping, heartbeat, limits); the {len(ctx.profile.entries)} "
            f"parameters of profile {ctx.profile.name} read as the set before commissioning")


def campaign(ctx: Context) -> str:
    from ..record import record
    result = record(ctx.config, ctx.link, ctx.out / OUTPUT["campaign"], on_plan=ctx.reporter.motion,
                    axes=ctx.axes)
    ctx.reporter.end_motion()
    if result.aborted is not None:
        raise result.aborted
    missing = sum(result.missing.values())
    return (f"{result.plan.duration:.1f} s of motion on {', '.join(result.plan.axes)} "
            f"({len(result.plan.segments)} segments), {missing} samples missing, bus load {result.bus_load}")


def identify(ctx: Context) -> str:
    from ..ident import identify as identify_log
    from ..ident.report import write_markdown
    source = ctx.out / OUTPUT["campaign"]
    results = identify_log(source, seed=ctx.options.seed, progress=lambda a: ctx.reporter.note(f"axis {a}"))
    write_markdown(results, ctx.out / OUTPUT["identify"], str(source))
    return "; ".join(f"{a}: J {r.model.params_['J']:.4g}, " + (
        " + ".join(t.effect.name for t in r.effects) or "no effect") + f", RMSE {r.before.rmse:.3g} → "
        f"{r.after.rmse:.3g} {r.units['torque']}" for a, r in results.items())


def tune(ctx: Context) -> str:
    models = read_identify_json(ctx.require(IDENTIFY_JSON))
    up = ctx.read_json(OUTPUT["bringup"])["axes"]
    doc = {"axes": {}}
    for a in ctx.config.nodes:
        if a not in models or a not in up:
            raise UserError(f"axis {a}: no identified model in {ctx.out / IDENTIFY_JSON}")
        before = up[a]["parameters_before"]
        t = tune_axis(a, models[a], up[a]["motor"]["R"], up[a]["motor"]["L"], {g: before[g] for g in GAINS
                                                                               if g in before})
        doc["axes"][a] = t.as_dict()
    ctx.write_json(OUTPUT["tune"], doc)
    return "; ".join(f"{a}: KpS {d['gains_before'].get('KpS', float('nan')):.3g} → {d['gains']['KpS']:.3g}, "
                     f"KpP {d['gains']['KpP']:.0f}, PM {d['margins']['velocity']['phase_margin_deg']:.1f}°, "
                     f"GM {d['margins']['velocity']['gain_margin_db']:.1f} dB" for a, d in doc["axes"].items())


def write(ctx: Context) -> str:
    params = _tuned(ctx)
    nodes = {a: ctx.axes[a].node for a in params}
    results = write_all(nodes, ctx.profile, params, backup_dir=ctx.out / OUTPUT["write"])
    ok = len(results) == len(params) and all(r.ok for r in results.values())
    ctx.write_json(WRITE_JSON, {"ok": ok, "axes": {a: r.as_dict() for a, r in results.items()}})
    if not ok:
        a, r = next((a, r) for a, r in results.items() if not r.ok)
        raise BusError(f"axis {a}: {r.error}; every drive written so far was restored from its backup "
                       f"({ctx.out / OUTPUT['write']}) and nothing was stored")
    for a, r in results.items():
        export_dcf(nodes[a], r, ctx.out / OUTPUT["write"] / f"{a}.dcf")
    n = sum(len(r.objects) for r in results.values())
    stored = "stored (0x1010 'save')" if all(r.stored for r in results.values()) else "not stored (no store object)"
    return f"{n} objects written and verified on {len(results)} drive(s), {stored}; DCFs in {OUTPUT['write']}/"


def validate(ctx: Context) -> str:
    from ..tuning.validate import validate as run_validation
    params = _tuned(ctx)
    before = {a: v["parameters_before"] for a, v in ctx.read_json(OUTPUT["bringup"])["axes"].items()}
    scenarios = {"before": {a: before[a] for a in params}, "after": params}
    model = {a: drive_model(p) for a, p in params.items()}
    axes = {a: ctx.axes[a] for a in params}
    written = (ctx.out / WRITE_JSON).exists() and ctx.read_json(WRITE_JSON)["ok"]
    try:
        runs = run_validation(ctx.config, ctx.link, axes, ctx.profile, scenarios, model,
                              on_plan=ctx.reporter.motion)
    finally:
        ctx.reporter.end_motion()
        for a, ax in axes.items():         # leave the drives with the set they have stored
            write_parameters(ax.node, ctx.profile, (params if written else before)[a], store=False)
    ctx.write_json(VALIDATE_JSON, {"runs": [r.as_dict() for r in runs]})
    traces = {}
    for r in runs:
        m = r.motion
        for a in m.position:
            key = f"{r.scenario}/{r.trajectory}/{a}"
            traces[key + "/t"] = m.t
            traces[key + "/position"], traces[key + "/demand"] = m.position[a], m.demand[a]
            traces[key + "/torque"] = m.torque[a]
    np.savez_compressed(ctx.out / TRACES, **traces)
    aborted = next((r for r in runs if r.aborted), None)
    if aborted is not None:
        raise MotionAborted(f"validation ({aborted.scenario}, {aborted.trajectory}): {aborted.aborted}")
    fe = {(r.scenario, r.trajectory, a): m.fe_rms for r in runs for a, m in r.axes.items()}
    return "; ".join(f"{a}: FE RMS " + ", ".join(
        f"{t.replace('_', '-')} {fe[('before', t, a)] * 1e3:.3g} → {fe[('after', t, a)] * 1e3:.3g} mrad"
        for t in ("point_to_point", "path")) for a in params)


def _tuned(ctx: Context) -> dict[str, dict[str, float]]:
    return read_tune_json(ctx.require(OUTPUT["tune"]))


STEP_FUNCTIONS = {"scan": scan, "bringup": bringup, "campaign": campaign, "identify": identify,
                  "tune": tune, "write": write, "validate": validate}
