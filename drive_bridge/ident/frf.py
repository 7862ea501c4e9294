"""The plant's frequency response measured through the drive, as the industrial auto-tuners do.

The axis sweeps its stroke at a constant speed (friction then stays on one side: no reversal,
no sticking) while the master adds a periodic torque offset to the drive's torque command
(0x60B2, once per SYNC): a Schroeder-phased multisine with every bin from ``F_LOW_HZ`` to
``F_HIGH_SHARE`` × the SYNC rate excited at the same amplitude.  With the drive's loops closed,
the offset ``u`` reaches the measured velocity through ``T = G / (1 + K·G)``, where ``G`` is the
plant from torque command to velocity (current loop, mechanics: a compliant transmission's
resonance included) and ``K`` the drive's own controller as seen at the torque command (its
velocity PI, the position P around it, the loop's delay: :func:`drive_bridge.params.cascade.controller`).
``T`` is read per excited bin from the SYNC samples of the position (its DFT times jω, the
constant sweep removed), averaged over the periods after the first (the loops' settling), and
divided by the zero-order hold the offset is applied through; then ``G = T / (1 − K·T)``.
Nothing of the logged torque is used: its reporting (averaged, filtered, delayed) differs from
drive to drive, the position does not.  Each bin's coherence is the share of its power the
excitation explains across the periods (1: no noise).  SI: Hz, rad/s per Nm.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

F_LOW_HZ = 2.0  # lowest excited frequency (below it the position loop holds the axis)
F_HIGH_SHARE = 0.45  # highest, × the SYNC rate (0.5: Nyquist)
TOP_SHARE = 0.4  # bins above this share of the SYNC rate are reported, not used for margins: the
# offset's held steps have images above the Nyquist frequency whose response
# aliases onto them (the rigid simulated axis: -2.6 dB at 0.4, -5.9 dB at 0.45)
PERIOD_SAMPLES = 512  # one period of the excitation, in SYNC periods (1.02 s at 500 Hz: 0.98 Hz bins)
PERIODS = 5  # periods streamed; the first is the loops' settling and is not used
MIN_COHERENCE = 0.8  # bins below it are reported, not used for margins
MAX_LOOP_GAIN = 10.0  # nor the bins below the first whose loop gain |K·G| is under this: there the loop,
# not the plant, sets the measured velocity, and G = T / (1 − K·T) divides by a
# small difference (a 1 % error of K: 10 % of G).  A resonance above may exceed it
# again: its peak is what the margins need


@dataclass
class Frf:
    """The plant's frequency response measured through the drive (:func:`measure`).

    Parameters
    ----------
    frequency_hz : numpy.ndarray
        The excited bins [Hz].
    response : numpy.ndarray
        The plant G(jω) there [rad/s per Nm], complex.
    coherence : numpy.ndarray
        Each bin's coherence (0..1).
    loop_gain : numpy.ndarray
        The drive's loop gain |K·G| with the gains it ran with.
    rate_hz : float
        The SYNC rate it was measured at [Hz].
    filled : int
        Position samples that were missing (late SYNCs) and filled in linearly before the DFT.
    late : int
        SYNC periods of the run whose set-point and torque offset reached the drive late (it
        applied the ones before again).
    """

    frequency_hz: np.ndarray
    response: np.ndarray
    coherence: np.ndarray
    loop_gain: np.ndarray
    rate_hz: float
    filled: int = 0
    late: int = 0

    def reliable(self) -> np.ndarray:
        """The bins that measure the plant: coherence at least ``MIN_COHERENCE``, from the lowest
        frequency whose loop gain stays at most ``MAX_LOOP_GAIN`` over the octave above it (one bin
        alone may read low where a disturbance at a fixed frequency -- a belt's teeth at the sweep's
        speed -- spoils it) up to ``TOP_SHARE`` of the SYNC rate.

        Returns
        -------
        numpy.ndarray
            A boolean per bin.
        """
        f = self.frequency_hz
        high = self.loop_gain > MAX_LOOP_GAIN
        starts = [fi for fi in f if not high[(f >= fi) & (f <= 2 * fi)].any()]
        above = f >= (starts[0] if starts else np.inf)
        return (self.coherence >= MIN_COHERENCE) & above & (f <= TOP_SHARE * self.rate_hz)

    def as_json(self) -> dict:
        """The response as frf.json holds it.

        Returns
        -------
        dict
            ``rate_hz``, ``filled_samples``, ``late_setpoints``, and per bin its frequency, magnitude [dB], phase [°],
            coherence, loop gain and whether it is reliable.
        """
        return {
            "rate_hz": self.rate_hz,
            "filled_samples": self.filled,
            "late_setpoints": self.late,
            "frequency_hz": [round(float(f), 4) for f in self.frequency_hz],
            "magnitude_db": [round(float(20 * np.log10(abs(g))), 3) for g in self.response],
            "phase_deg": [round(float(np.degrees(np.angle(g))), 2) for g in self.response],
            "coherence": [round(float(c), 4) for c in self.coherence],
            "loop_gain": [round(float(x), 4) for x in self.loop_gain],
            "reliable": [bool(r) for r in self.reliable()],
        }

    @classmethod
    def from_json(cls, doc: dict) -> Frf:
        """A response as :meth:`as_json` wrote it.

        Parameters
        ----------
        doc : dict
            The document.

        Returns
        -------
        Frf
            The response.
        """
        mag = 10 ** (np.asarray(doc["magnitude_db"], dtype=float) / 20)
        return cls(
            np.asarray(doc["frequency_hz"], dtype=float),
            mag * np.exp(1j * np.radians(np.asarray(doc["phase_deg"], dtype=float))),
            np.asarray(doc["coherence"], dtype=float),
            np.asarray(doc["loop_gain"], dtype=float),
            float(doc["rate_hz"]),
            int(doc.get("filled_samples", 0)),  # (frf.json before they were said)
            int(doc.get("late_setpoints", 0)),
        )


def excited_bins(rate_hz: float, samples: int = PERIOD_SAMPLES) -> np.ndarray:
    """The DFT bins of one period that the excitation drives.

    Parameters
    ----------
    rate_hz : float
        The SYNC rate [Hz].
    samples : int
        One period, in SYNC periods.

    Returns
    -------
    numpy.ndarray
        Their indices: from ``F_LOW_HZ`` to ``F_HIGH_SHARE`` × the rate.
    """
    f = np.fft.rfftfreq(samples, 1.0 / rate_hz)
    return np.flatnonzero((f >= F_LOW_HZ) & (f <= F_HIGH_SHARE * rate_hz))


def excitation(rate_hz: float, rms_Nm: float, samples: int = PERIOD_SAMPLES) -> np.ndarray:
    """One period of the torque offset: equal amplitudes on :func:`excited_bins`, Schroeder's
    phases (a low crest factor, deterministic).

    Parameters
    ----------
    rate_hz : float
        The SYNC rate [Hz].
    rms_Nm : float
        Its RMS [Nm].
    samples : int
        One period, in SYNC periods.

    Returns
    -------
    numpy.ndarray
        The offset at each SYNC of the period [Nm].
    """
    bins = excited_bins(rate_hz, samples)
    k = np.arange(1, len(bins) + 1)
    spectrum = np.zeros(samples // 2 + 1, dtype=complex)
    spectrum[bins] = np.exp(-1j * np.pi * k * (k - 1) / len(bins))
    u = np.fft.irfft(spectrum, samples)
    return u * rms_Nm / np.sqrt(np.mean(u**2))


def measure(
    position: np.ndarray,
    offset: np.ndarray,
    rate_hz: float,
    controller: Callable[[np.ndarray], np.ndarray],
    samples: int = PERIOD_SAMPLES,
) -> Frf:
    """The plant G(jω) from the positions sampled at each SYNC while the periodic offset was applied.

    Parameters
    ----------
    position : numpy.ndarray
        The positions [rad], from the first sample of a period, whole periods.
    offset : numpy.ndarray
        The torque offset applied [Nm], likewise.
    rate_hz : float
        The SYNC rate [Hz].
    controller : callable
        K(ω): the drive's controller with the gains it ran with [Nm per rad/s].
    samples : int
        One period, in SYNC periods.

    Returns
    -------
    Frf
        The response per excited bin, its coherence and the loop gain.

    Raises
    ------
    ValueError
        Fewer than three whole periods.
    """
    periods = len(position) // samples
    if periods < 3 or len(offset) < periods * samples:
        raise ValueError(
            f"the FRF needs at least three whole periods of {samples} samples, got {len(position)}"
        )
    bins = excited_bins(rate_hz, samples)
    f = np.fft.rfftfreq(samples, 1.0 / rate_hz)[bins]
    w = 2 * np.pi * f
    q = position[: periods * samples].reshape(periods, samples)[1:]
    sweep = (q[-1, 0] - q[0, 0]) / (len(q) - 1)  # the constant speed's travel in one period
    q = q - sweep * np.arange(samples) / samples
    v = 1j * w * np.fft.rfft(q, axis=1)[:, bins]  # velocity per period and bin
    u = np.fft.rfft(offset[:samples])[bins]
    hold = np.exp(-1j * w / (2 * rate_hz)) * np.sinc(f / rate_hz)  # the offset held over each SYNC period
    t = v / (u * hold)
    mean = t.mean(axis=0)
    coherence = np.abs(mean) ** 2 / np.mean(np.abs(t) ** 2, axis=0)
    k = controller(w)
    g = mean / (1 - k * mean)
    return Frf(f, g, coherence, np.abs(k * g), float(rate_hz))


LOG_BANDS = 48  # log-spaced bands the log's response is reported in, 1 Hz .. Nyquist
LOG_RESOLUTION_HZ = 0.5  # Welch resolution aimed at


def log_response(
    t: np.ndarray, qd: np.ndarray, tau: np.ndarray, J: float, c1: float, reference: np.ndarray | None = None
) -> dict | None:
    """The plant's torque → velocity response read from a campaign log, for reference, in
    ``LOG_BANDS`` log-spaced bands from 1 Hz to the Nyquist frequency, the rigid model's
    |1/(J·jω + c1)| beside it.  ``tau``: the torque as logged, aligned with the position, less what
    the identified model says is not J·q̈ + c1·q̇ (friction's sign, the traced effects); ``qd``: the
    velocity; ``t``: their instants (Welch over each stretch of evenly spaced samples).  With the
    position demand ``reference`` the response is its cross-spectrum with the velocity over its
    cross-spectrum with the torque (the setpoints are the instrument: in closed loop the torque
    also answers the loop's own measurement noise, which the plain ratio would mix in, drawing it
    towards the inverse controller), its coherence the smaller of the demand's with each;
    without, the plain cross- over auto-spectrum and its coherence (``method`` says which).
    Where the setpoints do not move the axis -- above the campaign's band -- the coherence falls:
    it says how little is left.  SI: Hz, rad/s per Nm (m/s per N).

    Parameters
    ----------
    t : numpy.ndarray
        The samples' instants [s].
    qd : numpy.ndarray
        The velocity [rad/s | m/s].
    tau : numpy.ndarray
        The torque as logged, aligned, less what the model says is not J·q̈ + c1·q̇ [Nm | N].
    J : float
        The identified inertia [kg·m² | kg].
    c1 : float
        The identified viscous friction [Nm·s/rad | N·s/m].
    reference : numpy.ndarray, optional
        The position demand at the same instants [rad | m].

    Returns
    -------
    dict or None
        Per band its frequency, magnitude, phase and coherence, the rigid model's magnitude, and
        ``method``; None for a log without a stretch long enough.
    """
    from .spectra import csd, welch  # (scipy.signal: imported where it is used)

    dt = float(np.median(np.diff(t)))
    fs = 1.0 / dt
    cuts = np.flatnonzero(np.diff(t) > 1.5 * dt) + 1
    stretches = list(zip(np.r_[0, cuts], np.r_[cuts, len(t)]))
    nper = int(2 ** np.ceil(np.log2(fs / LOG_RESOLUTION_HZ)))
    longest = max(b - a for a, b in stretches)
    while nper > 256 and nper > longest:
        nper //= 2
    x = tau if reference is None else reference
    sums = np.zeros((5, nper // 2 + 1), dtype=complex)  # S_xx, S_vv, S_tt, S_xv, S_xt
    f = None
    for a, b in stretches:
        if b - a < nper:
            continue
        sl = slice(a, b)
        f, pxx = welch(x[sl], fs, nper)
        sums += (
            (b - a)
            / nper
            * np.array(
                [
                    pxx,
                    welch(qd[sl], fs, nper)[1],
                    welch(tau[sl], fs, nper)[1],
                    csd(x[sl], qd[sl], fs, nper)[1],
                    csd(x[sl], tau[sl], fs, nper)[1],
                ]
            )
        )
    if f is None:
        return None
    edges = np.geomspace(1.0, fs / 2, LOG_BANDS + 1)
    out: dict[str, list] = {
        "frequency_hz": [],
        "magnitude": [],
        "phase_deg": [],
        "coherence": [],
        "model_magnitude": [],
    }
    for lo, hi in zip(edges[:-1], edges[1:]):
        band = (f >= lo) & (f < hi) & (f > 0)
        sxx, svv, stt, sxv, sxt = (complex(np.sum(row[band])) for row in sums)
        if not band.any() or sxx.real <= 0 or svv.real <= 0 or stt.real <= 0 or sxt == 0:
            continue
        g = sxv / sxt
        coh = min(abs(sxv) ** 2 / (sxx.real * svv.real), abs(sxt) ** 2 / (sxx.real * stt.real))
        fc = float(np.sqrt(lo * hi))
        out["frequency_hz"].append(round(fc, 3))
        out["magnitude"].append(float(abs(g)))
        out["phase_deg"].append(round(float(np.degrees(np.angle(g))), 2))
        out["coherence"].append(round(float(coh), 4))
        out["model_magnitude"].append(float(1 / abs(2j * np.pi * fc * J + max(c1, 0.0))))
    method = (
        "the position demand as instrument: S(demand, velocity) / S(demand, torque)"
        if reference is not None
        else "no position demand in the log: S(torque, velocity) / S(torque, torque), biased towards the "
        "inverse controller where the loop's own noise moves the axis"
    )
    return {
        "source": "the campaign log: the torque as logged, aligned and less the model's nonlinear terms, to the "
        "velocity",
        "method": method,
        **out,
    }
