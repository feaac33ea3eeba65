"""Milling stability lobes: the limit depth a_lim against spindle speed.

Three methods return the one lobe result, :class:`~chatterlab.lobes.LobeDiagram`
(its process the cutter: speeds in rpm, the width the axial depth a_p, the
limit a_lim):

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
from collections.abc import Callable
from dataclasses import replace
from typing import Any, Literal

import numpy as np

from ..errors import InputError, check_count, check_positive, check_speed
from ..frequency import (
    DEGREE,
    PoleResidue,
    classify,
)
from ..frequency._delay_system import single_threaded
from ..frequency._floquet import QuasiStatic, needs_split, split_structure
from ..process import ClosedLoop
from ._diagram import Plant, lobes
from ._milling_search import TOL_SHARE, floquet_limit
from ._result import LobeDiagram

__all__ = ["milling_lobes", "milling_ceiling", "zoa_plant"]

METHODS = ("spectral", "sdm", "zoa")


# ============================================================================ ZOA
def zoa_plant(loop: ClosedLoop, quasi_static: QuasiStatic | None = None) -> Plant:
    """The averaged milling process of a milling loop as a lobe-engine Plant.

    With the CE convention of the engine (force on the tool
    = -(Dl_P r + Dl_O r(t - T)) per unit width), the ZOA force
    F = -a_p H0 [r(t) - r(t - tau)] is Dl_P = H0, Dl_O = -H0 per metre of a_p.
    ``quasi_static``: the structure as its kept modes plus the static
    compliance of the others (:func:`chatterlab.frequency.split_structure`),
    which enters the FRF as its constant term.
    """
    # the cut's coordinates r = Ub (Jr q): a rank-deficient J (a 1-DOF tool) stays regular
    Ub, Jr, W = loop.cut_basis
    rho = Jr.shape[0]
    G = np.zeros((rho, rho))
    if quasi_static is not None:
        loop, G = quasi_static.loop, quasi_static.compliance
        Jr = Ub.T @ loop.J
        W = np.linalg.solve(loop.M, Jr.T)
    A = loop.state_matrix
    n = loop.n
    d = A.shape[0]
    B = np.zeros((d, rho))
    B[n:] = W
    Cm = np.zeros((rho, d))
    Cm[:, :n] = Jr
    p, S = np.linalg.eig(A)
    pr = PoleResidue(p, Cm @ S, np.linalg.solve(S, B.astype(complex)), G.astype(complex))
    H0 = Ub.T @ loop.milling.zoa() @ Ub
    structure = loop.structure

    def H(omega: np.ndarray) -> np.ndarray:
        return structure.receptance(omega, Jr) + G

    return Plant(H, p, H0, np.zeros((rho, rho)), -H0, pr)


def zoa_damping(loop: ClosedLoop) -> Any:
    """The averaged process-damping term of a milling loop on the cut's
    coordinates r of :func:`zoa_plant` (W_0 projected, its gain C_pd / V at each
    speed's own cutting speed: :mod:`chatterlab.lobes._damped`), None without."""
    if loop.damping is None or loop.damping.term.C_pd == 0.0:
        return None
    Ub = loop.cut_basis[0]
    term = loop.damping.term
    return replace(term, W=Ub.T @ term.W @ Ub, process=loop.milling, block=slice(None))


def _damping_meta(loop: ClosedLoop, split: bool) -> dict[str, Any]:
    """What a Floquet diagram says of the process damping its engines integrate: the
    rubbing teeth's periodic -a_p C_pd / V W(t) r' at each speed's own V = pi D n / 60
    (with a quasi-static split, what its velocity lacks)."""
    t = loop.damping.term  # type: ignore[union-attr]
    note = (
        {
            "split_note": "the quasi-static modes' velocity G dF/dt is damped inside each element, but not"
            " the impulse -a_p g W G dF of their jump where a tooth enters or leaves (an error O(a_p g G)"
            " that the split's check against twice its frequency does not see)"
        }
        if split
        else {}
    )
    return {
        **note,
        **t.meta(),
        "periodic": "the rubbing teeth's W(t) in the Floquet engines",
    }


def _zoa(
    loop: ClosedLoop, rpm: np.ndarray, depth_max: float, quasi_static: QuasiStatic | None = None
) -> LobeDiagram:
    """The zeroth-order approximation: the averaged cut's D-subdivision lobes,
    the cutter its process (speed in rpm, delay the tooth period)."""
    milling = loop.milling
    if not milling.uniform:
        raise InputError(
            "method 'zoa' handles a uniform pitch only (one delay); use method='spectral' for a variable pitch"
        )
    d = lobes(
        None,
        rpm,
        width_max=depth_max,
        plant=zoa_plant(loop, quasi_static),
        process=milling,
        verify=0,
        name=loop.name,
        damping=zoa_damping(loop),
    )
    n = rpm.size
    return replace(
        d,
        method="zoa",
        resolution=f"D-subdivision on {d.n_frequencies} frequencies",
        basis=np.full(n, "zoa"),
        certified=np.full(n, np.nan),
    )


@single_threaded
def milling_lobes(
    loop: ClosedLoop,
    rpm: np.ndarray,
    *,
    method: Literal["spectral", "sdm", "zoa"] = "spectral",
    depth_max: float | None = None,
    scan: int = 40,
    rtol: float = 1e-8,
    degree: int | None = None,
    elements: int | None = None,
    steps: int = 40,
    check: bool = True,
    jobs: int = 1,
    progress: Callable[[float], None] | None = None,
    split: float | Literal["auto"] | None = "auto",
) -> LobeDiagram:
    """Milling stability lobes a_lim(rpm).

    Parameters
    ----------
    loop : ClosedLoop
        The structure under the cutter (:func:`chatterlab.process.milling_loop`,
        or :func:`chatterlab.lobes.milling_loop_of` for a model file):
        ``loop.process`` is the :class:`~chatterlab.process.Milling` (cutter and
        cut: immersion, coefficients, pitch, helix).
    rpm : array (n,)
        Spindle speeds, rpm.
    method : {"spectral", "sdm", "zoa"}
        Spectral-element Floquet (reference), first-order semi-discretisation
        or the zeroth-order approximation through the D-subdivision engine.
    depth_max : float, optional
        Largest axial depth searched, m.  Default: from the problem, three
        times the largest limit of the zeroth-order approximation over the
        speeds (:func:`milling_ceiling`; the diagram's ``meta["ceiling"]``
        says how it was set).
    scan : int
        Depths scanned in (0, depth_max] before refining the first crossing
        (spectral, sdm).
    rtol : float
        Relative tolerance of Brent's method on a_lim.
    degree, elements : int, optional
        Spectral: polynomial degree; sub-elements per cutting piece.  Default
        (both None): one element per piece between breakpoints, its degree
        chosen for the accuracy asked (max(10 rtol, 1e-7) relative, the
        check's target; :func:`chatterlab.frequency.auto_degree`) at the
        depths searched, split only above degree 48.  An explicit degree:
        sub-elements with omega L <= 5 (omega the highest pole frequency).
    steps : int
        SDM: steps per period.
    check : bool
        Spectral: estimate the error of each a_lim from a degree
        + CHECK_DEGREE recomputation.
    jobs : int
        Speeds computed in parallel (processes; each speed is independent,
        so the diagram is the same whatever the number).
    progress : callable, optional
        Called with the fraction of speeds done (a progress bar).
    split : float, "auto" or None
        Spectral: integrate in time only the structure's modes below this
        frequency (Hz), the others quasi-static through their exact static
        compliance at the tool (:func:`chatterlab.frequency.split_structure`),
        with the split's error checked at every limit against the modes up
        to twice the frequency and added to ``error``.  ``"auto"`` (default):
        four times the highest mode carrying 5 % of the tool's static
        compliance, and only where the whole structure's discretisation at
        the slowest speed would exceed 200 multipliers (an FE-scale tool);
        None: never.  ``meta["split"]`` says what was done.

    Returns
    -------
    LobeDiagram
        ``b_lim`` (also ``a_lim``) the limit axial depth, m; ``kind`` the
        critical multiplier's type; ``basis`` what each verdict rests on.
    """
    t0 = time.perf_counter()
    ceiling_note = ""
    if depth_max is None:
        depth_max, ceiling_note = milling_ceiling(loop, np.atleast_1d(np.asarray(rpm, float)))
    rpm, depth_max, scan = _checked(loop, rpm, method, depth_max, scan)
    jobs = check_count(jobs, "jobs")
    if method == "zoa":
        d = _zoa(loop, rpm, depth_max)
        return replace(d, elapsed=time.perf_counter() - t0, meta={**d.meta, "ceiling": ceiling_note})
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
    qsplit = _split(loop, rpm, depth_max, split, target) if method == "spectral" else None
    args = (method, depth_max, scan, rtol, degree, elements, steps, check, target, qsplit)
    e_split = np.full(n, np.nan)
    for i, out in enumerate(_limits(loop, rpm, args, jobs, progress)):
        a, err[i], mu, f_hz, cnt, n_ref, basis[i], certified[i], e_split[i] = out
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
    fin = np.isfinite(a_lim) & (kind != "undetermined")
    if np.any(fin):
        j = int(np.argmin(np.where(fin, a_lim, np.inf)))
        minimum = {"width": float(a_lim[j]), "speed": float(rpm[j]), "chatter_hz": float(freq[j])}
    else:
        minimum = {"width": float("inf"), "speed": float("nan"), "chatter_hz": float("nan")}
    return LobeDiagram(
        speed=rpm,
        delay=np.asarray(loop.milling.delay(rpm), dtype=float),
        b_lim=a_lim,
        chatter_hz=freq,
        lobe=np.full(n, -1),
        lobes=(),
        minimum=minimum,
        absolute_minimum={"width": float("nan"), "chatter_hz": float("nan")},
        process=loop.milling,
        width_max=depth_max,
        terms="pdo",
        position=None,
        model=loop.name,
        elapsed=time.perf_counter() - t0,
        meta={
            **({"refined": refined, "target_rtol": target} if method == "spectral" else {}),
            "ceiling": ceiling_note,
            **(_split_meta(qsplit, e_split, a_lim) if qsplit is not None else {}),
            **(
                {"process_damping": _damping_meta(loop, qsplit is not None)}
                if zoa_damping(loop) is not None
                else {}
            ),
        },  # fmt: skip
        method=method,
        resolution=_resolution(method, degree, elements, steps)
        + (f"; {qsplit[0].note()}" if qsplit is not None else ""),
        kind=kind.astype(str),
        basis=basis.astype(str),
        certified=certified,
        multiplier=mult,
        error=err,
        scan_step=depth_max / scan,
        evaluations=evals,
    )


def _split(
    loop: ClosedLoop, rpm: np.ndarray, depth_max: float, split: Any, target: float
) -> tuple[QuasiStatic, QuasiStatic | None] | None:
    """The structure's quasi-static split for the spectral lobes (see :func:`milling_lobes`)
    and the finer one that checks it; None for none."""
    if split is None:
        return None
    if isinstance(split, str):
        if split != "auto":
            raise InputError(f"split must be 'auto', a frequency in Hz or None (got {split!r})")
        f = needs_split(loop, float(np.min(rpm)), depth_max, target / TOL_SHARE)
        if f is None:
            return None
    else:
        f = check_positive(split, "split", "Hz")
    qs = split_structure(loop, f)
    if qs.kept == loop.n:
        return None
    fine = split_structure(loop, 2.0 * f)
    return qs, (fine if fine.kept > qs.kept else None)


def _split_meta(
    qsplit: tuple[QuasiStatic, QuasiStatic | None], e_split: np.ndarray, a_lim: np.ndarray
) -> dict:
    """The diagram's record of the split: what was kept and its largest error estimate."""
    qs, fine = qsplit
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = e_split / a_lim
    rel = rel[np.isfinite(rel)]
    return {
        "split": qs.note(),
        "split_hz": qs.f_split,
        "split_kept": qs.kept,
        "split_check": (
            f"against {fine.kept} modes (below {fine.f_split:.4g} Hz): largest change"
            f" {float(rel.max()) if rel.size else float('nan'):.1e} of a_lim, in the error"
            if fine is not None
            else "no finer split to check against (every mode below twice the frequency)"
        ),
        "split_error_max_rel": float(rel.max()) if rel.size else float("nan"),
    }


def _limits(loop: ClosedLoop, rpm: np.ndarray, args: tuple, jobs: int, progress: Any) -> list[tuple]:
    """:func:`floquet_limit` at every speed, in order: in this process, or in
    ``jobs`` worker processes (each with one BLAS thread), chunk by chunk."""
    n = rpm.size
    out: list[tuple] = []
    if jobs == 1 or n == 1:
        for i, r in enumerate(rpm):
            out.append(floquet_limit(loop, r, *args))
            if progress is not None:
                progress((i + 1) / n)
        return out
    from joblib import Parallel, delayed

    from .._threads import one_blas_thread

    chunks = np.array_split(np.arange(n), min(n, 4 * jobs))
    with one_blas_thread(), Parallel(n_jobs=jobs, backend="loky", return_as="generator") as par:
        done = 0
        for part in par(delayed(_chunk)(loop, rpm[c], args) for c in chunks):
            out.extend(part)
            done += len(part)
            if progress is not None:
                progress(done / n)
    return out


def _chunk(loop: ClosedLoop, rpm: np.ndarray, args: tuple) -> list[tuple]:
    from .._threads import one_blas_thread

    with one_blas_thread():
        return [floquet_limit(loop, r, *args) for r in rpm]


def milling_ceiling(loop: ClosedLoop, rpm: np.ndarray) -> tuple[float, str]:
    """The depth ceiling of a milling diagram from the problem itself, m, and
    how it was set: three times the largest limit of the zeroth-order
    approximation (the averaged cut's D-subdivision lobes, searched up to
    1 m; for a structure the Floquet lobes would split, on its split) over
    the speeds, so that Floquet limits up to well above the averaged ones
    are found (at low immersion the averaged limits can be
    several times off; flip lobes lie below them).  With no averaged limit
    below 1 m at any speed the ceiling is 1 m."""
    rpm = np.atleast_1d(np.asarray(rpm, float))
    # an FE-scale tool: its modes far above the cut's band enter as their static compliance (the
    # ceiling is a bound with a factor 3 to spare, and the whole structure's D-subdivision cost
    # a minute on a 302-coordinate end mill)
    f = needs_split(loop, float(np.min(rpm)), 1.0, 1e-6)
    z = _zoa(loop, rpm, 1.0, split_structure(loop, f) if f is not None else None)
    fin = np.asarray(z.b_lim)[np.isfinite(z.b_lim)]
    if fin.size == 0:
        return 1.0, "1 m: the zeroth-order approximation has no limit below 1 m at these speeds"
    top = float(min(1.0, 3.0 * fin.max()))
    return top, (
        f"{top * 1e3:.4g} mm: three times the largest zeroth-order limit ({fin.max() * 1e3:.4g} mm)"
        " over these speeds"
    )


def _resolution(method: str, degree: int | None, elements: int | None, steps: int) -> str:
    """The discretisation, as the result states it."""
    if method != "spectral":
        return f"{steps} steps per period"
    if degree is None and elements is None:
        return "degree per element for the accuracy asked"
    p = DEGREE if degree is None else degree
    return f"degree {p}, omega L <= 5 per element" if elements is None else f"degree {p} x {elements}"


def _checked(
    loop: ClosedLoop, rpm: np.ndarray, method: str, depth_max: float, scan: int
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
    if not loop.stable():
        raise InputError(f"{loop.name}: the structure without cutting is unstable; check its damping")
    if loop.milling.helix > 0 and method == "sdm":  # (zoa averages the helix away)
        raise InputError(
            f"milling_lobes: method {method!r} takes no helix angle; use method='spectral' or helix=0"
        )
    return rpm, depth_max, scan
