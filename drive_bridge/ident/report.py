"""What ``identify`` tells: a terminal summary, the JSON contract, a Markdown report with plots."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..outputs import json_text, stamped, write_text
from .identify import AxisResult
from .model import AxisModel
from .trace import describe_unexplained

UNITS = {"rotary": {"J": "kg·m²", "c0": "Nm", "c1": "Nm·s/rad", "offset": "Nm", "cp": "Nm/rad"},
         "linear": {"J": "kg", "c0": "N", "c1": "N·s/m", "offset": "N", "cp": "N/m"}}


def _fmt(v) -> str:
    return f"{v:.6g}" if isinstance(v, (float, np.floating)) else str(v)


def summary(results: dict[str, AxisResult]) -> str:
    lines = []
    for axis, r in results.items():
        u = UNITS[r.kind]
        tu = r.units["torque"]
        lines.append(f"axis {axis} ({r.kind}; cut-off {r.settings.cutoff_hz:.1f} Hz, decimation "
                     f"{r.settings.decimation}, {int(r.est.moving.sum())} moving samples fitted; "
                     f"validation: {r.validation})")
        std = r.model.param_std_
        for k in ("J", "c0", "c1"):
            v = r.model.params_[k]
            rel = abs(std[k] / v) * 100 if v else float("inf")
            lines.append(f"  {k:<3} = {v:.6g} ± {std[k]:.2g} {u[k]}  ({rel:.2f} %)")
        lines.append(f"  base model J, c0, c1: validation RMSE {r.before.rmse:.4g} {tu} "
                     f"(relative error {r.before.relative_error:.2%})")
        for t in r.effects:
            p = ", ".join(f"{k} {_fmt(v)}" for k, v in t.params.items())
            lines.append(f"  + {t.effect.name} [{t.effect.depends_on}] ({p})")
            lines.append(f"      {t.evidence}")
        if not r.effects:
            lines.append("  no effect found beyond J, c0, c1")
        lines.append(f"  final: validation RMSE {r.after.rmse:.4g} {tu} (measured torque RMS {r.after.torque_rms:.4g}, "
                     f"noise floor {r.noise_floor:.3g}); relative error {r.after.relative_error:.2%}")
        lines.append(f"  GA (differential evolution) on the same data: validation RMSE {r.ga_errors.rmse:.4g} "
                     f"{tu}, J {r.ga_coef[0]:.6g}, c1 {r.ga_coef[1]:.6g}, c0 {r.ga_coef[2]:.6g}")
        for u_ in r.unexplained:
            lines.append(f"  unexplained: {describe_unexplained(u_)}")
        for d in r.dropped:
            lines.append(f"  dropped: {d}")
        if r.sampling.get("resampled"):
            lines.append(f"  {sampling_text(r.sampling)}")
        if r.sampling.get("torque_aligned") or r.sampling.get("torque_delay_note"):
            lines.append(f"  {delay_text(r.sampling)}")
        if r.consistency and not r.consistency["consistent"]:
            lines.append(f"  NOT CONSISTENT: {consistency_text(r.consistency)}")
    return "\n".join(lines)


def consistency_text(c: dict) -> str:
    """Which parameters moved between parts of the data, and by how much."""
    return "; ".join(f"{p} differs between the {m['between'][0]} and the {m['between'][1]} by {m['sigmas']:.3g} std ("
                     + ", ".join(f"{n} {v:.4g}" for n, v in m["values"].items()) + ")"
                     for p, m in c["moved"].items()) + \
        ": the data hold more than one value (a payload change, a warm-up, or structure the model lacks)"


def sampling_text(s: dict) -> str:
    """What the time stamps held and what was done about it, in one sentence."""
    return (f"time stamps not evenly spaced (steps off the median {s['period_s'] * 1e3:.3f} ms by up to "
            f"{s['max_step_deviation_s'] * 1e6:.0f} µs, std {s['jitter_std_s'] * 1e6:.0f} µs; {s['gaps']} gap(s) "
            f"split the log): resampled onto a uniform {s['period_s'] * 1e3:.3f} ms grid, position and torque "
            f"through the same cubic spline")


def delay_text(s: dict) -> str:
    """How the torque was (or was not) aligned with the position, in one sentence."""
    if not s["torque_aligned"]:
        d = s["torque_delay_estimate_ms"]
        return (f"the logged torque {'lags' if d > 0 else 'leads'} the position by {abs(d):.3g} ms by the estimate "
                f"(± {s['torque_delay_std_ms']:.2g} ms); {s['torque_delay_note']}")
    d = s["torque_delay_ms"]
    how = (f"estimated, ± {s['torque_delay_std_ms']:.2g} ms" if s["torque_delay_source"] == "estimated"
           else "as given")
    return (f"the logged torque {'lags' if d > 0 else 'leads'} the position by {abs(d):.3g} ms ({how}): the "
            f"positions were read at the instants the torque stands for")


def as_json(results: dict[str, AxisResult]) -> str:
    return json_text(stamped("identify", {"axes": {a: r.as_json() for a, r in results.items()}}))


def _plot_fit(r: AxisResult, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    s = r.val
    m = s.moving
    t = s.t
    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    for ax, model, title in ((axes[0], r.base, "base model J, c0, c1"), (axes[1], r.model, "final model")):
        pred = np.where(m, model.predict(s, logged=True), np.nan)
        ax.plot(t, s.tau, ".", ms=1.5, color="0.6", label="measured (as logged)")
        ax.plot(t, pred, ".", ms=1.5, color="C0", label="predicted")
        err = r.before if model is r.base else r.after
        ax.set_title(f"axis {r.axis}, {title}: validation RMSE {err.rmse:.4g} {r.units['torque']}")
        ax.set_ylabel(f"torque [{r.units['torque']}]")
        ax.legend(loc="upper right", markerscale=6)
    axes[1].set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _variable(r: AxisResult, depends_on: str) -> tuple[np.ndarray, str]:
    s = r.est
    pos = r.units["position"]
    table = {"position": (s.q, f"position [{pos}]"), "velocity": (s.qd, f"velocity [{pos}/s]"),
             "direction": (s.qd, f"velocity [{pos}/s]"), "time": (s.t, "time [s]"),
             "constant": (s.qd, f"velocity [{pos}/s]"), "acceleration": (s.qdd, f"acceleration [{pos}/s²]"),
             "abs_acceleration": (np.abs(s.qdd), f"|acceleration| [{pos}/s²]")}
    if depends_on in table:
        return table[depends_on]
    other, kind = depends_on.rsplit("_", 1)
    q, qd, qdd = s.others[other]
    return {"position": q, "velocity": qd, "acceleration": qdd}[kind], f"axis {other} {kind}"


def _plot_effect(r: AxisResult, k: int, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    t = r.effects[k]
    before = AxisModel(r.model.effects[:k]).fit(r.est)
    after = AxisModel(r.model.effects[:k + 1]).fit(r.est)
    s, m = r.est, r.est.moving
    x, label = _variable(r, t.effect.depends_on)
    resid = (s.tau_f - before.predict(s))[m]
    contribution = (after.predict(s) - before.predict(s))[m]
    fig, ax = plt.subplots(figsize=(8, 4.5))
    ax.plot(x[m], resid, ".", ms=1.5, color="0.6", label=f"residual before {t.effect.name}")
    order = np.argsort(x[m])
    ax.plot(x[m][order], contribution[order], ".", ms=1.5, color="C3", label=f"{t.effect.name}, fitted")
    ax.set_xlabel(label)
    ax.set_ylabel(f"torque [{r.units['torque']}]")
    ax.set_title(f"axis {r.axis}: {t.effect.name} ({t.effect.depends_on})")
    ax.legend(loc="upper right", markerscale=6)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def write_markdown(results: dict[str, AxisResult], out: Path, source: str) -> Path:
    """``out/identify.md`` with its plots beside it."""
    out.mkdir(parents=True, exist_ok=True)
    md = [f"# Identification of {source}", ""]
    for axis, r in results.items():
        u, tu = UNITS[r.kind], r.units["torque"]
        md += [f"## Axis {axis} ({r.kind})", "",
               f"Cut-off {r.settings.cutoff_hz:.1f} Hz (motion bandwidth {r.settings.motion_bandwidth_hz:.2f} Hz), "
               f"decimation {r.settings.decimation}, {int(r.est.moving.sum())} moving samples fitted. "
               f"Validation: {r.validation}.", "",
               "| parameter | LSE | std | rel. std | GA |", "| --- | --- | --- | --- | --- |"]
        for i, name in enumerate(r.model.coef_names):
            v = r.model.coef_[i]
            sd = float(np.sqrt(r.model.cov_[i, i]))
            md.append(f"| {name} {u.get(name, '')} | {v:.6g} | {sd:.2g} | {abs(sd / v) * 100 if v else 0:.2f} % "
                      f"| {r.ga_coef[i]:.6g} |")
        md += ["", f"Condition number {r.model.cond_:.1f}; residual std {r.model.sigma_:.4g} {tu}; "
               f"GA validation RMSE {r.ga_errors.rmse:.4g} {tu} (LSE {r.after.rmse:.4g}).", "",
               "| model | validation RMSE (logged torque) | relative error (filtered) |", "| --- | --- | --- |",
               f"| J, c0, c1 | {r.before.rmse:.4g} {tu} | {r.before.relative_error:.2%} |"]
        names = []
        for t in r.effects:
            names.append(t.effect.name)
            md.append(f"| + {' + '.join(names)} | {t.rmse_after:.4g} {tu} | {t.relative_error_after:.2%} |")
        md += ["", f"Measured torque RMS on the same samples {r.after.torque_rms:.4g} {tu}; "
               f"noise floor {r.noise_floor:.3g} {tu}.", ""]
        fit_png = out / f"{axis}_fit.png"
        _plot_fit(r, fit_png)
        md += [f"![measured vs predicted torque, axis {axis}]({fit_png.name})", ""]
        for k, t in enumerate(r.effects):
            png = out / f"{axis}_effect{k + 1}_{t.effect.name}.png"
            _plot_effect(r, k, png)
            md += [f"### {t.effect.name} (depends on {t.effect.depends_on})", "", t.evidence, "",
                   f"![{t.effect.name}]({png.name})", ""]
        if r.unexplained:
            md += ["Unexplained structure left in the residual:", ""]
            md += [f"- {describe_unexplained(x)}" for x in r.unexplained]
            md.append("")
        if r.dropped:
            md += ["Dropped from the log:", ""] + [f"- {d}" for d in r.dropped] + [""]
        if r.sampling.get("resampled"):
            md += [sampling_text(r.sampling)[0].upper() + sampling_text(r.sampling)[1:] + ".", ""]
        if r.sampling.get("torque_aligned") or r.sampling.get("torque_delay_note"):
            md += [delay_text(r.sampling)[0].upper() + delay_text(r.sampling)[1:] + ".", ""]
        if r.consistency and not r.consistency["consistent"]:
            md += [f"**Not consistent:** {consistency_text(r.consistency)}.", ""]
    path = out / "identify.md"
    write_text(out / "identify.json", as_json(results))
    write_text(path, "\n".join(md))
    return path
