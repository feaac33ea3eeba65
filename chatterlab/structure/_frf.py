"""The frequency response of a structure, modelled or measured: :class:`FRF`.

One container for every FRF chatterlab makes or reads: the open- or
closed-loop response a model gives (:func:`chatterlab.frequency.frf`), a
tap test read from a file (:meth:`FRF.read`: CSV/TXT, UFF 58/58b,
CutPro-style ``.frf``, netCDF), a python-control system evaluated at some
frequencies (:meth:`FRF.from_control`), a modal fit's synthesis and a
receptance coupling's result.  The lobe engine
(:func:`chatterlab.lobes.measured_plant`), the modal fit
(:func:`chatterlab.structure.fit_modes`) and receptance coupling
(:func:`chatterlab.structure.couple_tool`) take it.

Inside: angular frequency ``omega`` in rad/s, the values ``data`` shaped
``(n_out, n_in, n_freq)`` (python-control's order: ``data[o, i, k]`` is
output ``outputs[o]`` per unit input ``inputs[i]`` at ``omega[k]``), SI
(receptance m/N, mobility m/(N s), accelerance m/(N s^2); a rotation among
the coordinates: rad and N m as the model's).  Hz only in
:attr:`FRF.frequency_hz` and in files.  Code that needs one matrix per
frequency for batched linear algebra takes :attr:`FRF.matrices`
(n_freq, n_out, n_in).

Between the measured frequencies, :meth:`FRF.interpolate` uses a cubic
spline (not-a-knot) through the real and the imaginary part of every entry
separately, in w.  For data that are smooth on the scale of the spacing h,
the error of a cubic spline is at most (5/384) h^4 max|H''''| (Hall &
Meyer [1]; not-a-knot ends keep the order 4 with a larger constant in the
end intervals).  To leading order the error is the Hermite term, (1/384)
h^4 |H''''| at mid-interval, plus what the spline's slope errors add on an
uneven spacing; :meth:`FRF.interpolation_error` estimates that per interval
(H'''' from fourth divided differences, the slope errors against the
polynomial through seven samples).  Outside the measured band nothing is
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
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, ClassVar, Literal

import numpy as np

from ..errors import InputError
from ..io import Result
from ._frf_spline import BAND_TOL, check_frequency, slope_errors, spline, spline_error, spline_values

if TYPE_CHECKING:
    from ._system import FrozenSystem

__all__ = ["FRF"]

#: kind -> (power p of j w from a receptance, unit of the values)
_KINDS = {"receptance": (0, "m/N"), "mobility": (1, "m/(N s)"), "accelerance": (2, "m/(N s^2)")}
#: the closed-loop facts as files name them: file key -> field
_FACTS = {
    "closed_loop": "closed_loop",
    "terms": "terms",
    "method": "method",
    "position_m": "position",
    "width_m": "width",
    "delay_s": "delay",
}

Kind = Literal["receptance", "mobility", "accelerance"]


def _names(names: Any, n: int, what: str) -> tuple[str, ...]:
    if isinstance(names, str):
        names = (names,)
    out = tuple(str(x) for x in names)
    if len(out) != n:
        raise InputError(
            f"{what} must name {n} coordinate(s) to match the data (got {len(out)}: {list(out)})"
        )
    if len(set(out)) != len(out):
        raise InputError(f"{what} name a coordinate twice: {list(out)}")
    return out


def _unknown(name: str, known: tuple[str, ...], what: str) -> InputError:
    import difflib

    near = difflib.get_close_matches(name, known, n=1)
    hint = f" (did you mean {near[0]!r}?)" if near else ""
    return InputError(f"{what} {name!r} is not one of the FRF's {what}s{hint}: {', '.join(known)}")


def _pick(names: tuple[str, ...], key: int | str, what: str) -> int:
    """The index of an output or input given by index or by name."""
    if isinstance(key, str):
        if key not in names:
            raise InputError(f"{what} {key!r} is not one of the FRF's {what}s {list(names)}")
        return names.index(key)
    return int(key)


def _check_kind(kind: str) -> None:
    if kind not in _KINDS:
        raise InputError(f"kind must be one of {', '.join(_KINDS)} (got {kind!r})")


def _fact(key: str, text: Any) -> Any:
    """A closed-loop fact as a file gives it (text in CSV, typed in netCDF)."""
    if key == "closed_loop":
        return text if isinstance(text, bool) else str(text).strip().lower() in ("true", "1")
    if key in ("terms", "method"):
        return str(text)
    return None if text is None or str(text).strip().lower() in ("", "none", "null") else float(text)


@dataclass(frozen=True, eq=False)
class FRF(Result):
    """A frequency response: ``data[o, i, k]`` is output o per unit input i
    at ``omega[k]`` (module docstring).

    Attributes
    ----------
    omega : ndarray, shape (n_freq,)
        Angular frequency, rad/s.
    data : ndarray, shape (n_out, n_in, n_freq), complex
        Receptance (m/N), mobility (m/(N s)) or accelerance (m/(N s^2)),
        as ``kind`` says.
    outputs, inputs : tuple of str
        Coordinate names (``"tool.x"``; a UFF file's ``"NODE.x"``).
    kind : {"receptance", "mobility", "accelerance"}
    closed_loop, method, position, width, delay, terms
        What a computed FRF is: with the cutting process in the loop or
        not, how it was computed (``"direct"``, ``"modal"``, ``"lti"``;
        ``"measured"``, ``"modal fit"``, ``"rcsa"``...), the slide position
        (m), the width of cut (m), the delay (s) and the feedback's terms.
    meta : dict
        What a file said besides the data (its units and quantity ...).
    coherence : ndarray like ``data`` (real), optional
        Ordinary coherence (0..1) of each entry, when measured.
    source : str
        Where the data came from (a file name, ``"arrays"``, a model).
    """

    #: the kinds of response, by the power of j w that makes them of a receptance
    KINDS: ClassVar[tuple[str, ...]] = tuple(_KINDS)

    omega: np.ndarray
    data: np.ndarray
    outputs: tuple[str, ...]
    inputs: tuple[str, ...]
    kind: str = "receptance"
    closed_loop: bool = False
    method: str = "direct"
    position: float | None = None
    width: float | None = None
    delay: float | None = None
    terms: str = "none"
    meta: dict[str, Any] = field(default_factory=dict)
    coherence: np.ndarray | None = None
    source: str = ""

    def __post_init__(self) -> None:
        _check_kind(self.kind)
        shape = (len(self.outputs), len(self.inputs), np.shape(self.omega)[0])
        if np.shape(self.data) != shape:
            raise InputError(
                f"FRF data must have shape (n_out, n_in, n_freq) = {shape} (got {np.shape(self.data)})"
            )
        if self.coherence is not None and np.shape(self.coherence) != shape:
            raise InputError(
                f"FRF coherence must have the shape of data {shape} (got {np.shape(self.coherence)})"
            )

    # ------------------------------------------------------------------ construction

    @classmethod
    def from_arrays(
        cls,
        omega: Any,
        data: Any,
        outputs: Any = ("1",),
        inputs: Any = ("1",),
        *,
        hz: bool = False,
        kind: Kind = "receptance",
        coherence: Any = None,
        source: str = "arrays",
        method: str = "measured",
        meta: dict[str, Any] | None = None,
    ) -> FRF:
        """An FRF from arrays, checked (a measurement, or any response given
        as numbers).

        Parameters
        ----------
        omega : array, shape (n_freq,)
            rad/s (Hz with ``hz=True``); strictly increasing, finite, >= 0,
            at least 2 values.
        data : array, shape (n_out, n_in, n_freq) or (n_freq,)
            The response (a 1-D array is one output and one input), SI of
            ``kind``.
        outputs, inputs : sequence of str
            Coordinate names.
        coherence : array like ``data``, optional
            Values in [0, 1].
        """
        w = np.array(omega, dtype=float)
        if w.ndim != 1 or w.size < 2:
            raise InputError(
                f"{source}: frequency must be a 1-D array of at least 2 values (got shape {w.shape})"
            )
        if hz:
            w = 2 * np.pi * w
        _check_kind(kind)
        Hc = np.array(data, dtype=complex, order="C")
        if Hc.ndim == 1:
            Hc = Hc[None, None, :]
        if Hc.ndim != 3 or Hc.shape[2] != w.size:
            hint = (
                "; it looks like (n_freq, n_out, n_in): np.moveaxis(data, 0, -1) gives the FRF's order"
                if Hc.ndim == 3 and Hc.shape[0] == w.size
                else ""
            )
            raise InputError(
                f"{source}: data must have shape (n_out, n_in, n_freq) with n_freq = {w.size}"
                f" (got {Hc.shape}){hint}"
            )
        check_frequency(w, source)
        bad = ~np.isfinite(Hc)
        if np.any(bad):
            o, i, k = (int(x[0]) for x in np.nonzero(bad))
            raise InputError(
                f"{source}: the data are not finite at {w[k] / (2 * np.pi):g} Hz (entry {o}, {i});"
                " drop or repair that point"
            )
        outs = _names(outputs, Hc.shape[0], f"{source}: outputs")
        ins = _names(inputs, Hc.shape[1], f"{source}: inputs")
        coh = None
        if coherence is not None:
            coh = np.array(coherence, dtype=float, order="C")
            if coh.ndim == 1:
                coh = coh[None, None, :]
            if coh.shape != Hc.shape:
                raise InputError(
                    f"{source}: coherence must have the shape of data {Hc.shape} (got {coh.shape})"
                )
            if not np.all(np.isfinite(coh) & (coh >= 0) & (coh <= 1 + 1e-9)):
                raise InputError(f"{source}: coherence must lie in [0, 1]")
            coh.setflags(write=False)
        w.setflags(write=False)
        Hc.setflags(write=False)
        return cls(w, Hc, outs, ins, kind, method=method, meta=dict(meta or {}), coherence=coh, source=source)

    @classmethod
    def read(
        cls,
        path: str | os.PathLike[str],
        units: str | None = None,
        quantity: str | None = None,
        *,
        point: str | None = None,
        format: str | None = None,
        kind: Kind | None = "receptance",
    ) -> FRF:
        """Read an FRF file; the format from the suffix (``.csv``, ``.txt``:
        columns; ``.frf``: CutPro-style; ``.uff``, ``.unv``: UFF dataset
        58/58b; ``.nc``: netCDF as :meth:`to_netcdf` writes) or ``format``
        (``"csv"``, ``"frf"``, ``"uff"``, ``"netcdf"``).

        ``units`` (``"mm/N"``, ``"m/s/N"``, ``"g/N"``...) and ``quantity``
        (``"receptance"``, ``"mobility"``, ``"accelerance"``) override what
        the file says.  The values are converted to ``kind`` (default
        receptance in m/N; None keeps the file's quantity, in SI).
        ``point`` names the point of two-letter columns (``xy`` ->
        ``POINT.x`` / ``POINT.y``).  What a chatterlab file says of a
        closed loop (``closed_loop``, ``width_m`` ...) is read back into the
        fields.  See docs/measured-frf.md for the formats."""
        from ..io._frf_files import read_frf

        rec = read_frf(path, units=units, quantity=quantity, point=point, format=format)
        return cls.from_record(rec, kind=kind)

    @classmethod
    def from_record(cls, record: Any, *, source: str | None = None, kind: Kind | None = "receptance") -> FRF:
        """From what :func:`chatterlab.io.read_frf` returns (frequencies in
        Hz or rad/s, the values in SI of the file's quantity, coordinate
        names, coherence, what the file says), converted to ``kind`` (None:
        the file's quantity)."""
        meta = dict(record.meta)
        facts = {field_: _fact(key, meta.pop(key)) for key, field_ in _FACTS.items() if key in meta}
        exact = getattr(record, "omega", None)
        out = cls.from_arrays(
            record.frequency_hz if exact is None else exact,
            record.data,
            record.outputs,
            record.inputs,
            hz=exact is None,
            kind=record.quantity,
            coherence=record.coherence,
            source=source or record.source,
            method=str(facts.pop("method", "measured")),
            meta=meta,
        )
        out = replace(out, **facts) if facts else out
        return out if kind is None else out.as_kind(kind)

    @classmethod
    def from_control(
        cls,
        sys: Any,
        omega: Any = None,
        *,
        kind: Kind = "receptance",
        source: str | None = None,
    ) -> FRF:
        """The response of a python-control system at ``omega`` (rad/s): any
        LTI system (``StateSpace``, ``TransferFunction``) evaluated at
        j omega, or a ``FrequencyResponseData`` (its own frequencies when
        ``omega`` is None: exact, its data as stored).  The values are taken
        as ``kind`` in SI; the coordinate names are the system's signal
        labels (``:`` read as ``.``, see :meth:`to_control`).  The one way
        from python-control into chatterlab."""
        import control

        if not isinstance(sys, control.LTI):
            raise InputError(
                f"expected a python-control system (StateSpace, TransferFunction or FrequencyResponseData),"
                f" got {type(sys).__name__}"
            )
        frd = isinstance(sys, control.FrequencyResponseData)
        what = "FrequencyResponseData" if frd else type(sys).__name__
        outs = tuple(x.replace(":", ".") for x in sys.output_labels)
        ins = tuple(x.replace(":", ".") for x in sys.input_labels)
        src = source or f"python-control {what}"
        if omega is None:
            if not frd:
                raise InputError("from_control: give the frequencies omega (rad/s) to evaluate the system at")
            resp = getattr(sys, "frdata", None) if hasattr(sys, "frdata") else sys.fresp
            return cls.from_arrays(
                np.asarray(sys.omega, dtype=float),
                resp,
                outs,
                ins,
                kind=kind,
                source=src,
                method="python-control",
            )
        # any frequencies (a lobe engine's grid: unsorted, repeated, one): checked finite only
        w = np.atleast_1d(np.asarray(omega, dtype=float))
        if w.ndim != 1 or not np.all(np.isfinite(w)):
            raise InputError("from_control: omega must be a 1-D array of finite frequencies (rad/s)")
        resp = sys.eval(w, squeeze=False) if frd else sys(1j * w, squeeze=False)
        data = np.asarray(resp, dtype=complex).reshape(sys.noutputs, sys.ninputs, w.size)
        return cls(w, data, outs, ins, kind, method="python-control", source=src)

    @classmethod
    def from_model(
        cls,
        frozen: FrozenSystem,
        outputs: Any,
        inputs: Any | None = None,
        omega: Any = None,
    ) -> FRF:
        """A model's open-loop receptance at the frequencies ``omega``
        (rad/s), as if measured: the exact pole-residue sum over all complex
        modes (:func:`chatterlab.structure.modal_response`).  ``inputs``
        defaults to ``outputs`` (a driving-point matrix).  The oracle of the
        measured-FRF tests."""
        from ._complex import modal_response

        outs = [outputs] if isinstance(outputs, str) else list(outputs)
        ins = outs if inputs is None else ([inputs] if isinstance(inputs, str) else list(inputs))
        if omega is None:
            raise InputError("from_model needs the frequencies omega (rad/s)")
        w = np.asarray(omega, dtype=float)
        check_frequency(w, "from_model")
        rows = np.array([frozen.dof(s) for s in outs])
        cols = np.array([frozen.dof(s) for s in ins]).T
        cm = frozen.complex_modes
        G = modal_response(cm, rows, cols, 1j * w, np.arange(cm.lam.size), False)
        return cls.from_arrays(
            w, G, outs, ins, source=f"model {frozen.model.source}", method="modal", meta={"model": True}
        )

    # ------------------------------------------------------------------ views

    @property
    def frequency_hz(self) -> np.ndarray:
        """The frequencies, Hz."""
        return self.omega / (2 * np.pi)

    @cached_property
    def matrices(self) -> np.ndarray:
        """The data as one (n_out, n_in) matrix per frequency, shape
        (n_freq, n_out, n_in) (C-contiguous, read-only): the layout of
        batched linear algebra (``np.linalg.solve``, ``@``) and of the
        spline.  The same numbers as ``data``."""
        m = np.ascontiguousarray(np.moveaxis(np.asarray(self.data), -1, 0))
        m.setflags(write=False)
        return m

    @property
    def band(self) -> tuple[float, float]:
        """(lo, hi), rad/s: the first and the last frequency."""
        return float(self.omega[0]), float(self.omega[-1])

    @property
    def band_hz(self) -> tuple[float, float]:
        lo, hi = self.band
        return lo / (2 * np.pi), hi / (2 * np.pi)

    @property
    def unit(self) -> str:
        """Unit of ``data``: m/N (and /s, /s^2) for translations; with a
        rotation (``.rz``) among the inputs or outputs the entries mix m, rad,
        N and N m, and the label says so."""
        if any(x.endswith(".rz") for x in self.outputs + self.inputs):
            p = _KINDS[self.kind][0]
            return "(m or rad)/(N or N m)" + ("" if p == 0 else "/s" if p == 1 else "/s^2")
        return _KINDS[self.kind][1]

    @property
    def label(self) -> str:
        """``"open loop"``, ``"closed loop P+D"``... (a plot's legend)."""
        if not self.closed_loop:
            return "open loop"
        return {"pd": "closed loop P+D", "pdo": "closed loop P+D+delay", "o": "closed loop delay"}.get(
            self.terms, "closed loop"
        )

    def __getitem__(self, key: tuple[str, str]) -> np.ndarray:
        """``frf["tool.x", "tool.x"]`` -> (n_freq,) complex (output, input)."""
        o, i = key
        return self.data[self._out(o), self._in(i)]

    def _out(self, name: str) -> int:
        if name not in self.outputs:
            raise _unknown(name, self.outputs, "output")
        return self.outputs.index(name)

    def _in(self, name: str) -> int:
        if name not in self.inputs:
            raise _unknown(name, self.inputs, "input")
        return self.inputs.index(name)

    def select(self, outputs: Any = None, inputs: Any = None) -> FRF:
        """The sub-matrix between the named outputs and inputs (in that
        order; None keeps all)."""
        outs = (
            self.outputs if outputs is None else ((outputs,) if isinstance(outputs, str) else tuple(outputs))
        )
        ins = self.inputs if inputs is None else ((inputs,) if isinstance(inputs, str) else tuple(inputs))
        io = [self._out(o) for o in outs]
        ii = [self._in(i) for i in ins]
        sel = np.ix_(io, ii)
        coh = None if self.coherence is None else self.coherence[sel]
        return replace(self, data=self.data[sel], outputs=outs, inputs=ins, coherence=coh)

    def renamed(self, outputs: Any = None, inputs: Any = None) -> FRF:
        """The same data under other coordinate names."""
        outs = self.outputs if outputs is None else _names(outputs, len(self.outputs), "outputs")
        ins = self.inputs if inputs is None else _names(inputs, len(self.inputs), "inputs")
        return replace(self, outputs=outs, inputs=ins)

    def as_kind(self, kind: Kind) -> FRF:
        """Convert between receptance, mobility and accelerance: the values
        times (j w)^p (Ewins [2]); to a lower one at 0 Hz is refused."""
        _check_kind(kind)
        p = _KINDS[kind][0] - _KINDS[self.kind][0]
        if p == 0:
            return self
        if p > 0:
            return replace(self, data=self.data * (1j * self.omega) ** p, kind=kind)
        if np.any(self.omega == 0):
            raise InputError(
                f"{self.source or 'FRF'}: a {self.kind} at 0 Hz cannot be converted to {kind}; drop that point"
            )
        return replace(self, data=self.data / (1j * self.omega) ** (-p), kind=kind)

    def peaks(self, output: int | str = 0, input: int | str = 0, n: int = 3) -> list[tuple[float, float]]:
        """The n largest local maxima of |data| as (frequency Hz, magnitude);
        ``output`` and ``input`` by index or by name (``"rfe5.x"``), as in :meth:`plot`."""
        mag = np.abs(self.data[_pick(self.outputs, output, "output"), _pick(self.inputs, input, "input")])
        k = np.nonzero((mag[1:-1] > mag[:-2]) & (mag[1:-1] >= mag[2:]))[0] + 1
        k = k[np.argsort(-mag[k])][:n]
        out = []
        for j in sorted(k, key=lambda j: -mag[j]):
            # parabolic refinement of the peak on the sampled grid
            y0, y1, y2 = np.log(mag[j - 1 : j + 2])
            den = y0 - 2 * y1 + y2
            dx = 0.5 * (y0 - y2) / den if den != 0 else 0.0
            f = self.frequency_hz[j] + dx * (self.frequency_hz[j + 1] - self.frequency_hz[j])
            out.append((float(f), float(np.exp(y1 - 0.25 * (y0 - y2) * dx))))
        return out

    # ------------------------------------------------------------------ interpolation

    def in_band(self, omega: Any) -> np.ndarray:
        """Boolean mask of the frequencies (rad/s) inside the band."""
        w = np.asarray(omega, dtype=float)
        lo, hi = self.band
        tol = BAND_TOL * hi
        return (w >= lo - tol) & (w <= hi + tol)

    @cached_property
    def _spline(self) -> Any:
        """The cubic splines of Re and Im of every entry, built once."""
        check_frequency(np.asarray(self.omega), self.source or "FRF")
        return spline(self.omega, self.matrices)

    def interpolate(self, omega: Any, *, outside: Literal["raise", "nan"] = "raise") -> np.ndarray:
        """The values at the angular frequencies ``omega`` (rad/s), shape
        (n_out, n_in, n).

        A cubic spline (not-a-knot) through the real and the imaginary part
        of each entry in w; at the sampled frequencies it returns the data
        exactly.  Error: see :meth:`interpolation_error`.  Outside the band
        ``outside="raise"`` raises :class:`InputError`, ``"nan"`` returns
        NaN there; nothing is extrapolated."""
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
        out = spline_values(self._spline, np.asarray(self.omega), self.matrices, w, inside)
        return np.moveaxis(out, 0, -1)

    def interpolation_error(self, omega: Any) -> np.ndarray:
        """Estimated error of :meth:`interpolate` at ``omega`` (rad/s), per
        entry, shape (n_out, n_in, n), in the unit of ``data``: the largest
        leading-order error of the spline over the interval [x_j, x_j+1]
        that holds each w.

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
        x = np.asarray(self.omega)
        if x.size < 5:
            return np.full(self.data.shape[:2] + (w.size,), np.inf)
        err = spline_error(x, self.matrices, self._slope_errors, w, self.in_band(w))
        return np.moveaxis(err, 0, -1)

    @cached_property
    def _slope_errors(self) -> np.ndarray:
        """The spline's slope errors at the samples (``_frf_spline.slope_errors``)."""
        return slope_errors(self._spline, np.asarray(self.omega), self.matrices)

    # ------------------------------------------------------------------ out

    def to_control(self) -> Any:
        """A ``control.FrequencyResponseData`` (omega in rad/s, the data in
        SI), with the coordinate names as signal labels (python-control
        refuses '.' in a label: ``tool.x`` becomes ``tool:x``, and
        :meth:`from_control` turns it back).  The one way from chatterlab
        to python-control."""
        import control

        return control.FrequencyResponseData(
            np.asarray(self.data),
            np.asarray(self.omega),
            inputs=[x.replace(".", ":") for x in self.inputs],
            outputs=[x.replace(".", ":") for x in self.outputs],
        )

    def _record(self) -> Any:
        """The FRF as io's plain arrays (for its writers)."""
        from ..io._frf_table import FRFRecord

        facts: dict[str, Any] = {}
        if self.closed_loop or self.method not in ("measured",):
            facts = {key: getattr(self, f) for key, f in _FACTS.items()}
        return FRFRecord(
            frequency_hz=self.frequency_hz,
            data=np.asarray(self.data),
            outputs=self.outputs,
            inputs=self.inputs,
            quantity=self.kind,
            coherence=self.coherence,
            source=self.source,
            meta=facts,
            omega=np.asarray(self.omega),
        )

    def to_dict(self) -> dict[str, Any]:
        """The JSON form of ``chatterlab frf --format json``."""
        from .._version import __version__

        out = {
            "chatterlab": __version__,
            "kind": "frf",
            "quantity": self.kind,
            "unit": self.unit,
            "closed_loop": self.closed_loop,
            "terms": self.terms,
            "method": self.method,
            "position_m": self.position,
            "width_m": self.width,
            "delay_s": self.delay,
            "outputs": list(self.outputs),
            "inputs": list(self.inputs),
            "frequency_hz": self.frequency_hz.tolist(),
            "real": self.data.real.tolist(),
            "imag": self.data.imag.tolist(),
        }
        if self.coherence is not None:
            out["coherence"] = np.asarray(self.coherence).tolist()
        if self.source:
            out["source"] = self.source
        if self.meta:
            out["meta"] = self.meta
        return out

    def to_json(self, path: Any = None, *, indent: int | None = None) -> str:
        """Strict JSON of :meth:`to_dict` (every float exact, non-finite
        numbers as null; compact by default: an FRF is long), returned, and
        written to ``path`` (atomically) when one is given."""
        return super().to_json(path, indent=indent)

    def to_csv(
        self,
        path: str | os.PathLike[str] | IO[str],
        *,
        units: str | None = None,
        form: Literal["reim", "magphase", "both"] = "reim",
        comments: bool = True,
    ) -> Path | None:
        """Write a CSV file that :meth:`read` reads back
        (:func:`chatterlab.io.write_frf_csv`, docs/measured-frf.md):
        ``# units``, ``# quantity``, ``# source`` and the closed-loop facts
        as comment lines (``comments=False``: none), then frequency in Hz
        and per (output, input) pair ``re``/``im`` (``form="magphase"``:
        magnitude and phase in deg; ``"both"``: all four) in ``units`` (a
        unit of the FRF's kind: m/N, mm/N, um/N for a receptance; default
        SI), 17 significant digits (re/im: an exact round trip).  Written
        atomically; returns the path (None for a text stream)."""
        from ..io._frf_csv import write_frf_csv

        return write_frf_csv(path, self._record(), units=units, form=form, comments=comments)

    def to_uff(self, path: str | os.PathLike[str], *, binary: bool = False) -> Path:
        """Write UFF dataset 58 (58b with ``binary=True``: exact), one
        dataset per (output, input) pair, SI (needs pyuff: ``pip install
        chatterlab[uff]``); written atomically; returns the path."""
        from ..io._frf_uff import write_frf_uff

        return write_frf_uff(path, self._record(), binary=binary)

    def to_xarray(self) -> Any:
        """The FRF as an :class:`xarray.Dataset`: dimensions ``output``,
        ``input`` and ``frequency`` (Hz) labelled with the coordinate names,
        ``omega`` (rad/s) on ``frequency``, ``real`` and ``imag`` (SI of the
        kind), ``coherence`` when known; the kind, units, source and the
        closed-loop facts as attributes (:func:`chatterlab.io.frf_parts`)."""
        from ..io import frf_parts, make_dataset

        ds = make_dataset(*frf_parts(self._record()))
        ds = ds.assign_coords(output=list(self.outputs), input=list(self.inputs))
        for d in ("output", "input"):
            ds[d].attrs.update(units="", long_name=f"{d} coordinate (POINT.DIR)")
        return ds

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """``(coords, data, attrs)`` of the FRF dataset (:func:`chatterlab.io.frf_parts`):
        what :meth:`to_netcdf` writes (the values as doubles, omega exactly:
        :meth:`read` gives the same FRF back)."""
        from ..io import frf_parts

        return frf_parts(self._record())

    def plot(
        self,
        ax: Any = None,
        *,
        output: int | str | None = None,
        input: int | str | None = None,
        **style: Any,
    ) -> Any:
        """Magnitude (log) and phase against frequency in Hz
        (:func:`chatterlab.plot.plot_frf`; ``part="reim"``: real and
        imaginary part; ``peaks``, ``title`` ...): the entry ``output`` /
        ``input`` (index or name), or every entry when neither is given.
        ``ax`` is a pair of Axes.  Returns the pair.  Imports matplotlib."""
        from ..plot import plot_frf

        if output is None and input is None and len(self.outputs) * len(self.inputs) > 1:
            return plot_frf([self], output=None, input=None, ax=ax, **style)
        return plot_frf([self], output=output or 0, input=input or 0, ax=ax, **style)
