"""What ``identify`` tells: a terminal summary, the JSON contract, and a report with plots (HTML and
Markdown, :mod:`drive_bridge.document`)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..document import Document, Strong, measured, number
from ..figures import pyplot, side_by_side
from ..outputs import json_text, stamped, write_text
from .coverage import motion_text
from .frf import MIN_COHERENCE
from .identify import AxisResult
from .trace import describe_unexplained


def unit(name: str, kind: str) -> str:
    """The unit of a parameter or coefficient.

    Parameters
    ----------
    name : str
        The parameter (``J``, ``offset.offset``, ``spline_odd_position.b3``).
    kind : {"rotary", "linear"}
        The axis's kind.

    Returns
    -------
    str
        Its unit; "" where it has none or depends on the effect's form.
    """
    q, f = ("rad", "Nm") if kind == "rotary" else ("m", "N")
    inertia = "kg·m²" if kind == "rotary" else "kg"
    last = name.split(".")[-1]
    table = {
        "J": inertia,
        "c0": f,
        "c1": f"{f}·s/{q}",
        "offset": f,
        "cp": f"{f}/{q}",
        "dc0": f,
        "dc1": f"{f}·s/{q}",
        "amplitude": f,
        "a_sin": f,
        "a_cos": f,
        "b_sin": f,
        "angle": "rad",
        "period": q,
        "phase": "rad",
        "velocity": f"{q}/s",
        "time_constant_s": "s",
    }
    if last in table:
        return table[last]
    if name.startswith("spline_") and re.fullmatch(r"b\d+", last):
        return inertia if name.startswith("spline_inertial") else f
    return ""


def summary(results: dict[str, AxisResult]) -> str:
    """What ``identify`` prints.

    Parameters
    ----------
    results : dict of str to AxisResult
        Each axis identified.

    Returns
    -------
    str
        Per axis its settings, what the motion tells, the parameters with their std (or why
        undetermined), the effects, the errors before and after, and the diagnostics, in words.
    """
    lines = []
    for axis, r in results.items():
        tu = r.units["torque"]
        lines.append(
            f"axis {axis} ({r.kind}; cut-off {r.settings.cutoff_hz:.1f} Hz, decimation "
            f"{r.settings.decimation}, {int(r.est.moving.sum())} moving samples fitted; "
            f"validation: {r.validation})"
        )
        if r.diagnostics.motion:
            lines.append(f"  {motion_text(r.diagnostics.motion)}")
        std = r.param_std
        for k in ("J", "c0", "c1"):
            v = r.model.params_[k]
            rel = abs(std[k] / v) * 100 if v else float("inf")
            lines.append(
                f"  {k:<3} = {measured(v, std[k])} ± {std[k]:.2g} {unit(k, r.kind)}  ({rel:.2f} %)"
                + (
                    f"  UNDETERMINED: {r.diagnostics.undetermined[k]}"
                    if k in r.diagnostics.undetermined
                    else ""
                )
            )
        if r.diagnostics.friction:
            lines.append(f"  {friction_text(r)}")
        lines.append(
            f"  base model J, c0, c1: validation RMSE {r.before.rmse:.4g} {tu} "
            f"(relative error {r.before.relative_error:.2%})"
        )
        for t in r.effects:
            p = ", ".join(f"{k} {number(v)}" for k, v in t.params.items())
            lines.append(f"  + {t.effect.name} [{t.effect.depends_on}] ({p})")
            lines.append(f"      {t.evidence}")
        if not r.effects:
            lines.append("  no effect found beyond J, c0, c1")
        lines.append(
            f"  final: validation RMSE {r.after.rmse:.4g} {tu} (measured torque RMS {r.after.torque_rms:.4g}, "
            f"noise floor {r.diagnostics.noise_floor:.3g}); relative error {r.after.relative_error:.2%}"
        )
        if r.drive is not None:
            lines.append(f"  {drive_text(r)}")
        lines.append(
            f"  GA (differential evolution) on the same data: validation RMSE {r.ga.errors.rmse:.4g} "
            f"{tu}, J {r.ga.coef[0]:.6g}, c1 {r.ga.coef[1]:.6g}, c0 {r.ga.coef[2]:.6g}; {ga_text(r)}"
        )
        for u_ in r.diagnostics.unexplained:
            lines.append(f"  unexplained: {describe_unexplained(u_)}")
        for d in r.diagnostics.dropped:
            lines.append(f"  dropped: {d}")
        if r.diagnostics.sampling.get("resampled"):
            lines.append(f"  {sampling_text(r.diagnostics.sampling)}")
        if r.diagnostics.sampling.get("torque_clipped"):
            lines.append(f"  {clipped_text(r.diagnostics.sampling['torque_clipped'], tu)}")
        if r.diagnostics.sampling.get("torque_aligned") or r.diagnostics.sampling.get("torque_delay_note"):
            lines.append(f"  {delay_text(r.diagnostics.sampling)}")
        if r.diagnostics.consistency and r.diagnostics.consistency["consistent"] is False:
            lines.append(f"  NOT CONSISTENT: {consistency_text(r.diagnostics.consistency)}")
        if (
            r.diagnostics.consistency
            and r.diagnostics.consistency["consistent"]
            and (agreed := agreement_text(r.diagnostics.consistency))
        ):
            lines.append(f"  consistency: {agreed}")
        if r.diagnostics.consistency and r.diagnostics.consistency["consistent"] is None:
            lines.append(f"  consistency not checked: {not_run_text(r.diagnostics.consistency)}")
        if runs := (r.diagnostics.consistency or {}).get("between_runs"):
            lines.append(f"  two runs: {between_runs_text(runs)}")
        for part, why in (r.diagnostics.consistency or {}).get("degenerate", {}).items():
            lines.append(f"  consistency: the {part} not compared: {why}")
    return "\n".join(lines)


def drive_text(r: AxisResult) -> str:
    """The values written: the model refitted within what a drive's model holds, beside the full one
    (or why the full model's are).

    Parameters
    ----------
    r : AxisResult
        The axis identified.

    Returns
    -------
    str
        The sentence (where the model's effects are all ones a drive holds, that it is the model
        as it is).
    """
    drive = r.drive
    if drive is None:
        return "for the drive: the model as it is (a drive's model holds every term of it)"
    if drive.note:
        return f"for the drive: {drive.note}"
    d, sd = drive.model.params_, drive.param_std
    held = ", ".join(e.name for e in drive.model.effects) or "no effect"
    return (
        f"for the drive (its model holds J, c0, c1 and {held}; refitted without the rest): "
        + ", ".join(f"{k} {measured(d[k], sd[k])} ± {sd[k]:.2g}" for k in ("J", "c0", "c1"))
        + f"; validation RMSE {drive.errors.rmse:.4g} {r.units['torque']} (every term: {r.after.rmse:.4g})"
    )


GA_WITHIN_STD = 1.0  # a GA result this close to the least-squares minimum (in its std) is the same estimate


def ga_text(r: AxisResult) -> str:
    """Whether the GA's values are an estimate: converged, or how far from the least-squares
    minimum of the same cost its search stood when it reached its generation limit.

    Parameters
    ----------
    r : AxisResult
        The axis identified.

    Returns
    -------
    str
        The sentence.
    """
    far = r.ga.std_from_lse
    if r.ga.converged:
        return f"converged, within {far:.2g} std of the least-squares values"
    if far <= GA_WITHIN_STD:
        return f"stopped at its generation limit within {far:.2g} std of the least-squares values"
    return (
        f"stopped at its generation limit up to {far:.2g} std from the least-squares minimum of the same "
        f"cost: its values are where the search stood, not an estimate (the data leave coefficients collinear)"
    )


def friction_text(r: AxisResult) -> str:
    """The speeds c0 and c1 hold for, and where friction is not linear in velocity over them.

    Parameters
    ----------
    r : AxisResult
        The axis identified.

    Returns
    -------
    str
        The sentence.
    """
    f = r.diagnostics.friction
    q = "m" if r.kind == "linear" else "rad"
    text = f"c0 and c1 hold for speeds {f['velocity_range'][0]:.3g} to {f['velocity_range'][1]:.3g} {q}/s"
    if f["linear"]:
        return text
    halves = "; ".join(f"{n} half c0 {f[n]['c0']:.4g}, c1 {f[n]['c1']:.4g}" for n in ("slower", "faster"))
    return (
        f"{text}; friction is NOT linear in velocity over them ({halves}: "
        + ", ".join(f"{p} {s:g} std apart" for p, s in f["sigmas"].items())
        + "): their std is widened by half the difference"
    )


def between_runs_text(runs: dict) -> str:
    """The parameters the estimation and the validation run give differently, and the std widened.

    Parameters
    ----------
    runs : dict
        ``consistency``'s ``between_runs``.

    Returns
    -------
    str
        The sentence ("" where no parameter was widened).
    """
    return "; ".join(
        f"{p} {m['estimation']:.4g} from the estimation run, {m['validation']:.4g} from the validation "
        f"run ({m['sigmas']:.3g} std apart): its std widened {m['std_before']:.2g} -> {m['std_after']:.2g}"
        for p, m in runs.items()
    )


def not_run_text(c: dict) -> str:
    """Why the parts of the data were not compared, and the std widened instead.

    Parameters
    ----------
    c : dict
        ``consistency``'s answer.

    Returns
    -------
    str
        The sentence.
    """
    widened = ", ".join(
        f"{p} std {m['std_before']:.2g} -> {m['std_after']:.2g} (jackknife {m['jackknife_over_hac']:.3g}x HAC)"
        for p, m in (c.get("inflated") or {}).items()
    )
    return c["not_run"] + (
        f"; the std widened to the delete-one-block jackknife's where larger: {widened}"
        if widened
        else "; the jackknife over the log finds no std larger than reported"
    )


def consistency_text(c: dict) -> str:
    """Which parameters moved between parts of the data, and by how much.

    Parameters
    ----------
    c : dict
        ``consistency``'s answer.

    Returns
    -------
    str
        The sentence.
    """
    test = c.get("test") or {}
    return (
        "; ".join(
            f"{p} differs between the {m['between'][0]} and the {m['between'][1]} by {m['sigmas']:.3g} std ("
            + ", ".join(f"{n} {v:.4g}" for n, v in m["values"].items())
            + ")"
            for p, m in c["moved"].items()
        )
        + ": the data hold more than one value (a payload change, a warm-up, or structure the model lacks)"
        + (
            f"; the parts' chi-squared {test['chi2']:g} on {test['dof']} degrees of freedom, p = "
            f"{test['p_value']:.2g}, beyond the {test['false_alarm_rate']:.0%} that consistent data reach"
            if test
            else ""
        )
    )


def agreement_text(c: dict) -> str:
    """That the parts of the data agree, at what false-alarm rate, and the steps the test would see.

    Parameters
    ----------
    c : dict
        ``consistency``'s answer (``consistent`` true, with its ``test``).

    Returns
    -------
    str
        The sentence ("" where no test was made).
    """
    test = c.get("test") or {}
    if not test:
        return ""
    steps = test.get("detects") or {}
    return (
        f"the parts agree (p = {test['p_value']:.2g}; the test flags {test['false_alarm_rate']:.0%} of "
        f"consistent axes)"
        + (
            "; a step between the halves of "
            + ", ".join(f"{p} {s:.0%}" for p, s in sorted(steps.items()) if s is not None)
            + f" would be seen {test['detection_power']:.0%} of the time"
            if steps
            else ""
        )
    )


def sampling_text(s: dict) -> str:
    """What the time stamps held and what was done about it, in one sentence.

    Parameters
    ----------
    s : dict
        ``diagnostics.sampling``.

    Returns
    -------
    str
        The sentence.
    """
    return (
        f"time stamps not evenly spaced (steps off the median {s['period_s'] * 1e3:.3f} ms by up to "
        f"{s['max_step_deviation_s'] * 1e6:.0f} µs, std {s['jitter_std_s'] * 1e6:.0f} µs; {s['gaps']} gap(s) "
        f"split the log): resampled onto a uniform {s['period_s'] * 1e3:.3f} ms grid, position and torque "
        f"through the same cubic spline"
    )


def clipped_text(c: dict, unit_: str) -> str:
    """Where the logged torque was clipped and what was done about it, in one sentence.

    Parameters
    ----------
    c : dict
        ``diagnostics.sampling["torque_clipped"]``: the levels and their share.
    unit_ : str
        The torque's unit.

    Returns
    -------
    str
        The sentence.
    """
    return (
        f"the logged torque is clipped at {' and '.join(f'{v:g}' for v in c['levels'])} {unit_} on "
        f"{c['share']:.1%} of the samples: those (and one cut-off period around them) were not fitted"
    )


def delay_text(s: dict) -> str:
    """How the torque was (or was not) aligned with the position, in one sentence.

    Parameters
    ----------
    s : dict
        ``diagnostics.sampling``.

    Returns
    -------
    str
        The sentence.
    """
    if not s["torque_aligned"]:
        d = s["torque_delay_estimate_ms"]
        return (
            f"the logged torque {'lags' if d > 0 else 'leads'} the position by {abs(d):.3g} ms by the estimate "
            f"(± {s['torque_delay_std_ms']:.2g} ms); {s['torque_delay_note']}"
        )
    d = s["torque_delay_ms"]
    how = (
        f"estimated, ± {s['torque_delay_std_ms']:.2g} ms"
        if s["torque_delay_source"] == "estimated"
        else "as given"
    )
    return (
        f"the logged torque {'lags' if d > 0 else 'leads'} the position by {abs(d):.3g} ms ({how}): the "
        f"positions were read at the instants the torque stands for"
    )


def as_json(results: dict[str, AxisResult]) -> str:
    """identify.json and ``identify --json``.

    Parameters
    ----------
    results : dict of str to AxisResult
        Each axis identified.

    Returns
    -------
    str
        The JSON text (schema ``identify``: per axis :meth:`.identify.AxisResult.as_json`).
    """
    return json_text(stamped("identify", {"axes": {a: r.as_json() for a, r in results.items()}}))


SPAN_S = 3.0  # length of each stretch of the validation the fit figure shows [s]
SPANS = 3


def _spans(t: np.ndarray, moving: np.ndarray) -> list[slice]:
    """Up to :data:`SPANS` contiguous stretches of :data:`SPAN_S` (no gap in the time stamps) where
    the axis moves: from the longest blocks of the validation, or spread over one block."""
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    cuts = np.flatnonzero(np.diff(t) > 1.5 * dt) + 1
    blocks = sorted((b for b in np.split(np.arange(len(t)), cuts) if len(b) > 1), key=len, reverse=True)
    n = max(2, int(round(SPAN_S / dt)))
    if len(blocks) == 1 or len(blocks[0]) >= SPANS * n:
        b = blocks[0]
        starts = (
            [b[0] + int(f * max(0, len(b) - n)) for f in np.linspace(0.1, 0.9, SPANS)]
            if len(b) > n
            else [b[0]]
        )
    else:
        starts = [b[0] + max(0, (len(b) - n) // 2) for b in blocks[:SPANS]]
    out = []
    for i in sorted(starts):
        sl = slice(i, min(i + n, len(t)))
        if moving[sl].any():
            out.append(sl)
    return out or [slice(0, min(n, len(t)))]


def _plot_fit(r: AxisResult, path: Path) -> None:
    """Measured and predicted torque and the residual, before and after the traced effects, on a
    few contiguous stretches of the validation samples (lines, not clouds: agreement is visible)."""
    plt = pyplot()
    s, tu = r.val, r.units["torque"]
    base = np.where(s.moving, r.base.predict(s, logged=True), np.nan)
    final = np.where(s.moving, r.model.predict(s, logged=True), np.nan)
    spans = _spans(s.t, s.moving)
    fig, ax = plt.subplots(
        2, len(spans), figsize=(11, 6), sharey="row", squeeze=False, gridspec_kw={"height_ratios": [2, 1]}
    )
    for col, sl in enumerate(spans):
        t = s.t[sl]
        ax[0, col].plot(t, s.tau[sl], color="0.55", lw=1.6, label="measured (as logged)")
        ax[0, col].plot(t, base[sl], color="C1", lw=0.9, ls="--", label="predicted, J, c0, c1")
        ax[0, col].plot(t, final[sl], color="C0", lw=0.9, label="predicted, final model")
        ax[1, col].plot(t, s.tau[sl] - base[sl], color="C1", lw=0.8, label="residual, J, c0, c1")
        ax[1, col].plot(t, s.tau[sl] - final[sl], color="C0", lw=0.8, label="residual, final model")
        ax[1, col].set_xlabel("time [s]")
        for row in range(2):
            ax[row, col].grid(True, alpha=0.3)
    ax[0, 0].set_ylabel(f"torque [{tu}]")
    ax[1, 0].set_ylabel(f"residual [{tu}]")
    handles = [h for a_ in (ax[0, 0], ax[1, 0]) for h in a_.get_legend_handles_labels()[0]]
    fig.legend(
        handles, [h.get_label() for h in handles], loc="lower center", ncol=5, fontsize=8, frameon=False
    )
    fig.suptitle(
        f"axis {r.axis}, validation samples, {len(spans)} stretches of {SPAN_S:g} s: RMSE "
        f"{r.before.rmse:.4g} {tu} (J, c0, c1) → {r.after.rmse:.4g} {tu} (final model)"
    )
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.16, top=0.92, wspace=0.08, hspace=0.25)
    fig.savefig(path, dpi=85)
    plt.close(fig)


def plot_response(r: AxisResult, path: Path) -> bool:
    """The log's torque → velocity response beside the rigid model's (magnitude, phase, coherence;
    bands below ``MIN_COHERENCE`` hollow).

    Parameters
    ----------
    r : AxisResult
        The axis identified.
    path : Path
        The PNG to draw.

    Returns
    -------
    bool
        Drawn; False where the log has no response.
    """
    x = r.diagnostics.response
    if not x or not x["frequency_hz"]:
        return False
    plt = pyplot()
    f, coh = np.array(x["frequency_hz"]), np.array(x["coherence"])
    good = coh >= MIN_COHERENCE
    fig, ax = plt.subplots(3, 1, figsize=(9, 7), sharex=True, gridspec_kw={"height_ratios": [2, 1.4, 1]})
    mag = 20 * np.log10(np.array(x["magnitude"]))
    ax[0].semilogx(
        f, 20 * np.log10(np.array(x["model_magnitude"])), "k-", lw=1, label="rigid model 1/(J·jω + c1)"
    )
    for sel, style, label in ((good, "o", "from the log"), (~good, "o", f"coherence < {MIN_COHERENCE:g}")):
        face = "C0" if sel is good else "none"
        ax[0].semilogx(f[sel], mag[sel], style, mfc=face, mec="C0", ms=4, ls="none", label=label)
        ax[1].semilogx(f[sel], np.array(x["phase_deg"])[sel], style, mfc=face, mec="C0", ms=4, ls="none")
    ax[1].axhline(-90, color="k", lw=1)
    ax[2].semilogx(f, coh, "C0.-", lw=0.8)
    ax[2].axhline(MIN_COHERENCE, color="0.5", lw=0.8, ls="--")
    ax[0].set_ylabel("|G| [dB]")
    ax[1].set_ylabel("phase [°]")
    ax[2].set_ylabel("coherence")
    ax[2].set_xlabel("frequency [Hz]")
    ax[0].legend(fontsize=8)
    for a in ax:
        a.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"axis {r.axis}: torque → velocity read from the log")
    fig.savefig(path, dpi=85)
    plt.close(fig)
    return True


def _variable(r: AxisResult, depends_on: str) -> tuple[np.ndarray, str]:
    s = r.est
    pos = r.units["position"]
    table = {
        "position": (s.q, f"position [{pos}]"),
        "velocity": (s.qd, f"velocity [{pos}/s]"),
        "direction": (s.qd, f"velocity [{pos}/s]"),
        "time": (s.t, "time [s]"),
        "constant": (s.qd, f"velocity [{pos}/s]"),
        "acceleration": (s.qdd, f"acceleration [{pos}/s²]"),
        "abs_acceleration": (np.abs(s.qdd), f"|acceleration| [{pos}/s²]"),
    }
    if depends_on in table:
        return table[depends_on]
    other, kind = depends_on.rsplit("_", 1)
    q, qd, qdd = s.others[other]
    return {"position": q, "velocity": qd, "acceleration": qdd}[kind], f"axis {other} {kind}"


def _plot_effect(r: AxisResult, k: int, path: Path) -> None:
    """The effect's term in the final model (the parameters the table gives) over the variable it
    depends on, with the partial residual: what the final model leaves, plus this term."""
    plt = pyplot()
    t = r.effects[k]
    s, m = r.est, r.est.moving
    x, label = _variable(r, t.effect.depends_on)
    term = r.model.effect_term(t.effect, s)[m]
    partial = (s.tau_f - r.model.predict(s))[m] + term
    xs, ylabel = x[m], f"torque [{r.units['torque']}]"
    if getattr(t.effect, "form", None) == "inertial":  # the inertia it adds: torque per acceleration
        qdd = s.qdd[m]
        keep = np.abs(qdd) > 0.5 * np.sqrt(np.mean(qdd**2))  # samples with |acceleration| > ½ RMS
        xs, partial, term = xs[keep], partial[keep] / qdd[keep], term[keep] / qdd[keep]
        ylabel = f"inertia added [{unit('J', r.kind)}]"
    fig, ax = plt.subplots(figsize=(8, 4.5))
    ax.plot(xs, partial, ".", ms=1.5, color="0.6", label="residual of the final model + this term")
    order = np.argsort(xs, kind="stable")
    ax.plot(xs[order], term[order], ".", ms=2, color="C3", label=f"{t.effect.name} in the final model")
    p = ", ".join(f"{n} {number(v)}" for n, v in t.params.items() if not isinstance(v, (list, dict)))
    ax.set_xlabel(label)
    ax.set_ylabel(ylabel)
    ax.set_title(
        f"axis {r.axis}: {t.effect.name} ({t.effect.depends_on})" + (f": {p}" if len(p) < 70 else ""),
        fontsize=10,
    )
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(0, -0.14), ncol=2, markerscale=6, fontsize=8, frameon=False)
    fig.subplots_adjust(left=0.1, right=0.97, bottom=0.24, top=0.9)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _sentence(text: str) -> str:
    return text[0].upper() + text[1:] + "."


def draw_figures(results: dict[str, AxisResult], out: Path) -> dict[str, bool]:
    """Each axis's figures: its fit, its response read from the log and each effect's; the axes side
    by side where work is shared out.

    Parameters
    ----------
    results : dict of str to AxisResult
        Each axis identified.
    out : Path
        The directory they are drawn into.

    Returns
    -------
    dict of str to bool
        Per axis, whether its response was drawn (the log shows one).
    """
    return dict(zip(results, side_by_side(_draw_axis, list(results), (results, out))))


def _draw_axis(shared: tuple[dict[str, AxisResult], Path], axis: str) -> bool:
    results, out = shared
    return _draw(results[axis], out)


def _draw(r: AxisResult, out: Path) -> bool:
    _plot_fit(r, out / f"{r.axis}_fit.png")
    for k, t in enumerate(r.effects):
        _plot_effect(r, k, _effect_png(out, r.axis, k, t.effect.name))
    return plot_response(r, out / f"{r.axis}_response.png")


def _effect_png(out: Path, axis: str, k: int, name: str) -> Path:
    return out / f"{axis}_effect{k + 1}_{name}.png"


def build_report(results: dict[str, AxisResult], out: Path, source: str, figures: bool = True) -> Document:
    """The identification report.

    Parameters
    ----------
    results : dict of str to AxisResult
        Each axis identified.
    out : Path
        Where its figures are drawn.
    source : str
        What was identified (the log), for the title.
    figures : bool
        Draw the figures (each axis's in a process of its own where the work is shared out,
        :func:`draw_figures`); without, the report says so.

    Returns
    -------
    Document
        The report, not yet written.
    """
    drawn = draw_figures(results, out) if figures else dict.fromkeys(results, False)
    doc = Document(f"Identification of {source}", figures=figures)
    for axis, r in results.items():
        tu = r.units["torque"]
        doc.heading(1, f"Axis {axis} ({r.kind})")
        doc.para(
            f"Cut-off {r.settings.cutoff_hz:.1f} Hz (motion bandwidth {r.settings.motion_bandwidth_hz:.2f} Hz), "
            f"decimation {r.settings.decimation}, {int(r.est.moving.sum())} moving samples fitted. "
            f"Validation: {r.validation}."
            + (f" {motion_text(r.diagnostics.motion).capitalize()}." if r.diagnostics.motion else "")
        )
        rows = []
        coef_std = r.uncertainty.coef_std
        for i, name in enumerate(r.model.coef_names):
            v = r.model.coef_[i]
            sd = float(coef_std[i])
            rows.append(
                [
                    name,
                    unit(name, r.kind),
                    measured(v, sd),
                    f"{sd:.2g}",
                    f"{abs(sd / v) * 100 if v else 0:.2f} %",
                    measured(r.ga.coef[i], sd),
                ]
            )
        doc.table(["coefficient", "unit", "LSE", "std", "rel. std", "GA"], rows)
        doc.para(
            f"Condition number {r.model.cond_:.1f}; residual std {r.model.sigma_:.4g} {tu}; "
            f"GA validation RMSE {r.ga.errors.rmse:.4g} {tu} (LSE {r.after.rmse:.4g} {tu}); {ga_text(r)}."
        )
        rows = [["J, c0, c1", f"{r.before.rmse:.4g}", f"{r.before.relative_error:.2%}"]]
        names = []
        for t in r.effects:
            names.append(t.effect.name)
            rows.append([f"+ {' + '.join(names)}", f"{t.rmse_after:.4g}", f"{t.relative_error_after:.2%}"])
        doc.table(
            ["model", f"validation RMSE, logged torque [{tu}]", "relative error, filtered torque"], rows
        )
        doc.para(
            f"Measured torque RMS on the same samples {r.after.torque_rms:.4g} {tu}; "
            f"noise floor {r.diagnostics.noise_floor:.3g} {tu}."
        )
        doc.figure(out / f"{axis}_fit.png", f"axis {axis}: measured and predicted torque and the residual")
        if drawn[axis]:
            doc.figure(
                out / f"{axis}_response.png",
                f"axis {axis}: the plant's response read from the log "
                f"(the torque less the model's nonlinear terms, to the velocity), "
                f"beside the rigid model's; hollow: coherence below "
                f"{MIN_COHERENCE:g}",
            )
        for k, t in enumerate(r.effects):
            png = _effect_png(out, axis, k, t.effect.name)
            doc.heading(2, f"{t.effect.name} (depends on {t.effect.depends_on})")
            doc.para(_sentence(t.evidence))
            doc.figure(png, t.effect.name)
        if r.diagnostics.unexplained:
            doc.para("Unexplained structure left in the residual:")
            doc.bullets([describe_unexplained(x) for x in r.diagnostics.unexplained])
        if r.diagnostics.dropped:
            doc.para("Dropped from the log:")
            doc.bullets(list(r.diagnostics.dropped))
        if r.diagnostics.sampling.get("resampled"):
            doc.para(_sentence(sampling_text(r.diagnostics.sampling)))
        if r.diagnostics.sampling.get("torque_clipped"):
            doc.para(_sentence(clipped_text(r.diagnostics.sampling["torque_clipped"], tu)))
        if r.diagnostics.sampling.get("torque_aligned") or r.diagnostics.sampling.get("torque_delay_note"):
            doc.para(_sentence(delay_text(r.diagnostics.sampling)))
        if r.drive is not None:
            doc.para(_sentence(drive_text(r)))
        if r.diagnostics.friction:
            doc.para(_sentence(friction_text(r)))
        if r.diagnostics.consistency and r.diagnostics.consistency["consistent"] is False:
            doc.para([Strong("Not consistent:"), f" {consistency_text(r.diagnostics.consistency)}."])
        if (
            r.diagnostics.consistency
            and r.diagnostics.consistency["consistent"]
            and (agreed := agreement_text(r.diagnostics.consistency))
        ):
            doc.para([Strong("Consistency:"), f" {agreed}."])
        if r.diagnostics.consistency and r.diagnostics.consistency["consistent"] is None:
            doc.para([Strong("Consistency not checked:"), f" {not_run_text(r.diagnostics.consistency)}."])
        if runs := (r.diagnostics.consistency or {}).get("between_runs"):
            doc.para([Strong("Two runs:"), f" {between_runs_text(runs)}."])
        for name, why in r.diagnostics.undetermined.items():
            doc.para(
                [Strong(f"{name} undetermined:"), f" {why}; it is not used to tune nor written to a drive."]
            )
    return doc


REPORT, REPORT_MD = "identify.html", "identify.md"


def write_report(results: dict[str, AxisResult], out: Path, source: str, figures: bool = True) -> Path:
    """Write the identification report and its JSON.

    Parameters
    ----------
    results : dict of str to AxisResult
        Each axis identified.
    out : Path
        The directory: ``identify.html`` (self-contained), ``identify.md`` (its plots beside it,
        where ``figures`` are drawn) and ``identify.json``.
    source : str
        What was identified (the log), for the title.
    figures : bool
        Draw the figures.

    Returns
    -------
    Path
        The Markdown report.
    """
    out.mkdir(parents=True, exist_ok=True)
    if not figures:  # no figure of an earlier identification is left beside this one
        for axis in results:
            for png in out.glob(f"{axis}_*.png"):
                png.unlink()
    doc = build_report(results, out, source, figures)
    write_text(out / "identify.json", as_json(results))
    return doc.write(out / REPORT, out / REPORT_MD)[1]
