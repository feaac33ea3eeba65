"""Characteristic roots of linear second-order systems with one delay.

The frozen closed-loop system of Wittbrodt & Kaliński (Eq. 2.1 with the
feedback matrix of Eq. 2.23) is, in the time domain (Eqs. 2.25, 2.28),

.. math::

    M\\ddot q + (C - D_V)\\dot q + (K - D_P) q = D_O\\, q(t-\\tau),

with characteristic matrix

.. math::

    \\Delta(\\lambda) = \\lambda^2 M + \\lambda (C - D_V) + (K - D_P)
                       - D_O e^{-\\lambda\\tau},

and characteristic roots :math:`\\det\\Delta(\\lambda) = 0`.  The cutting
process acts through a few coordinates of a coupling element, so
:math:`D_O = U V^T` has a small rank :math:`r`; this module works with the
factors throughout.

Methods
-------
``"spectral"``
    Chebyshev collocation of the infinitesimal generator of the delay
    equation (Breda, Maset & Vermiglio 2005).  Only the delayed output
    :math:`z = V^T q` needs a discretised history, so the matrix has size
    :math:`2n + N r` instead of :math:`(N+1)\\,2n`.  Long delays (many chatter
    periods per delay interval) are handled by *frequency windows*: the
    generator of the frequency-shifted equation for
    :math:`e^{-j\\omega_0 t} q(t)` is discretised, whose eigenfunctions near
    :math:`\\lambda = j\\omega_0` are slowly varying, so a modest :math:`N`
    resolves the roots near :math:`j\\omega_0` whatever :math:`\\omega_0\\tau`.
    Windows are placed on predicted root locations (the phase condition
    :math:`\\omega\\tau - \\arg\\mu_j(j\\omega) = 2\\pi k` along each
    continuously tracked eigenvalue :math:`\\mu_j` of
    :math:`H = V^T P^{-1} U`, real part :math:`\\approx \\log|\\mu_j|/\\tau`)
    and added until every prediction right of the ``count``-th root found
    (minus a margin and the prediction's own uncertainty) lies in a window.
    The predictions only steer where to look; every reported root is an
    eigenvalue of a discretised generator.
    Every eigenvalue is refined by Newton's method on
    :math:`\\det\\Delta` and kept only if a second, finer discretisation
    (:math:`N_2 \\approx 1.5 N`) gives the same root.
``"branch"``
    Root enumeration from the low-rank factorisation
    :math:`\\det\\Delta = \\det P\\,\\det(I_r - H(\\lambda) e^{-\\lambda\\tau})`:
    along each eigenvalue branch :math:`\\mu_j` of :math:`H` the roots satisfy
    :math:`\\lambda\\tau = \\log\\mu_j(\\lambda) + 2\\pi i k`.  One start per
    integer :math:`k` and branch, a few fixed-point sweeps, then Newton on
    :math:`\\det\\Delta` (restarted with deflation when two starts reach the
    same root).  Accurate starting values when the delay is long; an
    independent check of the spectral route.
``"eig"``
    No delay: the quadratic eigenvalue problem, solved by linearisation.

Numerical failure is reported as ``status="not_converged"`` with a
``message``, never raised; bad *input* raises
:class:`chatterlab.errors.InputError`.

References
----------
.. [1] E. Wittbrodt, K. J. Kaliński, "Transient vibration of unsteady linear
   closed loop systems" (the seed paper of chatterlab), Eqs. 2.1, 2.22-2.28.
.. [2] D. Breda, S. Maset, R. Vermiglio, "Pseudospectral differencing methods
   for characteristic roots of delay differential equations", SIAM J. Sci.
   Comput. 27(2), 482-495, 2005.
.. [3] L. N. Trefethen, *Spectral Methods in MATLAB*, SIAM 2000, ch. 6
   (Chebyshev differentiation matrices).
.. [4] P. Lancaster, *Lambda-matrices and Vibrating Systems*, Pergamon 1966
   (Newton's method :math:`\\lambda \\leftarrow \\lambda -
   1/\\operatorname{tr}(\\Delta^{-1}\\Delta')`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import itertools
import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg as sla
from numpy.typing import ArrayLike, NDArray

from chatterlab.errors import InputError

__all__ = [
    "RootsResult",
    "DelaySystem",
    "make_system",
    "make_first_order_system",
    "characteristic_roots",
    "characteristic_roots_first_order",
    "characteristic_roots_system",
    "char_matrix",
    "char_matrix_derivative",
    "newton_refine",
    "chebyshev_nodes",
    "certified_top",
    "AXIS_GRID_MAX",
    "WINDOW_MAX",
]

ComplexArray = NDArray[np.complex128]
FloatArray = NDArray[np.float64]

# Largest discretised-generator size solved by one dense eigenvalue problem
# (about 0.15 s for a complex 400x400 matrix); beyond that, frequency windows.
_DENSE_MAX = 420
# Chebyshev collocation with N+1 nodes on [-tau, 0] resolves exp(s*theta) for
# |s| tau / 2 clearly below N; we trust eigenvalues with |s| <= N / tau, i.e.
# half the resolution limit, and use N = ceil(R tau) + _N_EXTRA for a radius R.
_N_EXTRA = 12
_N2_FACTOR = 1.5
# exp(-lambda tau) overflows for Re(lambda) tau < -709; candidates that far
# left are discarded (they are never among the rightmost roots).
_EXP_LIMIT = 600.0


# ---------------------------------------------------------------------------
# result object
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class RootsResult:
    """Rightmost characteristic roots of a delay system.

    Attributes
    ----------
    roots : ndarray of complex, shape (k,)
        Roots in rad/s, upper half plane and real axis only (conjugates
        omitted), sorted by decreasing real part; ``k <= count``.
    frequency_hz : ndarray of float, shape (k,)
        ``roots.imag / (2 pi)`` in Hz.
    damping_ratio : ndarray of float, shape (k,)
        ``-Re(lambda) / |lambda|`` (dimensionless; NaN for a root at 0).
    abscissa : float
        Largest real part (1/s): the spectral abscissa; negative means
        asymptotically stable.  NaN when no root was found.
    method : str
        ``"spectral"``, ``"spectral-windowed"``, ``"branch"`` or ``"eig"``.
    n_nodes : tuple of int
        ``(N, N2)``: Chebyshev nodes of the two discretisations (largest over
        the frequency windows); ``(0, 0)`` for methods without them.
    rejected : int
        Candidates dropped by the convergence check (Newton failed, or the
        root was not reproduced by the second discretisation / start).
    status : str
        ``"converged"`` or ``"not_converged"``.
    message : str
        Human-readable diagnostic.
    n_windows : int
        Number of frequency windows (spectral route); 0 otherwise.
    elapsed : float
        Wall-clock time in s.
    band_top : float
        Upper end (rad/s) of the frequency band searched (NaN when the
        caller fixed the band or the nodes).
    complete_above : float
        Every root with real part >= this (1/s) lies in the band searched:
        the gain bound of the loop transfer excludes the frequencies above it
        (NaN when not certified).  A verdict "stable" needs it < 0.
    """

    roots: ComplexArray
    frequency_hz: FloatArray
    damping_ratio: FloatArray
    abscissa: float
    method: str
    n_nodes: tuple[int, int]
    rejected: int
    status: str
    message: str
    n_windows: int = 0
    elapsed: float = 0.0
    band_top: float = math.nan
    complete_above: float = math.nan

    @property
    def converged(self) -> bool:
        """``True`` when ``status == "converged"``."""
        return self.status == "converged"

    @property
    def stable(self) -> bool:
        """``True`` when the rightmost root found has a negative real part."""
        return bool(self.abscissa < 0.0)

    def table(self) -> str:
        """Readable table of the roots (frequency in Hz, real part in 1/s)."""
        lines = [
            f"characteristic roots ({self.method}, N={self.n_nodes[0]}/{self.n_nodes[1]}, "
            f"status={self.status}, rejected={self.rejected})",
            f"{'#':>3} {'Re (1/s)':>14} {'Im (rad/s)':>14} {'f (Hz)':>12} {'zeta':>10}",
        ]
        for i, (lam, f, z) in enumerate(zip(self.roots, self.frequency_hz, self.damping_ratio, strict=True)):
            lines.append(f"{i:>3} {lam.real:>14.6g} {lam.imag:>14.6g} {f:>12.6g} {z:>10.4g}")
        lines.append(f"abscissa = {self.abscissa:.6g} 1/s; {self.message}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.table()


def _make_result(
    roots: ArrayLike,
    *,
    method: str,
    n_nodes: tuple[int, int],
    rejected: int,
    status: str,
    message: str,
    n_windows: int = 0,
    t0: float | None = None,
) -> RootsResult:
    lam = np.asarray(roots, dtype=complex).ravel()
    order = np.lexsort((lam.imag, -lam.real))
    lam = lam[order]
    mod = np.abs(lam)
    zeta = np.full(lam.shape, np.nan)
    nz = mod > 0
    zeta[nz] = -lam.real[nz] / mod[nz]
    lam.setflags(write=False)
    fhz = lam.imag / (2.0 * np.pi)
    fhz.setflags(write=False)
    zeta.setflags(write=False)
    return RootsResult(
        roots=lam,
        frequency_hz=fhz,
        damping_ratio=zeta,
        abscissa=float(lam[0].real) if lam.size else float("nan"),
        method=method,
        n_nodes=(int(n_nodes[0]), int(n_nodes[1])),
        rejected=int(rejected),
        status=status,
        message=message,
        n_windows=int(n_windows),
        elapsed=0.0 if t0 is None else time.perf_counter() - t0,
    )


# ---------------------------------------------------------------------------
# the system
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class DelaySystem:
    """Validated delay system :math:`\\Delta(\\lambda) = P(\\lambda) - U V^T e^{-\\lambda\\tau}`.

    Attributes
    ----------
    coeffs : tuple of ndarray, each shape (n, n)
        :math:`P(\\lambda) = \\sum_k \\lambda^k` ``coeffs[k]`` (the delay-free
        closed loop; ``(K - D_P, C - D_V, M)`` for the second-order form,
        ``(-A0, I)`` for the first-order form).
    U, V : ndarray, shape (n, r)
        Factors of the delayed feedback matrix :math:`D_O = U V^T`; ``r = 0``
        without delay.
    tau : float
        Delay in s (0.0 when ``r == 0``).
    A : ndarray, shape (m, m)
        First-order linearisation of :math:`P`: state ``(q, qdot)`` (``m = 2n``)
        or ``x`` (``m = n``).
    B : ndarray, shape (m, r)
        Input of the delayed output into the state equation.
    Cz : ndarray, shape (r, m)
        Delayed output ``z = V^T q`` from the state.
    open_coeffs : tuple of ndarray
        Coefficients of the open-loop structure :math:`P_0` (``(K, C, M)``),
        used by the winding count.
    """

    coeffs: tuple[NDArray[np.float64], ...]
    U: NDArray[np.float64]
    V: NDArray[np.float64]
    tau: float
    A: NDArray[np.float64]
    B: NDArray[np.float64]
    Cz: NDArray[np.float64]
    open_coeffs: tuple[NDArray[np.float64], ...]
    _cache: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)

    @property
    def n(self) -> int:
        """Number of coordinates."""
        return int(self.coeffs[0].shape[0])

    @property
    def r(self) -> int:
        """Rank of the delayed feedback."""
        return int(self.U.shape[1])

    @property
    def has_delay(self) -> bool:
        """Whether a delayed term is present."""
        return self.r > 0

    @property
    def DO(self) -> NDArray[np.float64]:
        """Dense delayed feedback matrix ``U @ V.T``, shape (n, n)."""
        return self.U @ self.V.T

    def P(self, lam: ArrayLike) -> ComplexArray:
        """Delay-free part :math:`P(\\lambda)`, shape ``lam.shape + (n, n)``."""
        lam = np.asarray(lam, dtype=complex)[..., None, None]
        out = np.zeros(lam.shape[:-2] + (self.n, self.n), dtype=complex)
        for k in range(len(self.coeffs) - 1, -1, -1):
            out = out * lam + self.coeffs[k]
        return out

    def dP(self, lam: ArrayLike) -> ComplexArray:
        """Derivative :math:`P'(\\lambda)`, shape ``lam.shape + (n, n)``."""
        lam = np.asarray(lam, dtype=complex)[..., None, None]
        out = np.zeros(lam.shape[:-2] + (self.n, self.n), dtype=complex)
        for k in range(len(self.coeffs) - 1, 0, -1):
            out = out * lam + k * self.coeffs[k]
        return out

    def delta(self, lam: ArrayLike) -> ComplexArray:
        """Characteristic matrix :math:`\\Delta(\\lambda)`, shape ``lam.shape + (n, n)``."""
        lam = np.asarray(lam, dtype=complex)
        out = self.P(lam)
        if self.has_delay:
            with np.errstate(over="ignore", invalid="ignore"):
                e = np.exp(-lam * self.tau)[..., None, None]
                out = out - e * self.DO
        return out

    def ddelta(self, lam: ArrayLike) -> ComplexArray:
        """Derivative :math:`\\Delta'(\\lambda)`, shape ``lam.shape + (n, n)``."""
        lam = np.asarray(lam, dtype=complex)
        out = self.dP(lam)
        if self.has_delay:
            with np.errstate(over="ignore", invalid="ignore"):
                e = np.exp(-lam * self.tau)[..., None, None]
                out = out + (self.tau * e) * self.DO
        return out

    def transfer(self, lam: ArrayLike) -> ComplexArray:
        """Low-rank loop transfer :math:`H(\\lambda) = V^T P(\\lambda)^{-1} U`.

        Returns shape ``lam.shape + (r, r)``; direct solves (accurate near
        poles too).
        """
        lam = np.asarray(lam, dtype=complex)
        Pm = self.P(lam)
        Ub = np.broadcast_to(self.U.astype(complex), Pm.shape[:-1] + (self.r,))
        X = _batched_solve(Pm, Ub)
        return np.einsum("ki,...kj->...ij", self.V, X)

    def transfer_fast(self, lam: ArrayLike) -> ComplexArray:
        r""":math:`H(\lambda)` by partial fractions of the linearisation.

        ``H = (Cz S) diag(1/(lam - p)) (S^{-1} B)`` with ``A = S diag(p) S^{-1}``;
        O(m r^2) per point.  Falls back to :meth:`transfer` when the
        eigenvector matrix is ill-conditioned (cond > 1e8).  Used only for
        predictions (root locations are always refined on Delta itself).
        """
        lam = np.asarray(lam, dtype=complex)
        if "pf" not in self._cache:
            p, S = np.linalg.eig(self.A)
            ok = np.linalg.cond(S) < 1e8
            self._cache["pf"] = (p, self.Cz @ S, np.linalg.solve(S, self.B)) if ok else None
        pf = self._cache["pf"]
        if pf is None:
            return self.transfer(lam)
        p, L, R = pf
        with np.errstate(all="ignore"):
            g = 1.0 / (lam[..., None] - p)
        return np.einsum("ik,...k,kj->...ij", L, g, R)

    def delay_free_poles(self) -> ComplexArray:
        """Eigenvalues of the delay-free closed loop :math:`P`, shape (m,)."""
        if "poles" not in self._cache:
            self._cache["poles"] = np.linalg.eigvals(self.A)
        return self._cache["poles"]


def _batched_solve(A: ComplexArray, B: ComplexArray, singular: Any = np.nan) -> ComplexArray:
    """Solve ``A X = B`` for a stack; exactly singular members give ``singular``.

    Never raises: non-finite members give NaN.
    """
    try:
        return np.linalg.solve(A, B)  # type: ignore[return-value]  # numpy stubs: complex128 in, complexfloating[Any, Any] out
    except np.linalg.LinAlgError:
        out = np.full(np.broadcast_shapes(A.shape[:-2], B.shape[:-2]) + B.shape[-2:], np.nan + 0j)
        Ab = np.broadcast_to(A, out.shape[:-2] + A.shape[-2:])
        Bb = np.broadcast_to(B, out.shape)
        for idx in np.ndindex(out.shape[:-2]):
            if not (np.all(np.isfinite(Ab[idx])) and np.all(np.isfinite(Bb[idx]))):
                continue
            try:
                out[idx] = np.linalg.solve(Ab[idx], Bb[idx])
            except np.linalg.LinAlgError:
                out[idx] = singular
        return out


def _as_real_matrix(x: Any, name: str, n: int | None = None) -> NDArray[np.float64]:
    try:
        a = np.asarray(x)
    except Exception as exc:  # pragma: no cover - exotic inputs
        raise InputError(f"{name} must be a real matrix ({exc})") from exc
    if a.dtype.kind == "c":
        raise InputError(f"{name} must be real (got complex entries)")
    if a.dtype.kind not in "biuf":
        raise InputError(f"{name} must be a real numeric matrix (got dtype {a.dtype})")
    a = np.atleast_2d(a.astype(float))
    if a.ndim != 2 or a.shape[0] != a.shape[1]:
        raise InputError(f"{name} must be a square matrix (got shape {np.shape(x)})")
    if n is not None and a.shape[0] != n:
        raise InputError(f"{name} must have shape ({n}, {n}) like M (got {a.shape})")
    if not np.all(np.isfinite(a)):
        raise InputError(f"{name} has non-finite entries (NaN or inf)")
    return a


def _factor_DO(DO: Any, n: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return ``(U, V)`` with ``DO = U V^T`` (r may be 0)."""
    if DO is None:
        return np.zeros((n, 0)), np.zeros((n, 0))
    if isinstance(DO, tuple | list) and len(DO) == 2:
        U = np.asarray(DO[0])
        V = np.asarray(DO[1])
        for nm, a in (("DO[0] (U)", U), ("DO[1] (V)", V)):
            if a.dtype.kind == "c":
                raise InputError(f"{nm} must be real (got complex entries)")
            if a.dtype.kind not in "biuf":
                raise InputError(f"{nm} must be numeric (got dtype {a.dtype})")
        U = U.astype(float)
        V = V.astype(float)
        if U.ndim == 1:
            U = U[:, None]
        if V.ndim == 1:
            V = V[:, None]
        if U.ndim != 2 or V.ndim != 2 or U.shape != V.shape or U.shape[0] != n:
            raise InputError(
                f"DO=(U, V) factors must both have shape (n, r) with n={n} (got U {U.shape}, V {V.shape})"
            )
        if not (np.all(np.isfinite(U)) and np.all(np.isfinite(V))):
            raise InputError("DO=(U, V) factors have non-finite entries")
        if U.shape[1] > 0 and (np.abs(U).max() == 0.0 or np.abs(V).max() == 0.0):
            return np.zeros((n, 0)), np.zeros((n, 0))
        return U, V
    D = _as_real_matrix(DO, "DO", n)
    if not np.any(D):
        return np.zeros((n, 0)), np.zeros((n, 0))
    W, s, Zt = np.linalg.svd(D)
    keep = s > 1e-12 * s[0]
    return W[:, keep] * s[keep], Zt[keep].T.copy()


def _check_tau(tau: Any, needed: bool) -> float:
    if not needed:
        return 0.0
    if tau is None:
        raise InputError("tau must be given (> 0, in s) when a delayed term DO is present")
    try:
        t = float(tau)
    except (TypeError, ValueError) as exc:
        raise InputError(f"tau must be a positive number in s (got {tau!r})") from exc
    if not math.isfinite(t) or t <= 0.0:
        raise InputError(f"tau must be finite and > 0 s when DO is given (got {tau!r})")
    return t


def make_system(
    M: ArrayLike,
    C: ArrayLike,
    K: ArrayLike,
    *,
    DP: ArrayLike | None = None,
    DV: ArrayLike | None = None,
    DO: ArrayLike | tuple[ArrayLike, ArrayLike] | None = None,
    tau: float | None = None,
) -> DelaySystem:
    """Validate the second-order closed-loop data and build a :class:`DelaySystem`.

    Parameters
    ----------
    M, C, K : array_like, shape (n, n)
        Inertia (kg, SPD), damping (N s/m) and stiffness (N/m) matrices.
    DP, DV : array_like, shape (n, n), optional
        Proportional (N/m) and velocity (N s/m) feedback, Eq. 2.23.
    DO : array_like, shape (n, n), or tuple ``(U, V)`` of shape (n, r), optional
        Delayed feedback (N/m); ``(U, V)`` means ``DO = U @ V.T``.  A dense
        matrix is factored by SVD (singular values below 1e-12 of the largest
        are dropped).
    tau : float, optional
        Delay in s; required (> 0) when ``DO`` is non-zero.

    Returns
    -------
    DelaySystem

    Raises
    ------
    InputError
        Non-square, mismatched or non-finite matrices, ``M`` not symmetric
        positive definite, ``tau <= 0`` with ``DO`` given.

    References
    ----------
    .. [1] E. Wittbrodt, K. Kaliński, seed paper, Eqs. 2.1, 2.22-2.28.
    """
    Mm = _as_real_matrix(M, "M")
    n = Mm.shape[0]
    Cm = _as_real_matrix(C, "C", n)
    Km = _as_real_matrix(K, "K", n)
    DPm = np.zeros((n, n)) if DP is None else _as_real_matrix(DP, "DP", n)
    DVm = np.zeros((n, n)) if DV is None else _as_real_matrix(DV, "DV", n)
    if not np.allclose(Mm, Mm.T, rtol=1e-10, atol=1e-14 * np.abs(Mm).max()):
        raise InputError("M must be symmetric positive definite (it is not symmetric)")
    try:
        cho = sla.cho_factor(Mm)
    except np.linalg.LinAlgError as exc:
        raise InputError("M must be symmetric positive definite (Cholesky failed)") from exc
    U, V = _factor_DO(DO, n)
    t = _check_tau(tau, U.shape[1] > 0)
    Ct = Cm - DVm
    Kt = Km - DPm
    r = U.shape[1]
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -sla.cho_solve(cho, Kt)
    A[n:, n:] = -sla.cho_solve(cho, Ct)
    B = np.zeros((2 * n, r))
    if r:
        B[n:] = sla.cho_solve(cho, U)
    Cz = np.zeros((r, 2 * n))
    Cz[:, :n] = V.T
    return DelaySystem(coeffs=(Kt, Ct, Mm), U=U, V=V, tau=t, A=A, B=B, Cz=Cz, open_coeffs=(Km, Cm, Mm))


def make_first_order_system(
    A0: ArrayLike, A1: ArrayLike | tuple[ArrayLike, ArrayLike] | None, tau: float | None
) -> DelaySystem:
    """Build a :class:`DelaySystem` for :math:`\\dot x = A_0 x + A_1 x(t-\\tau)`.

    Parameters
    ----------
    A0 : array_like, shape (n, n)
        Undelayed state matrix (1/s).
    A1 : array_like, shape (n, n), or tuple ``(U, V)``, or None
        Delayed state matrix (1/s), optionally factored ``A1 = U @ V.T``.
    tau : float or None
        Delay in s (> 0 when ``A1`` is non-zero).

    Returns
    -------
    DelaySystem
        With ``coeffs = (-A0, I)``; :math:`\\Delta(\\lambda) = \\lambda I - A_0
        - A_1 e^{-\\lambda\\tau}`.

    References
    ----------
    .. [1] E. Wittbrodt, K. Kaliński, seed paper, Eqs. 2.1, 2.22-2.28.
    """
    A = _as_real_matrix(A0, "A0")
    n = A.shape[0]
    try:
        U, V = _factor_DO(A1, n)
    except InputError as exc:
        raise InputError(str(exc).replace("DO", "A1")) from exc
    t = _check_tau(tau, U.shape[1] > 0)
    return DelaySystem(
        coeffs=(-A, np.eye(n)),
        U=U,
        V=V,
        tau=t,
        A=A.copy(),
        B=U.copy(),
        Cz=V.T.copy(),
        open_coeffs=(-A, np.eye(n)),
    )


# ---------------------------------------------------------------------------
# characteristic matrix and Newton
# ---------------------------------------------------------------------------
def char_matrix(
    lam: ArrayLike,
    M: ArrayLike,
    C: ArrayLike,
    K: ArrayLike,
    *,
    DP: ArrayLike | None = None,
    DV: ArrayLike | None = None,
    DO: ArrayLike | tuple[ArrayLike, ArrayLike] | None = None,
    tau: float | None = None,
) -> ComplexArray:
    """Characteristic matrix :math:`\\Delta(\\lambda)` of Eq. 2.1 with Eq. 2.23.

    Parameters
    ----------
    lam : complex or array_like of complex, shape (...)
        Laplace variable(s) in rad/s.
    M, C, K, DP, DV, DO, tau
        As in :func:`make_system`.

    Returns
    -------
    ndarray of complex, shape ``(...) + (n, n)``
        :math:`\\lambda^2 M + \\lambda (C - D_V) + K - D_P - D_O e^{-\\lambda\\tau}`.

    References
    ----------
    .. [1] E. Wittbrodt, K. Kaliński, seed paper, Eqs. 2.1, 2.22-2.28.
    """
    return make_system(M, C, K, DP=DP, DV=DV, DO=DO, tau=tau).delta(lam)


def char_matrix_derivative(
    lam: ArrayLike,
    M: ArrayLike,
    C: ArrayLike,
    K: ArrayLike,
    *,
    DP: ArrayLike | None = None,
    DV: ArrayLike | None = None,
    DO: ArrayLike | tuple[ArrayLike, ArrayLike] | None = None,
    tau: float | None = None,
) -> ComplexArray:
    """Derivative :math:`\\Delta'(\\lambda) = 2\\lambda M + C - D_V + \\tau D_O e^{-\\lambda\\tau}`.

    Same parameters and shapes as :func:`char_matrix`.

    References
    ----------
    .. [1] E. Wittbrodt, K. Kaliński, seed paper, Eqs. 2.1, 2.22-2.28.
    """
    return make_system(M, C, K, DP=DP, DV=DV, DO=DO, tau=tau).ddelta(lam)


def _newton(
    sys: DelaySystem,
    lam0: ArrayLike,
    *,
    tol: float = 1e-13,
    maxiter: int = 40,
    deflate: ComplexArray | None = None,
) -> tuple[ComplexArray, NDArray[np.bool_]]:
    """Vectorised Newton iteration on det Delta; returns (roots, converged).

    ``deflate``: known roots ``zeta_i``; Newton is then applied to
    ``det Delta(lam) / prod (lam - zeta_i)`` so that it cannot return them.
    """
    lam = np.array(lam0, dtype=complex).ravel()
    conv = np.zeros(lam.shape, dtype=bool)
    alive = np.isfinite(lam)
    if sys.has_delay:
        alive &= lam.real * sys.tau > -_EXP_LIMIT
    scale = _root_scale(sys)
    last = np.full(lam.shape, np.inf)
    for _ in range(maxiter):
        idx = np.flatnonzero(alive & ~conv)
        if idx.size == 0:
            break
        L = lam[idx]
        with np.errstate(all="ignore"):
            D = sys.delta(L)
            Dp = sys.ddelta(L)
            # an exactly singular Delta means lam is a root to machine precision
            X = _batched_solve(D, Dp, singular=np.inf)
            tr = np.trace(X, axis1=-2, axis2=-1)
            exact = np.isinf(tr.real) | np.isinf(tr.imag)
            if deflate is not None and deflate.size:
                tr = tr - (1.0 / (L[:, None] - deflate[None, :])).sum(axis=1)
            step = 1.0 / tr
            step[~np.isfinite(tr)] = np.nan
        step[exact] = 0.0
        bad = ~np.isfinite(step)
        new = L - np.where(bad, 0.0, step)
        if sys.has_delay:
            bad |= new.real * sys.tau < -_EXP_LIMIT
        lam[idx] = new
        a = np.abs(step)
        done = ~bad & (a <= tol * np.maximum(np.abs(new), scale))
        # a stalled iteration at roundoff level also counts as converged
        done |= ~bad & (a <= 1e-9 * np.maximum(np.abs(new), scale)) & (a >= 0.5 * last[idx])
        conv[idx[done]] = True
        alive[idx[bad]] = False
        last[idx] = np.where(bad, np.inf, a)
    # accept iterations that ended within a loose tolerance of a root
    idx = np.flatnonzero(alive & ~conv & (last <= 1e-8 * np.maximum(np.abs(lam), scale)))
    conv[idx] = True
    return lam, conv


def _root_scale(sys: DelaySystem) -> float:
    if "scale" not in sys._cache:
        p = sys.delay_free_poles()
        s = float(np.max(np.abs(p))) if p.size else 1.0
        if sys.has_delay:
            s = max(s, 1.0 / sys.tau)
        sys._cache["scale"] = max(s, 1e-300) * 1e-3
    return sys._cache["scale"]


def newton_refine(
    lam0: ArrayLike,
    M: ArrayLike,
    C: ArrayLike,
    K: ArrayLike,
    *,
    DP: ArrayLike | None = None,
    DV: ArrayLike | None = None,
    DO: ArrayLike | tuple[ArrayLike, ArrayLike] | None = None,
    tau: float | None = None,
    tol: float = 1e-13,
    maxiter: int = 40,
    system: DelaySystem | None = None,
) -> tuple[ComplexArray, NDArray[np.bool_]]:
    """Refine approximate characteristic roots by Newton's method on det Delta.

    Iterates :math:`\\lambda \\leftarrow \\lambda - 1/\\operatorname{tr}(
    \\Delta(\\lambda)^{-1}\\Delta'(\\lambda))`, quadratically convergent to a
    simple root.

    Parameters
    ----------
    lam0 : complex or array_like of complex, shape (k,)
        Starting values in rad/s.
    M, C, K, DP, DV, DO, tau
        As in :func:`make_system` (ignored when ``system`` is given).
    tol : float
        Relative step size at which an iterate counts as converged.
    maxiter : int
        Maximum number of Newton steps.
    system : DelaySystem, optional
        A prepared system (skips validation); e.g. from
        :func:`make_first_order_system`.

    Returns
    -------
    roots : ndarray of complex, shape (k,)
        Final iterates (rad/s).
    converged : ndarray of bool, shape (k,)
        Whether each iterate converged.

    References
    ----------
    .. [1] P. Lancaster, *Lambda-matrices and Vibrating Systems*, 1966.
    """
    sys = system if system is not None else make_system(M, C, K, DP=DP, DV=DV, DO=DO, tau=tau)
    return _newton(sys, lam0, tol=tol, maxiter=maxiter)


# ---------------------------------------------------------------------------
# helpers: dedupe, matching
# ---------------------------------------------------------------------------
def _canonical(lam: ComplexArray, scale: float) -> ComplexArray:
    """Map roots to the closed upper half plane; snap nearly-real roots to real."""
    lam = np.where(lam.imag < 0, lam.conj(), lam)
    near_real = np.abs(lam.imag) <= 1e-9 * np.maximum(np.abs(lam), scale)
    return np.where(near_real, lam.real + 0j, lam)


def _dedupe(lam: ComplexArray, tol_rel: float, scale: float) -> ComplexArray:
    if lam.size == 0:
        return lam
    lam = lam[np.lexsort((lam.imag, lam.real))]
    keep: list[complex] = []
    for z in lam:
        t = tol_rel * max(abs(z), scale)
        if not any(abs(z - w) <= t for w in keep[-8:]):
            # roots are sorted by real part; compare with the recent ones and
            # a vectorised pass over all kept ones for safety
            if keep and np.min(np.abs(np.asarray(keep) - z)) <= t:
                continue
            keep.append(complex(z))
    return np.asarray(keep, dtype=complex)


def _match(a: ComplexArray, b: ComplexArray, tol_rel: float, scale: float) -> NDArray[np.bool_]:
    """For each element of ``a``, whether ``b`` holds a root within tolerance."""
    if a.size == 0:
        return np.zeros(0, dtype=bool)
    if b.size == 0:
        return np.zeros(a.shape, dtype=bool)
    d = np.abs(a[:, None] - b[None, :]).min(axis=1)
    return d <= tol_rel * np.maximum(np.abs(a), scale)


# ---------------------------------------------------------------------------
# spectral discretisation of the infinitesimal generator
# ---------------------------------------------------------------------------
def chebyshev_nodes(N: int, tau: float) -> tuple[FloatArray, FloatArray]:
    """Chebyshev extremal nodes on ``[-tau, 0]`` and the differentiation matrix.

    Parameters
    ----------
    N : int
        Polynomial degree (``N + 1`` nodes).
    tau : float
        Interval length in s.

    Returns
    -------
    theta : ndarray, shape (N + 1,)
        ``theta[0] = 0``, ``theta[N] = -tau`` (s).
    D : ndarray, shape (N + 1, N + 1)
        Differentiation matrix in 1/s: ``(D @ p(theta))[i] = p'(theta[i])`` for
        polynomials ``p`` of degree ``<= N``.

    References
    ----------
    .. [1] L. N. Trefethen, *Spectral Methods in MATLAB*, SIAM 2000, ch. 6.
    """
    j = np.arange(N + 1)
    x = np.cos(np.pi * j / N)
    c = np.where((j == 0) | (j == N), 2.0, 1.0) * (-1.0) ** j
    dx = x[:, None] - x[None, :]
    np.fill_diagonal(dx, 1.0)
    D = np.outer(c, 1.0 / c) / dx
    np.fill_diagonal(D, 0.0)
    np.fill_diagonal(D, -D.sum(axis=1))  # rows of D annihilate constants
    theta = 0.5 * tau * (x - 1.0)
    return theta, D * (2.0 / tau)


def _generator_matrix(sys: DelaySystem, N: int, omega0: float) -> NDArray[Any]:
    """Collocation matrix of the (frequency-shifted) infinitesimal generator.

    State: ``x`` (the ODE state at theta = 0, size m) and the envelope
    ``u_i = exp(-j omega0 theta_i) z(theta_i)`` of the delayed output
    ``z = Cz x`` at nodes ``theta_1..theta_N`` (``u_0 = Cz x``).  Eigenvalues
    approximate characteristic roots near ``j omega0``.
    """
    m = sys.A.shape[0]
    r = sys.r
    _, D = chebyshev_nodes(N, sys.tau)
    real = omega0 == 0.0
    dtype = float if real else complex
    size = m + N * r
    G = np.zeros((size, size), dtype=dtype)
    G[:m, :m] = sys.A
    shift = 1.0 if real else np.exp(-1j * omega0 * sys.tau)
    G[:m, m + (N - 1) * r :] = sys.B * shift
    # u rows, node-major blocks of size r
    Dh = D[1:, 1:].copy()
    if not real:
        Dh = Dh + 1j * omega0 * np.eye(N)
    G[m:, m:] = np.kron(Dh, np.eye(r))
    G[m:, :m] = np.kron(D[1:, :1], sys.Cz)
    return G


@dataclass
class _Window:
    centre: float  # rad/s
    radius: float  # trusted radius, rad/s
    N: int
    N2: int
    roots: ComplexArray = field(default_factory=lambda: np.zeros(0, complex))
    rejected: int = 0
    failed: str = ""


#: largest generator matrix one window may need (its eigenvalues take seconds;
#: beyond this the search reports a status instead of running for minutes)
WINDOW_MAX = 1600


def _solve_window(sys: DelaySystem, w: _Window, match_tol: float) -> None:
    size = sys.A.shape[0] + w.N2 * sys.r
    if size > WINDOW_MAX:
        raise _TooLarge(
            f"a window of radius {w.radius:.4g} rad/s at {w.centre / 2 / math.pi:.4g} Hz needs a"
            f" {size} x {size} eigenproblem (limit {WINDOW_MAX}): roots far from the imaginary axis"
            " (e.g. an unstable delay-free loop) with a long delay; pass omega_max or n_nodes"
        )
    scale = _root_scale(sys)
    found = []
    for N in (w.N, w.N2):
        G = _generator_matrix(sys, N, w.centre)
        try:
            ev = np.linalg.eigvals(G)
        except np.linalg.LinAlgError:
            w.failed = f"eigenvalue solver failed (N={N}, centre {w.centre:.6g} rad/s)"
            found.append((np.zeros(0, complex), 0))
            continue
        s = ev - 1j * w.centre
        pre = ev[(np.abs(s) <= 1.3 * w.radius) & (ev.imag >= -0.05 * w.radius - 1e-12 * scale)]
        lam, ok = _newton(sys, pre)
        lam_ok = _canonical(lam[ok], scale)
        inside = np.abs(lam_ok - 1j * w.centre) <= w.radius
        # roots mapped from the lower half plane may sit outside the disc
        inside |= np.abs(lam_ok.conj() - 1j * w.centre) <= w.radius
        good = _dedupe(lam_ok[inside], 1e-8, scale)
        # candidates in the trusted disc whose Newton iteration failed
        nfail = int(np.sum(~ok & (np.abs(pre - 1j * w.centre) <= w.radius)))
        found.append((good, nfail))
    (a, fa), (b, _) = found
    conf = _match(a, b, match_tol, scale)
    w.roots = a[conf]
    w.rejected = int(np.sum(~conf)) + fa


#: roots outside the certified band have Re < -SIGMA_TAU / tau
SIGMA_TAU = 2.0


def _band_top(sys: DelaySystem, count: int, omega_max: float | None, sigma: float | None = None) -> float:
    """Upper end (rad/s) of the band in which root locations are predicted.

    A root lambda of det(P(lambda) - e^{-lambda tau} U V^T) needs
    ||e^{-lambda tau} V^T P(lambda)^{-1} U|| >= 1.  With the loop transfer in
    pole-residue form (:meth:`DelaySystem.transfer_fast`) the gain bound of
    :func:`chatterlab.frequency._bounds.certified_band` excludes every frequency above the
    returned value for roots with Re lambda >= -SIGMA_TAU / tau: the band
    follows from the loop, not from the highest structural pole.
    """
    if omega_max is not None:
        return omega_max
    floor_ = max(2.0 * np.pi * (2 * count + 4) / (sys.tau * sys.r), 20.0 / sys.tau)
    cert = certified_top(sys, -SIGMA_TAU / sys.tau if sigma is None else sigma)
    if cert is not None:
        return max(cert, floor_)
    p = sys.delay_free_poles()
    pmax = float(np.max(np.abs(p))) if p.size else 0.0
    return max(2.0 * pmax, floor_)


def certified_top(sys: DelaySystem, sigma: float) -> float | None:
    """Frequency (rad/s) above which no root with Re >= ``sigma`` exists (gain
    bound on the loop transfer), or None if it cannot be bounded (no
    well-conditioned pole-residue form of the loop transfer)."""
    key = f"band_top:{float(sigma)!r}"
    if key in sys._cache:
        return sys._cache[key]
    from ._bounds import PoleResidue, certified_band

    sys.transfer_fast(np.zeros(0, complex))  # fills the partial-fraction cache
    pf = sys._cache.get("pf")
    out: float | None = None
    if pf is not None and sys.r:
        p, L, R = pf
        pos = np.abs(p)[np.abs(p) > 0]
        w_low = 1e-3 * float(pos.min()) if pos.size else 1e-3
        r = sys.r
        Z = np.zeros((r, r))
        # ||e^{-lam tau} H(lam)|| <= e^{-sigma tau} ||H(lam)|| for Re lam >= sigma
        bd = certified_band(
            PoleResidue(p, L, R, Z), np.eye(r), Z, Z, float(np.exp(-sigma * sys.tau)), w_low, shift=sigma
        )
        if bd.certified:
            out = float(bd.hi)
    sys._cache[key] = out
    return out


def _branch_mu(sys: DelaySystem, lam: ComplexArray) -> ComplexArray:
    """Eigenvalues of H(lam), shape (len(lam), r); non-finite where H is singular.

    Evaluated in chunks, so memory stays bounded for long grids."""
    chunk = max(1024, _CHUNK_BYTES // (16 * max(sys.A.shape[0], 1)))
    if lam.size > chunk:
        return np.concatenate([_branch_mu(sys, lam[i : i + chunk]) for i in range(0, lam.size, chunk)])
    H = sys.transfer_fast(lam)
    with np.errstate(all="ignore"):
        if sys.r == 1:
            return H[:, :, 0]
        ok = np.all(np.isfinite(H), axis=(1, 2))
        mu = np.full(H.shape[:2], np.nan + 0j)
        if np.any(ok):
            mu[ok] = np.linalg.eigvals(H[ok])
        return mu


#: most frequencies the root prediction samples on the axis (bounds memory to
#: about 100 MB: the grid, the tracked eigenvalues and one chunk of the transfer)
AXIS_GRID_MAX = 2_000_000
#: bytes of the transfer's intermediate arrays per chunk of frequencies
_CHUNK_BYTES = 32_000_000


class _TooLarge(Exception):
    """A search that cannot complete within its memory limit (reported as a status)."""


def _axis_grid(sys: DelaySystem, top: float) -> FloatArray:
    """Frequencies in [0, top] (rad/s): step pi/(4 tau) plus refinement at poles."""
    tau = sys.tau
    step = min(math.pi / (4.0 * tau), top / 200.0)
    n = top / step
    if n > AXIS_GRID_MAX:
        raise _TooLarge(
            f"the delay {tau:.4g} s needs {n:.3g} axis samples up to {top / 2 / math.pi:.4g} Hz"
            f" (limit {AXIS_GRID_MAX:.0e}): the roots are too dense to enumerate; pass omega_max"
            " to narrow the band"
        )
    pts = [np.linspace(0.0, top, int(math.ceil(top / step)) + 1)]
    offs = np.array([-8, -4, -2, -1, -0.5, -0.25, 0, 0.25, 0.5, 1, 2, 4, 8])
    p = sys.delay_free_poles()
    for z in p[p.imag >= 0]:
        d = max(abs(z.real), 1e-9 * abs(z), 1e-12)
        loc = z.imag + d * offs
        pts.append(loc[(loc >= 0) & (loc <= top)])
    return np.unique(np.concatenate(pts))


def _track_branches(mu: ComplexArray) -> ComplexArray:
    """Reorder the columns of ``mu`` (shape (G, r)) into continuous branches."""
    G, r = mu.shape
    if r == 1 or G < 2:
        return mu
    perms = np.array(list(itertools.permutations(range(r)))) if r <= 4 else None
    out = np.empty_like(mu)
    order = np.arange(r)
    out[0] = mu[0]
    if perms is not None:
        # best raw-to-raw matching of consecutive samples, vectorised
        with np.errstate(invalid="ignore"):
            cost = np.abs(mu[1:, perms] - mu[:-1, None, :]).sum(axis=2)
        cost[~np.isfinite(cost)] = np.inf
        best = perms[np.argmin(cost, axis=1)]
        for i in range(1, G):
            order = best[i - 1][order]
            out[i] = mu[i, order]
        return out
    for i in range(1, G):  # pragma: no cover - r > 4 is unusual
        prev = out[i - 1]
        cur = list(range(r))
        for j in range(r):
            k = min(cur, key=lambda c: abs(mu[i, c] - prev[j]))
            order[j] = k
            cur.remove(k)
        out[i] = mu[i, order]
    return out


def _predict(sys: DelaySystem, top: float) -> tuple[ComplexArray, FloatArray]:
    """Predicted root locations from the phase condition along each branch.

    With ``mu_j(j w)`` the eigenvalues of ``H(j w)`` tracked continuously along
    the axis and ``phi_j`` their unwrapped phase, roots near the axis lie
    where ``tau w - phi_j(w) = 2 pi k`` (the phase condition of
    ``lam tau = log mu_j(lam) + 2 pi i k``); one Newton step of that scalar
    equation from the crossing ``j w*`` gives
    ``lam ~ j w* + log|mu_j| / (tau - s)``, ``s = d log mu_j / d lam``.
    Added: sign changes and dips of ``det Delta(x)`` on the real axis and the
    delay-free poles.  Returns the estimates (upper half plane) and an
    uncertainty (rad/s; ``inf`` where ``|s| > tau / 2``, i.e. where the
    long-delay picture does not hold).
    """
    tau = sys.tau
    w = _axis_grid(sys, top)
    mu = _track_branches(_branch_mu(sys, 1j * w))  # type: ignore[arg-type]  # numpy stubs: 1j * float64 is complexfloating[Any, Any]
    ests = []
    uncs = []
    with np.errstate(all="ignore"):
        for j in range(mu.shape[1]):
            m = mu[:, j]
            ok = np.isfinite(m) & (m != 0)
            if np.sum(ok) < 2:
                continue
            ww = w[ok]
            la = np.log(np.abs(m[ok]))
            ph = np.unwrap(np.angle(m[ok]))
            psi = (tau * ww - ph) / (2.0 * np.pi)
            lev = np.floor(psi)
            cross = np.flatnonzero(lev[1:] != lev[:-1])
            if cross.size == 0:
                continue
            dla = np.gradient(la, ww)
            dph = np.gradient(ph, ww)
            idx_list = []
            kk_list = []
            for i in cross:
                lo_, hi_ = sorted((psi[i], psi[i + 1]))
                ks = np.arange(math.floor(lo_) + 1, math.floor(hi_) + 1)
                idx_list.append(np.full(ks.shape, i))
                kk_list.append(ks)
            ii = np.concatenate(idx_list)
            kk = np.concatenate(kk_list)
            t = (kk - psi[ii]) / (psi[ii + 1] - psi[ii])
            wstar = ww[ii] + t * (ww[ii + 1] - ww[ii])
            lam_abs = la[ii] + t * (la[ii + 1] - la[ii])
            # d log mu / d lam on the axis = -i d log mu / d w
            s = -1j * ((dla[ii] + t * (dla[ii + 1] - dla[ii])) + 1j * (dph[ii] + t * (dph[ii + 1] - dph[ii])))
            corr = lam_abs / (tau - s)
            est = 1j * wstar + corr
            ratio = np.abs(s) / tau
            unc = np.where(ratio < 0.5, 2.0 * ratio * np.abs(corr) + 1e-12, np.inf)
            good = np.isfinite(est) & (est.real * tau > -_EXP_LIMIT)
            ests.append(est[good])
            uncs.append(unc[good])
    lam = np.concatenate(ests) if ests else np.zeros(0, complex)
    unc = np.concatenate(uncs) if uncs else np.zeros(0)
    # the real axis (two real roots may share a branch index)
    p = sys.delay_free_poles()
    with np.errstate(all="ignore"):
        a_hi = (
            max(float(np.max(lam.real)) if lam.size else 0.0, float(np.max(p.real)) if p.size else 0.0, 0.0)
            + 10.0 / tau
        )
    x = np.linspace(a_hi - 60.0 / tau, a_hi, 601)
    with np.errstate(all="ignore"):
        sg, ld = np.linalg.slogdet(sys.delta(x).real)
    flip = np.flatnonzero(sg[1:] * sg[:-1] < 0)
    dips = np.flatnonzero((ld[1:-1] < ld[:-2]) & (ld[1:-1] < ld[2:])) + 1
    xr = np.concatenate([0.5 * (x[flip] + x[flip + 1]), x[dips]])
    # the delay-free poles: starts for the structural roots when the delay
    # term is weak or the delay short (where the sweeps do not contract)
    pp = p[p.imag >= 0]
    lam = np.concatenate([lam, xr.astype(complex), pp])
    unc = np.concatenate([unc, np.full(xr.shape, x[1] - x[0]), np.zeros(pp.shape)])
    lam = np.where(lam.imag < 0, lam.conj(), lam)
    return lam, unc


def _n_for_radius(R: float, tau: float) -> int:
    return int(math.ceil(R * tau)) + _N_EXTRA


def _make_window(centre: float, R: float, tau: float) -> _Window:
    N = _n_for_radius(R, tau)
    return _Window(centre, R, N, int(math.ceil(_N2_FACTOR * N)))


def _window_size(sys: DelaySystem, R: float) -> int:
    N2 = int(math.ceil(_N2_FACTOR * _n_for_radius(R, sys.tau)))
    return sys.A.shape[0] + N2 * sys.r


def _spectral(
    sys: DelaySystem,
    count: int,
    omega_max: float | None,
    n_nodes: int | None,
    match_tol: float,
    max_windows: int,
    t0: float,
) -> RootsResult:
    tau = sys.tau
    scale = _root_scale(sys)
    if n_nodes is not None:
        N = int(n_nodes)
        win = _Window(0.0, N / tau, N, int(math.ceil(_N2_FACTOR * N)))
        _solve_window(sys, win, match_tol)
        return _finish(sys, [win], count, "spectral", t0, extra="(N fixed by caller)")
    top = _band_top(sys, count, omega_max)
    est, unc = _predict(sys, top)
    p = sys.delay_free_poles()
    pmax = float(np.max(np.abs(p))) if p.size else 0.0
    re_sorted = np.sort(est.real)[::-1]
    a_c = float(re_sorted[min(2 * count + 1, re_sorted.size - 1)]) if est.size else 0.0

    windows: list[_Window] = []
    single = True
    method = "spectral"
    note = ""
    for _round in range(20):
        delta = 0.25 / tau + 0.05 * abs(a_c)
        lo = a_c - delta
        sel = est.real + np.minimum(unc, 1e6) >= lo
        # only roots right of lo matter: cover the prediction clipped to lo
        need = np.maximum(est.real[sel], lo) + 1j * est.imag[sel]
        # a prediction whose fixed-point iteration did not settle is only
        # known to lie near the axis: cover the band from its estimate to lo
        cov = np.zeros(need.shape, dtype=bool)
        for win in windows:
            cov |= np.abs(need - 1j * win.centre) <= win.radius
        if windows and np.all(cov):
            roots = _collect(windows, scale)
            if roots.size >= count:
                a_new = float(np.sort(roots.real)[::-1][count - 1])
                if a_new >= a_c - 1e-12 * scale:
                    break
                a_c = a_new
                continue
            # everything predicted is covered but too few roots: lower the bar
            a_c = lo - delta
            continue
        todo = need[~cov]
        if single:
            R = max(1.1 * float(np.max(np.abs(need))) if need.size else 0.0, 8.0 / tau)
            if pmax * tau < 60.0:
                # short delay: the structural roots are cheap to include
                R = max(R, 1.2 * pmax + 4.0 / tau)
            if windows:
                R = max(R, 1.3 * windows[0].radius)
            if _window_size(sys, R) <= _DENSE_MAX:
                windows = [_make_window(0.0, R, tau)]
                _solve_window(sys, windows[0], match_tol)
                roots = _collect(windows, scale)
                if roots.size >= count:
                    a_c = min(a_c, float(np.sort(roots.real)[::-1][count - 1]))
                continue
            single = False
            method = "spectral-windowed"
        new = _cover(todo, tau, sys)
        for win in new:
            _solve_window(sys, win, match_tol)
        windows.extend(new)
        if len(windows) > max_windows:
            return _finish(
                sys,
                windows,
                count,
                method,
                t0,
                fail=f"more than {max_windows} frequency windows needed; "
                "pass omega_max to narrow the band or use method='branch'",
            )
        roots = _collect(windows, scale)
        if roots.size >= count:
            a_c = min(a_c, float(np.sort(roots.real)[::-1][count - 1]))
    else:
        note = "window placement did not settle after 20 rounds"
    return _finish(sys, windows, count, method, t0, fail=note)


def _cover(pts: ComplexArray, tau: float, sys: DelaySystem) -> list[_Window]:
    """Greedy cover of predicted root locations by discs centred on the imaginary axis."""
    out: list[_Window] = []
    pts = pts[np.argsort(pts.imag)]
    base = 36.0 / tau  # radius giving N of about 48
    todo = np.ones(pts.shape, dtype=bool)
    while np.any(todo):
        i = int(np.flatnonzero(todo)[0])
        near = pts[todo][:16]
        amag = float(np.max(np.abs(near.real)))
        R = max(base, 1.25 * amag)
        half = math.sqrt(max(R * R - amag * amag, 0.0))
        c = float(pts[i].imag) + 0.9 * half
        if pts[i].imag <= half:  # near the origin: real arithmetic, real roots too
            c = 0.0
            R = max(R, 1.05 * abs(pts[i]))
        win = _make_window(c, R, tau)
        hit = np.abs(pts - 1j * c) <= R
        hit[i] = True  # guarantees progress
        todo &= ~hit
        out.append(win)
    return out


def _collect(windows: list[_Window], scale: float) -> ComplexArray:
    allr = [w.roots for w in windows if w.roots.size]
    if not allr:
        return np.zeros(0, complex)
    return _dedupe(np.concatenate(allr), 1e-8, scale)


def _finish(
    sys: DelaySystem,
    windows: list[_Window],
    count: int,
    method: str,
    t0: float,
    *,
    fail: str = "",
    extra: str = "",
) -> RootsResult:
    scale = _root_scale(sys)
    roots = _collect(windows, scale)
    roots = roots[np.lexsort((roots.imag, -roots.real))][:count]
    rejected = sum(w.rejected for w in windows)
    N = max((w.N for w in windows), default=0)
    N2 = max((w.N2 for w in windows), default=0)
    fails = "; ".join(w.failed for w in windows if w.failed)
    if fail or fails:
        status = "not_converged"
        msg = "; ".join(x for x in (fail, fails) if x)
    elif roots.size < count:
        status = "not_converged"
        msg = f"only {roots.size} of {count} roots confirmed by both discretisations"
    else:
        status = "converged"
        msg = (
            f"{roots.size} roots confirmed by N={N} and N2={N2} after Newton "
            f"({len(windows)} window(s), {rejected} candidate(s) rejected)"
        )
    if extra:
        msg = f"{msg} {extra}"
    return _make_result(
        roots,
        method=method,
        n_nodes=(N, N2),
        rejected=rejected,
        status=status,
        message=msg,
        n_windows=len(windows),
        t0=t0,
    )


# ---------------------------------------------------------------------------
# branch enumeration
# ---------------------------------------------------------------------------
def _newton_distinct(sys: DelaySystem, starts: ComplexArray, known: ComplexArray) -> tuple[ComplexArray, int]:
    """Newton from each start; a start that lands on a root already claimed by
    another start is restarted with the claimed roots deflated, so that one
    start yields one distinct root.  Returns (all distinct roots, failures)."""
    scale = _root_scale(sys)
    lam, conv = _newton(sys, starts)
    roots = _dedupe(np.concatenate([known, _canonical(lam[conv], scale)]), 1e-8, scale)
    rejected = int(np.sum(~conv))
    ndup = int(np.sum(conv)) + known.size - roots.size
    if ndup <= 0:
        return roots, rejected
    # which starts collided: those whose root is closer to another start
    good = _canonical(lam, scale)
    d_own = np.abs(good - _canonical(starts, scale))
    dup_idx = []
    for z in roots:
        hit = np.flatnonzero(conv & (np.abs(good - z) <= 1e-8 * max(abs(z), scale)))
        if hit.size > 1:
            dup_idx.extend(hit[np.argsort(d_own[hit])][1:].tolist())
    if not dup_idx:
        return roots, rejected
    defl = np.concatenate([roots, roots[roots.imag != 0].conj()])
    lam2, conv2 = _newton(sys, starts[dup_idx], deflate=defl, maxiter=60)
    if np.any(conv2):
        # polish without deflation (deflation only steers the iteration)
        lam3, conv3 = _newton(sys, lam2[conv2])
        roots = _dedupe(np.concatenate([roots, _canonical(lam3[conv3], scale)]), 1e-8, scale)
    return roots, rejected


def _branch(sys: DelaySystem, count: int, omega_max: float | None, t0: float) -> RootsResult:
    tau = sys.tau
    top = _band_top(sys, count, omega_max)
    est, unc = _predict(sys, top)
    # Newton from the predictions that may end up among the rightmost
    re = est.real + np.minimum(unc, 1e6)
    take = np.argsort(-re)
    nstart = min(est.size, 4 * count + 16)
    roots, rejected = _newton_distinct(sys, est[take[:nstart]], np.zeros(0, complex))
    # widen until the count-th root is safely right of every unused prediction
    while nstart < est.size and roots.size:
        srt = np.sort(roots.real)[::-1]
        a_c = float(srt[min(count, srt.size) - 1])
        more = take[nstart:][re[take[nstart:]] >= a_c - 0.5 / tau - 0.1 * abs(a_c)]
        if more.size == 0 and roots.size >= count:
            break
        if more.size == 0:
            more = take[nstart : nstart + 4 * count + 16]
        roots, rej = _newton_distinct(sys, est[more], roots)
        rejected += rej
        nstart += more.size
        take = np.concatenate(
            [
                take[: nstart - more.size],
                more,
                np.setdiff1d(take[nstart - more.size :], more, assume_unique=True),
            ]
        )
    roots = roots[np.lexsort((roots.imag, -roots.real))][:count]
    status = "converged" if roots.size >= count else "not_converged"
    msg = (
        f"{roots.size} roots by Newton from {nstart} of {est.size} branch predictions "
        f"up to {top:.6g} rad/s ({rejected} start(s) without convergence)"
    )
    return _make_result(
        roots, method="branch", n_nodes=(0, 0), rejected=rejected, status=status, message=msg, t0=t0
    )


# ---------------------------------------------------------------------------
# public entry points
# ---------------------------------------------------------------------------
def _no_delay(sys: DelaySystem, count: int, t0: float) -> RootsResult:
    try:
        ev = np.linalg.eigvals(sys.A)
    except np.linalg.LinAlgError as exc:
        return _make_result(
            [],
            method="eig",
            n_nodes=(0, 0),
            rejected=0,
            status="not_converged",
            message=f"eigenvalue solver failed: {exc}",
            t0=t0,
        )
    scale = _root_scale(sys)
    ev = ev[ev.imag >= -1e-12 * np.maximum(np.abs(ev), scale)]
    ev = np.where(np.abs(ev.imag) <= 1e-12 * np.maximum(np.abs(ev), scale), ev.real + 0j, ev)
    ev = ev[np.lexsort((ev.imag, -ev.real))]
    total = ev.size
    ev = ev[:count]
    msg = f"no delay: eigenvalues of the linearised (companion) problem, {total} in Im >= 0"
    if total < count:
        msg += f"; only {total} roots exist (count={count})"
    return _make_result(ev, method="eig", n_nodes=(0, 0), rejected=0, status="converged", message=msg, t0=t0)


def _check_count(count: Any) -> int:
    if isinstance(count, bool) or not isinstance(count, int | np.integer):
        raise InputError(f"count must be an integer >= 1 (got {count!r})")
    if count < 1:
        raise InputError(f"count must be >= 1 (got {count})")
    return int(count)


def _blas_limits() -> Any:
    """Single-threaded BLAS for the many small dense problems, if possible.

    The matrices here are a few hundred wide; multi-threaded OpenBLAS gains
    nothing on them and loses 10x or more when the cores are shared.  Uses
    ``threadpoolctl`` when it is installed (optional), else does nothing.
    """
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


def _dispatch(
    sys: DelaySystem,
    count: Any,
    method: str,
    omega_max: float | None,
    n_nodes: int | None,
    match_tol: float,
    max_windows: int,
) -> RootsResult:
    t0 = time.perf_counter()
    count = _check_count(count)
    if method not in ("auto", "spectral", "branch"):
        raise InputError(f"method must be 'auto', 'spectral' or 'branch' (got {method!r})")
    if omega_max is not None:
        om = float(omega_max)
        if not math.isfinite(om) or om <= 0:
            raise InputError(f"omega_max must be finite and > 0 rad/s (got {omega_max!r})")
        omega_max = om
    if n_nodes is not None:
        if isinstance(n_nodes, bool) or not isinstance(n_nodes, int | np.integer) or n_nodes < 2:
            raise InputError(f"n_nodes must be an integer >= 2 (got {n_nodes!r})")
    with _blas_limits():
        if not sys.has_delay:
            # every root is an eigenvalue of the linearisation: complete
            return dataclasses.replace(_no_delay(sys, count, t0), complete_above=-math.inf)
        try:
            if omega_max is not None or n_nodes is not None:
                if method == "branch":
                    return _branch(sys, count, omega_max, t0)
                return _spectral(sys, count, omega_max, n_nodes, match_tol, max_windows, t0)
            # the band follows from the loop: certified for Re >= sigma, and
            # widened until it holds the count rightmost roots found
            sigma = -SIGMA_TAU / sys.tau
            top = _band_top(sys, count, None, sigma)
            for attempt in range(4):
                if method == "branch":
                    res = _branch(sys, count, top, t0)
                else:
                    res = _spectral(sys, count, top, None, match_tol, max_windows, t0)
                low = float(res.roots.real.min()) if res.roots.size else sigma
                if not res.converged or low >= sigma:
                    break
                sigma2 = low - 1.0 / sys.tau
                top2 = _band_top(sys, count, None, sigma2)
                if top2 <= top * (1 + 1e-9):
                    sigma = sigma2  # the band searched already holds every root right of sigma2
                    break
                if attempt == 3:
                    break  # the claim stays the one proven for the band searched
                top, sigma = top2, sigma2
            cert = certified_top(sys, sigma) is not None
            note = (
                f"; band 0..{top / 2 / math.pi:.5g} Hz holds every root with Re >= {sigma:.4g} 1/s"
                if cert
                else f"; band 0..{top / 2 / math.pi:.5g} Hz (not certified by the gain bound)"
            )
            return dataclasses.replace(
                res, message=res.message + note, band_top=top, complete_above=sigma if cert else math.nan
            )
        except _TooLarge as exc:
            return _make_result(
                np.zeros(0, complex),
                method=method,
                n_nodes=(0, 0),
                rejected=0,
                status="not_converged",
                message=str(exc),
                t0=t0,
            )


def characteristic_roots(
    M: ArrayLike,
    C: ArrayLike,
    K: ArrayLike,
    *,
    DP: ArrayLike | None = None,
    DV: ArrayLike | None = None,
    DO: ArrayLike | tuple[ArrayLike, ArrayLike] | None = None,
    tau: float | None = None,
    count: int = 6,
    method: str = "auto",
    omega_max: float | None = None,
    n_nodes: int | None = None,
    match_tol: float = 1e-6,
    max_windows: int = 60,
) -> RootsResult:
    """Rightmost characteristic roots of the delayed closed loop (Eq. 2.1, 2.23).

    Solves :math:`\\det[\\lambda^2 M + \\lambda (C - D_V) + K - D_P - D_O
    e^{-\\lambda\\tau}] = 0` for the ``count`` roots of largest real part.

    Parameters
    ----------
    M, C, K : array_like, shape (n, n)
        Inertia (kg, symmetric positive definite), damping (N s/m) and
        stiffness (N/m).
    DP, DV : array_like, shape (n, n), optional
        Proportional (N/m) and velocity (N s/m) feedback matrices.
    DO : array_like, shape (n, n), or tuple ``(U, V)`` of arrays of shape (n, r), optional
        Delayed feedback (N/m), dense or factored ``DO = U @ V.T``.  ``None``
        or zero: no delay, the quadratic eigenvalue problem is solved.
    tau : float, optional
        Delay in s, required (> 0) with ``DO``.
    count : int
        Number of rightmost roots wanted (upper half plane and real axis;
        conjugates omitted).
    method : {"auto", "spectral", "branch"}
        ``"auto"`` and ``"spectral"``: Chebyshev collocation of the
        infinitesimal generator (one discretisation through the origin when
        small, frequency windows otherwise); ``"branch"``: enumeration along
        the branches :math:`\\lambda\\tau = \\log\\mu_j + 2\\pi i k`.
    omega_max : float, optional
        Upper end (rad/s) of the frequency band scanned for root locations.
        Default: from the loop gain bound, the frequency above which no root
        with Re >= -2/tau exists (widened to hold the ``count`` rightmost
        roots; reported as ``band_top`` and ``complete_above``), or
        ``2 |p|_max`` of the delay-free poles when no bound is available.
    n_nodes : int, optional
        Force a single discretisation through the origin with this ``N``
        (``N2 = ceil(1.5 N)``); default chooses ``N`` from ``omega tau``.
    match_tol : float
        Relative tolerance for a root to count as reproduced by the finer
        discretisation (after Newton both are exact to ~1e-13, so 1e-6 only
        guards against matching neighbouring roots).
    max_windows : int
        Give up (``status="not_converged"``) beyond this many frequency windows.

    Returns
    -------
    RootsResult
        ``roots`` in rad/s sorted by decreasing real part, ``abscissa``,
        ``method``, ``n_nodes = (N, N2)``, ``rejected``, ``status``, ``message``.

    Raises
    ------
    InputError
        Invalid input (see :func:`make_system`), ``count < 1``, unknown method.

    Notes
    -----
    The discretised generator acts on the ODE state ``(q, qdot)`` at
    :math:`\\theta = 0` and on the delayed output :math:`z = V^T q` at ``N``
    Chebyshev nodes of :math:`[-\\tau, 0)`; the collocation polynomial of
    ``z`` equals :math:`V^T q` at :math:`\\theta = 0`.  Its size is
    :math:`2n + N r`.  In a window centred at :math:`j\\omega_0` the history is
    represented by the envelope :math:`e^{-j\\omega_0\\theta} z(\\theta)`
    (the generator of the equation for :math:`e^{-j\\omega_0 t} q(t)`,
    shifted back by :math:`j\\omega_0`), so ``N`` grows with the window radius
    times :math:`\\tau`, not with :math:`\\omega_0\\tau`.  Eigenvalues with
    :math:`|\\lambda - j\\omega_0| \\le N/\\tau` are trusted (half the
    Chebyshev resolution limit), refined by Newton, and kept when the
    discretisation with ``N2`` reproduces them.

    References
    ----------
    .. [1] E. Wittbrodt, K. Kaliński, seed paper, Eqs. 2.1, 2.22-2.28.
    .. [2] D. Breda, S. Maset, R. Vermiglio, SIAM J. Sci. Comput. 27(2),
       482-495, 2005.
    .. [3] L. N. Trefethen, *Spectral Methods in MATLAB*, SIAM 2000.
    """
    sys = make_system(M, C, K, DP=DP, DV=DV, DO=DO, tau=tau)
    return _dispatch(sys, count, method, omega_max, n_nodes, match_tol, max_windows)


def characteristic_roots_system(
    sys: DelaySystem,
    *,
    count: int = 6,
    method: str = "auto",
    omega_max: float | None = None,
    n_nodes: int | None = None,
    match_tol: float = 1e-6,
    max_windows: int = 60,
) -> RootsResult:
    """:func:`characteristic_roots` for a prepared :class:`DelaySystem` (its
    partial fractions and band are then shared with, e.g.,
    :func:`chatterlab.frequency.rhp_count_system`)."""
    return _dispatch(sys, count, method, omega_max, n_nodes, match_tol, max_windows)


def characteristic_roots_first_order(
    A0: ArrayLike,
    A1: ArrayLike | tuple[ArrayLike, ArrayLike] | None,
    tau: float | None,
    *,
    count: int = 6,
    method: str = "auto",
    omega_max: float | None = None,
    n_nodes: int | None = None,
    match_tol: float = 1e-6,
    max_windows: int = 60,
) -> RootsResult:
    """Rightmost roots of :math:`\\det(\\lambda I - A_0 - A_1 e^{-\\lambda\\tau}) = 0`.

    First-order entry point (e.g. the scalar test equation
    :math:`\\dot x = a x + b x(t-\\tau)`), same algorithms and result object
    as :func:`characteristic_roots`.

    Parameters
    ----------
    A0 : array_like, shape (n, n)
        Undelayed state matrix (1/s).
    A1 : array_like, shape (n, n), or tuple ``(U, V)``, or None
        Delayed state matrix (1/s), dense or factored ``A1 = U @ V.T``.
    tau : float or None
        Delay in s.
    count, method, omega_max, n_nodes, match_tol, max_windows
        As in :func:`characteristic_roots`.

    Returns
    -------
    RootsResult

    References
    ----------
    .. [1] D. Breda, S. Maset, R. Vermiglio, SIAM J. Sci. Comput. 27(2),
       482-495, 2005.
    """
    sys = make_first_order_system(A0, A1, tau)
    return _dispatch(sys, count, method, omega_max, n_nodes, match_tol, max_windows)
