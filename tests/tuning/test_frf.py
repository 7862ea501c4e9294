"""The plant's response measured through the drive (drive_bridge.ident.frf) and the margins on it
(params.cascade.measured_margins), on the simulated Y axis run bus-free (plant_log): the soft measurement
gains, a constant 10 rad/s sweep, the torque-offset multisine.  The compliant axis is checked
against its true two-mass plant, computed here from the simulator's parameters (not measured)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from drive_bridge.ident.frf import PERIODS, Frf, excitation, measure
from drive_bridge.params.cascade import (
    GM_MIN_DB,
    PM_MIN_DEG,
    Margins,
    controller,
    margins_at_points,
    measured_margins,
    rigid_response,
    velocity_open_loop,
)
from drive_bridge.params.controller import LOOP_TICK_S
from drive_bridge.sim.plantlog import plant_log
from drive_bridge.sim.robot_config import Motor, load_sim_config
from drive_bridge.sim.vendors import factory
from drive_bridge.tuning.design import PM_DESIGN_DEG, current_gains, design_gains, measurement_gains

from ..ident.test_identify import sim_config

pytestmark = pytest.mark.slow

RATE = 500.0
J, C1 = 1e-4, 5e-4
MOTOR = Motor()
W_I = current_gains(MOTOR.R, MOTOR.L)[2]
SHARE, RESONANCE_HZ, ZETA = 0.5, 120.0, 0.02  # the shipped compliant robot's Y


def two_mass(share=SHARE, resonance_hz=RESONANCE_HZ, zeta=ZETA) -> tuple[float, float, float]:
    """Load share, stiffness [Nm/rad] and damping [Nm·s/rad] of a mode at ``resonance_hz``."""
    jm, jl = J * (1 - share), J * share
    k = (2 * np.pi * resonance_hz) ** 2 * jm * jl / (jm + jl)
    return share, k, 2 * zeta * np.sqrt(k * jm * jl / (jm + jl))


def measured(effects: dict | None = None) -> Frf:
    soft = {**factory().gains, **measurement_gains(J, RATE)}
    u = np.tile(excitation(RATE, 0.05), PERIODS)
    n = len(u)
    cols = plant_log(
        sim_config(effects),
        {"y": -60 + 10 * np.arange(1, n + 1) / RATE, "z": np.zeros(n)},
        torque_offset={"y": u},
        gains={"y": soft},
    )
    return measure(cols["y_position_rad"], u, RATE, controller(soft))


def true_margins(gains: dict[str, float], share: float, k: float, d: float) -> tuple[Margins, Margins]:
    """The velocity and position loops' margins with ``gains`` on the true two-mass plant (motor
    J·(1 − share), load J·share on k, d; friction c1 on the motor), the drive's loop as the
    design models it, on a dense grid up to the loops' Nyquist frequency."""
    f = np.geomspace(0.5, 999.0, 4000)
    s = 2j * np.pi * f
    jm, jl = J * (1 - share), J * share
    spring = jl * s**2 + d * s + k
    plant = 1 / (s / W_I + 1) * spring / ((jm * s + C1) * spring + jl * s * (d * s + k))
    velocity = gains["KpS"] * (1 + gains["KiS"] / s) * np.exp(-s * LOOP_TICK_S) * plant
    position = gains["KpP"] / s * velocity / (1 + velocity)
    return margins_at_points(f, velocity), margins_at_points(f, position)


def floor_kept(m: Margins | None) -> bool:
    return m is not None and m.phase_margin_deg >= PM_MIN_DEG and m.gain_margin_db >= GM_MIN_DB


def test_the_measured_response_of_the_rigid_axis_matches_its_model_up_to_half_the_nyquist_frequency():
    """Rigid simulated axis: from where the drive's loop gain falls below 10 (under 10 Hz) up to
    half the Nyquist frequency (125 Hz) the measured G(jω) lies within 1 dB and 10° of the model
    1/(J·s + c1) behind the closed current loop, with coherence ≈ 1."""
    frf = measured()
    ok = frf.reliable()
    assert frf.frequency_hz[ok].min() < 10.0 and frf.frequency_hz[ok].max() >= 0.4 * RATE - 1
    band = ok & (frf.frequency_hz <= RATE / 4)
    ratio = frf.response[band] / rigid_response(J, C1, W_I, 2 * np.pi * frf.frequency_hz[band])
    assert np.max(np.abs(20 * np.log10(np.abs(ratio)))) < 1.0
    assert np.max(np.abs(np.degrees(np.angle(ratio)))) < 10.0
    assert frf.coherence[band].min() > 0.99


def test_on_a_compliant_axis_the_rigid_design_rings_and_the_design_on_the_measured_response_keeps_the_margins():
    """Y on a lightly damped spring (the shipped compliant robot): the gains designed on the rigid
    model keep PM ≥ 45° and GM ≥ 8 dB on that model but not on the true plant, and the measured
    response says so; designed with the measured response too, the gains keep them on the true
    plant, in both loops."""
    share, k, d = two_mass()
    frf = measured({"compliance": {"TM_SHARE": share, "TM_K": k, "TM_D": d}})
    rigid = design_gains(J, C1, MOTOR.R, MOTOR.L)
    assert rigid.velocity.ok() and rigid.position.ok()
    assert not floor_kept(true_margins(rigid.gains(), share, k, d)[0])
    assert not floor_kept(measured_margins(rigid.gains(), frf, W_I)[0])
    on_measured = design_gains(J, C1, MOTOR.R, MOTOR.L, frf=frf)
    for loop in true_margins(on_measured.gains(), share, k, d):
        assert floor_kept(loop), loop


def test_the_design_on_the_measured_response_of_a_rigid_axis_keeps_the_margins_on_it():
    frf = measured()
    gains = design_gains(J, C1, MOTOR.R, MOTOR.L, frf=frf).gains()
    for loop in true_margins(gains, 1e-6, 1e6, 0.0):  # (a load of nothing on a stiff spring: rigid)
        assert floor_kept(loop), loop


def test_margins_on_points_agree_with_python_control():
    """The margins read off a loop's frequency points are python-control's for a rigid loop."""
    import control  # (here, not at the top: with matplotlib it is over a second of every worker's collection)

    gains = design_gains(J, C1, MOTOR.R, MOTOR.L).gains()
    loop = velocity_open_loop(J, C1, gains["KpS"], gains["KiS"], W_I)
    f = np.geomspace(1.0, 999.0, 3000)
    points = margins_at_points(f, np.asarray(loop(2j * np.pi * f)).ravel())
    gm, pm, _, wc = control.margin(loop)
    assert points.phase_margin_deg == pytest.approx(pm, abs=0.2)
    assert points.gain_margin_db == pytest.approx(20 * np.log10(gm), abs=0.1)
    assert points.crossover_hz == pytest.approx(wc / (2 * np.pi), rel=1e-3)


def test_a_loop_above_one_at_the_top_of_the_band_is_not_verified():
    f = np.geomspace(10.0, 200.0, 100)
    assert margins_at_points(f, 1e4 / (2j * np.pi * f)) is None


def test_the_frf_survives_its_json():
    frf = measured()
    back = Frf.from_json(json.loads(json.dumps(frf.as_json())))
    assert np.allclose(back.frequency_hz, frf.frequency_hz, atol=1e-4)
    assert np.allclose(back.response, frf.response, rtol=1e-3)
    assert (back.reliable() == frf.reliable()).all()


def test_the_shipped_compliant_robot_rings_at_its_resonance():
    """The simulator's two-mass plant, let go with the motor moving and the load at rest, swings
    at √(k·(Jm + Jl)/(Jm·Jl)) / 2π: 120 Hz for the shipped compliant Y."""
    from drive_bridge.sim import kernel

    y = load_sim_config("compliant").axes["y"]
    state, param, demand = kernel.new_arrays(1)
    param[0, kernel.J], param[0, kernel.BRAKE], param[0, kernel.INC_PER_RAD] = (
        y.J,
        0.0,
        1e6,
    )  # power off, no friction
    for name, value in y.effects["compliance"].items():
        param[0, getattr(kernel, name)] = value
    state[0, kernel.V] = 1.0
    v = []
    for _ in range(800):
        kernel.advance(state, param, demand, np.zeros(1, dtype=np.int64), 1, np.full(1, 4))
        v.append(state[0, kernel.V])
    f = np.fft.rfftfreq(len(v), kernel.VELOCITY_TICK_S)
    peak = f[np.argmax(np.abs(np.fft.rfft(np.asarray(v) - np.mean(v))))]
    assert peak == pytest.approx(RESONANCE_HZ, abs=2 * (f[1] - f[0]))


def test_tune_takes_the_measured_response_and_says_its_margins(tmp_path, capsys):
    """``tune --offline --frf frf.json``: on the compliant axis's measured response the gains come out
    below the rigid model's and tune.json has the margins on the measured response; a frf.json
    that is not one is refused naming the file and the step to rerun (exit 2, nothing written)."""
    from drive_bridge.cli import main
    from drive_bridge.tuning.measure import frf_doc

    share, k, d = two_mass()
    (tmp_path / "frf.json").write_text(
        json.dumps(frf_doc({"y": measured({"compliance": {"TM_SHARE": share, "TM_K": k, "TM_D": d}})}, {}))
    )
    (tmp_path / "identify.json").write_text(
        json.dumps({"axes": {"y": {"params": {"J": J, "c0": 0.32, "c1": C1}}}})
    )
    argv = [
        "tune",
        "--ident",
        str(tmp_path / "identify.json"),
        "--offline",
        "--motor-R",
        str(MOTOR.R),
        "--motor-L",
        str(MOTOR.L),
    ]
    assert main(argv + ["--frf", str(tmp_path / "frf.json"), "--out", str(tmp_path / "t.json")]) == 0
    y = json.loads((tmp_path / "t.json").read_text())["axes"]["y"]
    assert y["gains"]["KpS"] < design_gains(J, C1, MOTOR.R, MOTOR.L).KpS
    assert y["measured"]["margins"]["velocity"]["phase_margin_deg"] >= PM_DESIGN_DEG
    capsys.readouterr()
    (tmp_path / "bad.json").write_text(json.dumps({"axes": {"y": {"frequency_hz": [1.0]}}}))
    assert main(argv + ["--frf", str(tmp_path / "bad.json"), "--out", str(tmp_path / "t2.json")]) == 2
    assert (
        "bad.json: not a frequency response" in capsys.readouterr().err
        and not (tmp_path / "t2.json").exists()
    )


def test_write_refuses_gains_the_measured_response_does_not_admit(tmp_path, capsys):
    """``write --frf``: the rigid model's gains for the compliant axis keep the floor on the model, so
    write admits them without the measured response and refuses them with it (exit 2, nothing
    written): on the measured plant their velocity loop crosses over above what was measured."""
    from drive_bridge.cli import main
    from drive_bridge.tuning.measure import frf_doc
    from drive_bridge.tuning.tune import tune, tune_doc
    from harness.support import bus_yml_beside

    share, k, d = two_mass()
    frf = tmp_path / "frf.json"
    frf.write_text(
        json.dumps(frf_doc({"y": measured({"compliance": {"TM_SHARE": share, "TM_K": k, "TM_D": d}})}, {}))
    )
    rigid = tune(
        {"y": {"J": J, "c0": 0.32, "c1": C1}},
        {"y": {"motor": {"R": MOTOR.R, "L": MOTOR.L}, "parameters_before": {}}},
    )
    (tmp_path / "tune.json").write_text(json.dumps(tune_doc(rigid)))
    cfg = bus_yml_beside(tmp_path)
    argv = [
        "write",
        "--sim",
        "--config",
        str(cfg),
        "--params",
        str(tmp_path / "tune.json"),
        "--dry-run",
        "--backup-dir",
        str(tmp_path / "b"),
    ]
    assert main(argv) == 0
    capsys.readouterr()
    assert main(argv + ["--frf", str(frf)]) == 2
    assert (
        "axis y: the velocity loop crosses over above the band its response was measured in"
        in capsys.readouterr().err
    )


# ---------------------------------------------------------------- the measured response checked against the model
def _tuned(frf: Frf) -> dict:
    """The tune step's record of how ``frf`` was used for the Y axis of model J, C1."""
    from drive_bridge.tuning.tune import tune_axis

    tuned = tune_axis("y", {"J": J, "c0": 0.0, "c1": C1}, MOTOR.R, MOTOR.L, dict(factory().gains), frf)
    return {**tuned.measured_response, "gains": tuned.design.gains()}


def _model_gains() -> dict:
    from drive_bridge.tuning.tune import tune_axis

    return tune_axis(
        "y", {"J": J, "c0": 0.0, "c1": C1}, MOTOR.R, MOTOR.L, dict(factory().gains)
    ).design.gains()


def test_a_response_the_model_explains_is_designed_on():
    record = _tuned(measured())
    assert record["used"] and record["suspect"] is None and record["departs"] is None


@pytest.mark.parametrize("scale", [0.1, 10.0])
def test_a_response_the_model_does_not_explain_is_set_aside_and_the_gains_are_the_models(scale):
    """A response off by a factor everywhere (a wrong unit, a corrupted run: no mode to explain it)
    would put a loop's crossover far from the model-based design's: the tune step says it is suspect
    and why, and designs on the model alone."""
    from dataclasses import replace

    from drive_bridge.tuning.tune import MEASURED_FACTOR

    frf = measured()
    record = _tuned(replace(frf, response=frf.response * scale))
    assert not record["used"] and "shows no mode that explains it" in record["suspect"]
    measured_hz, model_hz = record["crossover_hz"]["measured"], record["crossover_hz"]["model"]
    assert (
        max(max(measured_hz[loop] / model_hz[loop], model_hz[loop] / measured_hz[loop]) for loop in model_hz)
        > MEASURED_FACTOR
    )
    assert record["gains"] == _model_gains()


def test_a_response_measured_while_the_master_was_late_is_not_designed_on():
    """Samples missing and filled in, or set-points late, during the measurement (a wall-clock master
    held up): the response holds the timing's errors; the gains come from the model alone."""
    from dataclasses import replace

    record = _tuned(replace(measured(), filled=3, late=2))
    assert not record["used"] and "the master was late" in record["suspect"]
    assert "3 position samples missing" in record["suspect"] and "2 set-points" in record["suspect"]
    assert record["gains"] == _model_gains()


def test_a_compliant_axis_is_designed_on_its_response_and_the_mode_is_said_to_explain_the_departure():
    """The mode the rigid model lacks lowers the crossover more than the factor: the response explains
    it (a peak over a response that is the model's below it), so the design is on the response, and
    the record says why."""
    share, k, d = two_mass()
    record = _tuned(measured({"compliance": {"TM_SHARE": share, "TM_K": k, "TM_D": d}}))
    assert record["used"] and record["suspect"] is None
    mode_hz = float(record["departs"].split("the mode at ")[1].split(" Hz")[0])
    assert abs(mode_hz - RESONANCE_HZ) < 0.1 * RESONANCE_HZ
