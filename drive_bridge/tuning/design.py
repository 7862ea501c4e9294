"""Model-based design of the cascade gains (python-control computes every margin).

The drive's loops (see the README's control law)::

    voltage  = KpC·(e_i + KiC·∫e_i)                     current PI, 8 kHz
    torque   = KpS·(e_v + KiS·∫e_v) + model feed-forward  velocity PI, 2 kHz
    velocity = FwF·v_demand + KpP·(p_demand − p)         position P, 2 kHz

Current PI: pole-zero cancellation of the motor's R/L (KiC = R/L) and
KpC = L·ω_i for a closed current loop ω_i = 2π·1 kHz (an eighth of the 8 kHz rate).
Velocity PI on the identified plant 1/(J·s + c1) with the closed current loop
and the sampling delays (zero-order hold ½ T plus the backward-difference
velocity ½ T, T = 0.5 ms; a Padé approximant): the largest KpS whose open loop
keeps the phase and gain margins, KiS = crossover / ``INTEGRAL_RATIO`` (6).
Position P on the closed velocity loop, the same way.  FwF = 1 (the model
feed-forward supplies the torque the velocity demand needs).  Units SI, motor
side: KpS [Nm·s/rad], KiS [1/s], KpP [1/s], KpC [V/A], KiC [1/s].
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import control
import numpy as np

LOOP_TICK_S = 0.5e-3          # velocity / position loop period (2 kHz)
CURRENT_RATE_HZ = 8000.0
PM_MIN_DEG, GM_MIN_DB = 45.0, 8.0          # what must hold (industrial tuners' defaults)
PM_DESIGN_DEG, GM_DESIGN_DB = 50.0, 9.0    # what the design aims at: room for model error
INTEGRAL_RATIO = 6.0          # KiS = crossover / this
PADE_ORDER = 3


@dataclass
class Margins:
    phase_margin_deg: float
    gain_margin_db: float
    crossover_hz: float

    def ok(self) -> bool:
        return self.phase_margin_deg >= PM_MIN_DEG and self.gain_margin_db >= GM_MIN_DB


@dataclass
class GainDesign:
    """Gains (SI, motor side) and the margins of the velocity and position loops."""

    KpP: float
    FwF: float
    KpS: float
    KiS: float
    KpC: float
    KiC: float
    velocity: Margins
    position: Margins

    def gains(self) -> dict[str, float]:
        return {k: getattr(self, k) for k in ("KpP", "FwF", "KpS", "KiS", "KpC", "KiC")}

    def as_dict(self) -> dict:
        return asdict(self)


def _margins(open_loop) -> Margins:
    gm, pm, _, wc = control.margin(open_loop)
    gm_db = float(20 * np.log10(gm)) if np.isfinite(gm) and gm > 0 else float("inf")
    return Margins(float(pm), gm_db, float(wc / (2 * np.pi)))


def _plant_paths(J: float, c1: float, current_bw_rad_s: float):
    s = control.tf("s")
    num, den = control.pade(LOOP_TICK_S, PADE_ORDER)             # ½ T hold + ½ T velocity difference
    delay = control.tf(num, den)
    current = 1 / (s / current_bw_rad_s + 1)
    return s, delay * current / (J * s + max(c1, 0.0))


def velocity_open_loop(J, c1, KpS, KiS, current_bw_rad_s):
    s, plant = _plant_paths(J, c1, current_bw_rad_s)
    return KpS * (1 + KiS / s) * plant


def position_open_loop(J, c1, KpS, KiS, KpP, current_bw_rad_s):
    s, _ = _plant_paths(J, c1, current_bw_rad_s)
    closed_velocity = control.feedback(velocity_open_loop(J, c1, KpS, KiS, current_bw_rad_s), 1)
    return KpP / s * closed_velocity


def current_gains(R: float, L: float) -> tuple[float, float, float]:
    """KpC [V/A], KiC [1/s] and the closed current-loop bandwidth [rad/s]."""
    w_i = 2 * np.pi * CURRENT_RATE_HZ / 8
    return L * w_i, R / L, w_i


def open_loops(J, c1, gains: dict[str, float], L: float):
    """The velocity and the position loop, open, with given gains on the identified plant."""
    w_i = gains["KpC"] / L
    return (velocity_open_loop(J, c1, gains["KpS"], gains["KiS"], w_i),
            position_open_loop(J, c1, gains["KpS"], gains["KiS"], gains["KpP"], w_i))


def following_error(J, c1, gains: dict[str, float], L: float, torque_feedforward: bool):
    """Transfer functions from the position demand, and from a torque disturbance, to the
    following error (demand − position) of the cascade on the identified plant: velocity
    feed-forward FwF, and where ``torque_feedforward`` the model torque, which enters through the
    current loop alone (the drive adds it in the tick it computes it: no velocity-difference delay)."""
    w_i = gains["KpC"] / L
    s, _ = _plant_paths(J, c1, w_i)
    rigid = 1 / (J * s + max(c1, 0.0))
    fed = 1 / (s / w_i + 1) * rigid if torque_feedforward else 0 * rigid
    pc = velocity_open_loop(J, c1, gains["KpS"], gains["KiS"], w_i)
    den = s * (1 + pc) + pc * gains["KpP"]
    demand = s * (1 + pc * (1 - gains["FwF"]) - fed * (J * s + max(c1, 0.0))) / den
    return control.minreal(demand, verbose=False), control.minreal((rigid - fed) / den, verbose=False)


def loop_margins(J, c1, gains: dict[str, float], R: float, L: float) -> tuple[Margins, Margins]:
    """Margins of given gains on the identified plant (e.g. the factory or the paper's sets)."""
    velocity, position = open_loops(J, c1, gains, L)
    return _margins(velocity), _margins(position)


def _largest(margins_of, lo: float, hi: float, pm_min: float, what: str) -> tuple[float, Margins]:
    """The largest x in [lo, hi] whose margins hold (they shrink as x grows), by bisection on
    log x to 0.1 %."""
    def ok(x):
        m = margins_of(x)
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


def design_gains(J: float, c1: float, R: float, L: float) -> GainDesign:
    """Gains for the plant J [kg·m²], c1 [Nm·s/rad] and motor R [Ω], L [H]."""
    if not J > 0:
        raise ValueError(f"J must be positive to design a velocity loop, got {J}")
    KpC, KiC, w_i = current_gains(R, L)
    nyquist = np.pi / LOOP_TICK_S
    wc, vm = _largest(lambda w: _margins(velocity_open_loop(J, c1, J * w, w / INTEGRAL_RATIO, w_i)),
                      20.0, nyquist, PM_DESIGN_DEG, "velocity")           # the velocity-loop crossover
    KpS, KiS = J * wc, wc / INTEGRAL_RATIO
    KpP, pm = _largest(lambda k: _margins(position_open_loop(J, c1, KpS, KiS, k, w_i)),
                       1.0, nyquist, PM_DESIGN_DEG + 5, "position")
    return GainDesign(float(KpP), 1.0, float(KpS), float(KiS), float(KpC), float(KiC), vm, pm)
