"""``tune``, ``write`` and ``validate``: gains from the identified models, the transactional write
of gains and model, and the reference trajectories."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TYPE_CHECKING

from ..document import number
from ..errors import UserError
from ..master.bringup import plan_bring_up
from ..outputs import hex_object, write_json
from ..params.check import screen
from ..params.profile import DEFAULT_PROFILE, load_profile
from ..params.read import drive_state
from ..params.write import bind_axes, raise_for_failure, write_drives
from ..session import Session
from ..tuning.tune import (
    GAINS,
    drive_model,
    read_frf_json,
    read_identify_json,
    read_resonances,
    read_tune_json,
    tune,
    tune_doc,
    unwritable_effects,
)
from . import options

if TYPE_CHECKING:
    from ..config import BusConfig
    from ..master.bringup import AxisLink
    from ..master.campaign import Plan
    from ..params.profile import Profile
    from ..params.write import WriteOutcome
    from ..tuning.tune import AxisTuning
from .bus import degraded_exit, dry_run_end, holding_lines, motion_preview, validate_plans


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add this module's commands to the command line.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The command line's subparsers.
    """
    p = sub.add_parser(
        "tune",
        help="design the cascade gains from identified models (margins with python-control)",
        description="Gains from identify.json on the drives' motor data and present gains; "
        "--experiment also runs the paper's gain-raising procedure on the drive.",
    )
    options.drive(p, params=False)
    p.add_argument("--ident", required=True, help="identify --json output (identify.json)")
    p.add_argument("--out", default="tune.json", help="where to write the result (default: %(default)s)")
    p.add_argument(
        "--frf",
        help="frf.json of commission's measure step: keep the margins on each axis's measured "
        "response too (the worse counts)",
    )
    p.add_argument(
        "--experiment",
        action="store_true",
        help="also run the paper's gain-raising procedure on the drive "
        "(each gain through the same gate as write's)",
    )
    options.motion(p)
    options.write_checks(p)
    options.dry_run(p)
    p.add_argument(
        "--offline",
        action="store_true",
        help="design without a bus, from identify.json and the motor data given (--motor-R and "
        "--motor-L, or --motor-file); the gains before are then unknown",
    )
    p.add_argument(
        "--motor-file",
        help="YAML or JSON with the motor R [Ω] and L [H]: {R: .., L: ..} for every "
        "axis, or per axis {x: {R: .., L: ..}, ...}",
    )
    options.motor(p)
    p.set_defaults(func=cmd_tune)

    p = sub.add_parser(
        "write",
        help="write gains and model to the drives: backup, verify, then store",
        description="One transaction over all drives: backup, write, read back and compare, "
        "then store (0x1010); any failure restores every drive and stores nothing.",
    )
    options.drive(p)
    options.write_checks(p)
    p.add_argument("--dry-run", action="store_true", help="print old -> new and write nothing")
    p.add_argument("--backup-dir", default="backup", help="where the backups go (default: %(default)s)")
    p.add_argument("--dcf-dir", help="export each commissioned node as a DCF here")
    _frf_gate(p)
    options.history(p)
    p.set_defaults(func=cmd_write)

    p = sub.add_parser(
        "validate",
        help="reference trajectories: Table III scenarios against the tuned set",
        description="Point-to-point moves and a 3-D path with each Table III scenario and the "
        "tuned set; the drives are left with the parameters they held before.",
    )
    options.drive(p)
    options.motion(p)
    options.write_checks(p)
    options.dry_run(p)
    p.add_argument("--out", help="directory for validate.json and the logged runs (traces.npz)")
    _frf_gate(p)
    p.set_defaults(func=cmd_validate)


def _frf_gate(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--frf",
        help="frf.json of commission's measure step: the gate also checks the margins on each "
        "axis's measured response (the worse counts)",
    )


def _axes_in(config: BusConfig, names: Iterable[str], path: str | Path) -> list[str]:
    """The axes of a result file, every one of them configured (in ``config``'s order)."""
    unknown = [a for a in names if a not in config.nodes]
    if unknown:
        raise UserError(
            f"{path}: axis {unknown[0]!r} is not in {config.path} (configured: {', '.join(config.nodes)})"
        )
    return [a for a in config.nodes if a in names]


def _motor_given(args: argparse.Namespace, axes: Iterable[str]) -> dict[str, dict]:
    """Per axis the motor data of --motor-R/--motor-L or --motor-file, as drive_state gives it."""
    from ..yamlconf import Section, load_yaml

    if args.motor_file:
        top = Section(Path(args.motor_file), "", load_yaml(args.motor_file))
        per_axis = (
            {a: top.section(a) for a in axes}
            if not {"R", "L"} & set(top.keys())
            else dict.fromkeys(axes, top)
        )
        motor = {
            a: (s.get("R", float, low=1e-9, high=1e3), s.get("L", float, low=1e-9, high=10.0))
            for a, s in per_axis.items()
        }
        for s in per_axis.values():
            s.done()
        top.done()
    elif args.motor_R and args.motor_L:
        motor = dict.fromkeys(axes, (args.motor_R, args.motor_L))
    else:
        raise UserError("--offline needs the motor data: --motor-R and --motor-L, or --motor-file")
    return {a: {"motor": {"R": r, "L": ell}, "parameters_before": {}} for a, (r, ell) in motor.items()}


def cmd_tune(args: argparse.Namespace) -> int:
    """The ``tune`` command: gains from the identified models.

    Parameters
    ----------
    args : argparse.Namespace
        The command line.

    Returns
    -------
    int
        The exit code (:data:`drive_bridge.errors.EXIT_TABLE`).
    """
    from ..tuning.experiment import run_experiment

    models = read_identify_json(args.ident)
    frfs = read_frf_json(args.frf) if args.frf else None
    if args.offline:
        if args.experiment or args.sim:
            raise UserError("--offline designs without a bus: it does not go with --experiment or --sim")
        profile = load_profile(options.session_options(args).profile or DEFAULT_PROFILE)
        results = tune(
            models,
            _motor_given(args, list(models)),
            frfs,
            profile.controller,
            read_resonances(args.ident),
            profile.drive,
        )
    else:
        config = options.config(args)
        config = config.only(_axes_in(config, models, args.ident))
        if args.dry_run and not args.experiment:
            raise UserError("--dry-run shows the motion of --experiment; tune without it moves nothing")
        if args.experiment:
            options.asks(args, config, "tune --experiment")  # before anything is sent
            text = _experiment_preview(args, config, models)
            if args.dry_run:
                return dry_run_end(text)
            options.confirm_motion(args, config, "tune --experiment", lambda: text)
        with Session(config, options.session_options(args)) as session:
            results = tune(
                models,
                drive_state(session.axes, session.profile, session.options.motor),
                frfs,
                session.profile.controller,
                read_resonances(args.ident),
                session.profile.drive,
            )
            if args.experiment:
                for a, t in results.items():
                    profile = session.profile.for_axis(session.axes[a])
                    t.experiment = run_experiment(
                        config,
                        session.link,
                        session.axes,
                        a,
                        profile,
                        _experiment_start(t),
                        _experiment_gate(args, profile, t),
                    )
                holding = session.holding()
    doc = tune_doc(results, unwritable_effects(args.ident))
    out = write_json(args.out, doc)
    if args.json:
        options.print_json(doc)
        return 0
    for a, t in results.items():
        d = t.design
        print(f"axis {a}: J {t.model['J']:.4g} kg·m², c1 {t.model['c1']:.4g} Nm·s/rad")
        for g in GAINS:
            before = f"{t.before[g]:>10.5g}" if g in t.before else f"{'unknown':>10}"
            print(f"  {g:<4} {before} -> {getattr(d, g):.5g}")
        print(
            f"  velocity loop: phase margin {d.velocity.phase_margin_deg:.1f}°, gain margin "
            f"{d.velocity.gain_margin_db:.1f} dB, crossover {d.velocity.crossover_hz:.0f} Hz"
            + (
                ""
                if t.before_margins is None
                else f" (before: {t.before_margins[0].phase_margin_deg:.1f}°, "
                f"{t.before_margins[0].gain_margin_db:.1f} dB)"
            )
        )
        print(
            f"  position loop: phase margin {d.position.phase_margin_deg:.1f}°, gain margin "
            f"{d.position.gain_margin_db:.1f} dB, crossover {d.position.crossover_hz:.0f} Hz"
        )
        if t.experiment is not None:
            e = t.experiment
            print(
                f"  paper's procedure on the drive: KpS {e.KpS if e.KpS is None else round(e.KpS, 4)} after "
                f"{len(e.steps)} steps (model-based: {d.KpS:.4g})" + (f"; {e.gated}" if e.gated else "")
            )
    print(f"wrote {out}")
    if args.experiment:
        print(holding_lines(holding))
    return 0


def _experiment_start(t: AxisTuning) -> float:
    """The experiment's first KpS: the drive's own, else the designed one."""
    return t.before.get("KpS", t.design.KpS)


def _experiment_gate(
    args: argparse.Namespace, profile: Profile, t: AxisTuning
) -> Callable[[float], str | None]:
    """``admit(KpS)`` for the experiment on ``t``'s axis: the set the drive then runs (its gains
    with that KpS, on the identified model) through the gate every gain set passes."""

    def admit(kps: float) -> str | None:
        return screen(
            {t.axis: profile},
            {t.axis: {**t.model, **t.before, "KpS": kps}},
            {t.axis: t.motor["L"]},
            force=args.force,
            pm_floor=args.min_phase_margin,
            gm_floor=args.min_gain_margin,
            allow_unverified_scales=options.session_options(args).writes_unverified,
        )[1]

    return admit


def _experiment_preview(
    args: argparse.Namespace, config: BusConfig, models: dict[str, dict[str, float]]
) -> str:
    """What ``tune --experiment`` will do, read without writing anything: each axis's square wave
    from where it stands, and its first gain, refused here already when the gate refuses it."""
    from ..tuning import motion
    from ..tuning.experiment import RAISE, check_start, demand_of

    def plans(axes: dict[str, AxisLink]) -> list[tuple[str, Plan]]:
        return [
            (
                f"tune --experiment {a}, each step",
                motion.plan(
                    config,
                    {a: ax},
                    {a: demand_of(ax.cfg.limits, config.master.sync_period_s)[0]},
                    {a: ax.start_rad()},
                    kind="experiment",
                )[0],
            )
            for a, ax in axes.items()
        ]

    with Session(config, options.session_options(args)) as session:
        planned = tune(
            models,
            drive_state(plan_bring_up(session.link, config), session.profile, session.options.motor),
            controller=session.profile.controller,
        )
        for a, t in planned.items():
            profile = session.profile.bind(config.torque_constants[a], a)
            check_start(a, _experiment_start(t), _experiment_gate(args, profile, t))
        return (
            motion_preview(session, config, plans)
            + "\n"
            + "\n".join(
                f"  {a}: KpS from {_experiment_start(t):.5g}, x{RAISE} per step while the gate admits it"
                for a, t in planned.items()
            )
        )


def cmd_write(args: argparse.Namespace) -> int:
    """The ``write`` command: a parameter set written in one transaction.

    Parameters
    ----------
    args : argparse.Namespace
        The command line.

    Returns
    -------
    int
        The exit code (:data:`drive_bridge.errors.EXIT_TABLE`).
    """
    config = options.config(args)
    tuned = read_tune_json(args.params)
    config = config.only(_axes_in(config, tuned.parameters, args.params))
    from ..history.record import now

    o = options.session_options(args)
    started = now()
    with Session(config, o) as session:
        nodes = session.nodes
        outcome = write_drives(
            nodes,
            session.profile,
            {a: tuned.parameters[a] for a in nodes},
            backup_dir=args.backup_dir,
            dcf_dir=args.dcf_dir,
            dry_run=args.dry_run,
            inductance=tuned.inductance,
            force=o.force,
            pm_floor=o.pm_floor,
            gm_floor=o.gm_floor,
            allow_unverified_scales=o.writes_unverified,
            bitrate=config.master.nominal_bitrate,
            frf=read_frf_json(args.frf) if args.frf else None,
            torque_constants=config.torque_constants,
        )
        identities = session.identities
    if args.json:
        options.print_json(outcome.as_dict())
    else:
        _print_write(outcome, args.backup_dir, session.profile)
    if o.history and not args.dry_run:
        from ..history import keep
        from ..history.record import new_run_id, write_record

        record = write_record(
            new_run_id(), started, outcome.as_dict(), identities, config.path, o.sim, args.backup_dir
        )
        print(keep(record, o.db).line(), file=sys.stderr)
    raise_for_failure(outcome, args.backup_dir)
    return 0


def _print_write(outcome: WriteOutcome, backup_dir: str | None, profile: Profile) -> None:
    for reason in outcome.forced:
        print(f"FORCED: {reason}")
    if outcome.unverified_scales:
        print(
            f"UNVERIFIED SCALES (no documented source in the drive profile): {', '.join(outcome.unverified_scales)}"
        )
    width = max((len(w.parameter) for r in outcome.results.values() for w in r.objects), default=9)
    for a, r in outcome.results.items():
        print(f"axis {a} (node {r.node_id}, {r.drive}){' — dry run, nothing written' if r.dry_run else ''}:")
        for w in r.objects:
            state = "verified" if w.verified else ("" if r.dry_run else "NOT verified")
            if not profile.entries[w.parameter].verified:
                state += " UNVERIFIED SCALE"
            print(
                f"  {w.parameter:<{width}} {hex_object(w.index, w.sub):<9} {number(w.old_si):>11} -> {number(w.new_si):<11} "
                f"{w.unit:<18} (device {number(w.old_device)} -> {number(w.new_device)}) {state}"
            )
        for name in r.unsupported:
            print(f"  {name:<9} not supported by {r.drive}: not written")
        if r.stored:
            print("  stored to non-volatile memory (0x1010 'save')")
        for n in r.notes:
            print(f"  note: {n}")
        if not r.dry_run:
            print(
                f"  drive holds: RAM {r.ram}, stored set {r.stored_set}"
                + (f"; backup of the old values: {r.backup}" if r.backup else "")
            )
    if backup_dir is not None and not all(r.dry_run for r in outcome.results.values()):
        print(f"backups of the values before: {backup_dir}/")


def cmd_validate(args: argparse.Namespace) -> int:
    """The ``validate`` command: the reference trajectories before and after (the robot moves).

    Parameters
    ----------
    args : argparse.Namespace
        The command line.

    Returns
    -------
    int
        The exit code (:data:`drive_bridge.errors.EXIT_TABLE`).
    """
    from ..paper import TABLE_III
    from ..tuning.validate import degraded, run_scenarios, stopped, validate_doc

    options.out_dir(args.out)
    config = options.config(args)
    tuned = read_tune_json(args.params)
    params = tuned.parameters
    names = _axes_in(config, params, args.params)
    config = config.only(names)
    model = {a: drive_model(params[a]) for a in names}
    scenarios = {n: {a: dict(g) for a in names} for n, g in TABLE_III.items()}
    scenarios["tuned + model feed-forward"] = {a: params[a] for a in names}
    frf = read_frf_json(args.frf) if args.frf else None
    with Session(config, options.session_options(args)) as session:  # the bus opens when first used
        refused = {}
        for name, sets in list(scenarios.items()):  # every set through write's gate, on the identified model
            _, why = screen(
                bind_axes(session.profile, names, config.torque_constants),
                {a: {**params[a], **sets[a]} for a in names},
                tuned.inductance,
                force=args.force,
                pm_floor=args.min_phase_margin,
                gm_floor=args.min_gain_margin,
                allow_unverified_scales=args.allow_unverified_scales,
                frf=frf,
            )
            if why:
                refused[name] = why
                del scenarios[name]
                print(f"drive-bridge: {name} refused: {why}", file=sys.stderr)
        if not scenarios:
            raise UserError(
                f"every scenario was refused ({'; '.join(refused)}); nothing was written or moved"
            )
        plans = validate_plans(config, f"each of {len(scenarios)} scenarios ({', '.join(scenarios)})")
        if args.dry_run:
            return dry_run_end(motion_preview(session, config, plans))
        options.confirm_motion(args, config, "validate", lambda: motion_preview(session, config, plans))
        runs = run_scenarios(
            config,
            session.link,
            session.axes,
            session.profile,
            scenarios,
            model,
            out_dir=Path(args.out) if args.out else None,
            refused=refused,
        )
        holding = session.holding()
    if args.json:
        options.print_json(validate_doc(runs, refused))
    else:
        print(
            f"{'scenario':<28} {'trajectory':<15} {'axis':<4} {'FE rms [mrad]':>13} {'FE max [mrad]':>13} "
            f"{'overshoot [%]':>13} {'settling [ms]':>13} {'torque RMSE [mNm]':>17}"
        )
        for r in runs:
            for a, m in r.axes.items():
                settle = None if m.settling_s is None else m.settling_s * 1e3
                print(
                    f"{r.scenario:<28} {r.trajectory:<15} {a:<4} {number(m.fe_rms * 1e3, '.3g'):>13} "
                    f"{number(m.fe_max * 1e3, '.3g'):>13} {number(m.overshoot_pct, '.3g'):>13} {number(settle, '.3g'):>13} "
                    f"{number(m.torque_rmse * 1e3, '.3g'):>17}"
                )
        print(holding_lines(holding))
    stop = stopped(runs)
    if stop is not None:
        raise stop
    return degraded_exit(degraded(runs))
