"""Floquet multipliers of a cut under spindle-speed variation (SSV).

The equation.  With the spindle on the program Omega(t) of
:mod:`chatterlab.process._ssv` (Eq. 1 there) the regeneration reads the
surface one pitch angle back, at the time-varying delay tau_j(t) of its
Eq. (3).  With the state x = (q, q') of the structure and the width (depth)
b of the cut the closed loop is

    x'(t) = [A + b A_c(t)] x(t) + b sum_j B_j(t) C x(t - tau_j(t))            (1)

with A the free structure's state matrix and, per unit width,

* turning / shaping (one delay, coefficients constant): A_c the state form
  of D_P + s D_V, B C that of the delayed term D_O = U V^T
  (:class:`~chatterlab.process.ClosedLoop`), tau(t) from phi_p = 2 pi;
* milling: A_c(t) = -[0; W sum_j H_j(t)] C, B_j(t) = [0; W H_j(t)] with
  H_j the tooth's directional matrix at its angle theta(t) - lag_j and C
  the tool point (:class:`~chatterlab.process.VaryingSpeedMilling`).

Process damping (turning, shaping): the flank's b C_pd / V n n^T in D_V
follows the cutting speed V(t) = V_0 Omega(t) / Omega_0, so A_c(t) =
A_c^0 + (Omega_0 / Omega(t) - 1) A_d with A_d its state form at the mean speed.

A quasi-static split (turning, shaping; ``split``): the structure's modes
above a frequency enter by their exact static compliance G at the cut
(:func:`~chatterlab.frequency._floquet_spectral.split_structure`), the kept modes' state x is
integrated, and the delayed output y = V_d^T r carries the quasi-static
response too:

    x' = A~ x + B~ y(t - tau),   y = C_y x + E y(t - tau)                    (1q)

(:meth:`~chatterlab.process.VaryingDelayLoop.split_terms`; its error on the
loop: :func:`split_error`).

(1) is periodic with the period of the program and the cut together
(:meth:`SpeedVariation.period_phase`), taken here a whole number of times
when one period is shorter than the longest delay (a history of one period
then suffices; the multipliers of the k-fold map are the k-th powers).

Two discretisations, each with its accuracy knob:

``"sdm"``.  First-order semi-discretisation (Insperger & Stepan 2004, J. Vib.
Control, for turning; Seguy et al. 2010 for milling): ``steps`` steps per
period, the coefficients their exact mean over a step, the delayed output
C x(t - tau_j(t)) linear in time over the step between its values at the
step's ends, each interpolated linearly on the grid at the delay of that
instant (:func:`~chatterlab.frequency._floquet_sdm.sd_step_product`, the
one step of the method, which the constant-speed milling engine uses too).
Its multipliers converge as steps^-2.

``"spectral"``.  Spectral elements marched along the period (Butcher et al.
2004; Khasawneh & Mann 2011; Lehotzky, Insperger & Stepan 2016): the period
is cut where a coefficient jumps (a tooth enters or leaves the arc; the
triangle's corners and their delayed images), each piece into elements no
longer than the shortest delay and turning the fastest solution by at most
``span`` radians, on which x is the polynomial of degree p through its
Chebyshev-Lobatto nodes and (1) is collocated at nodes 1..p.  Because an
element is shorter than every delay, the delayed argument of its nodes lies
in elements already solved (or in the last period's history): each element
is one small linear solve, its nodal states linear maps of the history z
(the end state and C x at the history's nodes).  The delayed value is the
element's interpolant at t - tau_j(t) (barycentric).  Where no tooth cuts the
motion is free and exact, x(t) = e^{A (t - a)} x(a).  The multipliers are the
eigenvalues of the map z -> z one period later; their error falls
geometrically with p (algebraically for the triangle, whose delay has
corners).

References
----------
T. Insperger, G. Stepan, Stability analysis of turning with periodic
spindle speed modulation via semidiscretization, J. Vib. Control 10 (2004)
1835-1855.
S. Seguy, T. Insperger, L. Arnaud, G. Dessein, G. Peigne, On the stability
of high-speed milling with spindle speed variation, Int. J. Adv. Manuf.
Technol. 48 (2010) 883-895.
E. A. Butcher, H. Ma, E. Bueler, V. Averina, Z. Szabo, Stability of linear
time-periodic delay-differential equations via Chebyshev polynomials, Int.
J. Numer. Meth. Engng 59 (2004) 895-922.
F. A. Khasawneh, B. P. Mann, A spectral element approach for the stability
of delay systems, Int. J. Numer. Meth. Engng 87 (2011) 566-592.
D. Lehotzky, T. Insperger, G. Stepan, Extension of the spectral element
method for stability analysis of time-periodic delay-differential equations
with multiple and distributed delays, Commun. Nonlinear Sci. Numer. Simul.
35 (2016) 177-189.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import scipy.linalg as sla

from ..errors import InputError, check_count, check_nonneg
from ..process import ClosedLoop, SpeedVariation, VaryingDelayLoop, ssv_loop
from ._floquet_sdm import check_method, finite_monodromy, matched_change, sd_step_product
from ._floquet_spectral import CHECK_DEGREE, DEGREE, ELEMENT_SPAN, QuasiStatic, _bary, _cheb, split_structure

__all__ = [
    "ssv_multipliers",
    "ssv_monodromy",
    "sd_monodromy_ssv",
    "ssv_split",
    "split_error",
    "delayed_transfer",
    "MAX_HISTORY",
]

#: the largest history (multipliers) the spectral discretisation sets up
MAX_HISTORY = 4000


# ============================================================================ semi-discretisation
def sd_monodromy_ssv(sys: VaryingDelayLoop, width: float, steps: int) -> np.ndarray:
    """The monodromy of first-order semi-discretisation with ``steps`` steps per period
    (module docstring; :func:`~chatterlab.frequency._floquet_sdm.sd_step_product`)."""
    m = check_count(steps, "steps", 2)
    dt = sys.period / m
    t = np.arange(m + 1) * dt
    Ac, B = sys.mean_coefficients(t[:-1], t[1:])
    A_steps = sys.A[None] + width * Ac
    B_steps = width * B
    return sd_step_product(A_steps, B_steps, sys.C, sys.delays(t[:-1]) / dt, sys.delays(t[1:]) / dt, dt)


def sd_steps_for(sys: VaryingDelayLoop, per_delay: int) -> int:
    """Steps per period giving ``per_delay`` steps over the mean delay."""
    return max(2, math.ceil(per_delay * sys.period / sys.mean_delay))


# ============================================================================ spectral elements
@dataclass(frozen=True)
class _Element:
    a: float
    b: float
    p: int  # degree (0: a free piece, solved exactly)


def ssv_mesh(sys: VaryingDelayLoop, width: float, degree: int, span: float) -> list[_Element]:
    """The elements of one period (module docstring): every cutting piece split into
    elements no longer than the shortest delay and turning the solution by at most
    ``span`` radians at the loop's fastest frequency."""
    om = sys.omega_scale(width)
    tau_min = sys.tau_range[0]
    out = []
    for lo, hi, cut in sys.pieces():
        L = hi - lo
        if not cut:
            out.append(_Element(lo, hi, 0))
            continue
        k = max(1, math.ceil(L / tau_min), math.ceil(om * L / span))
        e = lo + L * np.arange(k + 1) / k
        out.extend(_Element(float(a), float(b), int(degree)) for a, b in zip(e[:-1], e[1:], strict=True))
    return out


def ssv_monodromy(
    sys: VaryingDelayLoop,
    width: float,
    degree: int = DEGREE,
    span: float = ELEMENT_SPAN,
    history_times: list[np.ndarray] | None = None,
) -> np.ndarray:
    """The spectral-element monodromy of (1) at width ``width`` (module docstring):
    the map of the history z = (x at the period's end, C x at the history's nodes);
    ``history_times``, a list, receives the time of each entry of z (s; nan for the
    end state)."""
    if history_times is None:
        history_times = []
    b = check_nonneg(width, "width of cut", "m")
    p = check_count(degree, "degree", 2)
    els = ssv_mesh(sys, b, p, span)
    T = sys.period
    t0 = els[0].a
    d, rho = sys.d, sys.rho
    tau_max = sys.tau_range[1]
    # the history: the elements reaching into [t0 + T - tau_max, t0 + T]
    hist = [i for i, e in enumerate(els) if e.b > t0 + T - tau_max - 1e-12 * T]
    cols: dict[int, int] = {}  # element -> first column of its block in z
    nz = d
    for i in hist:
        cols[i] = nz
        nz += d if els[i].p == 0 else (els[i].p + 1) * rho
    if nz > MAX_HISTORY:
        raise InputError(
            f"ssv spectral: a history of {nz} values (the delay holds {len(hist)} elements of degree {p}); at"
            f" most {MAX_HISTORY}: give split=F (--split F: the modes above F Hz quasi-static, turning and"
            " shaping), a higher degree with a longer span, or a higher speed"
        )
    ends = np.array([e.b for e in els])
    expm_cache: dict[float, np.ndarray] = {}

    def expA(g: float) -> np.ndarray:
        key = round(g / T, 13)
        if key not in expm_cache:
            expm_cache[key] = sla.expm(sys.A * g) if g > 0 else np.eye(d)
        return expm_cache[key]

    # the period's nodal values as maps of z: R[i] (p+1, rho, nz) for a cut element, X0[i] (d, nz)
    # the state entering element i
    R: dict[int, np.ndarray] = {}
    X0: dict[int, np.ndarray] = {}

    def r_at(td: float, current: bool) -> np.ndarray:
        """C x(td) as a (rho, nz) map of z; ``current``: td in this period, else in the history."""
        tol = 1e-12 * T
        i = int(np.searchsorted(ends, td - tol, side="left"))
        i = min(i, len(els) - 1)
        e = els[i]
        if e.p == 0:
            g = td - e.a
            if current:
                return sys.C @ expA(g) @ X0[i]
            out = np.zeros((rho, nz))
            out[:, cols[i] : cols[i] + d] = sys.C @ expA(g)
            return out
        nodes, _, bw = _cheb(e.p)
        u = min(max((td - e.a) / (e.b - e.a), 0.0), 1.0)
        wts = _bary(nodes, bw, u)
        if current:
            return np.einsum("l,lrz->rz", wts, R[i])
        out = np.zeros((rho, nz))
        c = cols[i]
        for l_ in np.nonzero(wts)[0]:
            out[:, c + l_ * rho : c + (l_ + 1) * rho] += wts[l_] * np.eye(rho)
        return out

    def delayed(td: float, L: float, a: float) -> np.ndarray:
        """The history's output at td (< the element's start a) as a map of z."""
        if td > a + 1e-9 * L:
            raise AssertionError("ssv spectral: an element longer than the delay")  # pragma: no cover
        cur = td >= t0 - 1e-12 * T
        return r_at(td if cur else td + T, cur)

    # Eq. (1q) with a quasi-static split: constant A~, B~, C_y, E at this width
    split = sys.split_terms(b) if sys.split_parts is not None else None
    x = np.zeros((d, nz))
    x[:, :d] = np.eye(d)  # the state at t0: the history's end state
    I_d = np.eye(d)
    for i, e in enumerate(els):
        X0[i] = x
        L = e.b - e.a
        if e.p == 0:
            x = expA(L) @ x
            continue
        nodes, Dm, _ = _cheb(e.p)
        tk = e.a + L * nodes
        pp = e.p
        blk = np.kron(Dm[1:, 1:] / L, I_d)
        rhs = -np.kron(Dm[1:, :1] / L, I_d) @ x
        if split is not None:
            As, Bs, Cy, Ey = split
            tau_all = sys.delays(tk)[:, 0]  # (p + 1,): one delay
            yd = [delayed(float(tk[k] - tau_all[k]), L, e.a) for k in range(pp + 1)]
            for k in range(pp):
                blk[k * d : (k + 1) * d, k * d : (k + 1) * d] -= As
                rhs[k * d : (k + 1) * d] += Bs @ yd[k + 1]
            Xn = np.linalg.solve(blk, rhs).reshape(pp, d, nz)
            Xall = np.concatenate([x[None], Xn], axis=0)
            R[i] = np.einsum("rd,ldz->lrz", Cy, Xall) + np.einsum("rs,lsz->lrz", Ey, np.stack(yd))
            x = Xn[-1]
            continue
        Ac, Bj = sys.coefficients(tk[1:], 0.5 * (e.a + e.b))
        tau = sys.delays(tk[1:])  # (p, J)
        for k in range(pp):
            blk[k * d : (k + 1) * d, k * d : (k + 1) * d] -= sys.A + b * Ac[k]
            for j in range(Bj.shape[1]):
                Bk = Bj[k, j]
                if not np.any(Bk):
                    continue
                rd = delayed(float(tk[k + 1] - tau[k, j]), L, e.a)
                rhs[k * d : (k + 1) * d] += b * (Bk @ rd)
        Xn = np.linalg.solve(blk, rhs).reshape(pp, d, nz)
        Xall = np.concatenate([x[None], Xn], axis=0)
        R[i] = np.einsum("rd,ldz->lrz", sys.C, Xall)
        x = Xn[-1]
    # the time of each history value (nan for the end state), for the chatter frequency
    times = np.full(nz, np.nan)
    for i in hist:
        if els[i].p > 0:
            tn = els[i].a + (els[i].b - els[i].a) * _cheb(els[i].p)[0]
            times[cols[i] : cols[i] + (els[i].p + 1) * rho] = np.repeat(tn, rho)
    history_times[:] = [times]
    # z one period later
    Mz = np.zeros((nz, nz))
    Mz[:d] = x
    for i in hist:
        c = cols[i]
        if els[i].p == 0:
            Mz[c : c + d] = X0[i]
        else:
            Mz[c : c + (els[i].p + 1) * rho] = R[i].reshape(-1, nz)
    return Mz


def dominant_frequency(
    mu: complex, vec: np.ndarray, times: np.ndarray, period: float, top_hz: float
) -> float:
    """The chatter frequency, Hz, of the Floquet solution x(t) = e^{lambda t} p(t)
    (lambda = ln(mu) / T, p T-periodic) whose history is ``vec`` at ``times``: the
    largest of the Fourier coefficients c_k of p over the history's nodes (trapezoid
    weights), k up to ``top_hz`` T; the frequency |Im lambda + 2 pi k / T| / 2 pi.
    Unlike the family member nearest a pole, it does not depend on which pole a
    member of a dense family (a long period) happens to fall near."""
    ok = np.isfinite(times)
    t, y = times[ok], np.asarray(vec)[ok]
    order = np.argsort(t, kind="stable")
    t, y = t[order], y[order]
    if t.size < 2:
        return float(abs(np.angle(mu)) / period / (2 * np.pi))
    lam = np.log(complex(mu)) / period
    p = y * np.exp(-lam * (t - t[0]))
    w = np.zeros(t.size)
    dt = np.diff(t)
    w[:-1] += 0.5 * dt
    w[1:] += 0.5 * dt
    K = max(1, math.ceil(top_hz * period) + 2)
    k = np.arange(-K, K + 1)
    c = np.exp(-2j * np.pi * np.outer(k, t - t[0]) / period) @ (w * p)
    best = int(k[int(np.argmax(np.abs(c)))])
    return float(abs(lam.imag + 2 * np.pi * best / period) / (2 * np.pi))


# ============================================================================ the quasi-static split
def ssv_split(loop: ClosedLoop, split: float | QuasiStatic | None) -> QuasiStatic | None:
    """The quasi-static split asked for: ``split`` Hz (the modes above it quasi-static,
    :func:`~chatterlab.frequency._floquet_spectral.split_structure`), a :class:`QuasiStatic` of ``loop``
    as it is, or None."""
    if split is None or isinstance(split, QuasiStatic):
        return split
    if loop.process is not None:
        raise InputError(
            "ssv: a quasi-static split (split=...) is modelled for turning and shaping, not for milling"
        )
    f = float(split)
    if not (math.isfinite(f) and f > 0):
        raise InputError(f"ssv: split must be a frequency > 0 in Hz (got {split!r})")
    return split_structure(loop, f)


#: frequencies sampled over the band of :func:`split_error`
SPLIT_SAMPLES = 65


def delayed_transfer(sys: VaryingDelayLoop, width: float, f: float, split: bool) -> np.ndarray:
    """G(omega) of :func:`split_error` at ``f`` Hz and width b: the full structure's
    (``split`` False) or Eq. (1q)'s (True), rho x rho (the delayed term's rank)."""
    assert sys.split_parts is not None and sys.quasi_static is not None
    sp, loop = sys.split_parts, sys.loop
    b, w = float(width), 2 * np.pi * float(f)
    Kc, Kv, Ud, Vd, G = sp["Kc"], sp["Kv"], sp["Ud"], sp["Vd"], sp["G"]
    if split:
        kl = sys.quasi_static.loop
        Jk = loop.cut_basis[0].T @ kl.J
        Hk = Jk @ np.linalg.solve(kl.K - w * w * kl.M + 1j * w * kl.C, Jk.T)
        H, Hv = Hk + G, Hk
    else:
        Jr = loop.cut_basis[1]
        H = Hv = Jr @ np.linalg.solve(loop.K - w * w * loop.M + 1j * w * loop.C, Jr.T)
    eye = np.eye(G.shape[0])
    return np.asarray(b * Vd.T @ H @ np.linalg.solve(eye - b * Kc @ H - 1j * w * b * Kv @ Hv, Ud))


def split_error(sys: VaryingDelayLoop, width: float, f_lo: float, f_hi: float) -> float:
    """The split's error at width b in the band [f_lo, f_hi] Hz: the largest relative
    change eps of the delayed loop's transfer G(omega), y -> y one delay later at
    constant speed (:func:`delayed_transfer`, ``SPLIT_SAMPLES`` frequencies), from the
    full structure to Eq. (1q).

    With the force f = b [K_c r + K_v r' + U_d y(t - tau)] on the cut's coordinates r
    and y = V_d^T r, the full structure (r = H f, H its receptance) gives
    G = b V_d^T H (I - b K_c H - i omega b K_v H)^-1 U_d and Eq. (1q) (r = (H_k + G_s) f,
    only the kept modes' velocity i omega H_k f damped) the same with H_k + G_s in place
    of H and H_k in the velocity term.  The constant-speed boundary is
    G(omega, b) e^{-i omega tau} = 1, i.e. ln G - i omega tau = 2 pi i k.  A change
    d ln G (|d ln G| <= eps / (1 - eps)) moves (omega, ln b) by the inverse of that
    equation's real 2 x 2 Jacobian [d_omega ln G - i tau, d_ln b ln G], so ln b_lim by
    at most kappa eps / (1 - eps) to first order, kappa the 2-norm of the inverse's
    second row (about 1 to 2 at the shaper's lobes; tests/test_ssv_split.py computes
    it).  Under SSV the chatter spreads over the band f_c (1 -+ RVA) (the delay's
    variation), where eps is taken."""
    out = 0.0
    for f in np.linspace(f_lo, f_hi, SPLIT_SAMPLES):
        full = delayed_transfer(sys, width, f, split=False)
        split = delayed_transfer(sys, width, f, split=True)
        out = max(out, float(np.linalg.norm(split - full, 2) / np.linalg.norm(full, 2)))
    return out


# ============================================================================ the entry
def _ranked(mu: np.ndarray) -> np.ndarray:
    mu = mu[np.abs(mu) > 1e-300]
    r = np.abs(mu)
    key = np.round(r / max(float(r.max(initial=0.0)), 1e-300), 12)
    return mu[np.lexsort((-mu.imag, -key))]


def ssv_multipliers(
    loop: ClosedLoop,
    speed: float | None,
    width: float,
    variation: SpeedVariation,
    *,
    method: Literal["spectral", "sdm"] = "spectral",
    degree: int = DEGREE,
    span: float = ELEMENT_SPAN,
    steps: int | None = None,
    check: bool = True,
    split: float | QuasiStatic | None = None,
) -> Any:
    """Floquet multipliers of a cut under spindle-speed variation at one mean speed
    and width (module docstring).

    Parameters
    ----------
    loop : ClosedLoop
        Milling (:func:`~chatterlab.process.milling_loop`) or turning/shaping at its
        mean delay (:func:`~chatterlab.process.closed_loop`).
    speed : float or None
        Mean speed: rpm for milling (required); turning/shaping: for the record.
    width : float
        Width of cut b (milling: axial depth a_p), m.
    variation : SpeedVariation
        The speed program.
    method : {"spectral", "sdm"}
        Spectral elements (reference) or first-order semi-discretisation.
    degree, span : int, float
        Spectral: polynomial degree; radians the fastest solution turns per element.
    steps : int, optional
        SDM: steps per period (default: 40 per mean delay).
    check : bool
        Also at a higher resolution (degree + CHECK_DEGREE; 2 x steps): the change of
        the critical multiplier is ``error``.
    split : float or QuasiStatic, optional
        Turning / shaping, spectral: the structure's modes above ``split`` Hz respond
        quasi-statically (their exact static compliance at the cut, Eq. (1q) of the
        module docstring), so only the modes below are integrated and the history
        resolves only their frequencies (a structure with many modes, a long delay).
        ``meta["split_error"]`` is :func:`split_error` over the chatter band
        f_c (1 -+ RVA) (the variation spreads the chatter over it), ``meta["split_hz"]``
        the frequency, ``meta["kept"]`` the modes integrated.  ``error`` (and so the
        verdict) is the discretisation's alone: the split's is on the loop's transfer,
        not on mu (it moves b_lim by at most kappa eps / (1 - eps), :func:`split_error`).

    Returns
    -------
    Multipliers
        ``period`` is the computational period (``meta["folds"]`` principal periods);
        ``rpm`` the mean speed, ``depth`` the width.
    """
    from ._floquet import Multipliers, chatter_frequency, process_names

    t_start = time.perf_counter()
    b = check_nonneg(width, "width of cut", "m")
    qs = ssv_split(loop, split)
    if qs is not None and method != "spectral":
        raise InputError(
            "ssv: a quasi-static split is discretised by spectral elements only: give method='spectral'"
        )
    sys = ssv_loop(loop, variation, speed, quasi_static=qs)
    f_c = math.nan
    if method == "spectral":

        def mono(up: int, times: list[np.ndarray] | None = None) -> np.ndarray:
            return finite_monodromy(ssv_monodromy(sys, b, degree + up, span, times), sys.speed, b)

        if qs is None:
            mu = _ranked(np.linalg.eigvals(mono(0)))
        else:
            # with a split the period is long: the chatter frequency from the critical solution's history
            times: list[np.ndarray] = []
            lam, vecs = np.linalg.eig(mono(0, times))
            mu = _ranked(lam)
            j = int(np.argmin(np.abs(lam - mu[0])))
            top = float(qs.loop.omega_max) / (2 * np.pi)  # the fastest mode integrated, Hz
            f_c = dominant_frequency(complex(mu[0]), vecs[:, j], times[0], sys.period, top)
        err = matched_change(complex(mu[0]), np.linalg.eigvals(mono(CHECK_DEGREE))) if check else float("nan")
        res = f"degree {degree}, span {span:g} rad"
    elif method == "sdm":
        m = sd_steps_for(sys, 40) if steps is None else check_count(steps, "steps", 2)

        def mono_sd(k: int) -> np.ndarray:
            return finite_monodromy(sd_monodromy_ssv(sys, b, k), sys.speed, b)

        mu = _ranked(np.linalg.eigvals(mono_sd(m)))
        err = matched_change(complex(mu[0]), np.linalg.eigvals(mono_sd(2 * m))) if check else float("nan")
        res = f"{m} steps"
    else:
        check_method(method)  # one line naming the methods
    if not math.isfinite(f_c):  # the family member nearest a pole of the structure
        f_c = chatter_frequency(complex(mu[0]), sys.period, loop)
    meta = {"folds": float(sys.folds), "rva": variation.amplitude, "rvf": variation.frequency}
    res += f"; {variation.describe()}"
    if qs is not None:
        a = variation.amplitude
        meta["split_hz"], meta["kept"] = qs.f_split, float(qs.kept)
        meta["split_error"] = split_error(sys, b, f_c * (1 - a), f_c * (1 + a)) if f_c > 0 else math.nan
        res += f"; {qs.kept} of {qs.n_full} modes integrated, quasi-static above {qs.f_split:g} Hz"
    if loop.process is not None:
        proc: Any = loop.process
    else:
        proc = loop.frozen.model.process if loop.frozen is not None else None
    return Multipliers.ranked(
        mu,
        error=err,
        frequency_hz=f_c,
        method=method,
        resolution=res,
        period=sys.period,
        rpm=float(sys.speed),
        depth=b,
        elapsed=time.perf_counter() - t_start,
        meta=meta,
        **process_names(proc),
    )
