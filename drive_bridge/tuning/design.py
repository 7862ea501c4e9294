"""Model-based design of the cascade gains (the loops and their margins: :mod:`drive_bridge.params.cascade`).

The drive's loops (see the README's control law)::

    voltage  = KpC·(e_i + KiC·∫e_i)                     current PI, 8 kHz
    torque   = KpS·(e_v + KiS·∫e_v) + model feed-forward  velocity PI, 2 kHz
    velocity = FwF·v_demand + KpP·(p_demand − p)         position P, 2 kHz

The rates are the drive's (:class:`Timing`, from its profile's controller: 2 kHz / 8 kHz on the
project's drive, the defaults here).  Current PI: pole-zero cancellation of the motor's R/L
(KiC = R/L) and KpC = L·ω_i for a closed current loop ω_i an eighth of the current loop's rate.
Velocity PI on the identified plant 1/(J·s + c1) with the closed current loop
and the sampling delays (zero-order hold ½ T plus the backward-difference
velocity ½ T, T the loop's period; a Padé approximant): the largest KpS whose open loop
keeps the phase and gain margins, KiS = crossover / ``INTEGRAL_RATIO`` (6).
Position P on the closed velocity loop, the same way.  FwF = 1 (the model
feed-forward supplies the torque the velocity demand needs).  Where the plant's
response was measured through the drive (:mod:`drive_bridge.ident.frf`), every
candidate gain must also keep the margins on the measured points (its gain
crossover among them; above them the plant is the inertia their top shows): a
compliant transmission's mode, which the rigid model lacks, then limits the
crossover.  Units SI, motor side: KpS [Nm·s/rad],
KiS [1/s], KpP [1/s], KpC [V/A], KiC [1/s].
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..params.cascade import Margins, margins_of, measured_loop, position_open_loop, velocity_open_loop
from ..params.controller import CURRENT_RATE_HZ, Timing

if TYPE_CHECKING:
    from ..ident.frf import Frf

PM_DESIGN_DEG, GM_DESIGN_DB = 50.0, 9.0  # what the design aims at: room for model error
INTEGRAL_RATIO = 6.0  # KiS = crossover / this

PROJECT = Timing()


@dataclass
class GainDesign:
    """Gains (SI, motor side) and the margins of the velocity and position loops.

    Parameters
    ----------
    KpP : float
        Position gain [1/s].
    FwF : float
        Velocity feed-forward factor [1].
    KpS : float
        Velocity gain [Nm·s/rad].
    KiS : float
        Velocity integral rate [1/s].
    KpC : float
        Current gain [V/A].
    KiC : float
        Current integral rate [1/s].
    velocity, position : Margins
        The velocity and position loops' margins with these gains.
    """

    KpP: float
    FwF: float
    KpS: float
    KiS: float
    KpC: float
    KiC: float
    velocity: Margins
    position: Margins

    def gains(self) -> dict[str, float]:
        """The gains by name.

        Returns
        -------
        dict of str to float
            KpP, FwF, KpS, KiS, KpC, KiC, SI.
        """
        return {k: getattr(self, k) for k in ("KpP", "FwF", "KpS", "KiS", "KpC", "KiC")}

    def as_dict(self) -> dict:
        """The gains and margins as a dict (JSON's).

        Returns
        -------
        dict
            Every field, the margins as dicts.
        """
        return asdict(self)


MEASURE_CROSSOVER_SHARE = 0.06  # the measurement's velocity loop crosses over at this share of the SYNC rate


def measurement_gains(J: float, rate_hz: float) -> dict[str, float]:
    """Soft gains for measuring the plant's response (:mod:`drive_bridge.ident.frf`): a velocity loop
    crossing over at ``MEASURE_CROSSOVER_SHARE`` of the SYNC rate ``rate_hz`` on the rigid model
    of inertia ``J`` (KiS a sixth of it), the position loop a sixth of that.  A stiffer loop on a
    compliant machine may ring above the log's Nyquist frequency, where the log cannot see it and
    its alias spoils the bins below; and the closer |K·G| is to 1 the better the plant is seen.

    Parameters
    ----------
    J : float
        The axis's inertia [kg·m²].
    rate_hz : float
        The SYNC rate [Hz].

    Returns
    -------
    dict of str to float
        KpP, KpS, KiS (SI).
    """
    wc = 2 * np.pi * MEASURE_CROSSOVER_SHARE * rate_hz
    return {"KpP": wc / INTEGRAL_RATIO, "KpS": J * wc, "KiS": wc / INTEGRAL_RATIO}


def current_bandwidth(current_hz: float = CURRENT_RATE_HZ) -> float:
    """The closed current loop's bandwidth the design gives it: an eighth of its rate.

    Parameters
    ----------
    current_hz : float
        The current loop's rate [Hz].

    Returns
    -------
    float
        [rad/s].
    """
    return 2 * np.pi * current_hz / 8


def current_gains(R: float, L: float, current_hz: float = CURRENT_RATE_HZ) -> tuple[float, float, float]:
    """The current loop's gains: its zero on the motor's electrical pole.

    Parameters
    ----------
    R : float
        Winding resistance [Ω].
    L : float
        Winding inductance [H].
    current_hz : float
        The current loop's rate [Hz].

    Returns
    -------
    KpC : float
        [V/A].
    KiC : float
        [1/s].
    bandwidth : float
        The closed current loop's bandwidth [rad/s] (:func:`current_bandwidth`).
    """
    w_i = current_bandwidth(current_hz)
    return L * w_i, R / L, w_i


def _largest(
    margins_at: Callable[[float], Margins], lo: float, hi: float, pm_min: float, what: str
) -> tuple[float, Margins]:
    """The largest x in [lo, hi] whose margins hold (they shrink as x grows), by bisection on
    log x to 0.1 %."""

    def ok(x: float) -> Margins | None:
        m = margins_at(x)
        return m if m.phase_margin_deg >= pm_min and m.gain_margin_db >= GM_DESIGN_DB else None

    best = ok(lo)
    if best is None:
        raise ValueError(f"no {what} gain meets the margins on this plant")
    while hi / lo > 1.001:
        mid = float(np.sqrt(lo * hi))
        m = ok(mid)
        if m is not None:
            lo, best = mid, m
        else:
            hi = mid
    return lo, best


def design_gains(
    J: float,
    c1: float,
    R: float,
    L: float,
    frf: Frf | None = None,
    timing: Timing = PROJECT,
    max_crossover_hz: float | None = None,
) -> GainDesign:
    """Gains for the plant J [kg·m²], c1 [Nm·s/rad] and motor R [Ω], L [H], for loops at the
    drive's rates ``timing``; with a measured plant ``frf`` (:class:`drive_bridge.ident.frf.Frf`)
    every candidate must keep the margins on it too (the worse of the two counts), its crossover
    within the bins measured.

    Parameters
    ----------
    J : float
        Inertia [kg·m²].
    c1 : float
        Viscous friction [Nm·s/rad].
    R : float
        Winding resistance [Ω].
    L : float
        Winding inductance [H].
    frf : Frf, optional
        The plant measured through the drive.
    timing : Timing
        The drive's loop rates.
    max_crossover_hz : float, optional
        The velocity crossover at most this [Hz] (a mode to keep clear of).

    Returns
    -------
    GainDesign
        The gains and the loops' margins.

    Raises
    ------
    ValueError
        No gain meets the margins on this plant.
    """
    if not J > 0:
        raise ValueError(f"J must be positive to design a velocity loop, got {J}")
    KpC, KiC, w_i = current_gains(R, L, timing.current_hz)
    T = timing.tick_s
    nyquist = np.pi / T

    def worse(model: Margins, gains: dict[str, float], loop: str) -> Margins:
        """The worse of the model's and the measured margins; a loop not verified, or a velocity
        loop crossing over above ``max_crossover_hz``, is refused."""
        if loop == "velocity" and max_crossover_hz is not None and model.crossover_hz > max_crossover_hz:
            return Margins(-np.inf, -np.inf, model.crossover_hz)
        if frf is None:
            return model
        measured = measured_loop(gains, frf, loop, w_i, T)
        return Margins(-np.inf, -np.inf, model.crossover_hz) if measured is None else model.worse(measured)

    wc, vm = _largest(
        lambda w: worse(
            margins_of(velocity_open_loop(J, c1, J * w, w / INTEGRAL_RATIO, w_i, T)),
            {"KpS": J * w, "KiS": w / INTEGRAL_RATIO},
            "velocity",
        ),
        20.0,
        nyquist,
        PM_DESIGN_DEG,
        "velocity",
    )  # the velocity-loop crossover
    KpS, KiS = J * wc, wc / INTEGRAL_RATIO
    KpP, pm = _largest(
        lambda k: worse(
            margins_of(position_open_loop(J, c1, KpS, KiS, k, w_i, T)),
            {"KpS": KpS, "KiS": KiS, "KpP": k},
            "position",
        ),
        1.0,
        nyquist,
        PM_DESIGN_DEG + 5,
        "position",
    )
    return GainDesign(float(KpP), 1.0, float(KpS), float(KiS), float(KpC), float(KiC), vm, pm)
