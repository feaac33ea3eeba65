"""Milling in the time domain: the Newmark scheme with the rotating cutting
force, the tooth leaving the cut, multiple regeneration and runout.

The structure
-------------
Any matrix-level system ``M q'' + C q' + K q = P^T F`` (n coordinates) with
a 2 x n map ``P`` giving the displacement ``r = (x, y) = P q`` of the tool
relative to the workpiece at the tool point (a 1-DOF, the 2-DOF x/y model, a
modal model, a reduced structural model; or a :class:`FrozenSystem` and the
names of the tool-point coordinates).  ``F`` is the cutting force on the
tool; ``P^T F`` is its generalised force (virtual work).

The cut (:class:`chatterlab.process.Milling`, whose sign convention this
module follows: feed along +x, tooth angle phi measured from +y towards +x,
tooth direction n_j = (sin phi_j, cos phi_j), tangential direction
t_j = (cos phi_j, -sin phi_j))
--------------------------------------------------------------------------
Tooth j carries the forces F_t = K_t a_p h_j + K_te a_p and
F_n = K_n a_p h_j + K_ne a_p, i.e. on the tool

    F = - sum_{j cutting} [ a_p (K_t t_j + K_n n_j) h_j + a_p (K_te t_j + K_ne n_j) ],   (1)

and it cuts when entry < phi_j (mod 2 pi) < exit **and** h_j > 0: a tooth
whose chip would be negative has left the material and carries no force.

Multiple regeneration (the surface a tooth meets).  In the workpiece frame
the material left at the tooth's angle phi is bounded by the innermost of
all previous passes of any tooth at that angle (material is gone wherever
any edge went).  Pass k before the current one (k = 1: the preceding tooth,
k = N: the same tooth one revolution earlier, ...) happened d_jk earlier,
d_jk = (pitch_j + pitch_{j-1} + ... + pitch_{j-k+1}) / Omega, when the tool
centre was v_f d_jk behind in the feed direction (v_f = N f_z Omega / 2 pi the
feed speed, f_z the mean feed per tooth) and displaced by r(t - d_jk); the
radius of the edge that made it was R + rho_{j-k} (runout rho, per tooth).
The chip is therefore the smallest distance to the previous edge positions,

    h_j(t) = min_{k=1..K} [ v_f d_jk sin phi_j + rho_j - rho_{j-k}
                             + n_j . (r(t) - r(t - d_jk)) ],                   (2)

the "minimum over previous passes" of the models with the tool leaving the
cut (Balachandran 2001; Insperger, Mann, Stepan & Bayly 2003, whose
period-doubling solutions are computed with this surface memory; Tlusty &
Ismail 1981, the first time-domain model with the tool leaving the cut).  The arc of the tooth is approximated by a circle about
the current centre (no trochoid), as in those references.  K = 4N
passes (four revolutions) by default; the result reports how often the
deepest pass gave the minimum (a sign that K is too small).

The linearised equation (``nonlinear=False``) drops the feed, the edge
forces, the runout, the leaving of the cut and all passes but the first:

    M q'' + C q' + K q = -a_p P^T sum_j H_j(t) P (q(t) - q(t - tau_j)),          (3)

H_j = g_j (K_t t_j + K_n n_j) n_j^T (:meth:`Milling.directional`), the periodic
delay equation the Floquet methods analyse (Insperger & Stepan 2002, 2004).

The scheme
----------
Average-acceleration Newmark (gamma = 1/2, beta = 1/4; the scheme of
:func:`chatterlab.time.newmark`) on a grid of ``N m`` steps per revolution
(``m`` steps per mean tooth period), locked to the revolution, so the delays
of a uniform-pitch cutter fall on the grid (exact delayed values) and those
of a variable-pitch cutter are interpolated by cubic Hermite interpolation
on r and r' (error O(h^4), as in the generic solver).  The force (1) is
implicit: with the effective stiffness factored once per step length, the
new position is q = L z + U F (z = (q, v, a) of the previous step), so the
tool-point position r = r* + Z F with Z = P U (2 x 2); the active teeth and F
follow from a 2 x 2 solve, repeated until the set of teeth with h_j > 0 is
consistent (an active-set iteration; it converges because |Z| ~ beta h^2/m is
small).  The screen g_j jumps where a tooth enters or leaves the arc
[entry, exit]: such instants are substep boundaries (the step is split there,
delayed values by Hermite interpolation) with a restart of the acceleration
from the equation of motion with the new screen, so the scheme stays second
order on the piecewise-smooth coefficients (tested: fitted slope 2).  A
tooth that leaves or re-enters the material inside a step (its active state
differs at the two ends) is located by interpolating h_j linearly to 0, and
the step is split there with the old teeth before and a restart with the new
ones after: without edge forces the force is only kinked there (h_j -> 0),
with them it jumps by a_p (K_te, K_ne), which unlocated would cost one order
(tested: slope 2 with runout and edge forces; without the location the
ratio of successive differences fell to 1.1 in that test).  Cost: a few
small matrix-vector products per step (the delayed values of a whole chunk,
up to the shortest delay, are gathered at once).

Default step (``steps_per_period=None``).  The average-acceleration rule
lengthens the period of a mode of circular frequency w by about
(w h)^2 / 12 (Bathe & Wilson 1976), so (w h)^2/12 <= 1e-3 -- a phase drift
below 2 pi 1e-3 rad per oscillation -- needs w h <= 0.1095, i.e.
m >= w_max tau / 0.1095 with w_max the highest natural frequency of the
structure stiffened by the largest cutting stiffness,
w_max^2 = lambda_max(M^-1 K) + a_p N (K_t^2 + K_n^2)^(1/2) lambda_max(P M^-1 P^T)
(an upper bound); at least 20.

Poincare samples and the verdict
--------------------------------
The tool-point state s_p = (x, y, x'/w_1, y'/w_1) (w_1 the lowest natural
frequency) is sampled once per principal period T of the coefficients (the
tooth period for a uniform pitch without runout, the revolution otherwise).
A forced periodic motion is a fixed point of this map; the differences
d_p = s_{p+1} - s_p then decay like mu^p, mu the critical Floquet multiplier
of the linearised motion.  On the last half of the samples:

* ``growth_per_period``: ln|mu|, mu the dominant eigenvalue of the linear
  map fitted to the delay-embedded deviations (d_p, d_{p+1}) ->
  (d_{p+1}, d_{p+2}) by least squares (Hankel dynamic mode decomposition,
  Schmid 2010; Arbabi & Mezic 2017), each snapshot scaled by its norm,
  singular values below 1e-7 of the largest dropped: exact when the
  deviations are a combination of up to four multipliers (two pairs: the
  x and y modes of a tool); ``growth_error``: its change when fitted to the
  last quarter only; ``growth_slope``: the least-squares slope of ln|d_p|.
* verdict, with D = growth_slope x (number of periods in the window):
  D <= -ln 10 (deviations from the periodic orbit fell tenfold):
  **"stable"**; D >= ln 10 (grew tenfold): **"flip chatter"** when the
  dominant fitted multiplier is real and negative, **"Hopf chatter"** when it
  is complex, "undetermined" when it is real and positive; |D| <= ln 2
  (bounded, neither decaying nor growing: a saturated nonlinear orbit):
  **"stable"** when the differences are below 1e-8 of the samples (a
  converged fixed point); otherwise the chatter frequency f_c -- the
  largest spectral peak of the last half of the vibration farther than two
  resolutions from every harmonic k/T of the forced motion -- decides:
  **"flip chatter"** when f_c is a half harmonic (k + 1/2)/T within two
  resolutions (period doubling: the samples alternate between two points),
  **"Hopf chatter"** otherwise (samples on a closed curve: quasi-periodic);
  "undetermined" without such a peak, and for a linear run there (at the
  limit).  Anything else, or fewer than 20 periods in the window, is
  **"undetermined"** (run longer).  The ratio mean|s_{p+2} - s_p| /
  mean|s_{p+1} - s_p| (0 for an exact period-2 orbit) is reported.

References
----------
.. [1] N. M. Newmark, J. Eng. Mech. Div. ASCE 85(EM3), 67-94, 1959;
   K.-J. Bathe and E. L. Wilson, *Numerical methods in finite element
   analysis*, Prentice Hall 1976 (period error of the trapezoidal rule).
.. [2] B. Balachandran, "Nonlinear dynamics of milling processes",
   Phil. Trans. R. Soc. Lond. A 359 (2001) 793-819 (loss of contact,
   multiple regeneration).
.. [3] T. Insperger, B. P. Mann, G. Stepan, P. V. Bayly, "Stability of
   up-milling and down-milling, part 1: alternative analytical methods",
   Int. J. Mach. Tools Manuf. 43 (2003) 25-34; part 2 (Mann et al.):
   experimental verification, 35-40 (period doubling, the tool leaving the
   cut).
.. [4] T. Insperger, G. Stepan, "Semi-discretization method for delayed
   systems", Int. J. Numer. Meth. Engng 55 (2002) 503-518; "Updated
   semi-discretization method for periodic delay-differential equations
   with discrete delay", 61 (2004) 117-141.
.. [5] Y. Altintas, *Manufacturing Automation*, Cambridge University Press
   2000, ch. 3-4 (the milling force model, runout).
.. [6] P. J. Schmid, "Dynamic mode decomposition of numerical and
   experimental data", J. Fluid Mech. 656 (2010) 5-28; H. Arbabi and
   I. Mezic, "Ergodic theory, dynamic mode decomposition, and computation of
   spectral properties of the Koopman operator", SIAM J. Appl. Dyn. Syst. 16
   (2017) 2096-2126 (the Hankel, delay-embedded variant).
.. [7] J. Tlusty, F. Ismail, "Basic non-linearity in machining chatter",
   Annals of the CIRP 30 (1981) 299-304.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import InputError, check_count, check_nonneg, check_positive, check_speed
from ..process._milling import Milling
from ._history import TimeHistory
from ._options import NewmarkOptions

__all__ = ["MillingSimulation", "simulate_milling", "default_steps_per_period"]

FloatArray = NDArray[Any]
TWO_PI = 2.0 * math.pi
#: (w h)^2 / 12 <= 1e-3: the relative period error of the trapezoidal rule
_WH_MAX = math.sqrt(12.0e-3)
_MIN_WINDOW = 20


# =========================================================================== result


@dataclass(frozen=True, eq=False)
class MillingSimulation(TimeHistory):
    """A milling transient: tool-point vibration, chips, forces, Poincare samples.

    Attributes
    ----------
    t : ndarray (n_t,)
        Times of the grid, s.
    x, y : ndarray (n_t,)
        Tool displacement relative to the workpiece, m.
    vx, vy : ndarray (n_t,)
        Its velocity, m/s.
    Fx, Fy : ndarray (n_t,)
        Cutting force on the tool, N.
    chip : ndarray (N, n_t)
        Chip thickness of each tooth, m (0 where the tooth does not cut); in a
        linear run the dynamic chip n_j . (r(t) - r(t - tau_j)) while in the arc.
    would_be_chip : ndarray (N, n_t)
        Eq. (2) while the tooth is in the arc [entry, exit] (negative: the tooth
        has left the material), NaN outside the arc.
    poincare_t : ndarray (n_p,)
        Times of the Poincare samples (multiples of ``sample_period``), s.
    poincare : ndarray (n_p, 4)
        Samples (x, y, vx, vy) at those times, m and m/s.
    sample_period : float
        The period of the coefficients sampled, s.
    growth_per_period : float
        ln|mu| of the dominant multiplier fitted to the Poincare samples
        (per ``sample_period``); NaN when it cannot be estimated.
    growth_error : float
        Its change when fitted to the last quarter of the run only: the
        uncertainty of the fit (not of the time step).
    growth_slope : float
        Least-squares slope of ln|s_{p+1} - s_p| over the analysed window.
    multiplier : complex
        The fitted dominant multiplier mu.
    verdict : str
        "stable", "Hopf chatter", "flip chatter" or "undetermined".
    reason : str
        Why (the rule and the numbers it used).
    chatter_frequency : float
        Largest spectral peak away from the harmonics of 1 / ``sample_period``,
        Hz (NaN when stable or undetermined).
    fraction_out_of_cut : float
        Fraction of the time a tooth is in the arc but has left the material
        (h <= 0), over the analysed window.
    """

    #: the histories shared with every time result (spectrum, growth, CSV, netCDF: TimeHistory)
    history_fields: ClassVar[dict[str, tuple[str, str]]] = {
        "x": ("m", "tool displacement x relative to the workpiece"),
        "y": ("m", "tool displacement y relative to the workpiece"),
        "vx": ("m/s", "tool velocity x"),
        "vy": ("m/s", "tool velocity y"),
        "Fx": ("N", "cutting force on the tool x"),
        "Fy": ("N", "cutting force on the tool y"),
        "chip": ("m", "chip thickness of tooth"),
    }

    t: FloatArray
    x: FloatArray
    y: FloatArray
    vx: FloatArray
    vy: FloatArray
    Fx: FloatArray
    Fy: FloatArray
    chip: FloatArray
    would_be_chip: FloatArray
    poincare_t: FloatArray
    poincare: FloatArray
    sample_period: float
    growth_per_period: float
    growth_error: float
    growth_slope: float
    multiplier: complex
    verdict: str
    reason: str
    chatter_frequency: float
    fraction_out_of_cut: float
    rpm: float
    depth: float
    feed: float
    nonlinear: bool
    steps_per_period: int
    h: float
    status: str
    message: str
    wall_time: float
    time_per_revolution: float
    attrs: dict[str, Any] = field(default_factory=dict)

    @property
    def tooth_passing_frequency(self) -> float:
        """N n / 60, Hz."""
        return float(self.attrs.get("teeth", 1)) * self.rpm / 60.0

    def file_attrs(self) -> dict[str, Any]:
        """The files' global attributes: the run's status and the cut."""
        return {
            **super().file_attrs(),
            "title": "chatterlab milling simulation",
            "rpm": float(self.rpm),
            "depth_m": float(self.depth),
            "feed_m": float(self.feed),
            "nonlinear": str(self.nonlinear),
            "verdict": self.verdict,
            "growth_per_period": float(self.growth_per_period),
        }

    def plot(self, axes: Any = None) -> Any:  # type: ignore[override]
        """Vibration, forces and the Poincare map; returns the three Axes."""
        import matplotlib.pyplot as plt

        if axes is None:
            fig = plt.figure(figsize=(10, 7), layout="constrained")
            gs = fig.add_gridspec(2, 2)
            axes = [fig.add_subplot(gs[0, 0]), fig.add_subplot(gs[1, 0]), fig.add_subplot(gs[:, 1])]
        a0, a1, a2 = axes
        a0.plot(self.t, 1e6 * self.x, lw=0.6, label="x")
        a0.plot(self.t, 1e6 * self.y, lw=0.6, label="y")
        a0.set_ylabel("tool vibration [µm]")
        a0.set_title(
            f"{self.rpm:.0f} rpm, a_p = {1e3 * self.depth:.3g} mm: {self.verdict} "
            f"(ln|mu| = {self.growth_per_period:.3g} per period)",
            fontsize=9,
        )
        a0.legend(fontsize=8)
        a1.plot(self.t, self.Fx, lw=0.6, label="Fx")
        a1.plot(self.t, self.Fy, lw=0.6, label="Fy")
        a1.set_xlabel("t [s]")
        a1.set_ylabel("cutting force [N]")
        a1.legend(fontsize=8)
        p = self.poincare
        half = p.shape[0] // 2
        c = 0 if np.ptp(p[:, 0]) >= np.ptp(p[:, 1]) else 1  # the coordinate that moves more
        a2.plot(1e6 * p[:half, c], 1e3 * p[:half, 2 + c], ".", ms=3, color="0.7", label="first half")
        a2.plot(1e6 * p[half:, c], 1e3 * p[half:, 2 + c], ".", ms=4, color="C3", label="last half")
        a2.set_xlabel(f"{'xy'[c]} at t = k T [µm]")
        a2.set_ylabel(f"{'xy'[c]}' at t = k T [mm/s]")
        a2.set_title("Poincaré samples", fontsize=9)
        a2.legend(fontsize=8)
        return axes


# =========================================================================== structure


def _matrices(
    structure: Any, tool_point: Any, workpiece_point: Any
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """(M, C, K, P) from a FrozenSystem (+ names) or a (M, C, K) tuple (+ P)."""
    if hasattr(structure, "dof") and hasattr(structure, "A"):
        M, C, K = (np.asarray(getattr(structure, a), dtype=float) for a in "ABC")
        if tool_point is None or isinstance(tool_point, str) or len(tool_point) != 2:
            raise InputError(
                "simulate_milling on a FrozenSystem: give tool_point=('tool.x', 'tool.y'), the names of "
                "the tool point's x and y (feed along x)"
            )
        P = np.array([structure.dof(str(s)) for s in tool_point], dtype=float)
        if workpiece_point is not None:
            if isinstance(workpiece_point, str) or len(workpiece_point) != 2:
                raise InputError("workpiece_point must name two coordinates, e.g. ('part.x', 'part.y')")
            P = P - np.array([structure.dof(str(s)) for s in workpiece_point], dtype=float)
        return M, C, K, P
    try:
        M, C, K = (np.asarray(a, dtype=float) for a in structure)
    except (TypeError, ValueError):
        raise InputError(
            "structure must be a FrozenSystem or a tuple (M, C, K) of n x n mass, damping and stiffness "
            "matrices"
        ) from None
    M, C, K = (np.atleast_2d(a) for a in (M, C, K))
    n = M.shape[0]
    for name, a in (("M", M), ("C", C), ("K", K)):
        if a.shape != (n, n) or not np.all(np.isfinite(a)):
            raise InputError(
                f"structure {name} must be a finite {n} x {n} matrix like M (got shape {a.shape})"
            )
    if tool_point is None:
        if n > 2:
            raise InputError(
                f"structure has {n} coordinates: give tool_point, the 2 x {n} map P with (x, y) = P q"
            )
        P = np.eye(2)[:, :n]
    else:
        P = np.asarray(tool_point, dtype=float)
        if P.ndim == 1 and n == 1 and P.size == 2:
            P = P.reshape(2, 1)
        if P.shape != (2, n) or not np.all(np.isfinite(P)):
            raise InputError(
                f"tool_point must be a finite 2 x {n} matrix P with (x, y) = P q (got shape {P.shape})"
            )
    return M, C, K, P


def _natural_frequencies(M: FloatArray, K: FloatArray) -> FloatArray:
    from scipy.linalg import eigh, eigvals

    try:
        lam = eigh(K, M, eigvals_only=True) if np.allclose(K, K.T) and np.allclose(M, M.T) else None
    except np.linalg.LinAlgError:
        lam = None
    if lam is None:
        lam = np.real(eigvals(np.linalg.solve(M, K)))
    return np.sqrt(np.clip(lam, 0.0, None))


def default_steps_per_period(
    structure: Any,
    milling: Milling,
    rpm: float,
    depth: float,
    *,
    tool_point: Any = None,
    workpiece_point: Any = None,
) -> int:
    """Steps per tooth period m giving a period error (w h)^2/12 <= 1e-3 at the
    highest mode stiffened by the cut (see the module docstring); at least 20."""
    M, _, K, P = _matrices(structure, tool_point, workpiece_point)
    return _default_m(M, K, P, milling, rpm, depth)


def _default_m(
    M: FloatArray, K: FloatArray, P: FloatArray, milling: Milling, rpm: float, depth: float
) -> int:
    w2 = float(np.max(_natural_frequencies(M, K))) ** 2
    comp = float(np.max(np.linalg.eigvalsh(P @ np.linalg.solve(M, P.T))))
    w2 += depth * milling.teeth * math.hypot(milling.Kt, milling.Kn) * comp
    tau = 60.0 / (milling.teeth * rpm)
    return max(20, int(math.ceil(math.sqrt(w2) * tau / _WH_MAX)))


# =========================================================================== setup


#: the cut at a point: (teeth in the arc, c_x, c_y, e_x, e_y, n_x, n_y), lists over the teeth
_Cut = tuple[list[int], list[float], list[float], list[float], list[float], list[float], list[float]]


@dataclass(frozen=True)
class _Family:
    """Newmark maps of one substep length: r* = PL z, r = r* + Z F, z' = Phi z + Psi F."""

    PL: FloatArray  # (2, 3n)
    Z: tuple[float, float, float, float]
    PhiPsi: FloatArray  # (3n, 3n + 2)


def _family(
    M: FloatArray, C: FloatArray, K: FloatArray, P: FloatArray, hs: float, gam: float, bet: float
) -> _Family:
    n = M.shape[0]
    c0 = 1.0 / (bet * hs * hs)
    c1 = gam / (bet * hs)
    Kinv = np.linalg.inv(c0 * M + c1 * C + K)
    eye = np.eye(n)
    zero = np.zeros((n, n))
    Qt = np.hstack([eye, hs * eye, hs * hs * (0.5 - bet) * eye])
    Vt = np.hstack([zero, eye, hs * (1.0 - gam) * eye])
    dL = Kinv @ (-C @ Vt - K @ Qt)  # L - Qt, without the cancellation of c0 M Qt
    L = Qt + dL
    U = Kinv @ P.T
    Aa = c0 * dL
    Phi = np.vstack([L, Vt + gam * hs * Aa, Aa])
    Psi = np.vstack([U, gam * hs * c0 * U, c0 * U])
    Z = P @ U
    return _Family(
        PL=np.ascontiguousarray(P @ L),
        Z=(float(Z[0, 0]), float(Z[0, 1]), float(Z[1, 0]), float(Z[1, 1])),
        PhiPsi=np.ascontiguousarray(np.hstack([Phi, Psi])),
    )


@dataclass
class _Pattern:
    """The substep points of one revolution (periodic), with the cut's data."""

    step: FloatArray  # (E,) step 1..n_rev whose interval holds the point
    theta: FloatArray  # (E,) position in the step, (0, 1]
    fam: list[int]
    restart: list[bool]
    grid: list[bool]
    g_left: FloatArray  # (E, N) bool: in the arc on the substep ending at the point
    left: list[list[int]]  # teeth in the arc on the substep ending at the point
    right: list[list[int]]  # ... on the substep starting there
    sin: FloatArray  # (E, N)
    cos: FloatArray
    first: FloatArray  # (n_rev,) index of the first point of each step
    count: FloatArray  # (n_rev,)
    hs: list[float]  # substep length (in steps) of each family


def _pattern(milling: Milling, n_rev: int, omega: float, h: float) -> _Pattern:
    N = milling.teeth
    lags = milling.lags
    T_rev = TWO_PI / omega
    off: dict[int, list[float]] = {}
    for edge in (milling.entry, milling.exit):
        for lag in lags:
            u = (math.fmod((edge + lag) / omega, T_rev) % T_rev) / h
            k = round(u)
            if abs(u - k) <= 1e-6:
                continue  # within 1e-6 h of a grid point: taken as on it (a tinier substep loses digits)  # on the grid: found by comparing the screens of neighbouring steps
            off.setdefault(int(math.floor(u)) + 1, []).append(u - math.floor(u))
    steps: list[int] = []
    thetas: list[float] = []
    for s in range(1, n_rev + 1):
        for th in sorted(set(off.get(s, []))):
            steps.append(s)
            thetas.append(th)
        steps.append(s)
        thetas.append(1.0)
    step = np.array(steps)
    theta = np.array(thetas)
    prev = np.where(np.r_[True, step[1:] != step[:-1]], 0.0, np.r_[0.0, theta[:-1]])
    hs_rel = theta - prev
    mid = (step - 1 + 0.5 * (prev + theta)) * h
    t_pt = (step - 1 + theta) * h
    phi_mid = omega * mid[:, None] - lags
    g_left = milling.in_cut(phi_mid)
    g_right = np.roll(g_left, -1, axis=0)
    phi = omega * t_pt[:, None] - lags
    fams: dict[float, int] = {}
    fam = []
    for v in np.round(hs_rel, 12):
        fam.append(fams.setdefault(float(v), len(fams)))
    first = np.searchsorted(step, np.arange(1, n_rev + 1))
    count = np.bincount(step - 1, minlength=n_rev)
    teeth = np.arange(N)
    return _Pattern(
        step=step,
        theta=theta,
        fam=fam,
        g_left=g_left,
        restart=[bool(v) for v in np.any(g_left != g_right, axis=1)],
        grid=[bool(v) for v in theta == 1.0],
        left=[teeth[g].tolist() for g in g_left],
        right=[teeth[g].tolist() for g in g_right],
        sin=np.sin(phi),
        cos=np.cos(phi),
        first=first,
        count=count,
        hs=list(fams),
    )


def _hermite(s: FloatArray, h: float) -> tuple[FloatArray, ...]:
    """Weights of r_b, r'_b, r_b+1, r'_b+1 for r(t_b + s h) (cubic Hermite)."""
    s2 = s * s
    s3 = s2 * s
    return 2 * s3 - 3 * s2 + 1, h * (s3 - 2 * s2 + s), -2 * s3 + 3 * s2, h * (s3 - s2)


# =========================================================================== entry point


def simulate_milling(
    structure: Any,
    milling: Milling,
    rpm: float,
    depth: float,
    *,
    feed: float = 0.0,
    revolutions: float = 50.0,
    steps_per_period: int | None = None,
    nonlinear: bool = True,
    tool_point: Any = None,
    workpiece_point: Any = None,
    runout: ArrayLike | None = None,
    passes: int | None = None,
    q0: ArrayLike | None = None,
    v0: ArrayLike | None = None,
    options: NewmarkOptions | None = None,
) -> MillingSimulation:
    """Simulate milling on a structure: vibration, chips, forces, Poincare verdict.

    Parameters
    ----------
    structure : FrozenSystem or (M, C, K)
        The structure: a frozen system (with ``tool_point`` naming the tool
        point's x and y, e.g. ``("tool.x", "tool.y")``, and optionally
        ``workpiece_point``), or mass [kg], damping [N s/m] and stiffness
        [N/m] matrices (n x n) with ``tool_point`` the 2 x n map ``P``,
        ``(x, y) = P q`` (default: ``[[1], [0]]`` for n = 1, the identity for
        n = 2).
    milling : Milling
        Cutter and cut (teeth, pitch, arc, coefficients). Straight teeth only.
    rpm : float
        Spindle speed, rpm.
    depth : float
        Axial depth of cut a_p, m (>= 0).
    feed : float, default 0
        Mean feed per tooth f_z, m (the static chip f_z sin phi).  Only used
        by the nonlinear model.
    revolutions : float, default 50
        Duration in spindle revolutions.
    steps_per_period : int, optional
        Steps m per (mean) tooth period; ``N m`` steps per revolution.
        Default: :func:`default_steps_per_period` (period error <= 1e-3 at the
        highest mode).
    nonlinear : bool, default True
        True: Eq. (1)-(2) (feed, edge forces, runout, leaving the cut, multiple
        regeneration).  False: the linear periodic delay equation (3).
    runout : array_like (N,), optional
        Radial offset of each tooth's edge, m (nonlinear model only).
    passes : int, optional
        Previous passes K in Eq. (2); default 4N (four revolutions).
    q0, v0 : array_like (n,), optional
        Initial state; history zero before t = 0.  Default zero, except in a
        linear run: a 1 µm tool-point displacement in x and y (q0 = P^+ (1, 1) µm).
    options : NewmarkOptions, optional
        gamma, beta and the divergence limit (|q| beyond it stops the run).

    Returns
    -------
    MillingSimulation

    Raises
    ------
    InputError
        One line naming the argument: non-positive speed, negative depth,
        steps per period not a whole number >= 1, runout of the wrong length,
        a helix angle, bad matrices.

    References
    ----------
    Balachandran (2001); Insperger, Mann, Stepan & Bayly (2003); Insperger &
    Stepan (2002, 2004); Newmark (1959): see the module docstring.
    """
    wall0 = time.perf_counter()
    if not isinstance(milling, Milling):
        raise InputError(f"milling must be a chatterlab Milling (got {type(milling).__name__})")
    if milling.helix != 0.0:
        raise InputError(
            "simulate_milling: helical teeth are not modelled in the time domain (straight teeth only); "
            "set helix = 0"
        )
    rpm = check_speed(rpm, "spindle speed rpm", "rpm")
    depth = check_nonneg(depth, "depth of cut a_p", "m")
    feed = check_nonneg(feed, "feed per tooth f_z", "m")
    revolutions = check_positive(revolutions, "revolutions")
    opts = NewmarkOptions() if options is None else options
    if not isinstance(opts, NewmarkOptions):
        raise InputError(f"options must be a NewmarkOptions (got {type(opts).__name__})")
    M, C, K, P = _matrices(structure, tool_point, workpiece_point)
    n = M.shape[0]
    N = milling.teeth
    try:
        Minv = np.linalg.inv(M)
    except np.linalg.LinAlgError:
        raise InputError("structure: the mass matrix M is singular; give a nonsingular M") from None
    if steps_per_period is None:
        m = _default_m(M, K, P, milling, rpm, depth)
    else:
        m = check_count(steps_per_period, "steps_per_period (steps per tooth period)")
    rho = np.zeros(N)
    if runout is not None:
        rho = np.asarray(runout, dtype=float).reshape(-1)
        if rho.size != N or not np.all(np.isfinite(rho)):
            raise InputError(
                f"runout must give one finite radial offset per tooth, {N} values in m (got {rho.size})"
            )
        if not nonlinear:
            rho = np.zeros(N)
    K_pass = 4 * N
    if passes is not None:
        K_pass = check_count(passes, "passes (previous passes in the chip)")
    if not nonlinear:
        K_pass = 1
    if q0 is None and not nonlinear:
        q0 = np.linalg.pinv(P) @ np.array([1e-6, 1e-6])
    q_init = np.zeros(n) if q0 is None else np.asarray(q0, dtype=float).reshape(-1)
    v_init = np.zeros(n) if v0 is None else np.asarray(v0, dtype=float).reshape(-1)
    for name, a in (("q0", q_init), ("v0", v_init)):
        if a.shape != (n,) or not np.all(np.isfinite(a)):
            raise InputError(f"{name} must be a finite vector of {n} values (got shape {a.shape})")

    omega = TWO_PI * rpm / 60.0
    n_rev = N * m
    h = (TWO_PI / omega) / n_rev
    n_total = int(round(revolutions * n_rev))
    need = 8 * (n_total + 1) * (8 + 2 * N)  # history, forces, chips and the result's copies
    if need > opts.max_output_bytes:
        raise InputError(
            f"revolutions = {revolutions:g} at {m} steps per tooth period needs ~{need / 2**30:.3g} GiB "
            f"(limit options.max_output_bytes = {opts.max_output_bytes / 2**30:.3g} GiB); "
            "simulate fewer revolutions or steps"
        )
    periodic_tooth = milling.uniform and (not np.any(rho) or not nonlinear)
    per_sample = m if periodic_tooth else n_rev
    run = _Run(M, C, K, P, Minv, milling, omega, h, n_rev, depth, feed, rho, K_pass, nonlinear, opts)
    status, msg, done = run.integrate(q_init, v_init, n_total)
    wall = time.perf_counter() - wall0
    return _result(
        run, status, msg, done, per_sample, m, rpm, depth, feed, nonlinear, wall, revolutions, n_total
    )


# =========================================================================== the run


class _Run:
    """One integration: the periodic pattern, the history buffers and the step loop."""

    #: locate the instants where a tooth leaves or re-enters the material (h_j = 0)
    locate = True

    def __init__(
        self,
        M: FloatArray,
        C: FloatArray,
        K: FloatArray,
        P: FloatArray,
        Minv: FloatArray,
        milling: Milling,
        omega: float,
        h: float,
        n_rev: int,
        depth: float,
        feed: float,
        rho: FloatArray,
        K_pass: int,
        nonlinear: bool,
        opts: NewmarkOptions,
    ) -> None:
        self.M, self.C, self.K, self.P, self.n = M, C, K, P, M.shape[0]
        self.mill, self.omega, self.h, self.n_rev = milling, omega, h, n_rev
        self.nonlinear, self.opts = nonlinear, opts
        N = milling.teeth
        self.N = N
        pat = _pattern(milling, n_rev, omega, h)
        self.pat = pat
        self.fams = [_family(M, C, K, P, hs * h, opts.gamma, opts.beta) for hs in pat.hs]
        n = self.n
        self.Ra = np.hstack([-Minv @ K, -Minv @ C, Minv @ P.T])  # a = Ra [q, v, F]
        self.Pv = np.ascontiguousarray(np.hstack([np.zeros((2, n)), P, np.zeros((2, n))]))
        # per-point cut coefficients (pattern level): c = a_p (Kt t + Kn n), e = a_p (Kte t + Kne n)
        s, c = pat.sin, pat.cos
        ap, mi = depth, milling
        self.c1 = (ap * (mi.Kt * c + mi.Kn * s)).tolist()
        self.c2 = (ap * (-mi.Kt * s + mi.Kn * c)).tolist()
        if nonlinear:
            self.e1 = (ap * (mi.Kte * c + mi.Kne * s)).tolist()
            self.e2 = (ap * (-mi.Kte * s + mi.Kne * c)).tolist()
        else:
            self.e1 = self.e2 = np.zeros_like(s).tolist()
        self.n1, self.n2 = s.tolist(), c.tolist()
        self.pdata: list[_Cut] = [
            (pat.left[e], self.c1[e], self.c2[e], self.e1[e], self.e2[e], self.n1[e], self.n2[e])
            for e in range(len(pat.left))
        ]
        self.depth = depth
        self.located = 0
        # passes: delay d_jk (in steps), the tooth that made the pass
        pitch = milling.pitches
        D = np.zeros((N, K_pass))
        prev_tooth = np.zeros((N, K_pass), dtype=int)
        for j in range(N):
            acc = 0.0
            for k in range(K_pass):
                acc += pitch[(j - k) % N]
                D[j, k] = acc / omega / h
                prev_tooth[j, k] = (j - k - 1) % N
        Dint = np.floor(D + 1e-9)
        Dfrac = D - Dint
        Dfrac[np.abs(Dfrac) < 1e-9] = 0.0
        self.Dint, self.Dfrac = Dint.astype(int), Dfrac
        self.chunk = max(1, int(math.floor(float(np.min(D)) + 1e-9)))
        self.off0 = int(np.max(Dint)) + 2
        v_f = feed * N * omega / TWO_PI
        # static part of Eq. (2) per pattern point: v_f d_jk sin(phi_j) + rho_j - rho_prev
        self.vf_steps = v_f * (D * h)  # (N, K): feed travelled since pass k
        self.rho_diff = rho[:, None] - rho[prev_tooth]
        self.static = self.vf_steps[None, :, :] * s[:, :, None] + self.rho_diff[None]
        self.K_pass = K_pass
        self.deepest = 0  # points where the deepest pass gave the minimum
        self.active_fail = 0

    # ---------------------------------------------------------------- delayed part of the chip
    def _chunk_s(self, i0: int, L: int) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Point indices (pattern), global steps and s_j (E, N) for steps i0+1 .. i0+L."""
        pat, n_rev = self.pat, self.n_rev
        ps = (np.arange(i0, i0 + L)) % n_rev  # pattern step - 1 of each global step
        start = int(pat.first[ps[0]])
        count = int(np.sum(pat.count[ps]))
        E = pat.step.size
        idx = (start + np.arange(count)) % E
        gstep = i0 + 1 + ((pat.step[idx] - 1 - ps[0]) % n_rev)
        theta = pat.theta[idx]
        # delayed position: u = (gstep - 1 - Dint) + (theta - Dfrac)
        x = theta[:, None, None] - self.Dfrac[None]
        fl = np.floor(x)
        frac = x - fl
        up = frac > 1.0 - 1e-9
        fl = np.where(up, fl + 1.0, fl)
        frac = np.where(up, 0.0, frac)
        base = (gstep[:, None, None] - 1 - self.Dint[None] + fl.astype(int)) + self.off0
        w0, w1, w2, w3 = _hermite(frac, self.h)
        rb, vb = self.rbuf, self.vbuf
        rd = (
            w0[..., None] * rb[base]
            + w1[..., None] * vb[base]
            + w2[..., None] * rb[base + 1]
            + w3[..., None] * vb[base + 1]
        )  # (E, N, K, 2)
        sn, cs = self.pat.sin[idx], self.pat.cos[idx]
        proj = sn[:, :, None] * rd[..., 0] + cs[:, :, None] * rd[..., 1]
        if self.nonlinear:
            cand = self.static[idx] - proj
            arg = np.argmin(cand, axis=2)
            s = np.take_along_axis(cand, arg[..., None], axis=2)[..., 0]
            if self.K_pass > 1:
                self.deepest += int(np.sum((arg == self.K_pass - 1) & pat.g_left[idx]))
        else:
            s = -proj[..., 0]
        return idx, gstep, s

    # ---------------------------------------------------------------- the cut at one instant
    def _point_data(self, t: float, screen: list[int]) -> tuple[_Cut, list[float]]:
        """The cut's data at a time t off the pattern (an instant where a tooth
        leaves or re-enters the material): directions, coefficients and s_j
        (Hermite on the history, as in :meth:`_chunk_s`)."""
        mi, ap, h = self.mill, self.depth, self.h
        phi = self.omega * t - mi.lags
        sn, cs = np.sin(phi), np.cos(phi)
        x = t / h - self.Dint - self.Dfrac
        base = np.floor(x)
        frac = x - base
        idx = base.astype(int) + self.off0
        w0, w1, w2, w3 = _hermite(frac, h)
        rb, vb = self.rbuf, self.vbuf
        rd = (
            w0[..., None] * rb[idx]
            + w1[..., None] * vb[idx]
            + w2[..., None] * rb[idx + 1]
            + w3[..., None] * vb[idx + 1]
        )
        proj = sn[:, None] * rd[..., 0] + cs[:, None] * rd[..., 1]
        stat = self.vf_steps * sn[:, None] + self.rho_diff
        sj = np.min(stat - proj, axis=1).tolist()
        cut = (
            screen,
            (ap * (mi.Kt * cs + mi.Kn * sn)).tolist(),
            (ap * (-mi.Kt * sn + mi.Kn * cs)).tolist(),
            (ap * (mi.Kte * cs + mi.Kne * sn)).tolist(),
            (ap * (-mi.Kte * sn + mi.Kne * cs)).tolist(),
            sn.tolist(),
            cs.tolist(),
        )
        return cut, sj

    # ---------------------------------------------------------------- force at a point
    def _force(
        self,
        d: _Cut,
        sj: list[float],
        r1s: float,
        r2s: float,
        Z: tuple[float, float, float, float],
        guess: tuple[float, float],
        fixed: list[int] | None = None,
    ) -> tuple[float, float, float, float, list[int]]:
        """Implicit force: F with r = r* + Z F, the active teeth consistent with
        h > 0 (or the teeth ``fixed``); returns F, r and the active teeth."""
        screen, c1, c2, e1, e2, n1, n2 = d
        z11, z12, z21, z22 = Z
        iterate = self.nonlinear and fixed is None
        if fixed is not None:
            act = fixed
        elif self.nonlinear:
            g1, g2 = guess
            ra1 = r1s + z11 * g1 + z12 * g2
            ra2 = r2s + z21 * g1 + z22 * g2
            act = [j for j in screen if n1[j] * ra1 + n2[j] * ra2 + sj[j] > 0.0]
        else:
            act = screen
        for _ in range(2 * self.N + 3):
            W11 = W12 = W21 = W22 = b1 = b2 = 0.0
            for j in act:
                W11 += c1[j] * n1[j]
                W12 += c1[j] * n2[j]
                W21 += c2[j] * n1[j]
                W22 += c2[j] * n2[j]
                b1 += c1[j] * sj[j] + e1[j]
                b2 += c2[j] * sj[j] + e2[j]
            A11 = 1.0 + W11 * z11 + W12 * z21
            A12 = W11 * z12 + W12 * z22
            A21 = W21 * z11 + W22 * z21
            A22 = 1.0 + W21 * z12 + W22 * z22
            g1 = -(W11 * r1s + W12 * r2s + b1)
            g2 = -(W21 * r1s + W22 * r2s + b2)
            det = A11 * A22 - A12 * A21
            F1 = (A22 * g1 - A12 * g2) / det
            F2 = (A11 * g2 - A21 * g1) / det
            ra1 = r1s + z11 * F1 + z12 * F2
            ra2 = r2s + z21 * F1 + z22 * F2
            if not iterate:
                break
            new = [j for j in screen if n1[j] * ra1 + n2[j] * ra2 + sj[j] > 0.0]
            if new == act:
                break
            act = new
        else:
            self.active_fail += 1
        return F1, F2, ra1, ra2, act

    def _explicit_force(
        self, d: _Cut, teeth: list[int], sj: list[float], r1: float, r2: float, test: bool = True
    ) -> tuple[float, float, list[int]]:
        """Force of the teeth ``teeth`` at the known position r (restart, start),
        those with h <= 0 left out in the nonlinear model when ``test``."""
        _, c1, c2, e1, e2, n1, n2 = d
        F1 = F2 = 0.0
        act = []
        for j in teeth:
            hj = n1[j] * r1 + n2[j] * r2 + sj[j]
            if test and self.nonlinear and hj <= 0.0:
                continue
            act.append(j)
            F1 -= c1[j] * hj + e1[j]
            F2 -= c2[j] * hj + e2[j]
        return F1, F2, act

    def _advance(
        self,
        z: FloatArray,
        fm: _Family,
        d: _Cut,
        sj: list[float],
        guess: tuple[float, float],
        fixed: list[int] | None = None,
    ) -> tuple[FloatArray, float, float, float, float, list[int]]:
        """One Newmark (sub)step: the new state, F, r and the active teeth."""
        n = self.n
        rs = np.dot(fm.PL, z)
        F1, F2, r1, r2, act = self._force(d, sj, float(rs[0]), float(rs[1]), fm.Z, guess, fixed)
        w = self.w
        w[: 3 * n] = z
        w[3 * n] = F1
        w[3 * n + 1] = F2
        return np.dot(fm.PhiPsi, w), F1, F2, r1, r2, act

    def _restart(self, z: FloatArray, F1: float, F2: float) -> None:
        """Acceleration from the equation of motion with the force F (in place)."""
        n, wa = self.n, self.wa
        wa[: 2 * n] = z[: 2 * n]
        wa[2 * n] = F1
        wa[2 * n + 1] = F2
        z[2 * n :] = np.dot(self.Ra, wa)

    def _split(
        self,
        z: FloatArray,
        t_a: float,
        hs: float,
        th: float,
        d: _Cut,
        sj: list[float],
        act_a: list[int],
        act_b: list[int],
        changed: list[int],
        guess: tuple[float, float],
    ) -> tuple[FloatArray, float, float, float, float, list[int]]:
        """The substep [t_a, t_a + hs] in which tooth ``changed`` leaves or
        re-enters the material, split at t* = t_a + th hs (h_j linearly
        interpolated to 0): the old set of teeth up to t*, a restart with the
        new one there, the active-set step after."""
        o = self.opts
        t_s = t_a + th * hs
        fm1 = _family(self.M, self.C, self.K, self.P, th * hs, o.gamma, o.beta)
        fm2 = _family(self.M, self.C, self.K, self.P, (1.0 - th) * hs, o.gamma, o.beta)
        d_s, sj_s = self._point_data(t_s, d[0])
        z1, F1, F2, r1, r2, _ = self._advance(z, fm1, d_s, sj_s, guess, fixed=act_a)
        new = [j for j in d[0] if (j in act_b) if j in changed] + [j for j in act_a if j not in changed]
        G1, G2, _ = self._explicit_force(d_s, sorted(new), sj_s, r1, r2, test=False)
        self._restart(z1, G1, G2)
        self.located += 1
        return self._advance(z1, fm2, d, sj, (G1, G2))

    # ---------------------------------------------------------------- the loop
    def integrate(self, q0: FloatArray, v0: FloatArray, n_total: int) -> tuple[str, str, int]:
        n, N, off0, pat, h = self.n, self.N, self.off0, self.pat, self.h
        size = n_total + 1 + off0 + 2
        self.rbuf = np.zeros((size, 2))
        self.vbuf = np.zeros((size, 2))  # r' = P v
        self.F = np.zeros((n_total + 1, 2))
        self.hraw = np.full((n_total + 1, N), np.nan)
        self.w = np.zeros(3 * n + 2)
        self.wa = np.zeros(2 * n + 2)
        P = self.P
        r0, rv0 = P @ q0, P @ v0
        self.rbuf[off0], self.vbuf[off0] = r0, rv0
        # start: the force of the first substep's teeth at r0 (history zero before t = 0)
        idx0, _, s0 = self._chunk_s(-1, 1)  # the point at t = 0 (end of step 0)
        e0 = int(idx0[-1])
        sj0 = s0[-1].tolist()
        pdata = self.pdata
        F1, F2, act_prev = self._explicit_force(pdata[e0], pat.right[e0], sj0, float(r0[0]), float(r0[1]))
        self.F[0] = (F1, F2)
        for j in pat.right[e0]:
            self.hraw[0, j] = pat.sin[e0, j] * r0[0] + pat.cos[e0, j] * r0[1] + sj0[j]
        z = np.concatenate([q0, v0, self.Ra @ np.concatenate([q0, v0, [F1, F2]])])
        Pv, fams = self.Pv, self.fams
        fam, restart, grid, right, theta = pat.fam, pat.restart, pat.grid, pat.right, pat.theta.tolist()
        hs_len = [x * h for x in pat.hs]
        locate = self.nonlinear and self.locate
        d0 = pdata[e0]
        h_prev = [d0[5][j] * r0[0] + d0[6][j] * r0[1] + sj0[j] for j in range(N)]
        t_prev = 0.0
        d_prev, sj_prev, ra_prev = d0, sj0, (float(r0[0]), float(r0[1]))
        dot = np.dot
        limit = float(self.opts.divergence_limit)
        i_done = 0
        guess = (F1, F2)
        while i_done < n_total:
            L = min(self.chunk, n_total - i_done)
            idx, gstep, s = self._chunk_s(i_done, L)
            sl = s.tolist()
            idl = idx.tolist()
            gl = gstep.tolist()
            rbuf, vbuf, Fout, hraw = self.rbuf, self.vbuf, self.F, self.hraw
            for k, e in enumerate(idl):
                fm = fams[fam[e]]
                d = pdata[e]
                sj = sl[k]
                z_a = z
                z, F1, F2, r1, r2, act = self._advance(z_a, fm, d, sj, guess)
                n1, n2 = d[5], d[6]
                if locate:
                    changed = [j for j in d[0] if (j in act_prev) != (j in act)]
                    if changed:
                        th = 1.0
                        for j in changed:
                            hb = n1[j] * r1 + n2[j] * r2 + sj[j]
                            if h_prev[j] != hb:
                                th = min(th, h_prev[j] / (h_prev[j] - hb))
                        if 1e-6 < th < 1.0 - 1e-6:
                            hs = hs_len[fam[e]]
                            z, F1, F2, r1, r2, act = self._split(
                                z_a, t_prev, hs, th, d, sj, act_prev, act, changed, guess
                            )
                        elif th <= 1e-6:
                            # the change happened at t_a itself (a tooth entering the arc with
                            # h = 0 to round-off, e.g. at phi = 0 in a periodic motion): restart
                            # there with the new set and redo the step
                            keep = [j for j in act_prev if j not in changed]
                            new = sorted(keep + [j for j in changed if j in act])
                            G1, G2, _ = self._explicit_force(
                                d_prev, new, sj_prev, ra_prev[0], ra_prev[1], test=False
                            )
                            z_a = z_a.copy()
                            self._restart(z_a, G1, G2)
                            z, F1, F2, r1, r2, act = self._advance(z_a, fm, d, sj, (G1, G2))
                            self.located += 1
                guess = (F1, F2)
                act_prev = act
                if grid[e]:
                    i = gl[k]
                    rbuf[i + off0, 0] = r1
                    rbuf[i + off0, 1] = r2
                    vbuf[i + off0] = dot(Pv, z)
                    Fout[i, 0] = F1
                    Fout[i, 1] = F2
                    for j in d[0]:
                        hraw[i, j] = n1[j] * r1 + n2[j] * r2 + sj[j]
                if restart[e]:
                    G1, G2, act_prev = self._explicit_force(d, right[e], sj, r1, r2)
                    self._restart(z, G1, G2)
                    guess = (G1, G2)
                if locate:
                    h_prev = [n1[j] * r1 + n2[j] * r2 + sj[j] for j in range(N)]
                    t_prev = (gl[k] - 1 + theta[e]) * h
                    d_prev, sj_prev, ra_prev = d, sj, (r1, r2)
            i_new = i_done + L
            block = self.rbuf[i_done + 1 + off0 : i_new + 1 + off0]
            if not np.all(np.isfinite(z)) or not np.all(np.isfinite(block)) or np.max(np.abs(z[:n])) > limit:
                return (
                    "diverged",
                    f"diverged by t = {i_new * self.h:.6g} s (|q| > {limit:.3g} or not finite)",
                    i_done,
                )
            i_done = i_new
        return "ok", "", i_done


# =========================================================================== post-processing


def _dmd(d: FloatArray, rtol: float = 1e-7) -> complex:
    """Dominant multiplier of the linear map fitted to the delay-embedded
    deviations z_p = (d_p, d_{p+1}) -> z_{p+1} (Hankel dynamic mode
    decomposition): several pairs of multipliers, e.g. the x and y modes of a
    2-DOF tool, are resolved (a scalar order-2 Prony fit assumes one pair).
    Each snapshot pair is scaled by |z_p| (the samples span decades);
    singular values below ``rtol`` x the largest are dropped (round-off,
    modes decayed away)."""
    if d.shape[0] < 4:
        return complex("nan")
    Z = np.hstack([d[:-1], d[1:]])  # (n_p - 1, 2k)
    X, Y = Z[:-1].T, Z[1:].T
    scale = np.linalg.norm(X, axis=0)
    ok = scale > 0
    if np.sum(ok) < 3:
        return complex("nan")
    X, Y = X[:, ok] / scale[ok], Y[:, ok] / scale[ok]
    U, S, Vt = np.linalg.svd(X, full_matrices=False)
    r = int(np.sum(S > rtol * S[0]))
    A = U[:, :r].T @ Y @ Vt[:r].T / S[:r]
    ev = np.linalg.eigvals(A)
    return complex(ev[np.argmax(np.abs(ev))])


def _analyse(
    pt: FloatArray, w1: float, nonlinear: bool, fc: float, T: float, res: float, diverged: bool = False
) -> tuple[float, float, float, complex, str, str]:
    """Growth per period, its fit error, slope, multiplier, verdict and reason from the samples
    pt (n_p, 4), the chatter frequency fc (Hz), the sampled period T (s) and the
    spectral resolution res (Hz).  A run that diverged is judged on the
    samples it has (at least 8 periods in the window), and only growth is
    concluded from it."""
    s = pt.copy()
    s[:, 2:] /= w1
    n_p = s.shape[0]
    first = n_p // 2
    win = s[first:]
    d = np.diff(win, axis=0)
    P_w = d.shape[0]
    need = 8 if diverged else _MIN_WINDOW
    if P_w < need:
        return (
            math.nan, math.nan, math.nan, complex("nan"), "undetermined",
            f"run too short: {P_w} periods in the analysed last half (need >= {need}: "
            f"run >= {2 * need + 2} periods)" + (" before it diverged" if diverged else ""),
        )  # fmt: skip
    e = np.linalg.norm(d, axis=1)
    scale = float(np.max(np.linalg.norm(win, axis=1)))
    tiny = 1e-300
    slope = float(np.polyfit(np.arange(P_w), np.log(np.maximum(e, tiny)), 1)[0])
    mu = _dmd(d)
    growth = math.log(abs(mu)) if np.isfinite(abs(mu)) and abs(mu) > 0 else math.nan
    mu_q = _dmd(d[P_w // 2 :])  # the last quarter of the run: the fit's own uncertainty
    g_q = math.log(abs(mu_q)) if np.isfinite(abs(mu_q)) and abs(mu_q) > 0 else math.nan
    g_err = abs(growth - g_q)
    D = slope * P_w
    base = f"over the last {P_w} periods the deviations changed by exp({D:.3g})"
    converged = float(np.max(e[-5:])) <= 1e-8 * max(scale, tiny)
    verdict, reason = _verdict(D, converged, mu, P_w, win, nonlinear, fc, T, res)
    if diverged:
        reason += " (the run diverged)"
        if D < math.log(10.0):
            verdict = "undetermined"
    return growth, g_err, slope, mu, verdict, base + reason


def _verdict(
    D: float,
    converged: bool,
    mu: complex,
    P_w: int,
    win: FloatArray,
    nonlinear: bool,
    fc: float,
    T: float,
    res: float,
) -> tuple[str, str]:
    """The rule of the module docstring: (verdict, the end of the reason)."""
    if D <= -math.log(10.0):
        return "stable", " <= 1/10: the samples converge to a fixed point (periodic motion)"
    if converged:
        return "stable", ": the samples are converged to 1e-8"
    if D >= math.log(10.0):
        tol_angle = math.pi / P_w
        ang = abs(math.atan2(mu.imag, mu.real)) if np.isfinite(abs(mu)) else math.nan
        what = f" >= 10; dominant multiplier {mu:.4g} (|arg| = {ang:.3g} rad)"
        if abs(mu.imag) <= 1e-12 * abs(mu) and mu.real < 0 or ang >= math.pi - tol_angle:
            return "flip chatter", what
        if tol_angle < ang < math.pi - tol_angle:
            return "Hopf chatter", what
        return "undetermined", what + ": real and positive"
    if abs(D) > math.log(2.0):
        return "undetermined", ": neither converged nor steady; run longer"
    if not nonlinear:
        return "undetermined", ": a linear run at the stability limit (|mu| ~ 1)"
    d1 = float(np.mean(np.linalg.norm(win[1:] - win[:-1], axis=1)))
    d2 = float(np.mean(np.linalg.norm(win[2:] - win[:-2], axis=1)))
    bounded = f" (bounded); |s_p+2 - s_p| / |s_p+1 - s_p| = {d2 / d1:.3g}"
    if not math.isfinite(fc):
        return "undetermined", bounded + "; no chatter peak off the harmonics of 1/T"
    if abs(fc * T - math.floor(fc * T) - 0.5) / T <= res:
        return "flip chatter", bounded + f"; chatter at {fc:.6g} Hz, a half harmonic of 1/T"
    return "Hopf chatter", bounded + f"; chatter at {fc:.6g} Hz, not a (half) harmonic of 1/T"


def _chatter_frequency(t: FloatArray, x: FloatArray, y: FloatArray, f_rev: float) -> tuple[float, float]:
    """Largest spectral peak of the last half of x or y (the larger) farther
    than two resolutions from every multiple of ``f_rev`` (the frequency of
    the sampled period: harmonics of the forced periodic motion), Hz, and
    that tolerance (two resolutions), Hz."""
    from ._signals import amplitude_spectrum, peaks

    half = t.size // 2
    if t.size - half < 16:
        return math.nan, math.nan
    tt = t[half:]
    res = 2.0 / (tt[-1] - tt[0])
    sig = x[half:] if np.ptp(x[half:]) >= np.ptp(y[half:]) else y[half:]
    if not np.ptp(sig) > 0:
        return math.nan, res
    f, a = amplitude_spectrum(tt, sig, detrend="constant")
    fp, ap = peaks(f, a, n=30, fmin=0.5 * f_rev)
    for fk, _ in zip(fp, ap, strict=True):
        k = round(fk / f_rev)
        if abs(fk - k * f_rev) > res:
            return float(fk), res
    return math.nan, res


def _result(
    run: _Run, status: str, msg: str, done: int, per_sample: int, m: int, rpm: float, depth: float,
    feed: float, nonlinear: bool, wall: float, revolutions: float, n_total: int,
) -> MillingSimulation:  # fmt: skip
    h, off0 = run.h, run.off0
    k = done + 1
    t = h * np.arange(k)
    r = run.rbuf[off0 : off0 + k]
    rv = run.vbuf[off0 : off0 + k]
    hraw = run.hraw[:k].T.copy()
    chip = np.where(np.isnan(hraw), 0.0, np.maximum(hraw, 0.0)) if nonlinear else np.nan_to_num(hraw)
    ip = np.arange(0, k, per_sample)
    pt = np.column_stack([r[ip], rv[ip]])
    w = _natural_frequencies(run.M, run.K)
    w_pos = w[w > 0]
    w1 = float(np.min(w_pos)) if w_pos.size else TWO_PI * rpm / 60.0
    T = per_sample * h
    fc, res = _chatter_frequency(t, r[:, 0], r[:, 1], 1.0 / T)
    growth, g_err, slope, mu, verdict, reason = _analyse(pt, w1, nonlinear, fc, T, res, status == "diverged")
    if verdict not in ("Hopf chatter", "flip chatter"):
        fc = math.nan
    half = k // 2
    arc = ~np.isnan(hraw[:, half:])
    n_arc = int(np.sum(arc))
    out_frac = float(np.sum(hraw[:, half:][arc] <= 0.0)) / n_arc if n_arc and nonlinear else math.nan
    wall_rev = wall / max(done / run.n_rev, 1e-12)
    notes = [
        f"{done} steps of h = {h:.4g} s ({m} per tooth period) in {wall:.3g} s "
        f"({1e3 * wall_rev:.3g} ms per revolution)"
    ]
    if msg:
        notes.insert(0, msg)
    if run.located:
        notes.append(f"{run.located} instants where a tooth left or re-entered the material located")
    if run.active_fail:
        notes.append(f"active-set iteration not converged at {run.active_fail} points")
    if nonlinear and run.K_pass > 1 and run.deepest:
        notes.append(f"the deepest of {run.K_pass} passes set the chip at {run.deepest} points: raise passes")
    return MillingSimulation(
        t=t,
        x=r[:, 0].copy(),
        y=r[:, 1].copy(),
        vx=rv[:, 0].copy(),
        vy=rv[:, 1].copy(),
        Fx=run.F[:k, 0].copy(),
        Fy=run.F[:k, 1].copy(),
        chip=chip,
        would_be_chip=hraw,
        poincare_t=t[ip],
        poincare=pt,
        sample_period=per_sample * h,
        growth_per_period=growth,
        growth_error=g_err,
        growth_slope=slope,
        multiplier=mu,
        verdict=verdict,
        reason=reason,
        chatter_frequency=fc,
        fraction_out_of_cut=out_frac,
        rpm=rpm,
        depth=depth,
        feed=feed,
        nonlinear=nonlinear,
        steps_per_period=m,
        h=h,
        status=status,
        message="; ".join(notes),
        wall_time=wall,
        time_per_revolution=wall_rev,
        attrs={"teeth": run.N, "passes": run.K_pass, "revolutions": revolutions, "n_steps": n_total},
    )
