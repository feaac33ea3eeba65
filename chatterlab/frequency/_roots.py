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

This module holds the entry points and the search of the certified band;
the pieces live beside it: the system in ``_delay_system.py``, the spectral
search in ``_spectral.py`` (frequency windows) and ``_collocation.py`` (the
discretised generator), the predictions and the ``"branch"`` method in
``_branches.py``, Newton in ``_newton.py``, the band in ``_band.py``.

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

import dataclasses
import math
import time
from typing import Any

import numpy as np

from chatterlab.errors import InputError

from ..process._loop import ClosedLoop
from ._band import SIGMA_TAU, band_top, certified_top
from ._branches import AXIS_GRID_MAX, branch_roots
from ._checks import check_count, check_integer, check_omega_max
from ._collocation import WINDOW_MAX, chebyshev_nodes
from ._delay_system import (
    DelaySystem,
    as_delay_system,
    loop_system,
    make_first_order_system,
    make_system,
    single_threaded_blas,
)
from ._newton import newton_refine, root_scale
from ._roots_result import RootsResult, TooLarge, make_result
from ._spectral import spectral_roots

__all__ = [
    "RootsResult",
    "DelaySystem",
    "make_system",
    "make_first_order_system",
    "loop_system",
    "characteristic_roots",
    "newton_refine",
    "chebyshev_nodes",
    "certified_top",
    "AXIS_GRID_MAX",
    "WINDOW_MAX",
]


def _no_delay(sys: DelaySystem, count: int, t0: float) -> RootsResult:
    try:
        ev = sys.delay_free_poles()
    except np.linalg.LinAlgError as exc:
        return make_result(
            [],
            method="eig",
            n_nodes=(0, 0),
            rejected=0,
            status="not_converged",
            message=f"eigenvalue solver failed: {exc}",
            t0=t0,
        )
    scale = root_scale(sys)
    ev = ev[ev.imag >= -1e-12 * np.maximum(np.abs(ev), scale)]
    ev = np.where(np.abs(ev.imag) <= 1e-12 * np.maximum(np.abs(ev), scale), ev.real + 0j, ev)
    ev = ev[np.lexsort((ev.imag, -ev.real))]
    total = ev.size
    ev = ev[:count]
    msg = f"no delay: eigenvalues of the linearised (companion) problem, {total} in Im >= 0"
    if total < count:
        msg += f"; only {total} roots exist (count={count})"
    return make_result(ev, method="eig", n_nodes=(0, 0), rejected=0, status="converged", message=msg, t0=t0)


def _dispatch(
    sys: DelaySystem,
    count: Any,
    method: str,
    omega_max: float | None,
    n_nodes: int | None,
    match_tol: float,
    max_windows: int,
) -> RootsResult:
    """Check the options, then search: the eigenvalues without a delay, the
    caller's band or nodes when given, else the certified band."""
    t0 = time.perf_counter()
    count = check_count(count)
    if method not in ("auto", "spectral", "branch"):
        raise InputError(f"method must be 'auto', 'spectral' or 'branch' (got {method!r})")
    omega_max = check_omega_max(omega_max)
    check_integer(n_nodes, "n_nodes", 2)
    with single_threaded_blas():
        if not sys.has_delay:
            # every root is an eigenvalue of the linearisation: complete
            return dataclasses.replace(_no_delay(sys, count, t0), complete_above=-math.inf)
        try:
            if omega_max is not None or n_nodes is not None:
                return _search(sys, count, method, omega_max, n_nodes, match_tol, max_windows, t0)
            return _search_certified(sys, count, method, match_tol, max_windows, t0)
        except TooLarge as exc:
            return make_result(
                np.zeros(0, complex),
                method=method,
                n_nodes=(0, 0),
                rejected=0,
                status="not_converged",
                message=str(exc),
                t0=t0,
            )


def _search(
    sys: DelaySystem,
    count: int,
    method: str,
    omega_max: float | None,
    n_nodes: int | None,
    match_tol: float,
    max_windows: int,
    t0: float,
) -> RootsResult:
    """One search by the method asked for, in the band up to ``omega_max``."""
    if method == "branch":
        return branch_roots(sys, count, omega_max, t0)
    return spectral_roots(sys, count, omega_max, n_nodes, match_tol, max_windows, t0)


def _search_certified(
    sys: DelaySystem, count: int, method: str, match_tol: float, max_windows: int, t0: float
) -> RootsResult:
    """Search the band that the loop's gain bound certifies for Re >= sigma
    (sigma = -SIGMA_TAU / tau first), widened (lowering sigma, at most three
    times) until it holds the ``count`` rightmost roots found; the result says
    which line the band is proven for (``complete_above``)."""
    sigma = -SIGMA_TAU / sys.tau
    top = band_top(sys, count, None, sigma)
    for attempt in range(4):
        res = _search(sys, count, method, top, None, match_tol, max_windows, t0)
        low = float(res.roots.real.min()) if res.roots.size else sigma
        if not res.converged or low >= sigma:
            break
        sigma2 = low - 1.0 / sys.tau
        top2 = band_top(sys, count, None, sigma2)
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


def characteristic_roots(
    system: DelaySystem | ClosedLoop,
    *,
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
    system : DelaySystem or ClosedLoop
        The delay equation: a :class:`chatterlab.process.ClosedLoop`, or a
        :class:`DelaySystem` from :func:`make_system` (``M, C, K, DP, DV,
        DO, tau``: no delayed term, the quadratic eigenvalue problem is
        solved) or :func:`make_first_order_system` (:math:`\\det(\\lambda I
        - A_0 - A_1 e^{-\\lambda\\tau}) = 0`, e.g. the scalar test equation
        :math:`\\dot x = a x + b x(t-\\tau)`).  A prepared system shares its
        partial fractions and band with :func:`chatterlab.frequency.rhp_count`.
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
        Not a system, ``count < 1``, unknown method.

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
    sys = as_delay_system(system)
    return _dispatch(sys, count, method, omega_max, n_nodes, match_tol, max_windows)
