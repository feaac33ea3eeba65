"""The structure's response: complex modes of the damped structure and
modal superposition, and the receptance by a linear solve per frequency.

The modes are used by the FRFs, the lobe engine and the loop band, and
cached on the frozen system
(:attr:`chatterlab.structure.FrozenSystem.complex_modes`);
:func:`dynamic_receptance` is the one direct solve of
J (K - w^2 M + j w C)^-1 J^T (the FRF engine, receptance coupling, the
milling structure and its zeroth-order plant call it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

__all__ = ["ComplexModes", "complex_modes", "dynamic_receptance", "modal_response", "taylor_terms"]


@dataclass(frozen=True, eq=False)
class ComplexModes:
    """Complex modes of s^2 A + s B + C: G(s) = sum_r phi_r phi_r^T / (a_r (s - lam_r))."""

    lam: np.ndarray  # (2n,)
    phi: np.ndarray  # (n, 2n), scaled so that a_r = 1
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray


def complex_modes(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> ComplexModes:
    """Eigen-decomposition of the symmetric first-order form
    [[B, A], [A, 0]] y' + [[C, 0], [0, -A]] y = [f, 0].

    The problem is first balanced -- q = S x with S = diag(A)^-1/2 and
    s = w0 mu with w0 a typical natural frequency -- because on the raw
    matrices (masses of kg, stiffnesses of 1e9 N/m) the eigen-solver loses
    ~1e-7 of the real part of a lightly damped mode.  With
    G_s(mu) = sum phi_s phi_s^T / (mu - mu_r) of the balanced problem,
    G(s) = S G_s(s / w0) S / w0^2, i.e. phi = S phi_s / sqrt(w0), lam = w0 mu.
    """
    n = A.shape[0]
    d = np.diag(A).copy()
    d[d <= 0] = 1.0
    S = 1.0 / np.sqrt(d)
    As = A * S[:, None] * S[None, :]
    Cs0 = C * S[:, None] * S[None, :]
    ratio = np.diag(Cs0) / np.diag(As)
    ratio = ratio[np.isfinite(ratio) & (ratio > 0)]
    w0 = float(np.sqrt(np.exp(np.mean(np.log(ratio))))) if ratio.size else 1.0
    Bs = B * S[:, None] * S[None, :] / w0
    Cs = Cs0 / w0**2
    Z = np.zeros_like(As)
    AA = np.block([[Bs, As], [As, Z]])
    BB = np.block([[Cs, Z], [Z, -As]])
    mu, psi = scipy.linalg.eig(-BB, AA)
    a = np.einsum("ir,ij,jr->r", psi, AA, psi)
    psi = psi / np.sqrt(
        a.astype(complex)
    )  # a real negative a (overdamped pairs, real vectors): sqrt of a complex
    lam = mu * w0
    phi = S[:, None] * psi[:n] / np.sqrt(w0)
    order = np.argsort(np.abs(lam))
    return ComplexModes(lam[order], phi[:, order], A, B, C)


def taylor_terms(cm: ComplexModes, rows: np.ndarray, cols: np.ndarray) -> list[np.ndarray]:
    """rows G_k cols for the Taylor coefficients of G(s) at s = 0, k = 0..2."""
    C, B, A = cm.C, cm.B, cm.A
    lu = scipy.linalg.lu_factor(C)
    X = scipy.linalg.lu_solve(lu, cols)  # C^-1 cols
    Y = scipy.linalg.lu_solve(lu, rows.T)  # C^-1 rows^T
    G0 = rows @ X
    G1 = -(Y.T @ B @ X)
    BX = scipy.linalg.lu_solve(lu, B @ X)
    G2 = Y.T @ B @ BX - Y.T @ A @ X
    return [G0, G1, G2]


#: points per block of :func:`pole_residue_sum`: a block's factors (256 x K complex,
#: 440 kB for the shaper's 108 poles) stay in cache, where the whole (N, K) array of
#: the lobe engine's 6000-7700 frequencies (7-13 MB, fresh pages each time) did not:
#: 35 % less time there, the same numbers (each point's row is its own product)
_BLOCK = 256


def pole_residue_sum(p: np.ndarray, L: np.ndarray, R: np.ndarray, s: np.ndarray) -> np.ndarray:
    """sum_k L[:, k] R[k, :] / (s - p_k) at the points ``s`` (any shape),
    shape ``s.shape + (n_rows, n_cols)``: the one modal (pole-residue) sum of
    chatterlab, evaluated as matrix products (N, K) @ (K, n_rows n_cols)
    of the factors 1/(s - p_k) with the rank-one residues, block by block
    of points."""
    s = np.asarray(s, dtype=complex)
    K = p.size
    nr, nc = L.shape[0], R.shape[1]
    LR = (L.T[:, :, None] * R[:, None, :]).reshape(K, nr * nc)
    flat = s.reshape(-1)
    out = np.empty((flat.size, nr * nc), dtype=complex)
    with np.errstate(divide="ignore", invalid="ignore"):
        for i in range(0, flat.size, _BLOCK):
            np.matmul(1.0 / (flat[i : i + _BLOCK, None] - p[None, :]), LR, out=out[i : i + _BLOCK])
    return out.reshape(s.shape + (nr, nc))


def modal_response(
    cm: ComplexModes, rows: np.ndarray, cols: np.ndarray, s: np.ndarray, keep: np.ndarray, residual: bool
) -> np.ndarray:
    """rows G(s) cols by modal superposition over ``keep`` + residual.
    Shape (n_rows, n_cols, n_s)."""
    pr = rows @ cm.phi[:, keep]  # (nr, m)
    pc = cm.phi[:, keep].T @ cols  # (m, nc)
    lam = cm.lam[keep]
    out = np.moveaxis(pole_residue_sum(lam, pr, pc, s), 0, -1)
    if residual and keep.size < cm.lam.size:
        T = taylor_terms(cm, rows, cols)
        for k in range(3):
            # exact sum over all modes of phi phi^T / lam^(k+1) is -G_k
            kept = np.einsum("rm,mc,m->rc", pr, pc, 1.0 / lam ** (k + 1))
            # truncated modes: sum phi phi^T/(s - lam) = sum_k s^k (G_k + kept_k)
            Rk = T[k] + kept
            out = out + Rk[:, :, None] * s[None, None, :] ** k
    return out


def dynamic_receptance(
    M: np.ndarray,
    C: np.ndarray,
    K: np.ndarray,
    omega: np.ndarray,
    rows: np.ndarray,
    cols: np.ndarray | None = None,
    *,
    minus: np.ndarray | None = None,
) -> np.ndarray:
    """rows (K - w^2 M + j w C - D)^-1 cols at the angular frequencies
    ``omega`` (rad/s), one linear solve per frequency (exact to the solve's
    backward error; valid for a free-free structure at w > 0, where the
    complex modes are not).

    ``rows`` (n_rows, n) and ``cols`` (n, n_cols, default ``rows.T``) pick
    or combine the coordinates (J and J^T: the receptance between them);
    ``minus`` (n_freq, n, n), optional, is a dynamic stiffness D(j w)
    subtracted before the solve (the cutting process of a closed loop).
    Returns the stack (n_freq, n_rows, n_cols), one matrix per frequency
    (the layout of batched linear algebra; an FRF stores
    ``np.moveaxis(..., 0, -1)``)."""
    w = np.asarray(omega, dtype=float)
    Z = K[None] - w[:, None, None] ** 2 * M[None] + 1j * w[:, None, None] * C[None]
    if minus is not None:
        Z = Z - minus
    B = rows.T if cols is None else cols
    return rows[None] @ np.linalg.solve(Z, np.broadcast_to(B, (w.size,) + B.shape))
