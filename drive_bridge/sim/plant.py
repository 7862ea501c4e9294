"""The simulated robot's plant: every axis's arrays, the one simulation clock and the seeded noise.

:class:`Plant` is what the drives (:mod:`.drive`) and the compiled streaming SYNC
(:mod:`.steady`) are handed instead of reaching into the robot (:mod:`.robot`): the kernel's
arrays per axis -- ``state``, ``param``, ``demand`` (:mod:`.kernel`) and the drives' own values
``drive_rows`` (:mod:`.cyclic`) --, the loop ticks each drive is into its interpolation period
(``tick0``), the simulation time [s] and one standard-normal sequence from the configuration's
seed, so that one seed gives byte-identical feedback in lockstep.
"""

from __future__ import annotations

import numpy as np

from . import cyclic, kernel

NOISE_BLOCK = 4096


def whole_ticks(period: float) -> int | None:
    """``period`` [s] in loop ticks (:data:`.kernel.VELOCITY_TICK_S`); None where it is not a
    whole number of them (or none).

    Parameters
    ----------
    period : float
        [s].

    Returns
    -------
    int or None
        The ticks.
    """
    ticks = round(period / kernel.VELOCITY_TICK_S)
    return ticks if ticks >= 1 and abs(ticks * kernel.VELOCITY_TICK_S - period) <= 1e-9 else None


class Plant:
    """The plant of ``n_axes`` axes whose drives' loops lock to a SYNC every ``sync_period`` [s] (a
    multiple of the loop tick, :data:`.kernel.VELOCITY_TICK_S`) and interpolate over their own
    periods (``period_ticks``), noise drawn from ``seed``.

    Parameters
    ----------
    n_axes : int
        Its axes.
    sync_period : float
        [s].
    seed : int or None
        The noise's seed.
    """

    def __init__(self, n_axes: int, sync_period: float, seed: int | None):
        self.set_sync_period(sync_period)
        self.time = 0.0
        self.state, self.param, self.demand = kernel.new_arrays(n_axes)
        self.drive_rows = np.zeros((n_axes, cyclic.N_DRIVE))
        self.tick0 = np.zeros(n_axes, dtype=np.int64)
        #: each axis's interpolation period [ticks] (its drive's 0x60C2; the SYNC period until set)
        self.period_ticks = np.full(n_axes, self.ticks_per_period, dtype=np.int64)
        self._rng = np.random.default_rng(seed)
        self._noise = np.empty(0)
        self._noise_i = 0

    def set_sync_period(self, sync_period: float) -> None:
        """The SYNC period [s] the drives' loops lock to (a whole number of loop ticks).

        Parameters
        ----------
        sync_period : float
            [s].

        Raises
        ------
        ValueError
            Not a whole number of loop ticks.
        """
        ticks = whole_ticks(sync_period)
        if ticks is None:
            raise ValueError(f"SYNC period {sync_period} s is not a multiple of the 0.5 ms loop tick")
        self.sync_period, self.ticks_per_period = sync_period, ticks

    def rows(self, axis: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The rows of axis ``axis`` (its index): state, param, demand, drive values.

        Parameters
        ----------
        axis : int
            Its index.

        Returns
        -------
        state, param, demand, drive : numpy.ndarray
            Views of its rows.
        """
        return self.state[axis], self.param[axis], self.demand[axis], self.drive_rows[axis]

    def advance(self, n_ticks: int) -> None:
        """Loops and plant of every axis for ``n_ticks`` velocity-loop ticks (the clock with them).

        Parameters
        ----------
        n_ticks : int
            Velocity-loop ticks.
        """
        kernel.advance(self.state, self.param, self.demand, self.tick0, n_ticks, self.period_ticks)
        self.time = float(self.state[0, kernel.T])

    def reserve_noise(self, n: int) -> tuple[np.ndarray, int]:
        """The noise samples drawn ahead, at least ``n`` of them from the index returned on: the
        same sequence :meth:`noise` gives (the next block drawn early).

        Parameters
        ----------
        n : int
            Samples needed.

        Returns
        -------
        block : numpy.ndarray
            The samples.
        index : int
            The first to use.
        """
        if self._noise.size - self._noise_i < n:
            self._noise = np.concatenate(
                (self._noise[self._noise_i :], self._rng.standard_normal(NOISE_BLOCK))
            )
            self._noise_i = 0
        return self._noise, self._noise_i

    def take_noise(self, index: int) -> None:
        """The samples before ``index`` of :meth:`reserve_noise`'s block have been used.

        Parameters
        ----------
        index : int
            The next unused sample.
        """
        self._noise_i = index

    def noise(self) -> float:
        """One standard-normal sample from the seeded generator.

        Returns
        -------
        float
            The sample.
        """
        if self._noise_i >= self._noise.size:
            self._noise = self._rng.standard_normal(NOISE_BLOCK)
            self._noise_i = 0
        self._noise_i += 1
        return float(self._noise[self._noise_i - 1])
