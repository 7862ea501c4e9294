"""``tune``: from identified axis models to gains and the parameter set to write (Python API)."""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from ..errors import UserError
from .design import GainDesign, Margins, design_gains, loop_margins
from .experiment import ExperimentResult

#: identify's parameter names -> the drive's model parameters
MODEL_KEYS = {"J": "J", "c0": "c0", "c1": "c1", "offset.offset": "offset", "position_linear.cp": "cp",
              "direction_asymmetry.dc0": "dc0", "direction_asymmetry.dc1": "dc1",
              "position_periodic.amplitude": "periodic_amplitude", "position_periodic.period": "periodic_period",
              "position_periodic.phase": "periodic_phase"}
GAINS = ("KpP", "FwF", "KpS", "KiS", "KpC", "KiC")


@dataclass
class AxisTuning:
    axis: str
    model: dict[str, float]                 # J, c0, c1 (+ effect terms), SI motor side
    design: GainDesign
    before: dict[str, float]                # the drive's gains before tuning
    before_margins: tuple[Margins, Margins] | None
    experiment: ExperimentResult | None = None

    def parameters(self) -> dict[str, float]:
        """Everything to write: the designed gains, the model, and the model feed-forward on."""
        return {**self.design.gains(), **self.model, "ff_enable": 1.0}

    def as_dict(self) -> dict:
        return {"model": self.model, "gains": self.design.gains(), "gains_before": self.before,
                "margins": {"velocity": vars(self.design.velocity), "position": vars(self.design.position)},
                "margins_before": None if self.before_margins is None else
                {"velocity": vars(self.before_margins[0]), "position": vars(self.before_margins[1])},
                "experiment": None if self.experiment is None else self.experiment.as_dict(),
                "parameters": self.parameters()}


def model_from_identify(params: dict[str, float]) -> dict[str, float]:
    """The drive-model subset of ``identify``'s parameters (effects the drive cannot add are left out)."""
    return {short: float(params[key]) for key, short in MODEL_KEYS.items() if key in params}


def drive_model(parameters: dict[str, float]) -> dict[str, float]:
    """The model part (J, c0, c1 and effect terms) of a parameter set to write."""
    return {k: v for k, v in parameters.items() if k in MODEL_KEYS.values()}


def read_identify_json(path: str | Path) -> dict[str, dict[str, float]]:
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
        return {a: model_from_identify(r["params"]) for a, r in doc["axes"].items()}
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise UserError(f"{path}: not an identify --json result ({exc})") from exc


def tune_axis(axis: str, model: dict[str, float], R: float, L: float, before: dict[str, float]) -> AxisTuning:
    try:
        design = design_gains(model["J"], model["c1"], R, L)
    except (KeyError, ValueError) as exc:
        raise UserError(f"axis {axis}: cannot design gains from the model {model}: {exc}") from exc
    margins = loop_margins(model["J"], model["c1"], before, R, L) if set(GAINS) <= set(before) else None
    return AxisTuning(axis, model, design, before, margins)


def tune_axes(models: dict[str, dict[str, float]], state: dict[str, dict]) -> dict[str, AxisTuning]:
    """The tune step: gains for every axis of ``state`` (what bring-up read:
    :func:`~drive_bridge.params.read.drive_state`) from its identified model in ``models``."""
    out = {}
    for a, st in state.items():
        if a not in models:
            raise UserError(f"axis {a}: no identified model (identify.json has {', '.join(models) or 'no axis'})")
        before = st["parameters_before"]
        out[a] = tune_axis(a, models[a], st["motor"]["R"], st["motor"]["L"],
                           {g: before[g] for g in GAINS if g in before})
    return out


def tune_doc(results: dict[str, AxisTuning]) -> dict:
    """tune.json: per axis the model, gains before and after, margins, the parameters to write."""
    return {"axes": {a: t.as_dict() for a, t in results.items()}}


def read_tune_json(path: str | Path) -> dict[str, dict[str, float]]:
    """axis -> parameters to write, from a ``tune`` result file."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
        return {a: {k: float(v) for k, v in r["parameters"].items()} for a, r in doc["axes"].items()}
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise UserError(f"{path}: not a tune result ({exc})") from exc
