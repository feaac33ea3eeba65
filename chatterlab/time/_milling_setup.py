"""Setting up a milling run in the time domain (:mod:`chatterlab.time._milling`):
the structure's matrices and the tool-point map, the default step, the Newmark
maps of each substep length and the periodic pattern of substep points where
a tooth enters or leaves the arc."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import InputError
from ..process import Milling

__all__: list[str] = []

FloatArray = NDArray[Any]
TWO_PI = 2.0 * math.pi
#: (w h)^2 / 12 <= 1e-3: the relative period error of the trapezoidal rule
_WH_MAX = math.sqrt(12.0e-3)


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
