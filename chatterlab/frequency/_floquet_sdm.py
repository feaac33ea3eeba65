"""First-order semi-discretisation of milling (:func:`sdm_monodromy`), the
method compared with the spectral reference in
:mod:`chatterlab.frequency._floquet`."""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ..errors import InputError, check_count, check_nonneg
from ..process._loop import ClosedLoop

__all__ = ["sdm_monodromy", "sdm_multipliers", "matched_change", "finite_monodromy"]


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
    & Turi 2008), ``steps`` steps per period, built as a product of dense
    step matrices (as the method's authors do).

    The state is (x_i, r_{i-1}, ..., r_{i-L}) with r = Jr q the cut
    coordinates; on step i the coefficients are their exact mean over the
    step and r(t - tau_j) is linear between its values at the step's ends,
    each interpolated linearly on the grid.  Helix is not supported (the
    spectral method takes it).
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
    taus = milling.delays(rpm) / dt
    mj = np.floor(taus + 1e-9).astype(int)
    fj = np.clip(taus - mj, 0.0, None)
    if np.any(mj < 1):
        raise InputError(f"sdm: steps must make the step shorter than the shortest delay (steps >= {m * 2})")
    Lh = int(mj.max()) + 1  # history r_{i-1} .. r_{i-Lh}
    D = d + rho * Lh
    t = np.arange(m + 1) * dt
    Hm = milling.directional_mean(t[:-1], t[1:], rpm)  # (m, N, 2, 2)
    Hr = np.einsum("ai,kjab,bl->kjil", Ub, Hm, Ub)
    Phi = np.eye(D)
    # r at grid index i - k for k >= 0: k = 0 is Jr q_i (from x), k >= 1 history slot k - 1
    Jq = np.zeros((rho, d))
    Jq[:, :n] = Jr

    def r_cols(k: int) -> tuple[slice, np.ndarray]:
        if k == 0:
            return slice(0, d), Jq
        i = d + (k - 1) * rho
        return slice(i, i + rho), np.eye(rho)

    # a cut far stiffer than the structure overflows the product: its inf and nan are the
    # caller's to report (finite_monodromy), not a raw numpy warning on the terminal
    with np.errstate(over="ignore", invalid="ignore"):
        for i in range(m):
            Bsum = np.zeros((d, d))
            Gs = []
            for j in range(milling.teeth):
                Hj = Hr[i, j]
                if not np.any(Hj):
                    continue
                Bq = np.zeros((d, rho))
                Bq[n:] = a * (W @ Hj)  # force term per unit r, q' rows
                Bsum[:, :n] += Bq @ Jr
                Gs.append((j, Bq))
            P, F1, F2 = _sdm_steps(A - Bsum, dt)
            G = np.zeros((D, D))
            G[:d, :d] = P
            for j, Bq in Gs:
                # r(t_i - tau_j) = (1 - f) r_{i-m_j} + f r_{i-m_j-1}; r(t_{i+1} - tau_j) likewise shifted by one
                c0 = (F1 - F2 / dt) @ Bq  # weight of u0 (value at the step start)
                c1 = (F2 / dt) @ Bq  # weight of u1 (value at the step end)
                for k, wgt in ((mj[j], 1 - fj[j]), (mj[j] + 1, fj[j])):
                    if wgt:
                        sl, R = r_cols(int(k))
                        G[:d, sl] += wgt * c0 @ R
                for k, wgt in ((mj[j] - 1, 1 - fj[j]), (mj[j], fj[j])):
                    if wgt:
                        sl, R = r_cols(int(k))
                        G[:d, sl] += wgt * c1 @ R
            # shift the history: new r_{i} = Jr q_i, r_{i-k} <- r_{i-k+1}
            G[d : d + rho, :d] = Jq
            for k in range(1, Lh):
                G[d + k * rho : d + (k + 1) * rho, d + (k - 1) * rho : d + k * rho] = np.eye(rho)
            Phi = G @ Phi
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
