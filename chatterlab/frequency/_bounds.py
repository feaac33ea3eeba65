"""Frequency bands proven free of characteristic roots (gain bounds).

With the structure (or a loop transfer) in pole-residue form
H(s) = sum_k R_k / (s - p_k) + D, no point of the strip Re s >= shift with
Im s in [a, b] can satisfy det(I + beta H (A + z O)) = 0 (|z| <= 1) when
beta ||H|| (||D_P|| + w ||D_V|| + ||D_O||) < 1 there.  ||H|| on the strip is
bounded by sum_k ||R_k|| / d_k + ||D||, or by
||sum_k R_k|| / a + sum_k ||R_k|| |p_k| / (a d_k) + ||D|| (from
R/(s - p) = R/s + R p / (s (s - p)); it decays like 1/w^2 for a mechanical
structure, whose residues sum to zero), d_k the distance of p_k from the
strip.  Used by the lobe engine (the chatter band) and the root solver (the
band that holds every root right of a line).

References
----------
.. [1] R. A. Horn, C. R. Johnson, *Matrix Analysis*, 2nd ed., Cambridge, 2013,
   Thm. 5.6.9 and Cor. 5.6.16 (rho(X) <= ||X||: I + X is invertible when
   ||X|| < 1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..structure._complex import pole_residue_sum

__all__ = ["Band", "PoleResidue", "certified_band"]


@dataclass(frozen=True)
class PoleResidue:
    """H(s) = sum_k L[:, k] R[k, :] / (s - p_k) + D (rank-one residues)."""

    p: np.ndarray  # (K,)
    L: np.ndarray  # (m, K)
    R: np.ndarray  # (K, m)
    D: np.ndarray  # (m, m)

    def norms(self) -> np.ndarray:
        return np.linalg.norm(self.L, axis=0) * np.linalg.norm(self.R, axis=1)

    def __call__(self, s: np.ndarray) -> np.ndarray:
        """H(s) at the points ``s`` (any shape), shape ``s.shape + (m, m)``:
        the sum over the poles as one matrix product (N, K) @ (K, m m) of the
        factors 1/(s - p_k) with the residues L_k R_k, plus D."""
        return pole_residue_sum(self.p, self.L, self.R, s) + self.D


@dataclass(frozen=True)
class Band:
    """The frequency band searched for boundary points and its certificate.

    ``lo``, ``hi`` (rad/s): the ends of the band to search; ``certified``:
    above ``hi`` no point exists with width <= beta_max (proven by the gain
    bound).  Below ``lo`` nothing is claimed: the caller's grid must reach
    down there itself (the lobe engine's reaches w = 0).
    """

    lo: float
    hi: float
    certified: bool
    reason: str


def _gain_bound(
    pr: PoleResidue,
    a: np.ndarray,
    b: np.ndarray,
    nP: float,
    nV: float,
    nO: float,
    beta_max: float,
    shift: float = 0.0,
) -> np.ndarray:
    """Upper bound of beta_max ||H(s)|| ||A(w) + z O|| over each strip
    {Re s >= shift, Im s in [a, b]} (on the imaginary axis for shift = 0)."""
    p = pr.p[None, :]
    rn = pr.norms()[None, :]
    dx = np.maximum(shift - p.real, 0.0)
    dy = np.maximum(np.maximum(a[:, None] - p.imag, p.imag - b[:, None]), 0.0)
    d = np.maximum(np.hypot(dx, dy), 1e-300)
    S0 = np.linalg.norm(pr.L @ pr.R, 2)
    nD = np.linalg.norm(pr.D, 2) if pr.D.size else 0.0
    with np.errstate(over="ignore", divide="ignore"):
        b1 = np.sum(rn / d, axis=1)
        b2 = S0 / a + np.sum(rn * np.abs(p) / d, axis=1) / a
        Hb = np.minimum(b1, b2) + nD
        # an overflow is an infinite bound: the strip is not certified by it (conservative)
        return beta_max * Hb * (nP + b * nV + nO)


_BLOCK = 64  #: partition intervals bounded together first (certified_band)


def _last_bad_interval(
    pr: PoleResidue,
    edges: np.ndarray,
    nP: float,
    nV: float,
    nO: float,
    beta_max: float,
    shift: float,
) -> int:
    """Index of the highest interval [edges[i], edges[i+1]] whose gain bound
    is not below 1 (-1: none), without bounding every interval.

    The bound over a union of intervals is at least the bound over each of
    them (every d_k is smaller, the lower end a smaller and the upper end b
    larger, and floating-point rounding is monotone), so a block of
    ``_BLOCK`` intervals whose bound is below 1 holds no bad interval; only the
    blocks that fail are bounded interval by interval, from the top down,
    until one holds a bad interval.  The result is the one of bounding all."""
    n = edges.size - 1
    starts = np.arange(0, n, _BLOCK)
    ends = np.minimum(starts + _BLOCK, n)
    coarse = _gain_bound(pr, edges[starts], edges[ends], nP, nV, nO, beta_max, shift)
    for blk in np.nonzero(~(coarse < 1.0))[0][::-1]:
        a, e = int(starts[blk]), int(ends[blk])
        g = _gain_bound(pr, edges[a:e], edges[a + 1 : e + 1], nP, nV, nO, beta_max, shift)
        bad = np.nonzero(g >= 1.0)[0]
        if bad.size:
            return a + int(bad[-1])
    return -1


def certified_band(
    pr: PoleResidue,
    Dl_P: np.ndarray,
    Dl_V: np.ndarray,
    Dl_O: np.ndarray,
    beta_max: float,
    w_low: float,
    shift: float = 0.0,
) -> Band:
    """The certified band: the frequencies (rad/s) where the gain bound
    cannot exclude a point with beta_max ||H (A + z O)|| >= 1 (|z| <= 1) in
    the strip Re s >= ``shift``.  ``lo`` is ``w_low``; below it nothing is
    certified (the caller's grid covers it)."""
    nP, nV, nO = (float(np.linalg.norm(x, 2)) for x in (Dl_P, Dl_V, Dl_O))
    pmax = float(np.max(np.abs(pr.p))) if pr.p.size else 1.0
    top = 10.0 * max(pmax, w_low)
    edges = np.geomspace(w_low, top, int(np.ceil(np.log(top / w_low) / np.log(1.002))) + 1)
    last_bad = _last_bad_interval(pr, edges, nP, nV, nO, beta_max, shift)
    # tail [top, inf): |s - p_k| >= w - |p_k| and |s| >= w there, and
    # ([S0 + sum_k |R_k||p_k| / (w - |p_k|)] / w + |D|) (c + w e) bounds the gain;
    # the first part times (c/w + e) decreases with w, |D| (c + w e) does not when e > 0
    S0 = np.linalg.norm(pr.L @ pr.R, 2)
    nD = np.linalg.norm(pr.D, 2) if pr.D.size else 0.0
    rn = pr.norms()
    certified = True
    reason = "loop gain bound below 1 outside the band"
    tail = top
    for _ in range(12):
        if nD > 0 and nV > 0:
            tail = np.inf
            break
        Hs = S0 + np.sum(rn * np.abs(pr.p) / (tail - np.abs(pr.p)))
        gt = beta_max * (Hs * ((nP + nO) / tail + nV) + nD * (nP + nO + tail * nV))
        if gt < 1.0:
            break
        tail *= 4.0
    else:
        tail = np.inf
    if not np.isfinite(tail):
        certified = False
        reason = "the loop gain bound does not fall below 1 at high frequency (feedthrough or improper loop)"
        tail = top
    hi = float(edges[last_bad + 1]) if last_bad >= 0 else w_low
    if tail > top:
        hi = max(hi, tail)
    return Band(w_low, hi, certified, reason)
