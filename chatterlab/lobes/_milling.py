"""Milling stability lobes: the limit depth a_lim against spindle speed.

Three methods return the same :class:`MillingLobes`:

* ``"spectral"`` (the reference), without helix: a_lim is the first depth
  in (0, ``depth_max``] at which a Floquet multiplier
  (:mod:`chatterlab.frequency._floquet`) reaches the unit circle, by a
  complete search (:func:`chatterlab.lobes._milling_search.certified_crossing`):
  every depth with a multiplier at -1 (flip) or +1 (fold) exactly, as the
  real eigenvalues of a matrix built from the affine monodromy pencil (no
  sampling), and the complex pairs (secondary Hopf) tracked with their
  exact derivatives d mu / d a_p between ``scan`` depths, bisected wherever
  a multiplier comes within its own rate of change of the unit circle.  No
  band of instability can hide between samples unless a complex multiplier
  moves more than its first-order rate predicts; where the search cannot
  decide, the speed is ``"undetermined"`` (``basis``) and a_lim is the depth
  up to which stability was established (a lower bound), never more.
* ``"spectral"`` with helix and ``"sdm"`` (first-order
  semi-discretisation): the spectral radius rho(a_p) is scanned on ``scan``
  depths up to ``depth_max``; the first scan interval where it reaches 1 is
  refined by Brent's method to ``rtol``.  A band of instability narrower
  than the scan step lying between two stable scan depths can be missed
  (``basis`` ``"scan"``).

  The multiplier at the limit gives the type of the lobe: secondary Hopf
  (complex pair), flip (mu = -1, period doubling) or fold (mu = +1).
* ``"zoa"`` (Altintas & Budak 1995): the time-averaged directional matrix H0
  handed to the D-subdivision lobe engine (:func:`chatterlab.lobes.lobes`)
  as a turning-like process with delay tau = 60/(N n).  Exact for the
  averaged system; it cannot see flip lobes and is poor at low radial
  immersion, where the coefficients are far from their mean.

The spectral method also checks its own convergence at each limit: the
spectral radius at a_lim recomputed with the degree raised by
``CHECK_DEGREE`` gives, through the slope d rho / d a, the change of a_lim
(``error``, m).  Its mesh resolves the structure's frequencies; where the
check finds a_lim less accurate than max(10 rtol, 1e-7) relative (a limit so
deep that the cut stiffens the structure), the speed is redone on a mesh
twice as fine, up to three times (``meta["refined"]`` counts them).

References
----------
Y. Altintas, E. Budak, Analytical prediction of stability lobes in milling,
CIRP Annals 44 (1995) 357-362.
T. Insperger, G. Stepan, Updated semi-discretization method for periodic
delay-differential equations with discrete delay, Int. J. Numer. Meth.
Engng 61 (2004) 117-141.
D. Lehotzky, T. Insperger, G. Stepan, Extension of the spectral element
method ..., Commun. Nonlinear Sci. Numer. Simul. 35 (2016) 177-189.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from ..errors import InputError, check_count, check_positive, check_speed
from ..frequency import (
    DEGREE,
    PoleResidue,
    ToolStructure,
    classify,
)
from ..frequency._delay_system import single_threaded
from ..model import Process
from ..process import Milling
from ._diagram import Plant, lobes
from ._milling_search import floquet_limit

__all__ = ["MillingLobes", "milling_lobes", "zoa_plant"]

METHODS = ("spectral", "sdm", "zoa")


@dataclass(frozen=True, eq=False)
class MillingLobes:
    """Result of :func:`milling_lobes`.

    Attributes
    ----------
    rpm : ndarray (n,)
        Spindle speeds, rpm.
    a_lim : ndarray (n,)
        Limit axial depth of cut, m; ``inf`` where stable up to
        ``depth_max`` (on the ``basis`` stated); where undetermined, the
        depth up to which stability was established.
    kind : ndarray of str (n,)
        ``"hopf"`` (secondary Hopf), ``"flip"`` (period doubling), ``"fold"``,
        ``"undetermined"`` (see ``basis``), or ``""`` where a_lim is inf.
    frequency_hz : ndarray (n,)
        Chatter frequency at the limit, Hz: the dominant harmonic of the
        critical Floquet solution (spectral), the member of the family
        |arg mu + 2 pi k| / T nearest a structural pole (SDM), the
        D-subdivision's (ZOA).
    multiplier : ndarray of complex (n,)
        The critical multiplier at the limit (|mu| = 1 to the solver's
        tolerance; nan for ZOA).
    error : ndarray (n,)
        Estimated error of a_lim, m (spectral: from the convergence check;
        nan where not estimated).
    method, resolution : str
        The method and its accuracy knob ("degree 16, omega L <= 5",
        "40 steps per period", ...).
    depth_max : float
        Largest depth searched, m.
    scan_step : float
        Spacing of the depth scan, m (with basis ``"scan"``, instability
        bands narrower than this between two stable scan points can be
        missed; with ``"complete"`` the scan only seeds the tracking).
    basis : ndarray of str (n,)
        What each speed's verdict rests on: ``"complete"`` (every flip/fold
        depth exact, complex pairs tracked to first order: see the module
        docstring), ``"undetermined"`` (the search could not decide above
        ``certified``; a_lim is then ``certified``, kind ``"undetermined"``),
        ``"scan"`` (first crossing seen on the scan: helix or SDM) or
        ``"zoa"``.
    certified : ndarray (n,)
        Depth, m, up to which the search established stability (nan for
        ``"scan"`` and ``"zoa"``): the limit itself, or depth_max for inf.
    """

    rpm: np.ndarray
    a_lim: np.ndarray
    kind: np.ndarray
    frequency_hz: np.ndarray
    multiplier: np.ndarray
    error: np.ndarray
    method: str
    resolution: str
    depth_max: float
    scan_step: float
    name: str = ""
    elapsed: float = 0.0
    evaluations: int = 0
    meta: dict[str, Any] = field(default_factory=dict)
    basis: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=str))
    certified: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        n = np.asarray(self.rpm).size
        if np.asarray(self.basis).size != n:
            object.__setattr__(self, "basis", np.full(n, "zoa" if self.method == "zoa" else "scan"))
        if np.asarray(self.certified).size != n:
            object.__setattr__(self, "certified", np.full(n, np.nan))

    def summary(self) -> str:
        basis = np.asarray(self.basis).astype(str)
        und = basis == "undetermined"
        fin = np.isfinite(self.a_lim) & ~und
        zoa = self.method == "zoa" or not np.isfinite(self.scan_step)
        complete = bool(np.all((basis == "complete") | und))
        if zoa:
            searched = (
                "(zeroth-order approximation: D-subdivision, no depth scan; flip lobes are not modelled)"
            )
        elif complete:
            searched = (
                f"(scan step {self.scan_step * 1e3:.3g} mm; complete: every flip/fold depth exact,"
                " complex pairs tracked between the scan depths to first order)"
            )
        else:
            searched = (
                f"(scan step {self.scan_step * 1e3:.3g} mm; first crossing seen on the scan: a narrower"
                " band between two stable scan depths can be missed)"
            )
        lines = [
            f"milling lobes ({self.method}, {self.resolution}) of {self.name}: {self.rpm.size} speeds "
            f"{self.rpm.min():g}-{self.rpm.max():g} rpm, depths to {self.depth_max * 1e3:g} mm {searched}"
        ]
        if np.any(fin):
            j = int(np.argmin(np.where(fin, self.a_lim, np.inf)))
            lines.append(
                f"  smallest a_lim {self.a_lim[j] * 1e3:.6g} mm at {self.rpm[j]:g} rpm ({self.kind[j]},"
                f" {self.frequency_hz[j]:.1f} Hz)"
            )
            lines.append(
                f"  flip lobes at {int(np.sum(self.kind == 'flip'))} speeds, Hopf at {int(np.sum(self.kind == 'hopf'))}"
                + (f", fold at {int(np.sum(self.kind == 'fold'))}" if np.any(self.kind == "fold") else "")
            )
        inf = ~np.isfinite(self.a_lim) & ~und
        if np.any(inf):
            n = int(np.sum(inf))
            how = (
                "by the approximation above"
                if zoa
                else "complete search"
                if complete
                else "searched on the scan above"
            )
            lines.append(
                f"  no instability found up to {self.depth_max * 1e3:g} mm at {n} speed{'s' if n != 1 else ''} ({how})"
            )
        if np.any(und):
            j = int(np.argmin(np.where(und, self.a_lim, np.inf)))
            n = int(np.sum(und))
            lines.append(
                f"  undetermined at {n} speed{'s' if n != 1 else ''}: stable established only up to the a_lim shown"
                f" (a lower bound; {self.a_lim[j] * 1e3:.6g} mm at {self.rpm[j]:g} rpm)"
            )
        lines.append(f"  {self.evaluations} evaluations, {self.elapsed:.2f} s")
        return "\n".join(lines)

    def to_csv(self, path: Any) -> None:
        """One row per speed, SI with ``name [unit]`` headers like every
        chatterlab CSV: ``speed [rpm]``, ``a_lim [m]`` (``inf``: no
        instability at the scanned depths), ``kind`` (hopf, flip, fold or
        none), ``chatter frequency [Hz]``, ``|mu| [-]`` and ``arg mu [rad]``
        of the critical multiplier, ``error [m]``, and what was searched:
        ``searched up to [m]`` and ``scan step [m]`` (the scan step is
        ``nan`` for the zeroth-order approximation), ``basis`` (what the
        row's verdict rests on: complete, undetermined, scan or zoa, see
        :attr:`basis`) and ``certified to [m]`` (depth up to which
        stability was established; nan for scan and zoa); floats as
        ``repr`` (exact), written atomically."""
        import csv

        from ..io._files import text_out

        def g(x: Any) -> str:
            return repr(float(x))

        with text_out(path) as fh:
            w = csv.writer(fh, lineterminator="\n")
            w.writerow(["speed [rpm]", "a_lim [m]", "kind", "chatter frequency [Hz]", "|mu| [-]",
                        "arg mu [rad]", "error [m]", "searched up to [m]", "scan step [m]", "basis",
                        "certified to [m]"])  # fmt: skip
            for i in range(self.rpm.size):
                mu = complex(self.multiplier[i])
                w.writerow([g(self.rpm[i]), g(self.a_lim[i]), self.kind[i] or "none", g(self.frequency_hz[i]),
                            g(abs(mu)), g(np.angle(mu)), g(self.error[i]), g(self.depth_max),
                            g(self.scan_step), self.basis[i], g(self.certified[i])])  # fmt: skip

    def to_xarray(self, attrs: dict[str, Any] | None = None) -> Any:
        """The lobes as an :class:`xarray.Dataset` with the spindle speed as
        coordinate: a_lim (m), the lobe type (0 none, 1 Hopf, 2 flip, 3 fold),
        chatter frequency (Hz), critical multiplier, error estimate (m)."""
        from ..io import make_dataset

        return make_dataset(*self.dataset_parts(attrs))

    def dataset_parts(
        self, attrs: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """``(coords, data, attrs)`` of :meth:`to_xarray` and :meth:`to_netcdf`."""
        code = {"": 0, "hopf": 1, "flip": 2, "fold": 3, "undetermined": 4}
        mu = self.multiplier.astype(complex)
        a = {
            "title": "chatterlab milling stability lobes",
            "model": self.name,
            "method": self.method,
            "resolution": self.resolution,
            "depth_max_m": self.depth_max,
            "scan_step_m": self.scan_step,
            "claim": _claim(self),
        }
        a.update(self.meta if all(isinstance(v, (int, float, str)) for v in self.meta.values()) else {})
        a.update(attrs or {})
        return (
            {"speed": (self.rpm, "rpm", "spindle speed")},
            {
                "a_lim": (self.a_lim, "m", "limit axial depth of cut"),
                "kind": (np.array([code.get(str(k), -1) for k in self.kind], float), "1",
                         "lobe type: 0 none, 1 Hopf, 2 flip, 3 fold, 4 undetermined"),
                "chatter_frequency": (self.frequency_hz, "Hz", "chatter frequency at the limit"),
                "multiplier_abs": (np.abs(mu), "1", "|critical Floquet multiplier|"),
                "multiplier_arg": (np.angle(mu), "rad", "arg of the critical Floquet multiplier"),
                "error": (self.error, "m", "estimated error of a_lim"),
            },
            a,
        )  # fmt: skip

    def to_netcdf(self, path: Any, attrs: dict[str, Any] | None = None) -> None:
        """netCDF-4 file of :meth:`to_xarray`, written atomically by
        :func:`chatterlab.io.write_netcdf` (the same file, without xarray)."""
        from ..io import write_netcdf

        write_netcdf(path, *self.dataset_parts(attrs))

    def plot(self, ax: Any = None, *, label: str | None = None, title: str | None = None, **kw: Any) -> Any:
        """a_lim (mm) against rpm, Hopf and flip lobes told apart, the
        unstable side shaded (:func:`chatterlab.plot.plot_milling_lobes`).
        Returns the Axes."""
        from ..plot import plot_milling_lobes

        return plot_milling_lobes(self, ax=ax, label=label, title=title, **kw)


def _claim(ml: MillingLobes) -> str:
    """What a_lim and inf rest on, for the dataset attributes."""
    basis = set(np.asarray(ml.basis).astype(str))
    if basis <= {"complete", "undetermined"}:
        return (
            "a_lim: the first depth with a Floquet multiplier on the unit circle; flip/fold depths exact"
            " (real eigenvalues of the affine monodromy pencil), complex pairs tracked with their derivatives"
            " between scan depths to first order; inf: no multiplier reaches the unit circle up to depth_max;"
            " basis 'undetermined': stable established only up to a_lim (a lower bound)"
        )
    if basis == {"zoa"}:
        return "zeroth-order approximation (averaged coefficients); flip lobes are not modelled"
    return (
        "a_lim: the first crossing of rho = 1 seen on the scan; inf: stable at every scanned depth up to"
        " depth_max (a band narrower than scan_step between two stable scan depths can be missed)"
    )


# ============================================================================ ZOA
def zoa_plant(structure: ToolStructure, milling: Milling) -> Plant:
    """The averaged milling process on ``structure`` as a lobe-engine Plant.

    With the CE convention of the engine (force on the tool
    = -(Dl_P r + Dl_O r(t - T)) per unit width), the ZOA force
    F = -a_p H0 [r(t) - r(t - tau)] is Dl_P = H0, Dl_O = -H0 per metre of a_p.
    """
    A = structure.A
    n = structure.n
    d = A.shape[0]
    # the cut's coordinates r = Ub (Jr q): a rank-deficient J (a 1-DOF tool) stays regular
    Ub, Jr, W = structure.cut_basis
    rho = Jr.shape[0]
    B = np.zeros((d, rho))
    B[n:] = W
    Cm = np.zeros((rho, d))
    Cm[:, :n] = Jr
    p, S = np.linalg.eig(A)
    pr = PoleResidue(p, Cm @ S, np.linalg.solve(S, B.astype(complex)), np.zeros((rho, rho)))
    H0 = Ub.T @ milling.zoa() @ Ub
    Z = structure

    def H(omega: np.ndarray) -> np.ndarray:
        from ..structure import dynamic_receptance

        return dynamic_receptance(Z.M, Z.C, Z.K, np.atleast_1d(np.asarray(omega, dtype=float)), Jr)

    return Plant(H, p, H0, np.zeros((rho, rho)), -H0, pr)


def _zoa(structure: ToolStructure, milling: Milling, rpm: np.ndarray, depth_max: float) -> dict[str, Any]:
    if not milling.uniform:
        raise InputError(
            "method 'zoa' handles a uniform pitch only (one delay); use method='spectral' for a variable pitch"
        )
    proc = Process(kind="turning", speed=float(rpm[0]))
    d = lobes(
        None,
        milling.teeth * rpm,
        width_max=depth_max,
        plant=zoa_plant(structure, milling),
        process=proc,
        verify=0,
        name=structure.name,
    )
    fin = np.isfinite(d.b_lim)
    return {
        "a_lim": np.asarray(d.b_lim, dtype=float),
        "kind": np.where(fin, "hopf", ""),
        "frequency_hz": np.asarray(d.chatter_hz, dtype=float),
        "multiplier": np.full(rpm.size, np.nan + 0j),
        "error": np.full(rpm.size, np.nan),
        "resolution": f"D-subdivision on {d.n_frequencies} frequencies",
        "evaluations": 0,
    }


@single_threaded
def milling_lobes(
    structure: ToolStructure,
    milling: Milling,
    rpm: np.ndarray,
    *,
    method: Literal["spectral", "sdm", "zoa"] = "spectral",
    depth_max: float = 0.01,
    scan: int = 40,
    rtol: float = 1e-8,
    degree: int = DEGREE,
    elements: int | None = None,
    steps: int = 40,
    check: bool = True,
) -> MillingLobes:
    """Milling stability lobes a_lim(rpm).

    Parameters
    ----------
    structure : ToolStructure
        The structure at the tool (M, C, K and the map J to (x, y)).
    milling : Milling
        Cutter and cut (immersion, coefficients, pitch, helix).
    rpm : array (n,)
        Spindle speeds, rpm.
    method : {"spectral", "sdm", "zoa"}
        Spectral-element Floquet (reference), first-order semi-discretisation
        or the zeroth-order approximation through the D-subdivision engine.
    depth_max : float
        Largest axial depth searched, m.
    scan : int
        Depths scanned in (0, depth_max] before refining the first crossing
        (spectral, sdm).
    rtol : float
        Relative tolerance of Brent's method on a_lim.
    degree, elements : int
        Spectral: polynomial degree; sub-elements per cutting piece (default:
        omega L <= 5, with omega the highest pole stiffened at depth_max).
    steps : int
        SDM: steps per period.
    check : bool
        Spectral: estimate the error of each a_lim from a degree
        + CHECK_DEGREE recomputation.

    Returns
    -------
    MillingLobes
    """
    t0 = time.perf_counter()
    rpm, depth_max, scan = _checked(structure, milling, rpm, method, depth_max, scan)
    if method == "zoa":
        out = _zoa(structure, milling, rpm, depth_max)
        return MillingLobes(
            rpm=rpm,
            depth_max=depth_max,
            scan_step=float("nan"),
            method="zoa",
            name=structure.name,
            elapsed=time.perf_counter() - t0,
            **out,
        )
    n = rpm.size
    a_lim = np.full(n, np.inf)
    kind = np.full(n, "", dtype=object)
    freq = np.full(n, np.nan)
    mult = np.full(n, np.nan + 0j)
    err = np.full(n, np.nan)
    evals = 0
    target = max(10.0 * rtol, 1e-7)  # relative error of a_lim the spectral check must confirm
    refined = 0
    basis = np.full(n, "scan", dtype=object)
    certified = np.full(n, np.nan)
    for i, r in enumerate(rpm):
        a, err[i], mu, f_hz, cnt, n_ref, basis[i], certified[i] = floquet_limit(
            structure, milling, r, method, depth_max, scan, rtol, degree, elements, steps, check, target
        )
        evals += cnt
        refined += n_ref
        if basis[i] == "undetermined":
            a_lim[i] = a
            kind[i] = "undetermined"
            continue
        if not np.isfinite(a):
            continue
        freq[i] = f_hz
        a_lim[i] = a
        mult[i] = mu
        kind[i] = classify(mu)
    return MillingLobes(
        rpm=rpm,
        a_lim=a_lim,
        kind=kind.astype(str),
        frequency_hz=freq,
        multiplier=mult,
        error=err,
        method=method,
        resolution=_resolution(method, degree, elements, steps),
        depth_max=depth_max,
        scan_step=depth_max / scan,
        name=structure.name,
        elapsed=time.perf_counter() - t0,
        evaluations=evals,
        meta={"refined": refined, "target_rtol": target} if method == "spectral" else {},
        basis=basis.astype(str),
        certified=certified,
    )


def _resolution(method: str, degree: int, elements: int | None, steps: int) -> str:
    """The discretisation, as the result states it."""
    if method != "spectral":
        return f"{steps} steps per period"
    return (
        f"degree {degree}, omega L <= 5 per element" if elements is None else f"degree {degree} x {elements}"
    )


def _checked(
    structure: ToolStructure, milling: Milling, rpm: np.ndarray, method: str, depth_max: float, scan: int
) -> tuple[np.ndarray, float, int]:
    """The arguments of :func:`milling_lobes` checked: (rpm, depth_max, scan)."""
    if method not in METHODS:
        raise InputError(f"method must be one of {', '.join(METHODS)} (got {method!r})")
    rpm = np.atleast_1d(np.asarray(rpm, dtype=float))
    if rpm.ndim != 1 or rpm.size == 0:
        raise InputError("rpm must be a non-empty 1-D array of spindle speeds")
    for v in (rpm.min(), rpm.max()) if np.all(np.isfinite(rpm)) else rpm[~np.isfinite(rpm)][:1]:
        check_speed(v, "rpm", "rpm")
    depth_max = check_positive(depth_max, "depth_max", "m")
    scan = check_count(scan, "scan", 2)
    if not structure.stable():
        raise InputError(f"{structure.name}: the structure without cutting is unstable; check its damping")
    if milling.helix > 0 and method == "sdm":  # (zoa averages the helix away)
        raise InputError(
            f"milling_lobes: method {method!r} takes no helix angle; use method='spectral' or helix=0"
        )
    return rpm, depth_max, scan
