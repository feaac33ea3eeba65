"""The one lobe result of chatterlab: :class:`LobeDiagram`, the limit
width against speed for every process and every method -- turning and
shaping by D-subdivision (:func:`chatterlab.lobes.lobes`), a measured FRF
(:func:`chatterlab.lobes.lobes_measured`), milling by Floquet multipliers or
the zeroth-order approximation (:func:`chatterlab.lobes.milling_lobes`) --
with its summary, claims, files and plot.  What the width and the speed are
called and in which unit the speed is given come from the diagram's process
(:attr:`LobeDiagram.process`, kept: the plot and the files never re-derive the
speed of a delay); the D-subdivision methods add one :class:`Lobe` per
integer k and branch, the Floquet methods the critical multiplier.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ..io import Result

__all__ = ["Lobe", "LobeDiagram", "ProcessNames", "count_failed"]

#: what a limit can rest on (:attr:`LobeDiagram.basis`), in the order of the files' codes
BASES = ("complete", "band", "measured", "undetermined", "scan", "zoa")


def count_failed(check: dict[str, Any]) -> bool:
    """True when a check's argument-principle count failed (its phase did not
    close: verdict ``undetermined``, or no count at all, ``rhp_roots < 0``):
    the check neither confirms nor contradicts the diagram."""
    return check["verdict"] == "undetermined" or int(check["rhp_roots"]) < 0


@dataclass(frozen=True, eq=False)
class Lobe:
    """One lobe: the boundary for one integer k (and one solution branch)."""

    k: int
    branch: int
    delay: np.ndarray  #: s
    speed: np.ndarray  #: in the process unit (m/s or rpm)
    width: np.ndarray  #: b_lim, m
    frequency_hz: np.ndarray  #: chatter frequency, Hz


class ProcessNames:
    """What a result calls its speed and its limit: its process's names (the
    one place they are written is the process: :class:`~chatterlab.model.Process`,
    :class:`~chatterlab.process.Milling`).  A result with a ``process``
    inherits them."""

    process: Any

    @property
    def speed_unit(self) -> str:
        """Unit of the speeds (the process's: ``"m/s"``, ``"rpm"``, ``"s"``)."""
        return str(self.process.speed_unit)

    @property
    def speed_name(self) -> str:
        """What the speed is (``"spindle speed"``, ``"work speed"``, ``"delay"``)."""
        return str(self.process.speed_name)

    @property
    def limit_name(self) -> str:
        """``"a_lim"`` for milling, ``"b_lim"`` otherwise."""
        return str(self.process.limit_name)

    @property
    def width_name(self) -> str:
        """``"axial depth of cut a_p"`` for milling, ``"width of cut b"`` otherwise."""
        return str(self.process.width_name)


@dataclass(frozen=True, eq=False)
class LobeDiagram(Result, ProcessNames):
    """The stability limit against speed: b_lim (or a_lim) for every process.

    Attributes
    ----------
    speed : ndarray, shape (n,)
        The requested speeds, in ``speed_unit`` (shaping: m/s; turning and
        milling: rpm; delay: s).
    delay : ndarray, shape (n,)
        The delay T (s) at each speed (milling: the tooth period).
    b_lim : ndarray, shape (n,)
        The limit width, m: the largest chatter-free width of cut b, or for
        milling the limit axial depth a_lim (:attr:`a_lim`); ``inf`` where no
        boundary lies below ``width_max`` (on the ``basis`` stated); where
        ``kind`` is ``"undetermined"``, the width up to which stability was
        established (a lower bound).
    chatter_hz : ndarray, shape (n,)
        Chatter frequency (Hz) at the limit.
    lobe : ndarray of int, shape (n,)
        The lobe number k forming the envelope (-1 where none or not known:
        the Floquet methods).
    kind : ndarray of str, shape (n,)
        How the loop loses stability at the limit: ``"hopf"`` (a complex
        pair of roots or multipliers), ``"flip"`` (a multiplier at -1, period
        doubling), ``"fold"`` (a real root at 0 or a multiplier at +1),
        ``"undetermined"``, or ``""`` where b_lim is inf.
    basis : ndarray of str, shape (n,)
        What each speed's verdict rests on: ``"complete"`` (the band or the
        depth search is proven complete), ``"band"`` (the D-subdivision band
        is not proven complete: an inf is only "none found"), ``"measured"``
        (a measured FRF: nothing is known outside its band), ``"undetermined"``
        (the Floquet search could not decide above ``certified``), ``"scan"``
        (the first crossing seen on a depth scan: helix or SDM) or ``"zoa"``
        (the zeroth-order approximation of milling).
    certified : ndarray, shape (n,)
        Width, m, up to which stability is established (nan where nothing is
        proven: ``"scan"``, ``"zoa"``, ``"band"`` with an inf).
    process : Process or Milling
        The process whose kinematics map speed to delay (``delay``,
        ``speed_for_delay``) and which names the width and the speed.
    method, resolution : str
        How the limit was computed (``"d-subdivision"``, ``"spectral"``,
        ``"sdm"``, ``"zoa"``) and its accuracy knob.
    lobes : tuple of Lobe
        Every lobe in the speed range (D-subdivision: curves sampled on the
        frequency grid; empty for the Floquet methods).
    minimum : dict
        The smallest limit over the speed range: ``width`` (m), ``speed``,
        ``chatter_hz``.
    absolute_minimum : dict
        The smallest boundary width over all delays (D-subdivision): ``width``
        (m), ``chatter_hz`` (the asymptote the lobes approach at low speed).
    checks : tuple of dict
        Argument-principle counts of right-half-plane roots just below and
        above the envelope and at the width ceiling where the diagram says
        ``inf`` (see ``verify``); ``verified`` says whether all agree.
    band_hz, band_certified, band_note, band_measured
        The chatter-frequency band searched (Hz, D-subdivision), whether the
        loop-gain bound proves that no boundary point below ``width_max`` lies
        outside it, why, and whether it is a measured FRF's band.
    multiplier, error : ndarray, shape (n,)
        Floquet methods: the critical multiplier at the limit (|mu| = 1 to
        the solver's tolerance) and the estimated error of the limit, m (nan
        where not estimated).
    scan_step : float
        Floquet methods: spacing of the depth scan, m (nan otherwise).
    folds, n_lobes, n_frequencies, evaluations
        Work done: folds of the boundary followed, lobes crossing the speed
        range (when denser than 400 per branch, ``lobes`` keeps only those that
        form the envelope), frequencies of the grid, monodromy evaluations.
    branches : tuple of ndarray, shape (m, 4) each
        The constant-gain D-subdivision boundary itself, from which every lobe
        at every speed follows: one array per continuous branch, rows
        (branch number, omega rad/s, phi = omega T mod 2 pi rad, width m) in
        order along the curve.  The geometry (:meth:`geometry`, the plot's
        curves and envelope between the requested speeds) is drawn from it;
        empty for the Floquet methods and process damping.
    """

    speed: np.ndarray
    delay: np.ndarray
    b_lim: np.ndarray
    chatter_hz: np.ndarray
    lobe: np.ndarray
    lobes: tuple[Lobe, ...]
    minimum: dict[str, float]
    absolute_minimum: dict[str, float]
    process: Any
    width_max: float
    terms: Literal["pdo", "o"]
    position: float | None
    model: str
    checks: tuple[dict[str, Any], ...] = ()
    elapsed: float = 0.0
    n_frequencies: int = 0
    meta: dict[str, Any] = field(default_factory=dict)
    band_hz: tuple[float, float] = (float("nan"), float("nan"))
    band_certified: bool = False
    band_note: str = ""
    folds: int = 0
    n_lobes: int = 0
    band_measured: bool = False
    method: str = "d-subdivision"
    resolution: str = ""
    kind: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=str))
    basis: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=str))
    certified: np.ndarray = field(default_factory=lambda: np.zeros(0))
    multiplier: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=complex))
    error: np.ndarray = field(default_factory=lambda: np.zeros(0))
    scan_step: float = float("nan")
    evaluations: int = 0
    branches: tuple[np.ndarray, ...] = ()

    def __post_init__(self) -> None:
        n = np.asarray(self.speed).size
        fin = np.isfinite(self.b_lim)
        if np.asarray(self.kind).size != n:
            # D-subdivision: a root crossing the imaginary axis; at 0 Hz a real root through s = 0
            zero = fin & (np.asarray(self.chatter_hz) == 0)
            object.__setattr__(self, "kind", np.where(zero, "fold", np.where(fin, "hopf", "")).astype(str))
        if np.asarray(self.basis).size != n:
            b = "measured" if self.band_measured else "complete" if self.band_certified else "band"
            object.__setattr__(self, "basis", np.full(n, b))
        if np.asarray(self.certified).size != n:
            cert = np.where(self.basis == "complete", np.where(fin, self.b_lim, self.width_max), np.nan)
            object.__setattr__(self, "certified", cert.astype(float))
        if np.asarray(self.multiplier).size != n:
            object.__setattr__(self, "multiplier", np.full(n, np.nan + 0j))
        if np.asarray(self.error).size != n:
            object.__setattr__(self, "error", np.full(n, np.nan))

    # ------------------------------------------------------------------ maps
    @property
    def a_lim(self) -> np.ndarray:
        """The limit axial depth of a milling diagram: :attr:`b_lim`."""
        return self.b_lim

    @property
    def floquet(self) -> bool:
        """The limits come from Floquet multipliers (a periodic process)."""
        return self.method in ("spectral", "sdm")

    def delay_of(self, speed: Any) -> np.ndarray:
        """The delay (s) at ``speed`` (process unit), by the process's kinematics."""
        v = np.asarray(speed, float)
        return v.copy() if self.process.kind == "delay" else np.asarray(self.process.delay(v), float)

    def speed_of(self, delay: Any) -> np.ndarray:
        """The speed (process unit) whose delay is ``delay`` (s); nan where
        no speed gives it (a shaper's delay below the return-stroke time)."""
        T = np.asarray(delay, float)
        if self.process.kind == "delay":
            return T.copy()
        with np.errstate(divide="ignore", invalid="ignore"):
            v = np.asarray(self.process.speed_for_delay(T), float)
        return np.where(np.isfinite(v) & (v > 0), v, np.nan)

    @cached_property
    def _geometry(self) -> Any:
        from ._curves import LobeGeometry

        return LobeGeometry.of(self)

    def geometry(self) -> Any:
        """The lobes as exact curves and their lower envelope at any speed
        (:class:`chatterlab.lobes._curves.LobeGeometry`): what the plot draws."""
        return self._geometry

    @property
    def verified(self) -> bool | None:
        """True if every check agreed with the diagram, None if none ran."""
        if not self.checks:
            return None
        return all(c["agrees"] for c in self.checks)

    # ------------------------------------------------------------------ summary
    def summary(self) -> str:
        """What the diagram says, in words (mm and the process's speed unit)."""
        return "\n".join(_floquet_lines(self) if self.method != "d-subdivision" else _boundary_lines(self))

    #: meaning of :attr:`claim` codes
    CLAIMS = (
        "boundary",
        "stable below width_max (band proven)",
        "undetermined (band not proven)",
        "contradicted by a check",
        "boundary in the measured band (outside it unknown)",
        "first crossing on the depth scan (a narrower band can be missed)",
        "zeroth-order approximation (flip lobes not modelled)",
        "undetermined (stable only up to the limit shown)",
    )

    @property
    def claim(self) -> np.ndarray:
        """What the diagram claims at each speed, as an index into
        :attr:`CLAIMS`: 0 a boundary at the limit, 1 no boundary below
        ``width_max`` in a proven band or complete search, 2 no boundary
        found in a band that is not proven complete, 3 a check at this speed
        disagrees, 4 a boundary within a measured band (a lower one at a
        chatter frequency outside the band is not excluded), 5 a milling
        limit or inf seen on a depth scan only, 6 the zeroth-order
        approximation's, 7 an undetermined Floquet search (stable up to the
        limit shown).  A check whose count failed (:func:`count_failed`)
        contradicts nothing: its speed keeps the diagram's claim, unverified,
        like a speed that was not checked."""
        fin = np.isfinite(self.b_lim)
        basis = np.asarray(self.basis).astype(str)
        code = np.where(fin, 0, 1)
        code = np.where(basis == "band", np.where(fin, 0, 2), code)
        code = np.where(basis == "measured", np.where(fin, 4, 2), code)
        code = np.where(basis == "scan", 5, code)
        code = np.where(basis == "zoa", 6, code)
        code = np.where(basis == "undetermined", 7, code)
        for c in self.checks:
            if not c["agrees"] and not count_failed(c):
                code[np.nonzero(self.speed == c["speed"])[0]] = 3
        return code

    # ------------------------------------------------------------------ files
    def columns(self) -> list[tuple[str, str, np.ndarray, str]]:
        """The diagram's per-speed data as ``(name, unit, values, what)``, in
        the order of the CSV and the netCDF variables (one naming scheme for
        every process and method; nan where a column does not apply)."""
        mu = np.asarray(self.multiplier, complex)
        n = mu.size
        code = {"": 0, "hopf": 1, "flip": 2, "fold": 3, "undetermined": 4}
        lim = self.limit_name
        return [
            ("delay", "s", np.asarray(self.delay, float), "delay between passes (milling: tooth period)"),
            (lim, "m", np.asarray(self.b_lim, float), f"limit {self.width_name}"),
            ("chatter_frequency", "Hz", np.asarray(self.chatter_hz, float), "chatter frequency at the limit"),
            ("kind", "1", np.array([code.get(str(k), -1) for k in self.kind], float),
             "lobe type: 0 none, 1 Hopf, 2 flip, 3 fold, 4 undetermined"),
            ("lobe", "1", np.asarray(self.lobe, dtype=np.int64), "lobe number k (-1: none or not known)"),
            ("claim", "1", self.claim.astype(float),
             "status: " + ", ".join(f"{i} {t}" for i, t in enumerate(self.CLAIMS))),
            ("basis", "1", np.array([BASES.index(str(b)) for b in self.basis], float),
             "what the limit rests on: " + ", ".join(f"{i} {t}" for i, t in enumerate(BASES))),
            ("certified", "m", np.asarray(self.certified, float), "width up to which stability is established"),
            ("multiplier_abs", "1", np.abs(mu), "|critical Floquet multiplier|"),
            ("multiplier_arg", "rad", np.angle(mu), "arg of the critical Floquet multiplier"),
            ("error", "m", np.asarray(self.error, float), "estimated error of the limit"),
            ("width_max", "m", np.full(n, float(self.width_max)), "the largest width searched"),
            ("scan_step", "m", np.full(n, float(self.scan_step)), "spacing of the depth scan (Floquet)"),
            ("band_low", "Hz", np.full(n, float(self.band_hz[0])), "lower end of the chatter band searched"),
            ("band_high", "Hz", np.full(n, float(self.band_hz[1])), "upper end of the chatter band searched"),
        ]  # fmt: skip

    def to_csv(self, path: Any) -> Path | None:
        """One row per speed, in the naming scheme of every chatterlab file
        (a column is named as the netCDF variable, ``name [unit]``; SI;
        every number the shortest decimal that reads back to the same
        double): ``speed`` in the process's unit, the numeric variables of
        :meth:`columns` (the limit named ``b_lim`` or ``a_lim``), the coded
        ones in words (``kind``: hopf, flip, fold, undetermined or none;
        ``claim``: the text of :attr:`CLAIMS`; ``basis``), and on every row
        what was searched (``width_max``, ``scan_step``, ``band_low``,
        ``band_high``: an ``inf`` means no boundary there, nothing more);
        written atomically.  Returns the path."""
        from ..io import write_csv

        coords, data, _ = self.dataset_parts()
        numeric = {k: v for k, v in data.items() if k not in ("kind", "claim", "basis")}
        kinds = ["none", "hopf", "flip", "fold", "undetermined"]
        kind_code = np.asarray(data["kind"][0], dtype=int)
        coded = {
            "kind": (kind_code, kinds),
            "claim": (self.claim.astype(int), list(self.CLAIMS)),
            "basis": (np.asarray(data["basis"][0], dtype=int), list(BASES)),
        }
        return write_csv(path, coords, numeric, coded=coded)

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """``(coords, data, attrs)``: the speed as coordinate, :meth:`columns`
        as data, the summary numbers and checks as attributes (the
        specifications of :func:`chatterlab.io.make_dataset`; the files and
        the dataset of :class:`chatterlab.io.Result` come from them)."""
        a = {
            "title": "chatterlab stability lobe diagram",
            "model": self.model,
            "process": str(self.process.kind),
            "method": self.method,
            "resolution": self.resolution,
            "terms": self.terms,
            "position_m": float("nan") if self.position is None else self.position,
            "width_max_m": self.width_max,
            "scan_step_m": self.scan_step,
            f"min_{self.limit_name}_m": self.minimum["width"],
            f"min_{self.limit_name}_speed": self.minimum["speed"],
            f"min_{self.limit_name}_chatter_hz": self.minimum["chatter_hz"],
            f"absolute_min_{self.limit_name}_m": self.absolute_minimum["width"],
            "absolute_min_chatter_hz": self.absolute_minimum["chatter_hz"],
            "verified": str(self.verified),
            "chatter_band_hz": list(self.band_hz),
            "chatter_band_certified": str(self.band_certified),
            "chatter_band_note": self.band_note,
            "chatter_band_measured": str(self.band_measured),
            "checks": json.dumps(list(self.checks)),
            "claim": _claim_text(self),
        }
        a.update({k: v for k, v in self.meta.items() if isinstance(v, (int, float, str))})
        return (
            {"speed": (self.speed, self.speed_unit, self.speed_name)},
            {name: (vals, unit, what) for name, unit, vals, what in self.columns()},
            a,
        )

    def plot(self, ax: Any = None, *, title: str | None = None, **style: Any) -> Any:
        """The lobe diagram (the limit in mm against speed, the unstable side
        shaded, what was searched stated; :func:`chatterlab.plot.plot_lobes`).
        Returns the Axes (a tuple of them for a D-subdivision diagram: the
        lobes and the chatter-frequency panel)."""
        from ..plot import plot_lobes

        return plot_lobes(self, ax=ax, title=title, **style)


# ---------------------------------------------------------------------------- summary lines
def _mm(x: float) -> str:
    return f"{x * 1e3:.6g} mm"


def _speed(d: LobeDiagram, v: float) -> str:
    return f"{v:.0f} {d.speed_unit}" if d.speed_unit == "rpm" else f"{v:.5g} {d.speed_unit}"


def _boundary_lines(d: LobeDiagram) -> list[str]:
    """The summary of a D-subdivision diagram."""
    m, a, lim = d.minimum, d.absolute_minimum, d.limit_name
    what = "milling lobes (zeroth-order approximation)" if d.method == "zoa" else "stability lobes"
    lines = [
        f"{what} of {d.model} ({d.terms} feedback"
        + (f", position {d.position:g} m" if d.position is not None else "")
        + ")",
        f"  speeds {_speed(d, d.speed.min())} .. {_speed(d, d.speed.max())} ({d.speed.size} points),"
        f" {d.n_lobes} lobes"
        + (
            f" ({len(d.lobes)} kept as curves: on each branch, the lobe numbers k of the envelope)"
            if d.n_lobes > len(d.lobes)
            else ""
        )
        + f", {d.n_frequencies} chatter frequencies, {d.elapsed:.2f} s",
    ]
    if np.isfinite(m["width"]):
        lines.append(
            f"  minimum {lim} in range: {m['width'] * 1e3:.4g} mm at {_speed(d, m['speed'])},"
            f" chatter {m['chatter_hz']:.2f} Hz"
            + (" (from the measured band; chatter outside it is unknown)" if d.band_measured else "")
        )
    elif d.band_certified:
        lines.append(f"  no chatter below {d.width_max * 1e3:g} mm in this speed range")
    else:
        lines.append(
            f"  no chatter found below {d.width_max * 1e3:g} mm in the band searched:"
            " stability outside it is undetermined"
        )
    lo, hi = d.band_hz
    lines.append(
        f"  chatter band searched {lo:.4g} .. {hi:.4g} Hz"
        + (" (complete: the loop gain is below 1 outside it)" if d.band_certified else f" ({d.band_note})")
    )
    if np.isfinite(a["width"]):
        lines.append(
            f"  absolute minimum (all speeds): {a['width'] * 1e3:.4g} mm at {a['chatter_hz']:.2f} Hz"
        )
    lines += _ceiling_lines(d)
    lines += _check_lines(d)
    if d.meta.get("mesh"):  # a model with beams: the discretisation error (lobes._mesh_error)
        lines.append(f"  {d.meta['mesh']}")
    return lines


def _ceiling_lines(d: LobeDiagram) -> list[str]:
    """How the width ceiling was set, and a word when most speeds end at it."""
    out = []
    if d.meta.get("ceiling"):
        out.append(f"  width ceiling {d.meta['ceiling']}")
    inf = ~np.isfinite(d.b_lim) & (np.asarray(d.kind).astype(str) != "undetermined")
    n = int(np.count_nonzero(inf))
    if n > 0.5 * d.speed.size:
        out.append(
            f"  most speeds ({n} of {d.speed.size}) end at the ceiling {d.width_max * 1e3:g} mm: raise it"
            " with --width-max (width_max= in Python) to see their limits"
        )
    return out


def _check_lines(d: LobeDiagram) -> list[str]:
    if not d.checks:
        return ["  not verified (verify=0 or a plant without matrices)"]
    ok = sum(c["agrees"] for c in d.checks)
    n_failed = sum(count_failed(c) for c in d.checks)
    what = {"below": "just below the envelope", "above": "just above it", "ceiling": "inf at the ceiling"}
    kinds = ", ".join(what[k] for k in ("below", "above", "ceiling") if any(c["kind"] == k for c in d.checks))
    lines = [
        f"  verified by the argument principle: {ok}/{len(d.checks)} checks agree ({kinds})"
        + (f"; {n_failed} could not count the roots" if n_failed else "")
    ]
    for c in d.checks:
        where = f"at {c['speed']:.6g} {d.speed_unit}, width {c['width'] * 1e3:.6g} mm"
        if count_failed(c):
            why = c.get("reason") or c.get("message")
            lines.append(
                f"  CHECK NOT COUNTED {where} (expected {c['expected']}): the argument-principle count"
                f" failed (its phase did not close{f': {why}' if why else ''}); nothing is verified there"
            )
        elif not c["agrees"]:
            lines.append(
                f"  CHECK FAILED {where}: expected {c['expected']}, the argument principle says"
                f" {c['verdict']} ({c['rhp_roots']} right-half-plane roots)"
            )
    return lines


def _floquet_lines(d: LobeDiagram) -> list[str]:
    """The summary of a Floquet (or zeroth-order) milling diagram."""
    if d.method == "zoa":
        return _boundary_lines(d)
    basis = np.asarray(d.basis).astype(str)
    und = basis == "undetermined"
    fin = np.isfinite(d.b_lim) & ~und
    complete = bool(np.all((basis == "complete") | und))
    lim = d.limit_name
    if complete:
        from ._milling_search import STEP_CAP

        searched = (
            f"(scan step {d.scan_step * 1e3:.3g} mm; complete: every flip/fold depth exact,"
            f" complex pairs tracked to first order in steps of at most {STEP_CAP:g} scan steps)"
        )
    else:
        searched = (
            f"(scan step {d.scan_step * 1e3:.3g} mm; first crossing seen on the scan: a narrower"
            " band between two stable scan depths can be missed)"
        )
    lines = [
        f"milling lobes ({d.method}, {d.resolution}) of {d.model}: {d.speed.size} speeds "
        f"{_speed(d, d.speed.min())} .. {_speed(d, d.speed.max())}, depths to {d.width_max * 1e3:g} mm {searched}"
    ]
    pd = d.meta.get("process_damping")
    if pd:
        lines.append(
            f"  process damping C_pd = {pd['C_pd']:.6g} N/m ({pd['model']}): the rubbing teeth's"
            " -a_p C_pd/V W(t) r' integrated at each speed's own V"
            + ("; the quasi-static modes' impulse at tooth entry/exit is not" if "split_note" in pd else "")
        )
    if np.any(fin):
        j = int(np.argmin(np.where(fin, d.b_lim, np.inf)))
        lines.append(
            f"  smallest {lim} {_mm(d.b_lim[j])} at {_speed(d, d.speed[j])} ({d.kind[j]},"
            f" {d.chatter_hz[j]:.1f} Hz)"
        )
        counts = {k: int(np.sum(d.kind == k)) for k in ("flip", "hopf", "fold")}
        lines.append(
            f"  flip lobes at {counts['flip']} speed{'s' if counts['flip'] != 1 else ''}, Hopf at {counts['hopf']}"
            + (f", fold at {counts['fold']}" if counts["fold"] else "")
        )
    inf = ~np.isfinite(d.b_lim) & ~und
    if np.any(inf):
        n = int(np.sum(inf))
        how = "complete search" if complete else "searched on the scan above"
        lines.append(
            f"  no instability found up to {d.width_max * 1e3:g} mm at {n} speed{'s' if n != 1 else ''} ({how})"
        )
    if np.any(und):
        j = int(np.argmin(np.where(und, d.b_lim, np.inf)))
        n = int(np.sum(und))
        lines.append(
            f"  undetermined at {n} speed{'s' if n != 1 else ''}: stable established only up to the {lim}"
            f" shown (a lower bound; {_mm(d.b_lim[j])} at {_speed(d, d.speed[j])})"
        )
    lines += _ceiling_lines(d)
    if d.meta.get("mesh"):  # a model with beams: the discretisation error (cli._milling)
        lines.append(f"  {d.meta['mesh']}")
    lines.append(f"  {d.evaluations} evaluations, {d.elapsed:.2f} s")
    return lines


def _claim_text(d: LobeDiagram) -> str:
    """What the limits and an inf rest on, for the dataset attributes."""
    basis = set(np.asarray(d.basis).astype(str))
    lim = d.limit_name
    if d.floquet and basis <= {"complete", "undetermined"}:
        return (
            f"{lim}: the first depth with a Floquet multiplier on the unit circle; flip/fold depths exact"
            " (real eigenvalues of the affine monodromy pencil), complex pairs tracked with their derivatives"
            " between scan depths to first order; inf: no multiplier reaches the unit circle up to width_max;"
            f" basis 'undetermined': stable established only up to {lim} (a lower bound)"
        )
    if d.floquet:
        return (
            f"{lim}: the first crossing of |mu| = 1 seen on the depth scan, refined; inf: none seen up to"
            " width_max (a band narrower than scan_step between two stable scan depths can be missed)"
        )
    if d.method == "zoa":
        return f"{lim}: the boundary of the time-averaged (zeroth-order) milling system; flip lobes are not modelled"
    if d.band_measured:
        return f"{lim}: the boundary within the measured band; outside it nothing is known"
    if d.band_certified:
        return f"{lim}: every boundary point below width_max is in the band searched (loop-gain bound); inf: none"
    return f"{lim}: the lowest boundary found in the band searched; inf: none found there (not proven)"
