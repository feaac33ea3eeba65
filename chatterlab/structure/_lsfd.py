"""Residues and residual terms of a modal model for fixed poles by least
squares in the frequency domain (LSFD; step 2 of the modal fit, see the
docstring of :mod:`chatterlab.structure._fit`), and the complex pole of a
natural frequency and damping ratio."""

from __future__ import annotations

import numpy as np

__all__ = ["lsfd"]

# ============================================================================ LSFD


def _pole(wn: np.ndarray, zeta: np.ndarray) -> np.ndarray:
    return -zeta * wn + 1j * wn * np.sqrt(np.maximum(1.0 - zeta**2, 0.0))


def _basis(s: np.ndarray, lam: np.ndarray, lower: bool, upper: bool) -> np.ndarray:
    """Complex basis columns (n_freq, 2m + residuals) of the real unknowns
    Re R_r, Im R_r, LR, UR."""
    a = 1.0 / (s[:, None] - lam[None, :])
    b = 1.0 / (s[:, None] - lam.conj()[None, :])
    cols = [a + b, 1j * (a - b)]
    if lower:
        cols.append((1.0 / s**2)[:, None])
    if upper:
        cols.append(np.ones((s.size, 1), complex))
    return np.hstack(cols)


def lsfd(
    omega: np.ndarray,
    H: np.ndarray,
    lam: np.ndarray,
    *,
    weights: np.ndarray | None = None,
    lower: bool = True,
    upper: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Residues and residual terms for fixed poles (one real weighted least
    squares per entry).  ``H`` (and ``weights``) is the receptance as one
    matrix per frequency, (n_freq, n_out, n_in): ``FRF.matrices``, the
    layout of the fit's batched least squares.

    Returns (R (m, n_out, n_in) complex, LR (n_out, n_in), UR (n_out, n_in),
    weighted residual (n_freq, n_out, n_in) complex)."""
    R, LR, UR, res, _ = _lsfd(omega, H, lam, weights, lower, upper)
    return R, LR, UR, res


def _solve_r(Rq: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with Rq x = b (upper triangular); a zero pivot (a column that is
    all zero, or two identical poles) gives the minimum-norm least-squares
    answer instead."""
    d = np.abs(np.diag(Rq))
    if d.size and d.min() > 1e-13 * d.max():
        from scipy.linalg import solve_triangular

        return np.asarray(solve_triangular(Rq, b))
    return np.linalg.lstsq(Rq, b, rcond=None)[0]


def _lsfd(
    w: np.ndarray, H: np.ndarray, lam: np.ndarray, Wt: np.ndarray | None, lower: bool, upper: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    s = 1j * w
    P = _basis(s, lam, lower, upper)
    n_f, n_o, n_i = H.shape
    m = lam.size
    R = np.zeros((m, n_o, n_i), complex)
    LR = np.zeros((n_o, n_i))
    UR = np.zeros((n_o, n_i))
    res = np.zeros(H.shape, complex)
    Wt = np.ones(H.shape) if Wt is None else Wt
    for o in range(n_o):
        for i in range(n_i):
            wt = Wt[:, o, i]
            if not np.any(wt > 0):
                continue  # not measured: residue 0, residual 0
            A = wt[:, None] * P
            Ar = np.vstack([A.real, A.imag])
            y = wt * H[:, o, i]
            # column scaling for the conditioning of the residual columns, then
            # Householder QR (backward stable; cheaper than the SVD of lstsq)
            sc = np.linalg.norm(Ar, axis=0)
            sc[sc == 0] = 1.0
            Q, Rq = np.linalg.qr(Ar / sc)
            x = _solve_r(Rq, Q.T @ np.concatenate([y.real, y.imag])) / sc
            R[:, o, i] = x[:m] + 1j * x[m : 2 * m]
            k = 2 * m
            if lower:
                LR[o, i] = x[k]
                k += 1
            if upper:
                UR[o, i] = x[k]
            res[:, o, i] = y - A @ x
    return R, LR, UR, res, P.shape[1]
