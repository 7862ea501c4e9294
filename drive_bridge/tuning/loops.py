"""The loop pictures a servo engineer looks at first, from the identified model and the gains.

Per axis: the open-loop Bode plots of the velocity and the position loop with the gains before
and after (the same loop models whose margins :mod:`.design` computes, python-control), the
crossover and the phase and gain margins marked; and the closed-loop position step response of
the model before and after.  Frequencies in Hz, magnitude in dB, phase in °, time in ms.  And the
following error the same model predicts along a demand (:func:`predicted_following_error`), which
the report draws beside the measured one.  Where the plant's response was measured through the
drive (:mod:`drive_bridge.ident.frf`), the open loops on its reliable bins are drawn as points
beside the model's curves.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..figures import pyplot, save
from ..params.cascade import following_error, open_loop_at, open_loops
from ..params.controller import LOOP_TICK_S
from .feedforward import model_torque

# python-control (with matplotlib and scipy.signal, over a second to import) is imported in the
# functions that compute a loop: every command would otherwise wait for it at start
if TYPE_CHECKING:
    from ..ident.frf import Frf


def loop_figure(
    J: float,
    c1: float,
    before: dict[str, float] | None,
    after: dict[str, float],
    L: float,
    path: str | Path,
    title: str = "",
    frf: Frf | None = None,
    tick_s: float = LOOP_TICK_S,
) -> Path:
    """Write the Bode plots and the step responses of one axis.

    Parameters
    ----------
    J : float
        Inertia [kg·m²].
    c1 : float
        Viscous friction [Nm·s/rad].
    before : dict of str to float or None
        The gains before tuning (None: not known).
    after : dict of str to float
        The gains designed.
    L : float
        Winding inductance [H].
    path : str or Path
        The PNG to write.
    title : str
        The figure's title.
    frf : Frf, optional
        The plant's measured response (:class:`drive_bridge.ident.frf.Frf`), drawn as points.
    tick_s : float
        The period of the drive's loop [s].

    Returns
    -------
    Path
        The PNG written.
    """
    import control

    plt = pyplot()
    from matplotlib.ticker import LogLocator

    sets = [("after", after, "C0")] + ([("before", before, "C3")] if before else [])
    f = np.logspace(0, 4, 600)  # 1 Hz .. 10 kHz
    fig, ax = plt.subplots(2, 3, figsize=(13, 6.5), gridspec_kw={"width_ratios": [1, 1, 0.9]})
    for name, gains, colour in sets:
        loops = open_loops(J, c1, gains, L, tick_s)
        for col, (loop, sys_) in enumerate(zip(("velocity", "position"), loops)):
            resp = sys_(2j * np.pi * f)
            mag, phase = 20 * np.log10(np.abs(resp)), np.degrees(np.unwrap(np.angle(resp)))
            gm, pm, wg, wc = control.margin(sys_)
            ax[0, col].semilogx(f, mag, colour, label=f"{name}")
            ax[1, col].semilogx(f, phase, colour, label=f"{name}")
            if np.isfinite(wc) and wc > 0:
                fc = wc / (2 * np.pi)
                ax[1, col].plot([fc, fc], [-180, -180 + pm], colour, lw=3, alpha=0.6)
                ax[1, col].annotate(
                    f"PM {pm:.0f}° at {fc:.0f} Hz",
                    (fc, -180 + pm),
                    color=colour,
                    fontsize=8,
                    xytext=(4, 4 if name == "after" else -12),
                    textcoords="offset points",
                )
            if np.isfinite(gm) and gm > 0 and np.isfinite(wg):
                fg = wg / (2 * np.pi)
                ax[0, col].plot([fg, fg], [0, -20 * np.log10(gm)], colour, lw=3, alpha=0.6)
                ax[0, col].annotate(
                    f"GM {20 * np.log10(gm):.1f} dB at {fg:.0f} Hz",
                    (fg, -20 * np.log10(gm)),
                    color=colour,
                    fontsize=8,
                    xytext=(4, -12 if name == "after" else 4),
                    textcoords="offset points",
                )
            ax[0, col].set_title(f"{loop} loop, open loop")
            if frf is not None:
                ok = frf.reliable()
                fm = frf.frequency_hz[ok]
                measured = open_loop_at(gains, fm, frf.response[ok], loop, tick_s)
                ax[0, col].semilogx(
                    fm,
                    20 * np.log10(np.abs(measured)),
                    ".",
                    color=colour,
                    ms=3,
                    label=f"{name}, on the measured plant",
                )
                ax[1, col].semilogx(
                    fm,
                    np.degrees(np.unwrap(np.angle(measured))) % 360 - 360,
                    ".",
                    color=colour,
                    ms=3,
                    label=f"{name}, on the measured plant",
                )
        closed = control.feedback(loops[1], 1)
        t = np.linspace(0, 0.05, 1000)
        _, y = control.step_response(closed, t)
        ax[0, 2].plot(t * 1e3, y, colour, label=name)
    for col in range(2):
        for r in range(2):  # minor ticks at 2 and 5 (matplotlib's eight a decade cost most of the figure)
            ax[r, col].xaxis.set_minor_locator(LogLocator(subs=(2.0, 5.0)))
        ax[0, col].axhline(0, color="0.5", lw=0.8)
        ax[1, col].axhline(-180, color="0.5", lw=0.8)
        ax[0, col].set_ylabel("magnitude [dB]")
        ax[1, col].set_ylabel("phase [°]")
        ax[1, col].set_xlabel("frequency [Hz]")
        ax[0, col].set_ylim(-60, 60)
        ax[1, col].set_ylim(-360, 0)
        for r in range(2):
            ax[r, col].grid(True, alpha=0.3)
            ax[r, col].legend(loc="lower left", fontsize=8)
    ax[0, 2].set_title("position step, closed loop (model)")
    ax[0, 2].set_xlabel("time [ms]")
    ax[0, 2].set_ylabel("position / step [1]")
    ax[0, 2].grid(True, alpha=0.3)
    ax[0, 2].legend(loc="lower right", fontsize=8)
    ax[1, 2].axis("off")
    ax[1, 2].text(
        0,
        0.9,
        "\n".join(
            [f"J = {J:.4g}, c1 = {c1:.4g} (identified)", f"L = {L:.3g} H"]
            + [
                f"{name}: KpP {g['KpP']:.4g} 1/s, KpS {g['KpS']:.4g},\n       KiS {g['KiS']:.4g} 1/s"
                for name, g, _ in sets
            ]
        ),
        fontsize=8,
        va="top",
        family="monospace",
    )
    if title:
        fig.suptitle(title)
    fig.subplots_adjust(left=0.06, right=0.98, bottom=0.08, top=0.9, wspace=0.3, hspace=0.25)
    return save(fig, Path(path))


def predicted_following_error(
    model: dict[str, float],
    gains: dict[str, float],
    L: float,
    torque_feedforward: bool,
    t: np.ndarray,
    demand: np.ndarray,
    tick_s: float = LOOP_TICK_S,
) -> np.ndarray:
    """The following error [rad] the identified ``model`` (J, c1 and what the drive model holds:
    c0, offset, ...) predicts along ``demand`` [rad] at ``t`` [s] with ``gains``: the linear cascade
    (:func:`drive_bridge.params.cascade.following_error`) driven by the demand and by the model's torque beyond J·q̈ + c1·q̇
    along it (held from the start: the axis waits at rest holding it).

    Parameters
    ----------
    model : dict of str to float
        The identified model (SI).
    gains : dict of str to float
        The cascade's gains (SI).
    L : float
        Winding inductance [H].
    torque_feedforward : bool
        The model torque is fed forward (the drive's or the master's).
    t : numpy.ndarray
        The instants [s].
    demand : numpy.ndarray
        The position demand at them [rad].
    tick_s : float
        The period of the drive's loop [s].

    Returns
    -------
    numpy.ndarray
        The following error [rad] at ``t``.
    """
    import control

    J, c1 = model["J"], model["c1"]
    to_error, from_torque = following_error(J, c1, gains, L, torque_feedforward, tick_s)
    dt = float(np.median(np.diff(t)))
    v = np.gradient(demand, dt)
    rest = model_torque(model, demand, dt) - J * np.gradient(v, dt) - c1 * v
    tt = t - t[0]
    return (
        control.forced_response(to_error, tt, demand - demand[0]).outputs
        + control.forced_response(from_torque, tt, rest - rest[0]).outputs
    )
