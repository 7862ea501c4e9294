"""The effect library: what the base model J·q̈ + c1·q̇ + c0·sign(q̇) may lack.

Each effect adds regressor columns that are linear in its coefficients, given
its nonlinear parameters (a period, a Stribeck velocity, a time constant),
which its ``fit`` learns with differential evolution.  Effects are
deviations around the base model, so J, c0 and c1 keep their meaning:
friction in the direction of motion is c0 + dc0 and c1 + dc1, against it
c0 - dc0 and c1 - dc1.  Units follow the axis (rotary: rad, Nm; linear: m, N).

``depends_on`` names the variable the effect's residual depends on:
``constant``, ``position``, ``velocity``, ``direction``, ``time``, or
``<other axis>_position|_velocity|_acceleration``.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable, Container, Iterator
from typing import ClassVar

import numpy as np
from scipy import optimize

from ..errors import InternalError
from .dependence import dependences, variables
from .signals import Samples, Signals

#: the effects a drive's model (or the master's feed-forward of it) carries: their terms are the drive
#: model's parameters (:data:`drive_bridge.tuning.feedforward.MODEL_KEYS`); any other is reported, not written
DRIVE_EFFECTS = ("offset", "position_linear", "direction_asymmetry", "position_periodic")


SEARCH_SAMPLES = 8192  # an effect's nonlinear parameters searched on about this many samples (Effect.fit)


class NotFittedError(InternalError):
    """An effect's columns were asked for before ``fit`` learned its nonlinear parameters."""


class Effect:
    """One term the base model may lack (scikit-learn's estimator conventions).

    The constructor's keyword parameters (``get_params``) are the starting values and
    search ranges of the effect's nonlinear parameters and are never changed; ``fit``
    learns those parameters, stored with a trailing underscore (``period_``).  The linear
    coefficients (``coef_names``) are fitted jointly with the whole model by
    :class:`~drive_bridge.ident.model.AxisModel`.
    """

    name: str  # the effect's name in reports (may be per instance)
    coef_names: tuple[str, ...]  # its linear coefficients (may depend on the instance)
    nonlinear: ClassVar[tuple[str, ...]] = ()  # nonlinear parameters, learned by fit as <name>_
    #: regressor columns (n × len(coef_names)) at the signals, with the nonlinear parameters given
    #: by keyword (``odd``: their magnitude)
    _columns: Callable[..., np.ndarray]

    @property
    def depends_on(self) -> str:
        """The variable the effect's residual depends on (see the module's docstring)."""
        raise NotImplementedError

    @property
    def linear_in_signals(self) -> bool:
        """Columns linear in the filtered signals (a constant, the position) are filtered as the
        torque is already; any other column is computed at the log's rate and filtered alike."""
        return False

    @property
    def odd(self) -> bool:
        """Friction-like: ``_columns`` is a magnitude, the columns are it times the direction of
        motion, made at the log's rate and filtered whole, as the torque and the Coulomb column
        are (the direction is zero at a standstill).  Filtered apart and multiplied, a magnitude
        peaked at standstill (Stribeck) lost its step at each reversal to the low-pass while the
        torque kept it: the mismatch, in the samples next to the reversals, read as inertia."""
        return False

    def get_params(self) -> dict:
        """The constructor's keyword parameters and their values.

        Returns
        -------
        dict
            Name -> value (the starting values and search ranges; never changed by ``fit``).
        """
        init = type(self).__init__
        if init is object.__init__:
            return {}
        return {
            k: getattr(self, k)
            for k, p in inspect.signature(init).parameters.items()
            if k != "self" and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)
        }

    def bounds(self) -> dict[str, tuple[float, float]]:
        """Search range of each nonlinear parameter.

        Returns
        -------
        dict of str to (float, float)
            Name -> (low, high), in the parameter's unit; empty for an effect without one.
        """
        return {}

    def _signed(self, s: Signals, cols: np.ndarray) -> np.ndarray:
        return cols * s.sgn[:, None] if self.odd else cols

    def columns(self, s: Samples, logged: bool = False) -> np.ndarray:
        """The effect's regressor columns, with the fitted nonlinear parameters.

        Parameters
        ----------
        s : Samples
            The samples.
        logged : bool
            Filtered and decimated as the torque as logged is, not as the filtered torque
            (:meth:`~.signals.Samples.parallel`).

        Returns
        -------
        numpy.ndarray
            n × len(``coef_names``).

        Raises
        ------
        NotFittedError
            An effect with nonlinear parameters that ``fit`` has not learned.
        """
        learned: dict[str, float] = {}
        for k in self.nonlinear:
            if not hasattr(self, k + "_"):
                raise NotFittedError(f"{self!r}: fit it before asking for its columns")
            learned[k] = getattr(self, k + "_")
        if self.linear_in_signals:
            return self._signed(s, self._columns(s, **learned))
        key = (type(self).__name__, str(self.get_params()), tuple(learned.values()))
        return s.parallel(key, lambda ch: self._signed(ch, self._columns(ch, **learned)), logged)

    def fit(self, s: Samples, fixed: np.ndarray, y: np.ndarray, seed: int = 0) -> Effect:
        """Learn the nonlinear parameters on samples ``s`` against the observation ``y``, with the
        columns ``fixed`` (the model so far) solved by least squares inside (variable projection):
        differential evolution seeded with ``seed`` finds the minimum on every ``n //
        SEARCH_SAMPLES``-th sample, L-BFGS-B polishes it on them all (on a log of up to
        ``SEARCH_SAMPLES`` samples: scipy's own polish).  An effect without nonlinear parameters
        has nothing to learn.

        Parameters
        ----------
        s : Samples
            The samples the columns are made at (the moving ones).
        fixed : numpy.ndarray
            The model so far's columns at them, n × p.
        y : numpy.ndarray
            The observation: the filtered torque at them [Nm | N].
        seed : int
            Seed of the differential evolution.

        Returns
        -------
        Effect
            This effect, its nonlinear parameters learned (``<name>_``).
        """
        if not self.nonlinear:
            return self
        bounds = [self.bounds()[k] for k in self.nonlinear]
        full = self._sse(s, fixed, y)
        every = max(1, len(y) // SEARCH_SAMPLES)
        search = (
            full
            if every == 1
            else self._sse(s.take(np.arange(len(y)) % every == 0), fixed[::every], y[::every])
        )
        x = optimize.differential_evolution(
            search, bounds, seed=seed, popsize=8, maxiter=25, tol=1e-6, polish=False
        ).x
        polished = optimize.minimize(full, x, method="L-BFGS-B", bounds=bounds)
        if polished.fun < full(x):
            x = polished.x
        for k, v in zip(self.nonlinear, x):
            setattr(self, k + "_", float(v))
        return self

    def _sse(self, s: Samples, fixed: np.ndarray, y: np.ndarray) -> Callable[[np.ndarray], float]:
        """The sum of squared errors of ``y`` with the columns ``fixed`` and this effect's at the
        nonlinear parameters given, every coefficient solved (the fixed columns projected out once)."""
        scale = np.sqrt(np.mean(fixed**2, axis=0))
        scale[scale == 0] = 1.0
        q, _ = np.linalg.qr(fixed / scale)
        y_perp = y - q @ (q.T @ y)
        yy = float(y_perp @ y_perp)

        def sse(x: np.ndarray) -> float:
            extra = self._signed(s, self._columns(s, **dict(zip(self.nonlinear, x))))
            # the few extra columns' least squares through their Gram matrix (k × k) with the
            # fixed columns projected out, G = XᵀX − (QᵀX)ᵀ(QᵀX), b = Xᵀy⊥ (y⊥ has no part along
            # Q), and the error y⊥ᵀy⊥ − bᵀG⁻¹b: no n × k product beyond QᵀX (an n × k SVD was
            # once most of the search's time, the projected columns and the residual the rest)
            along = q.T @ extra
            gram = extra.T @ extra - along.T @ along
            b = extra.T @ y_perp
            # (through its eigenvalues, those below lstsq's own cut-off left out: a column the
            # fixed ones nearly span explains nothing, not everything by round-off)
            value, vector = np.linalg.eigh(gram)
            kept = value > np.finfo(float).eps * len(value) * value[-1]
            along_b = vector[:, kept].T @ b
            return max(yy - float(along_b @ (along_b / value[kept])), 0.0)

        return sse

    def params(self, coef: np.ndarray) -> dict[str, float | str]:
        """Physical parameters from the fitted coefficients.

        Parameters
        ----------
        coef : numpy.ndarray
            The effect's coefficients (``coef_names`` order).

        Returns
        -------
        dict
            Name -> value, SI (and the learned nonlinear parameters; a name where the effect has
            one, as a coupling's source).
        """
        return dict(zip(self.coef_names, map(float, coef)))

    def param_std(self, coef: np.ndarray, cov: np.ndarray) -> dict[str, float]:
        """The std of the physical parameters.

        Parameters
        ----------
        coef : numpy.ndarray
            The effect's coefficients.
        cov : numpy.ndarray
            Their covariance.

        Returns
        -------
        dict of str to float
            Name -> std, SI.
        """
        return {k: float(math.sqrt(max(cov[i, i], 0.0))) for i, k in enumerate(self.coef_names)}

    def __repr__(self) -> str:
        return f"{type(self).__name__}({', '.join(f'{k}={v!r}' for k, v in self.get_params().items())})"


class Offset(Effect):
    """A constant torque: gravity on a vertical axis, a measurement offset (paper's D), or the
    constant part of a direction asymmetry of Coulomb friction (dc0·s·s = dc0)."""

    name, depends_on, coef_names = "offset", "constant", ("offset",)
    linear_in_signals = True

    def _columns(self, s: Signals) -> np.ndarray:
        return np.ones((len(s), 1))


class Gravity(Effect):
    """A weight on a rotary joint: a·cos q + b·sin q, one period per turn of the joint (the log's
    position is the joint's angle, 0 wherever its zero is); ``amplitude`` is the largest gravity
    torque, at ``angle`` (where the weight's arm is horizontal).  On a linear axis gravity is a
    constant: the offset."""

    name, depends_on, coef_names = "gravity", "position", ("a_cos", "b_sin")

    def _columns(self, s: Signals) -> np.ndarray:
        return np.column_stack((np.cos(s.q), np.sin(s.q)))

    def params(self, coef: np.ndarray) -> dict[str, float | str]:
        a, b = map(float, coef)
        return {"a_cos": a, "b_sin": b, "amplitude": math.hypot(a, b), "angle": math.atan2(b, a)}


class PositionLinear(Effect):
    """Torque proportional to position (the paper's cp): a spring, a cable carrier."""

    name, depends_on, coef_names = "position_linear", "position", ("cp",)
    linear_in_signals = True

    def _columns(self, s: Signals) -> np.ndarray:
        return s.q[:, None]


class PositionPeriodic(Effect):
    """A sin(2π q / period + phase): cogging, belt-tooth or screw-lead ripple.

    An axis may have several (a motor's torque ripple and a cogging at another period): the
    ``order``-th is named ``position_periodic_<order>`` from the second on.

    Parameters
    ----------
    period : float
        The starting value [rad | m] (from the residual's spectrum over position).
    spread : float
        ``fit`` searches ``period`` ± this share of it (the spectrum's resolution) and learns
        ``period_``.
    order : int
        Which of the axis's periodic terms this is (1: the first).
    """

    depends_on, coef_names, nonlinear = "position", ("a_sin", "a_cos"), ("period",)
    period_: float

    def __init__(self, period: float, spread: float = 0.1, order: int = 1):
        self.period, self.spread, self.order = period, spread, order
        self.name = "position_periodic" if order == 1 else f"position_periodic_{order}"

    def bounds(self) -> dict[str, tuple[float, float]]:
        return {"period": ((1 - self.spread) * self.period, (1 + self.spread) * self.period)}

    def _columns(self, s: Signals, period: float) -> np.ndarray:
        x = 2 * np.pi * s.q / period
        return np.column_stack((np.sin(x), np.cos(x)))

    def params(self, coef: np.ndarray) -> dict[str, float | str]:
        a, b = coef
        return {
            "amplitude": float(math.hypot(a, b)),
            "period": self.period_,
            "phase": float(math.atan2(b, a)),
        }

    def param_std(self, coef: np.ndarray, cov: np.ndarray) -> dict[str, float]:
        a, b = coef
        amp = math.hypot(a, b) or 1.0
        return {
            "amplitude": float(
                math.sqrt(max(0.0, (a * a * cov[0, 0] + b * b * cov[1, 1] + 2 * a * b * cov[0, 1]) / amp**2))
            )
        }


class Stribeck(Effect):
    """Extra friction near standstill: amplitude · exp(-(q̇/velocity)²) · sign(q̇), with q̇ over the
    log's band: it changes within a filter period of each reversal.

    Parameters
    ----------
    velocity : float
        The Stribeck velocity's starting value [rad/s | m/s]; ``fit`` learns ``velocity_``.
    low, high : float
        Its search range [rad/s | m/s].
    """

    name, depends_on, coef_names, nonlinear = "stribeck", "velocity", ("amplitude",), ("velocity",)
    odd = True
    velocity_: float

    def __init__(self, velocity: float, low: float, high: float):
        self.velocity, self.low, self.high = velocity, low, high

    def bounds(self) -> dict[str, tuple[float, float]]:
        return {"velocity": (self.low, self.high)}

    def _columns(self, s: Signals, velocity: float) -> np.ndarray:
        return np.exp(-((s.qd_band / velocity) ** 2))[:, None]

    def params(self, coef: np.ndarray) -> dict[str, float | str]:
        return {"amplitude": float(coef[0]), "velocity": self.velocity_}


class DirectionAsymmetry(Effect):
    """Friction that differs with the direction of motion: c1 ± dc1, c0 ± dc0.

    While moving, dc0 is a constant torque: with an offset already in the model
    the two cannot be told apart.

    Parameters
    ----------
    with_dc0 : bool
        Fit dc0 too (False: dc1 only, where the model has an offset).
    """

    name, depends_on = "direction_asymmetry", "direction"

    def __init__(self, with_dc0: bool = True):
        self.with_dc0 = with_dc0
        self.coef_names = ("dc1", "dc0") if with_dc0 else ("dc1",)

    def _columns(self, s: Signals) -> np.ndarray:
        cols = [np.abs(s.qd)]
        if self.with_dc0:
            cols.append(np.ones(len(s)))
        return np.column_stack(cols)


class CrossAxis(Effect):
    """Coupling with another axis of the same log.

    Parameters
    ----------
    source : str
        The other axis.
    form : {"position_friction", "position", "velocity", "acceleration"}
        ``position_friction``: Coulomb friction changing with the other axis's position
        (coef · q_src · sign(q̇)); ``position``: coef · q_src; ``velocity``: coef · q̇_src;
        ``acceleration``: coef · q̈_src (inertial).
    """

    name, coef_names = "cross_axis", ("coefficient",)
    FORMS = ("position_friction", "position", "velocity", "acceleration")

    def __init__(self, source: str, form: str):
        self.source, self.form = source, form

    @property
    def depends_on(self) -> str:
        return f"{self.source}_{'position' if self.form.startswith('position') else self.form}"

    @property
    def odd(self) -> bool:  # the friction form: q_src times sign(q̇)
        return self.form == "position_friction"

    @property
    def linear_in_signals(self) -> bool:  # q_src, q̇_src, q̈_src: filtered already
        return True

    def _columns(self, s: Signals) -> np.ndarray:
        q, qd, qdd = s.others[self.source]
        col = {"position_friction": q, "position": q, "velocity": qd, "acceleration": qdd}
        return col[self.form][:, None]

    def params(self, coef: np.ndarray) -> dict[str, float | str]:
        return {"source": self.source, "form": self.form, "coefficient": float(coef[0])}


class Drift(Effect):
    """Coulomb friction that changes with time (warm-up):
    amplitude · (exp(-t/time_constant) − its mean over [``start``, ``end``]) · sign(q̇).

    Centred on the log's span, so c0 stays the Coulomb friction over the log (not an
    extrapolation to the end of a warm-up the log may never reach).

    Parameters
    ----------
    time_constant : float
        Its starting value [s]; ``fit`` learns ``time_constant_``.
    low, high : float
        Its search range [s].
    start, end : float
        The log's span [s].
    """

    name, depends_on, coef_names, nonlinear = "drift", "time", ("amplitude",), ("time_constant",)
    odd = True
    time_constant_: float

    def __init__(self, time_constant: float, low: float, high: float, start: float = 0.0, end: float = 0.0):
        self.time_constant, self.low, self.high, self.start, self.end = time_constant, low, high, start, end

    def bounds(self) -> dict[str, tuple[float, float]]:
        return {"time_constant": (self.low, self.high)}

    def _columns(self, s: Signals, time_constant: float) -> np.ndarray:
        span = self.end - self.start
        mean = (
            time_constant * (np.exp(-self.start / time_constant) - np.exp(-self.end / time_constant)) / span
            if span > 0
            else 0.0
        )
        return (np.exp(-s.t / time_constant) - mean)[:, None]

    def params(self, coef: np.ndarray) -> dict[str, float | str]:
        return {"amplitude": float(coef[0]), "time_constant_s": self.time_constant_}


class Spline(Effect):
    """A smooth torque in one variable that no named effect describes: a cubic B-spline over the
    variable's range (interior ``knots`` at quantiles of the samples), ``even`` (the same torque
    both ways: cogging, gravity, a spring), ``odd`` (times the direction of motion: friction
    that changes along the stroke, with the load, with temperature) or ``inertial`` (times the
    acceleration: an inertia that changes along the stroke, J(q) = J + spline(q)).

    The spline never duplicates a term the model has by name: its basis is made orthogonal, over
    the variable's range (``grid``: evenly spaced points of it), to a constant and a
    straight line (even: the offset, cp·q, c1·q̇, J·q̈) or to a constant (odd: c0·sign(q̇);
    inertial: J·q̈), over the axis's own velocity to its sign as well (c0·sign(q̇)), and
    reduced to a full-rank set (SVD), deterministically from the constructor's parameters.

    Parameters
    ----------
    variable : str
        The variable (:func:`~.dependence.variables`: position, velocity, an other axis's ...).
    form : {"even", "odd", "inertial"}
        As above.
    knots : tuple of float
        The interior knots, in the variable's unit.
    low, high : float
        The variable's range.
    grid : tuple of float
        Evenly spaced points of the range the basis is made orthogonal over.
    """

    GRID = 512

    def __init__(
        self,
        variable: str,
        form: str,
        knots: tuple[float, ...],
        low: float,
        high: float,
        grid: tuple[float, ...],
    ):
        self.variable, self.form, self.knots, self.low, self.high = variable, form, tuple(knots), low, high
        self.grid = tuple(grid)
        self.name = f"spline_{form}_{variable}"
        x = np.asarray(self.grid)
        basis = self._basis(x)
        terms = [np.ones_like(x)]
        if form == "even":
            terms.append(x)
        if variable == "velocity":  # over its own velocity: a friction curve
            terms.append(np.sign(x))
        removed = np.column_stack(terms)
        orthogonal = basis - removed @ np.linalg.lstsq(removed, basis, rcond=None)[0]
        _, sv, vt = np.linalg.svd(orthogonal, full_matrices=False)
        reduce = vt[: int(np.sum(sv > 1e-9 * sv[0]))].T
        self._on_grid = orthogonal @ reduce  # the columns at the grid points
        self.coef_names = tuple(f"b{i + 1}" for i in range(reduce.shape[1]))

    def get_params(self) -> dict:
        return {
            "variable": self.variable,
            "form": self.form,
            "knots": self.knots,
            "low": self.low,
            "high": self.high,
            "grid": self.grid,
        }

    def __repr__(self) -> str:
        return (
            f"Spline(variable={self.variable!r}, form={self.form!r}, knots={len(self.knots)}, "
            f"low={self.low:.6g}, high={self.high:.6g})"
        )

    @property
    def depends_on(self) -> str:
        return self.variable

    def _basis(self, x: np.ndarray) -> np.ndarray:
        from scipy.interpolate import BSpline

        t = np.concatenate([[self.low] * 4, self.knots, [self.high] * 4])
        return BSpline.design_matrix(np.clip(x, self.low, self.high), t, 3).toarray()

    def _columns(self, s: Signals) -> np.ndarray:
        """The columns at the grid, linear between its points (512 over the range: far finer than
        the knots), at the variable's values held within [low, high]."""
        x = np.clip(variables(s)[self.variable], self.low, self.high)
        grid = np.asarray(self.grid)
        cols = np.column_stack([np.interp(x, grid, c) for c in self._on_grid.T])
        return cols * s.qdd[:, None] if self.form == "inertial" else cols

    @property
    def odd(self) -> bool:
        return self.form == "odd"

    def params(self, coef: np.ndarray) -> dict[str, float | str]:
        return {
            "variable": self.variable,
            "form": self.form,
            "low": self.low,
            "high": self.high,
            **{f"b{i + 1}": float(c) for i, c in enumerate(coef)},
        }


SPLINE_KNOTS = (3, 6, 10)  # smoothness candidates: interior knots (validation chooses)
SPLINE_SHARE = 0.15  # a variable the residual depends on by this share of its variance ...
SPLINE_P = 1e-3  # ... at this ANOVA p-value gets spline candidates
STILL_SHARE = 0.01  # another axis whose RMS speed is below this share of the axis's own stands still


def shape_of(e: Effect) -> tuple[str, str]:
    """The shape of the torque an effect adds, as a spline names it.

    Parameters
    ----------
    e : Effect
        The effect.

    Returns
    -------
    (str, str)
        (variable, form); a torque over the axis's own velocity, friction or not, is one even
        shape in the signed velocity.
    """
    if isinstance(e, Spline):
        return e.variable, e.form
    if e.depends_on in ("velocity", "direction"):
        return "velocity", "even"
    return e.depends_on, "odd" if e.odd else "even"


def standing_others(s: Samples) -> set[str]:
    """The other axes of the log that stand still while this one moves (RMS speed below
    ``STILL_SHARE`` of its own): their position is a constant there, their velocity and
    acceleration numerical dust.

    Parameters
    ----------
    s : Samples
        The axis's samples, with the other axes' at the same instants.

    Returns
    -------
    set of str
        Those axes.
    """
    m = s.moving
    own = float(np.sqrt(np.mean(s.qd[m] ** 2)))
    return {o for o, (_, qd, _) in s.others.items() if np.sqrt(np.mean(qd[m] ** 2)) < STILL_SHARE * own}


#: variables no spline is tried in: the direction alone (c0 and the asymmetry have it), and the axis's own
#: acceleration -- a rigid axis has no torque in it but J·q̈, and on a near-sinusoidal motion, whose
#: acceleration is nearly proportional to position, a spline in it rebuilds J·q̈ and a gravity term alike
#: and takes the inertia with it (a dependence on it stays in the unexplained list)
NO_SPLINE_IN = ("direction", "acceleration")


def spline_candidates(
    present: list[Effect], s: Samples, residual: np.ndarray, taken: Container[tuple[str, str]] = ()
) -> Iterator[Effect]:
    """Even or odd splines in each variable the residual depends on (not in ``NO_SPLINE_IN``),
    at each smoothness of ``SPLINE_KNOTS``; made as they are asked for, and none of a shape
    (:func:`shape_of`) in ``taken`` as it stands then (a named effect of that shape passed: its
    columns are not even filtered).

    Parameters
    ----------
    present : list of Effect
        The model's effects so far.
    s : Samples
        The estimation samples.
    residual : numpy.ndarray
        The model's residual at them [Nm | N].
    taken : container of (str, str)
        Shapes a named effect adds significantly this round.

    Yields
    ------
    Spline
        Each candidate, unfitted.
    """
    have = {e.name for e in present}
    m = s.moving
    still = standing_others(s)
    for d in dependences(s, residual, SPLINE_SHARE, SPLINE_P):
        name = f"spline_{d['form']}_{d['depends_on']}"
        if (
            d["depends_on"] in NO_SPLINE_IN
            or name in have
            or d["depends_on"].rsplit("_", 1)[0] in still
            or (d["depends_on"], d["form"]) in taken
        ):
            continue  # (another axis standing still: its signals are numerical dust)
        x = variables(s)[d["depends_on"]][m]
        low, high = float(np.min(x)), float(np.max(x))
        if not high > low or len(np.unique(x)) < 4 * (max(SPLINE_KNOTS) + 4):
            continue  # a still or coarsely quantised variable carries no smooth shape
        for k in SPLINE_KNOTS:
            knots = np.unique(np.quantile(x, np.linspace(0, 1, k + 2)[1:-1]))
            knots = knots[(knots > low) & (knots < high)]
            if len(knots) < k:
                break  # the samples sit on a few values (a still axis, quantised)
            grid = np.linspace(low, high, Spline.GRID)
            try:
                spline = Spline(
                    d["depends_on"], d["form"], tuple(map(float, knots)), low, high, tuple(map(float, grid))
                )
            except (np.linalg.LinAlgError, ValueError):
                break  # a basis the variable's samples cannot carry
            if not np.all(np.isfinite(spline.columns(s))):
                break
            yield spline


MAX_PERIODIC = 3  # periodic terms at different periods an axis may carry


def position_period(s: Samples, residual: np.ndarray) -> float | None:
    """Period [rad | m] of the strongest periodic component of ``residual`` over position.

    The residual is averaged in bins of position (a uniform grid, whatever the speed, as fine as
    the slow passes' spacing -- the 10th percentile of the steps -- so that a short period is not
    averaged away where the fast ones skip it), gaps are interpolated, and the spectrum of that
    profile gives the period; at least 3 periods must fit in the travelled range.

    Parameters
    ----------
    s : Samples
        The (moving) samples.
    residual : numpy.ndarray
        The residual at them [Nm | N].

    Returns
    -------
    float or None
        The period [rad | m]; None where the range or the samples allow none.
    """
    q = s.q
    span = float(np.ptp(q))
    step = float(
        np.percentile(np.abs(np.diff(q)), 10)
    )  # the slow passes' spacing: a short period shows there
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
    cycles = np.arange(len(spectrum))  # periods per travelled range
    valid = cycles >= 3
    if not valid.any():
        return None
    best = int(cycles[valid][np.argmax(spectrum[valid])])
    return span / best


def candidates(
    present: list[Effect], s: Samples, residual: np.ndarray, taken: Container[tuple[str, str]] = ()
) -> Iterator[Effect]:
    """Effects not yet in the model that the residual could reveal, unfitted, with starting values:
    the named ones, then the splines.

    Parameters
    ----------
    present : list of Effect
        The model's effects so far.
    s : Samples
        The estimation samples.
    residual : numpy.ndarray
        The model's residual at them [Nm | N].
    taken : container of (str, str)
        Shapes a named effect adds significantly this round (read as the splines are made:
        :func:`spline_candidates`).

    Yields
    ------
    Effect
        Each candidate.
    """
    names = {e.name for e in present}
    m = s.moving
    out: list[Effect] = []
    if "offset" not in names:
        out.append(Offset())
    if s.rotary and "gravity" not in names:
        out.append(Gravity())
    if "position_linear" not in names:
        out.append(PositionLinear())
    periodic = [e for e in present if isinstance(e, PositionPeriodic)]
    if len(periodic) < MAX_PERIODIC:
        period = position_period(s.take(m), residual[m])
        if period and all(abs(period - e.period_) > e.spread * e.period_ for e in periodic):
            out.append(PositionPeriodic(period, order=len(periodic) + 1))
    vmax = float(np.max(np.abs(s.qd[m])))
    vmin = float(np.min(np.abs(s.qd[m])))
    low, high = max(vmin, 0.01 * vmax), 0.5 * vmax
    if "stribeck" not in names and low < high:  # the log must reach down to low speeds
        out.append(Stribeck(min(max(0.1 * vmax, low), high), low=low, high=high))
    if "direction_asymmetry" not in names:
        out.append(DirectionAsymmetry(with_dc0="offset" not in names))
    if "drift" not in names:
        duration = float(np.ptp(s.t))
        out.append(
            Drift(
                duration / 5,
                low=duration / 100,
                high=3 * duration,
                start=float(s.t.min()),
                end=float(s.t.max()),
            )
        )
    coupled = {(e.source, e.form) for e in present if isinstance(e, CrossAxis)}
    still = standing_others(s)  # a coupling with a constant is an offset by another name
    for src in (o for o in s.others if o not in still):
        for form in CrossAxis.FORMS:
            if (src, form) not in coupled:
                out.append(CrossAxis(src, form))
    yield from out
    yield from spline_candidates(present, s, residual, taken)
