"""From a logged axis to identification samples (IDIM-LS practice, Gautier / Janot).

Position and torque get the same zero-phase Butterworth low-pass (parallel
filtering); velocity and acceleration are central differences of the filtered
position; the edges of every segment, where the filter has not settled, are
cut; then everything is decimated (``scipy.signal.decimate``, zero phase).
The torque as logged is kept at the decimated instants, for errors that mean
what a user thinks they mean.  A regressor column that is not linear in the filtered signals
(a cogging sine, a Stribeck curve, a spline) is computed at the log's rate and put through the
same low-pass, edge cut and decimation as the torque (:class:`Parallel`): a torque component
the low-pass attenuates is attenuated in its column alike, so its amplitude comes out as it is.  Units follow the log: rad, rad/s, rad/s², Nm
(rotary) or m, m/s, m/s², N (linear).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from functools import cache, cached_property
from typing import Any

import numpy as np
from scipy import signal

from ..errors import UserError
from .logdata import Log
from .spectra import welch

logger = logging.getLogger(__name__)

FILTER_ORDER = 4
MOTION_POWER = 0.99  # the motion bandwidth holds this share of the velocity power
CUTOFF_FACTOR = 25.0  # cut-off = 25 x the motion bandwidth (~5 x a closed-loop bandwidth,


# itself ~5 x the motion's; EMPS: 4.15 Hz -> 104 Hz, reference 100 Hz)
class FilterTooNarrow(UserError):
    """The log, through the filter and decimation chosen, leaves too little to fit (a band below a
    resonance is then not taken: :func:`~drive_bridge.ident.identify.identify_axis`)."""


MAX_CUTOFF_SHARE = 0.2  # ... at most this share of the log's rate: above it the derivatives of the
# quantised position are noise (a multisine at 14 Hz on a 500 Hz log: 100 Hz)
QUANTISATION_SHARE = 1e-3  # ... and where the position is on counts, its acceleration noise below this
QUANTISATION_BAND = 5.0  #     share of the motion's acceleration power (read below 5 x the bandwidth)
DECIMATION_MARGIN = 2.5  # decimated sample rate = 2.5 x the cut-off: nearly white residual samples
MOVING_FRACTION = 0.02  # |velocity| below this share of its maximum: near zero, not fitted
SETTLE_CYCLES = 1.0  # ... nor this many cut-off periods from it
STILL_SAMPLES = 3  # an encoder's position unchanged over this many log samples: standing still
WIDE_BAND = 0.4  # the light low-pass of the whole-band samples, × the sample rate
DELAY_HALF_TAPS = 16  # a position read between its samples: 32 taps of a windowed sinc ...
DELAY_KAISER_BETA = 11.0  # ... Kaiser window (_fractional_delay)
MIN_MOVING = 50  # decimated moving samples below this: nothing to identify
ACTIVE_DECAY = 1e-12  # filtered around where the axis moves: the filters' transients decayed to this


@dataclass
class Settings:
    """How the samples were made (:func:`choose_settings`).

    Parameters
    ----------
    cutoff_hz : float
        The low-pass cut-off [Hz].
    decimation : int
        The decimation factor.
    rate_hz : float
        The log's rate [Hz].
    edge : int
        The samples cut at each end of a segment, where the filter has not settled.
    motion_bandwidth_hz : float
        The motion's bandwidth [Hz] (:func:`motion_bandwidth`).
    torque_delay_s : float
        The delay [s] of the logged torque behind the logged position
        (:func:`.model.torque_delay`): the positions are read that much earlier, at the instants
        the torque stands for.
    """

    cutoff_hz: float
    decimation: int
    rate_hz: float
    edge: int
    motion_bandwidth_hz: float
    torque_delay_s: float = 0.0


@dataclass
class Samples:
    """Decimated samples of one axis (and the other axes of the log at the same instants).

    Parameters
    ----------
    axis : str
        The axis.
    t : numpy.ndarray
        Their instants [s].
    q, qd, qdd : numpy.ndarray
        Position [rad | m], velocity and acceleration of the filtered position.
    sgn : numpy.ndarray
        sign(q̇) through the same filters as the torque (the Coulomb column).
    tau_f : numpy.ndarray
        The filtered torque [Nm | N].
    tau : numpy.ndarray
        The torque as logged (mean over each decimation interval) [Nm | N].
    moving : numpy.ndarray
        |q̇| above the near-zero threshold, settled, not clipped: the samples fitted.
    others : dict of str to (numpy.ndarray, numpy.ndarray, numpy.ndarray)
        The other axes' (q, q̇, q̈) at the same instants.
    source : Parallel, optional
        The full-rate signals these samples were made from ...
    index : numpy.ndarray, optional
        ... and which of its samples these are.
    rotary : bool
        A joint whose position is its angle (one turn: 2π).
    """

    axis: str
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    sgn: np.ndarray
    tau_f: np.ndarray
    tau: np.ndarray
    moving: np.ndarray
    others: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]
    source: Parallel | None = None
    index: np.ndarray | None = None
    rotary: bool = False

    @property
    def qd_band(self) -> np.ndarray:
        """The velocity over the samples' whole band: the filtered one (see :class:`Channels`)."""
        return self.qd

    def take(self, mask: np.ndarray) -> Samples:
        """Some of the samples.

        Parameters
        ----------
        mask : numpy.ndarray
            Which (a boolean mask or indices).

        Returns
        -------
        Samples
            Those, with the same source (their columns are read from its cache).
        """
        index = np.arange(len(self)) if self.index is None else self.index
        return Samples(
            self.axis,
            self.t[mask],
            self.q[mask],
            self.qd[mask],
            self.qdd[mask],
            self.sgn[mask],
            self.tau_f[mask],
            self.tau[mask],
            self.moving[mask],
            {a: tuple(x[mask] for x in v) for a, v in self.others.items()},
            self.source,
            index[mask],
            self.rotary,
        )

    def parallel(
        self, key: object, columns: Callable[[Signals], np.ndarray], logged: bool = False
    ) -> np.ndarray:
        """``columns`` (a function of the signals, n × k) at these samples, computed at the log's
        rate and filtered and decimated as the torque is (``logged``: as the torque as logged
        is, by the mean over each decimation interval); at the samples as they are when they
        carry no source.

        Parameters
        ----------
        key : object
            Names the function for the source's cache.
        columns : callable
            The columns as a function of the signals (n × k).
        logged : bool
            As the torque as logged is (the mean over each decimation interval).

        Returns
        -------
        numpy.ndarray
            len(self) × k.
        """
        if self.source is None:
            return columns(self)
        cols = self.source.columns(key, columns, logged)
        return cols if self.index is None else cols[self.index]

    def __len__(self) -> int:
        return len(self.t)


@dataclass
class Channels:
    """The signals of one segment at the log's rate, as the regressor columns read them: logged
    position (what a position-periodic torque follows), velocity and acceleration of the
    filtered position, the velocity over the log's band (``qd_band``: for a torque that changes
    within a filter period of a reversal, as Stribeck friction does, which the filtered
    velocity would smear), the direction of motion unfiltered, the other axes alike, the
    torque as logged, and where the axis is moving: the torque, and every column, count only
    there before the low-pass (:func:`standing`).

    Parameters
    ----------
    t : numpy.ndarray
        The instants [s].
    q : numpy.ndarray
        The logged position, read at the torque's instants [rad | m].
    qd, qdd : numpy.ndarray
        Velocity and acceleration of the filtered position.
    sgn : numpy.ndarray
        The direction of motion, unfiltered (:func:`direction`).
    others : dict of str to (numpy.ndarray, numpy.ndarray, numpy.ndarray)
        The other axes' (q, q̇, q̈) alike.
    tau : numpy.ndarray
        The torque as logged [Nm | N].
    gate : numpy.ndarray
        0 where the encoder shows the axis standing still, else 1.
    qd_band : numpy.ndarray
        The logged position's derivative (the differentiator's own band).
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    sgn: np.ndarray
    others: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]
    tau: np.ndarray
    gate: np.ndarray
    qd_band: np.ndarray

    def __len__(self) -> int:
        return len(self.t)


#: what a regressor column is computed from: decimated samples, or a segment's signals at the log's rate
Signals = Samples | Channels


@dataclass
class Parallel:
    """Parallel filtering (IDIM: filter the regressor as the torque): a function of the full-rate
    signals goes through the same low-pass, edge cut and decimation as the torque in
    :func:`prepare`, segment by segment; the segments' signals and the results are cached (a
    fitted model asks for the same columns many times).

    Parameters
    ----------
    log : Log
        The log.
    axis : str
        The axis.
    settings : Settings
        How the samples are made.
    length : int
        The prepared samples' count (set by :func:`prepare`).
    """

    log: Log
    axis: str
    settings: Settings
    length: int = 0
    _cache: dict = field(default_factory=dict, repr=False, init=False)
    _segments: list = field(default_factory=list, repr=False, init=False)

    def __getstate__(self) -> dict[str, Any]:
        """Without the log and what was filtered from it (a result sent back from a worker process:
        the receiver attaches its own log, :meth:`.identify.AxisResult.attach`)."""
        return {**self.__dict__, "log": None, "_cache": {}, "_segments": []}

    def columns(
        self, key: object, columns: Callable[[Channels], np.ndarray], logged: bool = False
    ) -> np.ndarray:
        """A function of the full-rate signals, filtered, cut and decimated as the torque is.

        Parameters
        ----------
        key : object
            Names the function for the cache.
        columns : callable
            The columns as a function of a segment's signals (n × k).
        logged : bool
            As the torque as logged is (the mean over each decimation interval).

        Returns
        -------
        numpy.ndarray
            ``length`` × k, at the prepared samples.
        """
        if (key, logged) not in self._cache:
            sos, r = self.sos, self.settings.decimation
            parts = []
            for keep, ch in self.segments():
                x = np.asarray(columns(ch), dtype=float).reshape(len(ch), -1)
                if logged:
                    parts.append(
                        np.column_stack([_interval_mean(x[:, j], r)[keep][::r] for j in range(x.shape[1])])
                    )
                else:
                    xf = signal.sosfiltfilt(sos, x * ch.gate[:, None], axis=0)[keep]
                    parts.append(_decimate(xf, self.settings))
            self._cache[key, logged] = np.concatenate(parts)[: self.length]
        return self._cache[key, logged]

    @cached_property
    def sos(self) -> np.ndarray:
        """The low-pass, designed once."""
        return signal.butter(FILTER_ORDER, self.settings.cutoff_hz, fs=self.settings.rate_hz, output="sos")

    def segments(self) -> list[tuple[slice, Channels]]:
        """The usable segments' signals (made once).

        Returns
        -------
        list of (slice, Channels)
            Per segment, the part kept after the edge cut and its signals.
        """
        if not self._segments:
            sos, dt = self.sos, self.log.dt
            lag = self.settings.torque_delay_s / dt

            def kinematics(position: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
                """Position at the torque's instants, velocity and acceleration of it filtered."""
                x = _delayed(position, lag)
                xd = derivative(signal.sosfiltfilt(sos, x), dt)
                return x, xd, derivative(xd, dt)

            for sl, keep in _usable(self.log, self.axis, self.settings):
                sl, keep = self._active(sl, keep, lag)
                raw = self.log.axes[self.axis].q[sl]
                q, qd, qdd = kinematics(raw)
                others = {
                    o: kinematics(_filled(self.log.axes[o].q[sl])) for o in self.log.axes if o != self.axis
                }
                # the direction at the log's own instants (its fallback, the filtered velocity's
                # sign, too), then read at the torque's as the positions are
                sgn = np.sign(_delayed_steps(direction(raw, _delayed(qd, -lag)), lag))
                gate = 1.0 - np.ceil(_delayed_steps(standing(raw).astype(float), lag))
                self._segments.append(
                    (
                        keep,
                        Channels(
                            self.log.t[sl],
                            q,
                            qd,
                            qdd,
                            sgn,
                            others,
                            self.log.axes[self.axis].tau[sl],
                            gate,
                            derivative(q, dt),
                        ),
                    )
                )
        return self._segments

    def _active(self, sl: slice, keep: slice, lag: float) -> tuple[slice, slice]:
        """The part of segment ``sl`` around where the axis moves, and the part of that kept after
        the edge cut: from a margin before the first sample above ``MOVING_FRACTION`` of the
        segment's peak speed to as far after the last, on the decimation's grid.  What lies
        beyond is standstill no fit uses (a campaign that moves the axes one after the other: two
        thirds of each axis's log), and filtering it for every column was most of the
        identification's time.  The margin holds the edge cut, two filters' settling (the
        velocity's, then the columns': :func:`_settling_samples`), the torque delay and the reach
        of the differentiator and the fractional delay, so that within the part every signal is
        as it would be over the whole segment to ``ACTIVE_DECAY`` of its size.  The segment's
        speed is kept with the log: the same for every torque delay."""
        settings, r = self.settings, self.settings.decimation
        key = (self.axis, sl.start, sl.stop, settings.cutoff_hz)
        speed = self.log.speeds.get(key)
        if speed is None:
            speed = np.abs(
                derivative(signal.sosfiltfilt(self.sos, self.log.axes[self.axis].q[sl]), self.log.dt)
            )
            self.log.speeds[key] = speed
        moving = np.flatnonzero(speed > MOVING_FRACTION * np.max(speed))
        margin = (
            settings.edge
            + 2 * _settling_samples(settings, self.sos)
            + int(np.ceil(abs(lag)))
            + DELAY_HALF_TAPS
            + len(_DERIVATIVE)
        )
        n = sl.stop - sl.start
        if not len(moving):
            return sl, keep
        lo = max(0, int(moving[0]) - margin)
        lo -= lo % r  # the same decimated samples as the whole segment's
        hi = min(n, int(moving[-1]) + 1 + margin)
        if (lo, hi) == (0, n) or hi - lo <= 2 * settings.edge + 3 * r * 9:
            return sl, keep
        return slice(sl.start + lo, sl.start + hi), slice(settings.edge, hi - lo - settings.edge)


# A low-pass differentiator (Parks-McClellan, 51 taps): within 3e-5 of the derivative up to 0.2 ×
# the sample rate (the highest cut-off a fit uses, MAX_CUTOFF_SHARE), where np.gradient reads 24 % low
# (and J came out up to 1 % high); nothing above 0.3 ×, where an exact derivative would only lift the
# encoder's quantisation into the whole-band residual (J·q̈ of counts at up to 0.4 × the rate).
_DERIVATIVE = 2 * np.pi * signal.remez(51, [0.0, 0.2, 0.3, 0.5], [1.0, 0.0], type="differentiator", fs=1.0)


def derivative(x: np.ndarray, dt: float) -> np.ndarray:
    """Time derivative of a signal up to 0.2 × its rate, nothing above 0.3 × (the 25 samples at
    each end by np.gradient).

    Parameters
    ----------
    x : numpy.ndarray
        The signal.
    dt : float
        Its sample period [s].

    Returns
    -------
    numpy.ndarray
        dx/dt, per second.
    """
    out = np.gradient(x, dt)
    m = len(_DERIVATIVE) // 2
    if len(x) > 2 * m:
        out[m:-m] = np.convolve(x, _DERIVATIVE, mode="valid") / dt
    return out


def _settling_samples(settings: Settings, sos: np.ndarray) -> int:
    """Log samples in which the transient of the low-pass ``sos`` and of the decimation's filter
    (where :func:`_decimate` uses one) decays below ``ACTIVE_DECAY`` of its start: from their
    slowest poles."""
    poles = [signal.sos2zpk(sos)[1]]
    ba = _decimation_filter(settings)
    if ba is not None:
        poles.append(np.roots(ba[1]))
    radius = max(float(np.max(np.abs(p))) for p in poles)
    return int(np.ceil(np.log(ACTIVE_DECAY) / np.log(radius)))


def _usable(log: Log, axis: str, settings: Settings) -> Iterator[tuple[slice, slice]]:
    """(segment slice, the part kept after the edge cut) of each segment long enough to filter
    in which the axis moves: a segment that spans under ``MOVING_FRACTION`` of the axis's travel
    is its standstill (a campaign that moves the axes in turn, split by a time gap), which no fit
    uses."""
    r, edge = settings.decimation, settings.edge
    q = log.axes[axis].q
    travel = float(np.nanmax(q) - np.nanmin(q))
    for a, b in log.axes[axis].segments:
        if b - a > 2 * edge + 3 * r * 9 and np.nanmax(q[a:b]) - np.nanmin(q[a:b]) >= MOVING_FRACTION * travel:
            yield slice(a, b), slice(edge, b - a - edge)


def _fractional_delay(frac: float) -> np.ndarray:
    """Taps n = -15 … 16 of a Kaiser-windowed sinc (β 11) that reads a signal ``frac`` of a sample
    (0 ≤ frac < 1) earlier: Σ h[n]·x[k − n] = x(k − frac) within 2.4e-6 up to 0.2 × the rate;
    its gain at zero frequency is exactly 1."""
    x = np.arange(1 - DELAY_HALF_TAPS, DELAY_HALF_TAPS + 1) - frac
    h = np.sinc(x) * np.i0(DELAY_KAISER_BETA * np.sqrt(np.clip(1 - (x / DELAY_HALF_TAPS) ** 2, 0.0, None)))
    return h / h.sum()


def _delayed(x: np.ndarray, samples: float) -> np.ndarray:
    """A position read ``samples`` log samples earlier, x(t − d), held at the ends: the position
    at the instants the logged torque stands for.  Between the samples by a windowed sinc
    (:func:`_fractional_delay`), within 2.4e-6 up to 0.2 × the rate, the highest cut-off a fit
    uses (MAX_CUTOFF_SHARE): a straight line between the samples reads a signal at 0.05 × the
    rate 1.2 % low half a sample off; J came out 0.1–0.25 % high, and a cogging was added, on
    logs whose torque is averaged over each period."""
    if samples == 0 or not np.isfinite(x).all():
        return _delayed_steps(x, samples)
    whole = int(np.floor(samples))
    pad = DELAY_HALF_TAPS + abs(whole) + 1
    padded = np.pad(x, pad, mode="edge")
    read = np.convolve(padded, _fractional_delay(samples - whole))[DELAY_HALF_TAPS - 1 :][: len(padded)]
    out = read[pad - whole : pad - whole + len(x)]
    at = np.arange(len(x)) - samples
    out[at <= 0] = x[0]
    out[at >= len(x) - 1] = x[-1]
    return out


def _delayed_steps(x: np.ndarray, samples: float) -> np.ndarray:
    """A signal of steps (a direction, a gate) read ``samples`` log samples earlier, linear
    between the samples (the caller rounds it), held at the ends: a sinc would ring at each
    step."""
    if samples == 0:
        return x
    k = np.arange(len(x), dtype=float)
    return np.interp(k - samples, k, x)


def count_step(q: np.ndarray) -> float | None:
    """The count of a logged position where it is an encoder's (or a drive's position unit).

    Parameters
    ----------
    q : numpy.ndarray
        The logged position.

    Returns
    -------
    float or None
        One count, in the position's unit, where the position is on a grid of counts (as
        written, to 0.1 count), not noisy or interpolated; else None.
    """
    finite = q[np.isfinite(q)]
    moved = np.abs(np.diff(finite))
    # (a step below the float's resolution at the position is rounding, not a count)
    moved = moved[moved > 16 * np.finfo(float).eps * max(1.0, float(np.max(np.abs(finite), initial=0.0)))]
    if len(q) < 5 or not len(moved):
        return None
    step = float(np.mean(moved[moved < 1.5 * moved.min()]))  # one count: the smallest step
    counts = moved / step
    small = counts[counts < 50]  # (a large step's count carries the unit's rounding)
    return step if len(small) >= 10 and bool(np.max(np.abs(small - np.round(small))) <= 0.1) else None


def _on_counts(q: np.ndarray) -> bool:
    return count_step(q) is not None


def _runs(same: np.ndarray, length: int) -> np.ndarray:
    """Whether ``length`` equal positions start at each sample that has that many (``same``: the
    steps that are zero)."""
    return np.convolve(same.astype(float), np.ones(length - 1), mode="valid") == length - 1


def _in_runs(same: np.ndarray, length: int) -> np.ndarray:
    """Samples within a run of ``length`` equal positions (``same``: the steps that are zero)."""
    run = _runs(same, length)
    out = np.zeros(len(same) + 1, dtype=bool)
    for k in range(length):
        out[k : k + len(run)] |= run
    return out


def direction(q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """Direction of motion (-1, 0, 1) at each sample of the logged position ``q``, for the
    Coulomb column; ``qd``: the filtered velocity.

    The filtered velocity's sign rings about a reversal and changes sign in the middle of the
    time the axis sticks there, where friction is whatever holds it.  An encoder's position
    tells the truth: the sign of its central difference, zero where it stays on one count for
    ``STILL_SAMPLES`` samples; between two counts of a slow motion, and for a position that is
    not an encoder's, the filtered velocity's sign.

    Parameters
    ----------
    q : numpy.ndarray
        The logged position.
    qd : numpy.ndarray
        The filtered velocity.

    Returns
    -------
    numpy.ndarray
        -1, 0 or 1 per sample.
    """
    fallback = np.sign(qd)
    if not _on_counts(q):
        return fallback
    raw = np.sign(np.gradient(q))
    return np.where(raw != 0, raw, np.where(_in_runs(np.diff(q) == 0, STILL_SAMPLES), 0.0, fallback))


def standing(q: np.ndarray) -> np.ndarray:
    """Samples where an encoder's position ``q`` shows the axis standing still: one count over
    the five samples the velocity and acceleration columns reach (both are exactly zero there).

    There the drive holds the axis with whatever torque static friction allows, no model's
    torque; the torque and every column are set to zero there before the low-pass, so the
    filtered torque and columns still agree next to a standstill (none where ``q`` is not an
    encoder's).

    Parameters
    ----------
    q : numpy.ndarray
        The logged position.

    Returns
    -------
    numpy.ndarray
        True where the axis stands still.
    """
    if not _on_counts(q):
        return np.zeros(len(q), dtype=bool)
    out = np.zeros(len(q), dtype=bool)
    out[2:-2] = _runs(np.diff(q) == 0, 5)  # centred on the five samples
    return out


def _filled(q: np.ndarray) -> np.ndarray:
    """Another axis's position with its missing samples interpolated."""
    ok = np.isfinite(q)
    return q if ok.all() else np.interp(np.arange(len(q)), np.flatnonzero(ok), q[ok])


def motion_bandwidth(log: Log, axis: str) -> float:
    """The motion's bandwidth: the frequency below which ``MOTION_POWER`` of the axis's velocity
    power lies (over its segment with the most motion).

    Parameters
    ----------
    log : Log
        The log.
    axis : str
        The axis.

    Returns
    -------
    float
        [Hz].

    Raises
    ------
    UserError
        An axis that does not move.
    """
    a, b = _most_motion(log, axis)
    fs = 1.0 / log.dt
    v = np.gradient(log.axes[axis].q[a:b], log.dt)
    f, pxx = welch(v - v.mean(), fs, min(len(v), 4096))
    cum = np.cumsum(pxx)
    if cum[-1] <= 0:
        raise UserError(f"{log.path}: axis {axis!r} does not move (its position is constant)")
    return float(max(f[np.searchsorted(cum, MOTION_POWER * cum[-1])], f[1]))


def _most_motion(log: Log, axis: str) -> tuple[int, int]:
    """The axis's segment with the most motion (a log split by missing rows or a time gap may hold
    a long standstill)."""
    ax = log.axes[axis]
    return max(ax.segments, key=lambda s: int(np.count_nonzero(np.diff(ax.q[s[0] : s[1]]))))


def quantisation_cutoff(log: Log, axis: str, bw: float) -> float:
    """The highest cut-off [Hz] at which the acceleration a position quantised to its count
    carries stays below ``QUANTISATION_SHARE`` of the motion's acceleration power: a coarse
    position unit (a drive's 0.1°) otherwise puts noise into q̈, and the least squares read J low
    by that share (errors in a regressor); inf for a position that is not on counts.

    Quantisation is white up to the Nyquist frequency (variance count²/12); its acceleration's
    power below ``fc`` is (2π)⁴·count²/12·fc⁵ / (5·fs/2).  The motion's acceleration power is
    read from the velocity's spectrum below ``QUANTISATION_BAND`` × the motion bandwidth.

    Parameters
    ----------
    log : Log
        The log.
    axis : str
        The axis.
    bw : float
        Its motion's bandwidth [Hz].

    Returns
    -------
    float
        [Hz]; inf for a position that is not on counts.
    """
    a, b = _most_motion(log, axis)  # (the longest may be a standstill: a campaign split by a gap)
    step = count_step(log.axes[axis].q[a:b])
    if step is None:
        return np.inf
    fs = 1.0 / log.dt
    f, pxx = welch(np.gradient(log.axes[axis].q[a:b], log.dt), fs, min(b - a, 4096))
    band = f <= QUANTISATION_BAND * bw
    power = float(np.sum((2 * np.pi * f[band]) ** 2 * pxx[band]) * (f[1] - f[0]))
    noise = (2 * np.pi) ** 4 * step**2 / 12 / (5 * fs / 2)
    return float((QUANTISATION_SHARE * power / noise) ** 0.2)


def choose_settings(
    log: Log, axis: str, cutoff_hz: float | None = None, decimation: int | None = None
) -> Settings:
    """Cut-off and decimation from the data: the cut-off follows the motion's bandwidth, within a
    share of the rate and below what the position's quantisation allows.

    Parameters
    ----------
    log : Log
        The log.
    axis : str
        The axis.
    cutoff_hz : float, optional
        The cut-off [Hz], given (an expert's ``--cutoff``).
    decimation : int, optional
        The decimation factor, given.

    Returns
    -------
    Settings
        Cut-off, decimation, rate, edge cut and the motion's bandwidth.

    Raises
    ------
    UserError
        A cut-off outside (0, Nyquist), or an axis that does not move.
    """
    fs = 1.0 / log.dt
    bw = motion_bandwidth(log, axis)
    fc = (
        cutoff_hz
        if cutoff_hz
        else float(
            np.clip(min(CUTOFF_FACTOR * bw, quantisation_cutoff(log, axis, bw)), 0.5, MAX_CUTOFF_SHARE * fs)
        )
    )
    if not 0 < fc < fs / 2:
        raise UserError(f"cut-off {fc} Hz must be between 0 and the Nyquist frequency {fs / 2:g} Hz")
    r = decimation if decimation else max(1, int(fs / (DECIMATION_MARGIN * fc)))
    edge = max(50, int(3 * fs / fc))  # the Butterworth's settling, both ends
    logger.debug(
        "axis %s: motion bandwidth %.3g Hz, cut-off %.3g Hz%s, decimation %d",
        axis,
        bw,
        fc,
        " (given)" if cutoff_hz else "",
        max(1, r),
    )
    return Settings(fc, max(1, r), fs, edge, bw)


def _interval_window(r: int) -> np.ndarray:
    w = np.ones(r + 1 - r % 2)
    if r % 2 == 0:
        w[0] = w[-1] = 0.5
    return w / w.sum()


def _interval_mean(x: np.ndarray, r: int) -> np.ndarray:
    """Mean of the logged values over the decimation interval centred on each sample (nothing
    else): one sample in r would alias what the log holds near its Nyquist frequency."""
    return x if r == 1 else np.convolve(x, _interval_window(r), mode="same")


def _decimate(x: np.ndarray, settings: Settings) -> np.ndarray:
    """Keep every r-th sample (of each column, where ``x`` has several).  When the Butterworth
    already removed what would alias (the decimated Nyquist frequency is at least twice the
    cut-off) nothing more is needed; otherwise the Chebyshev filter forward and backward first,
    as scipy's decimate runs it (its ``filtfilt``: the filter's poles are complex), with its DC
    gain set to 1 (an even-order Chebyshev I passes DC at its ripple minimum, and filtered twice
    that scales every signal by 0.989 while sign(q̇) stays ±1: c0 would come out 1 % low)."""
    ba = _decimation_filter(settings)
    if ba is not None:  # (along the last axis of a contiguous copy: lfilter strides slowly)
        x = signal.filtfilt(*ba, np.ascontiguousarray(x.T)).T
    return x[:: settings.decimation]


def _decimation_filter(settings: Settings) -> tuple[np.ndarray, np.ndarray] | None:
    """The Chebyshev filter (b, a) :func:`_decimate` applies before it keeps every r-th sample, its
    DC gain 1; None where the Butterworth already removed what would alias."""
    r = settings.decimation
    if r == 1 or settings.rate_hz / r >= 4 * settings.cutoff_hz:
        return None
    return _chebyshev(r)


@cache
def _chebyshev(r: int) -> tuple[np.ndarray, np.ndarray]:
    b, a = signal.cheby1(8, 0.05, 0.8 / r)
    return b * (np.sum(a) / np.sum(b)), a


CLIP_SHARE = 0.002  # a torque level held by at least this share of the samples ...
CLIP_RUN = 3  # ... in runs of identical values this long, at the log's extreme: clipped


def clipped_levels(tau: np.ndarray) -> list[float]:
    """The levels the logged torque is clipped at (a drive's current limit, a logger's range).

    Parameters
    ----------
    tau : numpy.ndarray
        The torque as logged.

    Returns
    -------
    list of float
        Its highest or lowest value where the log holds it, identical, on at least
        ``CLIP_SHARE`` of the samples and in runs of at least ``CLIP_RUN`` (a measured torque at
        its peak does neither).
    """
    out = []
    for level in (float(np.max(tau)), float(np.min(tau))):
        at = tau == level
        if level != 0.0 and at.mean() >= CLIP_SHARE and _longest_run(at) >= CLIP_RUN:
            out.append(level)
    return out


def _longest_run(flags: np.ndarray) -> int:
    edges = np.diff(np.concatenate(([0], flags.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return int(np.max(ends - starts)) if len(starts) else 0


def prepare(log: Log, axis: str, settings: Settings) -> Samples:
    """Filtered, differentiated, decimated samples of ``axis`` (all segments), from the same
    full-rate signals the regressor columns are made of (:class:`Parallel`); samples within one
    cut-off period of a clipped torque (:func:`clipped_levels`) or of a filled sample
    (:attr:`.logdata.AxisLog.filled`: what the axis did there is not known) are not fitted.

    Parameters
    ----------
    log : Log
        The log.
    axis : str
        The axis.
    settings : Settings
        How to make them.

    Returns
    -------
    Samples
        The samples, with their full-rate source.

    Raises
    ------
    FilterTooNarrow
        Every usable run is shorter than the filter needs, or too few moving samples are left.
    UserError
        An axis that does not move.
    """
    r, edge = settings.decimation, settings.edge
    source = Parallel(log, axis, settings)
    sos = source.sos
    levels = clipped_levels(log.axes[axis].tau)
    filled = log.axes[axis].filled
    spread = np.ones(2 * int(settings.rate_hz / settings.cutoff_hz) + 1)
    parts: dict[str, list[np.ndarray]] = {
        k: [] for k in ("t", "q", "qd", "qdd", "sgn", "tau_f", "tau", "settled", "clean")
    }
    other_parts: dict[str, list[list[np.ndarray]]] = {o: [[], [], []] for o in log.axes if o != axis}
    for keep, ch in source.segments():  # (too short to filter, cut and decimate: skipped)
        # parallel filtering of the Coulomb column: the torque's step at a reversal is smoothed
        # by the low-pass, so sign(q̇) gets the same filter (IDIM: filter W and τ alike); the
        # channels go through the low-pass (where they have not yet), then the decimation, as the
        # columns of one array
        others = {o: ch.others[o] for o in other_parts}
        low = signal.sosfiltfilt(
            sos,
            np.column_stack([ch.q, ch.tau * ch.gate, ch.sgn * ch.gate, *(q for q, _, _ in others.values())]),
            axis=0,
        )
        names = ["q", "tau_f", "sgn", *(f"{o}.q" for o in others), "qd", "qdd"]
        names += [f"{o}.{k}" for o in others for k in ("qd", "qdd")]
        rest = [ch.qd, ch.qdd, *(x for _, qd, qdd in others.values() for x in (qd, qdd))]
        column = dict(zip(names, _decimate(np.column_stack([low, *rest])[keep], settings).T))
        for k in ("q", "qd", "tau_f", "qdd", "sgn"):
            parts[k].append(column[k])
        parts["settled"].append(_settled(ch.qd, settings)[keep][::r])
        unknown = np.isin(ch.tau, levels)
        if filled is not None:
            start = int(np.searchsorted(log.t, ch.t[0]))
            unknown |= filled[start : start + len(ch.t)]
        clipped = np.convolve(unknown, spread, "same") > 0
        parts["clean"].append(~(np.convolve(clipped, np.ones(r), "same") > 0)[keep][::r])
        parts["t"].append(ch.t[keep][::r])
        parts["tau"].append(_interval_mean(ch.tau, r)[keep][::r])
        for o, lists in other_parts.items():
            for i, k in enumerate(("q", "qd", "qdd")):
                lists[i].append(column[f"{o}.{k}"])
    if not parts["t"]:
        raise FilterTooNarrow(
            f"{log.path}: axis {axis!r}: every usable run is shorter than the filter needs "
            f"({2 * edge + 27 * r} samples)"
        )
    cat = {k: np.concatenate(v) for k, v in parts.items()}
    n = min(len(v) for v in cat.values())  # decimate rounds up; t[::r] too: align
    cat = {k: v[:n] for k, v in cat.items()}
    others = {
        o: (np.concatenate(q)[:n], np.concatenate(qd)[:n], np.concatenate(qdd)[:n])
        for o, (q, qd, qdd) in other_parts.items()
    }
    vmax = np.max(np.abs(cat["qd"]))
    moving = cat.pop("settled").astype(bool) & cat.pop("clean").astype(bool)
    if vmax == 0 or np.ptp(cat["q"]) == 0:
        raise UserError(f"{log.path}: axis {axis!r} does not move")
    if moving.sum() < MIN_MOVING:
        raise FilterTooNarrow(
            f"{log.path}: axis {axis!r}: only {int(moving.sum())} moving samples after filtering "
            f"and decimation (need {MIN_MOVING}); record longer or with more motion"
        )
    source.length = n
    return Samples(
        axis,
        cat["t"],
        cat["q"],
        cat["qd"],
        cat["qdd"],
        cat["sgn"],
        cat["tau_f"],
        cat["tau"],
        moving,
        others,
        source,
        rotary=log.axes[axis].kind == "rotary",
    )


def whole_band(log: Log, axis: str, settings: Settings) -> Samples:
    """Samples over the log's whole band (a light low-pass at ``WIDE_BAND`` × the sample rate, no
    decimation), for what the fitted samples cannot show: resonances, transients at reversals.

    Parameters
    ----------
    log : Log
        The log.
    axis : str
        The axis.
    settings : Settings
        The fitted samples' settings (their motion bandwidth and torque delay are kept).

    Returns
    -------
    Samples
        The whole-band samples.
    """
    fs = settings.rate_hz
    return prepare(
        log,
        axis,
        Settings(
            WIDE_BAND * fs,
            1,
            fs,
            max(50, int(3 / WIDE_BAND)),
            settings.motion_bandwidth_hz,
            settings.torque_delay_s,
        ),
    )


def _settled(qd: np.ndarray, settings: Settings) -> np.ndarray:
    """Samples that are moving, and not within the filters' reach of a standstill or reversal.

    At rest a drive holds the axis with whatever torque static friction allows,
    not c0·sign(q̇); the low-pass spreads that over its impulse response, so
    samples that close to a near-zero velocity are left out of the fit, not
    only the near-zero ones themselves (IDIM excludes low velocities).
    """
    near_zero = np.abs(qd) <= MOVING_FRACTION * np.max(np.abs(qd))
    settle_s = SETTLE_CYCLES / settings.cutoff_hz
    half = int(np.ceil(settle_s * settings.rate_hz))
    spread = np.convolve(near_zero.astype(float), np.ones(2 * half + 1), mode="same")
    return spread == 0


def noise_floor(log: Log, axis: str, settings: Settings) -> float:
    """Standard deviation of the torque measurement noise [Nm | N] in the logged torque as the
    errors see it (mean over each decimation interval).

    What the low-pass removes from the logged torque, scaled to the full band
    (white noise: the removed part holds 1 - fc/fN of it) and through the
    interval mean.  No model can have a smaller validation RMSE.

    Parameters
    ----------
    log : Log
        The log.
    axis : str
        The axis.
    settings : Settings
        The fitted samples' settings (cut-off, decimation, edge).

    Returns
    -------
    float
        The noise's std [Nm | N].
    """
    ax = log.axes[axis]
    sos = signal.butter(FILTER_ORDER, settings.cutoff_hz, fs=settings.rate_hz, output="sos")
    res = []
    for a, b in ax.segments:
        if b - a > 2 * settings.edge:
            x = ax.tau[a:b]
            res.append((x - signal.sosfiltfilt(sos, x))[settings.edge : -settings.edge])
    hf = np.concatenate(res) if res else np.zeros(1)
    share = 1.0 - settings.cutoff_hz / (settings.rate_hz / 2)
    return float(np.std(hf) / np.sqrt(share) * np.sqrt(np.sum(_interval_window(settings.decimation) ** 2)))
