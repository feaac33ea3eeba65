"""The chatter frequency of a recording: its spectrum with the spindle
harmonics removed, and the dominant peak that is left, if it stands out of the harmonics' leakage
(``LEAKAGE``) and 20 dB above the noise floor (``PROMINENCE``).

A cut at spindle speed n forces the structure at the spindle frequency
f_s = n / 60 and its harmonics -- the tooth-passing frequency N f_s and its
multiples among them (runout adds the others).  Chatter is a self-excited
vibration at a frequency of its own, near a natural frequency of the
structure (Tlusty; Schmitz & Smith, *Machining Dynamics*, ch. 4): the
dominant peak of the spectrum that is not a harmonic of f_s.

The spectrum is :func:`chatterlab.time.amplitude_spectrum` with the
4-term Blackman-Harris window (side lobes 92 dB down: a strong
tooth-passing harmonic leaks nothing that could pass for a chatter peak)
and :func:`chatterlab.time.peaks` refines each peak.  The window's main
lobe is +-4 bins of 1/D (D the record's duration), so a peak within
``NOTCH`` / D (plus the speed tolerance) of a harmonic m f_s is that
harmonic; two harmonics are ``f_s D`` bins apart, so the record must hold
at least ``MIN_REVOLUTIONS`` revolutions for a chatter peak to fit
between two notches (else it is refused, naming the length needed).  The
chatter frequency is known to the resolution 1/D (a lone peak is located
far better, to 2e-4 of it: :func:`chatterlab.time.peaks`, but a second
frequency within 1/D could not be told apart).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError
from ..io import Result

__all__ = ["ChatterFrequency", "chatter_frequency", "MIN_REVOLUTIONS", "NOTCH", "WINDOW"]

#: the window of the spectrum: side lobes 92 dB down, main lobe +-4 bins
WINDOW = "blackmanharris"
#: half-width of the notch around each harmonic, in bins of 1/D (the window's main lobe, and one more)
NOTCH = 5.0
#: the fewest spindle revolutions a record must hold: two notches of +-NOTCH bins leave two bins free
MIN_REVOLUTIONS = 2 * NOTCH + 2
#: a peak below this share of the largest harmonic may be its leakage (the window's side lobes are
#: 92 dB down, 2.5e-5; four times that), not chatter
LEAKAGE = 1e-4
#: a peak must stand this many times (20 dB) above the median of the spectrum off the harmonics
#: (the noise floor) to be chatter: a record without chatter has only noise there
PROMINENCE = 10.0


@dataclass(frozen=True, eq=False)
class ChatterFrequency(Result):
    """The chatter frequency found in a recording (:func:`chatter_frequency`).

    Attributes
    ----------
    frequency_hz : float
        The dominant peak that is not a spindle harmonic, Hz (nan: none).
    amplitude : float
        Its amplitude (the signal's unit).
    resolution_hz : float
        1 / duration, Hz: how close two frequencies may be told apart.
    spindle_hz, teeth : float, int
        The spindle frequency f_s (Hz) whose harmonics were removed, and
        the teeth N (the tooth-passing frequency N f_s is one of them).
    freq, amp : ndarray
        The spectrum (Hz, the signal's unit).
    harmonic : ndarray of bool
        Where the spectrum lies within a notch of a harmonic.
    peaks_hz, peaks_amp : ndarray
        The non-harmonic peaks, largest first (the first is the chatter).
    removed_hz, removed_amp : ndarray
        The peaks removed as harmonics.
    """

    frequency_hz: float
    amplitude: float
    resolution_hz: float
    spindle_hz: float
    teeth: int
    duration: float
    sample_rate: float
    freq: np.ndarray
    amp: np.ndarray
    harmonic: np.ndarray
    peaks_hz: np.ndarray
    peaks_amp: np.ndarray
    removed_hz: np.ndarray
    removed_amp: np.ndarray
    source: str = ""
    band: tuple[float, float] = (0.0, math.inf)
    threshold: float = 0.0  #: the least amplitude a chatter peak must have (leakage and noise floor)

    @property
    def found(self) -> bool:
        """Whether a non-harmonic peak was found."""
        return bool(np.isfinite(self.frequency_hz))

    @property
    def tooth_hz(self) -> float:
        """The tooth-passing frequency N f_s, Hz."""
        return self.teeth * self.spindle_hz

    def summary(self) -> str:
        head = (
            f"spectrum of {self.source}: {self.duration:.4g} s at {self.sample_rate:.6g} Hz (resolution"
            f" {self.resolution_hz:.3g} Hz); spindle {self.spindle_hz:.6g} Hz, tooth passing {self.tooth_hz:.6g} Hz"
        )
        lines = [head, f"  {self.removed_hz.size} peaks removed as spindle harmonics"]
        if self.found:
            ratio = self.frequency_hz / self.tooth_hz
            lines.append(
                f"  chatter frequency {self.frequency_hz:.2f} Hz +- {self.resolution_hz:.2g} Hz (amplitude"
                f" {self.amplitude:.4g}; {ratio:.3f} x the tooth-passing frequency)"
            )
            if self.peaks_hz.size > 1:
                lines.append(
                    "  next non-harmonic peaks: "
                    + ", ".join(
                        f"{f:.2f} Hz ({a / self.amplitude:.2g})"
                        for f, a in zip(self.peaks_hz[1:4], self.peaks_amp[1:4], strict=False)
                    )  # fmt: skip
                )
        else:
            lines.append(
                f"  no peak in {self.band[0]:.4g} .. {self.band[1]:.4g} Hz apart from the spindle harmonics"
                f" above {self.threshold:.3g} (their leakage, 20 dB over the noise floor): the recording shows"
                " no chatter"
            )
        return "\n".join(lines)

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """The spectrum against frequency, and what was found as attributes."""
        data = {
            "amplitude": (self.amp, "1", "amplitude spectrum (the signal's unit)"),
            "harmonic": (self.harmonic.astype(float), "1", "1 within a notch of a spindle harmonic"),
        }
        attrs = {
            "title": "chatterlab chatter frequency of a recording",
            "source": self.source,
            "chatter_frequency_hz": self.frequency_hz,
            "chatter_amplitude": self.amplitude,
            "resolution_hz": self.resolution_hz,
            "spindle_hz": self.spindle_hz,
            "teeth": self.teeth,
            "duration_s": self.duration,
            "sample_rate_hz": self.sample_rate,
            "peaks_hz": [float(x) for x in self.peaks_hz],
            "removed_hz": [float(x) for x in self.removed_hz],
            "threshold": self.threshold,
        }
        return {"frequency": (self.freq, "Hz", "frequency")}, data, attrs

    def plot(self, ax: Any = None, *, title: str | None = None) -> Any:
        """The spectrum with the harmonic notches shaded and the chatter peak
        marked (:func:`chatterlab.plot.plot_chatter_spectrum`).
        Returns the Axes."""
        from ..plot import plot_chatter_spectrum

        return plot_chatter_spectrum(self, ax=ax, title=title)


def chatter_frequency(
    recording: Any,
    *,
    spindle_hz: float,
    teeth: int = 1,
    fmin: float | None = None,
    fmax: float | None = None,
    tolerance: float = 0.0,
    channel: int = 0,
) -> ChatterFrequency:
    """The chatter frequency of a recording: the dominant spectral peak that
    is not a harmonic of the spindle frequency (module docstring).

    Parameters
    ----------
    recording : path or (t, x)
        A WAV or CSV file (:func:`read_recording`), or the times (s,
        uniform) and the signal.
    spindle_hz : float
        The spindle frequency n / 60, Hz (a shaper: its stroke rate 1 / T).
    teeth : int
        N: the tooth-passing frequency N f_s (its harmonics are among the
        spindle's; said in the summary).
    fmin, fmax : float, optional
        The band searched, Hz (default: half the spindle frequency to the
        Nyquist frequency).
    tolerance : float
        Relative uncertainty of the spindle speed: the notch around the
        m-th harmonic widens by m f_s tolerance (default 0: the speed is
        known exactly).
    channel : int
        A WAV's channel, or the CSV's signal column after the time.

    Returns
    -------
    ChatterFrequency
    """
    from ..time import amplitude_spectrum, peaks
    from ._recording import describe, read_recording

    f_s = _positive(spindle_hz, "spindle_hz", "Hz")
    if isinstance(teeth, bool) or not isinstance(teeth, int | np.integer) or teeth < 1:
        raise InputError(f"teeth must be a whole number >= 1 (got {teeth!r})")
    if not (isinstance(tolerance, int | float) and 0 <= tolerance < 0.1):
        raise InputError(f"tolerance must be a relative speed uncertainty in [0, 0.1) (got {tolerance!r})")
    name = describe(recording)
    if isinstance(recording, tuple | list) and len(recording) == 2:
        t, x = (np.asarray(a, float) for a in recording)
        if t.ndim != 1 or x.shape != t.shape:
            raise InputError("a recording (t, x) must be two 1-D arrays of equal length")
    else:
        t, x = read_recording(recording, channel=channel)
    n = t.size
    dt = (t[-1] - t[0]) / (n - 1) if n > 1 else math.nan
    duration = n * dt
    fs = 1.0 / dt
    revs = duration * f_s
    if revs < MIN_REVOLUTIONS:
        need = MIN_REVOLUTIONS / f_s
        raise InputError(
            f"recording {name}: {duration:.4g} s holds {revs:.3g} spindle revolutions ({f_s:.4g} Hz); the"
            f" spindle harmonics are told apart from a chatter peak from {MIN_REVOLUTIONS:g} revolutions on"
            f" (resolution 1/duration): record at least {need:.3g} s"
        )
    if teeth * f_s >= fs / 2:
        raise InputError(
            f"recording {name}: sampled at {fs:.6g} Hz, the tooth-passing frequency {teeth * f_s:.6g} Hz lies"
            f" above the Nyquist frequency {fs / 2:.6g} Hz, so its harmonics fold onto others: record at a"
            f" sample rate above {5 * teeth * f_s:.6g} Hz"
        )
    lo = 0.5 * f_s if fmin is None else _nonneg(fmin, "fmin")
    hi = fs / 2 if fmax is None else _positive(fmax, "fmax", "Hz")
    if not hi > lo:
        raise InputError(f"the band searched is empty: fmax ({hi:g} Hz) must exceed fmin ({lo:g} Hz)")
    freq, amp = amplitude_spectrum(t, x, window=WINDOW, pad=4)
    res = 1.0 / duration
    m = np.maximum(np.rint(freq / f_s), 1.0)
    near = np.abs(freq - m * f_s) <= NOTCH * res + m * f_s * tolerance
    fp, ap = peaks(freq, amp, n=max(50, int(4 * hi / f_s) + 50), fmin=lo)
    keep = fp <= hi
    fp, ap = fp[keep], ap[keep]
    mp = np.maximum(np.rint(fp / f_s), 1.0)
    harm = np.abs(fp - mp * f_s) <= NOTCH * res + mp * f_s * tolerance
    band = (freq >= lo) & (freq <= hi) & ~near
    floor = float(np.median(amp[band])) if np.any(band) else 0.0
    threshold = max(LEAKAGE * float(np.max(ap[harm], initial=0.0)), PROMINENCE * floor)
    free = ~harm & (ap > threshold)
    free_f, free_a = fp[free], ap[free]
    f_c = float(free_f[0]) if free_f.size else math.nan
    a_c = float(free_a[0]) if free_a.size else math.nan
    return ChatterFrequency(
        frequency_hz=f_c, amplitude=a_c, resolution_hz=res, spindle_hz=f_s, teeth=int(teeth), duration=duration,
        sample_rate=fs, freq=freq, amp=amp, harmonic=near, peaks_hz=free_f, peaks_amp=free_a,
        removed_hz=fp[harm], removed_amp=ap[harm], source=name, band=(lo, hi), threshold=threshold,
    )  # fmt: skip


def _positive(v: Any, name: str, unit: str) -> float:
    if (
        isinstance(v, bool)
        or not isinstance(v, int | float | np.floating)
        or not (math.isfinite(v) and v > 0)
    ):
        raise InputError(f"{name} must be a finite number > 0 {unit} (got {v!r})")
    return float(v)


def _nonneg(v: Any, name: str) -> float:
    if (
        isinstance(v, bool)
        or not isinstance(v, int | float | np.floating)
        or not (math.isfinite(v) and v >= 0)
    ):
        raise InputError(f"{name} must be a finite number >= 0 Hz (got {v!r})")
    return float(v)
