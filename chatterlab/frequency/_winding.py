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

Sampling.  In factored form every phase increment is proven
(:func:`chatterlab.frequency._phase_sampling.certified_phase`): between two
samples either ``sup ||H|| < 1`` (bounded from the partial fractions
:math:`H = \\sum_k h_k/(\\lambda - p_k)` by :math:`\\sum_k \\|h_k\\|/d_k`,
:math:`d_k` the distance of :math:`p_k` from the segment), so that every factor
:math:`1 - \\mu_k e^{-j\\omega\\tau}` keeps a positive real part and the
eigenvalues at the ends give the increment exactly, or a Lipschitz bound on
:math:`\\det(I - H e^{-j\\omega\\tau})` (from :math:`\\sum_k \\|h_k\\|
(1/d_k^2 + \\tau/d_k)`) keeps ``g`` within ``|g(a)|`` of ``g(a)`` on the
interval, so that it turns by less than :math:`\\pi/2` and the increment is the
principal value; otherwise the interval is bisected.  The tail beyond the
last sample is proven passive by a monotone bound.  So a :math:`2\\pi` turn of
``g`` between two samples (a double root next to the axis, as a symmetric
tool has) cannot be missed.  The first samples are only 0, the frequency
of every delay-free pole and 3 max |p| (the bounds place every
further sample: a few wide passive intervals away from the resonances, the
spacing the Lipschitz bound asks for near them -- ~90 samples for a shaper
check where the grid below laid ~5000, the count the same, both proven); an
interval still unproven at round-off width (1e-12 relative) is a root on
the axis: ``status="marginal"``.  ``WindingResult.proven`` says whether the
count rests on these bounds.  :func:`rhp_counts` counts several systems at
once (the lobe diagram's checks): their intervals are bisected together and
what they share (the open-loop structure, an equal delay-free loop) is
computed once.

The direct mode (and the fallback without partial fractions or without a
proven tail) samples as before: the phase is unwrapped between samples; an interval whose wrapped
phase increment exceeds :math:`\\pi/4` is bisected until it does not.  The
initial grid has the step :math:`\\pi/(8\\tau)` (one sixteenth of a turn of
:math:`e^{-j\\omega\\tau}`; for :math:`\\tau = 1.5` s this is 0.26 rad/s),
is refined near every pole and stops at :math:`\\omega_{max}`, beyond which
:math:`|f - 1| < 10^{-3}` (so the remaining phase is below a milliradian).
This is not a proof: a :math:`2\\pi` turn between two samples aliases away
(``proven`` is False).  A root on (or within ~1e-10 relative of) the axis
makes an increment that bisection cannot resolve, or a sample with
:math:`|f|` ~0 relative to its neighbours; the result is then
``status="marginal"``.

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
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..process._loop import ClosedLoop
from ._checks import check_integer, check_omega_max
from ._delay_system import DelaySystem, as_delay_system, single_threaded_blas
from ._phase_sampling import (
    MAX_SAMPLES,
    Certificate,
    Sampler,
    band_end,
    band_start,
    certification_grid,
    certified_phases,
    initial_grid,
    phase_change,
    refine,
)

__all__ = ["WindingResult", "rhp_count", "rhp_counts"]


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
    proven : bool
        Every phase increment is proven (passive or Lipschitz bound, see
        :func:`chatterlab.frequency._phase_sampling.certified_phase`) and so is
        the tail: the count then does not rest on the sampling.  False in the
        direct mode (sampled with the wrapped-increment heuristic) and when
        status is not ``"converged"``.
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
    proven: bool = False

    @property
    def stable(self) -> bool:
        """``True`` when no closed-loop root lies in the right half plane."""
        return self.count == 0


@dataclass(frozen=True)
class _Reference:
    """What the sampled factor is and what its winding is counted against.

    ``mode``: ``"factored"`` (sample ``g = det(I - H e^{-lam tau})``, count
    against the delay-free closed loop's RHP roots) or ``"direct"`` (sample
    ``det Delta`` divided by ``det P_ref``, whose roots are ``ref``);
    ``ref_shift = a`` when ``P_ref = M (lam + a)^2`` replaces ``P_0`` (open-loop
    roots on the axis); ``z_base``: RHP roots of the reference.
    """

    mode: str
    ref: NDArray[np.inexact[Any]]
    ref_shift: float | None
    z_base: int
    notes: tuple[str, ...]


def _reference(
    sys: DelaySystem,
    direct: bool,
    p0: NDArray[np.inexact[Any]],
    p: NDArray[np.complex128],
    z_open: int,
    z_p: int,
    scale: float,
    pf: Any,
) -> _Reference:
    """The factored form unless asked for ``direct``, or the delay-free
    eigenvectors are ill-conditioned (``pf`` None), or the delay-free loop has
    roots on the axis (its linear factors' phase is then not continuous)."""
    axis_tol = 1e-10 * scale
    on_axis = bool(np.any(np.abs(p.real) <= axis_tol))
    if not (direct or pf is None or on_axis):
        return _Reference("factored", p0, None, z_p, ())
    notes = []
    if pf is None and not direct:
        notes.append("delay-free eigenvectors ill-conditioned: sampled det(Delta) directly")
    if on_axis and not direct:
        notes.append("delay-free closed loop has roots on the axis: sampled det(Delta)")
    if np.any(np.abs(p0.real) <= axis_tol):
        a = max(scale, 1.0 / sys.tau)
        notes.append(f"open loop has roots on the axis: reference det M (s+{a:.3g})^2n")
        return _Reference("direct", np.full(p0.shape, -a + 0j), a, 0, tuple(notes))
    return _Reference("direct", p0, None, z_open, tuple(notes))


def _failed(z_open: int, z_p: int, W: float, message: str) -> WindingResult:
    return WindingResult(
        count=-1,
        open_loop_count=z_open,
        n_samples=0,
        min_abs_det=float("nan"),
        status="not_converged",
        message=message,
        omega_max=W,
        delay_free_count=z_p,
    )


def _status(
    w: NDArray[np.float64],
    val: NDArray[np.complex128],
    unresolved: int,
    winding: float,
    count_f: float,
    count: int,
    tail: float,
) -> tuple[str, list[str]]:
    """``converged``, ``marginal`` (a root on the axis: a jump bisection cannot
    resolve, a dip of |F| to ~0, or F(0) ~ 0) or ``not_converged`` (a
    non-integer winding, a large tail phase, too many or non-finite samples)."""
    absf = np.abs(val)
    finite = np.isfinite(val)
    nb = np.maximum(np.r_[absf[1:], 0.0], np.r_[0.0, absf[:-1]])
    dip = bool(np.any(finite & (absf <= 1e-9 * nb))) or bool(np.any(absf[finite] == 0.0))
    status = "converged"
    msg = []
    if unresolved or dip or (val.size and abs(val[0]) <= 1e-12 * max(1.0, float(np.median(absf)))):
        status = "marginal"
        msg.append("a root lies on (or within ~1e-10 relative of) the imaginary axis")
    if abs(count_f - count) > 0.05 or abs(tail) > math.pi / 4:
        status = "not_converged"
        msg.append(
            f"winding {winding:.4g} is not an integer (tail phase {tail:.3g} rad); "
            "raise omega_max or n_points"
        )
    elif w.size > MAX_SAMPLES:
        status = "not_converged"
        msg.append(f"the phase needed more than {MAX_SAMPLES} samples (a very lightly damped pole)")
    if not np.all(finite):
        status = "not_converged" if status == "converged" else status
        msg.append(f"{int(np.sum(~finite))} non-finite samples")
    return status, msg


@dataclass(frozen=True)
class _Pending:
    """A count prepared up to its phase: the system, what is sampled, the band."""

    sys: DelaySystem
    ref: _Reference
    F: Sampler
    W: float
    poles: NDArray[np.complex128]
    p: NDArray[np.complex128]
    scale: float
    z_open: int
    z_p: int
    auto_band: bool  # W not given: band_end still to be found if the phase is sampled


def _prepare(sys: DelaySystem, omega_max: float | None, direct: bool) -> WindingResult | _Pending:
    """The reference, the sampled factor and the band of one count, or the
    result itself when nothing has to be sampled (no delay) or the band does
    not close."""
    p0 = sys.open_loop_poles()
    pf = sys.partial_fractions() if sys.has_delay and not direct else None
    # the delay-free poles: the eigenvalues of the decomposition the partial
    # fractions come from (one eigendecomposition), else computed alone
    p = pf[0] if pf is not None else sys.delay_free_poles()
    scale = max(
        float(np.max(np.abs(p0))) if p0.size else 1.0, float(np.max(np.abs(p))) if p.size else 1.0, 1e-300
    )
    z_open = int(np.sum(p0.real > 0))
    z_p = int(np.sum(p.real > 0))
    if not sys.has_delay:
        # nothing to sample: f = det P / det P0 has the closed-form phase
        marginal = bool(np.any(np.abs(p.real) <= 1e-10 * scale))
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
            proven=not marginal,
        )
    ref = _reference(sys, direct, p0, p, z_open, z_p, scale, pf)
    # det M normalises the direct mode's det(Delta); the factored mode does not use it
    direct_mode = ref.mode == "direct" and len(sys.coeffs) == 3
    logdetM = float(np.linalg.slogdet(sys.coeffs[2])[1]) if direct_mode else 0.0
    F = Sampler(sys, ref.mode, ref.ref, logdetM)
    poles = np.concatenate([p, p0])
    if omega_max is not None:
        W = float(omega_max)
    elif ref.mode == "factored":
        # the certified phase proves its own tail beyond W (doubling it as
        # needed); band_end is found only if the phase has to be sampled
        W = band_start(sys, poles, scale)
    else:
        W, found = band_end(sys, ref.mode, ref.ref_shift, poles, scale)
        if not found:
            return _failed(z_open, z_p, W, "|f - 1| does not decay; is M singular?")
    return _Pending(sys, ref, F, W, poles, p, scale, z_open, z_p, omega_max is None)


def _finish(pd: _Pending, cert: Certificate | None, n_points: int | None) -> WindingResult:
    """The count from the proven phase (``cert``), or else from the sampled one."""
    sys, ref, F, W, z_open, z_p = pd.sys, pd.ref, pd.F, pd.W, pd.z_open, pd.z_p
    if cert is not None:
        w, val, unresolved, total, tail, W = cert.w, cert.val, cert.unresolved, cert.total, 0.0, cert.W
        proven_note = (
            f"every increment proven ({cert.n_passive} passive, {cert.n_lipschitz} Lipschitz intervals,"
            f" passive tail beyond {W:.4g} rad/s)"
        )
    else:
        if pd.auto_band and ref.mode == "factored":
            W, found = band_end(sys, ref.mode, ref.ref_shift, pd.poles, pd.scale)
            if not found:
                return _failed(z_open, z_p, W, "|f - 1| does not decay; is M singular?")
        pieces, n0, passive = initial_grid(sys, ref.mode, W, pd.poles, pd.scale, n_points)
        if n0 > MAX_SAMPLES:
            return _failed(
                z_open, z_p, W, f"{n0} samples needed up to {W:.4g} rad/s; pass a smaller omega_max"
            )
        w, val, passive_iv, unresolved = refine(F, np.unique(np.concatenate(pieces)), passive)
        total, tail = phase_change(w, val, passive_iv, passive, sys.tau)
        proven_note = "increments sampled (wrapped below pi/4), not proven"
    # F(0) is real: its phase is 0 or pi, and the sum starts there
    winding = total / math.pi
    count_f = ref.z_base - winding
    count = int(round(count_f))
    status, msg = _status(w, val, unresolved, winding, count_f, count, tail)
    if cert is not None and not cert.complete and status == "converged":
        status = "not_converged"
        msg.append(f"sample limit {MAX_SAMPLES} reached before every increment was proven")
    msg.append(
        f"{count} RHP root(s): Z = {ref.z_base} - ({winding:.4g}) with "
        f"{w.size} samples on [0, {W:.4g}] rad/s ({ref.mode}); {proven_note}"
    )
    msg.extend(ref.notes)
    finite = np.isfinite(val)
    return WindingResult(
        count=count,
        open_loop_count=z_open,
        n_samples=int(w.size),
        min_abs_det=float(np.min(np.abs(val)[finite])) if np.any(finite) else float("nan"),
        status=status,
        message="; ".join(msg),
        omega_max=W,
        delay_free_count=z_p,
        winding=winding,
        proven=cert is not None and status == "converged",
    )


def _count_many(
    systems: list[DelaySystem], omega_max: float | None, n_points: int | None, direct: bool
) -> list[WindingResult]:
    """:func:`rhp_counts` on validated systems (the steps -- reference, band,
    grid, bisection, phase -- are in :mod:`chatterlab.frequency._phase_sampling`).

    In factored form the phase is certified (:func:`certified_phases`, all the
    systems' intervals bisected together) from the first samples
    :func:`certification_grid`: the bounds place every further sample, so the
    dense grid of the sampled route is not laid.  Without a certificate
    (no partial fractions, a tail bound that does not close, the direct mode)
    each count samples its phase from :func:`initial_grid`."""
    pend = [_prepare(sys, omega_max, direct) for sys in systems]
    todo = [i for i, pd in enumerate(pend) if isinstance(pd, _Pending) and pd.ref.mode == "factored"]
    certs = certified_phases(
        [
            (pd.sys, certification_grid(pd.p, pd.W), pd.W)
            for pd in (pend[i] for i in todo)
            if isinstance(pd, _Pending)
        ]
    )
    cert_of = dict(zip(todo, certs, strict=True))
    return [
        pd if isinstance(pd, WindingResult) else _finish(pd, cert_of.get(i), n_points)
        for i, pd in enumerate(pend)
    ]


def rhp_count(
    system: DelaySystem | ClosedLoop,
    *,
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
    system : DelaySystem or ClosedLoop
        The delay equation (:func:`chatterlab.frequency.make_system` builds
        one from ``M, C, K, DP, DV, DO, tau``), or a
        :class:`chatterlab.process.ClosedLoop`.
    omega_max : float, optional
        Upper end of the sampled band in rad/s; default: 3x the largest
        delay-free eigenfrequency, doubled until :math:`|f - 1| < 10^{-3}`;
        in factored form (certified) doubled instead until the bound proves
        :math:`\\|H\\| < 1/2` beyond it (the proven passive tail).
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
        Not a system, or a non-positive ``omega_max`` / ``n_points``.

    References
    ----------
    .. [1] H. Nyquist, Bell Syst. Tech. J. 11, 126-147, 1932.
    .. [2] C. A. Desoer, Y.-T. Wang, IEEE Trans. Autom. Control 25(2),
       187-196, 1980.
    """
    return rhp_counts([system], omega_max=omega_max, n_points=n_points, direct=direct)[0]


def rhp_counts(
    systems: Sequence[DelaySystem | ClosedLoop],
    *,
    omega_max: float | None = None,
    n_points: int | None = None,
    direct: bool = False,
) -> list[WindingResult]:
    """:func:`rhp_count` of several systems, each result the one it would
    give alone, computed together: one BLAS setting, the certified phases
    bisected in one pass over all the systems' intervals
    (:func:`chatterlab.frequency._phase_sampling.certified_phases`), and what
    the systems share (the same open-loop structure, the same delay-free
    loop: :func:`chatterlab.frequency._delay_system.loop_systems`) computed
    once.  Used by the lobe diagram's checks."""
    syss = [as_delay_system(s) for s in systems]
    check_omega_max(omega_max)
    check_integer(n_points, "n_points", 2)
    with single_threaded_blas():
        return _count_many(syss, omega_max, n_points, direct)
