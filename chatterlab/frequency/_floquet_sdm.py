"""First-order semi-discretisation of milling (:func:`sdm_monodromy`), the
method compared with the spectral reference in
:mod:`chatterlab.frequency._floquet`."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import scipy.linalg as sla

from ..errors import InputError, check_count, check_nonneg
from ..process._damping import milling_rubbing
from ..process._loop import ClosedLoop

__all__ = [
    "sdm_monodromy",
    "sdm_multipliers",
    "sdm_steps",
    "sd_step_product",
    "sd_fixed_point",
    "sdm_forced",
    "matched_change",
    "finite_monodromy",
]


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
    return sd_step_product(*sdm_steps(loop, rpm, depth, steps))


def sdm_steps(
    loop: ClosedLoop, rpm: float, depth: float, steps: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """The step data of :func:`sdm_monodromy` (A_steps, B_steps, Jq, lag_start, lag_end, dt),
    the arguments of :func:`sd_step_product`: step i is [i dt, (i + 1) dt], dt = T / steps."""
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
    return A_steps, B_steps, Jq, lags, lag_end, dt


def sdm_forced(
    loop: ClosedLoop, rpm: float, depth: float, steps: int, mean_force: Any
) -> tuple[np.ndarray, np.ndarray, float]:
    """The periodic forced motion of the semi-discretised milling loop (the steps of
    :func:`sdm_monodromy`, the same monodromy) under the force a_p f(t) on the tool:
    (Phi, x, dt), x (steps + 1, d) the state (q, q') at t_i = i dt on the fixed point
    (:func:`sd_fixed_point`).

    ``mean_force(t0, t1)`` gives f's mean over each step [t0_i, t1_i], per unit depth, in the
    tool's (x, y) (N/m, shape (steps, 2)); it enters x' on the velocity rows as
    a_p M^-1 J^T f, the process's force through the cut basis, as the regenerative one does.
    """
    A_steps, B_steps, Jq, lags, lag_end, dt = sdm_steps(loop, rpm, depth, steps)
    m, d = A_steps.shape[0], A_steps.shape[1]
    Ub, _, W = loop.cut_basis
    t = np.arange(m + 1) * dt
    f = np.asarray(mean_force(t[:-1], t[1:]), dtype=float)  # (m, 2)
    forcing = np.zeros((m, d))
    forcing[:, loop.n :] = float(depth) * (f @ Ub) @ W.T
    Phi, x = sd_fixed_point(A_steps, B_steps, Jq, lags, lag_end, dt, forcing)
    return Phi, x, dt


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
    The same steps with a constant input on each (the forced response's
    affine term) and the fixed point of the period's map: :func:`sd_fixed_point`.

    References
    ----------
    T. Insperger, G. Stepan, Updated semi-discretization method for periodic
    delay-differential equations with discrete delay, Int. J. Numer. Meth.
    Engng 61 (2004) 117-141; T. Insperger, G. Stepan, Stability analysis of
    turning with periodic spindle speed modulation via semidiscretization,
    J. Vib. Control 10 (2004) 1835-1855.
    """
    return _sd_product(A_steps, B_steps, Jq, lag_start, lag_end, dt)[0]


#: the discretisations of a one-period map (Floquet multipliers, the forced orbit, SSV)
METHODS = ("spectral", "sdm")


def check_method(method: Any) -> str:
    """``method`` if it is one of :data:`METHODS`, else one line naming them."""
    if method not in METHODS:
        raise InputError(f"method must be 'spectral' or 'sdm' (got {method!r})")
    return str(method)


class _Steps:
    """The grid of :func:`sd_step_product`: where each step's delayed r comes from (the
    history slots and their weights) and the state's size D = d + rho L."""

    def __init__(self, Jq: np.ndarray, lag_start: np.ndarray, lag_end: np.ndarray, d: int) -> None:
        m = lag_start.shape[0]
        self.d, self.rho, self.Jq = d, Jq.shape[0], Jq
        self.mj = np.floor(lag_start + 1e-9).astype(int)
        self.fj = np.clip(lag_start - self.mj, 0.0, None)
        e1 = np.floor(lag_end + 1e-9).astype(int)  # the step's end is one step later: offset lag - 1
        self.fe = np.clip(lag_end - e1, 0.0, None)
        self.me = e1 - 1
        if np.any(self.mj < 1) or np.any(self.me < 0):
            # the lags are in steps of this grid: the shortest one, 1 step at least, asks this many
            short = float(min(np.min(lag_start), np.min(lag_end)))
            need = math.ceil(m / short - 1e-9) if short > 0 else 2 * m
            raise InputError(
                f"sdm: steps must make the step shorter than the shortest delay (steps >= {need}; got {m})"
            )
        self.Lh = int(max(self.mj.max(), self.me.max())) + 1  # history r_{i-1} .. r_{i-Lh}
        self.D = d + self.rho * self.Lh

    def r_cols(self, k: int) -> tuple[slice, np.ndarray]:
        """r at grid index i - k for k >= 0: k = 0 is Jq x_i (from x), k >= 1 history slot k - 1."""
        if k == 0:
            return slice(0, self.d), self.Jq
        i = self.d + (k - 1) * self.rho
        return slice(i, i + self.rho), np.eye(self.rho)

    def rows(
        self, i: int, P: np.ndarray, F1: np.ndarray, F2: np.ndarray, B_i: np.ndarray, dt: float
    ) -> np.ndarray:
        """The first d rows of step i's matrix: x_{i+1} = G z_i (+ the step's forcing)."""
        d = self.d
        G = np.zeros((d, self.D))
        G[:d, :d] = P
        for j in range(B_i.shape[0]):
            Bq = B_i[j]
            if not np.any(Bq):
                continue
            # r(t_i - tau_j) = (1 - f) r_{i-m_j} + f r_{i-m_j-1}; r(t_{i+1} - tau_j) likewise shifted by one
            c0 = (F1 - F2 / dt) @ Bq  # weight of u0 (value at the step start)
            c1 = (F2 / dt) @ Bq  # weight of u1 (value at the step end)
            for k, wgt in ((self.mj[i, j], 1 - self.fj[i, j]), (self.mj[i, j] + 1, self.fj[i, j])):
                if wgt:
                    sl, R = self.r_cols(int(k))
                    G[:d, sl] += wgt * c0 @ R
            for k, wgt in ((self.me[i, j], 1 - self.fe[i, j]), (self.me[i, j] + 1, self.fe[i, j])):
                if wgt:
                    sl, R = self.r_cols(int(k))
                    G[:d, sl] += wgt * c1 @ R
        return G

    def shift(self, G: np.ndarray, Z: np.ndarray) -> np.ndarray:
        """The step matrix [G; Jq 0; shift] times Z (a matrix or a vector): the new r_i = Jq x_i,
        r_{i-k} <- r_{i-k+1}; dense in its first d rows only, so O(d D^2) for a matrix, not O(D^3)."""
        d, rho, D = self.d, self.rho, self.D
        out = np.empty_like(Z)
        out[:d] = G[:d] @ Z
        out[d : d + rho] = self.Jq @ Z[:d]
        out[d + rho :] = Z[d : D - rho]
        return out


def _sd_product(
    A_steps: np.ndarray,
    B_steps: np.ndarray,
    Jq: np.ndarray,
    lag_start: np.ndarray,
    lag_end: np.ndarray,
    dt: float,
    forcing: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray | None, list[tuple[np.ndarray, np.ndarray, np.ndarray]]]:
    """(Phi, c, exps): the one-period map z' = Phi z + c of :func:`sd_step_product` with the
    steps' constant inputs ``forcing`` (m, d) added to x' (c None without them), and each
    step's exponentials (P, F1, F2) for a second pass along the period (only with forcing)."""
    m, d = A_steps.shape[0], A_steps.shape[1]
    grid = _Steps(Jq, lag_start, lag_end, d)
    Phi = np.eye(grid.D)
    c = None if forcing is None else np.zeros(grid.D)
    exps = []
    # a cut far stiffer than the structure overflows the product: its inf and nan are the
    # caller's to report (finite_monodromy), not a raw numpy warning on the terminal
    with np.errstate(over="ignore", invalid="ignore"):
        for i in range(m):
            P, F1, F2 = _sdm_steps(A_steps[i], dt)
            G = grid.rows(i, P, F1, F2, B_steps[i], dt)
            Phi = grid.shift(G, Phi)
            if forcing is not None and c is not None:
                c = grid.shift(G, c)
                c[:d] += F1 @ forcing[i]  # int_0^dt e^{A(dt-s)} ds w_i: the step's forced part
                exps.append((P, F1, F2))
    return Phi, c, exps


def sd_fixed_point(
    A_steps: np.ndarray,
    B_steps: np.ndarray,
    Jq: np.ndarray,
    lag_start: np.ndarray,
    lag_end: np.ndarray,
    dt: float,
    forcing: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The periodic solution of the semi-discretised system forced by the steps' constant
    inputs: (Phi, x), Phi the monodromy of :func:`sd_step_product` (the same steps) and x
    (m + 1, d) the state at the grid points t_0 .. t_m of the fixed point of the one-period
    map, x[m] = x[0] to its round-off.

    On step i the state obeys x' = A_i x + sum_j B_ij r(t - tau_j) + w_i, w_i = ``forcing[i]``
    (the force's mean over the step, as the coefficients'); solved exactly, the step adds
    F1_i w_i = int_0^dt e^{A_i (dt - s)} ds w_i to the first d rows, so one period is the
    affine map z' = Phi z + c, c the sum of the steps' terms carried to the period's end, and
    the periodic motion is its fixed point (I - Phi) z* = c (Insperger, Gradisek, Kalveram,
    Stepan, Winert & Weinert 2006).  InputError when I - Phi is singular to working
    precision (a multiplier at 1: no unique periodic motion).
    """
    m, d = A_steps.shape[0], A_steps.shape[1]
    Phi, c, exps = _sd_product(A_steps, B_steps, Jq, lag_start, lag_end, dt, forcing)
    assert c is not None
    Dn = Phi.shape[0]
    with np.errstate(over="ignore", invalid="ignore"):
        Ic = np.eye(Dn) - Phi
        if not np.all(np.isfinite(Ic)):
            return Phi, np.full((m + 1, d), np.nan)
        lu = sla.lu_factor(Ic, check_finite=False)
        if np.min(np.abs(np.diag(lu[0]))) <= Dn * np.finfo(float).eps * np.max(np.abs(Ic)):
            raise InputError(
                "sdm fixed point: a Floquet multiplier is 1 (I - Phi is singular): no unique periodic motion"
            )
        z = sla.lu_solve(lu, c, check_finite=False)
    grid = _Steps(Jq, lag_start, lag_end, d)
    x = np.empty((m + 1, d))
    x[0] = z[:d]
    for i, (P, F1, F2) in enumerate(exps):
        G = grid.rows(i, P, F1, F2, B_steps[i], dt)
        z = grid.shift(G, z)
        z[:d] += F1 @ forcing[i]
        x[i + 1] = z[:d]
    return Phi, x


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
