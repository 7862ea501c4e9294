"""The commissioning report's "since last time": each axis's parameters against the same drive's
previous commissioning and its siblings (:mod:`.compare`), with trend plots, kept in
``summary.json`` under ``history``."""

from __future__ import annotations

from pathlib import Path

from ..document import Document, Strong, measured, number
from ..figures import pyplot, save, side_by_side
from .compare import SIGMAS, SPREADS, THRESHOLD, History, compare_one, drive_name
from .outbox import Kept
from .record import identity_number
from .store import HistoryStore, HistoryUnavailable

TRENDED = ("J", "c0", "c1")  # the parameters the trend plots show
FIGURE = "figures/history_{axis}.png"


def since_last_time(record: dict, kept: Kept, db: str | None) -> dict:
    """``summary.json``'s ``history``: where the record went and, per axis whose drive has history
    in the database, its comparisons and the series of the trended parameters (none where Ctrl-C
    came while the history was read back: ``interrupted``).

    Parameters
    ----------
    record : dict
        This run's record.
    kept : Kept
        Where it went.
    db : str, optional
        The database URL.

    Returns
    -------
    dict
        Where the record went (``database``, ``run_id``, ``kept``, ``outbox``, ``reason``,
        ``interrupted``) and ``axes``: per axis its drive's serial, comparisons, what is named and
        the series.
    """
    doc: dict = {
        "database": kept.database,
        "run_id": kept.run_id,
        "kept": kept.stored,
        "outbox": None if kept.outbox is None else str(kept.outbox),
        "reason": kept.reason,
        "interrupted": kept.interrupted,
        "axes": {},
    }
    if not kept.stored:
        return doc
    try:
        store = HistoryStore(db)
        try:
            history = History(store.parameters())
        finally:
            store.close()
    except HistoryUnavailable as exc:
        doc["reason"] = f"the history could not be read back: {exc}"
        return doc
    except KeyboardInterrupt:  # the run is kept: the report is written without the comparison
        doc.update(interrupted=True, reason="interrupted (Ctrl-C) while the history was read back")
        return doc
    for a in record["axes"]:
        drive = a.get("drive")
        if not drive or not a.get("parameters"):
            continue
        key = (
            record["simulated"],
            *(identity_number(drive.get(k)) for k in ("vendor_id", "product_code", "serial")),
            a["axis"],
        )
        comparisons = compare_one(history, key, record["run_id"])
        if not any(c.previous is not None or c.siblings for c in comparisons):
            continue  # the drive's first commissioning, and no siblings yet
        doc["axes"][a["axis"]] = {
            "serial": drive.get("serial"),
            "comparisons": [c.as_dict() for c in comparisons],
            "named": [c.words() for c in comparisons if c.named],
            "series": {
                name: [
                    {
                        "when": r.started.isoformat(),
                        "value": r.value,
                        "std": r.std,
                        "determined": r.determined,
                        "run_id": r.run_id,
                    }
                    for r in history.series(key, name)
                ]
                for name in TRENDED
            },
        }
    return doc


def _trend_png(axis: str, entry: dict, path: Path) -> Path:
    """Each trended parameter over the drive's commissionings (±1 std; undetermined values hollow),
    the siblings' median and spread as a band."""
    plt = pyplot()
    fig, panels = plt.subplots(1, len(TRENDED), figsize=(12, 3.2))
    comps = {c["parameter"]: c for c in entry["comparisons"]}
    for ax, name in zip(panels, TRENDED):
        series = entry["series"].get(name) or []
        for determined in (True, False):
            pts = [(i, s) for i, s in enumerate(series) if s["determined"] == determined]
            if pts:
                ax.errorbar(
                    [i for i, _ in pts],
                    [s["value"] for _, s in pts],
                    yerr=[s["std"] or 0.0 for _, s in pts],
                    fmt="o-" if determined else "o",
                    ms=5,
                    capsize=3,
                    mfc=None if determined else "none",
                    color="C0" if determined else "0.5",
                    label="this drive" if determined else "undetermined",
                )
        days = [s["when"][:10] for s in series]
        labels = days if len(set(days)) == len(days) else [s["when"][5:16].replace("T", " ") for s in series]
        ax.set_xticks(range(len(series)), labels, rotation=30, fontsize=8)
        c = comps.get(name)
        if c and c["siblings_median"] is not None:
            m, s = c["siblings_median"], c["siblings_spread"]
            ax.axhspan(
                m - s, m + s, color="C2", alpha=0.2, label=f"{c['siblings']} siblings: median ± spread"
            )
            ax.axhline(m, color="C2", lw=1)
        ax.set_title(f"{name} [{c['unit'] if c else ''}]", fontsize=10)
        ax.grid(True, alpha=0.3)
    panels[0].legend(fontsize=8)
    fig.suptitle(
        f"axis {axis}, {drive_name(identity_number(entry['serial']))}: identified parameters at each "
        f"commissioning"
    )
    fig.subplots_adjust(left=0.07, right=0.99, bottom=0.25, top=0.84, wspace=0.3)
    return save(fig, path)


def trend_figures(out: Path, history: dict | None) -> dict[str, Path]:
    """Every axis's trend plot (drawn side by side where work is shared out).

    Parameters
    ----------
    out : Path
        The directory they are drawn into.
    history : dict or None
        :func:`since_last_time`'s answer.

    Returns
    -------
    dict of str to Path
        Per axis with a trend, its PNG.
    """
    axes = list((history or {}).get("axes", {}))
    return dict(zip(axes, side_by_side(_draw_trend, axes, (out, history))))


def _draw_trend(shared: tuple[Path, dict], axis: str) -> Path:
    out, history = shared
    return _trend_png(axis, history["axes"][axis], out / FIGURE.format(axis=axis))


def report_section(doc: Document, history: dict | None, axis: str, figures: dict[str, Path]) -> None:
    """The axis's "since last time": named changes, the comparison table, the trend plot.

    Parameters
    ----------
    doc : Document
        The report it is added to.
    history : dict or None
        :func:`since_last_time`'s answer.
    axis : str
        The axis.
    figures : dict of str to Path
        The trend plots (:func:`trend_figures`).
    """
    entry = (history or {}).get("axes", {}).get(axis)
    if entry is None:
        return
    doc.heading(2, "Since last time")
    named = entry["named"]
    doc.para(
        [Strong("Changed:"), " " + "; ".join(named)]
        if named
        else "Nothing changed beyond noise and the threshold, against the drive's previous commissioning or "
        "its siblings.",
        "failed" if named else "ok",
    )
    rows = []
    for c in entry["comparisons"]:
        prev = (
            "—"
            if c["previous"] is None
            else (f"{measured(c['previous'], c['previous_std'])} ({c['previous_when'][:10]})")
        )
        change = (
            "—" if c["relative"] is None else f"{c['relative'] * 100:+.1f} % ({number(c['sigmas'], '.2g')} σ)"
        )
        sib = (
            "—"
            if c["siblings_median"] is None
            else (
                f"{number(c['siblings_median'], '.4g')} ± "
                f"{number(c['siblings_spread'], '.2g')} "
                f"({c['siblings']}; {number(c['spreads'], '.2g')} spread)"
            )
        )
        rows.append(
            [
                Strong(c["parameter"]) if c["named"] else c["parameter"],
                measured(c["value"], c["std"]),
                c["unit"] or "",
                prev,
                change,
                sib,
            ]
        )
    doc.table(
        ["parameter", "now", "unit", "previous commissioning", "change", "siblings: median ± spread"], rows
    )
    if axis in figures:  # (not drawn: --no-figures)
        doc.figure(figures[axis], f"axis {axis}: trend")
    doc.para(
        f"A change is named at ≥ {SIGMAS:g} combined std and ≥ {THRESHOLD:.0%} since the previous "
        f"commissioning, or ≥ {SPREADS:g} spreads and ≥ {THRESHOLD:.0%} from the siblings' median (same drive "
        f"type and axis role).",
        "note",
    )


def history_note(doc: Document, history: dict | None) -> None:
    """Where this run's record went (the database, or the outbox and why).

    Parameters
    ----------
    doc : Document
        The report it is added to.
    history : dict or None
        :func:`since_last_time`'s answer.
    """
    if history is None:
        return
    if history["kept"]:
        doc.para(f"History: run {history['run_id']} kept in {history['database']}.", "note")
    else:
        doc.para(
            [
                Strong("History: "),
                f"the database {history['database']} was unreachable ({history['reason']}); "
                f"this run's record waits in {history['outbox']} and 'drive-bridge history sync' sends it.",
            ],
            "partial",
        )
