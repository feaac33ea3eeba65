"""First-order semi-discretisation of milling (:func:`sdm_monodromy`), the
method compared with the spectral reference in
:mod:`chatterlab.frequency._floquet`."""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ..errors import InputError, check_count, check_nonneg
from ..process._damping import milling_rubbing
from ..process._loop import ClosedLoop

__all__ = ["sdm_monodromy", "sdm_multipliers", "sd_step_product", "matched_change", "finite_monodromy"]


def _sdm_steps(A_i: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """e^{A dt}, int_0^dt e^{A(dt-s)} ds and int_0^dt e^{A(dt-s)} s ds (Van Loan)."""
    d = A_i.shape[0]
    Z = np.zeros((3 * d, 3 * d))
    Z[:d, :d] = A_i
    Z[:d, d : 2 * d] = np.eye(d)
    Z[d : 2 * d, 2 * d :] = np.eye(d)
    E = sla.expm(Z * dt)
    return E[:d, :d], E[:d, d : 2 * d], E[:d, 2 * d :]


def sdm_monodromy(loop: ClosedLoop, rpm: float, depth: float, steps: int = 40) -> np.ndarray:
    """Monodromy matrix of first-order semi-discretisation (Insperger, Stepan
    & Turi 2008), ``steps`` steps per period, built as a product of the
    step matrices (:func:`sd_step_product`).

    The state is (x_i, r_{i-1}, ..., r_{i-L}) with r = Jr q the cut
    coordinates; on step i the coefficients are their exact mean over the
    step and r(t - tau_j) is linear between its values at the step's ends,
    each interpolated linearly on the grid.  Helix is not supported (the
    spectral method takes it).  A cutter whose spindle speed varies
    (:class:`~chatterlab.process.VaryingSpeedMilling`) gives its delays at
    every step's ends (``delays_at``), its period and its steps' mean
    coefficients: the same product (:func:`sd_step_product`).
    """
    m = check_count(steps, "steps", 2)
    milling = loop.milling
    if milling.helix > 0:
        raise InputError("sdm: helix is not supported; use method='spectral'")
    a = check_nonneg(depth, "depth of cut a_p", "m")
    A = loop.state_matrix
    d = A.shape[0]
    n = loop.n
    Ub, Jr, W = loop.cut_basis
    rho = Jr.shape[0]
    T = milling.period(rpm)
    dt = T / m
    t = np.arange(m + 1) * dt
    delays_at = getattr(milling, "delays_at", None)  # a spindle-speed variation's delays tau_j(t)
    if delays_at is None:
        lags = lag_end = np.broadcast_to(milling.delays(rpm) / dt, (m, milling.teeth))
    else:
        lags, lag_end = delays_at(t[:-1], rpm) / dt, delays_at(t[1:], rpm) / dt
    Hm = milling.directional_mean(t[:-1], t[1:], rpm)  # (m, N, 2, 2)
    Hr = np.einsum("ai,kjab,bl->kjil", Ub, Hm, Ub)
    Jq = np.zeros((rho, d))
    Jq[:, :n] = Jr
    # process damping: the rubbing flanks' -a_p g W(t) r', its exact mean over each step (no delay:
    # one more term of the step's state matrix, in its velocity columns)
    Vd = np.zeros((m, d, d))
    rubbing = milling_rubbing(loop, rpm)
    if rubbing is not None:
        g, rub = rubbing
        Wm = np.einsum("ai,kjab,bl->kil", Ub, rub.directional_mean(t[:-1], t[1:], rpm), Ub)  # (m, rho, rho)
        Vd[:, n:, n:] = (a * g) * np.einsum("qr,krs,sp->kqp", W, Wm, Jr)
    A_steps = np.empty((m, d, d))
    B_steps = np.zeros((m, milling.teeth, d, rho))
    for i in range(m):
        Bsum = np.zeros((d, d))
        for j in range(milling.teeth):
            Hj = Hr[i, j]
            if not np.any(Hj):
                continue
            Bq = np.zeros((d, rho))
            Bq[n:] = a * (W @ Hj)  # force term per unit r, q' rows
            Bsum[:, :n] += Bq @ Jr
            B_steps[i, j] = Bq
        A_steps[i] = A - Bsum - Vd[i]
    return sd_step_product(A_steps, B_steps, Jq, lags, lag_end, dt)


def sd_step_product(
    A_steps: np.ndarray,
    B_steps: np.ndarray,
    Jq: np.ndarray,
    lag_start: np.ndarray,
    lag_end: np.ndarray,
    dt: float,
) -> np.ndarray:
    """The monodromy of first-order semi-discretisation as the product of its
    step matrices (dense in their first d rows, a shift below): the one step of the method, for constant delays
    (:func:`sdm_monodromy`) and for delays that vary along the period
    (spindle-speed variation, :mod:`chatterlab.frequency._floquet_ssv`).

    On step i (length ``dt``) the state obeys x' = A_i x + sum_j B_ij r(t - tau_j(t))
    with r = Jq x; the delayed r is linear in time over the step between its
    values at the step's ends, each interpolated linearly on the grid at
    ``lag_start[i, j]`` and ``lag_end[i, j]`` steps back (the delay at the
    step's start and end, in steps; both >= 1).  The state is
    (x_i, r_{i-1}, ..., r_{i-L}).  Shapes: A_steps (m, d, d), B_steps
    (m, J, d, rho) (an all-zero B_ij is skipped), Jq (rho, d), lags (m, J).

    References
    ----------
    T. Insperger, G. Stepan, Updated semi-discretization method for periodic
    delay-differential equations with discrete delay, Int. J. Numer. Meth.
    Engng 61 (2004) 117-141; T. Insperger, G. Stepan, Stability analysis of
    turning with periodic spindle speed modulation via semidiscretization,
    J. Vib. Control 10 (2004) 1835-1855.
    """
    m, d = A_steps.shape[0], A_steps.shape[1]
    rho = Jq.shape[0]
    mj = np.floor(lag_start + 1e-9).astype(int)
    fj = np.clip(lag_start - mj, 0.0, None)
    e1 = np.floor(lag_end + 1e-9).astype(int)  # the step's end is one step later: offset lag - 1
    fe = np.clip(lag_end - e1, 0.0, None)
    me = e1 - 1
    if np.any(mj < 1) or np.any(me < 0):
        raise InputError(f"sdm: steps must make the step shorter than the shortest delay (steps >= {m * 2})")
    Lh = int(max(mj.max(), me.max())) + 1  # history r_{i-1} .. r_{i-Lh}
    D = d + rho * Lh
    Phi = np.eye(D)

    # r at grid index i - k for k >= 0: k = 0 is Jq x_i (from x), k >= 1 history slot k - 1
    def r_cols(k: int) -> tuple[slice, np.ndarray]:
        if k == 0:
            return slice(0, d), Jq
        i = d + (k - 1) * rho
        return slice(i, i + rho), np.eye(rho)

    # a cut far stiffer than the structure overflows the product: its inf and nan are the
    # caller's to report (finite_monodromy), not a raw numpy warning on the terminal
    with np.errstate(over="ignore", invalid="ignore"):
        for i in range(m):
            P, F1, F2 = _sdm_steps(A_steps[i], dt)
            G = np.zeros((d, D))
            G[:d, :d] = P
            for j in range(B_steps.shape[1]):
                Bq = B_steps[i, j]
                if not np.any(Bq):
                    continue
                # r(t_i - tau_j) = (1 - f) r_{i-m_j} + f r_{i-m_j-1}; r(t_{i+1} - tau_j) likewise shifted by one
                c0 = (F1 - F2 / dt) @ Bq  # weight of u0 (value at the step start)
                c1 = (F2 / dt) @ Bq  # weight of u1 (value at the step end)
                for k, wgt in ((mj[i, j], 1 - fj[i, j]), (mj[i, j] + 1, fj[i, j])):
                    if wgt:
                        sl, R = r_cols(int(k))
                        G[:d, sl] += wgt * c0 @ R
                for k, wgt in ((me[i, j], 1 - fe[i, j]), (me[i, j] + 1, fe[i, j])):
                    if wgt:
                        sl, R = r_cols(int(k))
                        G[:d, sl] += wgt * c1 @ R
            # shift the history: new r_{i} = Jq x_i, r_{i-k} <- r_{i-k+1}; the step matrix is
            # dense in its first d rows only, so the product costs O(d D^2), not O(D^3)
            out = np.empty_like(Phi)
            out[:d] = G[:d] @ Phi
            out[d : d + rho] = Jq @ Phi[:d]
            out[d + rho :] = Phi[d : D - rho]
            Phi = out
    return Phi


def matched_change(mu: complex, others: np.ndarray) -> float:
    """|mu - nu| for the member nu of ``others`` nearest ``mu``: the change
    of one multiplier between two resolutions.

    Multipliers are matched by distance, not by rank: a complex pair has
    one modulus, so ranking by |mu| picks either member and compares mu
    with its conjugate (an "error" of 2 |Im mu|)."""
    nu = np.asarray(others, dtype=complex).ravel()
    if nu.size == 0:
        return float("nan")
    return float(np.min(np.abs(nu - complex(mu))))


def _ranked(mu: np.ndarray) -> np.ndarray:
    """Largest modulus first; of a conjugate pair (equal modulus to round-off)
    the member with Im >= 0 first, so the critical one does not depend on the
    eigensolver's order."""
    r = np.abs(mu)
    key = np.round(r / max(float(r.max(initial=0.0)), 1e-300), 12)
    return mu[np.lexsort((-mu.imag, -key))]


def sdm_multipliers(
    loop: ClosedLoop,
    rpm: float,
    depth: float,
    steps: int = 40,
    check: bool = True,
) -> tuple[np.ndarray, float]:
    """The SDM multipliers (largest modulus first, :func:`_ranked`) and the
    convergence error of the critical one: its change when the steps are
    doubled, matched by distance (:func:`matched_change`); nan without
    ``check``.

    The multipliers of first-order SDM converge as steps^-p with p = 2
    (Insperger, Stepan & Turi 2008; p = 1 at worst before the asymptotic
    range), so with e(m) = C m^-p the change e(m) - e(2m) is
    (1 - 2^-p) e(m): the error estimate is 3/4 (p = 2) to 1/2 (p = 1) of
    the true error of the ``steps`` result, and a close bound on that of
    the doubled-steps one (e(2m) = e(m) / 2^p)."""
    mu = _ranked(np.linalg.eigvals(finite_monodromy(sdm_monodromy(loop, rpm, depth, steps), rpm, depth)))
    err = float("nan")
    if check:
        mu2 = np.linalg.eigvals(finite_monodromy(sdm_monodromy(loop, rpm, depth, 2 * steps), rpm, depth))
        err = matched_change(complex(mu[0]), mu2)
    return mu, err


def finite_monodromy(X: np.ndarray, rpm: float, depth: float) -> np.ndarray:
    """X, or an InputError when it overflowed: a cut so far beyond the structure's stiffness
    that one period multiplies the motion past 1e308 (a model in the wrong units, a depth
    far above any limit)."""
    if not np.all(np.isfinite(X)):
        raise InputError(
            f"the Floquet multipliers at a_p = {depth * 1e3:g} mm, {rpm:g} rpm overflow (one period multiplies"
            " the motion past 1e308): the cut is far stiffer than the structure; check the model's stiffness"
            " and units, or give a smaller depth"
        )
    return X
