"""Turning with the indentation model of process damping in the time domain
(docs/process-damping.md, Eq. 5): the flank of the tool, a wear land of
width w followed by the clearance face at the angle gamma, pushes on the
material it indents, with a force proportional to the displaced area,

    F_flank = -K_sp b A(t),   A = int_0^inf max(delta(xi), 0) dxi,
    delta(xi) = u(t) - max(xi - w, 0) tan(gamma) - u(t - xi / V),

u the tool's penetration along the cut's normal (into the material), xi the
distance behind the edge, u(t - xi / V) the surface the edge left there
(:func:`chatterlab.process._damping.flank_interference`,
:func:`~chatterlab.process._damping.indented_area`), added to the
regenerative cut -b K_f [u(t) - u(t - T)] (Wu 1989; Chiou & Liang 1998;
Budak & Tunc 2010).  For a small vibration its first harmonic is the linear
model's -b C_pd / V u' with C_pd = K_sp w^2 / 4 (Eq. 6); at large amplitude
the clearance face touches too and the damping grows with the amplitude,
which bounds a vibration the linear model would let grow (finite-amplitude
stability).

The integration is the Newmark scheme of the time package's core, step by
step (:func:`chatterlab.time._core.step_map`: the step as a linear map of the
state and of the force at its end), the regenerative term's delayed value and
the surface between stored steps by its cubic Hermite interpolation
(:func:`~chatterlab.time._core.hermite_weights`,
:func:`~chatterlab.time._core.delay_on_grid`).  The flank force is implicit
(it depends on u at the end of the step): u = u* + Z F is solved by a
fixed-point iteration, a contraction since Z dF/du ~ beta h^2 K_sp b L / m
(L the contact length) is tiny.

References
----------
D. W. Wu, A new approach of formulating the transfer function for dynamic
cutting processes, J. Eng. Ind. 111 (1989) 37-47.
R. Y. Chiou, S. Y. Liang, Chatter stability of a slender cutting tool in
turning with tool wear effect, Int. J. Mach. Tools Manuf. 38 (1998) 315-327.
E. Budak, L. T. Tunc, Identification and modeling of process damping in
turning and milling using a new approach, CIRP Annals 59 (2010) 403-408.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError, check_nonneg, check_positive
from ..process._damping import flank_interference, indented_area
from ._core import delay_on_grid, hermite_weights, step_map

__all__ = ["IndentationResponse", "simulate_indentation"]

#: fixed-point iterations of the implicit flank force stop at this relative change of u
FIXED_POINT_TOL = 1e-13


@dataclass(frozen=True, eq=False)
class IndentationResponse:
    """A turning simulation with the indentation model.

    Attributes
    ----------
    t : ndarray (n_t,)
        Times, s.
    u, v : ndarray (n_t,)
        The penetration along the cut's normal, m, and its rate, m/s.
    flank : ndarray (n_t,)
        The flank's force along the normal, N (<= 0: it pushes the tool out).
    contact : ndarray (n_t,)
        The length of flank in contact with the material, m.
    status : str
        ``"ok"`` or ``"diverged"`` (the displacement left ``divergence_limit``, or the
        implicit flank force did not converge in a step: take a shorter one).
    """

    t: np.ndarray
    u: np.ndarray
    v: np.ndarray
    flank: np.ndarray
    contact: np.ndarray
    status: str


def _as_row(normal: Any, n: int) -> np.ndarray:
    row = np.atleast_1d(np.asarray(normal, dtype=float))
    if row.shape != (n,) or not np.all(np.isfinite(row)) or not np.any(row):
        raise InputError(
            f"normal: give the cut's normal as a finite nonzero row of {n} values (u = normal . q)"
        )
    return row


def simulate_indentation(
    structure: Any,
    normal: Any,
    *,
    width: float,
    Kf: float,
    delay: float,
    speed: float,
    K_sp: float,
    wear_land: float,
    clearance: float,
    h: float,
    t_end: float,
    v0: float = 0.0,
    gamma: float = 0.5,
    beta: float = 0.25,
    divergence_limit: float = 1.0,
) -> IndentationResponse:
    """Integrate ``M q'' + C q' + K q = n^T F`` with u = n . q and
    F = -b K_f [u(t) - u(t - T)] - K_sp b A(t) (module docstring) from rest
    at the surface (u = 0 before t = 0) with the tool's normal velocity ``v0``.

    Parameters
    ----------
    structure : Structure
        M, C, K of the tool (``chatterlab.structure.Structure``).
    normal : array (n,)
        The cut's normal on the coordinates: u = normal . q.
    width : float
        Width of cut b, m.
    Kf : float
        Cutting stiffness per unit width, N/m^2.
    delay : float
        Revolution period T, s (>= h).
    speed : float
        Cutting speed V, m/s (the surface behind the edge at xi was cut xi / V ago).
    K_sp, wear_land, clearance : float
        Indentation coefficient (N/m^3), wear land w (m), clearance angle (rad).
    h, t_end : float
        Time step and duration, s; the land should hold many steps (w / (V h) >= 10).
    v0 : float
        Initial normal velocity, m/s (the initial disturbance).
    """
    M, C, K = (np.asarray(x, dtype=float) for x in (structure.M, structure.C, structure.K))
    n = M.shape[0]
    row = _as_row(normal, n)
    b = check_nonneg(width, "width", "m")
    Kf = check_nonneg(Kf, "Kf", "N/m^2")
    K_sp = check_nonneg(K_sp, "K_sp", "N/m^3")
    V = check_positive(speed, "speed", "m/s")
    w = check_positive(wear_land, "wear_land", "m")
    h = check_positive(h, "h", "s")
    T = check_positive(delay, "delay", "s")
    if not 0.0 < clearance < math.pi / 2:
        raise InputError(f"clearance: must lie in (0, pi/2) rad (got {clearance!r})")
    if T < h:
        raise InputError(f"h: the step must not exceed the delay T = {T:g} s (got {h:g})")
    steps = int(math.floor(check_positive(t_end, "t_end", "s") / h + 1e-9))
    tang = math.tan(clearance)
    # the regenerative term's instantaneous part in the stiffness, its delayed part a known force
    P = np.vstack([row, np.zeros(n)])
    Keff = K + b * Kf * np.outer(row, row)
    sm = step_map(M, C, Keff, P, h, gamma, beta)
    Z = sm.Z[0]
    whole, remf = delay_on_grid(np.array([T / h]))
    dw, dr = int(whole[0]), float(remf[0])
    # the land's end xi = w, cut w / V ago: a sample of the area, interpolated like the delay
    if w / (V * h) < 2.0:
        raise InputError(
            f"h: the wear land must hold several steps (w / (V h) = {w / (V * h):.3g}); take h <= {w / (10 * V):.3g} s"
        )
    lwa, lra = delay_on_grid(np.array([w / (V * h)]))
    lw, lr = int(lwa[0]), float(lra[0])
    u = np.zeros(steps + 1)
    v = np.zeros(steps + 1)
    flank = np.zeros(steps + 1)
    contact = np.zeros(steps + 1)
    # the initial state: q along the normal's velocity, at rest on the surface
    q = np.zeros(n)
    qd = row * (v0 / float(row @ row))
    F0 = 0.0
    acc = np.linalg.solve(M, -C @ qd - Keff @ q + row * F0)
    z = np.concatenate([q, qd, acc])
    v[0] = float(row @ qd)
    u_min = 0.0
    status = "ok"

    def past(k: int, whole_: int, rem_: float) -> float:
        """u at t_k - (whole_ + rem_) h from the stored steps (zero before t = 0)."""
        if rem_ == 0.0:
            j = k - whole_
            return u[j] if j >= 0 else 0.0
        j = k - whole_ - 1
        if j + 1 < 0:
            return 0.0
        s = 1.0 - rem_
        a0, a1, a2, a3 = hermite_weights(s, h)
        y0, d0 = (u[j], v[j]) if j >= 0 else (0.0, 0.0)
        return float(a0 * y0 + a1 * d0 + a2 * u[j + 1] + a3 * v[j + 1])

    def area(k: int, u_now: float) -> tuple[float, float]:
        """The displaced area and the contact length with the edge at u_now at step k."""
        reach = w + max(u_now - u_min, 0.0) / tang  # beyond it the clearance face clears every surface
        kmax = min(int(math.ceil(reach / (V * h))) + 1, k)
        idx = np.arange(1, kmax + 1)
        xi = np.r_[0.0, idx * V * h]
        surf = np.r_[u_now, u[k - idx]]
        if kmax == k:  # the reach goes back before t = 0: the flat surface u = 0 there
            xi = np.r_[xi, max(reach, xi[-1]) + V * h]
            surf = np.r_[surf, 0.0]
        if lr != 0.0 and xi[-1] > w:  # the land's end between two samples
            pos = int(np.searchsorted(xi, w))
            xi = np.insert(xi, pos, w)
            surf = np.insert(surf, pos, past(k, lw, lr))
        d = flank_interference(u_now, xi, surf, w, clearance)
        d[0] = 0.0  # at the edge the surface is where the edge is
        A = indented_area(d, xi)
        L = float(np.sum(np.diff(xi)[(d[:-1] > 0) | (d[1:] > 0)]))  # to the sample spacing
        return A, L

    for k in range(1, steps + 1):
        base = sm.PhiPsi[:, : 3 * n] @ z
        ustar = float(sm.PL[0] @ z)
        Fd = b * Kf * past(k, dw, dr)  # the delayed chip: -b Kf (u - u(t - T)), u's part in Keff
        u_now = ustar + Z * Fd
        A = L = 0.0
        F = Fd
        for _ in range(50):
            A, L = area(k, u_now) if K_sp > 0.0 else (0.0, 0.0)
            F = Fd - K_sp * b * A
            nxt = ustar + Z * F
            if abs(nxt - u_now) <= FIXED_POINT_TOL * max(abs(nxt), 1e-300):
                break
            u_now = nxt
        else:  # Z dF/du >= 1: a flank this stiff needs a shorter step
            status = "diverged"
        z = base + sm.PhiPsi[:, 3 * n :] @ np.array([F, 0.0])
        u[k] = float(row @ z[:n])
        v[k] = float(row @ z[n : 2 * n])
        flank[k] = -K_sp * b * A
        contact[k] = L
        u_min = min(u_min, u[k])
        if status != "ok" or not math.isfinite(u[k]) or abs(u[k]) > divergence_limit:
            status = "diverged"
            u, v, flank, contact = u[: k + 1], v[: k + 1], flank[: k + 1], contact[: k + 1]
            break
    t = np.arange(u.size) * h
    return IndentationResponse(t, u, v, flank, contact, status)
