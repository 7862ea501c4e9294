"""``report.html`` and ``report.md``: the commissioning record a person reads and signs, the same
content twice (:mod:`drive_bridge.document`): one self-contained page, and Markdown with its
figures beside it for a ticket or a wiki.

Built from ``summary.json``'s content and the run directory: the verdict, status and steps; per
axis the identified parameters with uncertainty beside the paper's, each traced effect with its
evidence plot and the error before → after, the gains before and after with their margins and
loop pictures, the validation (following error, overshoot, settling, model torque error, before
and after, with what got worse explained) and its plots, and the objects written and verified.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..document import Document, Strong, measured, number
from ..figures import pyplot, save, side_by_side
from ..ident.presentation import unit
from ..ident.trace import describe_unexplained
from ..params.controller import Controller
from ..tuning.loops import predicted_following_error
from . import steps as step_functions
from .verdict import reasons
from .worse import worse

REPORT = "report.html"
REPORT_MD = "report.md"
FIGURES = "figures"  # the validation plots the report draws (the others are the steps')
#: the cascade's gains, SI motor side (rotary; a linear axis reads m for rad)
GAIN_UNITS = {"KpP": "1/s", "FwF": "1", "KpS": "Nm·s/rad", "KiS": "1/s", "KpC": "V/A", "KiC": "1/s"}


def _milli(v: float | None, fmt: str = ".3g") -> str:
    return number(None if v is None else v * 1e3, fmt)


def _validation_png(
    traces: Mapping[str, np.ndarray], axis: str, traj: str, path: Path, loop: dict | None
) -> Path | None:
    """Following error before and after (each on its own scale, with what the identified model and
    the gains predict for it where ``loop`` gives them: tune.json's model, motor and gains, and
    whether the after run fed the model torque forward), position, velocity, torque."""
    plt = pyplot()
    keys = {sc: f"{sc}/{traj}/{axis}" for sc in ("before", "after")}
    if f"{keys['after']}/t" not in traces:
        return None
    fig, (fe_b, fe_a, pos, vel, tq) = plt.subplots(5, 1, figsize=(11, 10), sharex=True)
    for sc, color, ax in (("before", "C1", fe_b), ("after", "C0", fe_a)):
        k = keys[sc]
        if f"{k}/t" not in traces:
            continue
        t = traces[f"{k}/t"]
        fe = (traces[f"{k}/demand"] - traces[f"{k}/position"]) * 1e3
        ax.plot(t, fe, color=color, lw=0.8, label=f"measured, RMS {np.sqrt(np.nanmean(fe**2)):.3g} mrad")
        if loop is not None:
            gains = loop["gains_before" if sc == "before" else "gains"]
            model_fe = 1e3 * predicted_following_error(
                loop["model"],
                gains,
                loop["motor"]["L"],
                sc == "after" and loop["feedforward"],
                t,
                traces[f"{k}/demand"],
                Controller.from_dict(loop.get("controller")).timing.tick_s,
            )
            ax.plot(
                t,
                model_fe,
                color="k",
                lw=0.7,
                ls="--",
                label=f"model, RMS {np.sqrt(np.mean(model_fe**2)):.3g} mrad",
            )
        ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
        ax.set_ylabel(f"FE {sc} [mrad]")  # each on its own scale: the after trace has a shape
        dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
        vel.plot(t, np.gradient(traces[f"{k}/position"], dt), color=color, lw=0.8, label=f"measured ({sc})")
        tq.plot(t, traces[f"{k}/torque"], color=color, lw=0.8, label=sc)
        if sc == "after":
            pos.plot(t, traces[f"{k}/demand"], color="0.5", lw=1.5, label="demand")
            pos.plot(t, traces[f"{k}/position"], color=color, lw=0.8, ls="--", label="measured (after)")
            vel.plot(t, np.gradient(traces[f"{k}/demand"], dt), color="0.5", lw=1.5, zorder=0, label="demand")
    pos.set_ylabel("position [rad]")
    vel.set_ylabel("velocity [rad/s]")
    tq.set_ylabel("torque [Nm]")
    tq.set_xlabel("time [s]")
    for ax in (pos, vel, tq):
        ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
    for ax in (fe_b, fe_a, pos, vel, tq):
        ax.grid(True, alpha=0.3)
    fe_b.set_title(
        f"axis {axis}, {traj.replace('_', '-')}: following error before and after commissioning "
        f"(own scales), position, velocity and torque"
    )
    fig.subplots_adjust(left=0.07, right=0.79, bottom=0.05, top=0.96, hspace=0.12)
    return save(fig, path)


def _model(doc: Document, out: Path, axis: str, a: dict) -> None:
    u = a["units"]["torque"]
    kind = "rotary" if a["units"]["position"] == "rad" else "linear"
    rows = []
    for k, v in a["params"].items():
        sd = a["param_std"].get(k)
        paper = (a.get("paper") or {}).get(k)
        rows.append(
            [
                k,
                measured(v, sd) if isinstance(v, float) else number(v, ".4g"),
                number(sd, ".2g"),
                unit(k, kind),
                number(paper and paper["paper"], ".6g"),
                number(paper and paper["deviation_pct"], "+.1f") + (" %" if paper else ""),
            ]
        )
    doc.heading(2, "Identified model")
    doc.table(["parameter", "value", "std", "unit", "paper (Table II)", "deviation"], rows)
    doc.para(
        f"Validation ({a['identify_validation']}): RMSE {number(a['rmse_before'], '.4g')} → {number(a['rmse_after'], '.4g')} {u} "
        f"(relative error {number(a['relative_error_before'] * 100, '.2f')} % → "
        f"{number(a['relative_error_after'] * 100, '.2f')} %); noise floor {number(a['noise_floor'], '.3g')} {u}. "
        f"Differential evolution on the same data: RMSE {number(a['ga']['rmse'], '.4g')} {u}."
    )
    doc.figure(
        out / step_functions.OUTPUT["identify"] / f"{axis}_fit.png",
        f"axis {axis}: measured and predicted torque",
    )
    if (out / step_functions.OUTPUT["identify"] / f"{axis}_response.png").exists():
        doc.figure(
            out / step_functions.OUTPUT["identify"] / f"{axis}_response.png",
            f"axis {axis}: the plant's response read from the campaign log beside the rigid model's "
            f"(reference; the measure step's response is the one the margins use)",
        )
    if not a["effects"]:
        doc.para("No effect found beyond J, c0, c1.")
    else:
        doc.heading(2, "Traced effects")
    for k, eff in enumerate(a["effects"]):
        p = ", ".join(f"{n} = {number(v, '.5g')}" for n, v in eff["params"].items())
        doc.heading(3, f"{k + 1}. {eff['name']} (depends on {eff['depends_on']})")
        doc.para(
            f"{p}. Error after adding it: RMSE {number(eff['rmse_after'], '.4g')} {u}, relative error "
            f"{number(eff['relative_error_after'] * 100, '.2f')} %."
        )
        doc.para(eff["evidence"], "note")
        doc.figure(
            out / step_functions.OUTPUT["identify"] / f"{axis}_effect{k + 1}_{eff['name']}.png", eff["name"]
        )
    for un in a.get("unexplained") or []:
        doc.para(f"Unexplained: {describe_unexplained(un)}.")


def _gains(doc: Document, out: Path, axis: str, a: dict) -> None:
    before, after = a["gains_before"], a["gains_after"]
    doc.heading(2, "Gains")
    doc.table(
        ["gain", "unit", "before", "after"],
        [
            [g, GAIN_UNITS.get(g, ""), number(before.get(g), ".4g"), number(v, ".4g")]
            for g, v in after.items()
        ],
    )
    rows = []
    for loop in ("velocity", "position"):
        m, mb = a["margins"][loop], (a["margins_before"] or {}).get(loop) or {}
        rows.append(
            [
                loop,
                number(mb.get("phase_margin_deg"), ".1f"),
                number(m["phase_margin_deg"], ".1f"),
                number(mb.get("gain_margin_db"), ".1f"),
                number(m["gain_margin_db"], ".1f"),
                number(mb.get("crossover_hz"), ".0f"),
                number(m["crossover_hz"], ".0f"),
            ]
        )
    doc.table(
        [
            "loop",
            "PM before [°]",
            "PM after [°]",
            "GM before [dB]",
            "GM after [dB]",
            "crossover before [Hz]",
            "crossover after [Hz]",
        ],
        rows,
    )
    doc.figure(
        out / step_functions.LOOPS.format(axis=axis), f"axis {axis} loops: Bode plots and step response"
    )
    tuned = _tuned(out, axis) or {}
    c = Controller.from_dict(tuned.get("controller"))
    rates = ", ".join(f"{k} {v:g} Hz" for k, v in c.rates_hz.items() if v)
    doc.para(
        f"Designed for the drive's {c.structure.replace('_', ' ')} ({rates})"
        + (f"; not documented: {', '.join(c.unverified())} (the profile's reading)" if c.unverified() else "")
        + (
            ". Written as the position PID that is this cascade (D = KpS, P = KpS·(KpP + KiS), "
            "I = KpS·KiS·KpP), its feed-forward the model's c1 and J."
            if c.structure == "position_pid"
            else "."
        )
    )
    if tuned.get("mode"):
        m = tuned["mode"]
        doc.para(f"A mode at {number(m['frequency_hz'], '.1f')} Hz ({m['source']}): {m['handling']}.")


def _tuned(out: Path, axis: str) -> dict | None:
    """``axis`` in tune.json; None where it cannot be read."""
    try:
        return json.loads((out / step_functions.OUTPUT["tune"]).read_text())["axes"][axis]
    except (OSError, ValueError, KeyError):
        return None


def _loop(out: Path, axis: str, a: dict) -> dict | None:
    """What predicts the following error of ``axis``: tune.json's model, motor and gains, and
    whether the after runs fed the model torque forward."""
    t = _tuned(out, axis)
    if t is None or not t.get("motor", {}).get("L") or not t.get("gains_before"):
        return None
    ff = all((v.get("feedforward") or "none") != "none" for v in a["validation"].values())
    return {**t, "feedforward": ff}


def _validation_figures(
    out: Path, summary: dict, loops: dict[str, dict | None]
) -> dict[tuple[str, str], Path | None]:
    """(axis, trajectory) -> its validation figure, drawn into ``out`` with what ``loops`` predict;
    side by side where work is shared out (:func:`..figures.side_by_side`)."""
    path = out / step_functions.TRACES
    jobs = [(axis, t) for axis in loops for t in summary["axes"][axis]["validation"]]
    if not jobs or not path.exists():
        return {}
    with np.load(path) as npz:
        traces = dict(npz)  # in memory: a forked process must not read the file's handle
    return dict(zip(jobs, side_by_side(_draw_validation, jobs, (traces, out, loops))))


def _draw_validation(
    shared: tuple[Mapping[str, np.ndarray], Path, dict], job: tuple[str, str]
) -> Path | None:
    traces, out, loops = shared
    axis, traj = job
    return _validation_png(traces, axis, traj, out / FIGURES / f"{axis}_{traj}.png", loops[axis])


def _validation(
    doc: Document, axis: str, a: dict, loop: dict | None, drawn: Mapping[tuple[str, str], Path | None]
) -> None:
    rows = [
        [
            t.replace("_", "-"),
            _milli(v["fe_rms_before"]),
            _milli(v["fe_rms_after"]),
            number(v["improvement"], ".1f") + "×",
            _milli(v["fe_max_before"]),
            _milli(v["fe_max_after"]),
            number(v.get("overshoot_pct_before"), ".2f"),
            number(v["overshoot_pct_after"], ".2f"),
            _milli(v.get("settling_s_before"), ".0f"),
            _milli(v["settling_s_after"], ".0f"),
            _milli(v["torque_rmse_before"]),
            _milli(v["torque_rmse_after"]),
        ]
        for t, v in a["validation"].items()
    ]
    doc.heading(2, "Validation on reference trajectories")
    doc.table(
        [
            "trajectory",
            "FE RMS before [mrad]",
            "after",
            "improvement",
            "FE max before [mrad]",
            "after",
            "overshoot before [%]",
            "after",
            "settling before [ms]",
            "after",
            "model torque RMSE before [mNm]",
            "after",
        ],
        rows,
    )
    notes = worse(a)
    if notes:
        doc.para([Strong("Worse after commissioning, and why:")])
        doc.bullets(notes)
    if loop is not None:
        doc.para(
            "The dashed lines: the following error the identified model and the gains predict along the same "
            "demand (the linear cascade with the model's other torques as a disturbance, "
            "drive_bridge/tuning/loops.py). After commissioning it gets the size, not the shape: what is left "
            "sits at the acceleration steps, where the drive's sampling decides.",
            "note",
        )
    for t in a["validation"]:
        png = drawn.get((axis, t))
        if png:
            doc.figure(png, f"axis {axis} {t}: following error, position, velocity, torque")


def _written(doc: Document, a: dict) -> None:
    rows = [
        [
            w["parameter"],
            w["object"],
            number(w["old"], ".6g"),
            number(w["new"], ".6g"),
            w["unit"],
            f"{number(w['old_device'], '.6g')} → {number(w['new_device'], '.6g')}",
            "verified" if w["verified"] else Strong("NOT verified"),
        ]
        for w in a["written"]
    ]
    doc.heading(2, "Objects written")
    doc.table(["parameter", "object", "old", "new", "unit", "device units", "read back"], rows)
    doc.para(
        ("Stored to non-volatile memory (0x1010 save)." if a["stored"] else "Not stored.")
        + (
            f" Not supported by the drive, not written: {', '.join(a['unsupported'])}."
            if a["unsupported"]
            else ""
        )
    )


def _verdict(doc: Document, v: dict) -> None:
    style = {"PASS": "ok", "WARN": "partial", "INCOMPLETE": "partial", "FAIL": "failed"}
    doc.para([Strong(f"Verdict: {v['overall']}")], style[v["overall"]])
    doc.table(
        ["axis", "verdict", "criteria not met"],
        [
            [Strong(a), Strong(x["verdict"]), reasons(x) or "every criterion met"]
            for a, x in v["axes"].items()
        ],
    )
    acc = v["acceptance"]
    doc.para(
        f"Criteria: velocity and position loop PM ≥ {acc['min_phase_margin_deg']:g}°, GM ≥ "
        f"{acc['min_gain_margin_db']:g} dB and following error ≥ {acc['min_fe_improvement']:g}× better than the "
        f"factory set on every validation trajectory (FAIL when not met); model torque RMSE ≤ "
        f"{acc['max_rmse_over_noise']:g}× the noise floor, relative std of J, c0, c1 ≤ "
        f"{acc['max_relative_std']:.0%}, identification consistent (WARN); bus.yml 'acceptance' sets them.",
        "note",
    )


def _status(doc: Document, summary: dict) -> None:
    status = summary["status"]
    if status == "failed":
        f = summary["failed"]
        doc.para([Strong("FAILED"), " in step ", Strong(f["step"]), f": {f['reason']}"], "failed")
    elif status == "ok":
        doc.para([Strong("OK"), ": every step completed."], "ok")
    elif status == "degraded":
        doc.para(
            [
                Strong("DEGRADED TIMING"),
                ": every step completed, but " + "; ".join(summary["timing_degraded"]),
            ],
            "partial",
        )
    else:
        doc.para([Strong("PARTIAL"), ": the steps run succeeded; some were not run."], "partial")


def build_report(out: Path, summary: dict, figures: bool = True) -> Document:
    """The commissioning report of the run in ``out`` (with ``figures``: the validation and trend
    figures drawn into it).

    Parameters
    ----------
    out : Path
        The run directory.
    summary : dict
        Its summary.json.
    figures : bool
        Draw the figures.

    Returns
    -------
    Document
        The report, not yet written.
    """
    from ..history.since import history_note, report_section, trend_figures

    doc = Document("Commissioning report", figures=figures)
    _verdict(doc, summary["verdict"])
    _status(doc, summary)
    doc.para(
        f"Bus configuration {summary['config']}{' (simulated robot)' if summary['simulated'] else ''}; "
        f"drive profile {summary['profile']}; run directory {summary['out']}."
    )
    history_note(doc, summary.get("history"))
    doc.table(
        ["step", "status", "duration [s]"],
        [[s["name"], s["status"], number(s["duration_s"], ".1f")] for s in summary["steps"]],
    )
    loops = {axis: _loop(out, axis, a) for axis, a in summary["axes"].items() if a and a.get("validation")}
    drawn = _validation_figures(out, summary, loops) if figures else {}
    trends = trend_figures(out, summary.get("history")) if figures else {}
    for axis, a in summary["axes"].items():
        if not a:
            continue
        doc.heading(1, f"Axis {axis}")
        if "params" in a:
            _model(doc, out, axis, a)
        report_section(doc, summary.get("history"), axis, trends)
        if "gains_after" in a:
            _gains(doc, out, axis, a)
        if a.get("validation"):
            _validation(doc, axis, a, loops[axis], drawn)
        if "written" in a:
            _written(doc, a)
    doc.para(", ".join(f"{k} {v}" for k, v in summary["versions"].items()), "note")
    return doc


def write_report(out: Path, summary: dict, figures: bool = True) -> Path:
    """``report.html`` and ``report.md`` (figures in the run directory, where drawn); the HTML's path.

    Parameters
    ----------
    out : Path
        The run directory.
    summary : dict
        Its summary.json.
    figures : bool
        Draw the figures.

    Returns
    -------
    Path
        report.html.
    """
    return build_report(out, summary, figures).write(out / REPORT, out / REPORT_MD)[0]
