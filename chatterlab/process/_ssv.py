"""Spindle-speed variation (SSV): the speed program, the phase it turns the
spindle through, and the time-varying delay it makes.

The program (Insperger & Stepan 2004; Zatarain et al. 2008; Seguy et al. 2010)
------------------------------------------------------------------------------
The spindle turns at

    Omega(t) = Omega_0 [1 + RVA S(RVF Omega_0 t)]                               (1)

with Omega_0 the mean speed (rad/s), RVA the relative amplitude, RVF the
ratio of the variation's frequency to the mean rotation frequency (the
variation's period is T_v = 2 pi / (RVF Omega_0), 1 / RVF revolutions) and
S a 2 pi-periodic wave of unit amplitude and zero mean:

* ``"sine"``:     S(u) = sin u;
* ``"triangle"``: S(u) = (2 / pi) arcsin(sin u), the triangle of the same
  phase (0 at u = 0, +1 at pi / 2, -1 at 3 pi / 2).

All the kinematics is a function of the mean phase x = Omega_0 t (rad); the
angle turned since t = 0 is

    theta(x) = x + (RVA / RVF) P(RVF x),   P(u) = int_0^u S                    (2)

in closed form: P(u) = 1 - cos u for the sine; for the triangle, with
v = u mod 2 pi, P = v^2 / pi on [0, pi/2], 2 v - v^2/pi - pi/2 on
[pi/2, 3 pi/2] and v^2/pi - 4 v + 4 pi on [3 pi/2, 2 pi] (P has period
2 pi because S has zero mean, so theta(x + 2 pi / RVF) = theta(x) + 2 pi / RVF).
theta' = 1 + RVA S >= 1 - RVA > 0: theta is strictly increasing and its
inverse x(theta) is found by safeguarded Newton iterations to round-off
(:meth:`SpeedVariation.inverse`).

The delay.  A tooth (or, in turning, the same point of the workpiece one
revolution later) meets the surface the one before it left when the spindle
has turned by the pitch angle phi_p (2 pi / N for a uniform cutter, 2 pi in
turning): the delay tau(t) is defined by

    int_{t - tau}^{t} Omega(s) ds = phi_p,   i.e.  theta(x) - theta(x - Omega_0 tau) = phi_p,   (3)

so Omega_0 tau(t) = x - x(theta(x) - phi_p) exactly (:meth:`SpeedVariation.lag`).
It is periodic with T_v; for small RVA, by (3) to first order,
Omega_0 tau = phi_p - RVA [P(RVF x) - P(RVF (x - phi_p))] / RVF + O(RVA^2).

The period.  The delay repeats with T_v; a milling cutter's coefficients
repeat with the spindle angle 2 pi / N (uniform pitch; 2 pi for a variable
one).  The cut is periodic when both have run whole numbers of times: over
k variation periods the spindle turns k 2 pi / RVF, which must be L pitch
angles.  With RVF = p / q in lowest terms this needs
L = q N_b / gcd(p, N_b) tooth passes (N_b = N, or 1 for a variable pitch)
and k = p / gcd(p, N_b) variation periods (:meth:`SpeedVariation.passes`):
RVF must be a ratio of whole numbers whose period chatterlab can discretise
(at most :data:`MAX_PASSES` tooth passes); a turning or shaping cut (whose
coefficients do not turn with the spindle) is periodic with T_v for any RVF.

Shaping.  A shaper has no spindle; its delay is the stroke cycle.  Its
"speed variation" is a modulation (1) of the drive's cycle rate (work and
return stroke alike), Omega_0 = 2 pi / T_0 with T_0 the stroke cycle at the
mean work speed, and phi_p = 2 pi: the same mathematics on the phase of the
cycle.

References
----------
T. Insperger, G. Stepan, Stability analysis of turning with periodic
spindle speed modulation via semidiscretization, J. Vib. Control 10 (2004)
1835-1855.
M. Zatarain, I. Bediaga, J. Munoa, R. Lizarralde, Stability of milling
processes with continuous spindle speed variation: analysis in the
frequency and time domains, and experimental correlation, CIRP Annals 57
(2008) 379-384.
S. Seguy, T. Insperger, L. Arnaud, G. Dessein, G. Peigne, On the stability
of high-speed milling with spindle speed variation, Int. J. Adv. Manuf.
Technol. 48 (2010) 883-895.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from functools import cached_property
from typing import Any

import numpy as np

from ..errors import InputError, check_finite, check_positive
from ..model._items import SSV_AMPLITUDE_MAX, SSV_FREQUENCY_RANGE, SSV_SHAPES
from ._loop import ClosedLoop
from ._milling import TWO_PI, Milling

__all__ = [
    "SpeedVariation",
    "VaryingSpeedMilling",
    "SHAPES",
    "AMPLITUDE_MAX",
    "FREQUENCY_RANGE",
    "MAX_PASSES",
    "varying_milling",
    "VaryingDelayLoop",
    "ssv_loop",
]

#: the wave shapes S of Eq. (1); the largest RVA (theta' = 1 + RVA S >= 1 - RVA stays well away
#: from 0: a spindle that stops has no delay); the RVF accepted -- the model file's limits
#: (``[ssv]``), one place for both
SHAPES, AMPLITUDE_MAX, FREQUENCY_RANGE = SSV_SHAPES, SSV_AMPLITUDE_MAX, SSV_FREQUENCY_RANGE
#: the most tooth passes (pitch angles) one period of a milling cut under SSV may span
MAX_PASSES = 400
#: a ratio RVF is taken as p / q when within this (relative) of it
RATIONAL_RTOL = 1e-9


# ============================================================================ the wave
def _wave(u: np.ndarray, shape: str) -> np.ndarray:
    """S(u) of Eq. (1), unit amplitude, zero mean, period 2 pi."""
    if shape == "sine":
        return np.sin(u)
    v = np.mod(u, TWO_PI)
    return np.where(
        v < 0.5 * math.pi,
        2.0 * v / math.pi,
        np.where(v < 1.5 * math.pi, 2.0 - 2.0 * v / math.pi, 2.0 * v / math.pi - 4.0),
    )


def _wave_integral(u: np.ndarray, shape: str) -> np.ndarray:
    """P(u) = int_0^u S (Eq. 2), closed form, period 2 pi."""
    if shape == "sine":
        return 1.0 - np.cos(u)
    v = np.mod(u, TWO_PI)
    pi = math.pi
    return np.where(
        v < 0.5 * pi,
        v * v / pi,
        np.where(v < 1.5 * pi, 2.0 * v - v * v / pi - 0.5 * pi, v * v / pi - 4.0 * v + 4.0 * pi),
    )


#: max P - min P of each shape (the phase's largest excursion from x, per RVA / RVF)
_P_RANGE = {"sine": 2.0, "triangle": 0.5 * math.pi}


# ============================================================================ the program
@dataclass(frozen=True)
class SpeedVariation:
    """A periodic spindle-speed program, Eq. (1) of the module docstring.

    Parameters
    ----------
    amplitude : float
        RVA = (speed amplitude) / (mean speed), in [0, AMPLITUDE_MAX].
    frequency : float
        RVF = (variation frequency) / (mean rotation frequency), > 0.
    shape : {"sine", "triangle"}
        The wave S.

    References
    ----------
    Insperger & Stepan (2004); Seguy et al. (2010): see the module docstring.
    """

    amplitude: float
    frequency: float
    shape: str = "sine"

    def __post_init__(self) -> None:
        a = check_finite(self.amplitude, "speed variation amplitude (RVA)")
        if not 0.0 <= a <= AMPLITUDE_MAX:
            raise InputError(
                f"speed variation amplitude (RVA) must be in [0, {AMPLITUDE_MAX:g}] (got {a:g}): it is the speed's"
                " amplitude over its mean, e.g. 0.1 for +-10 %"
            )
        f = check_finite(self.frequency, "speed variation frequency (RVF)")
        lo, hi = FREQUENCY_RANGE
        if not lo <= f <= hi:
            raise InputError(
                f"speed variation frequency (RVF) must be in [{lo:g}, {hi:g}] (got {f:g}): it is the variation's"
                " frequency over the mean rotation frequency, e.g. 0.05 for one cycle in 20 revolutions"
            )
        if self.shape not in SHAPES:
            raise InputError(f"speed variation shape must be one of {', '.join(SHAPES)} (got {self.shape!r})")
        object.__setattr__(self, "amplitude", a)
        object.__setattr__(self, "frequency", f)

    @classmethod
    def of_model(cls, model: Any) -> SpeedVariation | None:
        """The model file's ``[ssv]`` program (None when it has none)."""
        item = getattr(model, "ssv", None)
        return None if item is None else cls(item.rva, item.rvf, item.shape)

    # ------------------------------------------------------------------ kinematics (mean phase x = Omega_0 t)
    @property
    def is_constant(self) -> bool:
        """RVA = 0: the constant speed."""
        return self.amplitude == 0.0

    def rate(self, x: Any) -> np.ndarray:
        """Omega / Omega_0 = 1 + RVA S(RVF x) at mean phases x (rad)."""
        return 1.0 + self.amplitude * _wave(self.frequency * np.asarray(x, dtype=float), self.shape)

    def phase(self, x: Any) -> np.ndarray:
        """theta(x) = x + (RVA / RVF) P(RVF x) (Eq. 2): the angle turned at mean phase x, rad."""
        x = np.asarray(x, dtype=float)
        if self.is_constant:
            return x.copy()
        return x + (self.amplitude / self.frequency) * _wave_integral(self.frequency * x, self.shape)

    def inverse(self, theta: Any) -> np.ndarray:
        """The mean phase x with theta(x) = ``theta`` (rad), to round-off.

        Newton's iteration on g(x) = theta(x) - theta, g' = 1 + RVA S >= 1 - RVA,
        kept inside the bracket theta - (RVA / RVF) [max P, min P] (bisection when
        a step leaves it); the sine's g is smooth and the triangle's piecewise
        quadratic, so it converges in a few steps."""
        th = np.asarray(theta, dtype=float)
        if self.is_constant:
            return th.copy()
        A, F = self.amplitude, self.frequency
        lo = th - (A / F) * _P_RANGE[self.shape]
        hi = th.copy()  # P >= 0
        x = np.clip(th - (A / F) * float(np.mean([0.0, _P_RANGE[self.shape]])), lo, hi)
        scale = np.maximum(np.abs(th), 1.0)
        for _ in range(100):
            g = self.phase(x) - th
            lo = np.where(g < 0, x, lo)
            hi = np.where(g > 0, x, hi)
            step = g / self.rate(x)
            xn = x - step
            out = (xn <= lo) | (xn >= hi)
            xn = np.where(out, 0.5 * (lo + hi), xn)
            done = np.abs(xn - x) <= 4.0 * np.finfo(float).eps * scale
            x = xn
            if np.all(done):
                break
        return x

    def lag(self, x: Any, angle: float | np.ndarray) -> np.ndarray:
        """Omega_0 tau at mean phases x for a pitch angle ``angle`` (Eq. 3), rad of mean phase:
        x - x(theta(x) - angle)."""
        x = np.asarray(x, dtype=float)
        return x - self.inverse(self.phase(x) - angle)

    # ------------------------------------------------------------------ the period
    def ratio(self) -> Fraction:
        """RVF as p / q in lowest terms, q small enough that a milling period stays within
        :data:`MAX_PASSES` tooth passes (an :class:`InputError` when RVF is not such a ratio)."""
        f = self.frequency
        fr = Fraction(f).limit_denominator(MAX_PASSES)
        if abs(float(fr) - f) > RATIONAL_RTOL * f:
            near = sorted(
                {Fraction(f).limit_denominator(d) for d in (10, 20, 40, 100, MAX_PASSES // 2)},
                key=lambda r: abs(float(r) - f),
            )[:2]
            show = ", ".join(f"{float(r):.6g} (= {r.numerator}/{r.denominator})" for r in near)
            raise InputError(
                f"speed variation frequency (RVF) {f:.10g} is not a ratio of whole numbers p/q with q <="
                f" {MAX_PASSES}, so the milling cut under it never repeats: give a ratio, e.g. {show}"
            )
        return fr

    def passes(self, base: int) -> tuple[int, int]:
        """(L, k): one period of a cut whose coefficients repeat every 2 pi / ``base`` of spindle
        angle spans L such angles and k variation periods (module docstring), L <= MAX_PASSES."""
        fr = self.ratio()
        p, q = fr.numerator, fr.denominator
        g = math.gcd(p, base)
        L, k = q * base // g, p // g
        if L > MAX_PASSES:
            raise InputError(
                f"speed variation frequency (RVF) {self.frequency:g} = {p}/{q} makes one period of the cut"
                f" {L} tooth passes ({k} variation periods); at most {MAX_PASSES} are discretised: give a"
                f" ratio p/q with q * {base} / gcd(p, {base}) <= {MAX_PASSES}"
            )
        return L, k

    def period_phase(self, base: int | None) -> float:
        """The principal period in mean phase, rad: the variation's 2 pi / RVF for a cut whose
        coefficients do not turn with the spindle (``base`` None: turning, shaping), else
        L 2 pi / ``base`` (:meth:`passes`)."""
        if base is None:
            return TWO_PI / self.frequency
        L, _ = self.passes(base)
        return L * TWO_PI / base

    def describe(self) -> str:
        """The program in words: "sine SSV, RVA 0.1, RVF 0.05"."""
        return f"{self.shape} SSV, RVA {self.amplitude:g}, RVF {self.frequency:g}"


# ============================================================================ milling under SSV
@dataclass(frozen=True)
class VaryingSpeedMilling(Milling):
    """A :class:`Milling` cutter whose spindle follows a :class:`SpeedVariation`
    about the mean speed ``rpm`` (the speed every method takes is the mean one).

    The tooth angles are phi_j(t) = theta(Omega_0 t) - lag_j (Eq. 2), the
    delays tau_j(t) those of Eq. (3) with tooth j's pitch angle, the
    period that of the cut and the program together (:meth:`period`, at most
    :data:`MAX_PASSES` tooth passes), the breakpoints where a tooth enters or
    leaves the arc within it.  :meth:`delays` gives the *mean* delays
    pitch_j / Omega_0 (the speed axis of a diagram); the engines read the
    delays at their instants from :meth:`delays_at`."""

    variation: SpeedVariation | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        if not isinstance(self.variation, SpeedVariation):
            raise InputError(
                f"VaryingSpeedMilling needs a SpeedVariation (got {type(self.variation).__name__})"
            )
        self.variation.passes(self._base)  # refused here, before any engine: RVF must repeat

    @property
    def _base(self) -> int:
        """The coefficients repeat every 2 pi / base of spindle angle."""
        return self.teeth if self.uniform else 1

    @property
    def ssv(self) -> SpeedVariation:
        assert self.variation is not None
        return self.variation

    def period(self, rpm: float) -> float:
        """Principal period, s: L pitch angles of mean rotation (module docstring)."""
        return float(self.ssv.period_phase(self._base) / self.omega(rpm))

    def tooth_angles(self, t: float | np.ndarray, rpm: float) -> np.ndarray:
        """phi_j(t) = theta(Omega_0 t) - lag_j in [0, 2 pi), shape (..., N)."""
        ta = np.asarray(t, dtype=float)
        th = self.ssv.phase(self.omega(rpm) * ta)
        return np.mod(th[..., None] - self.lags, TWO_PI)

    def delays_at(self, t: float | np.ndarray, rpm: float) -> np.ndarray:
        """tau_j(t), s, shape (..., N): Eq. (3) with tooth j's pitch angle."""
        w = self.omega(rpm)
        x = w * np.asarray(t, dtype=float)
        return self.ssv.lag(x[..., None], self.pitches) / w

    def breakpoints(self, rpm: float, depth: float | None = None) -> np.ndarray:
        """Times in [0, period) where a tooth enters or leaves the arc (with a helix, also
        where the flute's last point does), s, sorted."""
        w = self.omega(rpm)
        X = self.ssv.period_phase(self._base)
        psi = self.lag_angle(depth)
        edges = [self.entry, self.exit] + ([self.entry + psi, self.exit + psi] if psi > 0 else [])
        th = []
        for e in edges:
            for lag in self.lags:
                first = e + lag
                m = np.arange(math.floor(-first / TWO_PI) - 1, math.ceil((X - first) / TWO_PI) + 2)
                th.append(first + TWO_PI * m)
        angles = np.concatenate(th)
        angles = angles[(angles >= -1e-12 * X) & (angles < X * (1 - 1e-13))]
        tb = np.sort(np.mod(self.ssv.inverse(angles) / w, X / w))
        T = X / w
        tb[np.isclose(tb, T, rtol=0, atol=1e-13 * T)] = 0.0
        tb = np.unique(tb)
        if tb.size > 1:
            tb = tb[np.r_[True, np.diff(tb) > 1e-12 * T]]
        return tb

    def directional_mean(self, t0: float | np.ndarray, t1: float | np.ndarray, rpm: float) -> np.ndarray:
        """Mean of H_j over [t0, t1] in time, shape (..., N, 2, 2).

        Under SSV dphi = Omega dt is not uniform, so the mean over time is
        int H(theta(t)) dt / (t1 - t0), by Gauss-Legendre quadrature (16 points)
        on each sub-interval between the breakpoints (where H is analytic and,
        for the sine, the speed too; the triangle's corners are one more
        breakpoint each): exact to round-off for steps of the engines' size."""
        t0 = np.atleast_1d(np.asarray(t0, dtype=float))
        t1 = np.atleast_1d(np.asarray(t1, dtype=float))
        T = self.period(rpm)
        w = self.omega(rpm)
        cuts = self.breakpoints(rpm)
        if self.ssv.shape == "triangle":  # the wave's corners: S' jumps at u = pi/2 + k pi
            F = self.ssv.frequency
            Xp = T * w
            u = 0.5 * math.pi + math.pi * np.arange(0, math.ceil(F * Xp / math.pi) + 2)
            cuts = np.unique(np.r_[cuts, np.mod(u / F / w, T)])
        gx, gw = np.polynomial.legendre.leggauss(16)
        shape = np.broadcast(t0, t1).shape
        t0, t1 = np.broadcast_to(t0, shape).ravel(), np.broadcast_to(t1, shape).ravel()
        out = np.zeros((t0.size, self.teeth, 2, 2))
        for i in range(t0.size):
            a, b = float(t0[i]), float(t1[i])
            base = math.floor(a / T)
            inner = np.concatenate([cuts + T * k for k in range(base - 1, math.floor(b / T) + 2)])
            inner = inner[(inner > a) & (inner < b)]
            ends = np.r_[a, inner, b]
            acc = np.zeros((self.teeth, 2, 2))
            for lo, hi in zip(ends[:-1], ends[1:], strict=True):
                tt = 0.5 * (hi - lo) * gx + 0.5 * (hi + lo)
                H = self.directional_on(tt, rpm, 0.5 * (lo + hi))
                acc += 0.5 * (hi - lo) * np.einsum("k,kjab->jab", gw, H)
            out[i] = acc / (b - a)
        return out.reshape(shape + (self.teeth, 2, 2))

    def zoa(self) -> np.ndarray:
        """The average over a revolution is that of the constant speed: the variation
        changes when the teeth cut, not where (:meth:`Milling.zoa`)."""
        return super().zoa()


def varying_milling(milling: Milling, variation: SpeedVariation | None) -> Milling:
    """``milling`` under ``variation`` (a :class:`VaryingSpeedMilling`), or ``milling``
    itself for no variation or RVA = 0 (the constant speed: the same object, so RVA -> 0
    is today's result to the bit)."""
    if variation is None or variation.is_constant:
        return milling
    base = {f: getattr(milling, f) for f in ("teeth", "diameter", "Kt", "Kn", "entry", "exit")}
    return VaryingSpeedMilling(
        **base,
        pitch=milling.pitch,
        helix=milling.helix,
        Kte=milling.Kte,
        Kne=milling.Kne,
        rpm=milling.rpm,
        variation=variation,
    )


# ============================================================================ the closed loop under SSV
@dataclass(frozen=True, eq=False)
class VaryingDelayLoop:
    """Eq. (1) of :mod:`chatterlab.frequency._floquet_ssv`: a closed loop under a spindle-speed
    variation at one mean speed, in scaled states (velocities in units of
    ``ws``; the multipliers do not depend on the scaling).

    Build it with :func:`ssv_loop`.  ``kind`` is ``"milling"`` or the
    constant process's (``"turning"``, ``"shaping"``, ``"delay"``);
    ``speed`` the mean speed in the process's unit, ``mean_delay`` the
    delay at the mean speed (s), ``omega0`` the mean phase rate (rad/s),
    ``angles`` the pitch angles phi_p (rad), ``period`` the computational
    period (s) and ``folds`` how many principal periods it holds."""

    loop: ClosedLoop
    variation: SpeedVariation
    kind: str
    speed: float
    mean_delay: float
    omega0: float
    angles: np.ndarray
    period: float
    folds: int
    A: np.ndarray
    C: np.ndarray
    ws: float
    milling: Milling | None = None
    Ac0: np.ndarray | None = None  # turning: constant A_c per unit width
    B0: np.ndarray | None = None  # turning: constant B per unit width (d, rho)
    W: np.ndarray | None = None  # milling: scaled [0; W] (d, rho), with Ub
    Ub: np.ndarray | None = None
    Acd: np.ndarray | None = None  # turning: process damping's part of Ac0 at the mean speed (over the rate)
    quasi_static: Any = None  # turning: the structure's quasi-static split (QuasiStatic), or None
    split_parts: dict[str, np.ndarray] | None = None  # turning with a split: the pieces of Eq. (1q)

    def split_terms(self, width: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Turning / shaping with a quasi-static split (Eq. (1q) of
        :mod:`chatterlab.frequency._floquet_ssv`): (A~, B~, C_y, E) at width b.

        With the kept modes' state x, the cut's coordinates r = C_r x + G f (G the
        quasi-static modes' exact static compliance, f the cut's force in r's
        coordinates), the force f = b [K_c r + K_v C_v x + U_d y(t - tau)] (the
        process's D_P, D_V on r; the kept modes' velocity C_v x) and the delayed
        output y = V_d^T r (D_O = U_d V_d^T on r):
        (I - b K_c G) f = b [(K_c C_r + K_v C_v) x + U_d y(t - tau)], so with
        [L_x, L_u] = (I - b K_c G)^-1 [K_c C_r + K_v C_v, U_d]::

            x' = (A + b B_f L_x) x + b B_f L_u y(t - tau)
            y  = V_d^T (C_r + b G L_x) x + b V_d^T G L_u y(t - tau)

        (B_f the force's entry into the kept modes).  With G = 0 this is Eq. (1)
        with A_c, B and C of the unsplit loop restricted to the kept modes."""
        assert self.split_parts is not None
        sp = self.split_parts
        b = float(width)
        d = self.d
        G, Kc = sp["G"], sp["Kc"]
        Nm = np.eye(G.shape[0]) - b * Kc @ G
        L = np.linalg.solve(Nm, np.concatenate([Kc @ sp["Cr"] + sp["Kv"] @ sp["Cv"], sp["Ud"]], axis=1))
        Lx, Lu = L[:, :d], L[:, d:]
        Vt = sp["Vd"].T
        return (
            self.A + b * sp["Bf"] @ Lx,
            b * sp["Bf"] @ Lu,
            Vt @ (sp["Cr"] + b * G @ Lx),
            b * Vt @ G @ Lu,
        )

    @property
    def d(self) -> int:
        return int(self.A.shape[0])

    @property
    def rho(self) -> int:
        return int(self.C.shape[0])

    @property
    def n_delays(self) -> int:
        return int(self.angles.size)

    def delays(self, t: Any) -> np.ndarray:
        """tau_j(t), s, shape t.shape + (J,) (Eq. 3 of :mod:`chatterlab.process._ssv`)."""
        x = self.omega0 * np.asarray(t, dtype=float)
        return self.variation.lag(x[..., None], self.angles) / self.omega0

    @cached_property
    def tau_range(self) -> tuple[float, float]:
        """(min, max) of the delays over a period, s (sampled densely, widened by 1 %)."""
        tt = np.linspace(0.0, self.period, 64 * max(self.folds, 1) * 16 + 1)
        tau = self.delays(tt)
        return float(tau.min()) * 0.99, float(tau.max()) * 1.01

    # ------------------------------------------------------------------ coefficients
    def coefficients(self, t: np.ndarray, t_inside: float) -> tuple[np.ndarray, np.ndarray]:
        """(A_c(t), B_j(t)) per unit width at times ``t`` of the smooth piece holding
        ``t_inside`` (one-sided at its ends): shapes (k, d, d) and (k, J, d, rho)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if self.milling is None:
            assert self.Ac0 is not None and self.B0 is not None
            k = t.size
            B = np.broadcast_to(self.B0, (k, 1) + self.B0.shape)
            if self.Acd is None:
                return np.broadcast_to(self.Ac0, (k,) + self.Ac0.shape), B
            # process damping: C_pd b / V(t), V(t) = V_0 Omega(t) / Omega_0 (Eq. 1q of the frequency module)
            inv_rate = 1.0 / self.variation.rate(self.omega0 * t)
            return self.Ac0[None] + (inv_rate - 1.0)[:, None, None] * self.Acd[None], B
        H = self.milling.directional_on(t, self.speed, t_inside)  # (k, N, 2, 2)
        return self._milling_terms(H)

    def mean_coefficients(self, t0: np.ndarray, t1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The exact means of (A_c, B_j) over the steps [t0, t1]: shapes (m, d, d), (m, J, d, rho)."""
        if self.milling is None:
            t0 = np.atleast_1d(np.asarray(t0, dtype=float))
            Ac, B = self.coefficients(t0, 0.0)
            if self.Acd is None:
                return Ac, B
            # the mean of 1 / rate over each step: 16-point Gauss-Legendre (1 / rate is analytic on a
            # step of the sine; the triangle's corners make it O(h^2) there, the order of SD itself)
            gx, gw = np.polynomial.legendre.leggauss(16)
            t1 = np.broadcast_to(np.asarray(t1, dtype=float), t0.shape)
            tt = 0.5 * (t1 - t0)[:, None] * gx[None] + 0.5 * (t1 + t0)[:, None]
            mean_inv = 0.5 * (1.0 / self.variation.rate(self.omega0 * tt)) @ gw
            assert self.Ac0 is not None
            return self.Ac0[None] + (mean_inv - 1.0)[:, None, None] * self.Acd[None], B
        H = self.milling.directional_mean(t0, t1, self.speed)
        return self._milling_terms(H)

    def _milling_terms(self, H: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        assert self.W is not None and self.Ub is not None
        Hr = np.einsum("ai,kjab,bl->kjil", self.Ub, H, self.Ub)
        B = np.einsum("dr,kjrs->kjds", self.W, Hr)  # (k, N, d, rho)
        Ac = -np.einsum("kjds,se->kde", B, self.C)
        return Ac, B

    def breakpoints(self) -> np.ndarray:
        """Times in [0, period) where a coefficient jumps or the delay has a corner, s."""
        T = self.period
        pts: list[np.ndarray] = [np.zeros(1)]
        var, w0, X = self.variation, self.omega0, self.omega0 * T
        if self.milling is not None:
            tb = self.milling.breakpoints(self.speed)
            Tp = self.milling.period(self.speed)
            tb = (tb[None, :] + Tp * np.arange(self.folds)[:, None]).ravel()
            pts.append(tb)
            if not self.milling.uniform:
                # the breakpoints' delayed images, where t - tau_j(t) is one (x'' jumps there)
                th = var.phase(w0 * tb)
                pts.append(np.mod(var.inverse(th[:, None] + self.angles[None, :]), X).ravel() / w0)
        if var.shape == "triangle" and not var.is_constant:
            # the speed's corners at RVF x = pi/2 + k pi, and where the delayed argument meets one
            F = var.frequency
            u = 0.5 * math.pi + math.pi * np.arange(0, math.ceil(F * X / math.pi) + 1)
            xc = u / F
            xc = xc[xc < X]
            th = var.phase(xc)
            pts.append(xc / w0)
            pts.extend(np.mod(var.inverse(th + a), X) / w0 for a in self.angles)
        t = np.mod(np.concatenate(pts), T)
        t = np.unique(t)
        t = t[np.r_[True, np.diff(t) > 1e-10 * T]]
        if t.size > 1 and T - t[-1] <= 1e-10 * T:
            t = t[:-1]
        return t

    def pieces(self) -> list[tuple[float, float, bool]]:
        """(start, end, cut) of the smooth pieces of one period from its first breakpoint."""
        tb = self.breakpoints()
        ends = np.r_[tb, tb[0] + self.period]
        out = []
        for lo, hi in zip(ends[:-1], ends[1:], strict=True):
            if self.milling is None:
                cut = True
            else:
                cut = bool(np.any(self.milling.directional(0.5 * (lo + hi), self.speed) != 0.0))
            out.append((float(lo), float(hi), cut))
        return out

    def omega_scale(self, width: float) -> float:
        """The fastest solution frequency at width b, rad/s: the structure's highest pole
        and that of the loop with the cut's mean current-state term."""
        if self.split_parts is not None:
            ev = np.linalg.eigvals(self.split_terms(width)[0])
            return max(float(np.abs(ev).max()), float(self.quasi_static.loop.omega_max), 1.0 / self.period)
        tt = np.linspace(0.0, self.period, 129)[:-1]
        Ac, _ = (
            self.coefficients(tt, 0.0)
            if self.milling is None
            else self.mean_coefficients(tt, tt + 1e-3 * self.period)
        )
        ev = np.linalg.eigvals(self.A + width * np.mean(Ac, axis=0))
        return max(float(np.abs(ev).max()), float(self.loop.omega_max), 1.0 / self.period)


def ssv_loop(
    loop: ClosedLoop, variation: SpeedVariation, speed: float | None = None, quasi_static: Any = None
) -> VaryingDelayLoop:
    """Eq. (1) of :mod:`chatterlab.frequency._floquet_ssv` for ``loop`` under
    ``variation`` at the mean ``speed``.

    Parameters
    ----------
    loop : ClosedLoop
        A milling loop (:func:`~chatterlab.process.milling_loop`; ``speed`` in rpm
        is then required) or a constant one with its delay at the mean speed
        (:func:`~chatterlab.process.closed_loop`: turning, shaping; ``speed``
        optional, in the process's unit, for the record).
    variation : SpeedVariation
        The program (RVA, RVF, shape).
    speed : float, optional
        The mean speed.
    quasi_static : QuasiStatic, optional
        Turning / shaping: the structure split into its kept modes, integrated, and
        the quasi-static rest (:func:`chatterlab.frequency._floquet_spectral.split_structure` of
        ``loop``); the loop is then Eq. (1q) (:meth:`VaryingDelayLoop.split_terms`).

    Returns
    -------
    VaryingDelayLoop
    """
    if not isinstance(variation, SpeedVariation):
        raise InputError(f"variation must be a SpeedVariation (got {type(variation).__name__})")
    if loop.actuators is not None:
        raise InputError(
            "spindle-speed variation with active dampers ([[actuator]]) is not modelled: remove the"
            " actuators or analyse them at constant speed"
        )
    if loop.damping is not None and (loop.process is not None or quasi_static is not None):
        raise InputError(
            "spindle-speed variation with process damping ([process_damping]) is modelled for turning and"
            " shaping without a quasi-static split: analyse milling's at constant speed, or give split=None"
        )
    struct = loop.structure
    n = struct.n
    A_raw = struct.state_matrix
    ws = max(float(loop.omega_max), 1e-300)
    sc = np.r_[np.ones(n), np.full(n, ws)]
    A = A_raw * sc[None, :] / sc[:, None]
    Minv = np.linalg.inv(struct.M)
    if loop.process is not None:
        if quasi_static is not None:
            raise InputError(
                "ssv: a quasi-static split is modelled for turning and shaping, not for milling: give split=None"
            )
        base = loop.process
        if not isinstance(base, Milling):
            raise InputError(f"ssv: unknown periodic process {type(base).__name__}")
        if base.helix > 0:
            raise InputError("spindle-speed variation with a helix angle is not modelled: give helix_deg = 0")
        if speed is None:
            raise InputError("ssv: a milling loop needs its mean spindle speed (speed, rpm)")
        rpm = check_positive(speed, "spindle speed", "rpm")
        if isinstance(base, VaryingSpeedMilling):
            raise InputError("ssv: give the loop at constant speed; the variation is its own argument")
        fields = {f: getattr(base, f) for f in ("teeth", "diameter", "Kt", "Kn", "entry", "exit", "pitch")}
        mil = VaryingSpeedMilling(**fields, Kte=base.Kte, Kne=base.Kne, rpm=base.rpm, variation=variation)
        Ub, Jr, W = loop.cut_basis
        rho = Jr.shape[0]
        C = np.zeros((rho, 2 * n))
        C[:, :n] = Jr
        Wd = np.zeros((2 * n, rho))
        Wd[n:] = W
        w0 = Milling.omega(rpm)
        T = mil.period(rpm)
        angles = mil.pitches
        tau_max = float(np.max(angles)) / (w0 * (1.0 - variation.amplitude))
        folds = max(1, math.ceil(tau_max / T * (1 + 1e-12)))
        return VaryingDelayLoop(
            loop, variation, "milling", rpm, float(np.max(angles)) / w0, w0, angles, folds * T, folds,
            A, C * sc[None, :], ws, milling=mil, W=Wd / sc[:, None], Ub=Ub,
        )  # fmt: skip
    if loop.delay is None or not np.any(loop.Dl_O):
        raise InputError(
            "ssv: the loop has no delayed (regenerative) term, so a speed variation changes nothing"
        )
    b = float(loop.width)
    T0 = float(loop.delay)
    if quasi_static is not None:
        return _split_loop(loop, variation, speed, quasi_static)
    Ac = np.zeros((2 * n, 2 * n))
    Ac[n:, :n] = Minv @ loop.DP / b
    Ac[n:, n:] = Minv @ loop.DV / b
    U, V = loop.U, loop.V  # D_O = U V^T at width b
    rho = U.shape[1]
    B0 = np.zeros((2 * n, rho))
    B0[n:] = Minv @ U / b
    C = np.zeros((rho, 2 * n))
    C[:, :n] = V.T
    Acd = None
    if loop.damping is not None:
        # the flank's b C_pd / V W at the mean speed, in D_V (process._damping): under SSV its gain
        # follows the cutting speed V(t) = V_0 Omega(t) / Omega_0 (coefficients())
        Dd = -loop.J.T @ loop.damping.matrix(b) @ loop.J
        Acd = np.zeros((2 * n, 2 * n))
        Acd[n:, n:] = Minv @ Dd / b
        Acd = Acd * sc[None, :] / sc[:, None]
    kind, spd, w0, folds, T = _turning_period(loop, variation, speed)
    return VaryingDelayLoop(
        loop, variation, kind, spd, T0, w0, np.array([TWO_PI]), T, folds,
        A, C * sc[None, :], ws, Ac0=Ac * sc[None, :] / sc[:, None], B0=B0 / sc[:, None], Acd=Acd,
    )  # fmt: skip


def _turning_period(
    loop: ClosedLoop, variation: SpeedVariation, speed: float | None
) -> tuple[str, float, float, int, float]:
    """(kind, mean speed, Omega_0, folds, computational period) of a turning / shaping loop."""
    T0 = float(loop.delay)  # type: ignore[arg-type]
    kind = "delay"
    if loop.frozen is not None and loop.frozen.model.process is not None:
        kind = str(loop.frozen.model.process.kind)
    w0 = TWO_PI / T0
    Tv = variation.period_phase(None) / w0
    folds = max(1, math.ceil(T0 / (1.0 - variation.amplitude) / Tv * (1 + 1e-12)))
    spd = float(speed) if speed is not None else float("nan")
    return kind, spd, w0, folds, folds * Tv


def _split_loop(
    loop: ClosedLoop, variation: SpeedVariation, speed: float | None, qs: Any
) -> VaryingDelayLoop:
    """Eq. (1q) (:meth:`VaryingDelayLoop.split_terms`) of a turning / shaping ``loop`` on the
    kept modes of ``qs`` (a :class:`~chatterlab.frequency._floquet_spectral.QuasiStatic` of this loop's structure
    and coupling), in scaled states (velocities in units of the kept modes' highest pole)."""
    Ub, Jr, _ = loop.cut_basis
    kl = qs.loop
    G = np.asarray(qs.compliance, dtype=float)
    if G.shape != (Jr.shape[0], Jr.shape[0]) or int(qs.n_full) != loop.n:
        raise InputError("ssv: the quasi-static split is not of this loop's structure and coupling")
    nk = kl.n
    Jk = Ub.T @ kl.J  # the kept modes' part of r = Jr q
    ws = max(float(kl.omega_max), 1e-300)
    sc = np.r_[np.ones(nk), np.full(nk, ws)]
    A = kl.structure.state_matrix * sc[None, :] / sc[:, None]
    b = float(loop.width)
    Kc, Kv, Kd = (-Ub.T @ D @ Ub / b for D in (loop.Dl_P, loop.Dl_V, loop.Dl_O))
    U_, s_, Vt_ = np.linalg.svd(Kd)
    rho = int(np.sum(s_ > 1e-12 * max(float(s_[0]), 1e-300)))
    Ud, Vd = U_[:, :rho] * s_[:rho], Vt_[:rho].T
    rc = Jr.shape[0]
    Cr = np.zeros((rc, 2 * nk))
    Cr[:, :nk] = Jk
    Cv = np.zeros((rc, 2 * nk))
    Cv[:, nk:] = ws * Jk  # r' of the kept modes: ws times the scaled velocity
    Bf = np.zeros((2 * nk, rc))
    Bf[nk:] = np.linalg.solve(kl.M, Jk.T) / ws
    parts = {"G": G, "Kc": Kc, "Kv": Kv, "Ud": Ud, "Vd": Vd, "Cr": Cr, "Cv": Cv, "Bf": Bf}
    kind, spd, w0, folds, T = _turning_period(loop, variation, speed)
    return VaryingDelayLoop(
        loop, variation, kind, spd, float(loop.delay), w0, np.array([TWO_PI]), T, folds,  # type: ignore[arg-type]
        A, Vd.T @ Cr, ws, quasi_static=qs, split_parts=parts,
    )  # fmt: skip
