"""The effect library: what the base model J·q̈ + c1·q̇ + c0·sign(q̇) may lack.

Each effect adds regressor columns that are linear in its coefficients, given
its nonlinear parameters (``hyper``: a period, a Stribeck velocity, a time
constant), which the tracer tunes with differential evolution.  Effects are
deviations around the base model, so J, c0 and c1 keep their meaning:
friction in the direction of motion is c0 + dc0 and c1 + dc1, against it
c0 - dc0 and c1 - dc1.  Units follow the axis (rotary: rad, Nm; linear: m, N).

``depends_on`` names the variable the effect's residual depends on:
``constant``, ``position``, ``velocity``, ``direction``, ``time``, or
``<other axis>_position|_velocity|_acceleration``.
"""
from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from .signals import Samples


class Effect:
    name: ClassVar[str]
    depends_on: str
    coef_names: ClassVar[tuple[str, ...]]

    def __init__(self, **hyper: float):
        self.hyper = dict(hyper)
        self.bounds: dict[str, tuple[float, float]] = {}      # hyper -> search range for tuning

    def columns(self, s: Samples) -> np.ndarray:
        """Regressor columns (n × len(coef_names)) at the samples ``s``."""
        raise NotImplementedError

    def params(self, coef: np.ndarray) -> dict[str, float | str]:
        """Physical parameters from the fitted coefficients (and the hyper-parameters)."""
        return dict(zip(self.coef_names, map(float, coef)))

    def param_std(self, coef: np.ndarray, cov: np.ndarray) -> dict[str, float]:
        return {k: float(math.sqrt(cov[i, i])) for i, k in enumerate(self.coef_names)}

    def label(self) -> str:
        return self.name

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.hyper})"


class Offset(Effect):
    """A constant torque: gravity on a vertical axis, a measurement offset (paper's D)."""

    name, depends_on, coef_names = "offset", "constant", ("offset",)

    def columns(self, s):
        return np.ones((len(s), 1))


class PositionLinear(Effect):
    """Torque proportional to position (the paper's cp): a spring, a cable carrier."""

    name, depends_on, coef_names = "position_linear", "position", ("cp",)

    def columns(self, s):
        return s.q[:, None]


class PositionPeriodic(Effect):
    """A sin(2π q / period + phase): cogging, belt-tooth or screw-lead ripple."""

    name, depends_on, coef_names = "position_periodic", "position", ("a_sin", "a_cos")

    def __init__(self, period: float):
        super().__init__(period=period)
        self.bounds = {"period": (0.9 * period, 1.1 * period)}     # the spectrum's resolution

    def columns(self, s):
        x = 2 * np.pi * s.q / self.hyper["period"]
        return np.column_stack((np.sin(x), np.cos(x)))

    def params(self, coef):
        a, b = coef
        return {"amplitude": float(math.hypot(a, b)), "period": self.hyper["period"],
                "phase": float(math.atan2(b, a))}

    def param_std(self, coef, cov):
        a, b = coef
        amp = math.hypot(a, b) or 1.0
        return {"amplitude": float(math.sqrt(max(0.0, (a * a * cov[0, 0] + b * b * cov[1, 1]
                                                       + 2 * a * b * cov[0, 1]) / amp ** 2)))}


class Stribeck(Effect):
    """Extra friction near standstill: amplitude · exp(-(q̇/velocity)²) · sign(q̇)."""

    name, depends_on, coef_names = "stribeck", "velocity", ("amplitude",)

    def __init__(self, velocity: float, low: float, high: float):
        super().__init__(velocity=velocity)
        self.bounds = {"velocity": (low, high)}

    def columns(self, s):
        return (np.exp(-(s.qd / self.hyper["velocity"]) ** 2) * np.sign(s.qd))[:, None]

    def params(self, coef):
        return {"amplitude": float(coef[0]), "velocity": self.hyper["velocity"]}


class DirectionAsymmetry(Effect):
    """Friction that differs with the direction of motion: c1 ± dc1, c0 ± dc0.

    While moving, dc0 is a constant torque: with an offset already in the model
    the two cannot be told apart and only dc1 is fitted.
    """

    name, depends_on = "direction_asymmetry", "direction"

    def __init__(self, with_dc0: bool = True):
        super().__init__()
        self.coef_names = ("dc1", "dc0") if with_dc0 else ("dc1",)

    def columns(self, s):
        cols = [np.abs(s.qd)]
        if len(self.coef_names) == 2:
            cols.append(np.ones(len(s)))
        return np.column_stack(cols)


class CrossAxis(Effect):
    """Coupling with another axis of the same log.

    ``form``: ``position_friction`` (Coulomb friction changing with the other
    axis's position: coef · q_src · sign(q̇)), ``position`` (coef · q_src),
    ``velocity`` (coef · q̇_src) or ``acceleration`` (coef · q̈_src, inertial).
    """

    name, coef_names = "cross_axis", ("coefficient",)
    FORMS = ("position_friction", "position", "velocity", "acceleration")

    def __init__(self, source: str, form: str):
        super().__init__()
        self.source, self.form = source, form
        self.depends_on = f"{source}_{'position' if form.startswith('position') else form}"

    def columns(self, s):
        q, qd, qdd = s.others[self.source]
        col = {"position_friction": q * np.sign(s.qd), "position": q, "velocity": qd, "acceleration": qdd}
        return col[self.form][:, None]

    def params(self, coef):
        return {"source": self.source, "form": self.form, "coefficient": float(coef[0])}

    def label(self):
        return f"cross_axis({self.source}, {self.form})"


class Drift(Effect):
    """Coulomb friction that changes with time (warm-up): amplitude · exp(-t/time_constant) · sign(q̇)."""

    name, depends_on, coef_names = "drift", "time", ("amplitude",)

    def __init__(self, time_constant: float, low: float, high: float):
        super().__init__(time_constant=time_constant)
        self.bounds = {"time_constant": (low, high)}

    def columns(self, s):
        return (np.exp(-s.t / self.hyper["time_constant"]) * np.sign(s.qd))[:, None]

    def params(self, coef):
        return {"amplitude": float(coef[0]), "time_constant_s": self.hyper["time_constant"]}


LIBRARY = ("offset", "position_linear", "position_periodic", "stribeck", "direction_asymmetry",
           "cross_axis", "drift")


def position_period(s: Samples, residual: np.ndarray) -> float | None:
    """Period [rad | m] of the strongest periodic component of ``residual`` over position.

    The residual is averaged in bins of position (a uniform grid, whatever the
    speed), gaps are interpolated, and the spectrum of that profile gives the
    period; at least 3 periods must fit in the travelled range.
    """
    q = s.q
    span = float(np.ptp(q))
    step = float(np.median(np.abs(np.diff(q))))
    if span <= 0 or step <= 0:
        return None
    n_bins = int(min(8192, max(64, span / step)))
    idx = np.minimum(((q - q.min()) / span * n_bins).astype(int), n_bins - 1)
    counts = np.bincount(idx, minlength=n_bins)
    filled = counts > 0
    if filled.sum() < 16:
        return None
    profile = np.bincount(idx, residual, minlength=n_bins)[filled] / counts[filled]
    grid = np.arange(n_bins)
    profile = np.interp(grid, grid[filled], profile)
    spectrum = np.abs(np.fft.rfft(profile - profile.mean()))
    cycles = np.arange(len(spectrum))                  # periods per travelled range
    valid = cycles >= 3
    if not valid.any():
        return None
    best = int(cycles[valid][np.argmax(spectrum[valid])])
    return span / best


def candidates(present: list[Effect], s: Samples, residual: np.ndarray) -> list[Effect]:
    """Effects not yet in the model that the residual could reveal, with starting hyper-parameters."""
    names = {e.name for e in present}
    m = s.moving
    out: list[Effect] = []
    if "offset" not in names:
        out.append(Offset())
    if "position_linear" not in names:
        out.append(PositionLinear())
    if "position_periodic" not in names:
        period = position_period(s.take(m), residual[m])
        if period:
            out.append(PositionPeriodic(period))
    vmax = float(np.max(np.abs(s.qd[m])))
    vmin = float(np.min(np.abs(s.qd[m])))
    if "stribeck" not in names:
        out.append(Stribeck(0.1 * vmax, max(vmin, 0.01 * vmax), 0.5 * vmax))
    if "direction_asymmetry" not in names:
        out.append(DirectionAsymmetry(with_dc0="offset" not in names))
    if "drift" not in names:
        duration = float(np.ptp(s.t))
        out.append(Drift(duration / 5, duration / 100, 3 * duration))
    coupled = {(e.source, e.form) for e in present if isinstance(e, CrossAxis)}
    for src in s.others:
        for form in CrossAxis.FORMS:
            if (src, form) not in coupled:
                out.append(CrossAxis(src, form))
    return out
