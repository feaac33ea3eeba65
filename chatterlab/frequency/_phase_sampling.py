"""Sampling the phase of :math:`f(j\\omega)` along the imaginary axis, for the argument principle.

The steps of :func:`chatterlab.frequency.rhp_count`, in the
order it takes them:

* :class:`Sampler` evaluates the sampled factor: :math:`g = \\det(I_r - H
  e^{-j\\omega\\tau})` (factored) or :math:`\\det\\Delta / \\det P_{ref}`
  (direct);
* :func:`band_end` finds :math:`\\omega_{max}`, beyond which
  :math:`|f - 1| < 10^{-3}` (so the remaining phase is below a milliradian);
* :func:`initial_grid` places the first samples: step :math:`\\pi/(8\\tau)`,
  refined near every pole; in factored form only where the spectral radius
  of :math:`H(j\\omega)` reaches 1/2 (:class:`PassiveBands` elsewhere);
* :func:`refine` bisects every interval whose wrapped phase increment
  exceeds :math:`\\pi/4`;
* :func:`phase_change` sums the increments, exactly from the eigenvalues of
  :math:`H` at the ends of a passive interval, and adds the tail to infinity.

In factored mode :func:`certified_phase` replaces the last three steps
(and the heuristic passive bands): every increment is proven by a bound on
``||H||`` or on the Lipschitz constant of ``g`` from the partial fractions of
the delay-free loop, and the tail by a monotone bound (see its docstring
for the derivation); it starts from :func:`certification_grid` (0, the
delay-free poles' frequencies and :func:`band_start`) and its bounds place
every other sample.  :func:`certified_phases` does it for several systems
in one bisection.  :func:`band_end`, :func:`initial_grid`, :func:`refine`
and :func:`phase_change` remain the direct mode's (and the fallback's),
which is not a proof.

See :mod:`chatterlab.frequency._winding` for the mathematics and references.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._delay_system import DelaySystem

__all__ = [
    "Sampler",
    "band_start",
    "band_end",
    "initial_grid",
    "certification_grid",
    "refine",
    "phase_change",
    "PassiveBands",
    "MAX_SAMPLES",
    "Certificate",
    "certified_phase",
    "certified_phases",
]

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

_PHASE_STEP = math.pi / 4  # largest wrapped phase increment accepted between samples
_TAIL = 1e-3  # |f - 1| bound beyond omega_max
_PASSIVE = 0.5  # spectral radius of H below which g cannot wind
MAX_SAMPLES = 400_000


class Sampler:
    """Evaluate the sampled factor F(j omega): complex values, finite or not."""

    def __init__(
        self, sys: DelaySystem, mode: str, ref_poles: NDArray[np.inexact[Any]], logdetM: float
    ) -> None:
        self.sys = sys
        self.mode = mode
        self.ref = ref_poles
        self.logdetM = logdetM

    def __call__(self, omega: FloatArray) -> ComplexArray:
        sys = self.sys
        lam = 1j * omega
        if self.mode == "factored":
            H = sys.transfer_fast(lam)
            with np.errstate(all="ignore"):
                e = np.exp(-lam * sys.tau)[:, None, None]
                G = np.eye(sys.r)[None] - H * e
                return np.linalg.det(G)
        out = np.empty(omega.shape, dtype=complex)
        chunk = max(1, 2_000_000 // max(1, sys.n * sys.n))
        for s in range(0, omega.size, chunk):
            sl = slice(s, s + chunk)
            with np.errstate(all="ignore"):
                sg, ld = np.linalg.slogdet(sys.delta(lam[sl]))
                den = np.log(lam[sl][:, None] - self.ref[None, :]).sum(axis=1) + self.logdetM
                out[sl] = sg * np.exp(ld - den)
        return out


def _tail_bound(sys: DelaySystem, mode: str, omega: float, ref_shift: float | None) -> float:
    """Norm of the perturbation of F from 1 at ``j omega`` (rad/s).

    Factored mode: ``||H(j omega)||_2``.  Direct mode: ``||P_ref^{-1}
    (Delta - P_ref)||_2`` with ``P_ref = P_0`` or ``M (lam + a)^2`` when
    ``ref_shift = a`` is given.
    """
    lam = 1j * omega
    if mode == "factored":
        # the partial fractions the factored form samples (one matrix-vector
        # product instead of a solve of P)
        H = sys.transfer_fast(np.array([lam]))[0]
        return float(np.linalg.norm(H, 2)) if H.shape[0] > 1 else float(abs(H[0, 0]))
    D = sys.delta(np.array([lam]))[0]
    lead = sys.coeffs[-1]
    Pr: NDArray[Any]
    if ref_shift is None:
        Pr = sys.P0(lam)
    else:
        Pr = lead * (lam + ref_shift) ** (len(sys.coeffs) - 1)
    try:
        X = np.linalg.solve(Pr, D - Pr)
    except np.linalg.LinAlgError:
        return float("inf")
    return float(np.linalg.norm(X, 2))


def band_start(sys: DelaySystem, poles: ComplexArray, scale: float) -> float:
    """Where :func:`band_end` starts (rad/s): 3x the largest pole frequency
    (or 3x ``scale``, or 10/tau).  A certified phase starts there too and
    proves its own tail (:func:`certified_phase`)."""
    return max(3.0 * float(np.max(np.abs(poles.imag))), 3.0 * scale, 10.0 / sys.tau)


def band_end(
    sys: DelaySystem, mode: str, ref_shift: float | None, poles: ComplexArray, scale: float
) -> tuple[float, bool]:
    """``(omega_max, found)``: the frequency (rad/s) beyond which ``|F - 1| <
    1e-3`` at it and at twice it, starting from 3x the largest pole (or
    ``scale``, or 10/tau) and doubling; ``found`` is False when 60 doublings
    do not get there (``M`` singular)."""
    W = band_start(sys, poles, scale)
    for _ in range(60):
        if _tail_bound(sys, mode, W, ref_shift) < _TAIL and _tail_bound(sys, mode, 2 * W, ref_shift) < _TAIL:
            return W, True
        W *= 2.0
    return W, False


@dataclass(frozen=True)
class PassiveBands:
    """Intervals ``[a_i, b_i]`` of the axis where the spectral radius of
    ``H(j omega)`` stays below 1/2.

    There ``g = prod_k (1 - mu_k e^{-j omega tau})`` cannot wind (each factor
    keeps Re > 1/2), so the phase increment between two samples is exact from
    the eigenvalues ``mu_k`` at the ends: the dense grid is needed only
    outside them.
    """

    sys: DelaySystem
    a: FloatArray
    b: FloatArray
    W: float

    def mu(self, om: FloatArray) -> ComplexArray:
        """Eigenvalues of ``H(j om)``, shape ``(om.size, r)``."""
        return self.sys.loop_eigenvalues(1j * om)

    def flags(self, grid: FloatArray) -> NDArray[np.bool_]:
        """Which intervals of ``grid`` lie inside a passive interval."""
        a0, b0 = self.a, self.b
        if a0.size == 0:
            return np.zeros(grid.size - 1, bool)
        k = np.searchsorted(a0, grid[:-1], side="right") - 1
        kc = np.clip(k, 0, a0.size - 1)
        return (k >= 0) & (grid[1:] <= b0[kc] + 1e-12 * self.W) & (grid[:-1] >= a0[kc])


def initial_grid(
    sys: DelaySystem, mode: str, W: float, poles: ComplexArray, scale: float, n_points: int | None
) -> tuple[list[FloatArray], int, PassiveBands | None]:
    """The first samples on ``[0, W]`` (rad/s): ``(pieces, n0, passive)``.

    ``pieces`` are to be merged (``np.unique(np.concatenate(pieces))``);
    ``n0`` is the number of samples they need (checked against the limit
    before they are merged); ``passive`` the passive intervals (factored
    mode only, else None).
    """
    tau = sys.tau
    step = math.pi / (8.0 * tau)
    offs = np.array([-16, -8, -4, -2, -1, -0.5, -0.25, 0, 0.25, 0.5, 1, 2, 4, 8, 16])
    pole_pts = []
    for z in poles:
        if z.imag < 0:
            continue
        d = max(abs(z.real), 1e-9 * scale)
        loc = z.imag + d * offs
        pole_pts.append(loc[(loc > 0) & (loc < W)])
    passive: PassiveBands | None = None
    if mode == "factored":
        # a coarse grid finds where the spectral radius of H reaches 1/2;
        # the dense pi/(8 tau) grid is laid only over those active bands
        wsm = np.unique(np.concatenate([np.linspace(0.0, W, 4001)] + pole_pts))
        rho = np.abs(sys.loop_eigenvalues(1j * wsm)).max(axis=1)
        act_pt = ~(rho < _PASSIVE)  # NaN counts as active
        act_iv = act_pt[:-1] | act_pt[1:]
        act_iv = act_iv | np.r_[act_iv[1:], False] | np.r_[False, act_iv[:-1]]
        dense = [
            np.linspace(a, b, int(math.ceil((b - a) / step)) + 1)
            for a, b in zip(wsm[:-1][act_iv], wsm[1:][act_iv], strict=True)
        ]
        n0 = int(sum(x.size for x in dense)) + wsm.size
        pts = [wsm] + dense
        passive = PassiveBands(sys, wsm[:-1][~act_iv], wsm[1:][~act_iv], W)
    else:
        n0 = int(math.ceil(W / step)) + 1
        pts = [np.linspace(0.0, W, n0)] + pole_pts
    if n_points is not None:
        n0 = max(n0, int(n_points))
        if mode != "factored":
            pts[0] = np.linspace(0.0, W, n0)
    return pts, n0, passive


def certification_grid(p: ComplexArray, W: float) -> FloatArray:
    """The first samples of a certified phase on ``[0, W]`` (rad/s): the ends
    and the frequency of every delay-free pole ``p`` (the poles of ``H``)
    between them.  :func:`certified_phase` adds every further sample where
    its bounds need one, so nothing more is laid in advance: away from the
    resonances a few wide intervals are passive at once, near them the
    bisection reaches the spacing the Lipschitz bound asks for."""
    f = p.imag[(p.imag > 0.0) & (p.imag < W)]
    return np.unique(np.concatenate([[0.0], f, [W]]))


def refine(
    F: Sampler, w: FloatArray, passive: PassiveBands | None
) -> tuple[FloatArray, ComplexArray, NDArray[np.bool_] | None, int]:
    """Bisect every interval whose wrapped phase increment exceeds pi/4 (or
    is not finite), outside the passive intervals, until none is left or the
    intervals are at round-off width.

    Returns ``(w, values, passive flags of the intervals, unresolved)``:
    ``unresolved`` counts intervals at round-off width that still jump (a
    root on the axis).
    """
    tau = F.sys.tau
    passive_iv = passive.flags(w) if passive is not None else None
    val = F(w)
    unresolved = 0
    for _ in range(200):
        ph = np.angle(val)
        d = np.angle(np.exp(1j * (ph[1:] - ph[:-1])))
        bad = ~np.isfinite(d) | (np.abs(d) > _PHASE_STEP)
        if passive_iv is not None:
            bad &= ~passive_iv
        width = w[1:] - w[:-1]
        tiny = width <= 1e-12 * np.maximum(w[1:], 1.0 / tau)
        unresolved = int(np.sum(bad & tiny))
        bad &= ~tiny
        if not np.any(bad) or w.size > MAX_SAMPLES:
            break
        mid = 0.5 * (w[:-1][bad] + w[1:][bad])
        vm = F(mid)
        w = np.concatenate([w, mid])
        val = np.concatenate([val, vm])
        o = np.argsort(w, kind="stable")
        w, val = w[o], val[o]
        passive_iv = passive.flags(w) if passive is not None else None
    return w, val, passive_iv, unresolved


def phase_change(
    w: FloatArray,
    val: ComplexArray,
    passive_iv: NDArray[np.bool_] | None,
    passive: PassiveBands | None,
    tau: float,
) -> tuple[float, float]:
    """``(total, tail)``: the phase change (rad) of F from 0 to infinity, and
    the part of it from the last sample to infinity (where F -> 1).

    Increments between samples are the wrapped differences, except on the
    passive intervals, where they are exact: ``sum_k Arg(1 - mu_k z)`` at
    both ends.  Non-finite increments count 0 (the caller reports them).
    """
    ph = np.angle(val)
    inc = np.angle(np.exp(1j * (ph[1:] - ph[:-1])))
    if passive is not None and passive_iv is not None and np.any(passive_iv):
        ends = np.nonzero(passive_iv)[0]
        idx = np.unique(np.concatenate([ends, ends + 1]))
        mu = passive.mu(w[idx])
        zz = np.exp(-1j * w[idx] * tau)[:, None]
        arg = np.angle(1.0 - mu * zz).sum(axis=1)
        # idx is sorted and holds every end and end + 1: their places in it
        inc[ends] = arg[np.searchsorted(idx, ends + 1)] - arg[np.searchsorted(idx, ends)]
    inc[~np.isfinite(inc)] = 0.0
    total = float(np.sum(inc))
    # remaining phase to infinity: F -> 1
    end = ph[-1] if np.isfinite(ph[-1]) else 0.0
    tail = -float(np.angle(np.exp(1j * end)))
    return total + tail, tail


# ---------------------------------------------------------------------------- the proven count


@dataclass(frozen=True)
class Certificate:
    """What :func:`certified_phase` proved.

    ``total``: the phase change (rad) of ``g`` from 0 to infinity, each
    increment proven; ``tail``: its part beyond ``W``; ``W``: where the proven
    passive tail starts (rad/s); ``w``, ``val``: the samples; ``unresolved``:
    intervals at round-off width left unproven (a root on the axis);
    ``n_passive``, ``n_lipschitz``: intervals proven by each argument.
    """

    total: float
    tail: float
    W: float
    w: FloatArray
    val: ComplexArray
    unresolved: int
    n_passive: int
    n_lipschitz: int
    complete: bool


def _residue_bounds(sys: DelaySystem) -> tuple[ComplexArray, FloatArray, float] | None:
    """``(p, n, s0)``: the poles of ``H = V^T P^{-1} U = sum_k h_k / (lam - p_k)``,
    the norms ``||h_k||_2`` (rank one: ``|L_k| |R_k|``) and ``||sum_k h_k||_2``;
    None without partial fractions."""
    pf = sys.partial_fractions()
    if pf is None:
        return None
    p, L, R = pf
    n = np.linalg.norm(L, axis=0) * np.linalg.norm(R, axis=1)
    s0 = float(np.linalg.norm(L @ R, 2)) if L.size else 0.0
    return p, n, s0


def _interval_bounds(
    p: ComplexArray, n: FloatArray, s0: FloatArray | float, a: FloatArray, b: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Upper bounds of ``||H(j w)||`` and ``||dH/dw||`` over each ``w`` in ``[a_i, b_i]``.

    With ``d_k`` the distance of ``p_k`` from the segment ``j[a, b]``:
    ``||H|| <= min(sum_k n_k / d_k, s0 / a + sum_k n_k |p_k| / (a d_k))`` (the second
    from ``h/(s - p) = h/s + h p / (s (s - p))``) and ``||H'|| <= sum_k n_k / d_k^2``.
    ``p``, ``n``: shape (K,) (one system) or (len(a), K) (each interval its
    own system's), ``s0`` a scalar or (len(a),)."""
    out_h = np.empty(a.size)
    out_d = np.empty(a.size)
    K = p.shape[-1]
    chunk = max(1, 4_000_000 // max(1, K))
    rows = p.ndim == 2
    s0a = np.broadcast_to(np.asarray(s0, dtype=float), a.shape)
    for s in range(0, a.size, chunk):
        sl = slice(s, s + chunk)
        aa, bb = a[sl, None], b[sl, None]
        pp = p[sl] if rows else p[None, :]
        nn = n[sl] if rows else n[None, :]
        dx = np.abs(pp.real)
        dy = np.maximum(np.maximum(aa - pp.imag, pp.imag - bb), 0.0)
        d = np.maximum(np.hypot(dx, dy), 1e-300)
        with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
            h1 = np.sum(nn / d, axis=1)
            h2 = np.where(aa[:, 0] > 0, (s0a[sl] + np.sum(nn * np.abs(pp) / d, axis=1)) / aa[:, 0], np.inf)
            out_h[sl] = np.minimum(h1, h2)
            out_d[sl] = np.sum(nn / d**2, axis=1)
    return out_h, out_d


def _tail_start(p: ComplexArray, n: FloatArray, s0: float, W: float) -> float:
    """The first ``W' >= W`` (doubling) beyond which ``||H(j w)|| < 1/2`` is proven
    for every ``w >= W'``: ``|j w - p_k| >= w - |p_k|``, so ``sum_k n_k / (W' - |p_k|)``
    or ``(s0 + sum_k n_k |p_k| / (W' - |p_k|)) / W'`` (both decrease with ``w``) bounds it."""
    ap = np.abs(p)
    for _ in range(80):
        gap = W - ap
        if np.all(gap > 0):
            b1 = float(np.sum(n / gap))
            b2 = float((s0 + np.sum(n * ap / gap)) / W)
            if min(b1, b2) < 0.5:
                return W
        W *= 2.0
    return math.inf


class _Loops:
    """The factored loops of several systems with the same number of poles K
    and the same rank r, stacked (row c: system c), so that the certification
    handles all their intervals in one pass: poles ``p`` (C, K), residue norms
    ``n`` (C, K), ``s0`` (C,), delays ``tau`` (C,), residues ``LR`` (C, K, r, r)."""

    def __init__(
        self, systems: list[DelaySystem], bounds: list[tuple[ComplexArray, FloatArray, float]]
    ) -> None:
        self.r = systems[0].r
        self.p = np.stack([b[0] for b in bounds])
        self.n = np.stack([b[1] for b in bounds])
        self.s0 = np.array([b[2] for b in bounds])
        self.tau = np.array([sy.tau for sy in systems])
        LR = []
        for sy in systems:
            _, L, R = sy.partial_fractions()  # type: ignore[misc]  # not None: bounds exist
            LR.append(L.T[:, :, None] * R[:, None, :])
        self.LR = np.stack(LR)

    def H(self, w: FloatArray, c: NDArray[np.intp]) -> ComplexArray:
        """H(j w_i) of system c_i, shape (len(w), r, r): the partial fractions."""
        with np.errstate(all="ignore"):
            g = 1.0 / (1j * w[:, None] - self.p[c])
            if self.r == 1:
                return np.sum(g * self.LR[c, :, 0, 0], axis=1)[:, None, None]
            return np.einsum("nk,nkij->nij", g, self.LR[c])

    def X(self, w: FloatArray, c: NDArray[np.intp]) -> ComplexArray:
        """X = H(j w) e^{-j w tau}, shape (len(w), r, r)."""
        with np.errstate(all="ignore"):
            return self.H(w, c) * np.exp(-1j * w * self.tau[c])[:, None, None]

    def g(self, w: FloatArray, c: NDArray[np.intp]) -> ComplexArray:
        """``g = det(I - X)`` (what :class:`Sampler` samples in factored mode)."""
        X = self.X(w, c)
        with np.errstate(all="ignore"):
            if self.r == 1:
                return 1.0 - X[:, 0, 0]
            return np.linalg.det(np.eye(self.r)[None] - X)

    def g_norm(self, w: FloatArray, c: NDArray[np.intp]) -> FloatArray:
        """``||I - X(j w)||_F`` (an upper bound of the spectral norm), r > 1."""
        with np.errstate(all="ignore"):
            return np.linalg.norm(np.eye(self.r)[None] - self.X(w, c), axis=(1, 2))

    def passive_args(self, w: FloatArray, c: NDArray[np.intp]) -> FloatArray:
        """``sum_k Arg(1 - mu_k)``, ``mu_k`` the eigenvalues of ``X(j w)``: the
        continuous phase of ``g`` wherever every ``|mu_k| < 1`` (each factor then
        has a positive real part)."""
        X = self.X(w, c)
        with np.errstate(all="ignore"):
            if self.r == 1:
                mu = X[:, 0, :]
            else:
                mu = np.full(X.shape[:2], np.nan + 0j)
                ok = np.all(np.isfinite(X), axis=(1, 2))
                if np.any(ok):
                    mu[ok] = np.linalg.eigvals(X[ok])
            return np.angle(1.0 - mu).sum(axis=1)


def certified_phase(F: Sampler, w0: FloatArray, W: float) -> Certificate | None:
    r"""The phase change of ``g = det(I_r - X)``, ``X = H(j w) e^{-j w tau}``, from
    ``w = 0`` to infinity, every increment proven (factored mode only; None
    without partial fractions).

    Each interval ``[a, b]`` of the samples is accepted by one of two arguments,
    else bisected:

    * **passive**: ``sup ||H|| < 1`` on it (the bound of
      :func:`_interval_bounds`).  Every eigenvalue ``mu_k`` of ``X`` then lies in
      the unit disc, each factor ``1 - mu_k`` of ``g`` keeps a positive real
      part, so ``sum_k Arg(1 - mu_k)`` is continuous and its end values give the
      increment exactly, however far ``g`` turns.
    * **Lipschitz**: with ``L = sup ||H'|| + tau sup ||H||`` (a bound of
      ``||dX/dw||``, since ``dX/dw = j (H' - tau H) e^{-j w tau}``),
      ``||X(w) - X(a)|| <= L (w - a)``; for ``r x r`` matrices
      ``|det(G + E) - det G| <= (||G|| + ||E||)^r - ||G||^r`` (expand ``det(G + E)``
      by columns and bound each of the ``C(r, k)`` terms with ``k`` columns of
      ``E`` by Hadamard's inequality), so with ``G = I - X(a)``

      .. math:: (\|G\|_F + L (b - a))^r - \|G\|_F^r < |g(a)|

      keeps ``g(w)`` in the open disc about ``g(a)`` of radius ``|g(a)|`` for all
      ``w`` in ``[a, b]``: ``g`` does not vanish and turns by less than ``pi/2``
      there, so the increment is the principal value ``Arg(g(b)/g(a))``.  (The
      same from ``b``.)  This is what catches a double zero next to the axis:
      near it ``|g|`` is small, the bound forces samples a fraction of its
      distance apart, and the ``2 pi`` turn cannot fall between two samples.

    The tail ``[W', inf)`` is passive by :func:`_tail_start` (``W' >= W``); its
    phase is ``-sum_k Arg(1 - mu_k)`` at ``W'``.  Intervals that reach
    round-off width (1e-12 relative) unproven are counted in ``unresolved``:
    a root on the axis, or within ~1e-12 of it.

    The bounds rest on the partial fractions ``H = sum_k h_k / (lam - p_k)`` of
    the delay-free loop, computed in floating point (``cond(S) < 1e8``), and
    ``g`` is evaluated in floating point: the proof is exact up to the round-off
    in the residues and in ``g`` (relative ~1e-12 here), which the criteria do
    not absorb.

    The work is done by :func:`certified_phases`, for one system.
    """
    return certified_phases([(F.sys, w0, W)])[0]


def certified_phases(items: Sequence[tuple[DelaySystem, FloatArray, float]]) -> list[Certificate | None]:
    """:func:`certified_phase` of several systems ``(sys, w0, W)`` at once.

    Each system is certified exactly as alone -- the same samples, bounds and
    decisions (an interval's arithmetic does not depend on the others) -- but
    the bisection rounds run over the open intervals of all the systems
    together (those with the same number of poles and rank), so that a set of
    checks pays the per-round overhead once."""
    out: list[Certificate | None] = [None] * len(items)
    groups: dict[tuple[int, int], list[tuple[int, DelaySystem, FloatArray, float, tuple[Any, ...]]]] = {}
    for i, (sys, w0, W) in enumerate(items):
        rb = _residue_bounds(sys)
        if rb is None:
            continue
        Wt = _tail_start(*rb, W)
        if not math.isfinite(Wt):
            continue
        groups.setdefault((rb[0].size, sys.r), []).append((i, sys, w0, Wt, rb))
    for members in groups.values():
        loops = _Loops([m[1] for m in members], [m[4] for m in members])
        for (i, *_), cert in zip(members, _certify(loops, [(m[2], m[3]) for m in members]), strict=True):
            out[i] = cert
    return out


def _certify(loops: _Loops, starts: list[tuple[FloatArray, float]]) -> list[Certificate]:
    """The bisection of :func:`certified_phase` over the systems of ``loops``,
    their samples concatenated (system by system, each sorted; the "interval"
    from one system's last sample to the next one's first is never open)."""
    ws = []
    for w0, Wt in starts:
        w = np.unique(np.concatenate([w0[w0 < Wt], [Wt]]))
        ws.append(np.r_[0.0, w] if w[0] > 0.0 else w)
    sid = np.concatenate([np.full(x.size, k) for k, x in enumerate(ws)])
    w = np.concatenate(ws)
    val = loops.g(w, sid)
    r = loops.r
    # per interval: 0 open, 1 passive, 2 Lipschitz, 3 unresolved, -1 between two systems
    kind = np.where(sid[1:] == sid[:-1], 0, -1).astype(np.int8)
    for _ in range(200):
        todo = np.nonzero(kind == 0)[0]
        if todo.size:
            over = np.bincount(sid, minlength=len(ws)) > MAX_SAMPLES
            todo = todo[~over[sid[todo]]]
        if todo.size == 0:
            break
        a, b, cs = w[todo], w[todo + 1], sid[todo]
        hb, hd = _interval_bounds(loops.p[cs], loops.n[cs], loops.s0[cs], a, b)
        passive = hb < 1.0
        tau = loops.tau[cs]
        L = hd + tau * hb
        ga, gb = val[todo], val[todo + 1]
        Xa = loops.g_norm(a, cs) if r > 1 else np.abs(ga)
        Xb = loops.g_norm(b, cs) if r > 1 else np.abs(gb)
        with np.errstate(over="ignore", invalid="ignore"):
            h = b - a
            lip = ((Xa + L * h) ** r - Xa**r < np.abs(ga)) | ((Xb + L * h) ** r - Xb**r < np.abs(gb))
        lip &= np.isfinite(ga) & np.isfinite(gb)
        kind[todo[passive]] = 1
        kind[todo[~passive & lip]] = 2
        fail = ~passive & ~lip
        bad = todo[fail]
        tiny = (b - a)[fail] <= 1e-12 * np.maximum(b[fail], 1.0 / tau[fail])
        kind[bad[tiny]] = 3
        split = bad[~tiny]
        if split.size == 0:
            break
        mid = 0.5 * (w[split] + w[split + 1])
        vm = loops.g(mid, sid[split])
        # insert: each split interval becomes two open intervals
        w = np.insert(w, split + 1, mid)
        val = np.insert(val, split + 1, vm)
        sid = np.insert(sid, split + 1, sid[split])
        kind = np.insert(kind, split + 1, 0)
        kind[split + np.arange(split.size)] = 0
    # the increments of all the systems at once (those between two systems dropped)
    C = len(ws)
    inc = np.angle(val[1:] * np.conj(val[:-1]))
    pas = np.nonzero(kind == 1)[0]
    if pas.size:
        ends = np.unique(np.concatenate([pas, pas + 1]))
        arg = loops.passive_args(w[ends], sid[ends])
        inc[pas] = arg[np.searchsorted(ends, pas + 1)] - arg[np.searchsorted(ends, pas)]
    inc[~np.isfinite(inc) | (kind == -1)] = 0.0
    first = np.searchsorted(sid, np.arange(C + 1))
    tails = -loops.passive_args(w[first[1:] - 1], np.arange(C))
    per = sid[:-1]
    total = np.bincount(per, weights=inc, minlength=C) + tails
    count = {k: np.bincount(per[kind == k], minlength=C) for k in (0, 1, 2, 3)}
    out = []
    for c in range(C):
        i0, i1 = int(first[c]), int(first[c + 1])
        out.append(
            Certificate(
                float(total[c]),
                float(tails[c]),
                float(w[i1 - 1]),
                w[i0:i1],
                val[i0:i1],
                int(count[3][c]),
                int(count[1][c]),
                int(count[2][c]),
                not count[0][c],
            )
        )
    return out
