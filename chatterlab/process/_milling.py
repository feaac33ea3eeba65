"""Milling: the cutting process of a rotating tool with N teeth.

Geometry and sign convention (Altintas & Budak 1995; Insperger & Stepan 2002,
2004).  The tool's centre moves relative to the workpiece by r = (x, y); the
feed is along +x.  A tooth's angular position phi is measured from +y,
clockwise (towards +x), and grows with time at Omega = 2 pi n / 60 (n in rpm).
The unit vector from the tool's axis to the tooth is (sin phi, cos phi); the
chip thickness cut by tooth j is

    h_j(t) = g_j(t) [f_z sin phi_j + (sin phi_j, cos phi_j) . (r(t) - r(t - tau_j))]

with g_j = 1 while entry < phi_j (mod 2 pi) < exit, else 0, and tau_j the time
since the preceding tooth passed the same angle.  The tangential and normal
(radial) forces on the tooth, F_t = K_t a_p h + K_te a_p and
F_n = K_n a_p h + K_ne a_p, act on the tool along -(cos phi, -sin phi) and
-(sin phi, cos phi).  Linearised about the static chip, the regenerative part
of the force on the tool is

    F(t) = -a_p sum_j H_j(t) [r(t) - r(t - tau_j)],                       (1)

    H_j(t) = g_j(t) [K_t (cos phi, -sin phi) + K_n (sin phi, cos phi)] (sin phi, cos phi)^T

i.e. H_j = g_j [[K_t c s + K_n s^2, K_t c^2 + K_n s c], [-K_t s^2 + K_n s c,
-K_t s c + K_n c^2]] with s = sin phi_j, c = cos phi_j (:meth:`Milling.directional`).
Its xx entry is Insperger & Stepan's 1-DOF h(t) = sum_j g_j sin phi_j
(K_t cos phi_j + K_n sin phi_j).  The edge coefficients only add a static
force: they do not enter (1) and do not change stability.

Pitch.  ``pitch[j]`` is the angle by which tooth j trails tooth j-1 (tooth 0
trails tooth N-1 by ``pitch[0]``); the angles sum to 2 pi.  Tooth j is at
phi_j(t) = Omega t - (pitch[1] + ... + pitch[j]) and its delay is
tau_j = pitch[j] / Omega (:meth:`Milling.delays`).  Uniform pitch (the
default, ``pitch=()``) gives one delay tau = 60 / (N n), and the
coefficients H(t) = sum_j H_j(t) are tau-periodic; a variable-pitch cutter
has N delays and coefficients periodic in one revolution, 60 / n
(:meth:`Milling.period`).

Averaging (zeroth-order approximation, Altintas & Budak 1995).  Over one
revolution each tooth sweeps the arc [entry, exit] once, so the mean of
sum_j H_j(t) is

    H0 = (N / 2 pi) int_entry^exit H(phi) dphi                               (2)

(:meth:`Milling.zoa`, N/m^2).  The ZOA force is F = -a_p H0 [r(t) - r(t - tau)]
for uniform pitch, and -a_p (H0 / N) sum_j [r(t) - r(t - tau_j)] for a
variable pitch.  In Altintas & Budak's notation F = (a K_t / 2) [A0] Delta
with Delta = r(t) - r(t - tau), so [A0] = -2 H0 / K_t.

Helix.  A helix angle beta makes the points of a cutting edge at height z
lag the tool's bottom by psi(z) = 2 z tan(beta) / D; the force of a depth a_p
is then the mean of (1) over the lag angles [0, psi_max], psi_max =
2 a_p tan(beta) / D (:meth:`Milling.directional` with ``depth``).  This
smooths the entry and exit of a tooth (the coefficients become continuous)
and makes them depend on a_p; it leaves the average (2) unchanged, so ZOA
does not see the helix.

References
----------
Y. Altintas, E. Budak, Analytical prediction of stability lobes in milling,
CIRP Annals 44 (1995) 357-362.
T. Insperger, G. Stepan, Semi-discretization method for delayed systems,
Int. J. Numer. Meth. Engng 55 (2002) 503-518.
T. Insperger, G. Stepan, Updated semi-discretization method for periodic
delay-differential equations with discrete delay, Int. J. Numer. Meth.
Engng 61 (2004) 117-141.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from ..errors import InputError, check_count, check_finite, check_nonneg, check_positive, check_speed
from ..model._items import HELIX_MAX_DEG, SPEED_PLAUSIBLE, SPEED_RANGE, spindle_speed_for, tooth_period

__all__ = ["Milling", "check_spindle_speed"]

TWO_PI = 2.0 * math.pi

#: the largest lag angle psi_max = 2 a_p tan(beta) / D of a flute, rad: ten
#: turns of the flute over the depth of cut.  The work of the helical
#: coefficients grows with it (every turn is a window of the integral), and
#: real cuts stay below one or two turns
LAG_MAX = 10 * TWO_PI


def check_spindle_speed(rpm: object, name: str = "spindle speed") -> float:
    """A spindle speed, rpm: finite and within :data:`SPEED_RANGE`, else
    :class:`InputError` naming the value, the accepted and the plausible range."""
    n = check_speed(rpm, name, "rpm")
    lo, hi = SPEED_RANGE
    if not lo <= n <= hi:
        raise InputError(
            f"{name} must be within {lo:g}..{hi:g} rpm (got {n:g} rpm); spindles run"
            f" {SPEED_PLAUSIBLE[0]:g}..{SPEED_PLAUSIBLE[1]:g} rpm"
        )
    return n


def _primitive(phi: np.ndarray, Kt: float, Kn: float) -> np.ndarray:
    """Antiderivative of H(phi) (without the window), shape (..., 2, 2)."""
    p = np.asarray(phi, dtype=float)
    s2 = np.sin(p) ** 2 / 2.0
    half = p / 2.0
    q = np.sin(2.0 * p) / 4.0
    out = np.empty(p.shape + (2, 2))
    out[..., 0, 0] = Kt * s2 + Kn * (half - q)
    out[..., 0, 1] = Kt * (half + q) + Kn * s2
    out[..., 1, 0] = -Kt * (half - q) + Kn * s2
    out[..., 1, 1] = -Kt * s2 + Kn * (half + q)
    return out


def _h(phi: np.ndarray, Kt: float, Kn: float) -> np.ndarray:
    """H(phi) without the window, shape (..., 2, 2)."""
    p = np.asarray(phi, dtype=float)
    s, c = np.sin(p), np.cos(p)
    out = np.empty(p.shape + (2, 2))
    out[..., 0, 0] = Kt * c * s + Kn * s * s
    out[..., 0, 1] = Kt * c * c + Kn * s * c
    out[..., 1, 0] = -Kt * s * s + Kn * s * c
    out[..., 1, 1] = -Kt * s * c + Kn * c * c
    return out


def _show(x: float) -> str:
    return f"{x:g}"


@dataclass(frozen=True)
class Milling:
    """A milling cutter and its cut, in SI units and radians.

    Parameters
    ----------
    teeth : int
        Number of teeth N >= 1.
    diameter : float
        Cutter diameter D, m.
    Kt, Kn : float
        Tangential and normal (radial) cutting-force coefficients, N/m^2
        (K_n = K_r K_t in Altintas's notation).
    entry, exit : float
        Entry and exit angles phi_st < phi_ex, rad, within [0, pi]
        (see the module docstring for the angle convention).  Use
        :meth:`from_immersion` for a radial immersion a_e / D with up- or
        down-milling.
    pitch : tuple of float
        Pitch angles, rad: ``pitch[j]`` is the angle by which tooth j
        trails tooth j-1 (cyclic); N positive values summing to 2 pi.
        Empty (default): uniform pitch 2 pi / N.
    helix : float
        Helix angle beta, rad, in [0, pi/2).
    Kte, Kne : float
        Edge coefficients, N/m (static force only; no effect on stability).
    rpm : float
        Default spindle speed, rpm (0: none).

    References
    ----------
    Altintas & Budak (1995); Insperger & Stepan (2002, 2004): see the module
    docstring.
    """

    teeth: int
    diameter: float
    Kt: float
    Kn: float
    entry: float
    exit: float
    pitch: tuple[float, ...] = ()
    helix: float = 0.0
    Kte: float = 0.0
    Kne: float = 0.0
    rpm: float = 0.0
    _angles: tuple[float, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        n = check_count(self.teeth, "milling teeth (number of teeth)")
        object.__setattr__(self, "teeth", n)
        object.__setattr__(self, "diameter", check_positive(self.diameter, "milling diameter", "m"))
        object.__setattr__(self, "Kt", check_nonneg(self.Kt, "milling Kt", "N/m^2"))
        object.__setattr__(self, "Kn", check_finite(self.Kn, "milling Kn", "N/m^2"))
        object.__setattr__(self, "Kte", check_finite(self.Kte, "milling Kte", "N/m"))
        object.__setattr__(self, "Kne", check_finite(self.Kne, "milling Kne", "N/m"))
        rpm = check_nonneg(self.rpm, "milling rpm", "rpm")
        object.__setattr__(self, "rpm", check_spindle_speed(rpm, "milling rpm") if rpm else 0.0)
        a = check_finite(self.entry, "milling entry angle", "rad")
        b = check_finite(self.exit, "milling exit angle", "rad")
        tol = 1e-12
        if not (-tol <= a and b <= math.pi + tol):
            raise InputError(
                f"milling entry and exit angles must lie within [0, pi] rad (0 deg to 180 deg); "
                f"got entry {_show(a)}, exit {_show(b)} rad"
            )
        if not a < b:
            raise InputError(
                f"milling entry angle {_show(a)} rad is not before the exit angle {_show(b)} rad;"
                " give entry < exit (or a radial immersion with up/down milling)"
            )
        object.__setattr__(self, "entry", min(max(a, 0.0), math.pi))
        object.__setattr__(self, "exit", min(max(b, 0.0), math.pi))
        beta = check_finite(self.helix, "milling helix angle", "rad")
        if not 0.0 <= beta < math.pi / 2:
            raise InputError(f"milling helix angle must be in [0, pi/2) rad (got {_show(beta)} rad)")
        if beta > math.radians(HELIX_MAX_DEG) * (1 + 1e-12):
            raise InputError(
                f"milling helix angle (helix_deg) must be at most {HELIX_MAX_DEG:g} deg (got"
                f" {math.degrees(beta):.6g} deg); end mills have up to about 60 deg, and towards 90 deg"
                " the flute wraps the tool without bound"
            )
        object.__setattr__(self, "helix", beta)
        if self.pitch is None or len(self.pitch) == 0:
            p = tuple([TWO_PI / n] * n)
            object.__setattr__(self, "pitch", ())
        else:
            try:
                p = tuple(
                    float(check_positive(v, f"milling pitch[{i}]", "rad")) for i, v in enumerate(self.pitch)
                )
            except TypeError:
                raise InputError(f"milling pitch must be a list of {n} angles (got {self.pitch!r})") from None
            if len(p) != n:
                raise InputError(
                    f"milling pitch has {len(p)} angles but the cutter has {n} teeth; give one pitch angle per tooth"
                )
            total = sum(p)
            if abs(total - TWO_PI) > 1e-9 * TWO_PI:
                raise InputError(
                    f"milling pitch angles sum to {math.degrees(total):.6g} deg; they must sum to 360 deg (2 pi rad)"
                )
            # store exactly 2 pi in total: the last angle takes the rounding
            p = p[:-1] + (TWO_PI - sum(p[:-1]),) if n > 1 else (TWO_PI,)
            object.__setattr__(self, "pitch", p)
        lag = [0.0]
        for v in p[1:]:
            lag.append(lag[-1] + v)
        object.__setattr__(self, "_angles", tuple(lag))

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_cut(cls, cut: Any, rpm: float = 0.0) -> Milling:
        """The cutter a model file describes (:class:`chatterlab.model.MillingCut`,
        ``[process] kind = "milling"``) at its default spindle speed ``rpm``."""
        return cls(
            cut.teeth,
            cut.diameter,
            cut.Kt,
            cut.Kn,
            cut.entry,
            cut.exit,
            pitch=cut.pitch,
            helix=cut.helix,
            Kte=cut.Kte,
            Kne=cut.Kne,
            rpm=rpm,
        )

    @classmethod
    def from_immersion(
        cls,
        teeth: int,
        diameter: float,
        Kt: float,
        Kn: float,
        radial_immersion: float,
        mode: Literal["up", "down"] = "down",
        **kw: object,
    ) -> Milling:
        """A cut of radial immersion a_e / D in (0, 1] in up- or down-milling.

        Down-milling: entry = arccos(2 a_e/D - 1), exit = pi; up-milling:
        entry = 0, exit = arccos(1 - 2 a_e/D) (Insperger & Stepan 2004).
        """
        r = check_finite(radial_immersion, "milling radial immersion a_e/D")
        if not 0.0 < r <= 1.0:
            raise InputError(
                f"milling radial immersion a_e/D must be in (0, 1] (got {_show(r)}); a_e is at most the diameter"
            )
        if mode == "down":
            entry, exit_ = math.acos(2.0 * r - 1.0), math.pi
        elif mode == "up":
            entry, exit_ = 0.0, math.acos(1.0 - 2.0 * r)
        else:
            raise InputError(f"milling mode must be 'up' or 'down' (got {mode!r})")
        return cls(teeth, diameter, Kt, Kn, entry, exit_, **kw)  # type: ignore[arg-type]

    # ------------------------------------------------------------------ kinematics
    @property
    def pitches(self) -> np.ndarray:
        """The N pitch angles, rad (uniform ones when ``pitch`` is empty)."""
        return np.array(self.pitch) if self.pitch else np.full(self.teeth, TWO_PI / self.teeth)

    @property
    def uniform(self) -> bool:
        """True when the pitch is uniform (one delay)."""
        p = self.pitches
        return bool(np.all(np.abs(p - TWO_PI / self.teeth) <= 1e-12 * TWO_PI))

    @property
    def lags(self) -> np.ndarray:
        """Angle by which each tooth trails tooth 0, rad, shape (N,)."""
        return np.array(self._angles)

    @staticmethod
    def omega(rpm: float) -> float:
        """Spindle speed in rad/s from rpm."""
        return TWO_PI * check_spindle_speed(rpm) / 60.0

    def tooth_period(self, rpm: float) -> float:
        """tau = 60 / (N n), s: the delay of a uniform-pitch cutter (the mean
        delay of a variable pitch)."""
        return float(tooth_period(check_spindle_speed(rpm), self.teeth))

    def period(self, rpm: float) -> float:
        """Principal period of the coefficients, s: tau (uniform pitch) or 60/n."""
        return self.tooth_period(rpm) if self.uniform else float(tooth_period(check_spindle_speed(rpm)))

    # ------------------------------------------------------------------ speed <-> delay
    # the process kinematics every lobe result keeps (as chatterlab.model.Process does)
    kind = "milling"
    speed_unit = "rpm"
    speed_name = "spindle speed"
    width_name = "axial depth of cut a_p"
    limit_name = "a_lim"
    min_delay = 0.0

    def delay(self, rpm: float | np.ndarray | None = None) -> float | np.ndarray:
        """The tooth period 60 / (N n), s, at n rpm (default: :attr:`rpm`)."""
        n = np.asarray(self.rpm if rpm is None else rpm, dtype=float)
        out = tooth_period(n, self.teeth)
        return float(out) if np.ndim(out) == 0 else out

    def speed_for_delay(self, T: float | np.ndarray) -> float | np.ndarray:
        """The spindle speed (rpm) whose tooth period is T (s)."""
        out = spindle_speed_for(np.asarray(T, dtype=float), self.teeth)
        return float(out) if np.ndim(out) == 0 else out

    def delays(self, rpm: float) -> np.ndarray:
        """tau_j = pitch_j / Omega, s, shape (N,)."""
        return self.pitches / self.omega(rpm)

    def tooth_angles(self, t: float | np.ndarray, rpm: float) -> np.ndarray:
        """Angular position of each tooth at time t (s), in [0, 2 pi), shape (..., N)."""
        ta = np.asarray(t, dtype=float)
        phi = self.omega(rpm) * ta[..., None] - self.lags
        return np.mod(phi, TWO_PI)

    def in_cut(self, phi: np.ndarray) -> np.ndarray:
        """g(phi): True where entry < phi (mod 2 pi) < exit."""
        p = np.mod(np.asarray(phi, dtype=float), TWO_PI)
        return (p > self.entry) & (p < self.exit)

    # ------------------------------------------------------------------ directional matrices
    def directional(self, t: float | np.ndarray, rpm: float, depth: float | None = None) -> np.ndarray:
        """Per-tooth directional matrices H_j(t), N/m^2, shape (..., N, 2, 2).

        Zero for a tooth out of the cut.  The regenerative cutting force on
        the tool is F(t) = -a_p sum_j H_j(t) [r(t) - r(t - tau_j)] (Eq. 1 of
        the module docstring).  With a helix angle, ``depth`` (a_p, m) is
        needed: H_j is then the mean over the lag angles of the flute.
        """
        phi = self.tooth_angles(t, rpm)
        psi = self.lag_angle(depth)
        if psi == 0.0:
            return _h(phi, self.Kt, self.Kn) * self.in_cut(phi)[..., None, None]
        return (self.windowed_integral(phi - psi, phi)) / psi

    def directional_on(
        self, t: np.ndarray, rpm: float, t_inside: float, depth: float | None = None
    ) -> np.ndarray:
        """H_j(t) continued from the piece between breakpoints that holds
        ``t_inside``: which teeth cut is decided at ``t_inside``, so at a
        breakpoint this is the one-sided limit from that piece (what a
        collocation node at an element's end needs).  Shape (..., N, 2, 2).
        With a helix the coefficients are continuous and this is
        :meth:`directional`."""
        if self.lag_angle(depth) > 0.0:
            return self.directional(t, rpm, depth)
        g = self.in_cut(self.tooth_angles(t_inside, rpm))
        return _h(self.tooth_angles(t, rpm), self.Kt, self.Kn) * g[..., None, None]

    def lag_angle(self, depth: float | None) -> float:
        """psi_max = 2 a_p tan(beta) / D, rad (0 without helix)."""
        if self.helix == 0.0:
            return 0.0
        if depth is None:
            raise InputError("milling with a helix angle: give the axial depth of cut a_p (depth, m)")
        a = check_nonneg(depth, "depth of cut a_p", "m")
        psi = 2.0 * a * math.tan(self.helix) / self.diameter
        if not psi <= LAG_MAX:  # the cost estimate, before the work: a window per turn of the flute
            hmax = math.degrees(math.atan(LAG_MAX * self.diameter / (2.0 * a)))
            raise InputError(
                f"milling helix: over a_p = {a * 1e3:.4g} mm the flute wraps the tool"
                f" {psi / TWO_PI:.3g} times (2 a_p tan(helix) / D = {psi:.3g} rad, D = {self.diameter * 1e3:.4g}"
                f" mm); at most {LAG_MAX / TWO_PI:g} turns are computed: helix_deg must be at most {hmax:.4g}"
                " deg at this depth and diameter (check the diameter's unit: m)"
            )
        return psi

    def windowed_integral(self, lo: np.ndarray, hi: np.ndarray, primitive: Any = None) -> np.ndarray:
        """int_lo^hi g(phi) f(phi) dphi for lo <= hi (unwrapped angles), g the
        cutting windows [entry + 2 pi k, exit + 2 pi k]: f = H, the directional
        matrix, by default (shape (..., 2, 2)); else ``primitive(phi)``, an
        antiderivative of a 2 pi periodic f (shape (..., *S)), evaluated at the
        angles reduced into each window."""
        lo = np.asarray(lo, dtype=float)
        hi = np.asarray(hi, dtype=float)
        if primitive is None:

            def primitive(p: np.ndarray) -> np.ndarray:
                return _primitive(p, self.Kt, self.Kn)

        # first window [entry + 2 pi k, exit + 2 pi k] ending after lo
        k0 = np.floor((lo - self.exit) / TWO_PI) + 1.0
        k1 = np.floor((hi - self.entry) / TWO_PI)  # last window starting before hi
        kmax = int(np.max(k1 - k0)) + 1 if k1.size else 0
        shape = np.broadcast(lo, hi).shape
        out = np.zeros(shape + np.shape(primitive(np.zeros(shape)))[len(shape) :])
        for i in range(max(kmax, 0)):
            k = k0 + i
            a = np.maximum(lo, self.entry + TWO_PI * k)
            b = np.minimum(hi, self.exit + TWO_PI * k)
            ok = (b > a) & (k <= k1)
            # the primitive at angles reduced into the window: f is 2 pi periodic, its primitive
            # need not be (H's phi/2 terms), so evaluate relative to the window's start
            d = primitive(b - TWO_PI * k) - primitive(a - TWO_PI * k)
            out += np.where(ok.reshape(ok.shape + (1,) * (d.ndim - ok.ndim)), d, 0.0)
        return out

    def directional_mean(self, t0: float | np.ndarray, t1: float | np.ndarray, rpm: float) -> np.ndarray:
        """Mean of H_j over [t0, t1] (t1 > t0), exactly, shape (..., N, 2, 2).

        The mean over a step is what semi-discretisation uses for its
        piecewise-constant coefficients (Insperger & Stepan 2004).
        Helix: not included (use :meth:`directional` with ``depth``).
        """
        w = self.omega(rpm)
        t0 = np.asarray(t0, dtype=float)
        t1 = np.asarray(t1, dtype=float)
        lo = w * t0[..., None] - self.lags
        hi = w * t1[..., None] - self.lags
        dphi = (hi - lo)[..., None, None]
        return self.windowed_integral(lo, hi) / dphi

    def zoa(self) -> np.ndarray:
        """Averaged directional matrix H0 = (N / 2 pi) int_entry^exit H dphi, N/m^2, (2, 2).

        The mean of sum_j H_j(t) over a revolution: the zeroth-order
        approximation's force is F = -a_p H0 [r(t) - r(t - tau)] (uniform
        pitch).  Altintas & Budak's [A0] = -2 H0 / K_t.
        """
        P = _primitive(np.array([self.entry, self.exit]), self.Kt, self.Kn)
        return self.teeth / TWO_PI * (P[1] - P[0])

    def breakpoints(self, rpm: float, depth: float | None = None) -> np.ndarray:
        """Times in [0, period) where a tooth enters or leaves the cut, s (sorted).

        Between consecutive breakpoints the coefficients H_j(t) are smooth
        (analytic).  With a helix, also where the flute's last point enters
        or leaves (entry/exit + psi_max).
        """
        T = self.period(rpm)
        w = self.omega(rpm)
        psi = self.lag_angle(depth)
        edges = [self.entry, self.exit] + ([self.entry + psi, self.exit + psi] if psi > 0 else [])
        ts = [(e + lag) / w for e in edges for lag in self.lags]
        tb = np.mod(np.array(ts), T)
        tb[np.isclose(tb, T, rtol=0, atol=1e-13 * T)] = 0.0
        tb = np.unique(tb)
        if tb.size > 1:
            keep = np.r_[True, np.diff(tb) > 1e-12 * T]
            tb = tb[keep]
        return tb

    # ------------------------------------------------------------------ forces (time domain)
    def tooth_forces(self, phi: np.ndarray, chip: np.ndarray, depth: float) -> np.ndarray:
        """Forces on the tool from each tooth, N, shape (..., N, 2).

        ``phi``: tooth angles (..., N), rad; ``chip``: chip thickness h_j, m.
        A tooth out of the cut, or with h_j <= 0 (it has left the material),
        carries no force; otherwise F_t = K_t a_p h + K_te a_p and
        F_n = K_n a_p h + K_ne a_p along -(cos phi, -sin phi) and
        -(sin phi, cos phi).
        """
        phi = np.asarray(phi, dtype=float)
        h = np.asarray(chip, dtype=float)
        on = self.in_cut(phi) & (h > 0)
        Ft = np.where(on, depth * (self.Kt * h + self.Kte), 0.0)
        Fn = np.where(on, depth * (self.Kn * h + self.Kne), 0.0)
        s, c = np.sin(phi), np.cos(phi)
        return np.stack([-Ft * c - Fn * s, Ft * s - Fn * c], axis=-1)

    @staticmethod
    def chip_direction(phi: np.ndarray) -> np.ndarray:
        """Unit vector (sin phi, cos phi) from the tool's axis to the tooth, (..., 2).

        The chip thickness of a tooth is h = f_z sin phi + chip_direction . (r(t) - r(t - tau_j)).
        """
        phi = np.asarray(phi, dtype=float)
        return np.stack([np.sin(phi), np.cos(phi)], axis=-1)
