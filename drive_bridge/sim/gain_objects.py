"""A simulated drive's controller as its drive profile (:mod:`..params.profile`) describes it: the
loops it runs and at what rate, its factory gains in its own controller's terms, the objects that
hold its gains and its model feed-forward with the kernel parameter each sets, and the object
that selects which of two sets of objects runs (Nanotec's 3212h:04)."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
from canopen.sdo import SdoAbortedError

from ..params.controller import Controller
from ..params.profile import SELECT, Entry, load_profile
from . import kernel
from .pdo_map import ABORT_RANGE
from .vendors import factory

ABORT_TOO_LOW = 0x06090032

#: drive-profile parameter -> kernel parameter: the gains, and the model feed-forward of a drive
#: that has one
GAIN_PARAMS = {
    "KpP": kernel.KPP,
    "FwF": kernel.FWF,
    "KpS": kernel.KPS,
    "KiS": kernel.KIS,
    "KpC": kernel.KPC,
    "KiC": kernel.KIC,
}
PID_PARAMS = {
    "PidP": kernel.PID_P,
    "PidI": kernel.PID_I,
    "PidD": kernel.PID_D,
    "PidFFv": kernel.PID_FFV,
    "PidFFa": kernel.PID_FFA,
}
MODEL_PARAMS = {
    "ff_enable": kernel.FF_EN,
    "J": kernel.FF_J,
    "c0": kernel.FF_C0,
    "c1": kernel.FF_C1,
    "offset": kernel.FF_OFF,
    "cp": kernel.FF_CP,
    "dc0": kernel.FF_DC0,
    "dc1": kernel.FF_DC1,
    "periodic_amplitude": kernel.FF_PER_AMP,
    "periodic_period": kernel.FF_PER_PERIOD,
    "periodic_phase": kernel.FF_PER_PHASE,
}
#: the kernel parameters a negative value is allowed for (every other one is refused below 0)
SIGNED = (kernel.FF_OFF, kernel.FF_CP, kernel.FF_DC0, kernel.FF_DC1, kernel.FF_PER_PHASE)


def _loop_divider(controller: Controller, eds_path: str | Path) -> int:
    """Kernel ticks per tick of the drive's position/velocity loop: the simulator runs loops at
    2 kHz / n and its current loop at 8 kHz; ValueError for a profile declaring other rates."""
    inner = controller.timing
    div = inner.tick_s / kernel.VELOCITY_TICK_S
    if (
        abs(div - round(div)) > 1e-9
        or round(div) < 1
        or inner.current_hz != kernel.CURRENT_SUBSTEPS / kernel.VELOCITY_TICK_S
    ):
        raise ValueError(
            f"{eds_path}: the simulator runs a drive's loops at 2 kHz / n and its current loop at 8 kHz, "
            f"not at {1 / inner.tick_s:g} Hz / {inner.current_hz:g} Hz as its profile declares"
        )
    return round(div)


class GainObjects:
    """The controller of a drive of profile ``profile`` (its current through a motor of torque
    constant ``torque_constant`` [Nm/A]) described by the file ``eds_path``.

    Parameters
    ----------
    profile : str
        The drive profile's name.
    torque_constant : float
        [Nm/A].
    eds_path : str or Path
        The drive's EDS/DCF.

    Raises
    ------
    ValueError
        A profile whose controller runs at rates the simulator's loops do not (2 kHz / n, current
        8 kHz).
    """

    def __init__(self, profile: str, torque_constant: float, eds_path: str | Path):
        bound = load_profile(profile).bind(torque_constant)
        #: the controller the drive runs (its profile's): structure and rates
        self.controller = bound.controller
        #: kernel ticks per tick of its position/velocity loop
        self.loop_div = _loop_divider(self.controller, eds_path)
        #: the factory gains in the drive's controller's terms: the project drive's cascade (its EDS
        #: defaults) with its loops slowed by the drive's loop rate (the same crossover share of the
        #: rate, the same margins)
        self.factory_gains = self.controller.to_drive(
            {k: v / self.loop_div if k in ("KpP", "KpS", "KiS") else v for k, v in factory().gains.items()}
        )
        #: the object that selects the profile's gain objects (Nanotec's 3212h:04) and the value that does;
        #: the other value runs the objects of the profile ``otherwise`` names
        self.select: tuple[Entry, int] | None = None if bound.select is None else bound.select[:2]
        otherwise = bound.otherwise() or bound
        #: selected or not -> {(index, sub): (kernel parameter, profile entry)} of the gain / model objects
        self.sets = {
            on: {
                (e.index, e.sub): ((GAIN_PARAMS | PID_PARAMS | MODEL_PARAMS)[name], e)
                for name, e in p.entries.items()
                if name != SELECT
            }
            for on, p in ((True, bound), (False, otherwise))
        }
        self.running = self.sets[True]  # the objects that run now (set by load)

    def factory_values(self) -> Iterator[tuple[int, int, int | float]]:
        """(index, sub, value in the drive's units) of every gain object that holds a factory gain."""
        for objects in self.sets.values():
            for (index, sub), (_, entry) in objects.items():
                if entry.parameter in self.factory_gains:
                    yield index, sub, entry.to_device(self.factory_gains[entry.parameter])

    def selects(self, index: int, sub: int) -> bool:
        """Whether (``index``, ``sub``) is the object that selects which set runs.

        Parameters
        ----------
        index, sub : int
            The object.

        Returns
        -------
        bool
            It is.
        """
        return self.select is not None and (index, sub) == self.select[0].index_sub

    def load(self, params: np.ndarray, read: Callable[[int, int], int]) -> None:
        """The loops (the kernel parameter row ``params``) run the objects of the profile's own set
        where the select object says so (or where there is none), else of the one that runs
        otherwise, each as ``read`` gives it now; a gain without an object keeps the factory value,
        a model term without one is 0.

        Parameters
        ----------
        params : numpy.ndarray
            The kernel parameter row (written in place).
        read : callable
            ``read(index, sub)``: an object's value now.
        """
        selected = self.select is None or read(*self.select[0].index_sub) == self.select[1]
        self.running = self.sets[selected]
        for name, col in (GAIN_PARAMS | PID_PARAMS).items():
            params[col] = self.factory_gains.get(name, 0.0)
        for col in MODEL_PARAMS.values():
            params[col] = 0.0
        for (index, sub), (col, entry) in self.running.items():
            params[col] = entry.to_si(read(index, sub))

    def written(self, index: int, sub: int, value: int | float) -> tuple[int, float] | None:
        """A value written to a running gain or model object: (kernel parameter, value in SI units),
        None where it is not one; SdoAbortedError where the drive cannot take it (not finite,
        negative where the term cannot be, a model switch other than 0 or 1).

        Parameters
        ----------
        index, sub : int
            The object.
        value : int or float
            The value written [device units].

        Returns
        -------
        (int, float) or None
            The kernel parameter and its value, SI.

        Raises
        ------
        SdoAbortedError
            A value the drive cannot take.
        """
        if (index, sub) not in self.running:
            return None
        col, entry = self.running[(index, sub)]
        si = entry.to_si(value)
        if (
            not math.isfinite(si)
            or si < 0
            and col not in SIGNED
            or col == kernel.FF_EN
            and value not in (0, 1)
        ):
            raise SdoAbortedError(ABORT_TOO_LOW if si < 0 else ABORT_RANGE)
        return col, si
