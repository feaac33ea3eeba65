"""The D-subdivision boundary curve, found completely.

At each frequency w the boundary widths are the real beta > 0 with
|nu(beta)| = 1 (see :mod:`chatterlab.lobes._diagram`).  Three things make that set
complete, where sampling beta and w on grids does not:

1. **All widths at one frequency, exactly.**  For a rank-one delayed term
   (chip-thickness regeneration) the matrix determinant lemma gives

       1 + nu(beta) = det(I + beta H (A + O)) / det(I + beta H A)
                    = p_AO(beta) / p_A(beta),

   with p_X(beta) = prod_i (1 + beta mu_i(H X)) from the m eigenvalues of an
   m x m matrix.  Hence |nu| = 1 is the real polynomial equation of degree 2m

       Q(beta) = |p_AO - p_A|^2 - |p_A|^2 = 0,

   whose real roots are all found at once (companion matrix), however close
   together: two boundary widths that merge and vanish between beta samples
   (the "nose" of a lobe that the old bracketing missed) are two roots of Q.
   For a delayed term of rank r > 1 the same holds for the resultant in z of
   q(beta, z) = det(I + beta H (A + z O)) and its reflection in the unit
   circle, a real polynomial of degree 2 r m (:func:`widths_resultant`).

2. **Folds located.**  Where the number of boundary widths changes between
   two grid frequencies, the boundary curve turns back in w (a fold).  The
   interval is bisected until the fold is located to ~1e-13 relative, so
   the curve is followed around its turning point and the two widths that
   merge there are joined into one branch.  Complex roots of Q close to the
   real axis (a closed boundary curve that could fit between two grid
   frequencies) are refined the same way.

3. **A band that is proven.**  No boundary lies at a frequency where the
   loop gain is below one: det(I + beta H (A + z O)) != 0 whenever
   beta ||H|| (||D_P|| + w ||D_V|| + ||D_O||) < 1.  With the structure in
   pole-residue form H(s) = sum_k R_k / (s - p_k) + D, ||H(jw)|| on an
   interval [a, b] is bounded by

       sum_k ||R_k|| / d_k + ||D||,   or
       ||sum_k R_k|| / a + sum_k ||R_k|| |p_k| / (a d_k) + ||D||,

   d_k the distance of p_k from the segment j[a, b] (the second form uses
   R/(s - p) = R/s + R p / (s (s - p)) and decays like 1/w^2 for a mechanical
   structure, whose residues sum to zero).  Every interval of a geometric
   partition where the bound times beta_max stays below one is certified
   free of boundary points; the searched band is the rest, and beyond the
   partition a monotone tail bound closes it.  The band therefore follows
   from the structure, the feedback matrices and the width ceiling, and the
   certificate is reported.

References
----------
.. [1] R. A. Horn, C. R. Johnson, *Matrix Analysis*, 2nd ed., Cambridge
   University Press, 2013 (the determinant lemma; rho(X) <= ||X||).
.. [2] T. Insperger, G. Stepan, *Semi-Discretization for Time-Delay
   Systems*, Springer, 2011, sec. 1.3 (D-subdivision method).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

LOG_SPAN = 9.0  #: decades of width searched below the width ceiling
_X_MAX = 1.0 + 1e-9  #: beta / beta_max accepted (the ceiling itself included)
_FOLD_REL = 1e-13  #: folds are located to this relative frequency
_CLUSTER = 1e-2  #: |Im x| / |Re x| of a resultant root treated as a scattered root of a cluster
_BISECT_DEPTH = 4  #: levels of the fold bisection evaluated in one batch


@dataclass(frozen=True)
class Ops:
    """Per-frequency operators of the boundary equation (reference width)."""

    omega: np.ndarray  # (N,)
    HA: np.ndarray  # (N, m, m)  H (P + jw V)
    HU: np.ndarray  # (N, m, r)
    Vt: np.ndarray  # (r, m)


def delayed_factors(Dl_O: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """D_O = U V^T with U (m, r), V^T (r, m), r its numerical rank."""
    u, sv, vt = np.linalg.svd(Dl_O)
    r = int(np.sum(sv > 1e-12 * max(sv[0], 1e-300)))
    return u[:, :r] * sv[:r], vt[:r]


def make_ops(
    H: Any,
    Dl_P: np.ndarray,
    Dl_V: np.ndarray,
    Dl_O: np.ndarray,
    omega: np.ndarray,
    factors: tuple[np.ndarray, np.ndarray] | None = None,
) -> Ops:
    """Operators H A and H U at the frequencies ``omega`` (rad/s);
    ``factors``: :func:`delayed_factors` of ``Dl_O`` when already known."""
    Hw = H(omega)
    A = Dl_P[None] + 1j * omega[:, None, None] * Dl_V[None]
    Uo, Vt = delayed_factors(Dl_O) if factors is None else factors
    return Ops(omega, Hw @ A, Hw @ Uo, Vt)


def nu(ops: Ops, beta: np.ndarray, idx: np.ndarray | None = None) -> np.ndarray:
    """Eigenvalues of N(beta) (..., r), sorted by magnitude; ``beta`` has
    shape (N, K) (or (len(idx), K) with ``idx`` selecting frequencies)."""
    HA = ops.HA if idx is None else ops.HA[idx]
    HU = ops.HU if idx is None else ops.HU[idx]
    m = HA.shape[-1]
    Mx = np.eye(m) + beta[..., None, None] * HA[:, None]
    if HU.shape[-1] == 1 and m <= 3:
        # rank one: nu = beta V^T (I + beta H A)^-1 H U by the adjugate
        y = np.broadcast_to(HU[:, None, :, 0], Mx.shape[:-1])
        return beta[..., None] * (_solve_small(Mx, y) @ ops.Vt[0])[..., None]
    X = np.linalg.solve(Mx, np.broadcast_to(HU[:, None], Mx.shape[:-1] + (HU.shape[-1],)))
    Nm = beta[..., None, None] * (ops.Vt @ X)
    if Nm.shape[-1] == 1:
        return Nm[..., 0, :]
    ev = np.linalg.eigvals(Nm)
    return np.take_along_axis(ev, np.argsort(np.abs(ev), axis=-1), axis=-1)


def _solve_small(M: np.ndarray, y: np.ndarray) -> np.ndarray:
    """x = M^-1 y for stacks of m x m matrices, m <= 3, by the adjugate
    (Cramer's rule): x = adj(M) y / det(M), a few dozen flops per matrix
    instead of a LAPACK call each.  For the well-conditioned I + beta H A of
    the boundary (no delay-free instability below the ceiling) its error is
    that of Gaussian elimination, ~cond(M) eps [Higham, Accuracy and
    Stability of Numerical Algorithms, 2nd ed., 2002, sec. 1.10.1]."""
    m = M.shape[-1]
    if m == 1:
        return y / M[..., 0, :]
    if m == 2:
        a, b, c, d = M[..., 0, 0], M[..., 0, 1], M[..., 1, 0], M[..., 1, 1]
        det = a * d - b * c
        return (
            np.stack([d * y[..., 0] - b * y[..., 1], a * y[..., 1] - c * y[..., 0]], axis=-1) / det[..., None]
        )
    a, b, c = M[..., 0, 0], M[..., 0, 1], M[..., 0, 2]
    d, e, f = M[..., 1, 0], M[..., 1, 1], M[..., 1, 2]
    g, h, i = M[..., 2, 0], M[..., 2, 1], M[..., 2, 2]
    A, B, C = e * i - f * h, f * g - d * i, d * h - e * g  # cofactors of the first row
    det = a * A + b * B + c * C
    y0, y1, y2 = y[..., 0], y[..., 1], y[..., 2]
    x0 = A * y0 + (c * h - b * i) * y1 + (b * f - c * e) * y2
    x1 = B * y0 + (a * i - c * g) * y1 + (c * d - a * f) * y2
    x2 = C * y0 + (b * g - a * h) * y1 + (a * e - b * d) * y2
    return np.stack([x0, x1, x2], axis=-1) / det[..., None]


# ---------------------------------------------------------------------------- widths at one frequency


def _poly_from_roots(ev: np.ndarray) -> np.ndarray:
    """Coefficients (ascending powers) of prod_i (1 + x ev_i), shape (N, m+1)."""
    N, m = ev.shape
    c = np.zeros((N, m + 1), dtype=complex)
    c[:, 0] = 1.0
    for i in range(m):
        c[:, 1:] = c[:, 1:] + ev[:, i : i + 1] * c[:, :-1].copy()
    return c


def _conv_conj(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Coefficients of a(x) conj(b(x)) for real x (ascending), shape (N, 2m+1)."""
    N, n = a.shape
    out = np.zeros((N, 2 * n - 1), dtype=complex)
    bc = b.conj()
    for i in range(n):
        out[:, i : i + n] += a[:, i : i + 1] * bc
    return out


def _real_poly_roots(c: np.ndarray) -> np.ndarray:
    """All complex roots of real polynomials (ascending coefficients, (N, d+1)).

    Returns roots (N, d), NaN-padded where a row has lower degree.  Leading
    coefficients below 1e-8 of the row's largest are dropped: their roots lie
    beyond ~1e8 (the widths wanted are in (0, 1]), and a companion matrix
    holding them would lose the small roots to its norm; the roots in range
    move by ~1e-8 relative, which :func:`_polish_rows` removes on the full
    polynomial.  Each degree is solved batched by its companion matrix."""
    N, d1 = c.shape
    d = d1 - 1
    scale = np.max(np.abs(c), axis=1, keepdims=True)
    scale[scale == 0] = 1.0
    c = c / scale
    big = np.abs(c) > 1e-8
    deg = np.where(big.any(axis=1), d - np.argmax(big[:, ::-1], axis=1), 0)
    out = np.full((N, d), np.nan + 0j)
    for k in np.unique(deg):
        if k == 0:
            continue
        rows = np.nonzero(deg == k)[0]
        ck = c[rows, : k + 1]
        comp = np.zeros((rows.size, k, k))
        if k > 1:
            comp[:, 1:, :-1] = np.eye(k - 1)
        comp[:, :, -1] = -ck[:, :-1] / ck[:, k : k + 1]
        with np.errstate(all="ignore"):
            out[rows, :k] = np.linalg.eigvals(comp)
    return out


def widths_rank1(
    ops: Ops, beta_max: float | np.ndarray, screen: bool = True
) -> tuple[list[np.ndarray], np.ndarray]:
    """All boundary widths x = beta / beta_max in (10^-LOG_SPAN, 1] at each
    frequency, for a rank-one delayed term, plus the smallest relative
    distance of a complex root of Q from the real segment (for refinement).

    Frequencies where :func:`_no_root_near_segment` proves that Q has no root
    near [-0.05, 1.05] (most of a grid: there the loop gain stays small up
    to the ceiling) have no width and proximity inf, without the companion
    matrix; every other frequency takes the route below, each row's
    arithmetic the same whatever the other rows are.  ``screen=False``
    skips that test (the caller knows every frequency has a width near).

    Returns (list of sorted x per frequency, near-real proximity (N,): exact
    where it is below 0.05, the only use made of it; inf or >= 0.05 above)."""
    N = ops.omega.size
    bm = np.broadcast_to(np.asarray(beta_max, dtype=float), ops.omega.shape)[:, None, None]
    HA = ops.HA * bm
    HAO = HA + bm * (ops.HU @ ops.Vt)
    out: list[np.ndarray] = [_EMPTY] * N
    prox = np.full(N, np.inf)
    if not screen:
        rows = np.arange(N)
    elif HA.shape[-1] <= 3:
        coarse = _q_coefficients(_char_poly(HA), _char_poly(HAO))
        rows = np.nonzero(~_no_root_near_segment(coarse))[0]
    else:
        rows = np.arange(N)
    if rows.size == 0:
        return out, prox
    if HA.shape[-1] <= 3:
        Q = _q_coefficients(_char_poly(HA[rows]), _char_poly(HAO[rows]))
    else:
        lam = np.linalg.eigvals(HA[rows])
        mu = np.linalg.eigvals(HAO[rows])
        Q = _q_coefficients(_poly_from_roots(lam), _poly_from_roots(mu))
    if screen and HA.shape[-1] > 3:
        keep = ~_no_root_near_segment(Q)
        rows, Q = rows[keep], Q[keep]
        if rows.size == 0:
            return out, prox
    roots = _real_poly_roots(Q)
    xlo = 10.0**-LOG_SPAN
    with np.errstate(invalid="ignore"):
        near_real = np.abs(roots.imag) <= 1e-7 * np.maximum(np.abs(roots.real), xlo)
        inside = (roots.real > xlo) & (roots.real <= _X_MAX)
    for i, x in zip(rows, _polish_rows(Q, roots, near_real & inside), strict=True):
        out[i] = x
    with np.errstate(invalid="ignore"):
        cand = ~near_real & (roots.real > -0.05) & (roots.real < 1.05)
        pr = np.where(cand, np.abs(roots.imag) / np.maximum(np.abs(roots.real), 0.05), np.inf)
    prox[rows] = np.min(pr, axis=1)
    return out, prox


_EMPTY = np.zeros(0)
_EMPTY.flags.writeable = False  #: the widths of a frequency without any (shared, read-only)


def _q_coefficients(pA: np.ndarray, pB: np.ndarray) -> np.ndarray:
    """Q = |p_B - p_A|^2 - |p_A|^2 on the real axis (ascending, (N, 2m+1))
    from the coefficients of p_A and p_B = p_AO."""
    d = pB - pA
    return (_conv_conj(d, d) - _conv_conj(pA, pA)).real


def _char_poly(X: np.ndarray) -> np.ndarray:
    """Coefficients (ascending) of det(I + x X) for a stack of m x m
    matrices, m <= 3, in closed form: 1, the trace, the sum of the principal
    2 x 2 minors, the determinant (the elementary symmetric functions of the
    eigenvalues [1], without computing them)."""
    N, m = X.shape[0], X.shape[-1]
    c = np.zeros((N, m + 1), dtype=complex)
    c[:, 0] = 1.0
    c[:, 1] = np.trace(X, axis1=1, axis2=2)
    if m >= 2:
        a, b = X[:, 0, 0], X[:, 1, 1]
        c2 = a * b - X[:, 0, 1] * X[:, 1, 0]
        if m == 3:
            e = X[:, 2, 2]
            c2 = c2 + a * e - X[:, 0, 2] * X[:, 2, 0] + b * e - X[:, 1, 2] * X[:, 2, 1]
            c[:, 3] = (
                a * (b * e - X[:, 1, 2] * X[:, 2, 1])
                - X[:, 0, 1] * (X[:, 1, 0] * e - X[:, 1, 2] * X[:, 2, 0])
                + X[:, 0, 2] * (X[:, 1, 0] * X[:, 2, 1] - b * X[:, 2, 0])
            )
        c[:, 2] = c2
    return c


#: discs that cover the region where a root of Q matters, R = [-0.05, 1.05] x
#: [-0.0525, 0.0525] (the real roots in (1e-9, 1] and the complex ones with
#: proximity below 0.05): four centres on the real axis, radius 1.01 hypot(h, 0.0525)
_DISC_H = 1.1 / 8
_DISCS = -0.05 + _DISC_H * np.arange(1, 8, 2)
_DISC_R = 1.01 * float(np.hypot(_DISC_H, 0.0525))
_SCREEN_MARGIN = 1e-6


def _no_root_near_segment(q: np.ndarray) -> np.ndarray:
    """Rows of real polynomials (ascending coefficients) proven to have no
    root in any of the discs ``_DISCS`` (radius ``_DISC_R``), which cover
    the region R where :func:`widths_rank1` uses a root.

    The test is the one :func:`_real_poly_roots` would face: each row scaled
    to max |c| = 1 and its negligible leading coefficients dropped.  Shifted
    to a disc's centre, c(x0 + y) = sum_k e_k y^k, and |c| >= |e_0| -
    sum_{k>=1} |e_k| r^k on the disc; the row passes when that exceeds
    ``_SCREEN_MARGIN`` sum_k |c_k| 1.2^k on every disc.  The margin covers what
    separates this polynomial from the one whose companion matrix would be
    solved: the round-off between the two routes to Q (~1e-15, closed-form
    coefficients or eigenvalues), a leading coefficient on the other side of
    the 1e-8 cut (<= 1e-8 per coefficient, times sum 1.2^k < 12 on the discs,
    |x| <= 1.2), the companion eigenvalues' backward error (~1e-16 in these
    units) and the round-off of the shift itself (~1e-15): a polynomial that
    far from this one has no root there either."""
    N, d1 = q.shape
    scale = np.max(np.abs(q), axis=1, keepdims=True)
    ok = np.all(np.isfinite(q), axis=1) & (scale[:, 0] > 0)
    c = q / np.where(scale > 0, scale, 1.0)
    big = np.abs(c) > 1e-8
    deg = np.where(big.any(axis=1), d1 - 1 - np.argmax(big[:, ::-1], axis=1), 0)
    c = np.where(np.arange(d1)[None, :] <= deg[:, None], c, 0.0)
    with np.errstate(invalid="ignore", over="ignore"):
        need = _SCREEN_MARGIN * (np.abs(c) @ (1.2 ** np.arange(d1)))
        e = np.abs(c @ _shift_matrix(d1)).reshape(N, _DISCS.size, d1)  # |e_k| at each disc
        lower = e[:, :, 0] - e[:, :, 1:] @ (_DISC_R ** np.arange(1, d1))
        ok &= np.all(lower > need[:, None], axis=1)
    return ok


def no_root_in_disc(q: np.ndarray, centre: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Rows of polynomials (ascending coefficients) proven to have no root
    in the disc |x - centre| <= radius (one disc per row): shifted to the
    centre, c(centre + y) = sum_k e_k y^k, and |c| >= |e_0| - sum_{k>=1}
    |e_k| r^k there, which must exceed ``_SCREEN_MARGIN`` sum_k |c_k| (|centre|
    + r)^k (the round-off of the coefficients and of the shift, relative to
    the polynomial's size on the disc, far below it)."""
    N, d1 = q.shape
    k = np.arange(d1)
    # e_k = sum_j c_j binom(j, k) x0^(j - k), the Taylor coefficients at x0
    binom = np.array([[math.comb(int(a), int(b)) for b in k] for a in k], dtype=float)
    expo = k[:, None] - k[None, :]
    with np.errstate(invalid="ignore", over="ignore"):
        S = np.where(expo >= 0, binom * centre[:, None, None] ** np.maximum(expo, 0), 0.0)  # (N, j, k)
        e = np.abs(np.einsum("nj,njk->nk", q, S))
        r = radius[:, None] ** k[None, 1:]
        lower = e[:, 0] - np.sum(e[:, 1:] * r, axis=1)
        need = _SCREEN_MARGIN * np.sum(np.abs(q) * (np.abs(centre) + radius)[:, None] ** k[None, :], axis=1)
        return np.isfinite(lower) & (lower > need)


def near_root(ops: Ops, beta_max: np.ndarray, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For a rank-one term, the root x of Q (in x = beta / beta_max, as
    :func:`widths_rank1`) that Newton reaches from ``x0``, and whether it is
    proven the root of Q nearest ``x0`` in log x: no other root of Q (real or
    complex) lies in the disc about ``x0`` that holds every point at most as
    far in log (radius 1.01 x0 (e^d - 1), d = |log(x / x0)|, and at least
    1e-6 x0), by :func:`no_root_in_disc` on Q / (x - x*).  Newton as in
    :func:`_polish_rows` (steps capped at 5 %, Horner on Q and Q'), at most
    16 steps, converged when the step is below 1e-15 relative."""
    bm = np.asarray(beta_max, dtype=float)[:, None, None]
    HA = ops.HA * bm
    Q = _q_coefficients(_char_poly(HA), _char_poly(HA + bm * (ops.HU @ ops.Vt)))
    N, d1 = Q.shape
    p = Q[:, ::-1]
    dp = p[:, :-1] * np.arange(d1 - 1, 0, -1)
    x = np.array(x0, dtype=float)
    conv = np.zeros(N, bool)
    for _ in range(16):
        f = np.zeros(N)
        for c in p.T:
            f = f * x + c
        g = np.zeros(N)
        for c in dp.T:
            g = g * x + c
        with np.errstate(all="ignore"):
            step = np.where(g != 0, f / g, 0.0)
        step = np.clip(np.nan_to_num(step), -0.05 * np.abs(x), 0.05 * np.abs(x))
        x = x - step
        conv = np.abs(step) <= 1e-15 * np.abs(x)
        if np.all(conv):
            break
    # deflate: Q(x) = (x - x*) q(x) + remainder (synthetic division, descending)
    quot = np.zeros((N, d1 - 1))
    acc = np.zeros(N)
    for j in range(d1 - 1):
        acc = acc * x + p[:, j]
        quot[:, j] = acc
    q_asc = quot[:, ::-1]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        d = np.abs(np.log(x / x0))
        radius = np.maximum(1.01 * np.abs(x0) * np.expm1(d), 1e-6 * np.abs(x0))
    sure = conv & np.isfinite(x) & (x > 0) & no_root_in_disc(q_asc, np.asarray(x0, float), radius)
    return x, sure


def _shift_matrix(d1: int) -> np.ndarray:
    """(d1, n_discs d1): c @ S gives, for each disc centre x0, the coefficients
    of c(x0 + y) in y (ascending): e_k = sum_j c_j binom(j, k) x0^(j - k)."""
    if d1 not in _SHIFTS:
        j = np.arange(d1)
        binom = np.array([[math.comb(int(a), int(b)) for b in j] for a in j], dtype=float)  # (j, k)
        expo = j[:, None] - j[None, :]
        S = [np.where(expo >= 0, binom * float(x0) ** np.maximum(expo, 0), 0.0) for x0 in _DISCS]
        _SHIFTS[d1] = np.concatenate(S, axis=1)
    return _SHIFTS[d1]


_SHIFTS: dict[int, np.ndarray] = {}


def _polish_rows(q: np.ndarray, roots: np.ndarray, take: np.ndarray) -> list[np.ndarray]:
    """Newton on the full polynomials (ascending coefficients, one per row of
    ``q``) from the real parts of the companion-matrix roots selected by
    ``take``; steps are capped at 5 % of x (a start near a double root only
    creeps, never jumps to another root).  A row stops when all its steps
    fall below 1e-15 relative (at most 8 steps).  All rows at once: the
    arithmetic of each row is that of :func:`numpy.polyval` (Horner) on it
    alone.  Returns the sorted polished roots of each row."""
    n, d1 = q.shape
    counts = take.sum(axis=1)
    width = int(counts.max(initial=0))
    if width == 0:
        return [_EMPTY] * n
    # the selected roots packed left, sorted, NaN-padded: x (n, width)
    key = np.where(take, roots.real, np.inf)
    x = np.sort(key, axis=1)[:, :width]
    valid = np.arange(width)[None, :] < counts[:, None]
    x = np.where(valid, x, np.nan)
    p = q[:, ::-1]  # descending, as numpy.polyval
    dp = p[:, :-1] * np.arange(d1 - 1, 0, -1)
    active = counts > 0
    for _ in range(8):
        rows = np.nonzero(active)[0]
        if rows.size == 0:
            break
        xr = x[rows]
        f = np.zeros_like(xr)
        for c in p[rows].T:
            f = f * xr + c[:, None]
        g = np.zeros_like(xr)
        for c in dp[rows].T:
            g = g * xr + c[:, None]
        with np.errstate(all="ignore"):
            step = np.where(g != 0, f / g, 0.0)
        step = np.clip(np.nan_to_num(step), -0.05 * np.abs(xr), 0.05 * np.abs(xr))
        x[rows] = xr - step
        with np.errstate(invalid="ignore"):
            done = np.all((np.abs(step) <= 1e-15 * np.abs(x[rows])) | ~valid[rows], axis=1)
        active[rows[done]] = False
    x = np.sort(np.where(valid, x, np.inf), axis=1)  # each row's polished roots, sorted, inf-padded
    return [x[i, : counts[i]] if counts[i] else _EMPTY for i in range(n)]


def _sylvester_det(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """det of the Sylvester matrices of polynomial pairs (ascending
    coefficients, shape (..., r+1) each): their resultant up to sign."""
    r = a.shape[-1] - 1
    S = np.zeros(a.shape[:-1] + (2 * r, 2 * r), dtype=complex)
    for i in range(r):
        S[..., i, i : i + r + 1] = a[..., ::-1]
        S[..., r + i, i : i + r + 1] = b[..., ::-1]
    return np.linalg.det(S)


def _secant_on_nu(
    ops: Ops, beta_max: float, xs: list[np.ndarray], index: int | None = None
) -> list[np.ndarray]:
    """Refine candidate widths ``xs[k]`` at each frequency k of ``ops`` on
    f(x) = log|nu_j(x beta_max)| of the eigenvalue nearest the unit circle
    (secant, 8 steps); keep those where |f| < 1e-9 (a resultant root whose
    common z is off the circle, or a spurious one, fails this).  With
    ``index`` = j: on the j-th smallest |nu| instead (a continuous function of
    x, which two close eigenvalues do not make switch).

    All frequencies at once: the candidates are packed in rows (padded with
    x = 1, masked), and a frequency stops stepping once all its |f| < 1e-13,
    as it did when each was refined alone (the arithmetic of every entry is
    that of the one-frequency loop)."""
    N = len(xs)
    width = max((x.size for x in xs), default=0)
    if width == 0:
        return [np.zeros(0) for _ in range(N)]
    valid = np.arange(width)[None, :] < np.array([x.size for x in xs])[:, None]
    x1 = np.ones((N, width))
    for k, x in enumerate(xs):
        x1[k, : x.size] = x

    def f(xx: np.ndarray, rows: np.ndarray) -> np.ndarray:
        v = nu(ops, beta_max * xx, rows)
        with np.errstate(
            divide="ignore"
        ):  # a zero eigenvalue of a rank-deficient N: -inf, never the nearest to 0
            g = np.log(np.abs(v))
        if index is not None:
            return g[..., index]
        return np.take_along_axis(g, np.argmin(np.abs(g), axis=-1)[..., None], axis=-1)[..., 0]

    rows = np.nonzero([x.size > 0 for x in xs])[0]
    x0 = x1 * (1 - 1e-7)
    f0 = np.zeros((N, width))
    f1 = np.zeros((N, width))
    f0[rows], f1[rows] = f(x0[rows], rows), f(x1[rows], rows)
    for _ in range(8):
        if rows.size == 0:
            break
        a0, a1, g0, g1 = x0[rows], x1[rows], f0[rows], f1[rows]
        with np.errstate(all="ignore"):
            step = np.where(g1 != g0, g1 * (a1 - a0) / (g1 - g0), 0.0)
        step = np.clip(np.nan_to_num(step), -0.01 * a1, 0.01 * a1)
        x0[rows], f0[rows] = a1, g1
        x1[rows] = a1 - step
        f1[rows] = f(x1[rows], rows)
        done = np.all((np.abs(f1[rows]) < 1e-13) | ~valid[rows], axis=1)
        rows = rows[~done]
    keep = (np.abs(f1) < 1e-9) & valid
    return [np.unique(x1[k][keep[k]]) for k in range(N)]


def widths_resultant(ops: Ops, beta_max: float) -> tuple[list[np.ndarray], np.ndarray]:
    """All boundary widths x = beta / beta_max in (10^-LOG_SPAN, 1] for a
    delayed term of rank r > 1, exactly.

    With q(beta, z) = det(I + beta H (A + z O)) = d(beta) det(I_r + z N(beta)),
    d = det(I + beta H A), a boundary point is a real beta at which q(beta, .)
    has a root z on the unit circle, i.e. a common root of q(beta, z) and its
    reflection z^r conj(q(beta, 1/conj z)).  Their resultant R(beta) (Sylvester
    determinant) is a polynomial of degree <= 2 r m in beta; it is sampled on
    2 r m + 1 points of the unit circle (in x) and interpolated by the FFT, and
    its real roots are the candidates (the circle is repeated at radii
    10^0, 10^-1.5, ... so that small widths are resolved too).  A candidate is
    kept when an eigenvalue
    of N has |nu| = 1 there (a common root off the circle, z0 and 1/conj z0,
    is dropped).  For r = 1 this is :func:`widths_rank1`'s Q."""
    N = ops.omega.size
    r = ops.Vt.shape[0]
    found: list[list[np.ndarray]] = [[] for _ in range(N)]
    loose: list[list[np.ndarray]] = [[] for _ in range(N)]
    prox = np.full(N, np.inf)
    # the coefficients interpolated on a circle of radius rho are accurate
    # relative to the polynomial's size on that circle: each radius serves the
    # roots within a factor 10^0.75 of it
    for e in np.arange(0.0, -LOG_SPAN - 0.01, -1.5):
        rho = 10.0**e
        roots, pr = _resultant_roots(ops, beta_max * rho)
        x = roots * rho
        lo = max(rho * 10.0**-0.75, 10.0**-LOG_SPAN)
        hi = _X_MAX if e == 0.0 else rho * 10.0**0.75
        with np.errstate(invalid="ignore"):
            near_real = np.abs(x.imag) <= 1e-6 * np.abs(x.real)
            inside = (x.real > lo) & (x.real <= hi)
            # a cluster of roots (two eigenvalues of N on the circle at nearly
            # the same width: R vanishes to fourth order there) scatters its
            # computed roots off the real axis by ~(round-off)^(1/4)
            cluster = ~near_real & (np.abs(x.imag) <= _CLUSTER * np.abs(x.real)) & inside
        for i in np.nonzero(np.any(near_real & inside, axis=1))[0]:
            found[i].append(x[i, near_real[i] & inside[i]].real)
        for i in np.nonzero(np.any(cluster, axis=1))[0]:
            loose[i].append(x[i, cluster[i]].real)
        if e == 0.0:
            prox = pr
    cands = [np.sort(np.concatenate(found[k])) if found[k] else np.zeros(0) for k in range(N)]
    main = _secant_on_nu(ops, beta_max, cands)
    rows = [k for k in range(N) if loose[k]]
    if rows:
        # at a cluster: every candidate, the loose ones too, refined on each
        # sorted |nu_j| in turn (the eigenvalue nearest the circle switches
        # between two close ones); widths the main pass has are not added again
        sub = Ops(ops.omega[rows], ops.HA[rows], ops.HU[rows], ops.Vt)
        cl = [np.sort(np.concatenate([cands[k], *loose[k]])) for k in rows]
        extra = [_secant_on_nu(sub, beta_max, cl, index=j) for j in range(r)]
        for pos, k in enumerate(rows):
            x = np.unique(np.concatenate([e[pos] for e in extra]))
            have = main[k]
            if have.size and x.size:
                near = np.min(np.abs(x[:, None] - have[None, :]), axis=1) <= 1e-9 * x
                x = x[~near]
            if x.size:
                x = x[np.r_[True, np.diff(x) > 1e-9 * x[1:]]]
                main[k] = np.sort(np.concatenate([have, x]))
    out = []
    for x in main:
        # one width found from two circles: keep one
        out.append(x[np.r_[True, np.diff(x) > 1e-9 * x[1:]]] if x.size else x)
    return out, prox


def _resultant_roots(ops: Ops, beta_r: float) -> tuple[np.ndarray, np.ndarray]:
    """Roots y of R(beta_r y) (see :func:`widths_resultant`), (N, 2 r m), and
    the proximity of complex roots to the real segment (0, 1]."""
    N, m = ops.omega.size, ops.HA.shape[-1]
    r = ops.Vt.shape[0]
    K = 2 * r * m + 1
    beta = beta_r * np.exp(2j * np.pi * np.arange(K) / K)
    Mx = np.eye(m) + beta[None, :, None, None] * ops.HA[:, None]  # (N, K, m, m)
    d = np.linalg.det(Mx)
    X = np.linalg.solve(Mx, np.broadcast_to(ops.HU[:, None], Mx.shape[:-1] + (r,)))
    Nm = beta[None, :, None, None] * (ops.Vt @ X)  # (N, K, r, r)
    ev = np.linalg.eigvals(Nm).reshape(N * K, r)
    a = _poly_from_roots(ev).reshape(N, K, r + 1) * d[..., None]  # q's z-coefficients
    b = np.conj(a[:, (-np.arange(K)) % K, ::-1])  # z^r conj(q(conj beta, 1/conj z))
    coef = np.fft.fft(_sylvester_det(a, b), axis=1) / K  # ascending powers of y
    scale = np.max(np.abs(coef), axis=1, keepdims=True)
    scale[scale == 0] = 1.0
    roots = _real_poly_roots((coef / scale).real)
    with np.errstate(invalid="ignore"):
        cand = (np.abs(roots.imag) > 1e-6 * np.abs(roots.real)) & (roots.real > -0.05) & (roots.real < 1.05)
        prox = np.where(cand, np.abs(roots.imag) / np.maximum(np.abs(roots.real), 0.05), np.inf)
    return roots, np.min(prox, axis=1)


def widths(ops: Ops, beta_max: float) -> tuple[list[np.ndarray], np.ndarray]:
    """Boundary widths (relative to beta_max) at each frequency of ``ops``."""
    if ops.Vt.shape[0] == 1:
        return widths_rank1(ops, beta_max)
    return widths_resultant(ops, beta_max)


# ---------------------------------------------------------------------------- folds and branches


def refine_folds(
    make: Any, omega: np.ndarray, beta_max: float, max_rounds: int = 48
) -> tuple[np.ndarray, list[np.ndarray], int]:
    """Grid frequencies plus bisection points at every change of the number of
    boundary widths (folds of the curve) and near-real complex roots of Q.

    ``make(omega)`` returns the operators at given frequencies.  Returns the
    sorted frequencies, the widths at each, and the number of folds located.
    """
    w = np.asarray(omega, float)
    xs, prox = widths(make(w), beta_max)
    counts = np.array([x.size for x in xs])
    folds = 0
    # near-real complex roots: a boundary curve could appear between samples
    lo_w, hi_w = w[:-1], w[1:]
    suspect = (counts[:-1] != counts[1:]) | (np.minimum(prox[:-1], prox[1:]) < 0.05)
    A, B = lo_w[suspect], hi_w[suspect]
    cA, cB = counts[:-1][suspect], counts[1:][suspect]
    folds = int(np.sum(cA != cB))
    new_w: list[np.ndarray] = []
    new_x: list[np.ndarray] = []
    levels = 0
    while A.size and levels < max_rounds:
        # the next ``depth`` levels of every interval's bisection, all at once:
        # the midpoints of the complete binary tree below it (node n has the
        # children 2n + 1, 2n + 2), evaluated in one batch; then the bisection
        # is walked level by level exactly as one midpoint per round would be
        # (the same points, the same decisions), and the points it does not
        # visit are dropped.  A row's widths do not depend on the other rows.
        depth = min(_BISECT_DEPTH, max_rounds - levels)
        nodes = 2**depth - 1
        lo = np.empty((A.size, nodes))
        hi = np.empty((A.size, nodes))
        mid = np.empty((A.size, nodes))
        lo[:, 0], hi[:, 0] = A, B
        for n in range(nodes):
            mid[:, n] = 0.5 * (lo[:, n] + hi[:, n])
            if 2 * n + 2 < nodes:
                lo[:, 2 * n + 1], hi[:, 2 * n + 1] = lo[:, n], mid[:, n]
                lo[:, 2 * n + 2], hi[:, 2 * n + 2] = mid[:, n], hi[:, n]
        flat = mid.ravel()
        xt, _ = widths(make(flat), beta_max)
        ct = np.array([x.size for x in xt]).reshape(mid.shape)
        item = np.arange(A.size)
        node = np.zeros(A.size, int)
        for _level in range(depth):
            if A.size == 0:
                break
            M = mid[item, node]
            cm = ct[item, node]
            new_w.append(M)
            new_x.extend(xt[k] for k in item * nodes + node)
            # keep the half (or halves) where the count changes; a proximity-only
            # interval (the count the same at both ends and the midpoint) gets its
            # midpoint, once: it used to be kept whole, and so re-evaluated at the
            # same midpoint up to max_rounds times, adding nothing (the grid is the
            # same), which made a loop with persistent near-real complex roots of
            # the resultant (close or coincident eigenvalues of N) 48x slower
            goL = cm != cA
            goR = cm != cB
            keepA = np.concatenate([A[goL], M[goR]])
            keepB = np.concatenate([M[goL], B[goR]])
            kcA = np.concatenate([cA[goL], cm[goR]])
            kcB = np.concatenate([cm[goL], cB[goR]])
            kitem = np.concatenate([item[goL], item[goR]])
            knode = np.concatenate([2 * node[goL] + 1, 2 * node[goR] + 2])
            sel = (keepB - keepA) > _FOLD_REL * keepB
            A, B, cA, cB = keepA[sel], keepB[sel], kcA[sel], kcB[sel]
            item, node = kitem[sel], knode[sel]
            levels += 1
    if new_w:
        w = np.concatenate([w, *new_w])
        xs = xs + new_x
    order = np.argsort(w, kind="stable")
    w = w[order]
    xs = [xs[i] for i in order]
    keep = np.concatenate([[True], np.diff(w) > 0])
    return w[keep], [xs[i] for i in np.nonzero(keep)[0]], folds


def link(xs: list[np.ndarray]) -> list[list[tuple[int, int]]]:
    """Chains of (frequency index, root index) through consecutive
    frequencies, joined at folds.

    Between neighbouring frequencies the widths are matched by least total
    |log| distance (in order when the counts agree).  Two chains that end (or
    start) at the same frequency with adjacent widths meet at a fold and are
    joined into one branch that turns back in frequency."""
    n = len(xs)
    none = np.zeros(0, int)
    chain_of: list[np.ndarray] = [np.full(x.size, -1) if x.size else none for x in xs]
    chains: list[list[tuple[int, int]]] = []
    for j in range(xs[0].size):
        chain_of[0][j] = len(chains)
        chains.append([(0, j)])
    ends: list[tuple[int, int, int]] = []  # (freq index, kind 0=end/1=start, chain) at unmatched points
    for i in range(1, n):
        a, b = xs[i - 1], xs[i]
        if a.size == 0 and b.size == 0:
            continue  # most of a grid: no width on either side
        if a.size and b.size:
            if a.size == b.size:
                ra, rb = np.arange(a.size), np.arange(b.size)
            else:
                cost = np.abs(np.log(a)[:, None] - np.log(b)[None, :])
                ra, rb = assignment(cost)
        else:
            ra = rb = np.zeros(0, int)
        for p, q in zip(ra, rb, strict=True):
            c = chain_of[i - 1][p]
            chain_of[i][q] = c
            chains[c].append((i, int(q)))
        if ra.size == a.size and rb.size == b.size:
            continue  # every point matched: no chain ends or starts here
        for p in np.setdiff1d(np.arange(a.size), ra):
            ends.append((i - 1, 0, int(chain_of[i - 1][p])))
        for q in np.setdiff1d(np.arange(b.size), rb):
            chain_of[i][q] = len(chains)
            chains.append([(i, int(q))])
            ends.append((i, 1, len(chains) - 1))
    # joins at folds: two chains ending at the same index with adjacent widths,
    # or two starting at the same index
    joined: list[list[tuple[int, int]]] = []
    used: set[int] = set()
    by_key: dict[tuple[int, int], list[int]] = {}
    for fi, kind, c in ends:
        by_key.setdefault((fi, kind), []).append(c)
    for (fi, kind), cs in by_key.items():
        if len(cs) < 2:
            continue
        # sort the chains by their width at fi, pair neighbours
        pos = sorted(cs, key=lambda c: xs[fi][chains[c][-1 if kind == 0 else 0][1]])
        for c1, c2 in zip(pos[::2], pos[1::2], strict=False):
            if c1 in used or c2 in used:
                continue
            used.update((c1, c2))
            if kind == 0:  # both end here: c1 forward, then c2 backward
                joined.append(chains[c1] + chains[c2][::-1])
            else:  # both start here: c1 backward, then c2 forward
                joined.append(chains[c1][::-1] + chains[c2])
    rest = [ch for k, ch in enumerate(chains) if k not in used]
    return _merge_open(joined + rest)


def assignment(cost: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of a minimum-cost matching of a rectangular cost
    matrix: every row matched when rows <= columns, every column otherwise;
    rows in increasing order (the contract of scipy's
    ``linear_sum_assignment``, whose import costs 0.16 s of the README main
    job for matrices of a few widths).

    The Hungarian method in its shortest-augmenting-path form (Kuhn 1955,
    Munkres 1957; with dual potentials, Tomizawa 1971, Edmonds & Karp 1972):
    rows are added one at a time, each by a Dijkstra search over reduced
    costs ``c[i, j] - u[i] - v[j] >= 0`` that ends at a free column, then the
    path is flipped and the potentials updated.  Exact (a minimum, by
    complementary slackness), O(n^2 m) for n <= m; the costs must be finite.
    tests/test_startup_assignment.py checks it against every permutation.
    """
    c = np.asarray(cost, dtype=float)
    if c.ndim != 2:
        raise ValueError(f"assignment: the cost must be a 2-D matrix (got {c.ndim}-D)")
    if c.shape[0] > c.shape[1]:  # every column matched: the transposed problem
        cols, rows = assignment(c.T)
        order = np.argsort(rows, kind="stable")
        return rows[order], cols[order]
    n, m = c.shape
    u = np.zeros(n + 1)  # row potentials (1-based; 0 is the virtual row)
    v = np.zeros(m + 1)  # column potentials (0: the virtual column)
    row_of = np.zeros(m + 1, dtype=int)  # row matched to each column (0: none)
    for i in range(1, n + 1):
        row_of[0] = i
        j0 = 0
        dist = np.full(m + 1, np.inf)  # shortest reduced path length to each column
        prev = np.zeros(m + 1, dtype=int)  # the column before it on that path
        done = np.zeros(m + 1, dtype=bool)
        while True:
            done[j0] = True
            i0 = row_of[j0]
            red = c[i0 - 1] - u[i0] - v[1:]
            better = ~done[1:] & (red < dist[1:])
            dist[1:][better] = red[better]
            prev[1:][better] = j0
            open_ = np.flatnonzero(~done[1:]) + 1
            j1 = int(open_[np.argmin(dist[open_])])
            delta = dist[j1]
            u[row_of[done]] += delta
            v[done] -= delta
            dist[~done] -= delta
            j0 = j1
            if row_of[j0] == 0:
                break
        while j0:  # flip the augmenting path
            j1 = int(prev[j0])
            row_of[j0] = row_of[j1]
            j0 = j1
    cols = np.flatnonzero(row_of[1:])
    rows = row_of[1:][cols] - 1
    order = np.argsort(rows, kind="stable")
    return rows[order], cols[order]


def _merge_open(chains: list[list[tuple[int, int]]]) -> list[list[tuple[int, int]]]:
    """Join chains that share an end point (a branch with several folds)."""
    changed = True
    while changed:
        changed = False
        for i in range(len(chains)):
            for j in range(i + 1, len(chains)):
                a, b = chains[i], chains[j]
                if a[-1] == b[0]:
                    chains[i] = a + b[1:]
                elif a[-1] == b[-1]:
                    chains[i] = a + b[::-1][1:]
                elif a[0] == b[-1]:
                    chains[i] = b + a[1:]
                elif a[0] == b[0]:
                    chains[i] = b[::-1] + a[1:]
                else:
                    continue
                del chains[j]
                changed = True
                break
            if changed:
                break
    return chains


def static_width(H0: np.ndarray, Dl_P: np.ndarray, Dl_O: np.ndarray, beta_max: float) -> float:
    """Smallest width <= beta_max with a characteristic root at s = 0, from
    det(I + beta H(0) (D_P + D_O)) = 0 (independent of the delay); inf if none."""
    if not np.all(np.isfinite(H0)):
        return float("inf")
    mu = np.linalg.eigvals(H0 @ (Dl_P + Dl_O))
    with np.errstate(divide="ignore", invalid="ignore"):
        b = -1.0 / mu
    ok = (np.abs(b.imag) <= 1e-9 * np.abs(b)) & (b.real > 0) & (b.real <= beta_max)
    return float(np.min(b.real[ok])) if np.any(ok) else float("inf")
