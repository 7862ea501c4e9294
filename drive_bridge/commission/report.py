"""``report.html``: the commissioning record a person reads, one self-contained file.

Built from ``summary.json``'s content and the run directory (plots are embedded as
PNG data): status and steps; per axis the identified parameters with uncertainty beside
the paper's, each traced effect with its evidence plot and the error before → after, the
gains before and after with their margins, the validation plots (following error and
torque, before vs after) and the objects written and verified.
"""
from __future__ import annotations

import base64
import html
import io
from pathlib import Path

import numpy as np

from ..ident.trace import describe_unexplained
from ..outputs import write_text
from . import steps as S

REPORT = "report.html"
UNITS = {"J": "kg·m²", "c0": "Nm", "c1": "Nm·s/rad", "offset": "Nm", "cp": "Nm/rad", "dc0": "Nm",
         "dc1": "Nm·s/rad", "amplitude": "Nm", "period": "rad", "phase": "rad"}
CSS = """body{font-family:system-ui,sans-serif;max-width:1100px;margin:1.5em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:.6em 0}td,th{border:1px solid #ccc;padding:.25em .6em;text-align:right}
th{background:#f2f2f2}td:first-child,th:first-child{text-align:left}img{max-width:100%;margin:.4em 0}
.ok{background:#e3f4e3;border:1px solid #7c7;padding:.6em 1em}.failed{background:#fbe3e3;border:1px solid #d77;
padding:.6em 1em}.partial{background:#fff5d6;border:1px solid #db5;padding:.6em 1em}.yes{color:#080}.no{color:#b00}
.evidence{color:#555;font-size:.92em}h2{border-bottom:2px solid #ddd;margin-top:1.6em}"""


#: the cascade's gains, SI motor side (rotary; a linear axis reads m for rad)
GAIN_UNITS = {"KpP": "1/s", "FwF": "1", "KpS": "Nm·s/rad", "KiS": "1/s", "KpC": "V/A", "KiC": "1/s"}

def _e(x) -> str:
    return html.escape(str(x))


def _n(v, fmt=".4g") -> str:
    if v is None:
        return "–"
    return format(v, fmt) if isinstance(v, (int, float)) else _e(v)


def _table(head: list[str], rows: list[list]) -> str:
    h = "".join(f"<th>{_e(c)}</th>" for c in head)
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><tr>{h}</tr>{body}</table>"


def _img(png: bytes, alt: str) -> str:
    return f'<img alt="{_e(alt)}" src="data:image/png;base64,{base64.b64encode(png).decode()}">'


def _file_img(path: Path, alt: str) -> str:
    return _img(path.read_bytes(), alt) if path.exists() else ""


def _validation_png(traces, axis: str, traj: str) -> bytes | None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    keys = {sc: f"{sc}/{traj}/{axis}" for sc in ("before", "after")}
    if f"{keys['after']}/t" not in traces:
        return None
    fig, (fe_b, fe_a, pos, tq) = plt.subplots(4, 1, figsize=(10, 8.5), sharex=True)
    for sc, color, ax in (("before", "C1", fe_b), ("after", "C0", fe_a)):
        k = keys[sc]
        if f"{k}/t" not in traces:
            continue
        t = traces[f"{k}/t"]
        fe = (traces[f"{k}/demand"] - traces[f"{k}/position"]) * 1e3
        ax.plot(t, fe, color=color, lw=0.8)
        ax.set_ylabel(f"FE {sc} [mrad]")              # each on its own scale: the after trace has a shape
        tq.plot(t, traces[f"{k}/torque"], color=color, lw=0.8, label=sc)
        if sc == "after":
            pos.plot(t, traces[f"{k}/demand"], color="0.5", lw=1.5, label="demand")
            pos.plot(t, traces[f"{k}/position"], color=color, lw=0.8, ls="--", label="measured (after)")
    pos.set_ylabel("position [rad]")
    tq.set_ylabel("torque [Nm]")
    tq.set_xlabel("time [s]")
    for ax in (pos, tq):
        ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
    for ax in (fe_b, fe_a, pos, tq):
        ax.grid(True, alpha=0.3)
    fe_b.set_title(f"axis {axis}, {traj.replace('_', '-')}: following error before and after commissioning "
                   f"(own scales), position and torque")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=80)
    plt.close(fig)
    return buf.getvalue()


def _axis(out: Path, axis: str, a: dict, traces) -> str:
    parts = [f"<h2>Axis {_e(axis)}</h2>"]
    if "params" in a:
        u = a["units"]["torque"]
        rows = []
        for k, v in a["params"].items():
            sd = a["param_std"].get(k)
            paper = (a.get("paper") or {}).get(k)
            rows.append([_e(k), _n(v, ".6g"), _n(sd, ".2g"), _e(UNITS.get(k.split(".")[-1], "")),
                         _n(paper and paper["paper"], ".6g"),
                         _n(paper and paper["deviation_pct"], "+.1f") + (" %" if paper else "")])
        parts += ["<h3>Identified model</h3>",
                  _table(["parameter", "value", "std", "unit", "paper (Table II)", "deviation"], rows),
                  f"<p>Validation ({_e(a['identify_validation'])}): RMSE {_n(a['rmse_before'])} → {_n(a['rmse_after'])} {_e(u)}"
                  f" (relative error {_n(a['relative_error_before'] * 100, '.2f')} % → "
                  f"{_n(a['relative_error_after'] * 100, '.2f')} %); noise floor {_n(a['noise_floor'], '.3g')} {_e(u)}. "
                  f"Differential evolution on the same data: RMSE {_n(a['ga']['rmse'])} {_e(u)}.</p>",
                  _file_img(out / S.OUTPUT["identify"] / f"{axis}_fit.png", f"axis {axis} fit")]
        parts.append("<h3>Traced effects</h3>" if a["effects"] else "<p>No effect found beyond J, c0, c1.</p>")
        for k, eff in enumerate(a["effects"]):
            p = ", ".join(f"{_e(n)} = {_n(v, '.5g')}" for n, v in eff["params"].items())
            parts += [f"<h4>{k + 1}. {_e(eff['name'])} (depends on {_e(eff['depends_on'])})</h4>",
                      f"<p>{p}. Error after adding it: RMSE {_n(eff['rmse_after'])} {_e(u)}, relative error "
                      f"{_n(eff['relative_error_after'] * 100, '.2f')} %.</p>",
                      f"<p class='evidence'>{_e(eff['evidence'])}</p>",
                      _file_img(out / S.OUTPUT["identify"] / f"{axis}_effect{k + 1}_{eff['name']}.png", eff["name"])]
        for un in a.get("unexplained") or []:
            parts.append(f"<p>Unexplained: {_e(describe_unexplained(un))}.</p>")
    if "gains_after" in a:
        before, after = a["gains_before"], a["gains_after"]
        parts += ["<h3>Gains</h3>", _table(["gain", "unit", "before", "after"],
                                           [[_e(g), _e(GAIN_UNITS.get(g, "")), _n(before.get(g)), _n(v)]
                                            for g, v in after.items()])]
        rows = []
        for loop in ("velocity", "position"):
            m, mb = a["margins"][loop], (a["margins_before"] or {}).get(loop)
            rows.append([loop, _n(mb and mb["phase_margin_deg"], ".1f"), _n(m["phase_margin_deg"], ".1f"),
                         _n(mb and mb["gain_margin_db"], ".1f"), _n(m["gain_margin_db"], ".1f"),
                         _n(m["crossover_hz"], ".0f")])
        parts.append(_table(["loop", "PM before [°]", "PM after [°]", "GM before [dB]", "GM after [dB]",
                             "crossover after [Hz]"], rows))
        parts.append(_file_img(out / S.LOOPS.format(axis=axis), f"axis {axis} loops: Bode plots and step response"))
    if a.get("validation"):
        rows = [[_e(t.replace("_", "-")), _n(v["fe_rms_before"] and v["fe_rms_before"] * 1e3, ".3g"),
                 _n(v["fe_rms_after"] * 1e3, ".3g"), _n(v["improvement"], ".1f") + "×",
                 _n(v["fe_max_before"] and v["fe_max_before"] * 1e3, ".3g"), _n(v["fe_max_after"] * 1e3, ".3g"),
                 _n(v["overshoot_pct_after"], ".2f"), _n(v["settling_s_after"], ".3f"),
                 _n(v["torque_rmse_before"], ".3g"), _n(v["torque_rmse_after"], ".3g")]
                for t, v in a["validation"].items()]
        parts += ["<h3>Validation on reference trajectories</h3>",
                  _table(["trajectory", "FE RMS before [mrad]", "after", "improvement", "FE max before [mrad]", "after",
                          "overshoot after [%]", "settling after [s]", "model torque RMSE before [Nm]", "after"],
                         rows)]
        for t in a["validation"]:
            png = traces is not None and _validation_png(traces, axis, t)
            if png:
                parts.append(_img(png, f"axis {axis} {t}"))
    if "written" in a:
        rows = [[_e(w["parameter"]), _e(w["object"]), _n(w["old"], ".6g"), _n(w["new"], ".6g"), _e(w["unit"]),
                 f"{_n(w['old_device'], '.6g')} → {_n(w['new_device'], '.6g')}",
                 "<span class='yes'>verified</span>" if w["verified"] else "<span class='no'>not verified</span>"]
                for w in a["written"]]
        parts += ["<h3>Objects written</h3>",
                  _table(["parameter", "object", "old", "new", "unit", "device units", ""], rows),
                  f"<p>{'Stored to non-volatile memory (0x1010 save).' if a['stored'] else 'Not stored.'}"
                  + (f" Not supported by the drive, not written: {_e(', '.join(a['unsupported']))}."
                     if a["unsupported"] else "") + "</p>"]
    return "\n".join(p for p in parts if p)


def write_report(out: Path, summary: dict) -> Path:
    status = summary["status"]
    if status == "failed":
        f = summary["failed"]
        banner = f"<div class='failed'><b>FAILED</b> in step <b>{_e(f['step'])}</b>: {_e(f['reason'])}</div>"
    elif status == "ok":
        banner = "<div class='ok'><b>OK</b>: every step completed.</div>"
    elif status == "degraded":
        banner = ("<div class='partial'><b>DEGRADED TIMING</b>: every step completed, but "
                  + _e("; ".join(summary["timing_degraded"])) + "</div>")
    else:
        banner = "<div class='partial'><b>PARTIAL</b>: the steps run succeeded; some were not run.</div>"
    steps = _table(["step", "status", "duration [s]"],
                   [[_e(s["name"]), _e(s["status"]), _n(s["duration_s"], ".1f")] for s in summary["steps"]])
    v = summary["verdict"]
    css = {"PASS": "ok", "WARN": "partial", "INCOMPLETE": "partial", "FAIL": "failed"}
    verdict_rows = [[f"<b>{_e(a)}</b>", f"<b>{_e(x['verdict'])}</b>",
                     _e("; ".join(x["unmet"]) or ("not evaluated: " + ", ".join(x["not_evaluated"])
                                                 if x["not_evaluated"] else "every criterion met"))]
                    for a, x in v["axes"].items()]
    acc = v["acceptance"]
    verdict_html = (f"<div class='{css[v['overall']]}'><b>Verdict: {_e(v['overall'])}</b></div>"
                    + _table(["axis", "verdict", "criteria not met"], verdict_rows)
                    + f"<p class='evidence'>Criteria: velocity and position loop PM ≥ {acc['min_phase_margin_deg']:g}°, "
                      f"GM ≥ {acc['min_gain_margin_db']:g} dB and following error ≥ {acc['min_fe_improvement']:g}× "
                      f"better than the factory set on every validation trajectory (FAIL when not met); model "
                      f"torque RMSE ≤ {acc['max_rmse_over_noise']:g}× the noise floor, relative std of J, c0, c1 ≤ "
                      f"{acc['max_relative_std']:.0%}, identification consistent (WARN); bus.yml "
                      f"<code>acceptance</code> sets them.</p>")
    vers = ", ".join(f"{_e(k)} {_e(v)}" for k, v in summary["versions"].items())
    traces_path = out / S.TRACES
    traces = np.load(traces_path) if traces_path.exists() else None
    body = ["<h1>Commissioning report</h1>", verdict_html, banner,
            f"<p>Bus configuration {_e(summary['config'])}{' (simulated robot)' if summary['simulated'] else ''}; "
            f"drive profile {_e(summary['profile'])}; run directory {_e(summary['out'])}.</p>", steps,
            *(_axis(out, a, v, traces) for a, v in summary["axes"].items() if v),
            f"<p class='evidence'>{vers}</p>"]
    path = out / REPORT
    write_text(path, f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>drive-bridge commissioning"
                     f"</title><style>{CSS}</style></head><body>{''.join(body)}</body></html>")
    return path
