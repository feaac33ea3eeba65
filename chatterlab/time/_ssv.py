"""The linear cut under spindle-speed variation in the time domain: Eq. (1)
of :mod:`chatterlab.frequency._floquet_ssv` (the regenerative loop whose
delays tau_j(t) follow the speed program) integrated by the one Newmark
step of the package (:func:`chatterlab.time._core.step_map`), the delayed
values read from the stored steps by the one cubic Hermite interpolation
(:func:`chatterlab.time._core.hermite_weights`) at t - tau_j(t).

The structure M q'' + C q' + K q = P^T F is cut through r = P q (P the
cut's coordinates: the tool point in milling, the delayed term's factor
V^T in turning, D_O = U V^T):

* turning / shaping: the current terms D_P, D_V go into K and C, and the
  delayed force U (b V^T q(t - tau(t))) is known before the step (h <= tau);
* milling: F = -b sum_j H_j(t) [r(t) - r(t - tau_j(t))] is implicit in r at
  the step's end, r = r* + Z F (the step's compliance): a 2 x 2 solve.

The record is the displacement at every step; :meth:`SsvRun.growth` is the
growth factor of its envelope over one period of the cut, the quantity the
critical Floquet multiplier |mu| predicts (Insperger & Stepan 2004 compare
their multipliers with simulations the same way).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError, check_count, check_nonneg, check_positive
from ..process import VaryingDelayLoop
from ._core import hermite_weights, step_map

__all__ = ["SsvRun", "simulate_ssv"]

#: the largest number of steps one run may take
MAX_STEPS = 5_000_000


@dataclass(frozen=True, eq=False)
class SsvRun:
    """A time history of the linear cut under SSV: ``t`` (s), ``q`` (steps x n, m),
    the cut's ``period`` (s) and the step ``h`` (s)."""

    t: np.ndarray
    q: np.ndarray
    period: float
    h: float

    def envelope(self) -> np.ndarray:
        """max |q| over each whole period of the run, m."""
        per = int(round(self.period / self.h))
        k = self.q.shape[0] // per
        amp = np.abs(self.q[: k * per]).max(axis=1)
        return amp.reshape(k, per).max(axis=1)

    def growth(self, last: int = 3) -> float:
        """The envelope's growth factor per period, the geometric mean over the ``last``
        periods: |mu| of the critical multiplier once the others have died out."""
        env = self.envelope()
        if env.size < last + 1:
            raise InputError(f"the run holds {env.size} periods; the growth needs at least {last + 1}")
        return float((env[-1] / env[-1 - last]) ** (1.0 / last))


def simulate_ssv(
    sys: VaryingDelayLoop,
    width: float,
    periods: int,
    *,
    steps_per_period: int | None = None,
    omega_h: float = 0.05,
    q0: float = 1e-6,
) -> SsvRun:
    """Integrate Eq. (1) at width ``width`` over ``periods`` periods of the cut.

    Parameters
    ----------
    sys : VaryingDelayLoop
        The loop under the speed program (:func:`chatterlab.process.ssv_loop`).
    width : float
        Width of cut b (milling: a_p), m.
    periods : int
        Periods of the cut to integrate.
    steps_per_period : int, optional
        Newmark steps per period (default: the structure's fastest pole turning by
        ``omega_h`` radians per step, and at least 20 steps per shortest delay).
    omega_h : float
        The default step's omega_max h.
    q0 : float
        Initial displacement (m) of every coordinate along the cut's first direction;
        the history before t = 0 is at rest.

    Returns
    -------
    SsvRun
    """
    b = check_nonneg(width, "width of cut", "m")
    k = check_count(periods, "periods", 1)
    if sys.split_parts is not None or sys.Acd is not None:
        raise InputError(
            "simulate_ssv: a quasi-static split or process damping (a gain that follows the speed) is not"
            " integrated in time: simulate the loop without them"
        )
    loop = sys.loop
    st = loop.structure
    n = st.n
    T = sys.period
    if steps_per_period is None:
        om = max(float(loop.omega_max), 1.0 / T)
        m = max(math.ceil(om * T / check_positive(omega_h, "omega_h")), math.ceil(20 * T / sys.tau_range[0]))
    else:
        m = check_count(steps_per_period, "steps_per_period", 2)
    h = T / m
    if h > sys.tau_range[0]:
        raise InputError(
            f"simulate_ssv: the step {h:.3g} s exceeds the shortest delay; give more steps per period"
        )
    total = m * k
    if total > MAX_STEPS:
        raise InputError(f"simulate_ssv: {total} steps exceed {MAX_STEPS}; fewer periods or a coarser step")
    Mm, Cm, Km = st.M, st.C, st.K
    milling = sys.milling
    if milling is None:
        f = b / loop.width
        Cm = Cm - f * loop.DV
        Km = Km - f * loop.DP
        P = loop.U.T  # force U F on the structure, F = f V^T q(t - tau)
        Vt = f * loop.V.T
    else:
        Ub, Jr, _ = loop.cut_basis
        P = Jr
    rho = P.shape[0]
    if rho > 2:
        raise InputError(f"simulate_ssv: the cut has {rho} coordinates; at most 2 are integrated")
    P2 = np.vstack([P, np.zeros((2 - rho, n))]) if rho < 2 else P
    sm = step_map(Mm, Cm, Km, P2, h, 0.5, 0.25)
    Z = np.array(sm.Z).reshape(2, 2)[:rho, :rho]
    PhiPsi = sm.PhiPsi
    PL = sm.PL[:rho]
    t = np.arange(total + 1) * h
    tau = sys.delays(t)  # (steps, J)
    q = np.zeros((total + 1, n))
    v = np.zeros((total + 1, n))
    z = np.zeros(3 * n)
    u0 = P[0] / max(float(np.linalg.norm(P[0])), 1e-300)
    z[:n] = q0 * u0 / max(float(np.max(np.abs(u0))), 1e-300)
    # the initial acceleration: M a = -C v - K q (+ the delayed force of a history at rest: 0)
    z[2 * n :] = np.linalg.solve(Mm, -Km @ z[:n])
    q[0], v[0] = z[:n], z[n : 2 * n]
    read = Vt if milling is None else P

    def delayed(i: int, j: int) -> np.ndarray:
        """read @ q(t_i - tau_j(t_i)) from the stored steps (0 before t = 0)."""
        s = (t[i] - tau[i, j]) / h
        if s < 0.0:
            return np.zeros(read.shape[0])
        i0 = min(int(math.floor(s)), i - 1)
        fr = s - i0
        w0, w1, w2, w3 = hermite_weights(fr, h)
        return read @ (w0 * q[i0] + w1 * v[i0] + w2 * q[i0 + 1] + w3 * v[i0 + 1])

    F2 = np.zeros(2)
    for i in range(total):
        if milling is None:
            F = delayed(i + 1, 0)
        else:
            H = milling.directional(t[i + 1], sys.speed)  # (N, 2, 2)
            Hr = np.einsum("ai,jab,bl->jil", Ub, H, Ub)
            Hs = Hr.sum(axis=0)
            rstar = PL @ z
            rhs = -b * (Hs @ rstar)
            for j in range(Hr.shape[0]):
                if np.any(Hr[j]):
                    rhs += b * (Hr[j] @ delayed(i + 1, j))
            F = np.linalg.solve(np.eye(rho) + b * (Hs @ Z), rhs)
        F2[:rho] = F
        z = PhiPsi @ np.r_[z, F2]
        q[i + 1], v[i + 1] = z[:n], z[n : 2 * n]
    return SsvRun(t, q, T, h)
