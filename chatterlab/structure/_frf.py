"""A measured frequency response: a structure known only by its FRF.

:class:`MeasuredFRF` holds the receptance H (m/N) of a structure between
named coordinates at the measured frequencies, the band those frequencies
cover, and optionally the coherence.  It is the object every measured input
becomes however it arrives (CSV/TXT, UFF 58/58b, CutPro-style ``.frf``,
python-control ``FrequencyResponseData``, arrays, or a model's computed FRF
as the oracle of the tests), and the object the lobe engine
(:func:`chatterlab.lobes.measured_plant`), the modal fit and receptance
coupling take.

Inside: angular frequency in rad/s, receptance in m/N (a rotation among the
coordinates: rad and N m as the model's), data shaped ``(n_freq, n_out,
n_in)``.  Hz only in :attr:`MeasuredFRF.frequency_hz` and in files.

Between the measured frequencies, :meth:`MeasuredFRF.interpolate` uses a
cubic spline (not-a-knot) through the real and the imaginary part of every
entry separately, in w.  For data that are smooth on the scale of the
spacing h, the error of a cubic spline is at most (5/384) h^4 max|H''''|
(Hall & Meyer [1]; not-a-knot ends keep the order 4 with a larger constant
in the end intervals).  To leading order the error is the Hermite term,
(1/384) h^4 |H''''| at mid-interval, plus what the spline's slope errors add
on an uneven spacing; :meth:`MeasuredFRF.interpolation_error` estimates
that per interval (H'''' from fourth divided differences, the slope errors
against the polynomial through seven samples).  Outside the measured band nothing is
extrapolated: the call raises (``outside="raise"``, the default) or returns
NaN (``outside="nan"``).

References
----------
.. [1] C. A. Hall, W. W. Meyer, "Optimal error bounds for cubic spline
   interpolation", J. Approx. Theory 16, 105-122, 1976.
.. [2] D. J. Ewins, *Modal Testing: Theory, Practice and Application*, 2nd
   ed., Research Studies Press, 2000 (receptance, mobility, accelerance).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from ..errors import InputError

if TYPE_CHECKING:
    from ._system import FrozenSystem

__all__ = ["MeasuredFRF"]

#: relative tolerance on the band ends (a frequency that prints equal is inside)
_BAND_TOL = 1e-12


def _names(names: Any, n: int, what: str) -> tuple[str, ...]:
    if isinstance(names, str):
        names = (names,)
    out = tuple(str(x) for x in names)
    if len(out) != n:
        raise InputError(f"{what} must name {n} coordinate(s) to match H (got {len(out)}: {list(out)})")
    if len(set(out)) != len(out):
        raise InputError(f"{what} name a coordinate twice: {list(out)}")
    return out


def _unknown(name: str, known: tuple[str, ...], what: str) -> InputError:
    import difflib

    near = difflib.get_close_matches(name, known, n=1)
    hint = f" (did you mean {near[0]!r}?)" if near else ""
    return InputError(f"{what} {name!r} is not measured{hint}; measured: {', '.join(known)}")


@dataclass(frozen=True, eq=False)
class MeasuredFRF:
    """Receptance of a structure between named coordinates, as measured.

    Attributes
    ----------
    frequency : ndarray, shape (n_freq,)
        Angular frequencies, rad/s, strictly increasing, >= 0.  Spacing may
        be uneven.
    H : ndarray, shape (n_freq, n_out, n_in), complex
        Receptance, m/N: ``H[k, o, i]`` is the displacement of coordinate
        ``outputs[o]`` per unit force at ``inputs[i]`` at ``frequency[k]``.
    outputs, inputs : tuple of str
        Coordinate names (``"tool.x"``; for a UFF file ``"NODE.x"``).
    coherence : ndarray, shape (n_freq, n_out, n_in), optional
        Ordinary coherence (0..1) of each entry, when measured.
    source : str
        Where the data came from (a file name, ``"arrays"``, ``"model ..."``).
    meta : dict
        What the file said besides the data (its units and quantity...).
    """

    frequency: np.ndarray
    H: np.ndarray
    outputs: tuple[str, ...]
    inputs: tuple[str, ...]
    coherence: np.ndarray | None = None
    source: str = "arrays"
    meta: dict[str, Any] = field(default_factory=dict)

    # ------------------------------------------------------------------ construction

    @classmethod
    def from_arrays(
        cls,
        frequency: Any,
        H: Any,
        outputs: Any = ("1",),
        inputs: Any = ("1",),
        *,
        hz: bool = False,
        coherence: Any = None,
        source: str = "arrays",
        meta: dict[str, Any] | None = None,
    ) -> MeasuredFRF:
        """A measured FRF from arrays, checked.

        Parameters
        ----------
        frequency : array, shape (n_freq,)
            rad/s (Hz with ``hz=True``); strictly increasing, finite, >= 0.
        H : array, shape (n_freq, n_out, n_in) or (n_freq,)
            Receptance, m/N (a 1-D array is one output and one input).
        outputs, inputs : sequence of str
            Coordinate names.
        coherence : array like ``H``, optional
            Values in [0, 1].
        """
        w = np.asarray(frequency, dtype=float)
        if w.ndim != 1 or w.size < 2:
            raise InputError(
                f"{source}: frequency must be a 1-D array of at least 2 values (got shape {w.shape})"
            )
        if hz:
            w = 2 * np.pi * w
        Hc = np.asarray(H, dtype=complex)
        if Hc.ndim == 1:
            Hc = Hc[:, None, None]
        if Hc.ndim != 3 or Hc.shape[0] != w.size:
            raise InputError(
                f"{source}: H must have shape (n_freq, n_out, n_in) with n_freq = {w.size} (got {Hc.shape})"
            )
        _check_frequency(w, source)
        bad = ~np.isfinite(Hc)
        if np.any(bad):
            k, o, i = (int(x[0]) for x in np.nonzero(bad))
            raise InputError(
                f"{source}: H is not finite at {w[k] / (2 * np.pi):g} Hz (entry {o}, {i}); drop or repair that point"
            )
        outs = _names(outputs, Hc.shape[1], f"{source}: outputs")
        ins = _names(inputs, Hc.shape[2], f"{source}: inputs")
        coh = None
        if coherence is not None:
            coh = np.asarray(coherence, dtype=float)
            if coh.ndim == 1:
                coh = coh[:, None, None]
            if coh.shape != Hc.shape:
                raise InputError(f"{source}: coherence must have the shape of H {Hc.shape} (got {coh.shape})")
            if not np.all(np.isfinite(coh) & (coh >= 0) & (coh <= 1 + 1e-9)):
                raise InputError(f"{source}: coherence must lie in [0, 1]")
        w.setflags(write=False)
        Hc.setflags(write=False)
        return cls(w, Hc, outs, ins, coh, source, dict(meta or {}))

    @classmethod
    def read(
        cls,
        path: str | os.PathLike[str],
        units: str | None = None,
        quantity: str | None = None,
        *,
        point: str | None = None,
        format: str | None = None,
    ) -> MeasuredFRF:
        """Read a measured FRF file; the format from the suffix (``.csv``,
        ``.txt``: columns; ``.frf``: CutPro-style; ``.uff``, ``.unv``: UFF
        dataset 58/58b) or ``format`` (``"csv"``, ``"frf"``, ``"uff"``).

        ``units`` (``"mm/N"``, ``"m/s/N"``, ``"g/N"``...) and ``quantity``
        (``"receptance"``, ``"mobility"``, ``"accelerance"``) override what
        the file says; everything is converted to receptance in m/N.
        ``point`` names the point of two-letter columns (``xy`` ->
        ``POINT.x`` / ``POINT.y``).  See docs/measured-frf.md for the formats.
        """
        from ..io._frf_files import read_frf

        return cls.from_table(read_frf(path, units=units, quantity=quantity, point=point, format=format))

    @classmethod
    def from_table(cls, t: Any, source: str | None = None) -> MeasuredFRF:
        """From what :func:`chatterlab.io.read_frf` returns (an ``FRFTable``:
        frequencies in Hz, receptance in m/N, coordinate names)."""
        return cls.from_arrays(
            t.frequency_hz,
            t.H,
            t.outputs,
            t.inputs,
            hz=True,
            coherence=t.coherence,
            source=source or t.source,
            meta=dict(t.meta),
        )

    @classmethod
    def from_control(cls, frd: Any, *, source: str = "python-control FrequencyResponseData") -> MeasuredFRF:
        """From a ``control.FrequencyResponseData`` (receptance, m/N; omega in
        rad/s); the coordinate names are its signal labels (``:`` read as
        ``.``, see :meth:`to_control`)."""
        import control

        if not isinstance(frd, control.FrequencyResponseData):
            raise InputError(f"expected a control.FrequencyResponseData, got {type(frd).__name__}")
        resp = np.asarray(
            getattr(frd, "frdata", None) if hasattr(frd, "frdata") else frd.fresp, dtype=complex
        )  # (n_out, n_in, n_freq)
        outs = tuple(x.replace(":", ".") for x in frd.output_labels)
        ins = tuple(x.replace(":", ".") for x in frd.input_labels)
        return cls.from_arrays(
            np.asarray(frd.omega, dtype=float), np.transpose(resp, (2, 0, 1)), outs, ins, source=source
        )

    @classmethod
    def from_frf(cls, frf: Any, *, source: str | None = None) -> MeasuredFRF:
        """From a computed :class:`chatterlab.frequency.FRF` (any quantity;
        converted to receptance).  Duck-typed: ``omega``, ``data`` (n_out,
        n_in, n_freq), ``outputs``, ``inputs``, ``kind``."""
        power = {"receptance": 0, "mobility": 1, "accelerance": 2}[frf.kind]
        w = np.asarray(frf.omega, dtype=float)
        data = np.asarray(frf.data, dtype=complex)
        if power:
            if np.any(w == 0):
                raise InputError(f"a {frf.kind} at 0 Hz cannot be converted to receptance; drop that point")
            data = data / (1j * w) ** power
        return cls.from_arrays(
            w,
            np.transpose(data, (2, 0, 1)),
            frf.outputs,
            frf.inputs,
            source=source or f"computed FRF ({frf.method})",
        )

    @classmethod
    def from_model(
        cls,
        frozen: FrozenSystem,
        outputs: Any,
        inputs: Any | None = None,
        omega: Any = None,
    ) -> MeasuredFRF:
        """A model's open-loop receptance at the frequencies ``omega``
        (rad/s), as if measured: the exact pole-residue sum over all complex
        modes (the same sum as ``chatterlab.frequency.frf(...,
        method="modal")``).  ``inputs`` defaults to ``outputs`` (a
        driving-point matrix).  The oracle of the measured-FRF tests."""
        from ._complex import modal_response

        outs = [outputs] if isinstance(outputs, str) else list(outputs)
        ins = outs if inputs is None else ([inputs] if isinstance(inputs, str) else list(inputs))
        if omega is None:
            raise InputError("from_model needs the frequencies omega (rad/s)")
        w = np.asarray(omega, dtype=float)
        _check_frequency(w, "from_model")
        rows = np.array([frozen.dof(s) for s in outs])
        cols = np.array([frozen.dof(s) for s in ins]).T
        cm = frozen.complex_modes
        G = modal_response(cm, rows, cols, 1j * w, np.arange(cm.lam.size), False)
        return cls.from_arrays(
            w,
            np.transpose(G, (2, 0, 1)),
            outs,
            ins,
            source=f"model {frozen.model.source}",
            meta={"model": True},
        )

    # ------------------------------------------------------------------ views

    @property
    def frequency_hz(self) -> np.ndarray:
        """The measured frequencies, Hz."""
        return self.frequency / (2 * np.pi)

    @property
    def band(self) -> tuple[float, float]:
        """(lo, hi), rad/s: the measured band, first to last frequency."""
        return float(self.frequency[0]), float(self.frequency[-1])

    @property
    def band_hz(self) -> tuple[float, float]:
        lo, hi = self.band
        return lo / (2 * np.pi), hi / (2 * np.pi)

    @property
    def shape(self) -> tuple[int, int, int]:
        n, o, i = self.H.shape
        return n, o, i

    def __getitem__(self, key: tuple[str, str]) -> np.ndarray:
        """``frf["tool.x", "tool.x"]`` -> (n_freq,) complex."""
        o, i = key
        return self.H[:, self._out(o), self._in(i)]

    def _out(self, name: str) -> int:
        if name not in self.outputs:
            raise _unknown(name, self.outputs, "output")
        return self.outputs.index(name)

    def _in(self, name: str) -> int:
        if name not in self.inputs:
            raise _unknown(name, self.inputs, "input")
        return self.inputs.index(name)

    def select(self, outputs: Any = None, inputs: Any = None) -> MeasuredFRF:
        """The sub-matrix between the named outputs and inputs (in that
        order; None keeps all)."""
        outs = (
            self.outputs if outputs is None else ((outputs,) if isinstance(outputs, str) else tuple(outputs))
        )
        ins = self.inputs if inputs is None else ((inputs,) if isinstance(inputs, str) else tuple(inputs))
        io = [self._out(o) for o in outs]
        ii = [self._in(i) for i in ins]
        H = self.H[:, io][:, :, ii]
        coh = None if self.coherence is None else self.coherence[:, io][:, :, ii]
        return MeasuredFRF.from_arrays(
            self.frequency, H, outs, ins, coherence=coh, source=self.source, meta=self.meta
        )

    def renamed(self, outputs: Any = None, inputs: Any = None) -> MeasuredFRF:
        """The same data under other coordinate names."""
        outs = self.outputs if outputs is None else _names(outputs, len(self.outputs), "outputs")
        ins = self.inputs if inputs is None else _names(inputs, len(self.inputs), "inputs")
        return MeasuredFRF(self.frequency, self.H, outs, ins, self.coherence, self.source, self.meta)

    # ------------------------------------------------------------------ interpolation

    def in_band(self, omega: Any) -> np.ndarray:
        """Boolean mask of the frequencies (rad/s) inside the measured band."""
        w = np.asarray(omega, dtype=float)
        lo, hi = self.band
        tol = _BAND_TOL * hi
        return (w >= lo - tol) & (w <= hi + tol)

    @cached_property
    def _spline(self) -> Any:
        """The cubic splines of Re H and Im H (all entries), built once."""
        from scipy.interpolate import CubicSpline

        n = self.frequency.size
        flat = self.H.reshape(n, -1)
        y = np.concatenate([flat.real, flat.imag], axis=1)
        return CubicSpline(self.frequency, y, axis=0, bc_type="not-a-knot", extrapolate=False)

    def interpolate(self, omega: Any, *, outside: Literal["raise", "nan"] = "raise") -> np.ndarray:
        """H at the angular frequencies ``omega`` (rad/s), shape (n, n_out, n_in).

        A cubic spline (not-a-knot) through the real and the imaginary part
        of each entry in w; at the measured frequencies it returns the data
        exactly.  Error: see :meth:`interpolation_error`.  Outside the
        measured band ``outside="raise"`` raises :class:`InputError`,
        ``"nan"`` returns NaN there; nothing is extrapolated."""
        w = np.atleast_1d(np.asarray(omega, dtype=float))
        inside = self.in_band(w)
        if not np.all(inside) and outside == "raise":
            bad = w[~inside][0]
            lo, hi = self.band_hz
            raise InputError(
                f"{self.source}: {bad / (2 * np.pi):g} Hz is outside the measured band {lo:g} .. {hi:g} Hz;"
                " a measured FRF is not extrapolated (use outside='nan' or stay inside the band)"
            )
        if outside not in ("raise", "nan"):
            raise InputError(f"outside must be 'raise' or 'nan' (got {outside!r})")
        lo, hi = self.band
        wc = np.clip(w, lo, hi)
        n, no, ni = self.H.shape
        y = self._spline(wc)
        out = (y[:, : no * ni] + 1j * y[:, no * ni :]).reshape(w.size, no, ni)
        # exact at the samples (the spline passes through them to round-off; make it exact)
        k = np.searchsorted(self.frequency, wc)
        k = np.minimum(k, n - 1)
        hit = self.frequency[k] == wc
        out[hit] = self.H[k[hit]]
        out[~inside] = np.nan
        return out

    def interpolation_error(self, omega: Any) -> np.ndarray:
        """Estimated error of :meth:`interpolate` at ``omega`` (rad/s), per
        entry, shape (n, n_out, n_in), m/N: the largest leading-order error
        of the spline over the interval [x_j, x_j+1] that holds each w.

        On an interval of length h the spline s is the cubic Hermite
        interpolant of the samples with the spline's own slopes s'_j, so
        with t = (w - x_j) / h, to leading order,

            s - H = -(H4 / 24) h^4 t^2 (1-t)^2 + h [t (1-t)^2 d_j - t^2 (1-t) d_j+1]

        with H4 the fourth derivative and d_j = s'(x_j) - H'(x_j) the slope
        errors.  H4 is the mean of 24 times the fourth divided differences
        of the five samples from x_j-2 and from x_j-1 (centred on the
        interval), H'(x_j) the slope of the polynomial through the seven
        samples around x_j; the estimate is the largest |s - H| of this
        expansion over the interval.  On an even spacing the slope errors
        are of higher order (h^4 H^(5)) and the estimate is (1/384) h^4 |H4|,
        the Hermite term at mid-interval: the spline's error to leading
        order, a fifth of Hall & Meyer's worst-case bound (5/384) h^4 max|H4|
        (which allows for slope errors of order h^3; an estimate built on it
        comes out 4-5 times the true error).  On an uneven spacing the slope
        errors are of that order and the second term carries them.

        Accuracy (tested in tests/test_reference_defects.py): on a 1-DOF
        FRF with spacing h <= sigma / 8 (sigma the half-power half-width,
        rad/s: >= 8 points per half-power width), away from the two end
        intervals, between 0.6 and 1.25 times the largest true error over
        each interval, on an even, a geometric and a randomly jittered
        spacing: within a factor 2 both ways.  At h = sigma / 4 it may be
        3 times too small.  An estimate, not a guarantee: it assumes H
        smooth on the scale of the spacing, and it also measures noise,
        which a spline passes through."""
        w = np.atleast_1d(np.asarray(omega, dtype=float))
        x = self.frequency
        n = x.size
        if n < 5:
            return np.full((w.size,) + self.H.shape[1:], np.inf)
        j = np.clip(np.searchsorted(x, w) - 1, 0, n - 2)  # interval [x_j, x_j+1]
        h = x[j + 1] - x[j]
        # the fourth derivative (complex, per entry) at mid-interval: the mean of the fourth
        # divided differences of the five samples from x_j-2 and from x_j-1
        s0, s1 = np.clip(j - 2, 0, n - 5), np.clip(j - 1, 0, n - 5)
        d4 = 12.0 * (_newton(x, self.H, s0, 5)[4] + _newton(x, self.H, s1, 5)[4])
        slope = self._slope_errors
        t = np.linspace(0.0, 1.0, 17)[1:-1, None, None, None]
        hh = h[None, :, None, None]
        e = -(d4[None] / 24.0) * hh**4 * t**2 * (1 - t) ** 2 + hh * (
            t * (1 - t) ** 2 * slope[j][None] - t**2 * (1 - t) * slope[j + 1][None]
        )
        err = np.max(np.abs(e), axis=0)
        err[~self.in_band(w)] = np.nan
        return err

    @cached_property
    def _slope_errors(self) -> np.ndarray:
        """d_j = s'(x_j) - H'(x_j) at every sample, (n, n_out, n_in): the
        spline's slope less that of the polynomial through the seven samples
        around x_j (whose slope error, O(h^6), is below the spline's)."""
        x = self.frequency
        n, no, ni = self.H.shape
        ds = self._spline.derivative()(x)
        spline_slope = (ds[:, : no * ni] + 1j * ds[:, no * ni :]).reshape(n, no, ni)
        k = min(7, n)  # the polynomial through the k (7) samples around x_j
        s = np.clip(np.arange(n) - k // 2, 0, n - k)
        c = _newton(x, self.H, s, k)
        P = np.ones(n)
        dP = np.zeros(n)
        poly_slope = np.zeros_like(spline_slope)
        for i in range(k):  # d/dx of the Newton form sum_i c_i prod_{l<i} (x - x_l)
            poly_slope += c[i] * dP[:, None, None]
            xk = x[s + i]
            dP = dP * (x - xk) + P
            P = P * (x - xk)
        return spline_slope - poly_slope

    # ------------------------------------------------------------------ out

    def to_control(self) -> Any:
        """A ``control.FrequencyResponseData`` (omega in rad/s, m/N), with
        the coordinate names as signal labels (python-control refuses '.' in
        a label: ``tool.x`` becomes ``tool:x``, and :meth:`from_control`
        turns it back)."""
        import control

        return control.FrequencyResponseData(
            np.transpose(self.H, (1, 2, 0)),
            self.frequency,
            inputs=[x.replace(".", ":") for x in self.inputs],
            outputs=[x.replace(".", ":") for x in self.outputs],
        )

    def _table(self) -> Any:
        from ..io._frf_files import FRFTable

        return FRFTable(
            frequency_hz=self.frequency_hz,
            H=np.asarray(self.H),
            outputs=self.outputs,
            inputs=self.inputs,
            coherence=self.coherence,
            source=self.source,
        )

    def to_csv(self, path: str | os.PathLike[str], *, units: str = "m/N", form: str = "reim") -> None:
        """Write a CSV file (docs/measured-frf.md): frequency in Hz, then per
        pair ``OUT/IN re``, ``OUT/IN im`` (``form="magphase"``: ``mag``,
        ``phase`` in deg), in ``units`` (a receptance unit: m/N, mm/N, um/N),
        17 significant digits (exact round trip); written atomically."""
        from ..io._frf_files import write_frf_csv

        write_frf_csv(path, self._table(), units=units, form=form)

    def to_uff(self, path: str | os.PathLike[str], *, binary: bool = False) -> None:
        """Write UFF dataset 58 (58b with ``binary=True``), one dataset per
        (output, input) pair, receptance in SI (needs pyuff: ``pip install
        chatterlab[uff]``); written atomically."""
        from ..io._frf_files import write_frf_uff

        write_frf_uff(path, self._table(), binary=binary)

    def plot(
        self, axes: Any = None, *, form: Literal["magphase", "reim"] = "magphase", title: str | None = None
    ) -> Any:
        """Magnitude (log) and phase, or real and imaginary part, of every
        entry against frequency in Hz; returns the two Axes."""
        import matplotlib.pyplot as plt

        if axes is None:
            _, axes = plt.subplots(2, 1, sharex=True, figsize=(8, 6), gridspec_kw={"height_ratios": [2, 1]})
        a0, a1 = axes
        f = self.frequency_hz
        for o, on in enumerate(self.outputs):
            for i, inn in enumerate(self.inputs):
                z = self.H[:, o, i]
                lab = f"{on} / {inn}"
                if form == "magphase":
                    (ln,) = a0.semilogy(f, np.abs(z), label=lab)
                    a1.plot(f, np.degrees(np.angle(z)), color=ln.get_color())
                else:
                    (ln,) = a0.plot(f, z.real, label=lab)
                    a1.plot(f, z.imag, color=ln.get_color())
        if form == "magphase":
            a0.set_ylabel("|H|  [m/N]")
            a1.set_ylabel("phase [deg]")
            a1.set_yticks([-180, -90, 0, 90, 180])
        else:
            a0.set_ylabel("Re H  [m/N]")
            a1.set_ylabel("Im H  [m/N]")
        a1.set_xlabel("frequency [Hz]")
        for ax in axes:
            ax.grid(True, which="both", alpha=0.3)
        a0.legend(fontsize=8)
        a0.set_title(title or f"measured FRF: {self.source}")
        return axes


def _check_frequency(w: np.ndarray, source: str) -> None:
    if not np.all(np.isfinite(w)):
        raise InputError(f"{source}: frequencies must be finite")
    if np.any(w < 0):
        raise InputError(f"{source}: frequencies must be >= 0 (got {w.min() / (2 * np.pi):g} Hz)")
    d = np.diff(w)
    if np.any(d <= 0):
        k = int(np.nonzero(d <= 0)[0][0])
        what = "repeated" if d[k] == 0 else "decreasing"
        raise InputError(
            f"{source}: frequencies must increase strictly; {w[k + 1] / (2 * np.pi):g} Hz after"
            f" {w[k] / (2 * np.pi):g} Hz is {what} (point {k + 2}); sort the data and drop duplicates"
        )


def _newton(x: np.ndarray, H: np.ndarray, s: np.ndarray, k: int) -> list[np.ndarray]:
    """Newton divided differences H[x_s], H[x_s, x_s+1], ..., H[x_s .. x_s+k-1]
    of the k samples from index s (one start per entry of ``s``), each
    (len(s), n_out, n_in), complex."""
    idx = s[:, None] + np.arange(k)[None, :]
    xs = x[idx]
    dd = H[idx]
    out = [dd[:, 0]]
    for level in range(1, k):
        den = (xs[:, level:] - xs[:, : k - level])[:, :, None, None]
        dd = (dd[:, 1:] - dd[:, :-1]) / den
        out.append(dd[:, 0])
    return out
