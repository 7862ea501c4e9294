"""The drive's cascade as loops, and their margins (python-control computes every margin).

The loops of a cascade drive (:mod:`.controller`), on the identified rigid plant
1/(J·s + c1) behind the closed current loop and the sampling delays (zero-order hold ½ T plus
the backward-difference velocity ½ T, T the loop's period; a Padé approximant), or on a plant
whose response was measured through the drive (:mod:`drive_bridge.ident.frf`)::

    velocity loop, open:  KpS·(1 + KiS/s)·e^(−sT)·G(s)
    position loop, open:  KpP/s · (velocity loop, closed)

What the gain gate checks before a set is written (:mod:`.check`) and what the tuner designs
with (:mod:`drive_bridge.tuning.design`).  Units SI, motor side: J [kg·m²], c1 [Nm·s/rad],
KpS [Nm·s/rad], KiS [1/s], KpP [1/s], KpC [V/A], L [H].
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .controller import LOOP_TICK_S

# python-control (with matplotlib and scipy.signal, over a second to import) is imported in the
# functions that compute a loop: every command would otherwise wait for it at start
if TYPE_CHECKING:
    import control

    from ..ident.frf import Frf

PM_MIN_DEG, GM_MIN_DB = 45.0, 8.0  # what must hold (industrial tuners' defaults)
PADE_ORDER = 3
CROSSOVER_SHARE = 0.3  # a loop's gain crossover must lie below this share of the SYNC rate the plant was
# measured at: higher, the response of the offset's images above the Nyquist
# frequency, aliased, reads the plant's gain low (-0.6 dB at 0.3 on the rigid
# simulated axis, -2.6 dB at 0.4) and the margins high


@dataclass
class Margins:
    """A loop's stability margins.

    Parameters
    ----------
    phase_margin_deg : float
        [°].
    gain_margin_db : float
        [dB].
    crossover_hz : float
        The gain crossover [Hz].
    """

    phase_margin_deg: float
    gain_margin_db: float
    crossover_hz: float

    def ok(self) -> bool:
        """Whether both hold: at least ``PM_MIN_DEG`` and ``GM_MIN_DB``.

        Returns
        -------
        bool
            Both margins at least the industrial tuners' defaults.
        """
        return self.phase_margin_deg >= PM_MIN_DEG and self.gain_margin_db >= GM_MIN_DB

    def worse(self, other: Margins) -> Margins:
        """The smaller phase and gain margin of the two, at this crossover (the model's and the
        measured plant's margins of one loop).

        Parameters
        ----------
        other : Margins
            The same loop's margins on the other plant.

        Returns
        -------
        Margins
            The worse of each.
        """
        return Margins(
            min(self.phase_margin_deg, other.phase_margin_deg),
            min(self.gain_margin_db, other.gain_margin_db),
            self.crossover_hz,
        )


def margins_of(open_loop: control.TransferFunction) -> Margins:
    """The margins of an open loop.

    Parameters
    ----------
    open_loop : control.TransferFunction
        The open loop.

    Returns
    -------
    Margins
        Phase and gain margins [°, dB] and the gain crossover [Hz].
    """
    import control

    gm, pm, _, wc = control.margin(open_loop)
    gm_db = float(20 * np.log10(gm)) if np.isfinite(gm) and gm > 0 else float("inf")
    return Margins(float(pm), gm_db, float(wc / (2 * np.pi)))


@functools.lru_cache(maxsize=32)
def _plant_paths(
    J: float, c1: float, current_bw_rad_s: float, tick_s: float = LOOP_TICK_S
) -> tuple[control.TransferFunction, control.TransferFunction]:
    """``s`` and the plant behind the loop's delay and the closed current loop, built once per
    plant: a tuner's bisection asks for some thirty loops on one plant, and python-control's
    polynomial products and Padé approximant were half of the tuning's time (the loops are new
    objects each; these two are never changed)."""
    import control

    s = control.tf("s")
    num, den = control.pade(tick_s, PADE_ORDER)  # ½ T hold + ½ T velocity difference
    delay = control.tf(num, den)
    current = 1 / (s / current_bw_rad_s + 1)
    return s, delay * current / (J * s + max(c1, 0.0))


def velocity_open_loop(
    J: float, c1: float, KpS: float, KiS: float, current_bw_rad_s: float, tick_s: float = LOOP_TICK_S
) -> control.TransferFunction:
    """The velocity loop, open, on the rigid plant: KpS·(1 + KiS/s) times the plant behind the closed
    current loop and the loop's delay (Padé).

    Parameters
    ----------
    J : float
        Inertia [kg·m²].
    c1 : float
        Viscous friction [Nm·s/rad].
    KpS : float
        Velocity gain [Nm·s/rad].
    KiS : float
        Velocity integral rate [1/s].
    current_bw_rad_s : float
        The closed current loop's bandwidth [rad/s].
    tick_s : float
        The period of the drive's loop [s].

    Returns
    -------
    control.TransferFunction
        The open loop.
    """
    s, plant = _plant_paths(J, c1, current_bw_rad_s, tick_s)
    return KpS * (1 + KiS / s) * plant


def position_open_loop(
    J: float,
    c1: float,
    KpS: float,
    KiS: float,
    KpP: float,
    current_bw_rad_s: float,
    tick_s: float = LOOP_TICK_S,
) -> control.TransferFunction:
    """The position loop, open: KpP/s around the closed velocity loop.

    Parameters
    ----------
    J : float
        Inertia [kg·m²].
    c1 : float
        Viscous friction [Nm·s/rad].
    KpS : float
        Velocity gain [Nm·s/rad].
    KiS : float
        Velocity integral rate [1/s].
    KpP : float
        Position gain [1/s].
    current_bw_rad_s : float
        The closed current loop's bandwidth [rad/s].
    tick_s : float
        The period of the drive's loop [s].

    Returns
    -------
    control.TransferFunction
        The open loop.
    """
    import control

    s = control.tf("s")
    closed_velocity = control.feedback(velocity_open_loop(J, c1, KpS, KiS, current_bw_rad_s, tick_s), 1)
    return KpP / s * closed_velocity


def controller(gains: dict[str, float], tick_s: float = LOOP_TICK_S) -> Callable[[np.ndarray], np.ndarray]:
    """K(jω) of the drive's cascade as seen at its torque command [Nm per rad/s]: the velocity PI
    around the measured velocity, the position P around that, the loop's delay (½ T hold + ½ T
    velocity difference) -- what a torque offset added to the command sees close the loop.

    Parameters
    ----------
    gains : dict of str to float
        The cascade's gains by name (KpP, FwF, KpS, KiS, KpC; SI): those the loop uses.
    tick_s : float
        The period of the drive's loop [s].

    Returns
    -------
    callable
        K(ω) for ω [rad/s] (an array), complex.
    """

    def k(w: np.ndarray) -> np.ndarray:
        s = 1j * np.asarray(w, dtype=float)
        return _velocity_pi(gains, s, tick_s) * (1 + gains["KpP"] / s)

    return k


def _velocity_pi(gains: dict[str, float], s: np.ndarray, tick_s: float) -> np.ndarray:
    """The velocity PI with the loop's delay, KpS·(1 + KiS/s)·e^(−sT), at the points ``s``."""
    return gains["KpS"] * (1 + gains["KiS"] / s) * np.exp(-s * tick_s)


def rigid_response(J: float, c1: float, current_bw_rad_s: float, w: np.ndarray) -> np.ndarray:
    """G(jω) of the identified rigid plant: torque command → velocity through the closed current
    loop.

    Parameters
    ----------
    J : float
        Inertia [kg·m²].
    c1 : float
        Viscous friction [Nm·s/rad].
    current_bw_rad_s : float
        The closed current loop's bandwidth [rad/s].
    w : numpy.ndarray
        The frequencies [rad/s].

    Returns
    -------
    numpy.ndarray
        [rad/s per Nm], complex.
    """
    s = 1j * np.asarray(w, dtype=float)
    return 1 / (s / current_bw_rad_s + 1) / (J * s + max(c1, 0.0))


def measured_margins(
    gains: dict[str, float], frf: Frf, current_bw_rad_s: float, tick_s: float = LOOP_TICK_S
) -> tuple[Margins | None, Margins | None]:
    """Margins of the velocity and the position loop with ``gains`` on a measured plant
    (:class:`drive_bridge.ident.frf.Frf`, its reliable bins): the velocity loop
    KpS·(1 + KiS/jω)·e^(−jωT)·G(jω), the position loop KpP/jω around it closed.  Above the bins
    measured the plant is taken as the inertia their top shows, behind the closed current loop
    (``current_bw_rad_s``), up to the loops' Nyquist frequency: a gain margin beyond the band
    counts on no mode there.

    Parameters
    ----------
    gains : dict of str to float
        The cascade's gains by name (KpP, FwF, KpS, KiS, KpC; SI): those the loop uses.
    frf : Frf
        The measured plant.
    current_bw_rad_s : float
        The closed current loop's bandwidth [rad/s].
    tick_s : float
        The period of the drive's loop [s].

    Returns
    -------
    velocity, position : Margins or None
        Each loop's margins; None for a loop whose gain crossover lies above
        ``CROSSOVER_SHARE`` of the SYNC rate (not verified).
    """
    return (
        measured_loop(gains, frf, "velocity", current_bw_rad_s, tick_s),
        measured_loop(gains, frf, "position", current_bw_rad_s, tick_s),
    )


def open_loop_at(
    gains: dict[str, float], f: np.ndarray, g: np.ndarray, loop: str, tick_s: float = LOOP_TICK_S
) -> np.ndarray:
    """The open ``loop`` ("velocity" or "position") with ``gains`` on a plant whose response is
    ``g`` at some frequencies: KpS·(1 + KiS/jω)·e^(−jωT)·G, and KpP/jω around that closed.

    Parameters
    ----------
    gains : dict of str to float
        The cascade's gains by name (KpP, FwF, KpS, KiS, KpC; SI): those the loop uses.
    f : numpy.ndarray
        The frequencies [Hz].
    g : numpy.ndarray
        The plant's response there [rad/s per Nm], complex.
    loop : {"velocity", "position"}
        Which loop.
    tick_s : float
        The period of the drive's loop [s].

    Returns
    -------
    numpy.ndarray
        The open loop at ``f``, complex.
    """
    s = 2j * np.pi * np.asarray(f, dtype=float)
    velocity = _velocity_pi(gains, s, tick_s) * g
    return velocity if loop == "velocity" else gains["KpP"] / s * velocity / (1 + velocity)


def measured_loop(
    gains: dict[str, float], frf: Frf, loop: str, current_bw_rad_s: float, tick_s: float = LOOP_TICK_S
) -> Margins | None:
    """One loop's margins of :func:`measured_margins`.

    Parameters
    ----------
    gains : dict of str to float
        The cascade's gains by name (KpP, FwF, KpS, KiS, KpC; SI): those the loop uses.
    frf : Frf
        The measured plant.
    loop : {"velocity", "position"}
        Which loop.
    current_bw_rad_s : float
        The closed current loop's bandwidth [rad/s].
    tick_s : float
        The period of the drive's loop [s].

    Returns
    -------
    Margins or None
        None where its crossover lies beyond what was measured (not verified).
    """
    ok = frf.reliable()
    f, g = frf.frequency_hz[ok], frf.response[ok]
    if len(f) < 2:
        return None
    top = f[-1]
    beyond = np.geomspace(top, 0.5 / tick_s, 200)[1:]
    inertia = rigid_response(1.0, 0.0, current_bw_rad_s, 2 * np.pi * np.append(beyond, top))
    f, g = np.append(f, beyond), np.append(g, g[-1] * inertia[:-1] / inertia[-1])
    open_loop = open_loop_at(gains, f, g, loop, tick_s)
    sure = np.flatnonzero(f <= CROSSOVER_SHARE * frf.rate_hz)
    if not len(sure) or abs(open_loop[sure[-1]]) > 1:
        return None  # its crossover lies above the bins measured well
    return margins_at_points(f, open_loop)


def margins_at_points(f: np.ndarray, loop: np.ndarray) -> Margins | None:
    """Phase and gain margins of an open loop known at the frequencies ``f`` [Hz] (interpolated
    linearly in log frequency between them): at each gain crossover the angle between the loop and
    −1, at each phase crossover of −180° (± 360°) how far its gain stays below 1; the worst of each
    where it crosses more than once (a mode's resonance and anti-resonance make several).  A loop
    whose gain is below 1 throughout has its crossover below ``f``: no phase margin is measured
    (infinite, crossover nan).

    Parameters
    ----------
    f : numpy.ndarray
        The frequencies [Hz], ascending.
    loop : numpy.ndarray
        The open loop there, complex.

    Returns
    -------
    Margins or None
        None where the gain still exceeds 1 at the highest frequency: its crossover lies beyond.
    """
    mag = np.log(np.abs(loop))
    if mag[-1] > 0:
        return None
    phase = np.degrees(np.unwrap(np.angle(loop)))
    x = np.log(f)
    pm, wc = np.inf, np.nan
    for i in np.flatnonzero(np.sign(mag[:-1]) != np.sign(mag[1:])):
        r = mag[i] / (mag[i] - mag[i + 1])
        to_minus_one = abs((phase[i] + r * (phase[i + 1] - phase[i])) % 360.0 - 180.0)
        if to_minus_one < pm:
            pm, wc = to_minus_one, float(np.exp(x[i] + r * (x[i + 1] - x[i])))
    gm = np.inf
    shifted = (phase + 180.0) / 360.0  # crossings of -180° (+ k·360°)
    for i in np.flatnonzero(np.floor(shifted[:-1]) != np.floor(shifted[1:])):
        edge = np.floor(max(shifted[i], shifted[i + 1]))
        r = (edge - shifted[i]) / (shifted[i + 1] - shifted[i])
        gm = min(gm, float(-20 / np.log(10) * (mag[i] + r * (mag[i + 1] - mag[i]))))
    return Margins(float(pm), gm, wc)


def open_loops(
    J: float, c1: float, gains: dict[str, float], L: float, tick_s: float = LOOP_TICK_S
) -> tuple[control.TransferFunction, control.TransferFunction]:
    """The velocity and the position loop, open, with given gains on the identified plant.

    Parameters
    ----------
    J : float
        Inertia [kg·m²].
    c1 : float
        Viscous friction [Nm·s/rad].
    gains : dict of str to float
        The cascade's gains by name (KpP, FwF, KpS, KiS, KpC; SI): those the loop uses.
    L : float
        Winding inductance [H] (the current loop's bandwidth is KpC / L).
    tick_s : float
        The period of the drive's loop [s].

    Returns
    -------
    velocity, position : control.TransferFunction
        The open loops.
    """
    w_i = gains["KpC"] / L
    return (
        velocity_open_loop(J, c1, gains["KpS"], gains["KiS"], w_i, tick_s),
        position_open_loop(J, c1, gains["KpS"], gains["KiS"], gains["KpP"], w_i, tick_s),
    )


def following_error(
    J: float,
    c1: float,
    gains: dict[str, float],
    L: float,
    torque_feedforward: bool,
    tick_s: float = LOOP_TICK_S,
) -> tuple[control.TransferFunction, control.TransferFunction]:
    """Transfer functions from the position demand, and from a torque disturbance, to the
    following error (demand − position) of the cascade on the identified plant: velocity
    feed-forward FwF, and where ``torque_feedforward`` the model torque, which enters through the
    current loop alone (the drive adds it in the tick it computes it: no velocity-difference delay).

    Parameters
    ----------
    J : float
        Inertia [kg·m²].
    c1 : float
        Viscous friction [Nm·s/rad].
    gains : dict of str to float
        The cascade's gains by name (KpP, FwF, KpS, KiS, KpC; SI): those the loop uses.
    L : float
        Winding inductance [H].
    torque_feedforward : bool
        The model torque is fed forward.
    tick_s : float
        The period of the drive's loop [s].

    Returns
    -------
    from_demand, from_disturbance : control.TransferFunction
        Position demand [rad] → following error [rad], and torque disturbance [Nm] → following
        error [rad].
    """
    import control

    w_i = gains["KpC"] / L
    s = control.tf("s")
    rigid = 1 / (J * s + max(c1, 0.0))
    fed = 1 / (s / w_i + 1) * rigid if torque_feedforward else 0 * rigid
    pc = velocity_open_loop(J, c1, gains["KpS"], gains["KiS"], w_i, tick_s)
    den = s * (1 + pc) + pc * gains["KpP"]
    demand = s * (1 + pc * (1 - gains["FwF"]) - fed * (J * s + max(c1, 0.0))) / den
    return control.minreal(demand, verbose=False), control.minreal((rigid - fed) / den, verbose=False)


def loop_margins(
    J: float, c1: float, gains: dict[str, float], R: float, L: float, tick_s: float = LOOP_TICK_S
) -> tuple[Margins, Margins]:
    """Margins of given gains on the identified plant (e.g. the factory or the paper's sets).

    Parameters
    ----------
    J : float
        Inertia [kg·m²].
    c1 : float
        Viscous friction [Nm·s/rad].
    gains : dict of str to float
        The cascade's gains by name (KpP, FwF, KpS, KiS, KpC; SI): those the loop uses.
    R : float
        Winding resistance [Ω].
    L : float
        Winding inductance [H].
    tick_s : float
        The period of the drive's loop [s].

    Returns
    -------
    velocity, position : Margins
        Each loop's margins.
    """
    velocity, position = open_loops(J, c1, gains, L, tick_s)
    return margins_of(velocity), margins_of(position)
