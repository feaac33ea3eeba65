"""The delay system: one value for the delay equation every root method solves.

The frozen closed loop of Wittbrodt & Kaliński (Eq. 2.1 with the feedback
matrix of Eq. 2.23; time domain Eqs. 2.25, 2.28) has the characteristic matrix

.. math::

    \\Delta(\\lambda) = P(\\lambda) - U V^T e^{-\\lambda\\tau},\\qquad
    P(\\lambda) = \\lambda^2 M + \\lambda (C - D_V) + (K - D_P),

with the delayed feedback :math:`D_O = U V^T` of small rank :math:`r` (the
cutting process acts through a few coordinates of a coupling element).
:class:`DelaySystem` holds it once, validated, with its first-order
linearisation; :func:`make_system` builds it from the seven matrices
``M, C, K, DP, DV, DO, tau`` (the only place they are read),
:func:`make_first_order_system` from :math:`\\dot x = A_0 x + A_1 x(t-\\tau)`,
:func:`loop_system` from a :class:`chatterlab.process.ClosedLoop`.  Every
root method (:func:`chatterlab.frequency.characteristic_roots`,
:func:`chatterlab.frequency.rhp_count`, :func:`chatterlab.frequency.newton_refine`)
takes one such value (:func:`as_delay_system`), never loose matrices.

Several delays.  A machine with an active damper (``[[actuator]]``, whose
delayed term has the controller's own delay T_a beside the cut's T) has

.. math::

    \\Delta(\\lambda) = P(\\lambda) - \\sum_i U_i V_i^T e^{-\\lambda\\tau_i}
                     = P(\\lambda) - U\\,E(\\lambda)\\,V^T,\\qquad
    E = \\operatorname{diag}(e^{-\\lambda\\tau_k}),

one delay per column of ``U``, ``V`` (:attr:`DelaySystem.taus`; the paper's
Table 1 gives every feedback transfer its own time constant).  A system whose
delayed terms share one delay is the single-delay system above, exactly as
before (``taus`` None); :func:`make_system` takes several delayed terms as
``delays=[(DO_1, tau_1), ...]``, :func:`loop_system` builds them from a loop
with actuators.  Its ``tau`` is then the largest delay, which sets the
sampling of the argument principle; the factored form of the phase (which
multiplies the loop transfer by one scalar :math:`e^{-\\lambda\\tau}`) does not
apply, so :meth:`DelaySystem.partial_fractions` is None and the count samples
:math:`\\det\\Delta` directly; the root search is
:func:`chatterlab.frequency._roots.characteristic_roots`' several-delay route.

References
----------
.. [1] E. Wittbrodt, K. J. Kaliński, "Transient vibration of unsteady linear
   closed loop systems" (the seed paper of chatterlab), Eqs. 2.1, 2.22-2.28.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, ParamSpec, TypeVar

import numpy as np
import scipy.linalg as sla
from numpy.typing import ArrayLike, NDArray

from chatterlab.errors import InputError

from ._checks import as_real_matrix, check_tau, factor_delayed

P = ParamSpec("P")
R = TypeVar("R")

__all__ = [
    "DelaySystem",
    "loop_system",
    "loop_systems",
    "make_system",
    "make_first_order_system",
    "as_delay_system",
]

ComplexArray = NDArray[np.complex128]
FloatArray = NDArray[np.float64]

#: bytes of the transfer's intermediate arrays per chunk of frequencies
_CHUNK_BYTES = 32_000_000


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
    taus : ndarray, shape (r,), or None
        Several delays: the delay of each column of ``U``, ``V`` (s), and
        ``tau`` the largest; None when every delayed term has the delay
        ``tau`` (the single-delay system).
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
    taus: NDArray[np.float64] | None = None

    @property
    def multi_delay(self) -> bool:
        """The delayed terms have several delays (:attr:`taus`)."""
        return self.taus is not None

    @property
    def delays(self) -> tuple[float, ...]:
        """The distinct delays, s, ascending (empty without a delayed term)."""
        if not self.has_delay:
            return ()
        if self.taus is None:
            return (self.tau,)
        return tuple(float(t) for t in np.unique(self.taus))

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
        return _horner(self.coeffs, lam)

    def dP(self, lam: ArrayLike) -> ComplexArray:
        """Derivative :math:`P'(\\lambda)`, shape ``lam.shape + (n, n)``."""
        return _horner(self.coeffs, lam, derivative=True)

    def P0(self, lam: ArrayLike) -> ComplexArray:
        """Open-loop structure :math:`P_0(\\lambda)` (no feedback at all), shape ``lam.shape + (n, n)``."""
        return _horner(self.open_coeffs, lam)

    def delta(self, lam: ArrayLike) -> ComplexArray:
        """Characteristic matrix :math:`\\Delta(\\lambda)`, shape ``lam.shape + (n, n)``."""
        lam = np.asarray(lam, dtype=complex)
        out = self.P(lam)
        if self.taus is not None:
            with np.errstate(over="ignore", invalid="ignore"):
                e = np.exp(-lam[..., None] * self.taus)  # (..., r)
                return out - (self.U * e[..., None, :]) @ self.V.T
        if self.has_delay:
            with np.errstate(over="ignore", invalid="ignore"):
                e = np.exp(-lam * self.tau)[..., None, None]
                out = out - e * self.DO
        return out

    def ddelta(self, lam: ArrayLike) -> ComplexArray:
        """Derivative :math:`\\Delta'(\\lambda)`, shape ``lam.shape + (n, n)``."""
        lam = np.asarray(lam, dtype=complex)
        out = self.dP(lam)
        if self.taus is not None:
            with np.errstate(over="ignore", invalid="ignore"):
                e = self.taus * np.exp(-lam[..., None] * self.taus)
                return out + (self.U * e[..., None, :]) @ self.V.T
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
        X = batched_solve(Pm, Ub)
        return np.einsum("ki,...kj->...ij", self.V, X)

    def transfer_fast(self, lam: ArrayLike) -> ComplexArray:
        r""":math:`H(\lambda)` by partial fractions of the linearisation.

        ``H = (Cz S) diag(1/(lam - p)) (S^{-1} B)`` with ``A = S diag(p) S^{-1}``;
        O(m r^2) per point.  Falls back to :meth:`transfer` when the
        eigenvector matrix is ill-conditioned (cond > 1e8).  Used only for
        predictions (root locations are always refined on Delta itself).
        """
        lam = np.asarray(lam, dtype=complex)
        pf = self.partial_fractions()
        if pf is None:
            return self.transfer(lam)
        p, L, R = pf
        with np.errstate(all="ignore"):
            g = 1.0 / (lam[..., None] - p)
        # sum_k L_ik g_k R_kj as one product over k (a GEMM; the 3-operand einsum is 2-4x slower)
        LR = self.cached("pf_outer", lambda: L[:, :, None] * R[None, :, :])
        return np.tensordot(g, LR, axes=([-1], [1]))

    def loop_eigenvalues(self, lam: ArrayLike) -> ComplexArray:
        """Eigenvalues :math:`\\mu_j(\\lambda)` of the loop transfer :math:`H(\\lambda)`
        (:meth:`transfer_fast`), shape ``(len(lam), r)``; NaN where ``H`` is
        not finite.  Evaluated in chunks, so memory stays bounded for long
        grids."""
        lam = np.asarray(lam, dtype=complex)
        chunk = max(1024, _CHUNK_BYTES // (16 * max(self.A.shape[0], 1)))
        if lam.size > chunk:
            return np.concatenate(
                [self.loop_eigenvalues(lam[i : i + chunk]) for i in range(0, lam.size, chunk)]
            )
        H = self.transfer_fast(lam)
        with np.errstate(all="ignore"):
            if self.r == 1:
                return H[:, :, 0]
            ok = np.all(np.isfinite(H), axis=(1, 2))
            mu = np.full(H.shape[:2], np.nan + 0j)
            if np.any(ok):
                mu[ok] = np.linalg.eigvals(H[ok])
            return mu

    def partial_fractions(self) -> tuple[ComplexArray, ComplexArray, ComplexArray] | None:
        """``(p, L, R)`` with :math:`H(\\lambda) = L \\operatorname{diag}(1/(\\lambda - p)) R`
        (from ``A = S diag(p) S^{-1}``: ``L = Cz S``, ``R = S^{-1} B``), or
        None when the eigenvector matrix is ill-conditioned (cond > 1e8), and
        for several delays (:attr:`taus`), whose loop is not ``H`` times one
        scalar delay: its consumers (the factored phase, the predicted roots,
        the gain band) then take their direct routes."""
        if self.taus is not None:
            return None

        def compute() -> tuple[ComplexArray, ComplexArray, ComplexArray] | None:
            p, S, ok = self.eigen()
            return (p, self.Cz @ S, np.linalg.solve(S, self.B)) if ok else None

        return self.cached("pf", compute)

    def eigen(self) -> tuple[Any, Any, bool]:
        """``(p, S, well_conditioned)``: ``A = S diag(p) S^{-1}`` (one
        eigendecomposition, :func:`_eig`) and whether ``cond(S) < 1e8``.
        Shared by systems with the same ``A`` (:func:`loop_systems`)."""
        return self.cached("eig", lambda: _eig(self.A))

    def delay_free_poles(self) -> ComplexArray:
        """Eigenvalues of the delay-free closed loop :math:`P`, shape (m,)."""
        return self.cached("poles", lambda: np.linalg.eigvals(self.A))

    def open_loop_poles(self) -> NDArray[np.inexact[Any]]:
        """Roots of the open-loop structure :math:`P_0`, shape (m,) (real
        float64 when all are real: what ``np.linalg.eigvals`` returns)."""

        def compute() -> NDArray[np.inexact[Any]]:
            if len(self.open_coeffs) == 2:  # first-order form: P0 = lambda I - A0
                return np.linalg.eigvals(-self.open_coeffs[0])
            K, C, M = self.open_coeffs
            return np.linalg.eigvals(_companion(sla.cho_factor(M), K, C))

        return self.cached("open_poles", compute)

    def cached(self, key: str, compute: Callable[[], Any]) -> Any:
        """``compute()``, memoised on this system under ``key`` (the system is
        immutable, so a derived quantity is computed once and shared by the
        root search, the argument principle and the band)."""
        if key not in self._cache:
            self._cache[key] = compute()
        return self._cache[key]

    def factored_log_derivative(self, lam: ArrayLike) -> ComplexArray | None:
        """:math:`\\operatorname{tr}(\\Delta^{-1}\\Delta') = (\\log\\det\\Delta)'` at
        ``lam`` from the factorisation :math:`\\det\\Delta = \\det P\\,\\det F`,
        :math:`F = I_r - e^{-\\lambda\\tau} H(\\lambda)`: with the delay-free
        poles :math:`p_k` and :math:`H` in pole-residue form
        (:meth:`partial_fractions`),

        .. math::

            (\\log\\det\\Delta)' = \\sum_k \\frac{1}{\\lambda - p_k}
              + \\operatorname{tr}(F^{-1} F'),\\qquad
            F' = e^{-\\lambda\\tau}(\\tau H - H'),\\quad
            H' = -\\sum_k \\frac{L_k R_k}{(\\lambda - p_k)^2},

        (:math:`\\det P = \\det(\\text{leading coefficient}) \\prod_k (\\lambda -
        p_k)`), O(m r^2) per point instead of the O(n^3) solve with
        :math:`\\Delta` itself.  Newton's step on :math:`\\det\\Delta` is its
        inverse.  Shape ``lam.shape``; NaN where it is not finite (``lam`` on a
        pole).  None without a pole-residue form (ill-conditioned eigenvectors,
        several delays)."""
        pf = self.partial_fractions()
        if pf is None or not self.has_delay:
            return None
        p, L, R = pf
        lam = np.asarray(lam, dtype=complex)
        LR = self.cached("pf_outer", lambda: L[:, :, None] * R[None, :, :])
        with np.errstate(all="ignore"):
            g = 1.0 / (lam[..., None] - p)
            H = np.tensordot(g, LR, axes=([-1], [1]))
            dH = -np.tensordot(g * g, LR, axes=([-1], [1]))
            e = np.exp(-lam * self.tau)[..., None, None]
            F = np.eye(self.r) - e * H
            dF = e * (self.tau * H - dH)
            X = batched_solve(F.astype(complex), dF.astype(complex), singular=np.inf)
            tr = g.sum(axis=-1) + np.trace(X, axis1=-2, axis2=-1)
        return np.where(np.isfinite(g).all(axis=-1), tr, np.nan + 0j)

    def band_model(self, top: float, tol: float) -> DelaySystem | None:
        """A reduced system for the roots in the band up to ``top`` (rad/s):
        the Ritz projection of :math:`\\Delta` on the delay-free modes below a
        cut and the static response to the delayed input.

        The basis :math:`W` (orthonormal) spans the real and imaginary parts of
        the kept modes' shapes (their coordinates ``q``; the state ``x`` in
        first order) and :math:`P(0)^{-1} U`; the reduced system is
        :math:`W^T \\Delta(\\lambda) W` (coefficients, ``U`` and ``V``
        projected).  It has the kept poles :math:`p_k` exactly (their shapes lie
        in :math:`W`) and the exact static loop transfer
        :math:`V^T W (W^T P(0) W)^{-1} W^T U = V^T P(0)^{-1} U` (the static
        vectors lie in :math:`W`): a mode left out enters by its static part,
        the modal truncation augmentation (Dickens, Nakagawa & Wittbrodt 1997).
        In the band, :math:`|\\lambda| \\le` ``top``, replacing the term
        :math:`L_k R_k/(\\lambda - p_k)` of :math:`H` by its static value
        :math:`-L_k R_k/p_k` errs by at most
        :math:`|L_k||R_k|\\,\\text{top}/(|p_k|(|p_k| - \\text{top}))`; the
        cut is the lowest that keeps the sum of these bounds over the modes
        left out below ``tol``; the bound is the modal truncation's, so the
        Ritz model's transfer is then compared with the exact one on the
        band's axis, and refused beyond ``tol``.  The model's roots only
        *locate* the roots of the band; they are refined on :math:`\\Delta`
        itself.

        None when its transfer errs by more than ``tol``, no coordinate would be dropped, without a pole-residue form
        or a delay, or for a first-order form from controller states (``A``
        not the companion matrix of the coefficients).

        References
        ----------
        .. [1] J. M. Dickens, J. M. Nakagawa, M. J. Wittbrodt, "A critique of
           mode acceleration and modal truncation augmentation methods for
           modal response analysis", Computers & Structures 62(6), 985-998, 1997.
        """
        key = f"band_model:{float(top)!r}:{float(tol)!r}"
        return self.cached(key, lambda: _band_model(self, float(top), float(tol)))


def _band_model(sys: DelaySystem, top: float, tol: float) -> DelaySystem | None:
    """:meth:`DelaySystem.band_model` (None where it does not apply)."""
    pf = sys.partial_fractions()
    if pf is None or not sys.has_delay or sys.taus is not None:
        return None
    n, m = sys.n, sys.A.shape[0]
    second = len(sys.coeffs) == 3 and m == 2 * n
    if not (second or (len(sys.coeffs) == 2 and m == n)):
        return None
    p, S, _ = sys.eigen()
    _, L, R = pf
    size = np.abs(p)
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = np.linalg.norm(L, axis=0) * np.linalg.norm(R, axis=1) * top / (size * (size - top))
    bound[~(size > top)] = np.inf  # the band's own modes are always kept
    order = np.argsort(size)
    # tail[i]: the error bound with the modes order[:i] kept (a sum from the top)
    tail = np.append(np.cumsum(bound[order][::-1])[::-1], 0.0)
    first = int(np.flatnonzero(tail <= tol)[0])
    cut = float(size[order[first - 1]]) if first else -1.0
    keep = (size <= cut) & (p.imag >= 0)
    shapes = S[:n, keep] if second else S[:, keep]
    if 2 * int(np.sum(keep)) + sys.r >= n:
        return None
    try:
        # P(0) = K - D_P (second order) or -A0 (first order): the static response to U
        static = np.linalg.solve(sys.coeffs[0], sys.U)
    except np.linalg.LinAlgError:
        static = np.zeros((n, 0))
    basis = np.concatenate([shapes.real, shapes.imag[:, np.abs(p[keep].imag) > 0], static], axis=1)
    basis = basis[:, np.all(np.isfinite(basis), axis=0)]
    W = sla.orth(basis)  # orthonormal; drops directions below round-off (a real mode's zero imaginary part)

    def project(X: FloatArray) -> FloatArray:
        return W.T @ X @ W

    U, V = W.T @ sys.U, W.T @ sys.V
    if not second:
        A0 = -project(sys.coeffs[0])
        red = make_first_order_system(A0, (U, V), sys.tau)
        red = dataclasses.replace(red, open_coeffs=tuple(project(c) for c in sys.open_coeffs))
    else:
        Kt, Ct, Mr = (project(c) for c in sys.coeffs)
        K0, C0, _ = (project(c) for c in sys.open_coeffs)
        structure = _structure(0.5 * (Mr + Mr.T), C0, K0)
        red = _system(structure, K0 - Kt, C0 - Ct, (U, V), sys.tau)
    # the bound above is the modal truncation's; the Ritz model is checked
    # against it on the band's axis (every 1/2000 of the band and at each of
    # its poles' frequencies, where the error of a residue shows), both
    # transfers in pole-residue form
    wp = np.abs(p[keep].imag)
    w = np.unique(np.concatenate([np.linspace(0.0, top, 2001), wp[wp <= top]]))
    if red.partial_fractions() is None:
        return None
    err = np.abs(red.transfer_fast(1j * w) - sys.transfer_fast(1j * w)).max()
    return red if err <= tol else None


#: eigendecompositions of first-order matrices done (a work counter, read by tests)
EIG_COUNT = [0]


def _eig(A: FloatArray) -> tuple[Any, Any, bool]:
    """``np.linalg.eig(A)`` and whether the eigenvector matrix ``S`` has
    ``cond_2(S) < 1e8``.  ``cond_2(S) <= ||S||_F ||S^{-1}||_F``, so the bound
    (one inverse) decides when it is below 1e8; the SVD is taken only when it
    is not (the same verdict as ``np.linalg.cond(S) < 1e8`` either way)."""
    EIG_COUNT[0] += 1
    p, S = np.linalg.eig(A)
    try:
        Sinv = np.linalg.inv(S)
    except np.linalg.LinAlgError:
        return p, S, False
    bound = float(np.linalg.norm(S) * np.linalg.norm(Sinv))
    ok = bool(bound < 1e8) or bool(np.linalg.cond(S) < 1e8)
    return p, S, ok


def _horner(coeffs: tuple[FloatArray, ...], lam: ArrayLike, derivative: bool = False) -> ComplexArray:
    """:math:`\\sum_k \\lambda^k` ``coeffs[k]`` (or its derivative) by Horner's
    rule, shape ``lam.shape + (n, n)``."""
    lam = np.asarray(lam, dtype=complex)[..., None, None]
    n = coeffs[0].shape[0]
    out = np.zeros(lam.shape[:-2] + (n, n), dtype=complex)
    if derivative:
        for k in range(len(coeffs) - 1, 0, -1):
            out = out * lam + k * coeffs[k]
    else:
        for k in range(len(coeffs) - 1, -1, -1):
            out = out * lam + coeffs[k]
    return out


def _companion(cho: Any, K: FloatArray, C: FloatArray) -> FloatArray:
    """First-order form ``A`` of :math:`M\\ddot q + C\\dot q + K q`, state ``(q, qdot)``;
    ``cho`` is the Cholesky factor of ``M``."""
    n = K.shape[0]
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -sla.cho_solve(cho, K)
    A[n:, n:] = -sla.cho_solve(cho, C)
    return A


#: how many single_threaded_blas contexts are open (the limit is the process's)
_BLAS_DEPTH = [0]


@contextlib.contextmanager
def single_threaded_blas() -> Iterator[None]:
    """Single-threaded BLAS for the many small dense problems
    (:func:`chatterlab._threads.one_blas_thread`).  Inside another such
    context (rhp_counts called by the lobe engine, itself single-threaded)
    every loaded BLAS is already limited, and the inner context does
    nothing: setting the limit again costs threadpoolctl a scan of the
    loaded libraries, ~2 ms each time."""
    if _BLAS_DEPTH[0]:
        _BLAS_DEPTH[0] += 1
        try:
            yield
        finally:
            _BLAS_DEPTH[0] -= 1
        return
    from .._threads import one_blas_thread

    with one_blas_thread():
        _BLAS_DEPTH[0] += 1
        try:
            yield
        finally:
            _BLAS_DEPTH[0] -= 1


def single_threaded(func: Callable[P, R]) -> Callable[P, R]:
    """Run ``func`` under :func:`single_threaded_blas` (a public entry point
    whose work is many small dense problems: the lobe engine's)."""

    @functools.wraps(func)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        with single_threaded_blas():
            return func(*args, **kwargs)

    return wrapper


def batched_solve(A: ComplexArray, B: ComplexArray, singular: Any = np.nan) -> ComplexArray:
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


def make_system(
    M: ArrayLike,
    C: ArrayLike,
    K: ArrayLike,
    *,
    DP: ArrayLike | None = None,
    DV: ArrayLike | None = None,
    DO: ArrayLike | tuple[ArrayLike, ArrayLike] | None = None,
    tau: float | None = None,
    delays: Sequence[tuple[Any, float]] | None = None,
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
    delays : sequence of ``(DO_i, tau_i)``, optional
        Several delayed terms, each with its own delay (instead of ``DO``
        and ``tau``): :math:`\\Delta = P - \\sum_i D_{O,i} e^{-\\lambda\\tau_i}`.
        Terms with equal delays are summed; one distinct delay gives the
        single-delay system.

    Returns
    -------
    DelaySystem

    Raises
    ------
    InputError
        Non-square, mismatched or non-finite matrices, ``M`` not symmetric
        positive definite, ``tau <= 0`` with ``DO`` given, ``delays`` with
        ``DO`` or ``tau``.

    References
    ----------
    .. [1] E. Wittbrodt, K. Kaliński, seed paper, Eqs. 2.1, 2.22-2.28.
    """
    if delays is None:
        return _system(_structure(M, C, K), DP, DV, DO, tau)
    if DO is not None or tau is not None:
        raise InputError("give either DO and tau (one delay) or delays=[(DO_i, tau_i), ...], not both")
    st = _structure(M, C, K)
    n = st[0].shape[0]
    parts = []
    for i, item in enumerate(delays):
        if not (isinstance(item, tuple | list) and len(item) == 2):
            raise InputError(f"delays[{i}] must be a pair (DO_i, tau_i) (got {type(item).__name__})")
        try:
            U, V = factor_delayed(item[0], n)
        except InputError as exc:
            raise InputError(str(exc).replace("DO", f"delays[{i}] DO")) from exc
        if U.shape[1]:
            parts.append((U, V, check_tau(item[1], True)))
    return _system_delays(st, DP, DV, parts)


def _merge_delayed(
    parts: Sequence[tuple[FloatArray, FloatArray, float]], n: int
) -> tuple[FloatArray, FloatArray, float, FloatArray | None]:
    """``(U, V, tau, taus)`` of delayed terms ``(U_i, V_i, tau_i)``: one
    delay -- every term's (summed), ``taus`` None -- or the columns stacked
    with their delays ``taus`` and ``tau`` the largest."""
    parts = [p for p in parts if p[0].shape[1]]
    if not parts:
        return np.zeros((n, 0)), np.zeros((n, 0)), 0.0, None
    U = np.hstack([p[0] for p in parts])
    V = np.hstack([p[1] for p in parts])
    taus = np.concatenate([np.full(p[0].shape[1], float(p[2])) for p in parts])
    if np.all(taus == taus[0]):
        if len(parts) > 1:  # one delay: the sum, factored again at its rank
            U, V = factor_delayed(U @ V.T, n)
        return U, V, float(taus[0]), None
    return U, V, float(taus.max()), taus


def _system_delays(
    structure: tuple[FloatArray, FloatArray, FloatArray, Any],
    DP: ArrayLike | None,
    DV: ArrayLike | None,
    parts: Sequence[tuple[FloatArray, FloatArray, float]],
) -> DelaySystem:
    """The second-order system with the delayed terms ``parts`` (each ``(U_i,
    V_i, tau_i)``): :func:`_system` for one delay, else the columns' delays."""
    n = structure[0].shape[0]
    U, V, tau, taus = _merge_delayed(parts, n)
    sys = _system(structure, DP, DV, (U, V) if U.shape[1] else None, tau if U.shape[1] else None)
    return sys if taus is None else dataclasses.replace(sys, taus=taus, _cache={})


def _structure(M: ArrayLike, C: ArrayLike, K: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray, Any]:
    """``(M, C, K, cho)``: the structure's matrices validated (square, finite,
    M symmetric positive definite) and the Cholesky factor of M."""
    Mm = as_real_matrix(M, "M")
    n = Mm.shape[0]
    Cm = as_real_matrix(C, "C", n)
    Km = as_real_matrix(K, "K", n)
    if not np.allclose(Mm, Mm.T, rtol=1e-10, atol=1e-14 * np.abs(Mm).max()):
        raise InputError("M must be symmetric positive definite (it is not symmetric)")
    try:
        cho = sla.cho_factor(Mm)
    except np.linalg.LinAlgError as exc:
        raise InputError("M must be symmetric positive definite (Cholesky failed)") from exc
    return Mm, Cm, Km, cho


def _system(
    structure: tuple[FloatArray, FloatArray, FloatArray, Any],
    DP: ArrayLike | None,
    DV: ArrayLike | None,
    DO: ArrayLike | tuple[ArrayLike, ArrayLike] | None,
    tau: float | None,
) -> DelaySystem:
    """:func:`make_system` on a structure already validated by :func:`_structure`."""
    Mm, Cm, Km, cho = structure
    n = Mm.shape[0]
    DPm = np.zeros((n, n)) if DP is None else as_real_matrix(DP, "DP", n)
    DVm = np.zeros((n, n)) if DV is None else as_real_matrix(DV, "DV", n)
    U, V = factor_delayed(DO, n)
    t = check_tau(tau, U.shape[1] > 0)
    Ct = Cm - DVm
    Kt = Km - DPm
    r = U.shape[1]
    A = _companion(cho, Kt, Ct)
    B = np.zeros((2 * n, r))
    if r:
        B[n:] = sla.cho_solve(cho, U)
    Cz = np.zeros((r, 2 * n))
    Cz[:, :n] = V.T
    return DelaySystem(coeffs=(Kt, Ct, Mm), U=U, V=V, tau=t, A=A, B=B, Cz=Cz, open_coeffs=(Km, Cm, Mm))


def loop_system(loop: Any) -> DelaySystem:
    """The delay system of a :class:`chatterlab.process.ClosedLoop`: the one
    place where a closed loop's matrices become the characteristic equation
    Delta(s) = s^2 M + s (C - D_V) + K - D_P - U V^T e^{-sT} (Eq. 2.1, 2.23)."""
    return _loop_system(loop, _structure(loop.M, loop.C, loop.K))


def _loop_system(loop: Any, structure: tuple[FloatArray, FloatArray, FloatArray, Any]) -> DelaySystem:
    """:func:`loop_system` with the loop's structure already validated."""
    acts = getattr(loop, "actuators", None)
    if acts is not None:
        return _controlled_system(loop, acts, structure)
    DO = (loop.U, loop.V) if loop.U.shape[1] else None
    return _system(structure, loop.DP, loop.DV, DO, loop.delay if DO is not None else None)


def _controlled_system(
    loop: Any, acts: Any, structure: tuple[FloatArray, FloatArray, FloatArray, Any]
) -> DelaySystem:
    """The delay system of a loop with actuators (:class:`chatterlab.process.Actuators`):
    actuator k adds -D_a = B_k (P_k + s V_k + O_k e^{-s T_k}) S_k / (1 + s tau_k)
    to Delta.  Without a bandwidth it is second order: P_k and V_k join
    D_P and D_V, the delayed term U = -O_k B_k, V = S_k^T has the delay T_k
    (a proportional term when T_k = 0).  An actuator with a bandwidth adds
    its force f_k as a state, tau_k f_k' = -f_k - (P_k y + V_k y' + O_k
    y(t - T_k)), and the system is written in first order, x = (q, q', x_f)
    with f = kappa_k x_f (kappa_k the actuator's gain at a mean natural
    frequency, so that x_f is of the size of a displacement)."""
    Mm, Cm, Km, cho = structure
    n = Mm.shape[0]
    DP = np.array(loop.DP, dtype=float)
    DV = np.array(loop.DV, dtype=float)
    parts: list[tuple[FloatArray, FloatArray, float]] = []
    if loop.U.shape[1]:
        parts.append((np.asarray(loop.U, float), np.asarray(loop.V, float), float(loop.delay)))
    lagged = [k for k in range(acts.m) if acts.lag[k] > 0]
    for k in range(acts.m):
        if k in lagged:
            continue
        b, c = acts.B[:, k], acts.S[k]
        DP = DP - acts.P[k] * np.outer(b, c)
        DV = DV - acts.V[k] * np.outer(b, c)
        if acts.O[k] != 0:
            if acts.delay[k] > 0:
                parts.append((-acts.O[k] * b[:, None], c[:, None], float(acts.delay[k])))
            else:
                DP = DP - acts.O[k] * np.outer(b, c)
    if not lagged:
        return _system_delays(structure, DP, DV, parts)
    # first order: x = (q, q', f_lagged)
    ml = len(lagged)
    m = 2 * n + ml
    A = np.zeros((m, m))
    A[:n, n : 2 * n] = np.eye(n)
    A[n : 2 * n, :n] = -sla.cho_solve(cho, Km - DP)
    A[n : 2 * n, n : 2 * n] = -sla.cho_solve(cho, Cm - DV)
    fparts: list[tuple[FloatArray, FloatArray, float]] = []
    for U, V, t in parts:  # M q'' = ... + U V^T q(t - t): rows q'', columns q
        Uf = np.zeros((m, U.shape[1]))
        Uf[n : 2 * n] = sla.cho_solve(cho, U)
        Vf = np.zeros((m, V.shape[1]))
        Vf[:n] = V
        fparts.append((Uf, Vf, t))
    # the force state in units of a displacement, f = kappa x_f with kappa the actuator's gain at a
    # mean natural frequency: q and x_f of one size keep the eigenvectors well conditioned
    w_mean = math.sqrt(max(float(np.trace(Km) / np.trace(Mm)), 0.0))
    for j, k in enumerate(lagged):
        b, c, tk = acts.B[:, k], acts.S[k], float(acts.lag[k])
        kap = abs(acts.P[k]) + abs(acts.O[k]) + w_mean * abs(acts.V[k]) or 1.0
        row = 2 * n + j
        A[n : 2 * n, row] = sla.cho_solve(cho, b) * kap
        A[row, :n] = -acts.P[k] * c / (tk * kap)
        A[row, n : 2 * n] = -acts.V[k] * c / (tk * kap)
        A[row, row] = -1.0 / tk
        if acts.O[k] != 0:
            e = np.zeros((m, 1))
            e[row, 0] = -acts.O[k] / (tk * kap)
            Vf = np.zeros((m, 1))
            Vf[:n, 0] = c
            if acts.delay[k] > 0:
                fparts.append((e, Vf, float(acts.delay[k])))
            else:
                A[row, :n] += -acts.O[k] * c / (tk * kap)
    U, V, tau, taus = _merge_delayed(fparts, m)
    sys = DelaySystem(
        coeffs=(-A, np.eye(m)),
        U=U,
        V=V,
        tau=tau,
        A=A,
        B=U.copy(),
        Cz=V.T.copy(),
        open_coeffs=(-A, np.eye(m)),
    )
    return sys if taus is None else dataclasses.replace(sys, taus=taus, _cache={})


def loop_systems(loops: Sequence[Any]) -> list[DelaySystem]:
    """:func:`loop_system` of several closed loops, sharing what they share.

    The loops of one structure at other widths and delays (the lobe
    diagram's argument-principle checks) have the same open-loop structure
    ``(K, C, M)``: its roots are computed once.  Loops whose delay-free closed
    loop is the same (no proportional or velocity feedback: only the delayed
    term, which sits in ``U``, scales with the width; or two checks at one
    width) have the same first-order matrix ``A``: it is decomposed once
    (:meth:`DelaySystem.eigen`), and only ``L = C_z S``, ``R = S^{-1} B`` are
    formed per system.  Each system is the one :func:`loop_system` builds;
    the shared values are the ones each would compute (the same input, the
    same arithmetic)."""
    structures: dict[tuple[int, int, int], tuple[FloatArray, FloatArray, FloatArray, Any]] = {}
    systems = []
    for loop in loops:
        # one structure's loops hold the same M, C, K arrays: validated and factored once
        key = (id(loop.M), id(loop.C), id(loop.K))
        if key not in structures:
            structures[key] = _structure(loop.M, loop.C, loop.K)
        systems.append(_loop_system(loop, structures[key]))
    opens: dict[bytes, DelaySystem] = {}
    firsts: dict[bytes, DelaySystem] = {}
    for sys in systems:
        ko = b"".join(np.ascontiguousarray(c).tobytes() for c in sys.open_coeffs)
        ka = np.ascontiguousarray(sys.A).tobytes()
        if ko in opens:
            sys._cache["open_poles"] = opens[ko].open_loop_poles()
        else:
            opens[ko] = sys
        if ka in firsts:
            sys._cache["eig"] = firsts[ka].eigen()
        else:
            firsts[ka] = sys
    return systems


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
    A = as_real_matrix(A0, "A0")
    n = A.shape[0]
    try:
        U, V = factor_delayed(A1, n)
    except InputError as exc:
        raise InputError(str(exc).replace("DO", "A1")) from exc
    t = check_tau(tau, U.shape[1] > 0)
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


def as_delay_system(system: Any, what: str = "system") -> DelaySystem:
    """A :class:`DelaySystem` as given, or the one of a
    :class:`chatterlab.process.ClosedLoop` (:func:`loop_system`); anything
    else is an :class:`~chatterlab.errors.InputError` that says how to build one."""
    if isinstance(system, DelaySystem):
        return system
    from ..process._loop import ClosedLoop

    if isinstance(system, ClosedLoop):
        return loop_system(system)
    raise InputError(
        f"{what} must be a DelaySystem (make_system(M, C, K, DP=..., DV=..., DO=..., tau=...) or"
        f" make_first_order_system(A0, A1, tau)) or a ClosedLoop (closed_loop(frozen, width=..., speed=...));"
        f" got {type(system).__name__}"
    )
