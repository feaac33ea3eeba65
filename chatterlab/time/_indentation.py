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

The same loop runs a whole structure (:func:`flank_run`): ``A q'' + B q' +
C q = p(t) + G q(t - T) + r F_flank`` with the penetration u = r . q, the
continuous cut of :func:`chatterlab.time.simulate` (its constant matrices,
the flank on the coupling the model's ``[process_damping]`` names); the known
forces of a step (p and the delayed term) enter through the step map's
columns of a whole force vector.

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

__all__ = ["IndentationResponse", "simulate_indentation", "Flank", "FlankRun", "flank_run", "ToothFlanks"]

#: fixed-point iterations of the implicit flank force stop at this relative change of u
FIXED_POINT_TOL = 1e-13
#: samples of the surface the wear land must hold at least (the area's quadrature)
MIN_LAND_STEPS = 2.0


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


@dataclass(frozen=True, eq=False)
class Flank:
    """The indentation model of one cut's flank on a structure.

    Attributes
    ----------
    row : ndarray (n,)
        The penetration u = row . q (into the material, m); the flank's force
        acts on q through the same row.
    width : float
        Width of cut b, m.
    speed : float
        Cutting speed V, m/s.
    K_sp, wear_land, clearance : float
        N/m^3, m, rad.
    """

    row: np.ndarray
    width: float
    speed: float
    K_sp: float
    wear_land: float
    clearance: float

    def land_steps(self, h: float) -> float:
        """Samples of the surface along the wear land at the step h: w / (V h)."""
        return self.wear_land / (self.speed * h)

    def check_step(self, h: float, option: str = "h") -> None:
        """One line naming ``option`` when the land holds fewer than
        :data:`MIN_LAND_STEPS` samples at the step h."""
        if self.land_steps(h) < MIN_LAND_STEPS:
            raise InputError(
                f"{option}: the indentation model's wear land must hold several steps (w / (V h) ="
                f" {self.land_steps(h):.3g});"
                f" take {option} <= {self.wear_land / (10 * self.speed):.3g} s"
            )


@dataclass(frozen=True, eq=False)
class FlankRun:
    """What :func:`flank_run` integrated: every step's state, the flank's
    force along the row (N) and its contact length (m), the status and how
    the run ended."""

    t: np.ndarray
    q: np.ndarray  # (n_t, n)
    v: np.ndarray
    a: np.ndarray
    flank: np.ndarray
    contact: np.ndarray
    status: str
    message: str


def _as_row(normal: Any, n: int) -> np.ndarray:
    row = np.atleast_1d(np.asarray(normal, dtype=float))
    if row.shape != (n,) or not np.all(np.isfinite(row)) or not np.any(row):
        raise InputError(
            f"normal: give the cut's normal as a finite nonzero row of {n} values (u = normal . q)"
        )
    return row


def flank_run(
    mats: tuple[Any, Any, Any, Any],
    delay: float | None,
    force: Any,
    flank: Flank,
    *,
    h: float,
    t_end: float,
    q0: Any = None,
    v0: Any = None,
    history: Any = None,
    gamma: float = 0.5,
    beta: float = 0.25,
    divergence_limit: float = 1.0,
    progress: Any = None,
) -> FlankRun:
    """Integrate ``A q'' + B q' + C q = p(t) + G q(t - T) + row F`` with the
    flank's force F = -K_sp b A(t) (module docstring) by Newmark steps
    (:func:`~chatterlab.time._core.step_map`).

    Parameters
    ----------
    mats : (A, B, C, G)
        Constant (n, n) matrices; G None without a delayed term.
    delay : float or None
        T, s (>= h), with G.
    force : callable or None
        p(t) for an array of times, (len(t), n) N; None: no force.
    flank : Flank
        The flank's row, width, speed and indentation model.
    h, t_end : float
        Step and duration, s.
    q0, v0 : array (n,), optional
        The state at t = 0 (zero by default).
    history : None or array (n,)
        q before t = 0 (zero, or a constant): the delayed term's and the
        surface's (u = row . history there).
    """
    A, B, C, G = (None if x is None else np.asarray(x, dtype=float) for x in mats)
    assert A is not None and B is not None and C is not None
    n = A.shape[0]
    row = _as_row(flank.row, n)
    b = check_nonneg(flank.width, "width", "m")
    K_sp = check_nonneg(flank.K_sp, "K_sp", "N/m^3")
    V = check_positive(flank.speed, "speed", "m/s")
    w = check_positive(flank.wear_land, "wear_land", "m")
    h = check_positive(h, "h", "s")
    clearance = flank.clearance
    if not 0.0 < clearance < math.pi / 2:
        raise InputError(f"clearance: must lie in (0, pi/2) rad (got {clearance!r})")
    T = None if G is None else check_positive(delay, "delay", "s")
    if T is not None and T < h * (1 - 1e-12):
        raise InputError(f"h: the step must not exceed the delay T = {T:g} s (got {h:g})")
    steps = int(math.floor(check_positive(t_end, "t_end", "s") / h + 1e-9))
    flank.check_step(h)
    hist = np.zeros(n) if history is None else np.asarray(history, dtype=float)
    if hist.shape != (n,):
        raise InputError(
            "history: the indentation model reads the surface before t = 0 from a constant history"
            " ('zero' or 'constant')"
        )
    u_pre = float(row @ hist)  # the surface before t = 0
    tang = math.tan(clearance)
    # the step map: the flank along the row (column 0), every known force along the identity
    sm = step_map(A, B, C, np.vstack([row, np.eye(n)]), h, gamma, beta)
    Z = sm.Z[0]
    Phi, Psi_row, Psi_all = sm.PhiPsi[:, : 3 * n], sm.PhiPsi[:, 3 * n], sm.PhiPsi[:, 3 * n + 1 :]
    if T is not None:
        whole, remf = delay_on_grid(np.array([T / h]))
        dw, dr = int(whole[0]), float(remf[0])
    # the land's end xi = w, cut w / V ago: a sample of the area, interpolated like the delay
    lwa, lra = delay_on_grid(np.array([w / (V * h)]))
    lw, lr = int(lwa[0]), float(lra[0])
    q = np.zeros((steps + 1, n))
    v = np.zeros((steps + 1, n))
    a = np.zeros((steps + 1, n))
    u = np.zeros(steps + 1)
    ud = np.zeros(steps + 1)
    flank_f = np.zeros(steps + 1)
    contact = np.zeros(steps + 1)
    q[0] = 0.0 if q0 is None else np.asarray(q0, dtype=float)
    v[0] = 0.0 if v0 is None else np.asarray(v0, dtype=float)

    def p_at(k0: int, k1: int) -> np.ndarray:
        if force is None:
            return np.zeros((k1 - k0, n))
        return np.asarray(force(np.arange(k0, k1) * h), dtype=float).reshape(k1 - k0, n)

    f_start = p_at(0, 1)[0] + (G @ hist if G is not None else 0.0)
    a[0] = np.linalg.solve(A, f_start - B @ v[0] - C @ q[0])
    u[0], ud[0] = float(row @ q[0]), float(row @ v[0])
    u_min = min(u_pre, u[0])
    status, message = "ok", f"{steps} steps of h = {h:.6g} s with the indentation model's flank"

    def delayed(k: int, whole_: int, rem_: float) -> np.ndarray:
        """q at t_k - (whole_ + rem_) h from the stored steps (the history before t = 0)."""
        if rem_ == 0.0:
            j = k - whole_
            return q[j] if j >= 0 else hist
        j = k - whole_ - 1
        if j + 1 < 0:
            return hist
        a0_, a1_, a2_, a3_ = hermite_weights(1.0 - rem_, h)
        y0, d0 = (q[j], v[j]) if j >= 0 else (hist, np.zeros(n))
        return a0_ * y0 + a1_ * d0 + a2_ * q[j + 1] + a3_ * v[j + 1]

    def past(k: int, whole_: int, rem_: float) -> float:
        """u at t_k - (whole_ + rem_) h (the surface before t = 0: u_pre)."""
        if rem_ == 0.0:
            j = k - whole_
            return float(u[j]) if j >= 0 else u_pre
        j = k - whole_ - 1
        if j + 1 < 0:
            return u_pre
        a0_, a1_, a2_, a3_ = hermite_weights(1.0 - rem_, h)
        y0, d0 = (u[j], ud[j]) if j >= 0 else (u_pre, 0.0)
        return float(a0_ * y0 + a1_ * d0 + a2_ * u[j + 1] + a3_ * ud[j + 1])

    VH = V * h
    xi_grid = VH * np.arange(steps + 2, dtype=float)
    land_pos = lw + 1  # where the land's end goes among the samples xi_j = j V h

    def area(k: int, u_now: float) -> tuple[float, float]:
        """The displaced area and the contact length with the edge at u_now at step k."""
        reach = w + max(u_now - u_min, 0.0) / tang  # beyond it the clearance face clears every surface
        kmax = min(int(math.ceil(reach / VH)) + 1, k)
        xi = xi_grid[: kmax + 1]
        surf = np.concatenate(((u_now,), u[k - kmax : k][::-1]))
        if kmax == k:  # the reach goes back before t = 0: the surface held there
            xi = np.append(xi, max(reach, xi[-1]) + VH)
            surf = np.append(surf, u_pre)
        if lr != 0.0 and xi[-1] > w:  # the land's end between two samples
            pos = min(land_pos, xi.size - 1)
            xi = np.concatenate((xi[:pos], (w,), xi[pos:]))
            surf = np.concatenate((surf[:pos], (past(k, lw, lr),), surf[pos:]))
        d = flank_interference(u_now, xi, surf, w, clearance)
        d[0] = 0.0  # at the edge the surface is where the edge is
        A_ = indented_area(d, xi)
        if A_ == 0.0:
            return 0.0, 0.0
        touch = (d[:-1] > 0) | (d[1:] > 0)
        return A_, float(np.dot(touch, np.diff(xi)))  # the contact length, to the sample spacing

    chunk = 4096
    pk = p_at(1, min(chunk, steps) + 1) if steps else np.zeros((0, n))
    k0 = 1
    last = 0
    for k in range(1, steps + 1):
        if k - k0 >= pk.shape[0]:
            k0 = k
            pk = p_at(k, min(k + chunk, steps + 1))
            if progress is not None:
                progress((k - 1) / steps)
        known = pk[k - k0] + (G @ delayed(k, dw, dr) if G is not None else 0.0)
        z = np.concatenate([q[k - 1], v[k - 1], a[k - 1]])
        base = Phi @ z + Psi_all @ known
        ustar = float(row @ base[:n])
        u_now = ustar
        Ar = L = 0.0
        F = 0.0
        for _ in range(50):
            Ar, L = area(k, u_now) if K_sp > 0.0 else (0.0, 0.0)
            F = -K_sp * b * Ar
            nxt = ustar + Z * F
            if abs(nxt - u_now) <= FIXED_POINT_TOL * max(abs(nxt), 1e-300):
                break
            u_now = nxt
        else:  # Z dF/du >= 1: a flank this stiff needs a shorter step
            status = "diverged"
            message = (
                f"the flank's force did not converge at t = {k * h:.9g} s (step {k}): take a shorter step"
            )
        zn = base + Psi_row * F
        q[k], v[k], a[k] = zn[:n], zn[n : 2 * n], zn[2 * n :]
        u[k], ud[k] = float(row @ q[k]), float(row @ v[k])
        flank_f[k] = F
        contact[k] = L
        u_min = min(u_min, u[k])
        last = k
        if status != "ok":
            break
        if not (np.all(np.isfinite(zn)) and np.max(np.abs(q[k])) <= divergence_limit):
            status = "diverged"
            message = (
                f"diverged at t = {k * h:.9g} s (step {k}): non-finite state or |q| > divergence_limit ="
                f" {float(divergence_limit):.3g}"
            )
            break
    if progress is not None and status == "ok":
        progress(1.0)
    sl = slice(0, last + 1)
    t = np.arange(last + 1) * h
    return FlankRun(t, q[sl], v[sl], a[sl], flank_f[sl], contact[sl], status, message)


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
    check_positive(delay, "delay", "s")
    # the regenerative cut -b Kf (u - u(t - T)) along the normal: its instantaneous part in the
    # stiffness, its delayed part the delayed term
    cut = b * Kf * np.outer(row, row)
    run = flank_run(
        (M, C, K + cut, cut), delay, None, Flank(row, b, speed, K_sp, wear_land, clearance),
        h=h, t_end=t_end, v0=row * (v0 / float(row @ row)), gamma=gamma, beta=beta,
        divergence_limit=divergence_limit,
    )  # fmt: skip
    return IndentationResponse(
        run.t, run.q @ row, run.v @ row, run.flank, run.contact, "ok" if run.status == "ok" else "diverged"
    )


@dataclass(frozen=True, eq=False)
class ToothFlanks:
    """The indentation model on the teeth of a milling cutter
    (:func:`chatterlab.time.simulate_milling`; docs/process-damping.md,
    "Milling in the time domain"): each tooth j in the cut pushes
    ``-K_sp a_p A_j n_j`` on the tool, A_j the area under its flank (Eq. 6a)
    with the penetration u_j = n_j . r (into the material: the sign of the
    chip) and the surface behind the edge the tool's own path,
    n_j . r(t - xi / V), sampled by the milling run (:mod:`._contact`).

    Attributes
    ----------
    depth : float
        Axial depth of cut a_p, m.
    speed : float
        Cutting speed V at the cutter's diameter, m/s.
    K_sp, wear_land, clearance : float
        N/m^3, m, rad.
    """

    depth: float
    speed: float
    K_sp: float
    wear_land: float
    clearance: float

    def land_steps(self, h: float) -> float:
        """Samples of the surface along the wear land at the step h: w / (V h)."""
        return self.wear_land / (self.speed * h)

    def steps_per_period(self, period: float, samples: float) -> int:
        """The steps per ``period`` (s) that put ``samples`` steps across the wear land."""
        return int(math.ceil(samples * self.speed * period / self.wear_land - 1e-9))

    def check_steps(self, period: float, m: int, option: str) -> None:
        """One line naming ``option`` when ``m`` steps per ``period`` leave
        fewer than :data:`MIN_LAND_STEPS` samples across the wear land."""
        if self.land_steps(period / m) < MIN_LAND_STEPS:
            raise InputError(
                f"{option}: the indentation model's wear land must hold several steps (w / (V h) ="
                f" {self.land_steps(period / m):.3g} at {m}); give at least"
                f" {self.steps_per_period(period, MIN_LAND_STEPS)}"
            )

    def area(self, u_now: float, xi: np.ndarray, surface: np.ndarray) -> float:
        """The area under the flank, m^2, with the edge at ``u_now`` and the
        surface ``surface`` at the distances ``xi`` behind it (``xi[0] = 0``,
        the edge itself)."""
        d = flank_interference(u_now, xi, surface, self.wear_land, self.clearance)
        d[0] = 0.0  # at the edge the surface is where the edge is
        return indented_area(d, xi)

    def describe(self) -> str:
        """The model's line in a result: its fields and the linear equivalent."""
        return (
            f"indentation, K_sp = {self.K_sp:.4g} N/m^3, wear land {self.wear_land * 1e6:.4g} um, clearance"
            f" {math.degrees(self.clearance):.4g} deg at V = {self.speed:.4g} m/s (small-vibration equivalent"
            f" C_pd = K_sp w^2/4 = {self.K_sp * self.wear_land**2 / 4:.6g} N/m)"
        )
