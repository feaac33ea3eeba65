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
from typing import Any

import numpy as np

from ..errors import InputError, check_finite
from ._milling import TWO_PI, Milling

__all__ = [
    "SpeedVariation",
    "VaryingSpeedMilling",
    "SHAPES",
    "AMPLITUDE_MAX",
    "FREQUENCY_RANGE",
    "MAX_PASSES",
    "varying_milling",
]

#: the wave shapes S of Eq. (1)
SHAPES = ("sine", "triangle")
#: the largest relative amplitude RVA accepted: theta' = 1 + RVA S >= 1 - RVA stays
#: well away from 0 (a spindle that stops has no delay); programs use 0.05..0.3
AMPLITUDE_MAX = 0.9
#: the ratios RVF accepted: a variation from a hundred-thousandth of the rotation frequency
#: (a period of 1e5 revolutions, which no discretisation resolves anyway) to ten times it
#: (a spindle's inertia follows at most a fraction of its rotation frequency: 0.005..1)
FREQUENCY_RANGE = (1e-5, 10.0)
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
