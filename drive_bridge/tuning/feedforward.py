"""The identified model as feed-forward torque, in the drive or from the master.

The project's drive adds the model torque of its demand itself (objects 0x2001).  A drive
without model objects gets the same torque from the master: for each setpoint, the model
torque J·a + (c1 + dc1·s)·v + (c0 + dc0·s)·s + offset + cp·q + ripple(q) of the interpolation
segment that setpoint opens (the drive moves from the previous setpoint to it during the
next SYNC period), taken at the segment's middle, sent as torque offset 0x60B2 with the
setpoint; where the drive has no velocity feed-forward of its own, the segment's velocity
goes as velocity offset 0x60B1.  SI inside: rad, rad/s, rad/s², Nm.

The project's drive also restarts its velocity integrator when a move starts, so the model
alone carries the axis out of stiction; no object does that on another drive, so at each move
start the streaming loop measures the torque the loop holds and sends that much less with the
move (the stream's unloading of the torque offset, :mod:`drive_bridge.master.stream`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..cia.objects import TORQUE_OFFSET, VELOCITY_OFFSET
from ..master.bringup import AxisLink
from ..params.profile import Profile

#: identify's parameter names -> the drive's model parameters
MODEL_KEYS = {
    "J": "J",
    "c0": "c0",
    "c1": "c1",
    "offset.offset": "offset",
    "position_linear.cp": "cp",
    "direction_asymmetry.dc0": "dc0",
    "direction_asymmetry.dc1": "dc1",
    "position_periodic.amplitude": "periodic_amplitude",
    "position_periodic.period": "periodic_period",
    "position_periodic.phase": "periodic_phase",
}
MODEL = set(MODEL_KEYS.values())  # J, c0, c1 and the effect terms


def model_torque_at(p: dict[str, float], q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
    """The model torque at given positions, velocities and accelerations.

    Parameters
    ----------
    p : dict of str to float
        The model: J, c0, c1 and the drive-model effect terms (SI).
    q : numpy.ndarray
        Positions [rad].
    v : numpy.ndarray
        Velocities [rad/s].
    a : numpy.ndarray
        Accelerations [rad/s²].

    Returns
    -------
    numpy.ndarray
        The torque [Nm].
    """
    sg = np.sign(np.where(np.abs(v) > 1e-6, v, 0.0))
    period = p.get("periodic_period", 0.0)
    ripple = (
        p.get("periodic_amplitude", 0.0) * np.sin(2 * np.pi * q / period + p.get("periodic_phase", 0.0))
        if period > 0
        else 0.0
    )
    return (
        p.get("J", 0.0) * a
        + (p.get("c1", 0.0) + p.get("dc1", 0.0) * sg) * v
        + (p.get("c0", 0.0) + p.get("dc0", 0.0) * sg) * sg
        + p.get("offset", 0.0)
        + p.get("cp", 0.0) * q
        + ripple
    )


def model_torque(p: dict[str, float], q: np.ndarray, period: float) -> np.ndarray:
    """The model torque along a trajectory (derivatives by differences).

    Parameters
    ----------
    p : dict of str to float
        The model (SI).
    q : numpy.ndarray
        The positions [rad], one per period.
    period : float
        The period [s].

    Returns
    -------
    numpy.ndarray
        The torque [Nm] per period.
    """
    v = np.gradient(q, period)
    return model_torque_at(p, q, v, np.gradient(v, period))


def segments(demand: np.ndarray, period: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Middle of the segment each setpoint opens: position, velocity and acceleration (the
    parabola through the last three setpoints, as the drive interpolates).

    Parameters
    ----------
    demand : numpy.ndarray
        The setpoints [rad].
    period : float
        The SYNC period [s].

    Returns
    -------
    position, velocity, acceleration : numpy.ndarray
        [rad], [rad/s], [rad/s²] per setpoint.
    """
    prev = np.concatenate([demand[:1], demand[:-1]])
    v = (demand - prev) / period
    a = np.diff(v, prepend=0.0) / period
    return 0.5 * (demand + prev), v, a


@dataclass(frozen=True)
class MasterFeedForward:
    """What the master sends one axis with each setpoint: the model torque as torque offset
    and the demand velocity as velocity offset.

    Parameters
    ----------
    model : dict of str to float
        The model (SI).
    torque : bool
        The model torque is sent (the RPDOs map 0x60B2).
    velocity : bool
        The demand velocity is sent (the RPDOs map 0x60B1).
    """

    model: dict[str, float]
    torque: bool
    velocity: bool

    def offsets(self, demand: np.ndarray, period: float) -> tuple[np.ndarray, np.ndarray]:
        """The offsets sent with each setpoint.

        Parameters
        ----------
        demand : numpy.ndarray
            The setpoints [rad].
        period : float
            The SYNC period [s].

        Returns
        -------
        torque : numpy.ndarray
            [Nm] per setpoint (zeros without ``torque``).
        velocity : numpy.ndarray
            [rad/s] per setpoint (zeros without ``velocity``).
        """
        q, v, a = segments(demand, period)
        return (
            model_torque_at(self.model, q, v, a) if self.torque else np.zeros_like(demand),
            v if self.velocity else np.zeros_like(demand),
        )

    def describe(self) -> str:
        """What the master sends, in words.

        Returns
        -------
        str
            ``master: torque offset 0x60B2 + velocity offset 0x60B1`` (or one of them).
        """
        sent = [
            o
            for o, on in (("torque offset 0x60B2", self.torque), ("velocity offset 0x60B1", self.velocity))
            if on
        ]
        return "master: " + " + ".join(sent)


def route(
    ax: AxisLink, profile: Profile, model: dict[str, float], force_master: bool = False
) -> MasterFeedForward | str:
    """How an axis gets its model feed-forward.

    Parameters
    ----------
    ax : AxisLink
        The brought-up axis (its RPDOs).
    profile : Profile
        Its drive's profile (whether it holds the model).
    model : dict of str to float
        The model (SI).
    force_master : bool
        The master sends it even where the drive could hold it.

    Returns
    -------
    MasterFeedForward or str
        "drive" (the profile writes the model to the drive), what the master sends, or a sentence
        saying why the axis gets none and what that costs.
    """
    if not model:
        return "none: no model in this parameter set"
    held = [k for k in model if any(n in profile.entries for n in profile.controller.drive_names([k]))]
    if "J" in held and not force_master:
        left = [k for k, v in model.items() if k not in held and v]
        return "drive" + (f" ({', '.join(held)}; no object for {', '.join(left)})" if left else "")
    mapped = {i for c in ax.rpdos for i in c.objects}
    torque = TORQUE_OFFSET in mapped
    velocity = VELOCITY_OFFSET in mapped and not any(
        n in profile.entries for n in profile.controller.drive_names(["FwF"])
    )
    if torque or velocity:
        return MasterFeedForward(model, torque, velocity)
    if TORQUE_OFFSET in ax.cfg.od:
        return (
            "none: the torque offset 0x60B2 is not in the RPDO mapping (map it in the node's rpdo): the model "
            "torque is left to the velocity loop"
        )
    return (
        "none: the drive has neither model objects nor a torque offset 0x60B2: the model torque is left to "
        "the velocity loop (the project's drive gains 12-65x in following error with it, 1.2-2.4x without)"
    )
