"""Chebyshev collocation of the delay equation's infinitesimal generator, one frequency window at a time.

Only the delayed output :math:`z = V^T q` needs a discretised history, so the
generator matrix has size :math:`2n + N r`.  In a window centred at
:math:`j\\omega_0` the history is represented by the envelope
:math:`e^{-j\\omega_0\\theta} z(\\theta)` (the generator of the equation
for :math:`e^{-j\\omega_0 t} q(t)`, shifted back by :math:`j\\omega_0`), so
``N`` grows with the window radius times :math:`\\tau`, not with
:math:`\\omega_0\\tau`.  Eigenvalues within the trusted radius are refined
by Newton and kept when a second, finer discretisation (``N2 = 1.5 N``)
reproduces them.

References
----------
.. [1] D. Breda, S. Maset, R. Vermiglio, "Pseudospectral differencing methods
   for characteristic roots of delay differential equations", SIAM J. Sci.
   Comput. 27(2), 482-495, 2005.
.. [2] L. N. Trefethen, *Spectral Methods in MATLAB*, SIAM 2000, ch. 6
   (Chebyshev differentiation matrices).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._delay_system import DelaySystem
from ._newton import canonical, dedupe, match, newton, root_scale
from ._roots_result import TooLarge

__all__ = ["chebyshev_nodes", "Window", "WINDOW_MAX", "solve_window", "make_window", "window_size"]

ComplexArray = NDArray[np.complex128]
FloatArray = NDArray[np.float64]

# Chebyshev collocation with N+1 nodes on [-tau, 0] resolves exp(s*theta) for
# |s| tau / 2 clearly below N; we trust eigenvalues with |s| <= N / tau, i.e.
# half the resolution limit, and use N = ceil(R tau) + _N_EXTRA for a radius R.
_N_EXTRA = 12
N2_FACTOR = 1.5


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


def generator_matrix(sys: DelaySystem, N: int, omega0: float) -> NDArray[Any]:
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
class Window:
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


def solve_window(sys: DelaySystem, w: Window, match_tol: float, model: DelaySystem | None = None) -> None:
    """The roots of ``sys`` in the window ``w``: the eigenvalues of the
    generator of ``model`` (default ``sys``; a reduced model of it,
    :meth:`DelaySystem.band_model`) at ``N`` and ``N2`` nodes near the window,
    each refined by Newton on ``sys`` (from its low-rank factorisation when
    ``model`` is a reduced one), kept when both discretisations give it."""
    gen = sys if model is None else model
    size = gen.A.shape[0] + w.N2 * gen.r
    if size > WINDOW_MAX:
        raise TooLarge(
            f"a window of radius {w.radius:.4g} rad/s at {w.centre / 2 / math.pi:.4g} Hz needs a"
            f" {size} x {size} eigenproblem (limit {WINDOW_MAX}): roots far from the imaginary axis"
            " (e.g. an unstable delay-free loop) with a long delay; pass omega_max or n_nodes"
        )
    scale = root_scale(sys)
    found = []
    for N in (w.N, w.N2):
        G = generator_matrix(gen, N, w.centre)
        try:
            ev = np.linalg.eigvals(G)
        except np.linalg.LinAlgError:
            w.failed = f"eigenvalue solver failed (N={N}, centre {w.centre:.6g} rad/s)"
            found.append((np.zeros(0, complex), 0))
            continue
        s = ev - 1j * w.centre
        pre = ev[(np.abs(s) <= 1.3 * w.radius) & (ev.imag >= -0.05 * w.radius - 1e-12 * scale)]
        lam, ok = newton(sys, pre, factored=gen is not sys)
        lam_ok = canonical(lam[ok], scale)
        inside = np.abs(lam_ok - 1j * w.centre) <= w.radius
        # roots mapped from the lower half plane may sit outside the disc
        inside |= np.abs(lam_ok.conj() - 1j * w.centre) <= w.radius
        good = dedupe(lam_ok[inside], 1e-8, scale)
        # candidates in the trusted disc whose Newton iteration failed
        nfail = int(np.sum(~ok & (np.abs(pre - 1j * w.centre) <= w.radius)))
        found.append((good, nfail))
    (a, fa), (b, _) = found
    conf = match(a, b, match_tol, scale)
    w.roots = a[conf]
    w.rejected = int(np.sum(~conf)) + fa


def _n_for_radius(R: float, tau: float) -> int:
    return int(math.ceil(R * tau)) + _N_EXTRA


def make_window(centre: float, R: float, tau: float) -> Window:
    N = _n_for_radius(R, tau)
    return Window(centre, R, N, int(math.ceil(N2_FACTOR * N)))


def window_size(sys: DelaySystem, R: float) -> int:
    N2 = int(math.ceil(N2_FACTOR * _n_for_radius(R, sys.tau)))
    return sys.A.shape[0] + N2 * sys.r
