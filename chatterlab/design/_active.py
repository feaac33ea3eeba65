"""Active damping with the paper's feedback: the co-design of an actuator's
gains (and placement) that maximises the minimum chatter-free width.

An actuator (``[[actuator]]``, :mod:`chatterlab.model._actuator`) measures
y = e_s . w_S and pushes with f = -G(s) y at its own point,

    G(s) = (g_P + s g_V + g_O e^{-s T_a}) / (1 + s / w_b),                    (1)

the proportional, ideal-derivative and delayed feedback of the seed paper
(Eq. 2.23, Table 1) with the controller's own delay T_a and an optional
first-order bandwidth.  It is a coupling term of the one closed loop
(:class:`chatterlab.process.Actuators`): with the cut the machine has two
delays, T and T_a.  The co-design is

    maximise   b_min(g)  over the free gains g in their bounds                (2)
    subject to the machine with the actuators stable without cutting
               (its rightmost exact-delay root: Re lambda_1 < -sigma),
               the control loop's gain margin >= GM and phase margin >= PM,
               the actuator force at the design width <= its limit,
               b_min(g) >= b_d (with a force limit),

b_min the minimum of b_lim over the speed range (or over all speeds), b_d the
design width (default 1.1 times the bare structure's minimum).  As for
absorbers (:mod:`chatterlab.design._epigraph`) b_min is the lowest of a few
smooth candidates whose *exact* gradients in the gains are the sensitivities
of :mod:`chatterlab.design._critical` (the gains are entries of the loop's
actuator blocks: d b / d g_P = S_Pa, and so on -- no finite difference).

The constraints:

* **stability of the controller** -- the rightmost root lambda_1 of
  Delta_c(s) = s^2 M + s C + K + F_a diag(G(s)) S_a, computed with the delay
  as it is (:func:`chatterlab.design._controlled.machine_roots`); its
  gradient is that of a simple root of a nonlinear eigenproblem [3],
  d lambda / d g = -w^H (dDelta_c/dg) v / (w^H Delta_c'(lambda) v), with v,
  w its right and left null vectors;
* **margins of the control loop** -- broken at actuator k (the others
  closed), L_k(jw) = G_k(jw) S_k Z_k(jw)^-1 F_k with Z_k the structure and
  the other actuators: the gain margin 1/|L| where L crosses the negative
  real axis, the phase margin 180 deg - |arg L| where |L| = 1 (each crossing
  located by Brent's method between grid samples; the lowest of each);
  Nyquist's criterion [4] on the open loop of a stable structure;
* **the force limit at the design width** -- the actuator's steady force
  amplitude when the cutting force fluctuates harmonically with the
  amplitude of its static value F_0(b_d) (the full modulation of an
  interrupted cut), at the worst frequency and the worst phase z = e^{-jwT}
  the speed range gives:

      F_k = max_{w, T} |G_k(jw) S_k Delta(jw, T)^-1 J^T F_0(b_d)|,
      Delta = Z_c(w) + b_d J^T (A + e^{-jwT} O) J,                         (3)

  (Delta^-1 by Woodbury in the rank of O, so every T costs an r x r solve);
  its gradient by the envelope theorem at the maximiser.  A step of the
  static force (the cut's entry) moves the actuator less than this
  worst-case harmonic (the time-domain check shows it).

Margins and force constraints are written log(GM/GM_min), log(F_max/F),
(PM - PM_min)/PM_min (order 1, >= 0 when met).  Each start is solved by
SLSQP on the epigraph form; the best design is drawn again on the requested
speeds and checked by the argument principle on the full two-delay loop.
The trade-off of width against actuator effort: for widths b from the
optimum's limit down to the bare structure's, the least force (3) at b of
any gains stable at b (minimum limit above b) and meeting the other
constraints -- the force an actuator needs to cut at b.  (For a damper the
force does not grow with the gain: it saturates at the cutting force it
fights, and falls as the damping lowers the regenerative amplification; what
grows without bound is the force near the limit, so the effort is a
function of the width cut.)

Oracle (tests/test_active_design.py): velocity feedback without delay on a
1-DOF tool is extra damping, b_min = 2 k zeta' (1 + zeta') / K_f with
zeta' = zeta + g_V / (2 sqrt(k m)).

References
----------
.. [1] E. Wittbrodt, K. J. Kalinski, the seed paper, Eq. 2.22-2.25, Table 1.
.. [2] J. Munoa, I. Mancisidor, N. Loix, L. G. Uriarte, R. Barcena,
   M. Zatarain, "Chatter suppression in ram type travelling column milling
   machines using a biaxial inertial actuator", CIRP Annals 62(1) (2013)
   407-410 (active damping of a machine's structural chatter mode with
   velocity feedback; actuator force as the limit).
.. [3] P. Lancaster, *Lambda-matrices and Vibrating Systems*, Pergamon 1966
   (derivative of a simple eigenvalue of a nonlinear eigenproblem).
.. [4] H. Nyquist, "Regeneration theory", Bell Syst. Tech. J. 11 (1932)
   126-147; K. J. Astrom, R. M. Murray, *Feedback Systems*, Princeton 2008,
   sec. 9.3 (gain and phase margins).
.. [5] N. Olgac, B. T. Holm-Hansen, "A novel active vibration absorption
   technique: delayed resonator", J. Sound Vib. 176(1) (1994) 93-104
   (delayed position feedback as damping).
"""

from __future__ import annotations

import functools
import json
import math
import time
import warnings
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np

from ..errors import ChatterlabError, InputError, UnitWarning, check_width
from ..io import Result
from ..model import Model
from ..process._loop import closed_loop_unwarned
from ..structure import assemble, dynamic_receptance
from ._absorber import _rebuild, host_mode
from ._controlled import (
    ControllerUnstable,
    bare_band,
    check_controller,
    design_lobes,
    machine_roots,
    plant_lobes,
)
from ._epigraph import (
    CANDIDATES,
    best_start,
    candidate_points,
    check_bound,
    check_starts,
    solve_epigraph,
    start_points,
    starts_line,
)
from ._limits import limits_of
from ._matrices import LoopMatrices, matrices_of
from ._receptance import control_at

__all__ = [
    "ActiveDesign",
    "design_active",
    "with_actuator",
    "without_actuators",
    "loop_margins",
    "force_required",
    "Margins",
    "GAINS",
    "confirm_active",
]

#: the gains of (1) a co-design may vary: name -> (LoopMatrices block, model field, unit)
GAINS = {
    "proportional": ("Pa", "proportional_gain", "N/m"),
    "velocity": ("Va", "velocity_gain", "N s/m"),
    "delayed": ("Oa", "delayed_gain", "N/m"),
}
OBJECTIVES = ("minimum", "absolute")
#: the value of a margin row of a loop without that crossing (the margin is infinite: met)
_INACTIVE = 10.0


# ------------------------------------------------------------------ actuators in a model
def _spec(text: str, what: str) -> tuple[str, str]:
    """``"POINT.DIR"`` -> (POINT, DIR) with DIR x or y."""
    point, _, d = str(text).rpartition(".")
    if not point or d not in ("x", "y"):
        raise InputError(f"{what} '{text}' is not POINT.DIR: write e.g. 'tool.y' (DIR x or y)")
    return point, d


def with_actuator(
    model: Model,
    id: str,
    sensor: str,
    *,
    at: str | None = None,
    reaction: str | None = None,
    proportional_gain: float = 0.0,
    velocity_gain: float = 0.0,
    delayed_gain: float = 0.0,
    delay: float = 0.0,
    bandwidth_hz: float | None = None,
    force_limit: float | None = None,
) -> Model:
    """A copy of ``model`` with one more ``[[actuator]]``: the sensor at
    ``sensor`` (``"POINT.DIR"``), the force at ``at`` (``"POINT.DIR"``,
    default the sensor's: collocated), the gains, delay, bandwidth and force
    limit of docs/model-format.md; validated like a model file."""
    sp, sd = _spec(sensor, "sensor")
    fp, fd = _spec(at, "at") if at is not None else (sp, sd)
    t: dict[str, Any] = {"id": id, "sensor": sp, "sensor_direction": sd, "at": fp, "direction": fd}
    for key, v in (("proportional_gain", proportional_gain), ("velocity_gain", velocity_gain),
                   ("delayed_gain", delayed_gain), ("delay", delay)):  # fmt: skip
        if v:
            t[key] = float(v)
    if reaction is not None:
        t["reaction"] = reaction
    if bandwidth_hz is not None:
        t["bandwidth_hz"] = float(bandwidth_hz)
    if force_limit is not None:
        t["force_limit"] = float(force_limit)
    raw = json.loads(model.raw)
    raw.setdefault("actuator", []).append(t)
    return _rebuild(model, raw)


def without_actuators(model: Model) -> Model:
    """The machine without its controller: ``model`` without its ``[[actuator]]`` items."""
    raw = json.loads(model.raw)
    raw.pop("actuator", None)
    return _rebuild_drop(model, raw, {a.id for a in model.actuators})


def _rebuild_drop(model: Model, raw: dict[str, Any], ids: set[str]) -> Model:
    """``raw`` rebuilt with the overrides of ``model`` except those of the actuators ``ids``."""

    def kept(path: str) -> bool:
        parts = str(path).split(".")
        return not (len(parts) == 3 and parts[0] == "actuator" and parts[1] in ids)

    overrides = {k: v for k, v in dict(model.overrides).items() if kept(k)}
    return model.rebuild(
        raw, source=model.source, text=model.text, variant=model.variant, overrides=overrides
    )


def _with_gains(model: Model, values: dict[str, dict[str, float]]) -> Model:
    """``model`` with actuators ``id -> {field: value}`` (gains written, zeros dropped)."""
    raw = json.loads(model.raw)
    for t in raw.get("actuator", []):
        if isinstance(t, dict) and t.get("id") in values:
            for key, v in values[t["id"]].items():
                t.pop(key, None)
                if v != 0.0:
                    t[key] = float(v)
    return _rebuild_drop(model, raw, set(values))


def _placed(model: Model, aid: str, sensor: str, at: str) -> Model:
    """``model`` with actuator ``aid``'s sensor and force moved to ``sensor``, ``at`` (POINT.DIR)."""
    sp, sd = _spec(sensor, "sensor")
    fp, fd = _spec(at, "at")
    raw = json.loads(model.raw)
    for t in raw.get("actuator", []):
        if isinstance(t, dict) and t.get("id") == aid:
            for key in ("sensor", "sensor_direction", "sensor_angle_deg", "at", "direction", "angle_deg"):
                t.pop(key, None)
            t.update({"sensor": sp, "sensor_direction": sd, "at": fp, "direction": fd})
    return _rebuild_drop(model, raw, {aid})


# ------------------------------------------------------------------ the control loop's margins
@dataclass(frozen=True)
class Margins:
    """The margins of the control loop broken at one actuator: ``gain``
    (1/|L| at the phase crossover, inf: none), ``gain_hz`` its frequency,
    ``phase_deg`` (180 - |arg L| at the gain crossover, inf: none),
    ``phase_hz``."""

    gain: float
    gain_hz: float
    phase_deg: float
    phase_hz: float


def plant_transfer(L: LoopMatrices, k: int, omega: np.ndarray) -> np.ndarray:
    """P_k(jw) = S_k Z_k(jw)^-1 F_k: the structure with the other actuators
    closed, from actuator k's force to its sensor (m/N), at ``omega`` (rad/s)."""
    acts = L.actuators
    assert acts is not None
    s = 1j * np.asarray(omega, dtype=float)
    g = acts.gains(s)
    others = acts.D(s) + np.einsum("i,f,j->fij", L.Fa[:, k], g[:, k], L.Sa[k])  # D_a without actuator k
    P = dynamic_receptance(
        L.M, L.C, L.K, np.asarray(omega, float), L.Sa[k : k + 1], L.Fa[:, k : k + 1], minus=others
    )
    return np.asarray(P[:, 0, 0])


def _loop_point(L: LoopMatrices, k: int, w: float) -> tuple[complex, complex, dict[str, complex]]:
    """L_k(jw), dL_k/dw and the partial derivatives of L_k in actuator k's
    gains (``Pa``, ``Va``, ``Oa``), at one frequency."""
    ctl = control_at(L, w)
    assert ctl is not None
    Fk, Sk = L.Fa[:, k], L.Sa[k]
    Do = ctl.Da + np.outer(Fk, Sk) * ctl.G[k]  # the other actuators' term
    dDo = ctl.dDa + np.outer(Fk, Sk) * ctl.dG[k]
    Z = L.K - w * w * L.M + 1j * w * L.C - Do
    x = np.linalg.solve(Z, Fk.astype(complex))
    y = np.linalg.solve(Z.T, Sk.astype(complex))
    P = complex(Sk @ x)
    dP = complex(-(y @ ((-2 * w * L.M + 1j * L.C - dDo) @ x)))
    Lw = ctl.G[k] * P
    dLw = ctl.dG[k] * P + ctl.G[k] * dP
    return complex(Lw), complex(dLw), {"Pa": ctl.dP[k] * P, "Va": ctl.dV[k] * P, "Oa": ctl.dO[k] * P}


def margin_grid(L: LoopMatrices) -> np.ndarray:
    """The frequencies (rad/s) the margins are sampled on: every structural
    resonance resolved (:func:`chatterlab.frequency.resonance_grid`) up to 3
    times the highest, at most pi / (8 T_a) apart (the delay turns the phase
    by 22.5 degrees between samples)."""
    from ..frequency import resonance_grid
    from ..structure import complex_modes

    lam = complex_modes(L.M, L.C, L.K).lam
    top = 3.0 * float(np.max(np.abs(lam.imag))) if lam.size else 1.0
    n = 2000
    tmax = float(np.max(L.Ta)) if L.Ta.size else 0.0
    if tmax > 0:
        n = int(min(max(n, top * tmax * 8 / math.pi), 200_000))
    return np.unique(np.r_[0.0, resonance_grid(lam, 0.0, top, n)])


def loop_margins(L: LoopMatrices, k: int, omega: np.ndarray, P: np.ndarray | None = None) -> Margins:
    """The gain and phase margins of the loop broken at actuator ``k``
    (module docstring): L_k = G_k P_k sampled on ``omega`` (``P`` =
    :func:`plant_transfer` on it when known), each crossing that can set a
    margin located by Brent's method -- the phase crossovers whose samples
    reach half the largest |L| of any, every gain crossover."""
    from scipy.optimize import brentq

    acts = L.actuators
    assert acts is not None
    if P is None:
        P = plant_transfer(L, k, omega)
    Lw = acts.gains(1j * omega)[:, k] * P

    def one(w: float) -> complex:
        return _loop_point(L, k, w)[0]

    gm, gm_w = math.inf, math.nan
    re, im = Lw.real, Lw.imag
    if omega[0] == 0.0 and re[0] < 0:  # negative static loop gain: a crossing at w = 0
        gm, gm_w = -1.0 / re[0], 0.0
    cross = np.nonzero((np.sign(im[:-1]) * np.sign(im[1:]) < 0) & ((re[:-1] < 0) | (re[1:] < 0)))[0]
    if cross.size:
        reach = np.maximum(np.abs(Lw[cross]), np.abs(Lw[cross + 1]))
        for i in cross[reach >= 0.5 * reach.max()]:
            w = brentq(lambda x: one(x).imag, omega[i], omega[i + 1], xtol=1e-13 * omega[i + 1])
            v = one(w)
            if v.real < 0 and 1.0 / abs(v) < gm:
                gm, gm_w = 1.0 / abs(v), w
    pm, pm_w = math.inf, math.nan
    mag = np.log(np.abs(Lw) + 1e-300)
    for i in np.nonzero(np.sign(mag[:-1]) * np.sign(mag[1:]) < 0)[0]:
        w = brentq(lambda x: math.log(abs(one(x))), omega[i], omega[i + 1], xtol=1e-13 * omega[i + 1])
        p = 180.0 - abs(math.degrees(np.angle(one(w))))
        if p < pm:
            pm, pm_w = p, w
    return Margins(gm, gm_w / (2 * np.pi), pm, pm_w / (2 * np.pi))


def margin_gradients(
    L: LoopMatrices, k: int, mg: Margins, blocks: list[tuple[int, str]]
) -> tuple[np.ndarray, np.ndarray]:
    """d log(GM) and d PM (deg) in the variables ``blocks`` at the located
    crossings, the crossing frequency following the gains (implicit function
    theorem on Im L = 0, resp. |L| = 1):

        dw/dg = -Im L_g / Im L_w,             d log GM = -Re((L_g + L_w dw/dg) / L),
        dw/dg = -Re(L* L_g) / Re(L* L_w),     d PM = -sign(arg L) (180/pi) Im((L_g + L_w dw/dg) / L);

    the gains of the other actuators (which move P_k) count 0."""
    gg, gp = np.zeros(len(blocks)), np.zeros(len(blocks))
    if math.isfinite(mg.gain) and mg.gain_hz > 0:
        Lw, dLw, part = _loop_point(L, k, 2 * np.pi * mg.gain_hz)
        for i, (j, blk) in enumerate(blocks):
            if j == k:
                Lg = part[blk]
                dw = -Lg.imag / dLw.imag if dLw.imag != 0 else 0.0
                gg[i] = -((Lg + dLw * dw) / Lw).real
    if math.isfinite(mg.phase_deg):
        Lw, dLw, part = _loop_point(L, k, 2 * np.pi * mg.phase_hz)
        sgn = 1.0 if np.angle(Lw) >= 0 else -1.0
        for i, (j, blk) in enumerate(blocks):
            if j == k:
                Lg = part[blk]
                den = (np.conj(Lw) * dLw).real
                dw = -(np.conj(Lw) * Lg).real / den if den != 0 else 0.0
                gp[i] = -sgn * math.degrees(((Lg + dLw * dw) / Lw).imag)
    return gg, gp


# ------------------------------------------------------------------ the force at the design width
def _phases(w: np.ndarray, T: tuple[float, float], n: int = 48) -> np.ndarray:
    """z = e^{-jwT} for T over the range at each w (the full circle when it
    turns by 2 pi or more), shape (len(w), n)."""
    lo, hi = T
    span = np.minimum(w * (hi - lo), 2 * np.pi)
    t = np.linspace(0.0, 1.0, n, endpoint=False)
    return np.exp(-1j * (w * lo)[:, None] - 1j * span[:, None] * t[None, :])


def force_required(
    L: LoopMatrices, f1: np.ndarray, width: float, omega: np.ndarray, delays: tuple[float, float]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each actuator's force amplitude (3) at the width b (N), with the
    maximiser's (w, z): ``(F (m,), w (m,), z (m,))``; ``f1`` is the cut's
    static force per metre of width as generalised forces (n,)."""
    acts = L.actuators
    assert acts is not None
    n, m = L.M.shape[0], acts.m
    from numpy.linalg import svd

    Uo, so, Vot = svd(L.O)
    r = int(np.sum(so > 1e-12 * max(so[0], 1e-300)))
    Ub = L.J.T @ (Uo[:, :r] * so[:r])  # J^T O J = Ub Vb^T
    Vb = L.J.T @ Vot[:r].T
    f0 = width * f1
    s = 1j * omega
    Z = (L.K[None] - omega[:, None, None] ** 2 * L.M[None] + s[:, None, None] * L.C[None]) - acts.D(s)
    A = L.P[None] + s[:, None, None] * L.V[None]
    D0 = Z + width * np.einsum("pi,fpq,qj->fij", L.J, A, L.J)
    X = np.linalg.solve(D0, np.broadcast_to(np.c_[f0, Ub], (omega.size, n, 1 + r)))
    G = acts.gains(s)  # (f, m)
    SX = np.einsum("kn,fnc->fkc", L.Sa, X)  # (f, m, 1 + r)
    a = -G * SX[:, :, 0]
    c = -G[:, :, None] * SX[:, :, 1:]  # (f, m, r)
    Q = np.einsum("nr,fnc->frc", Vb, X[:, :, 1:])  # (f, r, r)
    d = np.einsum("nr,fn->fr", Vb, X[:, :, 0])  # (f, r)
    zz = _phases(omega, delays)  # (f, t)
    eye = np.eye(r)
    M = eye[None, None] + width * zz[:, :, None, None] * Q[:, None]  # (f, t, r, r)
    y = np.linalg.solve(M, np.broadcast_to(d[:, None, :, None], M.shape[:3] + (1,)))[..., 0]  # (f, t, r)
    Tk = a[:, None, :] - width * zz[:, :, None] * np.einsum("fkr,ftr->ftk", c, y)  # (f, t, m)
    mag = np.abs(Tk)
    F, wz, zk = np.zeros(m), np.zeros(m), np.zeros(m, complex)
    for k in range(m):
        fi, ti = np.unravel_index(int(np.nanargmax(mag[:, :, k])), mag.shape[:2])
        F[k], wz[k], zk[k] = mag[fi, ti, k], omega[fi], zz[fi, ti]
    return F, wz, zk


def _force_gradient(
    L: LoopMatrices, f1: np.ndarray, width: float, k: int, w: float, z: complex, blocks: list[tuple[int, str]]
) -> np.ndarray:
    """d|T_k| / d gain at the maximiser (w, z) of (3) (envelope theorem), for
    the variables ``blocks`` ((actuator, LoopMatrices block) each)."""
    acts = L.actuators
    assert acts is not None
    s = 1j * w
    Z = L.K - w * w * L.M + s * L.C - acts.D(s)
    Dl = L.J.T @ (L.P + s * L.V + z * L.O) @ L.J
    D = Z + width * Dl
    x = np.linalg.solve(D, width * f1)
    yT = np.linalg.solve(D.T, L.Sa[k])  # Sa_k D^-1 as a row
    G = acts.gains(s)
    T = -G[k] * (L.Sa[k] @ x)
    lag = 1.0 + s * L.La
    part = {"Pa": 1.0 / lag, "Va": s / lag, "Oa": np.exp(-s * L.Ta) / lag}
    out = np.zeros(len(blocks))
    for i, (j, blk) in enumerate(blocks):
        dG = part[blk][j]
        # dT = -dG_k S_k x [j = k] + G_k (S_k D^-1 F_j) dG_j (S_j x)
        dT = G[k] * (yT @ L.Fa[:, j]) * dG * (L.Sa[j] @ x)
        if j == k:
            dT += -dG * (L.Sa[k] @ x)
        out[i] = float(np.real(np.conj(T) * dT) / max(abs(T), 1e-300))
    return out


# ------------------------------------------------------------------ the problem
@dataclass
class _Problem:
    """The co-design (2) of one placement, on the loop matrices ``L0``."""

    L0: LoopMatrices
    ids: tuple[str, ...]
    blocks: list[tuple[int, str]]  #: the variables: (actuator index, block) each
    lo: np.ndarray
    hi: np.ndarray
    speeds: np.ndarray
    process: Any
    objective: str
    lobe_kw: dict[str, Any]
    top: float
    f1: np.ndarray
    design_width: float
    force_limits: np.ndarray
    gain_margin: float
    phase_margin: float
    decay: float
    delays: tuple[float, float]
    grid: np.ndarray = field(default_factory=lambda: np.zeros(0))  #: the margins' frequencies, rad/s
    grid_poles: np.ndarray = field(default_factory=lambda: np.zeros(0, complex))  #: the bare structure's
    scale: float = 1.0
    root_scale: float = 1.0  #: 1e-2 |lambda_1| of the file's controller: the stability row's unit, 1/s
    evaluations: int = 0
    cache: dict[bytes, dict[str, Any]] = field(default_factory=dict)
    plants: dict[Any, np.ndarray] = field(default_factory=dict)

    def gains(self, u: np.ndarray) -> dict[str, np.ndarray]:
        x = self.lo + np.clip(u, 0.0, 1.0) * (self.hi - self.lo)
        out = {b: np.array(getattr(self.L0, b), dtype=float) for b in ("Pa", "Va", "Oa")}
        for (k, blk), v in zip(self.blocks, x, strict=True):
            out[blk][k] = v
        return out

    def L_at(self, u: np.ndarray) -> LoopMatrices:
        return replace(self.L0, **self.gains(u))

    def evaluate(self, u: np.ndarray) -> dict[str, Any]:
        key = np.asarray(u, float).tobytes()
        if key in self.cache:
            return self.cache[key]
        self.evaluations += 1
        L = self.L_at(u)
        span = self.hi - self.lo
        roots = machine_roots(L)
        out: dict[str, Any] = {"roots": roots}
        # the controller's stability: Re lambda_1 <= -decay, scaled by |lambda_1|
        lam = complex(roots.roots[0]) if roots.roots.size else complex(np.nan)
        dlam = _root_gradient(L, lam, self.blocks) * span
        sc = self.root_scale
        cons = [(-lam.real - self.decay) / sc]
        jac = [-dlam.real / sc]
        stable = bool(np.isfinite(lam.real) and lam.real < 0)
        # the objective's candidates
        ceiling = False
        if stable:
            try:
                d = plant_lobes(L, roots, self.speeds, self.process, top=self.top, **self.lobe_kw)
                ceiling = not np.any(np.isfinite(d.b_lim))
                cps = candidate_points(d, L, self.objective) if not ceiling else []
            except (ChatterlabError, ArithmeticError):
                cps = []
        else:
            cps = []
        if cps:
            vals = np.array([cp.b for cp in cps])
            grads = np.array([[getattr(cp.S, blk)[k] for k, blk in self.blocks] for cp in cps]) * span
        elif ceiling:  # no boundary below the width ceiling: the objective is the ceiling, flat
            vals, grads = np.array([float(self.lobe_kw["width_max"])]), np.zeros((1, u.size))
        else:  # an unstable controller or no lobe: nothing (the stability row says why)
            vals, grads = np.zeros(1), np.zeros((1, u.size))
        order = np.argsort(vals)[:CANDIDATES]
        vals, grads = vals[order], grads[order]
        while vals.size < CANDIDATES:
            vals, grads = np.r_[vals, vals[-1]], np.vstack([grads, grads[-1]])
        out["vals"], out["grads"] = vals, grads
        # the control loop's margins
        margins = [loop_margins(L, k, self.grid, self._plant(L, k)) for k in range(len(self.ids))]
        out["margins"] = margins
        if self.gain_margin > 1 or self.phase_margin > 0:
            for k, mg in enumerate(margins):
                gvals, gjac = self._margin_rows(L, k, mg, span)
                cons += gvals
                jac += gjac
        out["n_cons"] = len(cons)  # stability and margins: the rows before the force's
        # the force at the design width (when the design width is stable: else it is unbounded)
        m = len(self.ids)
        F, dF = np.full(m, np.inf), np.zeros((m, u.size))
        if self.f1_any and stable and vals[0] > self.design_width:
            F, wz, zk = force_required(L, self.f1, self.design_width, self.force_grid(roots), self.delays)
            for k in range(m):
                dF[k] = _force_gradient(L, self.f1, self.design_width, k, wz[k], zk[k], self.blocks) * span
        out["force"], out["force_grad"] = F, dF
        for k in range(m):
            if np.isfinite(self.force_limits[k]):
                if np.isfinite(F[k]):
                    cons.append(math.log(self.force_limits[k] / max(F[k], 1e-300)))
                    jac.append(-dF[k] / max(F[k], 1e-300))
                else:  # the design width chatters: the bound t >= b_d pushes back
                    cons.append(-1.0)
                    jac.append(np.zeros(u.size))
        out["cons"], out["jac"] = np.array(cons, float), np.array(jac, float)
        self.cache[key] = out
        return out

    def _plant(self, L: LoopMatrices, k: int) -> np.ndarray:
        """P_k on the grid: once per placement for one actuator (it does not
        depend on its own gains), else for the other actuators' gains."""
        key = (k, np.asarray(L.Pa).tobytes() + np.asarray(L.Va).tobytes() + np.asarray(L.Oa).tobytes())
        if len(self.ids) == 1:
            key = (k, b"")
        if key not in self.plants:
            self.plants[key] = plant_transfer(L, k, self.grid)
        return self.plants[key]

    def _margin_rows(
        self, L: LoopMatrices, k: int, mg: Margins, span: np.ndarray
    ) -> tuple[list[float], list[np.ndarray]]:
        """log(GM / GM_min) and (PM - PM_min) / PM_min with their gradients
        (:func:`margin_gradients`); a fixed number of rows: a loop without a
        crossing meets its margin (a constant row)."""
        vals: list[float] = []
        rows: list[np.ndarray] = []
        gg, gp = margin_gradients(L, k, mg, self.blocks)
        if self.gain_margin > 1:
            has = math.isfinite(mg.gain)
            vals.append(math.log(mg.gain / self.gain_margin) if has else _INACTIVE)
            rows.append(gg * span if has else np.zeros(span.size))
        if self.phase_margin > 0:
            has = math.isfinite(mg.phase_deg)
            vals.append((mg.phase_deg - self.phase_margin) / self.phase_margin if has else _INACTIVE)
            rows.append(gp * span / self.phase_margin if has else np.zeros(span.size))
        return vals, rows

    @property
    def f1_any(self) -> bool:
        """The cut has static forces (the force (3) can be computed)."""
        return bool(np.any(self.f1))

    def force_grid(self, roots: Any) -> np.ndarray:
        """The force (3) is sampled on the chatter band (0 .. ``top``), every
        structural and controlled resonance in it resolved."""
        from ..frequency import resonance_grid

        lam = np.r_[np.asarray(roots.roots, complex), self.grid_poles]
        return np.unique(np.r_[0.0, resonance_grid(lam, 0.0, self.top, 2000)])

    # the interface of solve_epigraph
    def candidates(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        e = self.evaluate(u)
        return e["vals"], e["grads"]

    def constraints(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        e = self.evaluate(u)
        return e["cons"], e["jac"]


def _root_gradient(L: LoopMatrices, lam: complex, blocks: list[tuple[int, str]]) -> np.ndarray:
    """d lambda / d gain of a simple root of Delta_c(s) = s^2 M + s C + K +
    F_a diag(G(s)) S_a: -w^H (dDelta/dg) v / (w^H Delta'(lambda) v), v and w
    its right and left null vectors (the smallest singular vectors)."""
    acts = L.actuators
    if acts is None or not np.isfinite(lam):
        return np.zeros(len(blocks), complex)
    G = acts.gains(lam)
    D = lam * lam * L.M + lam * L.C + L.K + (L.Fa * G[None, :]) @ L.Sa
    U, _, Vh = np.linalg.svd(D)
    v = Vh[-1].conj()
    wl = U[:, -1]
    lag = 1.0 + lam * L.La
    e = np.exp(-lam * L.Ta)
    dG = (L.Va - L.Ta * L.Oa * e) / lag - L.La * G / lag  # dG/ds
    dD = 2 * lam * L.M + L.C + (L.Fa * dG[None, :]) @ L.Sa
    den = np.conj(wl) @ dD @ v
    part = {"Pa": 1.0 / lag, "Va": lam / lag, "Oa": e / lag}
    out = np.zeros(len(blocks), complex)
    for i, (k, blk) in enumerate(blocks):
        num = (np.conj(wl) @ L.Fa[:, k]) * part[blk][k] * (L.Sa[k] @ v)
        out[i] = -num / den
    return out


# ------------------------------------------------------------------ the result
@dataclass(frozen=True, eq=False)
class ActiveDesign(Result):
    """An active damper's co-design and what it buys.

    Attributes
    ----------
    actuators : tuple of dict
        Per tuned actuator: ``id``, ``sensor`` and ``at`` (POINT.DIR or the
        file's points), the optimised ``proportional_gain`` (N/m),
        ``velocity_gain`` (N s/m), ``delayed_gain`` (N/m), its ``delay``
        (s), ``bandwidth_hz``, ``force_limit`` and ``force`` (N: the force
        (3) at the design width), the margins ``gain_margin``,
        ``phase_margin_deg``.
    objective : {"minimum", "absolute"}
    width, bare_width, file_width : float
        The objective (m) of the optimised design, of the structure without
        actuators and with the file's gains.
    design_width : float
        b_d (m): the width of the force limit and of the time-domain check.
    abscissa : float
        The rightmost root's real part of the machine with the optimised
        actuators, without cutting (1/s; < 0: stable).
    before, after : LobeDiagram
        The lobes without actuators and of the optimised design (checked by
        the argument principle on the full two-delay loop: ``after.verified``).
    places : tuple of dict
        Each placement tried: ``sensor``, ``at``, ``width`` (m), its gains.
    starts : tuple of dict
        Every start of the chosen placement: ``label``, ``start``, ``end``
        (gains), ``width``, ``iterations``.
    tradeoff : dict
        The trade-off curve of width against actuator effort: ``width`` (m,
        a width to cut at), ``force`` (N: the least force (3) at that width
        of any gains whose minimum limit exceeds it; nan where the
        optimiser found none) and the gains of each point (arrays), empty
        when not computed.
    model : Model
        The optimised model.
    confirmation : ActiveConfirmation or None
        The time-domain confirmation (:func:`confirm_active`): the cut at the
        optimised gains and 1.1 times the old limit, its verdict ("stable"
        only when proven), its decay against the rightmost root, the
        actuator's largest force against its limit; None when not run.
    """

    name: str
    actuators: tuple[dict[str, Any], ...]
    objective: str
    width: float
    bare_width: float
    file_width: float
    design_width: float
    abscissa: float
    before: Any = field(repr=False)
    after: Any = field(repr=False)
    places: tuple[dict[str, Any], ...] = ()
    starts: tuple[dict[str, Any], ...] = ()
    tradeoff: dict[str, Any] = field(default_factory=dict, repr=False)
    model: Any = field(default=None, repr=False)
    free: tuple[str, ...] = ()
    elapsed: float = 0.0
    evaluations: int = 0
    confirmation: Any = field(default=None, repr=False)

    @property
    def gain(self) -> float:
        """width / bare_width (inf when the bare structure chatters at any width)."""
        return self.width / self.bare_width if self.bare_width > 0 else float("inf")

    @property
    def verified(self) -> bool | None:
        """The optimised design's lobes passed every argument-principle check."""
        return self.after.verified

    @property
    def verification(self) -> str:
        """The check of the optimised lobes, in one line: the same
        argument-principle checks as any lobe diagram
        (:func:`chatterlab.lobes.verify_diagram`: the count of roots right of
        the axis just below and above the envelope and at the ceiling), on the
        full loop with the actuators (two delays: the phase sampled, not
        proven; one delay: proven)."""
        ch = self.after.checks
        if not ch:
            return "optimised design not verified (verify=0)"
        proven = sum(bool(c["proven"]) for c in ch)
        return (
            f"optimised design verified by the argument principle (the lobe diagram's checks below and above the"
            f" envelope, on the loop with the actuators): {sum(c['agrees'] for c in ch)}/{len(ch)} checks agree,"
            f" {proven} proven, {len(ch) - proven} sampled"
        )

    def toml(self) -> str:
        """The optimised ``[[actuator]]`` gains, to paste into the model file."""
        out = []
        for a in self.actuators:
            lines = [
                f'[[actuator]]\nid = "{a["id"]}"\n# sensor, at, delay, bandwidth_hz, force_limit: as in the model'
            ]
            for key in ("proportional_gain", "velocity_gain", "delayed_gain"):
                lines.append(f"{key} = {float(a[key])!r}")
            out.append("\n".join(lines) + "\n")
        return "\n".join(out)

    def summary(self) -> str:
        what = (
            "minimum b_lim over the speed range" if self.objective == "minimum" else "absolute minimum b_lim"
        )
        lines = [
            f"active damper co-design of {self.after.model}: maximise the {what} (free: {', '.join(self.free)})"
        ]
        for a in self.actuators:
            f = a["force"]
            lines.append(
                f"  {a['id']}: sensor {a['sensor']}, force {a['at']}; g_P {float(a['proportional_gain']):.5g} N/m,"
                f" g_V {float(a['velocity_gain']):.5g} N s/m, g_O {float(a['delayed_gain']):.5g} N/m,"
                f" T_a {float(a['delay']) * 1e3:.4g} ms"
                + (
                    f", bandwidth {float(a['bandwidth_hz']):.4g} Hz"
                    if math.isfinite(a["bandwidth_hz"])
                    else ""
                )
            )
            lim = a["force_limit"]
            lines.append(
                f"    force at the design width {self.design_width * 1e3:.4g} mm: {f:.4g} N"
                + (f" (limit {lim:.4g} N)" if math.isfinite(lim) else " (no limit)")
                + f"; gain margin {_db(a['gain_margin'])}, phase margin {_deg(a['phase_margin_deg'])}"
            )
        bare = f"{self.bare_width * 1e3:.4g} mm" if self.bare_width > 0 else "0 (an undamped mode)"
        gain = f"x {self.gain:.3g}" if np.isfinite(self.gain) else "from 0"
        opt = f"{self.width * 1e3:.5g} mm"
        if not math.isfinite(self.width):
            ceiling = float(self.after.width_max)
            # the objective is flat there: any gains that clear the ceiling are optimal, and the
            # ones printed are where the search stopped (they differ between CPUs in the 4th digit)
            opt = (
                f"above the {ceiling * 1e3:.4g} mm ceiling (no boundary below it: any gains that reach it are"
                " optimal, these are where the search stopped)"
            )
            gain = f"more than x {ceiling / self.bare_width:.3g}" if self.bare_width > 0 else "from 0"
        lines.append(
            f"  optimised: {opt}; without the actuator: {bare} ({gain});"
            f" the file's gains: {self.file_width * 1e3:.5g} mm"
        )
        lines.append(
            f"  the machine with the actuator, without cutting: rightmost root Re = {self.abscissa:.4g} 1/s (stable)"
        )
        if len(self.places) > 1:
            lines.append(
                "  placements: "
                + "; ".join(f"{p['sensor']} -> {p['at']}: {p['width'] * 1e3:.4g} mm" for p in self.places)
            )
        if self.starts:
            lines.append(starts_line(self.starts, self.width, self.evaluations, self.elapsed))
        if self.tradeoff:
            fl, wd = np.asarray(self.tradeoff["force"]), np.asarray(self.tradeoff["width"])
            lines.append(
                "  trade-off (width cut <- least actuator force it needs): "
                + ", ".join(
                    f"{b * 1e3:.4g} mm <- {a:.3g} N"
                    for a, b in zip(fl, wd, strict=True)
                    if np.isfinite(a * b)
                )
            )
        lines.append("  " + self.verification)
        if self.confirmation is not None:
            lines += self.confirmation.lines(str(self.after.speed_unit))
        if self.after.verified is False:
            lines.append(
                "  CHECK FAILED: the optimised design's lobes are contradicted by the argument principle"
            )
        return "\n".join(lines)

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """``(coords, data, attrs)``: the lobes before and after on the speeds
        (``b_lim_before``, ``b_lim_after``, their chatter frequencies), the
        trade-off curve on its points, the design in the attributes."""
        d0, d1 = self.before, self.after
        coords: dict[str, Any] = {"speed": (d1.speed, d1.speed_unit, str(d1.speed_name))}
        data: dict[str, Any] = {
            "b_lim_before": (d0.b_lim, "m", "limit width without the actuators", ("speed",)),
            "b_lim_after": (d1.b_lim, "m", "limit width with the optimised actuators", ("speed",)),
            "chatter_hz_before": (d0.chatter_hz, "Hz", "chatter frequency without the actuators", ("speed",)),
            "chatter_hz_after": (
                d1.chatter_hz,
                "Hz",
                "chatter frequency with the optimised actuators",
                ("speed",),
            ),
        }
        if self.tradeoff:
            k = np.arange(len(self.tradeoff["width"]))
            coords["point"] = (k, "1", "point of the trade-off curve")
            data["tradeoff_width"] = (self.tradeoff["width"], "m", "the width cut", ("point",))
            data["tradeoff_force"] = (
                self.tradeoff["force"],
                "N",
                "the least actuator force (3) that cutting at that width needs",
                ("point",),
            )
            for g, (_, _, unit) in GAINS.items():
                if f"{g}_gain" in self.tradeoff:
                    data[f"tradeoff_{g}_gain"] = (self.tradeoff[f"{g}_gain"], unit, f"{g} gain", ("point",))
        attrs: dict[str, Any] = {
            "title": "chatterlab active damper co-design",
            "model": self.name,
            "objective": self.objective,
            "width_m": self.width,
            "bare_width_m": self.bare_width,
            "file_width_m": self.file_width,
            "design_width_m": self.design_width,
            "abscissa_per_s": self.abscissa,
            "free_gains": json.dumps(list(self.free)),
            "actuators": json.dumps([{k: _plain(v) for k, v in a.items()} for a in self.actuators]),
            "verified": str(self.verified),
            "verification": self.verification,
        }
        c = self.confirmation
        if c is not None:
            attrs.update(
                {
                    "confirmation_verdict": c.verdict,
                    "confirmation_reason": c.reason,
                    "confirmation_speed": c.speed,
                    "confirmation_width_m": c.width,
                    "confirmation_abscissa_per_s": c.abscissa,
                    "confirmation_rhp_count": c.rhp_count,
                    "confirmation_count_proven": str(c.count_proven),
                    "confirmation_rate_per_s": c.rate,
                    "confirmation_rate_error_per_s": c.rate_error,
                    "confirmation_rate_agrees": str(c.rate_agrees),
                    "confirmation_force_max_n": json.dumps([_plain(f) for f in c.forces]),
                    "confirmation_force_ok": str(c.force_ok),
                }
            )
        return coords, data, attrs

    def to_csv(self, path: Any) -> Any:
        """The lobes before and after, one row per speed (exact floats,
        ``name [unit]`` headers); written atomically; returns the path."""
        from ..io._netcdf_csv import write_csv

        coords, data, _ = self.dataset_parts()
        rows = {k: (v[0], v[1], v[2]) for k, v in data.items() if v[3] == ("speed",)}
        return write_csv(path, {"speed": coords["speed"]}, rows)

    def plot(self, ax: Any = None, *, title: str | None = None) -> Any:
        """The lobes before and after on one axis and, with a trade-off curve,
        the curve beside them (:func:`chatterlab.plot.plot_lobes_compare`,
        :func:`chatterlab.plot.plot_tradeoff`); returns the Axes (a tuple of
        two with the curve)."""
        from ..plot import plot_lobes_compare
        from ..plot._design import plot_tradeoff

        two = bool(self.tradeoff)
        if ax is None and two:
            import matplotlib.pyplot as plt

            _, axs = plt.subplots(1, 2, figsize=(13.0, 4.5), width_ratios=(1.6, 1.0))
            ax = tuple(axs)
        a0 = ax[0] if isinstance(ax, tuple | list | np.ndarray) else ax
        ceiling = float(self.after.width_max)
        what = (
            f"{self.width * 1e3:.4g} mm" + (f" (x {self.gain:.3g})" if np.isfinite(self.gain) else "")
            if math.isfinite(self.width)
            else f"no lobe below the {ceiling * 1e3:.4g} mm ceiling"
        )
        head = title or f"{self.name}: active damper, {what}"
        a0 = plot_lobes_compare(
            [self.before, self.after], ["without actuator", "optimised actuator"], ax=a0, title=head
        )
        if not two:
            return a0
        a1 = ax[1] if isinstance(ax, tuple | list | np.ndarray) and len(ax) > 1 else None
        a1 = plot_tradeoff(
            self.tradeoff["force"], self.tradeoff["width"], ax=a1, bare=self.bare_width,
            design=self.design_width, chosen=(self.actuators[0]["force"], self.width),
        )  # fmt: skip
        return (a0, a1)


def _plain(v: Any) -> Any:
    if isinstance(v, float | np.floating):
        return float(v) if math.isfinite(float(v)) else None
    return v


def _db(gm: float) -> str:
    return "inf" if not math.isfinite(gm) else f"{gm:.3g} ({20 * math.log10(gm):.3g} dB)"


def _deg(pm: float) -> str:
    return "inf" if not math.isfinite(pm) else f"{pm:.3g} deg"


# ------------------------------------------------------------------ the co-design
def _objective_of(d: Any, L: LoopMatrices, objective: str) -> float:
    lim = limits_of(d, L, speeds=False)
    cp = lim.minimum if objective == "minimum" else lim.absolute
    return float(cp.b) if cp is not None else float("inf")


def design_active(
    model: Model,
    speeds: Any,
    *,
    actuators: list[str] | None = None,
    free: tuple[str, ...] | list[str] = ("proportional", "velocity", "delayed"),
    bounds: dict[str, tuple[float, float]] | None = None,
    places: list[tuple[str, str]] | None = None,
    objective: Literal["minimum", "absolute"] = "minimum",
    design_width: float | None = None,
    force_limit: float | None = None,
    gain_margin: float = 2.0,
    phase_margin: float = 45.0,
    decay: float = 0.0,
    tradeoff: int = 0,
    starts: int = 3,
    position: float | None = None,
    width_max: float = 0.02,
    terms: Literal["pdo", "o"] = "pdo",
    n_frequencies: int | None = None,
    verify: int = 16,
    seed: int = 0,
    confirm: bool = True,
) -> ActiveDesign:
    """Choose an actuator's gains (and placement) to maximise the minimum
    chatter-free width (module docstring).

    Parameters
    ----------
    model : Model
        With one or more ``[[actuator]]`` items (:func:`with_actuator` adds
        one): their points, directions, delays, bandwidths and force limits
        are kept; their gains are the starting point.
    speeds : array
        Speeds (process unit) of the lobe diagrams.
    actuators : list of str, optional
        Ids of the actuators tuned (default: all).
    free : tuple of str
        The gains varied, among ``"proportional"``, ``"velocity"``,
        ``"delayed"`` (the delayed gain only with a delay T_a > 0).
    bounds : dict, optional
        ``gain -> (lo, hi)`` in N/m or N s/m (velocity: lo >= 0); default
        from the host mode the sensor sees (modal stiffness k_h, mass m_h):
        velocity 0 .. 0.2 sqrt(k_h m_h) (up to 10 % of the host's critical
        damping), proportional and delayed -k_h/10 .. k_h/10.
    places : list of (sensor, at), optional
        Candidate placements (``"POINT.DIR"`` each) of the one tuned
        actuator: the gains are optimised at each, the best is kept.
    objective : {"minimum", "absolute"}
    design_width : float, optional
        b_d, m (default 1.1 times the bare structure's objective).
    force_limit : float, optional
        N; overrides every tuned actuator's ``force_limit`` (inf: none).
    gain_margin, phase_margin : float
        Required margins of each control loop (ratio; degrees); 1 and 0 to
        drop them.
    decay : float
        Required decay rate of the controlled machine's rightmost root, 1/s.
    tradeoff : int
        Points of the trade-off curve (0: none).
    starts : int
        Optimiser starts: the file's gains, velocity feedback alone, then
        Latin-hypercube points (``seed``).
    position, width_max, terms, n_frequencies, verify
        As for :func:`chatterlab.lobes.lobes`.
    confirm : bool
        Confirm the optimum in the time domain (:func:`confirm_active`):
        ``ActiveDesign.confirmation``.

    Returns
    -------
    ActiveDesign

    Raises
    ------
    ControllerUnstable
        The machine with the file's actuators is unstable without cutting
        (an :class:`~chatterlab.errors.InputError`: nothing is optimised).
    """
    t0 = time.perf_counter()
    if objective not in OBJECTIVES:
        raise InputError(f"objective must be one of {', '.join(OBJECTIVES)} (got {objective!r})")
    width_max = check_width(width_max, "width_max")
    check_starts(starts)
    if not isinstance(tradeoff, int) or isinstance(tradeoff, bool) or tradeoff < 0:
        raise InputError(f"tradeoff must be a whole number >= 0 (got {tradeoff!r})")
    if not (isinstance(gain_margin, int | float) and math.isfinite(gain_margin) and gain_margin >= 1):
        raise InputError(f"gain_margin must be a ratio >= 1 (got {gain_margin!r}); 1 drops it")
    if not (isinstance(phase_margin, int | float) and 0 <= phase_margin < 180):
        raise InputError(f"phase_margin must be in degrees, 0 <= PM < 180 (got {phase_margin!r}); 0 drops it")
    if not (isinstance(decay, int | float) and math.isfinite(decay) and decay >= 0):
        raise InputError(f"decay must be a rate >= 0 in 1/s (got {decay!r})")
    if force_limit is not None and not (isinstance(force_limit, int | float) and force_limit > 0):
        raise InputError(f"force_limit must be a force > 0 in N (got {force_limit!r})")
    known = [a.id for a in model.actuators]
    if not known:
        raise InputError(
            f"{model.source} has no [[actuator]]: add one (docs/model-format.md) or use with_actuator(...)"
        )
    ids = list(known if actuators is None else actuators)
    for aid in ids:
        if aid not in known:
            raise InputError(f"unknown actuator '{aid}' (known: {', '.join(known)})")
    free = tuple(free)
    for g in free:
        if g not in GAINS:
            raise InputError(f"free gains must be among {', '.join(GAINS)} (got {g!r})")
    if not free:
        raise InputError("free: give at least one gain to vary (proportional, velocity, delayed)")
    bounds = dict(bounds or {})
    for g, b in bounds.items():
        if g not in GAINS:
            raise InputError(f"bounds: unknown gain {g!r} (known: {', '.join(GAINS)})")
        lo, hi = check_bound(f"bounds of the {g} gain", *b)
        if g == "velocity" and lo < 0:
            raise InputError(
                f"bounds of the velocity gain must be >= 0 (got {lo:g} .. {hi:g} N s/m): a negative velocity"
                " gain feeds energy in"
            )
    if places is not None:
        if len(ids) != 1:
            raise InputError("places: the placement is chosen for one actuator; name it (actuators=[...])")
        if not places:
            raise InputError("places: give at least one (sensor, at) pair")
        for sp, fp in places:
            _spec(sp, "sensor")
            _spec(fp, "at")
    speeds = np.asarray(speeds, dtype=float)
    lobe_kw: dict[str, Any] = {"width_max": width_max, "terms": terms, "n_frequencies": n_frequencies}
    proc = model.process
    if proc is None:
        raise InputError(f"{model.source} has no [process] table: add one so that speeds map to delays")
    if proc.kind == "milling":
        raise InputError(
            f"{model.source} is a milling model: the active co-design works on D-subdivision lobes (turning, shaping)"
        )
    # the file's controller: stable, or nothing is optimised
    fz = assemble(model).at(position)
    L_file = _loop_matrices(fz, terms)
    check_controller(model.source, machine_roots(L_file), _delays(model))
    # the bare structure: its lobes, objective and chatter frequency
    bare = without_actuators(model)
    fz_bare = assemble(bare).at(position)
    before = design_lobes(fz_bare, speeds, verify=verify, **lobe_kw)
    Lb = _loop_matrices(fz_bare, terms)
    bare_width = _objective_of(before, Lb, objective)
    f_c = float(before.absolute_minimum["chatter_hz"])
    b_d = check_width(design_width, "design_width") if design_width is not None else 1.1 * bare_width
    if not math.isfinite(b_d):
        raise InputError("the bare structure has no limit below width_max: give design_width")
    inner = np.linspace(float(speeds.min()), float(speeds.max()), 9)
    inner_kw = {**lobe_kw, "n_frequencies": min(n_frequencies or 2000, 400)}
    top = bare_band(Lb, width_max)
    T = np.asarray(proc.delay(speeds) if proc.kind != "delay" else speeds, dtype=float)
    delays = (float(T.min()), float(T.max()))
    file_d = design_lobes(fz, speeds, verify=0, **lobe_kw)
    file_width = _objective_of(file_d, L_file, objective)

    def build(mdl: Model) -> tuple[_Problem, list[tuple[str, np.ndarray]]]:
        fzm = assemble(mdl).at(position)
        L0 = _loop_matrices(fzm, terms)
        idx = [mdl.actuators.index(next(a for a in mdl.actuators if a.id == i)) for i in ids]
        blocks, lo, hi = [], [], []
        for k in idx:
            a = mdl.actuators[k]
            row = L0.Sa[k]
            f_h, m_h = host_mode(L0.M, L0.K, row, f_c, f'[[actuator]] "{a.id}": its sensor')
            k_h = m_h * (2 * math.pi * f_h) ** 2
            dflt = {  # 10 % of the host's critical damping, of its stiffness
                "velocity": (0.0, 0.2 * math.sqrt(k_h * m_h)),
                "proportional": (-0.1 * k_h, 0.1 * k_h),
                "delayed": (-0.1 * k_h, 0.1 * k_h),
            }
            for g in free:
                if g == "delayed" and a.delay == 0:
                    continue  # undelayed, g_O is a proportional gain
                b = bounds.get(g, dflt[g])
                blocks.append((k, GAINS[g][0]))
                lo.append(float(b[0]))
                hi.append(float(b[1]))
        if not blocks:
            raise InputError("no gain to vary: the delayed gain needs a delay (T_a > 0); free another gain")
        flims = np.array(
            [force_limit if force_limit is not None else mdl.actuators[k].force_limit for k in idx]
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UnitWarning)
            f1 = closed_loop_unwarned(fzm, width=1.0, delay=1.0, terms=terms).force
        if np.any(np.isfinite(flims)) and not np.any(f1):
            raise InputError(
                f"{mdl.source}: a force limit needs the cut's static forces: give forces = [...] (N at width_ref)"
                " in the [[coupling]], or drop force_limit"
            )
        from ..structure import complex_modes

        lam0 = complex_modes(L0.M, L0.C, L0.K).lam
        prob = _Problem(
            L0, tuple(ids), blocks, np.array(lo), np.array(hi), inner, proc, objective, inner_kw, top, f1,
            b_d, flims, float(gain_margin), float(phase_margin), float(decay), delays,
            grid=margin_grid(L0), grid_poles=lam0[lam0.imag > 0],
            root_scale=1e-2 * max(abs(complex(machine_roots(L0).roots[0])), 1.0),
        )  # fmt: skip
        u_file = np.array(
            [(getattr(L0, blk)[k] - l_) / (h_ - l_) for (k, blk), l_, h_ in zip(blocks, lo, hi, strict=True)]
        )
        uv = np.array(
            [
                0.25 if blk == "Va" else (0.0 - l_) / (h_ - l_)
                for (k, blk), l_, h_ in zip(blocks, lo, hi, strict=True)
            ]
        )
        named = [("file", np.clip(u_file, 0.0, 1.0)), ("velocity", np.clip(uv, 0.0, 1.0))]
        return prob, start_points(named, len(blocks), starts, seed)

    def solve(prob: _Problem, u: np.ndarray) -> tuple[np.ndarray, float, int]:
        t_min = prob.design_width * (1 + 1e-6) if np.any(np.isfinite(prob.force_limits)) else 0.0
        return solve_epigraph(prob, u, prob.constraints, t_min=t_min)

    def feasible(prob: _Problem, u: np.ndarray) -> bool:
        c, _ = prob.constraints(u)
        return bool(np.all(c >= -1e-6))

    candidates = [(sp, fp) for sp, fp in places] if places is not None else [None]
    place_info, best = [], None
    evaluations = 0
    for pl in candidates:
        mdl = model if pl is None else _placed(model, ids[0], *pl)
        if pl is not None:
            check_controller(
                mdl.source, machine_roots(_loop_matrices(assemble(mdl).at(position), terms)), _delays(mdl)
            )
        prob, u0 = build(mdl)
        prob.scale = (
            max(float(prob.candidates(u0[0][1])[0][0]), bare_width * 1e-3) if bare_width > 0 else width_max
        )
        runs, (label, u_s, u_b, w_b, nit) = best_start(
            u0, functools.partial(solve, prob), functools.partial(feasible, prob)
        )
        evaluations += prob.evaluations
        place_info.append((pl, mdl, prob, runs, u_b, w_b))
        if best is None or w_b > best[5]:
            best = place_info[-1]
    assert best is not None
    pl, mdl, prob, runs, u_b, w_b = best
    if not math.isfinite(w_b):
        raise InputError(
            "no gains meet the constraints (controller stability, margins"
            + (", the force limit at the design width" if np.any(np.isfinite(prob.force_limits)) else "")
            + "): widen the bounds, lower the margins or raise the force limit"
        )
    # the trade-off curve: the least force at the design width for each minimum width
    trade: dict[str, Any] = {}
    if tradeoff:
        trade, n_ev = _pareto(prob, u_b, w_b, bare_width, tradeoff)
        evaluations += n_ev
    # the optimised model, drawn again and verified
    gains = prob.gains(u_b)
    idx = [[a.id for a in mdl.actuators].index(i) for i in ids]
    values = {
        aid: {GAINS[g][1]: float(gains[GAINS[g][0]][k]) for g in GAINS}
        for aid, k in zip(ids, idx, strict=True)
    }
    tuned = _with_gains(mdl, values)
    fz_t = assemble(tuned).at(position)
    after = design_lobes(fz_t, speeds, verify=verify, **lobe_kw)
    L_t = _loop_matrices(fz_t, terms)
    width = _objective_of(after, L_t, objective)
    roots = machine_roots(L_t)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnitWarning)
        f1 = closed_loop_unwarned(fz_t, width=1.0, delay=1.0, terms=terms).force
    F = (
        force_required(L_t, f1, b_d, prob.force_grid(roots), delays)[0]
        if np.any(f1) and width > b_d
        else np.full(len(tuned.actuators), np.nan)
    )
    acts = []
    for aid, k in zip(ids, idx, strict=True):
        a = tuned.actuators[k]
        mg = loop_margins(L_t, k, prob.grid)
        flim = force_limit if force_limit is not None else a.force_limit
        acts.append(
            {
                "id": aid,
                "sensor": pl[0] if pl is not None else _where(tuned, aid)[0],
                "at": pl[1] if pl is not None else _where(tuned, aid)[1],
                "proportional_gain": a.proportional_gain,
                "velocity_gain": a.velocity_gain,
                "delayed_gain": a.delayed_gain,
                "delay": a.delay,
                "bandwidth_hz": a.bandwidth_hz,
                "force_limit": float(flim),
                "force": float(F[k]),
                "gain_margin": mg.gain,
                "phase_margin_deg": mg.phase_deg,
            }
        )
    places_t = tuple(
        {
            "sensor": p[0] if p is not None else "(file)",
            "at": p[1] if p is not None else "(file)",
            "width": float(w),
            **{g: float(pr.gains(ub)[GAINS[g][0]][0]) for g in GAINS},
        }
        for p, _, pr, _, ub, w in place_info
    )
    starts_t = tuple(
        {
            "label": lb,
            "start": prob.gains(us),
            "end": prob.gains(ub),
            "width": float(wb),
            "iterations": int(it),
        }
        for lb, us, ub, wb, it in runs
    )
    design = ActiveDesign(
        name=str(getattr(model, "name", "") or model.source),
        actuators=tuple(acts),
        objective=objective,
        width=width,
        bare_width=bare_width,
        file_width=file_width,
        design_width=b_d,
        abscissa=float(roots.abscissa),
        before=before,
        after=after,
        places=places_t,
        starts=starts_t,
        tradeoff=trade,
        model=tuned,
        free=tuple(
            g for g in free if not (g == "delayed" and all(tuned.actuators[k].delay == 0 for k in idx))
        ),
        elapsed=time.perf_counter() - t0,
        evaluations=evaluations,
    )
    if confirm:
        design = replace(design, confirmation=confirm_active(design, position=position, terms=terms))
        design = replace(design, elapsed=time.perf_counter() - t0)
    return design


def confirm_active(
    design: ActiveDesign,
    *,
    factor: float = 1.1,
    speed: float | None = None,
    position: float | None = None,
    terms: Literal["pdo", "o"] = "pdo",
) -> Any:
    """The time domain confirms a co-design
    (:func:`chatterlab.design._confirm.confirm_loop`): the cut at the
    optimised gains and ``factor`` times the old (uncontrolled) limit, at
    ``speed`` (default: where the optimised lobes are lowest, the hardest
    speed of the range), integrated with the actuators' bandwidth and delay;
    its verdict is "stable" only when proven, else "undetermined" (or
    "unstable"), with the run's decay against the rightmost root and each
    actuator's largest force against its limit.  Returns a
    :class:`~chatterlab.design.ActiveConfirmation`."""
    from ._confirm import confirm_loop

    if not (isinstance(factor, int | float) and math.isfinite(factor) and factor > 0):
        raise InputError(f"factor must be a number > 0 (got {factor!r})")
    d = design.after
    if speed is None:  # the optimised lobes' lowest speed, else (none below the ceiling) the old one's
        for dd in (d, design.before):
            b = np.asarray(dd.b_lim, dtype=float)
            if np.any(np.isfinite(b)):
                speed = float(dd.speed[int(np.nanargmin(np.where(np.isfinite(b), b, np.nan)))])
                break
        else:
            speed = float(d.speed[0])
    fz = assemble(design.model).at(position if position is not None else d.position)
    # the roots' band: twice the highest chatter frequency of the lobes before and after
    hz = np.r_[np.asarray(d.chatter_hz, float), np.asarray(design.before.chatter_hz, float)]
    hz = hz[np.isfinite(hz)]
    top = 2 * 2 * math.pi * float(hz.max()) if hz.size else None
    return confirm_loop(
        fz, float(speed), factor * design.bare_width, design.bare_width, terms=terms, omega_max=top
    )


def _min_force(prob: _Problem, u0: np.ndarray, target: float) -> tuple[np.ndarray, bool]:
    """The gains of least actuator force (3) at the design width whose
    minimum width is at least ``target`` (m), the other constraints held:
    SLSQP on the epigraph form, minimise s subject to log(F_k / F_0) <= s,
    b_i >= target (every candidate), stability and margins >= 0; from
    ``u0``.  Returns the gains and whether they meet the constraints."""
    from scipy.optimize import minimize

    n, m = u0.size, len(prob.ids)
    F0 = prob.evaluate(u0)["force"]
    Fref = np.where(np.isfinite(F0) & (F0 > 0), F0, 1.0)
    sc = prob.scale

    def e(y: np.ndarray) -> dict[str, Any]:
        return prob.evaluate(y[:n])

    def logF(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ev = e(y)
        F, dF = ev["force"], ev["force_grad"]
        ok = np.isfinite(F)
        val = np.where(ok, np.log(np.where(ok, F, 1.0) / Fref), 10.0)
        grad = np.where(ok[:, None], dF / np.where(ok, F, 1.0)[:, None], 0.0)
        return val, grad

    def c_vals(y: np.ndarray) -> np.ndarray:
        ev = e(y)
        lf, _ = logF(y)
        return np.r_[(ev["vals"] - target) / sc, ev["cons"][: ev["n_cons"]], y[n] - lf]

    def c_jac(y: np.ndarray) -> np.ndarray:
        ev = e(y)
        _, dlf = logF(y)
        k0 = ev["n_cons"]
        rows = [np.c_[ev["grads"] / sc, np.zeros((ev["grads"].shape[0], 1))]]
        rows.append(np.c_[ev["jac"][:k0], np.zeros((k0, 1))])
        rows.append(np.c_[-dlf, np.ones((m, 1))])
        return np.vstack(rows)

    y0 = np.r_[u0, float(np.max(logF(np.r_[u0, 0.0])[0]))]
    res = minimize(
        lambda y: y[n],
        y0,
        jac=lambda y: np.r_[np.zeros(n), 1.0],
        method="SLSQP",
        bounds=[(0.0, 1.0)] * n + [(None, None)],
        constraints=[{"type": "ineq", "fun": c_vals, "jac": c_jac}],
        options={"ftol": 1e-9, "maxiter": 60},
    )
    u = np.clip(res.x[:n], 0.0, 1.0)
    ok = bool(np.all(c_vals(np.r_[u, res.x[n]])[:-m] >= -1e-6) and np.all(np.isfinite(e(u)["force"])))
    return u, ok


def _pareto(
    prob: _Problem, u_best: np.ndarray, w_best: float, bare: float, points: int
) -> tuple[dict[str, Any], int]:
    """The trade-off of width against actuator effort: for ``points`` widths
    b from the optimum's minimum down to 2 % above the bare structure's, the
    least force (3) that cutting at b needs (the force at the design width b,
    the minimum width of the gains at least b, :func:`_min_force`; each
    warm-started from the previous, wider one).  Returns the curve (``width``
    m, ``force`` N, the gains) and the evaluations it took."""
    hi = 0.98 * min(w_best, float(prob.lobe_kw["width_max"]))
    lo = 1.02 * bare
    targets = np.linspace(hi, lo, points) if hi > lo else np.array([hi])
    u = u_best
    wd: list[float] = []
    ff: list[float] = []
    gains: dict[str, list[float]] = {g: [] for g in GAINS}
    n_ev = 0
    for t in targets:
        pt = replace(
            prob, design_width=float(t), force_limits=np.full(len(prob.ids), np.inf), cache={}, evaluations=0
        )
        try:
            u2, ok = _min_force(pt, u, float(t) * (1 + 1e-3))
        except (ChatterlabError, ArithmeticError, np.linalg.LinAlgError):
            ok = False
        n_ev += pt.evaluations
        if ok:
            u = u2
            ff.append(float(np.max(pt.evaluate(u2)["force"])))
            gv = pt.gains(u2)
        else:
            ff.append(np.nan)
            gv = {b: np.full(len(prob.ids), np.nan) for b in ("Pa", "Va", "Oa")}
        wd.append(float(t))
        for g, (blk, _, _) in GAINS.items():
            gains[g].append(float(gv[blk][0]))
    out: dict[str, Any] = {"width": np.array(wd), "force": np.array(ff)}
    out.update({f"{g}_gain": np.array(v) for g, v in gains.items()})
    return out, n_ev


def _where(model: Model, aid: str) -> tuple[str, str]:
    """How the file places actuator ``aid``: its sensor and force as
    ``POINT.DIR`` (``POINT@ANGLEdeg`` for an angle; an inline point as written)."""
    t = next(
        x for x in json.loads(model.raw).get("actuator", []) if isinstance(x, dict) and x.get("id") == aid
    )

    def name(p: Any) -> str:
        return p if isinstance(p, str) else json.dumps(p, separators=(",", ":"))

    def suffix(dkey: str, akey: str, dflt: str) -> str:
        if dkey in t:
            return f".{t[dkey]}"
        if akey in t:
            return f"@{float(t[akey]):g}deg"
        return dflt

    s_suf = suffix("sensor_direction", "sensor_angle_deg", "")
    sensor = name(t["sensor"]) + s_suf
    force = name(t.get("at", t["sensor"])) + suffix("direction", "angle_deg", s_suf)
    return sensor, force


def _loop_matrices(fz: Any, terms: str) -> LoopMatrices:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnitWarning)
        loop = closed_loop_unwarned(fz, width=1.0, delay=1.0, terms=terms)  # type: ignore[arg-type]
    return matrices_of(loop)


def _delays(model: Model) -> str:
    return ", ".join(f"{a.id}: T_a = {a.delay * 1e3:.4g} ms" for a in model.actuators)


__all__ += ["ControllerUnstable"]
