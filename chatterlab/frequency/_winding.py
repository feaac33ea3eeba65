"""Right-half-plane root count of a delayed closed loop by the argument principle.

An independent check of :mod:`chatterlab.frequency._roots`: no characteristic root is
computed.  With :math:`\\Delta(\\lambda) = P(\\lambda) - D_O e^{-\\lambda\\tau}`,
:math:`P(\\lambda) = \\lambda^2 M + \\lambda (C - D_V) + K - D_P` and the
open-loop structure :math:`P_0(\\lambda) = \\lambda^2 M + \\lambda C + K`, the
function

.. math::

    f(\\lambda) = \\frac{\\det\\Delta(\\lambda)}{\\det P_0(\\lambda)}
               = \\det\\bigl(I - P_0^{-1}(\\lambda) D(\\lambda)\\bigr),
    \\qquad D = D_P + \\lambda D_V + D_O e^{-\\lambda\\tau}

is meromorphic, tends to 1 as :math:`|\\lambda| \\to \\infty` in
:math:`\\Re\\lambda \\ge 0` (``M`` nonsingular), has the closed-loop roots as
zeros and the open-loop roots as poles.  Along the Nyquist contour (the
imaginary axis upwards, closed by a large right semicircle on which
:math:`f \\to 1`), which encircles the right half plane clockwise,

.. math::

    Z_{closed} = Z_{open} - \\frac{1}{2\\pi}
        \\Delta_{\\omega=-\\infty}^{\\infty} \\arg f(j\\omega)
      = Z_{open} - \\frac{1}{\\pi}\\Delta_{\\omega=0}^{\\infty} \\arg f(j\\omega)

(the matrices are real, so :math:`f(-j\\omega) = \\overline{f(j\\omega)}`).

Evaluation.  By default ``f`` is evaluated in factored form,
:math:`f = \\frac{\\det M \\prod_k (\\lambda - p_k)}{\\det M \\prod_k
(\\lambda - p^0_k)} \\det(I_r - H(\\lambda) e^{-\\lambda\\tau})` with the
delay-free closed-loop poles :math:`p_k`, the open-loop poles :math:`p^0_k`
and :math:`H = V^T P^{-1} U` (``D_O = U V^T``).  The phase of the linear
factors is continuous and known in closed form; it contributes
:math:`\\pi (Z_{open} - Z_P)` to the total, so
:math:`Z_{closed} = Z_P - \\frac{1}{\\pi}\\Delta_0^\\infty \\arg g`,
:math:`g = \\det(I_r - H e^{-j\\omega\\tau})`, and only the ``r x r``
determinant ``g`` has to be sampled.  ``direct=True`` (and the fallback when
the delay-free poles are ill-conditioned or on the axis) samples
:math:`\\det\\Delta(j\\omega)` itself by LU, divided by the analytic
:math:`\\det P_0` (or by :math:`\\det M (\\lambda + a)^{2n}` when ``P_0`` has
roots on the axis).

Sampling.  The phase is unwrapped between samples; an interval whose wrapped
phase increment exceeds :math:`\\pi/4` is bisected until it does not.  The
initial grid has the step :math:`\\pi/(8\\tau)` (one sixteenth of a turn of
:math:`e^{-j\\omega\\tau}`; for :math:`\\tau = 1.5` s this is 0.26 rad/s),
is refined near every pole and stops at :math:`\\omega_{max}`, beyond which
:math:`|f - 1| < 10^{-3}` (so the remaining phase is below a milliradian).
A root on (or within ~1e-10 relative of) the axis makes an increment that
bisection cannot resolve, or a sample with :math:`|f|` ~0 relative to its
neighbours; the result is then ``status="marginal"``.

References
----------
.. [1] E. Wittbrodt, K. Kaliński, seed paper, Eqs. 2.1, 2.22-2.28.
.. [2] H. Nyquist, "Regeneration theory", Bell Syst. Tech. J. 11, 126-147,
   1932 (the argument principle along the imaginary axis).
.. [3] C. A. Desoer, Y.-T. Wang, "On the generalized Nyquist stability
   criterion", IEEE Trans. Autom. Control 25(2), 187-196, 1980
   (:math:`\\det(I - G D)` for multivariable loops).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg as sla
from numpy.typing import ArrayLike, NDArray

from chatterlab.errors import InputError

from ._delay_system import DelaySystem, make_system, single_threaded_blas

__all__ = ["WindingResult", "rhp_count", "rhp_count_system"]

_PHASE_STEP = math.pi / 4  # largest wrapped phase increment accepted between samples
_TAIL = 1e-3  # |f - 1| bound beyond omega_max
_PASSIVE = 0.5  # spectral radius of H below which g cannot wind
_MAX_SAMPLES = 400_000


@dataclass(frozen=True)
class WindingResult:
    """Right-half-plane root count from the argument principle.

    Attributes
    ----------
    count : int
        Number of closed-loop roots with :math:`\\Re\\lambda > 0` (with
        multiplicity; conjugate pairs count twice).
    open_loop_count : int
        Roots of :math:`P_0(\\lambda) = \\lambda^2 M + \\lambda C + K` with
        positive real part.
    n_samples : int
        Frequencies evaluated (after adaptive refinement).
    min_abs_det : float
        Smallest :math:`|f(j\\omega)|` over the samples (dimensionless; the
        normalised determinant).  Near 0: a root close to the axis.
    status : str
        ``"converged"``, ``"marginal"`` (a root on or extremely close to the
        imaginary axis; ``count`` is then a best effort) or ``"not_converged"``.
    message : str
        Human-readable diagnostic.
    omega_max : float
        Upper end of the sampled band in rad/s.
    delay_free_count : int
        Roots of the delay-free closed loop :math:`P(\\lambda)` (with
        :math:`D_P, D_V`) with positive real part.
    winding : float
        :math:`\\Delta_0^\\infty \\arg f(j\\omega) / \\pi` (an integer when
        converged).
    """

    count: int
    open_loop_count: int
    n_samples: int
    min_abs_det: float
    status: str
    message: str
    omega_max: float = float("nan")
    delay_free_count: int = 0
    winding: float = float("nan")

    @property
    def stable(self) -> bool:
        """``True`` when no closed-loop root lies in the right half plane."""
        return self.count == 0


def _open_loop_poles(sys: DelaySystem) -> NDArray[np.inexact[Any]]:
    # real (float64) when every eigenvalue is real: that is what np.linalg.eigvals returns
    Km, Cm, Mm = (
        sys.open_coeffs if len(sys.open_coeffs) == 3 else (sys.open_coeffs[0], sys.open_coeffs[1], None)
    )
    if Mm is None:  # first-order form: P0 = lambda I - A0
        return np.linalg.eigvals(-Km)
    n = Mm.shape[0]
    cho = sla.cho_factor(Mm)
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -sla.cho_solve(cho, Km)
    A[n:, n:] = -sla.cho_solve(cho, Cm)
    return np.linalg.eigvals(A)


class _Sampler:
    """Evaluate the sampled factor F(j omega): complex values, finite or not."""

    def __init__(
        self, sys: DelaySystem, mode: str, ref_poles: NDArray[np.inexact[Any]], logdetM: float
    ) -> None:
        self.sys = sys
        self.mode = mode
        self.ref = ref_poles
        self.logdetM = logdetM

    def __call__(self, omega: NDArray[np.float64]) -> NDArray[np.complex128]:
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
        H = sys.transfer(np.array([lam]))[0]
        return float(np.linalg.norm(H, 2))
    D = sys.delta(np.array([lam]))[0]
    lead = sys.coeffs[-1]
    if ref_shift is None:
        Pr = sum(lam**k * c for k, c in enumerate(sys.open_coeffs))
    else:
        Pr = lead * (lam + ref_shift) ** (len(sys.coeffs) - 1)
    try:
        X = np.linalg.solve(Pr, D - Pr)
    except np.linalg.LinAlgError:
        return float("inf")
    return float(np.linalg.norm(X, 2))


def rhp_count_system(
    sys: DelaySystem,
    *,
    omega_max: float | None = None,
    n_points: int | None = None,
    direct: bool = False,
) -> WindingResult:
    """Right-half-plane root count for a prepared :class:`~chatterlab.frequency._roots.DelaySystem`.

    See :func:`rhp_count` for the parameters and the method.
    """
    tau = sys.tau if sys.has_delay else 0.0
    p0 = _open_loop_poles(sys)
    p = sys.delay_free_poles()
    scale = max(
        float(np.max(np.abs(p0))) if p0.size else 1.0, float(np.max(np.abs(p))) if p.size else 1.0, 1e-300
    )
    z_open = int(np.sum(p0.real > 0))
    z_p = int(np.sum(p.real > 0))
    axis_tol = 1e-10 * scale
    mode = "factored"
    ref = p0
    ref_shift: float | None = None
    z_base = z_p
    notes = []
    if not sys.has_delay:
        # nothing to sample: f = det P / det P0 has the closed-form phase
        marginal = bool(np.any(np.abs(p.real) <= axis_tol))
        return WindingResult(
            count=z_p,
            open_loop_count=z_open,
            n_samples=0,
            min_abs_det=float("nan"),
            status="marginal" if marginal else "converged",
            message="no delay: count from the delay-free eigenvalues"
            + ("; a root lies on the imaginary axis" if marginal else ""),
            omega_max=0.0,
            delay_free_count=z_p,
            winding=float(z_open - z_p),
        )
    pf = sys.partial_fractions()
    if direct or pf is None or np.any(np.abs(p.real) <= axis_tol):
        mode = "direct"
        if pf is None and not direct:
            notes.append("delay-free eigenvectors ill-conditioned: sampled det(Delta) directly")
        if np.any(np.abs(p.real) <= axis_tol) and not direct:
            notes.append("delay-free closed loop has roots on the axis: sampled det(Delta)")
        if np.any(np.abs(p0.real) <= axis_tol):
            a = max(scale, 1.0 / tau)
            ref_shift = a
            ref = np.full(p0.shape, -a + 0j)
            z_base = 0
            notes.append(f"open loop has roots on the axis: reference det M (s+{a:.3g})^2n")
        else:
            ref = p0
            z_base = z_open
    logdetM = 0.0
    if len(sys.coeffs) == 3:
        logdetM = float(np.linalg.slogdet(sys.coeffs[2])[1])
    F = _Sampler(sys, mode, ref, logdetM)

    # --- band -----------------------------------------------------------
    poles_for_grid = np.concatenate([p, p0])
    if omega_max is None:
        W = max(3.0 * float(np.max(np.abs(poles_for_grid.imag))), 3.0 * scale, 10.0 / tau)
        for _ in range(60):
            if (
                _tail_bound(sys, mode, W, ref_shift) < _TAIL
                and _tail_bound(sys, mode, 2 * W, ref_shift) < _TAIL
            ):
                break
            W *= 2.0
        else:
            return WindingResult(
                count=-1,
                open_loop_count=z_open,
                n_samples=0,
                min_abs_det=float("nan"),
                status="not_converged",
                message="|f - 1| does not decay; is M singular?",
                omega_max=W,
                delay_free_count=z_p,
            )
    else:
        W = float(omega_max)
    # --- initial grid ---------------------------------------------------
    step = math.pi / (8.0 * tau)
    offs = np.array([-16, -8, -4, -2, -1, -0.5, -0.25, 0, 0.25, 0.5, 1, 2, 4, 8, 16])
    pole_pts = []
    for z in poles_for_grid:
        if z.imag < 0:
            continue
        d = max(abs(z.real), 1e-9 * scale)
        loc = z.imag + d * offs
        pole_pts.append(loc[(loc > 0) & (loc < W)])
    passive_iv: NDArray[np.bool_] | None = None
    mu_of: Any = None
    if mode == "factored":
        # g = prod_k (1 - mu_k e^{-jwT}) can only wind where the spectral radius of
        # H(jw) reaches 1.  Where it stays below 1/2 each factor keeps Re > 1/2, so
        # the phase increment between two samples is exact from the eigenvalues at
        # the ends: the dense pi/(8 tau) grid is needed only in the active bands.
        wsm = np.unique(np.concatenate([np.linspace(0.0, W, 4001)] + pole_pts))

        def mu_of(om: NDArray[np.float64]) -> NDArray[np.complex128]:
            with np.errstate(all="ignore"):
                return np.linalg.eigvals(sys.transfer_fast(1j * om))  # type: ignore[return-value]  # numpy stubs: complex128 in, complexfloating[Any, Any] out

        rho = np.abs(mu_of(wsm)).max(axis=1)
        act_pt = ~(rho < _PASSIVE)  # NaN counts as active
        act_iv = act_pt[:-1] | act_pt[1:]
        act_iv = act_iv | np.r_[act_iv[1:], False] | np.r_[False, act_iv[:-1]]
        dense = [
            np.linspace(a, b, int(math.ceil((b - a) / step)) + 1)
            for a, b in zip(wsm[:-1][act_iv], wsm[1:][act_iv], strict=True)
        ]
        n0 = int(sum(x.size for x in dense)) + wsm.size
        pts = [wsm] + dense
        passive_pairs = (wsm[:-1][~act_iv], wsm[1:][~act_iv])
    else:
        n0 = int(math.ceil(W / step)) + 1
        pts = [np.linspace(0.0, W, n0)] + pole_pts
    if n_points is not None:
        n0 = max(n0, int(n_points))
        if mode != "factored":
            pts[0] = np.linspace(0.0, W, n0)
    if n0 > _MAX_SAMPLES:
        return WindingResult(
            count=-1,
            open_loop_count=z_open,
            n_samples=0,
            min_abs_det=float("nan"),
            status="not_converged",
            message=f"{n0} samples needed up to {W:.4g} rad/s; pass a smaller omega_max",
            omega_max=W,
            delay_free_count=z_p,
        )
    w = np.unique(np.concatenate(pts))

    def passive_flags(grid: NDArray[np.float64]) -> NDArray[np.bool_] | None:
        """Intervals of ``grid`` lying inside a passive interval of ``wsm``."""
        if mode != "factored":
            return None
        a0, b0 = passive_pairs
        if a0.size == 0:
            return np.zeros(grid.size - 1, bool)
        k = np.searchsorted(a0, grid[:-1], side="right") - 1
        kc = np.clip(k, 0, a0.size - 1)
        return (k >= 0) & (grid[1:] <= b0[kc] + 1e-12 * W) & (grid[:-1] >= a0[kc])

    passive_iv = passive_flags(w)
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
        if not np.any(bad) or w.size > _MAX_SAMPLES:
            break
        mid = 0.5 * (w[:-1][bad] + w[1:][bad])
        vm = F(mid)
        w = np.concatenate([w, mid])
        val = np.concatenate([val, vm])
        o = np.argsort(w, kind="stable")
        w, val = w[o], val[o]
        passive_iv = passive_flags(w)
    absf = np.abs(val)
    finite = np.isfinite(val)
    min_abs = float(np.min(absf[finite])) if np.any(finite) else float("nan")
    ph = np.angle(val)
    inc = np.angle(np.exp(1j * (ph[1:] - ph[:-1])))
    if passive_iv is not None and np.any(passive_iv):
        # exact increments on the passive intervals: sum_k Arg(1 - mu_k z) at both ends
        ends = np.nonzero(passive_iv)[0]
        idx = np.unique(np.concatenate([ends, ends + 1]))
        mu = mu_of(w[idx])
        zz = np.exp(-1j * w[idx] * tau)[:, None]
        arg = np.angle(1.0 - mu * zz).sum(axis=1)
        pos = {int(k): j for j, k in enumerate(idx)}
        inc[ends] = np.array([arg[pos[int(k) + 1]] - arg[pos[int(k)]] for k in ends])
    inc[~np.isfinite(inc)] = 0.0
    total = float(np.sum(inc))
    # remaining phase to infinity: F -> 1
    end = ph[-1] if np.isfinite(ph[-1]) else 0.0
    tail = -float(np.angle(np.exp(1j * end)))
    total += tail
    # start: F(0) is real; its phase is 0 or pi
    winding = total / math.pi
    count_f = z_base - winding
    count = int(round(count_f))
    # marginal checks
    nb = np.maximum(np.r_[absf[1:], 0.0], np.r_[0.0, absf[:-1]])
    dip = bool(np.any(finite & (absf <= 1e-9 * nb))) or bool(np.any(absf[finite] == 0.0))
    status = "converged"
    msg = []
    if unresolved or dip or (val.size and abs(val[0]) <= 1e-12 * max(1.0, float(np.median(absf)))):
        status = "marginal"
        msg.append("a root lies on (or within ~1e-10 relative of) the imaginary axis")
    if abs(count_f - count) > 0.05 or abs(tail) > math.pi / 4 or w.size > _MAX_SAMPLES:
        status = "not_converged"
        msg.append(
            f"winding {winding:.4g} is not an integer (tail phase {tail:.3g} rad); "
            "raise omega_max or n_points"
        )
    if not np.all(finite):
        status = "not_converged" if status == "converged" else status
        msg.append(f"{int(np.sum(~finite))} non-finite samples")
    msg.append(
        f"{count} RHP root(s): Z = {z_base} - ({winding:.4g}) with "
        f"{w.size} samples on [0, {W:.4g}] rad/s ({mode})"
    )
    msg.extend(notes)
    return WindingResult(
        count=count,
        open_loop_count=z_open,
        n_samples=int(w.size),
        min_abs_det=min_abs,
        status=status,
        message="; ".join(msg),
        omega_max=W,
        delay_free_count=z_p,
        winding=winding,
    )


def rhp_count(
    M: ArrayLike,
    C: ArrayLike,
    K: ArrayLike,
    *,
    DP: ArrayLike | None = None,
    DV: ArrayLike | None = None,
    DO: ArrayLike | tuple[ArrayLike, ArrayLike] | None = None,
    tau: float | None = None,
    omega_max: float | None = None,
    n_points: int | None = None,
    direct: bool = False,
) -> WindingResult:
    """Number of closed-loop characteristic roots with positive real part.

    Argument principle for :math:`f = \\det\\Delta/\\det P_0` along the
    imaginary axis (see the module docstring); independent of
    :func:`chatterlab.frequency._roots.characteristic_roots`.

    Parameters
    ----------
    M, C, K : array_like, shape (n, n)
        Inertia (kg, SPD), damping (N s/m), stiffness (N/m).
    DP, DV : array_like, shape (n, n), optional
        Proportional (N/m) and velocity (N s/m) feedback.
    DO : array_like, shape (n, n), or tuple ``(U, V)`` of shape (n, r), optional
        Delayed feedback (N/m), ``DO = U @ V.T`` when factored.
    tau : float, optional
        Delay in s (> 0 with ``DO``).
    omega_max : float, optional
        Upper end of the sampled band in rad/s; default: 3x the largest
        delay-free eigenfrequency, doubled until :math:`|f - 1| < 10^{-3}`.
    n_points : int, optional
        Minimum number of initial samples (default from the step
        :math:`\\pi/(8\\tau)`).
    direct : bool
        Sample :math:`\\det\\Delta(j\\omega)` by LU (O(n^3) per sample) instead
        of the factored low-rank form.

    Returns
    -------
    WindingResult
        ``count``, ``open_loop_count``, ``n_samples``, ``min_abs_det``,
        ``status`` (``"converged"``, ``"marginal"``, ``"not_converged"``),
        ``message``.

    Raises
    ------
    InputError
        Invalid input (as :func:`chatterlab.frequency._roots.make_system`) or a
        non-positive ``omega_max`` / ``n_points``.

    References
    ----------
    .. [1] H. Nyquist, Bell Syst. Tech. J. 11, 126-147, 1932.
    .. [2] C. A. Desoer, Y.-T. Wang, IEEE Trans. Autom. Control 25(2),
       187-196, 1980.
    """
    sys = make_system(M, C, K, DP=DP, DV=DV, DO=DO, tau=tau)
    _check_options(omega_max, n_points)
    with single_threaded_blas():
        return rhp_count_system(sys, omega_max=omega_max, n_points=n_points, direct=direct)


def _check_options(omega_max: Any, n_points: Any) -> None:
    if omega_max is not None:
        try:
            om = float(omega_max)
        except (TypeError, ValueError) as exc:
            raise InputError(f"omega_max must be a positive number in rad/s (got {omega_max!r})") from exc
        if not math.isfinite(om) or om <= 0:
            raise InputError(f"omega_max must be finite and > 0 rad/s (got {omega_max!r})")
    if n_points is not None and (
        isinstance(n_points, bool) or not isinstance(n_points, int | np.integer) or n_points < 2
    ):
        raise InputError(f"n_points must be an integer >= 2 (got {n_points!r})")
