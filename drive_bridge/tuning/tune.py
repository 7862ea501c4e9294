"""``tune``: from identified axis models to gains and the parameter set to write (Python API)."""

from __future__ import annotations

import json
import logging
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..config import BusConfig
from ..errors import UserError
from ..outputs import stamped
from ..params.cascade import (
    Margins,
    loop_margins,
    measured_margins,
    rigid_response,
)
from ..params.cascade import (
    controller as loop_controller,
)
from ..params.controller import GAINS, Controller
from ..yamlconf import too_large
from .design import GainDesign, current_bandwidth, design_gains
from .experiment import ExperimentResult
from .feedforward import MODEL_KEYS

if TYPE_CHECKING:  # (identification's package loads scipy's signal processing: imported where used)
    from ..ident.frf import Frf

log = logging.getLogger(__name__)

MODE_SHARE = 1 / 3  # without a filter object, a mode the measured response does not cover keeps the
# velocity crossover below this share of its frequency (rule of thumb for a rigid
# design near a lightly damped mode: 1/3 ... 1/5)
MODE_PEAK = 2.0  # a measured |G| this many times the rigid model's (6 dB) at its peak: a mode
LOOP_RINGING = (
    2**0.5
)  # an identified peak where the drive's own loop amplifies this much (3 dB) is the loop's
MEASURED_FACTOR = 3.0  # a design on the measured response whose velocity or position crossover lies
# further than this factor (either way) from the model-based design's sets the response aside
MIN_MEASURED_BINS = 20  # reliable bins a measured response needs to be designed on
MODE_AGREES = 2**0.5  # a mode explains a departing design where, below half its frequency, the response
MODE_BELOW_BINS = 5  # (the median over at least this many reliable bins) is the rigid model's within 3 dB


@dataclass
class AxisTuning:
    """One axis tuned (:func:`tune_axis`).

    Parameters
    ----------
    axis : str
        The axis.
    model : dict of str to float
        J, c0, c1 and the effect terms a drive holds, SI, motor side.
    design : GainDesign
        The gains designed (KpP, FwF, KpS, KiS, KpC, KiC; SI) and the loops' margins.
    before : dict of str to float
        The drive's gains before tuning.
    before_margins : (Margins, Margins) or None
        The velocity and position loops' margins with those gains, on the model.
    motor : dict of str to float
        R [Ω] and L [H] the current loop was designed for.
    experiment : ExperimentResult, optional
        The velocity gain raised on the machine until it oscillated, where that ran.
    frf : Frf, optional
        The plant's response measured through the drive, designed on too.
    controller : Controller
        The structure and rates the gains are designed for.
    mode : dict, optional
        A mode of the transmission, where one is known, and how the design meets it.
    measured_response : dict, optional
        With a measured response: whether the design used it, why not (``suspect``), why it was
        used although its design departs from the model-based one (``departs``), and the loops'
        crossovers on it and on the model alone (:func:`tune_axis`).
    """

    axis: str
    model: dict[str, float]
    design: GainDesign
    before: dict[str, float]
    before_margins: tuple[Margins, Margins] | None
    motor: dict[str, float]
    experiment: ExperimentResult | None = None
    frf: Frf | None = None
    controller: Controller = Controller()
    mode: dict | None = None
    measured_response: dict | None = None

    def parameters(self) -> dict[str, float]:
        """Everything to write.

        Returns
        -------
        dict of str to float
            The designed gains, the model, and the model feed-forward on (``ff_enable`` 1), SI.
        """
        return {**self.design.gains(), **self.model, "ff_enable": 1.0}

    def as_dict(self) -> dict:
        """The axis as tune.json holds it.

        Returns
        -------
        dict
            The model, motor, gains before and after, their margins (on the model and, where
            measured, on the response), the experiment, the controller, the mode and the
            parameters to write.
        """
        return {
            "model": self.model,
            "motor": self.motor,
            "gains": self.design.gains(),
            "gains_before": self.before,
            "margins": {"velocity": vars(self.design.velocity), "position": vars(self.design.position)},
            "margins_before": None
            if self.before_margins is None
            else {"velocity": vars(self.before_margins[0]), "position": vars(self.before_margins[1])},
            "experiment": None if self.experiment is None else self.experiment.as_dict(),
            "measured": None if self.frf is None else self.measured(),
            "controller": self.controller.as_dict(),
            "mode": self.mode,
            "measured_response": self.measured_response,
            "parameters": self.parameters(),
        }

    def measured(self) -> dict:
        """The margins before and after on the measured response.

        Returns
        -------
        dict
            ``band_hz``: the band the response is reliable in [Hz]; ``margins`` and
            ``margins_before``: the velocity and position loops' margins [°, dB] (a loop whose
            crossover lies above the band: None, not verified); empty without a response.
        """
        frf = self.frf
        if frf is None:
            return {}
        band = frf.frequency_hz[frf.reliable()]

        def margins(gains: dict[str, float]) -> dict | None:
            if not {"KpP", "KpS", "KiS", "KpC"} <= set(gains):
                return None
            v, p = measured_margins(gains, frf, gains["KpC"] / self.motor["L"], self.controller.timing.tick_s)
            return {"velocity": None if v is None else vars(v), "position": None if p is None else vars(p)}

        return {
            "band_hz": [float(band.min()), float(band.max())] if len(band) else None,
            "margins": margins(self.design.gains()),
            "margins_before": margins(self.before),
        }


def model_from_identify(params: dict[str, float]) -> dict[str, float]:
    """The drive-model subset of ``identify``'s parameters.

    Parameters
    ----------
    params : dict of str to float
        An axis's identified parameters (``model.params_``: J, c0, c1, ``<effect>.<name>``).

    Returns
    -------
    dict of str to float
        J, c0, c1 and the effect terms a drive model holds, by their short names (effects the
        drive cannot add are left out).
    """
    return {short: float(params[key]) for key, short in MODEL_KEYS.items() if key in params}


def drive_model(parameters: dict[str, float]) -> dict[str, float]:
    """The model part of a parameter set to write.

    Parameters
    ----------
    parameters : dict of str to float
        A parameter set (gains and model).

    Returns
    -------
    dict of str to float
        J, c0, c1 and the effect terms in it.
    """
    return {k: v for k, v in parameters.items() if k in MODEL_KEYS.values()}


def _axes_of(path: Path, what: str) -> dict:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError as exc:
        raise UserError(f"{path}: no such file ({what})") from exc
    except (OSError, ValueError) as exc:
        raise UserError(f"{path}: not a {what} (not readable JSON: {exc})") from exc
    except RecursionError as exc:
        raise UserError(f"{path}: not a {what} (nested too deeply)") from exc
    axes = doc.get("axes") if isinstance(doc, dict) else None
    if not isinstance(axes, dict) or not axes or not all(isinstance(v, dict) for v in axes.values()):
        raise UserError(f"{path}: not a {what}: it needs an 'axes' mapping of axis name to its result")
    return axes


def _numbers(path: Path, where: str, values: object) -> dict[str, float]:
    if not isinstance(values, dict):
        raise UserError(f"{path}: {where} must be a mapping of names to numbers")
    out = {}
    for k, v in values.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise UserError(f"{path}: {where}.{k} = {v!r} is not a number")
        try:
            out[k] = float(v)
        except OverflowError as exc:  # only an int overflows a float
            raise UserError(f"{path}: {where}.{k}: {too_large(int(v))}") from exc
    return out


def read_frf_json(path: str | Path) -> dict[str, Frf]:
    """The measured responses the measure step wrote.

    Parameters
    ----------
    path : str or Path
        frf.json.

    Returns
    -------
    dict of str to Frf
        Per axis, its measured torque -> velocity response.

    Raises
    ------
    UserError
        A file that is not one the measure step writes.
    """
    from ..ident.frf import Frf

    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        return {a: Frf.from_json(r) for a, r in doc["axes"].items()}
    except (OSError, KeyError, TypeError, ValueError, AttributeError) as exc:
        raise UserError(
            f"{path}: not a frequency response as the measure step writes it ({exc!r}); rerun the "
            f"measure step"
        ) from exc


def read_identify_json(path: str | Path) -> dict[str, dict[str, float]]:
    """The drive-model subset of every axis's identified parameters.

    Parameters
    ----------
    path : str or Path
        An ``identify --json`` result (identify.json).

    Returns
    -------
    dict of str to dict
        Per axis, :func:`model_from_identify` of what its drive's model holds, SI.

    Raises
    ------
    UserError
        A file that is not such a result, a value that is not a number, or an axis whose J, c0 or
        c1 the identification says it could not determine.
    """
    path = Path(path)
    axes = _axes_of(path, "identify --json result")
    out = {}
    for a, r in axes.items():
        unknown = r.get("undetermined")
        if isinstance(unknown, dict) and unknown:
            k, why = next(iter(unknown.items()))
            raise UserError(
                f"{path}: axis {a}: the identification could not determine {', '.join(map(str, unknown))} "
                f"({k}: {why}); it is not used to tune or written to a drive. Record a log that "
                f"determines it (a richer excitation: several speeds and accelerations, both directions), "
                f"or leave the axis out of identify.json"
            )
        params = r.get("drive_params", r.get("params"))  # what the drive's model holds, where identify says
        if isinstance(params, dict):  # text values (a cross-axis effect's source) are not numbers
            params = {k: v for k, v in params.items() if not isinstance(v, str)}
        out[a] = model_from_identify(_numbers(path, f"axes.{a}.params", params))
    return out


def read_resonances(path: str | Path) -> dict[str, dict | None]:
    """The resonance an identification reports per axis.

    Parameters
    ----------
    path : str or Path
        An ``identify --json`` result.

    Returns
    -------
    dict of str to dict or None
        Per axis, its ``resonance`` (None: none).
    """
    return {
        a: r.get("resonance") if isinstance(r.get("resonance"), dict) else None
        for a, r in _axes_of(Path(path), "identify --json result").items()
    }


def unwritable_effects(path: str | Path) -> dict[str, list[str]]:
    """The traced effects no drive model parameter (nor the master's feed-forward, which sends the
    same model) can carry: reported, not dropped.

    Parameters
    ----------
    path : str or Path
        An ``identify --json`` result.

    Returns
    -------
    dict of str to list of str
        Per axis, those effects' names.
    """
    from ..ident.effects import DRIVE_EFFECTS  # (here: identification's modules load scipy's statistics)

    axes = _axes_of(Path(path), "identify --json result")
    writable = set(DRIVE_EFFECTS)
    return {
        a: [
            e["name"] for e in r.get("effects") or [] if isinstance(e, dict) and e.get("name") not in writable
        ]
        for a, r in axes.items()
    }


#: the largest J [kg·m² | kg], c0 [Nm | N], c1 [Nm·s/rad | N·s/m] a servo axis can have (linear axes too)
PLAUSIBLE = {"J": 1e4, "c0": 1e5, "c1": 1e5}


def check_model(axis: str, model: dict[str, float]) -> None:
    """Check that an identified model is physical: J > 0, c0 and c1 ≥ 0, all finite and within
    :data:`PLAUSIBLE`.

    Parameters
    ----------
    axis : str
        The axis (named in the error).
    model : dict of str to float
        J [kg·m² | kg], c0 [Nm | N], c1 [Nm·s/rad | N·s/m].

    Raises
    ------
    UserError
        Naming the axis and each parameter that is not.
    """
    bad = [f"{k} missing" for k in ("J", "c0", "c1") if k not in model]
    bad += [f"{k} = {v}" for k, v in model.items() if not math.isfinite(v)]
    if not bad:
        bad = (
            ([f"J = {model['J']:.6g} (must be > 0)"] if model["J"] <= 0 else [])
            + [f"{k} = {model[k]:.6g} (friction must be ≥ 0)" for k in ("c0", "c1") if model[k] < 0]
            + [
                f"{k} = {model[k]:.6g} (no servo axis has that much)"
                for k, most in PLAUSIBLE.items()
                if model[k] > most
            ]
        )
    if bad:
        raise UserError(
            f"axis {axis}: the identified model is not physical ({', '.join(bad)}); identify it "
            f"again (longer or richer excitation) before tuning"
        )


def measured_mode(frf: Frf, J: float, c1: float, current_bw_rad_s: float) -> float | None:
    """The frequency of a mode the measured response shows.

    Parameters
    ----------
    frf : Frf
        The measured torque -> velocity response (its reliable bins are read).
    J : float
        The identified inertia [kg·m² | kg].
    c1 : float
        The identified viscous friction [Nm·s/rad | N·s/m].
    current_bw_rad_s : float
        The current loop's bandwidth [rad/s].

    Returns
    -------
    float or None
        [Hz] where |G| stands at least ``MODE_PEAK`` times the rigid model's; None where it does
        not.
    """
    ok = frf.reliable()
    if not ok.any():
        return None
    f = frf.frequency_hz[ok]
    ratio = np.abs(frf.response[ok] / rigid_response(J, c1, current_bw_rad_s, 2 * np.pi * f))
    k = int(np.argmax(ratio))
    return float(f[k]) if ratio[k] >= MODE_PEAK else None


def loop_amplification(
    model: dict[str, float], gains: dict[str, float], current_bw_rad_s: float, tick_s: float, f_hz: float
) -> float:
    """How much a drive's loop amplifies at one frequency on the rigid model.

    Parameters
    ----------
    model : dict of str to float
        J [kg·m² | kg] and c1 [Nm·s/rad | N·s/m].
    gains : dict of str to float
        The loop's gains (KpP, KpS, KiS; SI).
    current_bw_rad_s : float
        The current loop's bandwidth [rad/s].
    tick_s : float
        The drive's control period [s].
    f_hz : float
        The frequency [Hz].

    Returns
    -------
    float
        The larger of |1 / (1 + K·G)| and |K·G / (1 + K·G)|, broken at the torque command
        (whatever the structure, the same loop): above 1 the loop rings there by itself.
    """
    w = np.array([2 * np.pi * f_hz])
    open_loop = loop_controller(gains, tick_s)(w) * rigid_response(
        model["J"], model["c1"], current_bw_rad_s, w
    )
    return float(max(abs(1 / (1 + open_loop[0])), abs(open_loop[0] / (1 + open_loop[0]))))


def _mode(
    axis: str,
    model: dict[str, float],
    resonance: dict | None,
    frf: Frf | None,
    controller: Controller,
    drive: str,
    before: dict[str, float],
) -> tuple[dict | None, float | None]:
    """A mode of the axis's transmission (identified or measured) and how the design meets it:
    the record for tune.json, and the velocity crossover cap [Hz] (None: none).  An identified
    peak where the drive's own loop with its gains ``before`` peaks on the rigid model is that
    loop ringing in the log, not the machine: no cap."""
    w_i = current_bandwidth(controller.timing.current_hz)
    measured = measured_mode(frf, model["J"], model["c1"], w_i) if frf is not None else None
    if measured is not None:
        source, f = "measured response", measured
    elif resonance and not resonance.get("mains") and resonance.get("frequency_hz"):
        source, f = "identification", float(resonance["frequency_hz"])
    else:
        return None, None

    def met(handling: str, cap: float | None = None) -> tuple[dict, float | None]:
        return (
            {
                "frequency_hz": round(f, 2),
                "source": source,
                "filter": None,
                "handling": handling,
                "crossover_cap_hz": None if cap is None else round(cap, 2),
            },
            cap,
        )

    band = frf.frequency_hz[frf.reliable()] if frf is not None else np.array([])
    no_filter = f"the {drive} profile names no notch or low-pass filter object"
    if source == "identification" and {"KpP", "KpS", "KiS"} <= set(before):
        gain = loop_amplification(model, before, w_i, controller.timing.tick_s, f)
        if gain >= LOOP_RINGING:
            return met(
                f"the drive's own loop with its gains before amplifies {20 * np.log10(gain):.1f} dB there on "
                f"the rigid model: the log shows that loop ringing, not a mode of the machine (measure the "
                f"response to tell them apart); no limit"
            )
    if len(band) and band.min() <= f <= band.max():
        return met(
            f"{no_filter}; the response measured through the mode limits the crossover: the margins hold on it"
        )
    cap = MODE_SHARE * f
    log.info("axis %s: a mode at %.0f Hz (%s): velocity crossover kept below %.0f Hz", axis, f, source, cap)
    return met(
        f"{no_filter}; not measured through: the velocity crossover kept at most {MODE_SHARE:.2g} × the mode",
        cap,
    )


def tune_axis(
    axis: str,
    model: dict[str, float],
    R: float,
    L: float,
    before: dict[str, float],
    frf: Frf | None = None,
    controller: Controller = Controller(),
    resonance: dict | None = None,
    drive: str = "drive",
) -> AxisTuning:
    """Gains for one axis from its identified model, for the controller its drive runs.

    Parameters
    ----------
    axis : str
        The axis (named in errors).
    model : dict of str to float
        J [kg·m² | kg], c0 [Nm | N], c1 [Nm·s/rad | N·s/m], motor side (and effect terms).
    R : float
        The motor's resistance [Ω].
    L : float
        The motor's inductance [H].
    before : dict of str to float
        The drive's gains before tuning (their margins are reported beside the new ones).
    frf : Frf, optional
        The plant's response measured through the drive: the margins are kept on it too.
    controller : Controller
        The structure and loop rates the drive runs (default: the project drive's cascade at
        2 kHz).
    resonance : dict, optional
        A mode identify found (``diagnostics.resonance``); one the response shows counts too.
    drive : str
        The drive model, in words.

    Returns
    -------
    AxisTuning
        The gains (``design.gains()``: KpP, FwF, KpS, KiS, KpC, KiC), the margins before and
        after, and how a mode was met.

    Raises
    ------
    UserError
        A model or motor values no gains can be designed from, named with the axis.
    """
    check_model(axis, model)
    if not (math.isfinite(R) and math.isfinite(L) and R > 0 and L > 0):
        raise UserError(f"axis {axis}: motor R = {R} Ω, L = {L} H must be positive numbers")
    timing = controller.timing
    mode, cap = _mode(axis, model, resonance, None, controller, drive, before)
    try:  # on the model alone: the reference
        design = design_gains(model["J"], model["c1"], R, L, None, timing, cap)
    except (KeyError, ValueError) as exc:
        raise UserError(f"axis {axis}: cannot design gains from the model {model}: {exc}") from exc
    measured_response = None
    if frf is not None:
        on_frf, suspect, departs = _on_measured(
            axis, model, R, L, frf, controller, resonance, drive, before, design
        )
        measured_response = {
            "used": suspect is None,
            "suspect": suspect,
            "departs": departs,
            "factor": MEASURED_FACTOR,
            "crossover_hz": {
                "model": _crossovers(design),
                "measured": None if on_frf is None else _crossovers(on_frf[0]),
            },
        }
        if suspect is None and on_frf is not None:
            design, mode = on_frf
        else:
            log.warning(
                "axis %s: the measured response is suspect (%s): gains from the model alone", axis, suspect
            )
    margins = (
        loop_margins(model["J"], model["c1"], before, R, L, timing.tick_s)
        if set(GAINS) <= set(before)
        else None
    )
    log.info(
        "axis %s: %s; velocity loop PM %.1f° at %.0f Hz",
        axis,
        ", ".join(f"{g} {v:.5g}" for g, v in design.gains().items()),
        design.velocity.phase_margin_deg,
        design.velocity.crossover_hz,
    )
    return AxisTuning(
        axis,
        model,
        design,
        before,
        margins,
        {"R": R, "L": L},
        frf=frf,
        controller=controller,
        mode=mode,
        measured_response=measured_response,
    )


def _crossovers(design: GainDesign) -> dict[str, float]:
    """The velocity and position loops' crossovers [Hz]."""
    return {
        "velocity": round(float(design.velocity.crossover_hz), 3),
        "position": round(float(design.position.crossover_hz), 3),
    }


def _on_measured(
    axis: str,
    model: dict[str, float],
    R: float,
    L: float,
    frf: Frf,
    controller: Controller,
    resonance: dict | None,
    drive: str,
    before: dict[str, float],
    reference: GainDesign,
) -> tuple[tuple[GainDesign, dict | None] | None, str | None, str | None]:
    """The design on the measured response ``frf`` with its mode record, why the response is
    suspect (None: it is designed on) and, where its design departs from the model-based
    ``reference`` by more than ``MEASURED_FACTOR`` but is used, why.

    It is not designed on where samples were filled in (a linear fill spreads its error over every
    bin) or too few bins are reliable.  Its design is set aside where a loop's crossover lies further
    than ``MEASURED_FACTOR`` from the model-based one's and nothing the response shows explains it:
    a corrupted measurement, or a plant that changed since the identification -- either way not one
    to write gains from unasked.  A mode it shows (one the rigid model lacks) explains it."""
    if frf.filled or frf.late:
        return (
            None,
            f"the master was late during the measurement ({frf.filled} position samples missing and filled "
            f"in, {frf.late} set-points and torque offsets late): the response holds its timing errors",
            None,
        )
    bins = int(frf.reliable().sum())
    if bins < MIN_MEASURED_BINS:
        return None, f"only {bins} bins are reliable (at least {MIN_MEASURED_BINS} are needed)", None
    mode, cap = _mode(axis, model, resonance, frf, controller, drive, before)
    try:
        design = design_gains(model["J"], model["c1"], R, L, frf, controller.timing, cap)
    except ValueError as exc:
        return None, f"no gains keep the margins on it ({exc}) while the model has some", None
    for loop in ("velocity", "position"):
        on_frf, on_model = getattr(design, loop).crossover_hz, getattr(reference, loop).crossover_hz
        ratio = max(on_frf / on_model, on_model / on_frf)
        if ratio <= MEASURED_FACTOR:
            continue
        departs = (
            f"the {loop} loop's crossover designed on it, {on_frf:.3g} Hz, is {ratio:.2g}× "
            f"{'below' if on_frf < on_model else 'above'} the model-based design's {on_model:.3g} Hz "
            f"(more than {MEASURED_FACTOR:g}×)"
        )
        shown = _mode_explains(frf, model, current_bandwidth(controller.timing.current_hz))
        if shown is None:
            return (design, mode), departs + " and the response shows no mode that explains it", None
        return (design, mode), None, f"{departs}: the mode at {shown:.3g} Hz the response shows explains it"
    return (design, mode), None, None


def _mode_explains(frf: Frf, model: dict[str, float], current_bw_rad_s: float) -> float | None:
    """The mode [Hz] the measured response shows on a plant the rigid model explains below it (its
    reliable bins under half the mode within ``MODE_AGREES`` of the model's, a few at least); None
    where it shows none, or where the response departs from the model everywhere (a wrong
    measurement, not a mode)."""
    f_mode = measured_mode(frf, model["J"], model["c1"], current_bw_rad_s)
    if f_mode is None:
        return None
    ok = frf.reliable() & (frf.frequency_hz < f_mode / 2)
    if ok.sum() < MODE_BELOW_BINS:
        return None
    rigid = rigid_response(model["J"], model["c1"], current_bw_rad_s, 2 * np.pi * frf.frequency_hz[ok])
    ratio = float(np.median(np.abs(frf.response[ok] / rigid)))
    return f_mode if 1 / MODE_AGREES <= ratio <= MODE_AGREES else None


def tune(
    models: dict[str, dict[str, float]],
    state: dict[str, dict],
    frfs: dict[str, Frf] | None = None,
    controller: Controller = Controller(),
    resonances: dict[str, dict | None] | None = None,
    drive: str = "drive",
) -> dict[str, AxisTuning]:
    """The cascade gains of every axis from its identified model.

    Parameters
    ----------
    models : dict of str to dict of str to float
        Per axis the identified model: J [kg·m²], c0 [Nm], c1 [Nm·s/rad].
    state : dict of str to dict
        Per axis what bring-up read (:func:`~drive_bridge.params.read.drive_state`): the motor's
        R [Ω] and L [H] and the parameters before.
    frfs : dict of str to Frf, optional
        Per axis the response measured through the drive: the margins are kept on it too.
    controller : Controller
        The controller the drive runs (its profile's: structure and loop rates).
    resonances : dict of str to dict, optional
        Per axis the mode identify found (frequency [Hz], damping).
    drive : str
        The drive's name, for the messages.

    Returns
    -------
    dict of str to AxisTuning
        Per axis the design (KpP [1/s], FwF [1], KpS [Nm·s/rad], KiS [1/s], KpC [V/A],
        KiC [1/s]), the loop margins before and after, and how a mode was met.

    Raises
    ------
    UserError
        An axis without a model, a model or motor data that cannot be designed for.
    """
    out = {}
    for a, st in state.items():
        if a not in models:
            raise UserError(
                f"axis {a}: no identified model (identify.json has {', '.join(models) or 'no axis'})"
            )
        before = st["parameters_before"]
        out[a] = tune_axis(
            a,
            models[a],
            st["motor"]["R"],
            st["motor"]["L"],
            {g: before[g] for g in GAINS if g in before},
            (frfs or {}).get(a),
            controller,
            (resonances or {}).get(a),
            drive,
        )
    return out


def tune_doc(results: dict[str, AxisTuning], unwritable: dict[str, list[str]] | None = None) -> dict:
    """tune.json's document.

    Parameters
    ----------
    results : dict of str to AxisTuning
        Per axis, its tuning.
    unwritable : dict of str to list of str, optional
        Per axis, the identified effects no drive parameter can carry (:func:`unwritable_effects`).

    Returns
    -------
    dict
        Per axis the model, gains before and after, margins, the parameters to write and
        ``not_writable``; stamped with the tool's version (schema ``tune``).
    """
    return stamped(
        "tune",
        {
            "axes": {
                a: {**t.as_dict(), "not_writable": (unwritable or {}).get(a, [])} for a, t in results.items()
            }
        },
    )


@dataclass
class TuneFile:
    """A ``tune`` result as written (:func:`read_tune_json`).

    Parameters
    ----------
    path : Path
        The file.
    parameters : dict of str to dict
        Per axis, the parameters to write, SI.
    inductance : dict of str to float or None
        Per axis, the motor inductance [H] its current loop was designed for (None in a file
        without it).
    """

    path: Path
    parameters: dict[str, dict[str, float]]
    inductance: dict[str, float | None]

    def only(self, config: BusConfig) -> TuneFile:
        """This result, checked against a bus configuration.

        Parameters
        ----------
        config : BusConfig
            The bus configuration the values are to be written on.

        Returns
        -------
        TuneFile
            This result.

        Raises
        ------
        UserError
            An axis of the file that ``config`` does not have.
        """
        unknown = [a for a in self.parameters if a not in config.nodes]
        if unknown:
            raise UserError(
                f"{self.path}: axis {unknown[0]!r} is not in {config.path} "
                f"(its axes: {', '.join(config.nodes)})"
            )
        return self


def read_tune_json(path: str | Path) -> TuneFile:
    """Read a ``tune`` result file.

    Parameters
    ----------
    path : str or Path
        tune.json.

    Returns
    -------
    TuneFile
        Per axis the parameters to write and the motor inductance [H].

    Raises
    ------
    UserError
        A file that is not a tune result, or a value that is not a number, named.
    """
    path = Path(path)
    axes = _axes_of(path, "tune result")
    params, inductance = {}, {}
    for a, r in axes.items():
        params[a] = _numbers(path, f"axes.{a}.parameters", r.get("parameters"))
        motor = r.get("motor")
        inductance[a] = _numbers(path, f"axes.{a}.motor", motor).get("L") if motor is not None else None
    return TuneFile(path, params, inductance)
