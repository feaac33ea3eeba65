"""Stable cuts: the forced vibration of milling and the surface location error,
and the forced response of turning to an eccentric workpiece.

Milling: the periodic forced response
-------------------------------------
Linearised about the nominal path, the cutting force on the tool
(:mod:`chatterlab.process._milling`, Eq. 1, with the static chip f_z sin phi
and the edge forces of :meth:`Milling.tooth_forces`) is

    F(t) = -a_p sum_j H_j(t) [r(t) - r(t - tau_j)] + a_p f(t),                   (1)

    f(t) = -sum_j g_j(t) [H_j(t) (f_z, 0)^T / g_j + K_te t_j + K_ne n_j],          (2)

(t_j = (cos phi_j, -sin phi_j), n_j = (sin phi_j, cos phi_j): the static chip
f_z sin phi_j = n_j . (f_z, 0) is the feed f_z e_x seen through the
directional matrix, H_j (f_z, 0)^T = (K_t t_j + K_n n_j) f_z sin phi_j).  A
stable cut settles on the T-periodic solution of (1); in the spectral-element
discretisation of one period (:class:`SpectralMonodromy`, whose collocation
equations take (2) at the force nodes: :meth:`SpectralMonodromy.forced`) it is
the fixed point of the one-period map z' = X(a_p) z + a_p P (I + a_p K)^-1 f,

    (I - X(a_p)) z* = a_p P (I + a_p K)^-1 f,                                     (3)

the same matrices as the multipliers, the approach of Insperger et al.
(2006) with the semi-discretisation and of SemiDiscretizationMethod.jl's
fixed point.  For a uniform pitch the periodic motion has the tooth period
tau, so r(t) - r(t - tau) = 0: the regenerative term vanishes on the orbit
and the response is the structure's own to f(t), the sum over the harmonics
k N Omega of G(i k N Omega) times f's Fourier coefficients (Schmitz & Mann
2006, their closed form; tests/test_forced_milling.py evaluates it on its
own).  A variable pitch regenerates (the orbit has the revolution's period).

The semi-discretisation's fixed point
------------------------------------
First-order semi-discretisation (:mod:`chatterlab.frequency._floquet_sdm`)
cuts the period into m steps of length h; on step i the coefficients and the
force are replaced by their exact means over the step, the delayed
displacement by its linear interpolant between the grid values, and the step
is solved exactly.  With the state z_i = (x_i, r_{i-1}, ..., r_{i-L}) and
w_i = a_p M^-1 J^T mean_i f on the velocity rows, the step adds to the
multipliers' step z_{i+1} = S_i z_i the forced part
int_0^h e^{A_i (h - s)} ds w_i, so one period is the affine map

    z' = Phi z + c,    (I - Phi) z* = c,                                         (6)

Phi the SD monodromy (the multipliers' own matrix) and c the steps' forced
parts carried to the period's end (Insperger, Gradisek, Kalveram, Stepan,
Winert & Weinert 2006).  The fixed point's error is O(h^2), as the
multipliers': the means leave O(h^3) per step, the interpolation O(h^3)
through the step's integral, over T/h steps O(h^2).  Between the grid points
the orbit is the cubic Hermite interpolant of the displacement and the
velocity (its O(h^4) below the method's O(h^2)); the generation instant of
tooth 0 (phi = 0 or pi) is a grid point of an even number of steps.

The surface location error (SLE)
--------------------------------
The wall of a peripheral cut is generated where a tooth's chip is zero on the
wall's side: at phi_s = 0 (tooth entry) in up-milling, at phi_s = pi (tooth
exit) in down-milling (a slot: the down-milling wall).  At the instant t_s a
tooth passes phi_s, its edge is at r(t_s) + R n(phi_s); the wall is displaced
from the commanded one by the tool's displacement along n(phi_s), the unit
vector from the tool's axis towards the wall:

    SLE = - n(phi_s) . r(t_s)                                                    (4)

positive: undercut (the tool deflected away from the wall, material left
standing); negative: overcut (Insperger, Gradisek, Kalveram, Stepan, Winert &
Weinert 2006; Schmitz & Mann 2006 use the displacement normal to the wall the
same way).  A tool flexible along the feed x only has SLE = 0 at phi_s = 0 or
pi (n is along y).  With several teeth of a variable pitch each has its own
(4); the wall is where the deepest one cut, the smallest SLE.

The wall's profile: the material is gone wherever an edge went.  Along the
wall (coordinate X, the feed direction) each pass of a tooth sweeps the arc
X(t) = v_f t + x(t) + R sin phi_j(t), with the penetration beyond the
commanded wall p(t) = n(phi_s) . r(t) + R cos(phi_j(t) - phi_s) - R; the wall
at X is the deepest p over all passes, and its peak-to-valley is the height
of the cusps between the passes: R - sqrt(R^2 - f_z^2 / 4) ~ f_z^2 / (8 R)
for a rigid tool (the feed marks), changed by the vibration during the
passes.

Turning: the eccentric workpiece
--------------------------------
A workpiece whose stock is eccentric by e (its radius under the tool
R_0 + e cos Omega t) is cut with the width b(t) = b + e cos(Omega t): the
force varies by K_f h_0 e cos(Omega t) (h_0 the feed per revolution), a
harmonic excitation at the spindle frequency that the previous revolution did
not leave in the chip.  The regenerative loop's response to a force at
omega is the closed-loop FRF (chatterlab.frequency.frf on the
:class:`ClosedLoop`), for one degree of freedom

    X(omega) = G(i omega) F / (1 + b K_f (1 - e^{-i omega T}) G(i omega)),        (5)

and at omega = Omega, with T = 2 pi / Omega, e^{-i Omega T} = 1: the delay
term vanishes and |X| = K_f h_0 e |G(i Omega)|.  The runout is not
regenerated because it repeats every revolution: the surface the tool meets
carries the same runout it leaves.  For the same reason a displacement runout
in the chip direction (a spindle whose axis orbits once per revolution)
changes no chip at all in the steady state: the tool-workpiece vibration it
excites is (5) with F = b K_f (1 - e^{-i Omega T}) e = 0, and the surface
is round about the orbiting axis, i.e. it carries the runout e.  The loop's
other terms at Omega (process damping, i Omega V) are kept in (5).

References
----------
T. Insperger, J. Gradisek, M. Kalveram, G. Stepan, K. Winert, K. Weinert,
Machine tool chatter and surface location error in milling processes,
J. Manuf. Sci. Eng. 128 (2006) 913-920.
T. L. Schmitz, B. P. Mann, Closed-form solutions for surface location error
in milling, Int. J. Mach. Tools Manuf. 46 (2006) 1369-1377.
T. Insperger, G. Stepan, Updated semi-discretization method for periodic
delay-differential equations with discrete delay, Int. J. Numer. Meth.
Engng 61 (2004) 117-141.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from functools import partial
from typing import Any, Literal

import numpy as np

from ..errors import InputError, check_count, check_nonneg, check_positive
from ..io._result import Result
from ..model._items import tooth_period
from ..process._loop import ClosedLoop
from ._floquet import Multipliers, chatter_frequency
from ._floquet_sdm import _ranked, check_method, finite_monodromy, matched_change, sdm_forced
from ._floquet_spectral import CHECK_DEGREE, SpectralMonodromy

__all__ = [
    "ForcedResponse",
    "SurfaceLocation",
    "RunoutResponse",
    "forced_response",
    "surface_location",
    "runout_response",
    "generation_angle",
]

TWO_PI = 2.0 * math.pi
#: verdict codes of a speed in :class:`SurfaceLocation` (netCDF/CSV integers)
VERDICTS = ("stable", "unstable", "undetermined")
#: samples along each tooth's pass for the wall's profile
PASS_SAMPLES = 801


def generation_angle(milling: Any) -> float:
    """phi_s: where the wall is generated (the chip zero on the wall's side):
    pi (tooth exit) when the arc ends at pi (down-milling, a slot), 0 (tooth
    entry) when it starts at 0 (up-milling); else InputError (no wall)."""
    if milling.exit >= math.pi - 1e-12:
        return math.pi
    if milling.entry <= 1e-12:
        return 0.0
    raise InputError(
        f"surface location: the cut's arc {math.degrees(milling.entry):.4g}..{math.degrees(milling.exit):.4g} deg"
        " neither starts at 0 deg (up-milling) nor ends at 180 deg (down-milling): it generates no wall;"
        " give a radial immersion with milling = 'up' or 'down'"
    )


def static_load(sm: SpectralMonodromy, feed: float) -> np.ndarray:
    """f of Eq. (2) at the force nodes of ``sm``, per unit depth, in the cut's
    coordinates (N/m, length m_f): the forcing of :meth:`SpectralMonodromy.forced`."""
    milling, rpm = sm.milling, sm.rpm
    t, mid = sm.force_nodes
    if t.size == 0:
        return np.zeros(0)
    H = np.stack([milling.directional_on(t[i : i + 1], rpm, float(mid[i]))[0] for i in range(t.size)])
    # tooth j's static chip is the feed travelled since the tooth before it passed the same angle,
    # f_z p_j / (2 pi / N) (the mean f_z for a uniform pitch)
    feeds = feed * milling.pitches * milling.teeth / TWO_PI
    f = -np.einsum("mja,j->ma", H[..., :, 0], feeds)  # H_j (f_j, 0)^T: the first column
    if milling.Kte or milling.Kne:
        g = milling.in_cut(milling.tooth_angles(mid, rpm))  # (m, N): one-sided at an element's ends
        phi = milling.tooth_angles(t, rpm)
        s, c = np.sin(phi), np.cos(phi)
        f[:, 0] -= np.sum(g * (milling.Kte * c + milling.Kne * s), axis=1)
        f[:, 1] -= np.sum(g * (-milling.Kte * s + milling.Kne * c), axis=1)
    Ub = sm._cut[0]
    return np.ravel(f @ Ub)


def static_load_mean(milling: Any, rpm: float, feed: float, t0: np.ndarray, t1: np.ndarray) -> np.ndarray:
    """f of Eq. (2) averaged exactly over each interval [t0_i, t1_i], per unit depth, in the
    tool's (x, y) (N/m, shape (len(t0), 2)): the forcing of the semi-discretisation, whose
    coefficients are their means over the same steps (:meth:`Milling.directional_mean`)."""
    t0 = np.asarray(t0, dtype=float)
    t1 = np.asarray(t1, dtype=float)
    feeds = feed * milling.pitches * milling.teeth / TWO_PI  # each tooth's static chip, as static_load's
    f = -np.einsum("mja,j->ma", milling.directional_mean(t0, t1, rpm)[..., :, 0], feeds)
    if milling.Kte or milling.Kne:
        # -(K_te t + K_ne n) over the arc, its primitive in phi: -(K_te sin - K_ne cos, K_te cos + K_ne sin)
        Om = milling.omega(rpm)
        lo = Om * t0[:, None] - milling.lags  # (m, N), unwrapped
        hi = Om * t1[:, None] - milling.lags

        def prim(p: np.ndarray) -> np.ndarray:
            s, c = np.sin(p), np.cos(p)
            return -np.stack([milling.Kte * s - milling.Kne * c, milling.Kte * c + milling.Kne * s], axis=-1)

        acc = milling.windowed_integral(lo, hi, prim)
        f += acc.sum(axis=1) / (hi - lo)[:, :1]
    return f


class _SdOrbit:
    """The tool's (x, y) on the semi-discretisation's fixed point (:func:`sdm_forced`): the
    method's own values at the grid points t_i = i dt, between them the cubic Hermite
    interpolant of the displacement and the velocity (error O(dt^4) times the fourth
    derivative, below the method's O(dt^2); O(dt^2) across a step where the force jumps,
    the method's order)."""

    def __init__(self, loop: ClosedLoop, x: np.ndarray, dt: float) -> None:
        n = loop.n
        self.r = x[:, :n] @ loop.J.T  # (m + 1, 2)
        self.v = x[:, n:] @ loop.J.T
        self.dt = dt
        self.m = x.shape[0] - 1
        self.period = self.m * dt

    def __call__(self, t: np.ndarray) -> np.ndarray:
        u = np.mod(np.asarray(t, dtype=float), self.period) / self.dt
        i = np.clip(np.floor(u).astype(int), 0, self.m - 1)
        s = (u - i)[:, None]
        h00, h10 = (1 + 2 * s) * (1 - s) ** 2, s * (1 - s) ** 2
        h01, h11 = s**2 * (3 - 2 * s), s**2 * (s - 1)
        return (
            h00 * self.r[i] + h10 * self.dt * self.v[i] + h01 * self.r[i + 1] + h11 * self.dt * self.v[i + 1]
        )


@dataclass(frozen=True, eq=False)
class ForcedResponse(Result):
    """The periodic forced vibration of a milling cut at one (rpm, a_p) and
    its surface location error (module docstring, Eqs. 3-4).

    Attributes
    ----------
    t : ndarray
        Times over one period of the orbit from a tooth's generation instant, s.
    x, y : ndarray
        The tool's displacement relative to the workpiece on the orbit, m
        (NaN unless the cut is stable).
    sle : float
        Surface location error, m (Eq. 4; positive: undercut); NaN unless
        stable.
    sle_teeth : ndarray
        Eq. (4) for each tooth, m.
    peak_to_valley : float
        Height of the wall's profile between the passes, m.
    angle : float
        The generation angle phi_s, rad (0: up-milling, pi: down-milling).
    multipliers : Multipliers
        The stability of the cut from the same discretisation.
    verdict : str
        ``"stable"``, ``"unstable"`` (chatter: no forced orbit is reached) or
        ``"undetermined"`` (|mu| within its convergence error of 1).
    error : float
        Convergence check of the SLE: its change at the higher resolution
        (spectral: the degree raised by CHECK_DEGREE; sdm: 2 x steps), m
        (NaN without the check).
    """

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    sle: float
    sle_teeth: np.ndarray
    peak_to_valley: float
    angle: float
    multipliers: Multipliers
    verdict: str
    error: float
    rpm: float
    depth: float
    feed: float
    elapsed: float = 0.0

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """The orbit over one period (coordinate ``time``); the SLE, the verdict and the cut as attributes."""
        return (
            {"time": (self.t, "s", "time from a tooth's generation instant")},
            {
                "x": (self.x, "m", "tool displacement x relative to the workpiece (periodic orbit)"),
                "y": (self.y, "m", "tool displacement y relative to the workpiece (periodic orbit)"),
            },
            {
                "title": "chatterlab forced vibration of a milling cut",
                "verdict": self.verdict,
                "sle_m": float(self.sle),
                "sle_error_m": float(self.error),
                "peak_to_valley_m": float(self.peak_to_valley),
                "generation_angle_rad": float(self.angle),
                "spectral_radius": float(self.multipliers.spectral_radius),
                "method": self.multipliers.method,
                "resolution": self.multipliers.resolution,
                "speed_rpm": float(self.rpm),
                "depth_m": float(self.depth),
                "feed_per_tooth_m": float(self.feed),
            },
        )

    def plot(self, ax: Any = None, **style: Any) -> Any:
        """The orbit over one period (:func:`chatterlab.plot._sle.plot_forced_orbit`); returns the Axes."""
        from ..plot._sle import plot_forced_orbit

        return plot_forced_orbit(self, ax=ax, **style)


def _orbit(
    sm: SpectralMonodromy, a: float, load: np.ndarray, t: np.ndarray
) -> np.ndarray:  # (len(t), 2): (x, y) of the tool on the fixed point
    z = sm.forced(a, load)
    xn = sm.nodal_states(a, z, load)
    T = sm.period
    tt = sm.mesh.t0 + np.mod(np.asarray(t, dtype=float) - sm.mesh.t0, T)
    xs = sm.states_at(xn, tt).real
    return (sm.structure.J @ xs[:, : sm.structure.n].T).T


def _wall(orbit: Any, milling: Any, rpm: float, feed: float, angle: float) -> tuple[np.ndarray, float]:
    """(SLE of every tooth, peak-to-valley of the wall's profile) on the fixed point whose
    tool motion is ``orbit(t)`` ((len(t), 2): x, y), whichever discretisation gave it."""
    Om = milling.omega(rpm)
    N = milling.teeth
    R = 0.5 * milling.diameter
    n_s = np.array([math.sin(angle), math.cos(angle)])
    ts = (angle + milling.lags) / Om  # each tooth's generation instant in its first revolution
    v_f = N * feed * Om / TWO_PI
    # each tooth's pass in three revolutions, the arc wide enough to overlap the neighbouring passes
    span = min(math.pi / 2, 2.0 * max(feed * N, 1e-12) / R + 1e-3)
    u = np.linspace(-span, span, PASS_SAMPLES)
    k = np.arange(-1, 2)
    t = ts[None, :, None] + (TWO_PI * k[:, None, None] + u[None, None, :]) / Om  # (3, N, samples)
    r_all = orbit(np.r_[ts, t.ravel()])
    sle_teeth = -(r_all[:N] @ n_s)
    r = r_all[N:].reshape(t.shape + (2,))
    X = v_f * t + r[..., 0] + R * np.sin(angle + u)
    p = r @ n_s + R * np.cos(u) - R
    X_mid = v_f * ts[0] + R * math.sin(angle) + np.linspace(0.0, N * feed, 4 * PASS_SAMPLES)
    wall = np.full(X_mid.size, -np.inf)
    for Xi, pi in zip(X.reshape(-1, u.size), p.reshape(-1, u.size), strict=True):
        o = np.argsort(Xi)
        Xi, pi = Xi[o], pi[o]
        inside = (X_mid >= Xi[0]) & (X_mid <= Xi[-1])
        wall[inside] = np.maximum(wall[inside], np.interp(X_mid[inside], Xi, pi))
    pv = float(np.max(wall) - np.min(wall)) if feed > 0 and np.all(np.isfinite(wall)) else 0.0
    return sle_teeth, pv


def _setup(loop: ClosedLoop, rpm: float, a: float, degree: int | None, tol: float, mesh: Any = None) -> Any:
    return SpectralMonodromy(loop, rpm, degree, depth=a, depth_hint=a, tol=tol, mesh=mesh)


def _check_loop(loop: ClosedLoop, feed: float) -> float:
    if not isinstance(loop, ClosedLoop) or loop.process is None:
        raise InputError(
            "forced response: give a milling ClosedLoop (chatterlab.process.milling_loop or"
            " chatterlab.lobes.milling_loop_of(frozen))"
        )
    if loop.milling.helix > 0:
        raise InputError(
            "forced response and surface location: straight teeth only (helix_deg = 0); a helical flute"
            " generates the wall along its length at different instants"
        )
    if getattr(loop.milling, "variation", None) is not None:
        raise InputError(
            "forced response and surface location: a constant spindle speed only; under spindle-speed"
            " variation the static chip, the forcing and the instants the wall is generated follow the"
            " varying speed, which this orbit does not (drop the variation)"
        )
    return check_nonneg(feed, "feed per tooth f_z", "m")


def _method(method: str, steps: int) -> int:
    check_method(method)
    return check_count(steps, "steps", 2)


def forced_response(
    loop: ClosedLoop,
    rpm: float,
    depth: float,
    feed: float,
    *,
    method: Literal["spectral", "sdm"] = "spectral",
    degree: int | None = None,
    steps: int = 40,
    tol: float = 1e-10,
    check: bool = True,
    samples: int = 256,
) -> ForcedResponse:
    """The periodic forced vibration of a milling cut and its surface location
    error (module docstring, Eqs. 1-4), from the discretisation that gives its
    Floquet multipliers: the fixed point of its one-period map.

    Parameters
    ----------
    loop : ClosedLoop
        The structure under the cutter (:func:`chatterlab.process.milling_loop`).
    rpm : float
        Spindle speed, rpm.
    depth : float
        Axial depth of cut a_p, m.
    feed : float
        Feed per tooth f_z, m (the static chip f_z sin phi).
    method : {"spectral", "sdm"}
        Spectral-element collocation (Eq. 3; converges geometrically in the
        degree) or first-order semi-discretisation (Eq. 6; converges as
        steps^-2).
    degree : int, optional
        Spectral: collocation degree (None: per element for the accuracy ``tol``).
    steps : int
        Semi-discretisation: steps per period (even: the generation instant of
        tooth 0 is a grid point).
    check : bool
        Also at a higher resolution (spectral: the degree raised by
        CHECK_DEGREE; sdm: 2 x steps): the multipliers' and the SLE's
        convergence errors.
    samples : int
        Points of the orbit over one period.

    Returns
    -------
    ForcedResponse
        An unstable cut (chatter) or an undetermined one gets no orbit and
        no SLE (NaN) but its verdict; its ``multipliers`` record the method
        and the resolution.
    """
    t0 = time.perf_counter()
    f_z = _check_loop(loop, feed)
    a = check_nonneg(depth, "depth of cut a_p", "m")
    m = _method(method, steps)
    angle = generation_angle(loop.milling)
    milling = loop.milling
    if method == "sdm":
        orbit, mu, T = _sd_orbit(loop, rpm, a, f_z, m)
        c = complex(mu[0]) if mu.size else 0j
        err, orbit2 = float("nan"), None
        if check:
            orbit2, mu2, _ = _sd_orbit(loop, rpm, a, f_z, 2 * m)
            err = matched_change(c, mu2)
        mult = Multipliers.ranked(
            mu[np.abs(mu) > 1e-300], error=err, frequency_hz=chatter_frequency(c, T, loop), method="sdm",
            resolution=f"{m} steps", period=T, rpm=float(rpm), depth=a,
        )  # fmt: skip
    else:
        sm = _setup(loop, rpm, a, degree, tol)
        mu = np.linalg.eigvals(finite_monodromy(sm.monodromy(a), rpm, a))
        mu = mu[np.argsort(-np.abs(mu))]
        mu = mu[np.abs(mu) > 1e-300]
        c = complex(mu[0]) if mu.size else 0j
        err = float("nan")
        sm2 = None
        if check:
            sm2 = _setup(loop, rpm, a, None, tol, mesh=sm.mesh.raised(CHECK_DEGREE))
            err = matched_change(c, sm2.at(a))
        mult = Multipliers.ranked(
            mu,
            error=err,
            frequency_hz=sm.critical(a)[1] if sm.m_f else float("nan"),
            method="spectral",
            resolution=f"degree {sm.degree} x {sm.n_sub} elements",
            period=sm.period,
            rpm=float(rpm),
            depth=a,
        )
        T = sm.period
    verdict = mult.verdict  # stable / unstable / undetermined: |mu| against its convergence error
    t = angle / milling.omega(rpm) + T * np.arange(samples) / samples
    nan = np.full(samples, np.nan)
    if verdict != "stable":
        return ForcedResponse(
            t, nan, nan, float("nan"), np.full(milling.teeth, np.nan), float("nan"), angle, mult, verdict,
            float("nan"), float(rpm), a, f_z, time.perf_counter() - t0,
        )  # fmt: skip
    if method == "spectral":
        load = static_load(sm, f_z)
        orbit = partial(_orbit, sm, a, load)
        orbit2 = None if sm2 is None else partial(_orbit, sm2, a, static_load(sm2, f_z))
    r = orbit(t)
    sle_teeth, pv = _wall(orbit, milling, rpm, f_z, angle)
    sle = float(np.min(sle_teeth))
    sle_err = float("nan")
    if orbit2 is not None:
        s2, _ = _wall(orbit2, milling, rpm, f_z, angle)
        sle_err = abs(float(np.min(s2)) - sle)
    return ForcedResponse(
        t, r[:, 0], r[:, 1], sle, sle_teeth, pv, angle, mult, verdict, sle_err, float(rpm), a, f_z,
        time.perf_counter() - t0,
    )  # fmt: skip


def _sd_orbit(
    loop: ClosedLoop, rpm: float, a: float, feed: float, steps: int
) -> tuple[Any, np.ndarray, float]:
    """(orbit, multipliers ranked, period) of the semi-discretisation with ``steps`` steps:
    the fixed point of its one-period map under the static force (Eq. 6) and its monodromy."""
    milling = loop.milling
    Phi, x, dt = sdm_forced(loop, rpm, a, steps, partial(static_load_mean, milling, rpm, feed))
    mu = _ranked(np.linalg.eigvals(finite_monodromy(Phi, rpm, a)))
    return _SdOrbit(loop, x, dt), mu, steps * dt


@dataclass(frozen=True, eq=False)
class SurfaceLocation(Result):
    """The surface location error and the wall's peak-to-valley against the
    spindle speed at one depth (:func:`surface_location`): what a stable cut
    leaves, beside where the cut chatters.

    Attributes
    ----------
    speeds : ndarray
        Spindle speeds, rpm.
    sle : ndarray
        Surface location error, m (Eq. 4; positive: undercut); NaN where the
        cut is not stable.
    sle_error : ndarray
        Its change at the higher resolution (spectral: the degree raised by
        CHECK_DEGREE; sdm: 2 x steps), m.
    peak_to_valley : ndarray
        Height of the wall's profile, m; NaN where not stable.
    spectral_radius, radius_error : ndarray
        The critical multiplier's modulus and its convergence error.
    verdict : list of str
        Per speed: "stable", "unstable" (chatter: no SLE) or "undetermined".
    depth, feed : float
        a_p and f_z, m.
    angle : float
        Generation angle, rad.
    method, resolution : str
        The discretisation of the one-period map (``"spectral"`` or
        ``"sdm"``) and its resolution (the degrees, or the steps).
    """

    speeds: np.ndarray
    sle: np.ndarray
    sle_error: np.ndarray
    peak_to_valley: np.ndarray
    spectral_radius: np.ndarray
    radius_error: np.ndarray
    verdict: list[str]
    depth: float
    feed: float
    angle: float
    name: str = ""
    elapsed: float = 0.0
    meta: dict[str, Any] = field(default_factory=dict)
    method: str = "spectral"
    resolution: str = ""

    @property
    def side(self) -> str:
        """``"up-milling (tooth entry)"`` or ``"down-milling (tooth exit)"``."""
        return "up-milling (tooth entry)" if self.angle == 0.0 else "down-milling (tooth exit)"

    @property
    def how(self) -> str:
        """The discretisation in words: ``"spectral elements"`` or ``"semi-discretisation, M steps per period"``."""
        if self.method == "sdm":
            return f"semi-discretisation, {self.resolution.replace(' steps', '')} steps per period"
        return "spectral elements"

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """Per speed: SLE, its error, peak-to-valley, spectral radius, its error, verdict code."""
        code = np.array([VERDICTS.index(v) for v in self.verdict], dtype=int)
        return (
            {"speed": (np.asarray(self.speeds, dtype=float), "rpm", "spindle speed")},
            {
                "sle": (self.sle, "m", "surface location error (positive: undercut)"),
                "sle_error": (self.sle_error, "m", "change of the SLE at the higher resolution"),
                "peak_to_valley": (self.peak_to_valley, "m", "peak-to-valley of the wall's profile"),
                "spectral_radius": (self.spectral_radius, "1", "largest |Floquet multiplier|"),
                "radius_error": (self.radius_error, "1", "convergence error of the spectral radius"),
                "verdict": (code, "1", "0 stable, 1 unstable (chatter), 2 undetermined"),
            },
            {
                "title": "chatterlab surface location error",
                "model": self.name,
                "depth_m": float(self.depth),
                "feed_per_tooth_m": float(self.feed),
                "generation_angle_rad": float(self.angle),
                "wall": self.side,
                "method": self.method,
                "resolution": self.resolution,
            },
        )

    def summary(self) -> str:
        """What the command prints: the speeds, the verdicts and the SLE range."""
        ok = np.array([v == "stable" for v in self.verdict])
        n_u = sum(v == "unstable" for v in self.verdict)
        n_d = sum(v == "undetermined" for v in self.verdict)
        lines = [
            f"surface location error: {self.name}, a_p = {self.depth * 1e3:.4g} mm, f_z = {self.feed * 1e3:.4g} mm,"
            f" {self.side}, {self.how}",
            f"{len(self.speeds)} speeds {self.speeds[0]:g}..{self.speeds[-1]:g} rpm: {int(ok.sum())} stable,"
            f" {n_u} unstable (chatter, no SLE), {n_d} undetermined",
        ]
        if ok.any():
            s = self.sle[ok]
            i, j = int(np.argmin(s)), int(np.argmax(s))
            sp = self.speeds[ok]
            lines.append(
                f"SLE {s[i] * 1e6:.4g} um at {sp[i]:.6g} rpm to {s[j] * 1e6:.4g} um at {sp[j]:.6g} rpm"
                " (positive: undercut)"
            )
            lines.append(f"peak-to-valley up to {np.max(self.peak_to_valley[ok]) * 1e6:.4g} um")
            e = np.abs(self.sle_error[ok])
            if np.isfinite(e).any():
                big = float(np.nanmax(e))
                rel = big / max(float(np.max(np.abs(s))), 1e-300)
                # SD's change when the steps are doubled is (1 - 2^-p) of its error: up to half
                line = f"SLE check: change at the higher resolution up to {big * 1e6:.3g} um ({rel:.2g} of the largest |SLE|)"
                if self.method == "sdm":
                    line += "; the SD result's error is up to twice that"
                if rel > 0.1:
                    line += (
                        ": COARSE, raise --steps"
                        if self.method == "sdm"
                        else ": COARSE, the degree is too low"
                    )
                lines.append(line)
        return "\n".join(lines)

    def plot(self, ax: Any = None, *, lobes: Any = None, **style: Any) -> Any:
        """The SLE against the speed under the lobes (:func:`chatterlab.plot.plot_sle`);
        returns the Axes."""
        from ..plot import plot_sle

        return plot_sle(self, lobes=lobes, ax=ax, **style)


def surface_location(
    loop: ClosedLoop,
    speeds: Any,
    depth: float,
    feed: float,
    *,
    method: Literal["spectral", "sdm"] = "spectral",
    degree: int | None = None,
    steps: int = 40,
    tol: float = 1e-10,
    check: bool = True,
    progress: Any = None,
) -> SurfaceLocation:
    """:func:`forced_response` at every speed (rpm) of ``speeds``: the SLE and
    peak-to-valley of the stable cuts, the verdict of every one, by the
    ``method`` (``"spectral"`` with ``degree``, ``"sdm"`` with ``steps``).

    Returns
    -------
    SurfaceLocation
    """
    t0 = time.perf_counter()
    v = np.atleast_1d(np.asarray(speeds, dtype=float))
    if v.ndim != 1 or v.size == 0:
        raise InputError("speeds must be a non-empty 1-D list of spindle speeds (rpm)")
    _method(method, steps)
    out = []
    for n in v:
        out.append(
            forced_response(
                loop, float(n), depth, feed, method=method, degree=degree, steps=steps, tol=tol, check=check,
                samples=8,
            )
        )  # fmt: skip
        if progress is not None:
            progress()
    return SurfaceLocation(
        speeds=v,
        sle=np.array([r.sle for r in out]),
        sle_error=np.array([r.error for r in out]),
        peak_to_valley=np.array([r.peak_to_valley for r in out]),
        spectral_radius=np.array([r.multipliers.spectral_radius for r in out]),
        radius_error=np.array([r.multipliers.error for r in out]),
        verdict=[r.verdict for r in out],
        depth=float(depth),
        feed=float(feed),
        angle=generation_angle(loop.milling),
        name=loop.name,
        elapsed=time.perf_counter() - t0,
        method=method,
        resolution=_resolution(method, degree, steps, out),
    )


def _resolution(method: str, degree: int | None, steps: int, out: list[ForcedResponse]) -> str:
    """The sweep's resolution: the steps (sdm), the degree asked, or the range the speeds chose."""
    if method == "sdm":
        return f"{steps} steps"
    if degree is not None:
        return f"degree {degree}"
    res = sorted({r.multipliers.resolution for r in out})
    return res[0] if len(res) == 1 else f"per speed ({len(res)} meshes), e.g. {res[0]}"


# ============================================================================ turning
@dataclass(frozen=True, eq=False)
class RunoutResponse(Result):
    """The forced vibration of a turning cut under an eccentric workpiece
    (module docstring, Eq. 5), at each spindle speed.

    Attributes
    ----------
    speeds : ndarray
        Spindle speeds, rpm.
    amplitude : ndarray
        |X|: the tool-workpiece vibration amplitude at the spindle frequency, m.
    phase : ndarray
        Its phase relative to the force, rad.
    force : float
        The force amplitude K_f h_0 e, N.
    verdict : list of str
        Per speed, the loop's stability (:func:`chatterlab.frequency.stability`):
        an amplitude only where "stable" (NaN where the cut chatters: there is
        no steady forced vibration to speak of).
    """

    speeds: np.ndarray
    amplitude: np.ndarray
    phase: np.ndarray
    force: float
    eccentricity: float
    feed: float
    width: float
    verdict: list[str] = field(default_factory=list)

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """Per speed: the amplitude and phase; the excitation as attributes."""
        return (
            {"speed": (np.asarray(self.speeds, dtype=float), "rpm", "spindle speed")},
            {
                "amplitude": (self.amplitude, "m", "vibration amplitude at the spindle frequency"),
                "phase": (self.phase, "rad", "phase of the vibration relative to the force"),
                "verdict": (
                    np.array([VERDICTS.index(v) if v in VERDICTS else 2 for v in self.verdict], dtype=int),
                    "1",
                    "0 stable, 1 unstable (chatter), 2 undetermined",
                ),
            },
            {
                "title": "chatterlab runout response (turning)",
                "force_amplitude_N": float(self.force),
                "eccentricity_m": float(self.eccentricity),
                "feed_m": float(self.feed),
                "width_m": float(self.width),
            },
        )

    def plot(self, ax: Any = None, **style: Any) -> Any:
        """The amplitude against the speed (:func:`chatterlab.plot._sle.plot_runout`); returns the Axes."""
        from ..plot._sle import plot_runout

        return plot_runout(self, ax=ax, **style)


def runout_response(
    loop: ClosedLoop,
    speeds: Any,
    eccentricity: float,
    feed: float,
    Kf: float,
    *,
    inputs: str,
    outputs: str,
) -> RunoutResponse:
    """The vibration of a turning cut at the spindle frequency under an
    eccentric workpiece: the closed-loop FRF of ``loop`` (its delay set to
    each speed's revolution, :meth:`ClosedLoop.at`) at Omega, times the
    force K_f h_0 e (module docstring, Eq. 5).

    Parameters
    ----------
    loop : ClosedLoop
        The turning loop (:func:`chatterlab.process.closed_loop`) at its width b.
    speeds : array
        Spindle speeds, rpm.
    eccentricity : float
        e, m.
    feed : float
        h_0, the feed per revolution, m.
    Kf : float
        The cutting coefficient, N/m^2, whose force the width varies.
    inputs, outputs : str
        ``"POINT.DIR"``: where and along what the force acts, what is read.

    Returns
    -------
    RunoutResponse
        With the stability of the cut at each speed; a speed where it
        chatters (or is undetermined) gets no amplitude (NaN).
    """
    from ._frf import frf
    from ._stability import stability

    e = check_nonneg(eccentricity, "eccentricity e", "m")
    h0 = check_positive(feed, "feed per revolution h_0", "m")
    kf = check_positive(Kf, "cutting coefficient K_f", "N/m^2")
    if not isinstance(loop, ClosedLoop) or loop.frozen is None or loop.process is not None:
        raise InputError(
            "runout response: give a turning ClosedLoop of a model (chatterlab.process.closed_loop(frozen, ...))"
        )
    v = np.atleast_1d(np.asarray(speeds, dtype=float))
    F = kf * h0 * e
    amp, ph, verdict = [], [], []
    for n in v:
        T = float(tooth_period(check_positive(float(n), "spindle speed", "rpm")))
        L = loop.at(delay=T)
        st = stability(loop.frozen, width=loop.width, delay=T, terms=loop.terms)  # type: ignore[arg-type]
        verdict.append(st.verdict if st.verdict in ("stable", "unstable") else "undetermined")
        if verdict[-1] != "stable":
            amp.append(float("nan"))
            ph.append(float("nan"))
            continue
        G = frf(L, np.array([TWO_PI / T]), inputs=inputs, outputs=outputs)
        x = complex(G.data[0, 0, 0]) * F
        amp.append(abs(x))
        ph.append(float(np.angle(x)))
    return RunoutResponse(v, np.array(amp), np.array(ph), F, e, h0, float(loop.width), verdict)
