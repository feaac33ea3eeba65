"""The critical point of the stability boundary and the exact derivative
of the limit width there.

On the boundary of the lobe diagram (:mod:`chatterlab.lobes._diagram`)

    det X = 0,   X(b, w, z) = I + b H(w) (A(w) + z O),   z = e^{-j w T},        (1)

with H = J Z^-1 J^T the structure's FRF between the coupling-element (CE)
coordinates, Z(w) = K - w^2 M + j w C - D_a(jw) (the machine's actuators,
:mod:`chatterlab.design._receptance`: 0 without), A = P + j w V and O the CE
matrices at b = 1 m.  (By the matrix determinant lemma (1) is the loop condition of the
lobe engine, det(I + z N(b)) = 0 with N = b V^T (I + b H A)^-1 H U, |nu| = 1
for an eigenvalue nu of N, times the factor det(I + b H A), which does not
vanish at a boundary point of the delayed loop: the two have the same zeros
and, through them, the same implicit derivatives.)  At a boundary point one
eigenvalue lambda of X is zero; for a simple eigenvalue with right and left
eigenvectors u, y its derivative along any change dX is [1]

    d lambda = y^H dX u / (y^H u).                                            (2)

lambda(b, x, p) = 0 is one complex -- two real -- equations in the width b
and one more real unknown x, so by the implicit function theorem

    db/dp = -Im(lambda_p conj(lambda_x)) / Im(lambda_b conj(lambda_x)).        (3)

Which x depends on the limit:

* **b_lim at a speed** (fixed delay T): x = w, the chatter frequency, with
  z = e^{-j w T} following it, lambda_x = lambda_w - j T z lambda_z; a field
  that changes the process kinematics changes T at the same speed
  (lambda_p gains lambda_T dT/dp, lambda_T = -j w z lambda_z);
* **a minimum over speeds** -- the bottom of a lobe, the minimum over a
  speed range when it lies inside the range, and the absolute minimum over
  all speeds: min over T of b is a min over the branch b(w) with the phase
  of z free, so by the envelope theorem db_min/dp is (3) at the minimiser
  with x = theta, z = e^{j theta}, lambda_x = j z lambda_z, w held;
* **a static root** (w = 0, z = 1): X is real and db/dp = -lambda_p / lambda_b.

Every lambda_* is (2) of a closed-form dX: with the FRF factors
G_R = Z^-1 J^T and G_L = J Z^-1,

    dX/db = H (A + z O),   dX/dw|_z = b [H' (A + z O) + j H V],   dX/dz = b H O,
    H' = -G_L (-2 w M + j C) G_R,
    dX/dp = b [(dJ G_R + G_L dJ^T - G_L dZ G_R)(A + z O) + H (dP + j w dV + z dO)],
    dZ = dK - w^2 dM + j w dC + d(F_a diag(G) S_a),

so (3) is a *linear* function of the derivatives of the matrices,
db/dp = sum over blocks of S_X : dX/dp, with real "sensitivity matrices"
S_M, S_C, S_K, S_J, S_P, S_V, S_O, S_T and, for the actuators, S of their
maps, gains, delays and time constants (through the partial derivatives of
G_k) computed once per critical point
(:attr:`CriticalPoint.S`); a field then costs one elementwise product.

References
----------
.. [1] J. H. Wilkinson, *The Algebraic Eigenvalue Problem*, Oxford, 1965,
   ch. 2, sec. 5-10 (first-order perturbation of a simple eigenvalue).
.. [2] J. Nocedal, S. J. Wright, *Numerical Optimization*, 2nd ed., Springer,
   2006, sec. 12.8 (the envelope theorem / sensitivity of an optimal value).
.. [3] T. Insperger, G. Stepan, *Semi-Discretization for Time-Delay
   Systems*, Springer, 2011, sec. 1.3 (D-subdivision boundaries).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ._matrices import LoopMatrices
from ._receptance import Control, control_at, receptances

__all__ = ["CriticalPoint", "at_delay", "at_frequency", "branch_minimum", "static_point"]

_EPS = float(np.finfo(float).eps)
#: a second eigenvalue of X this close to 0 (relative to 1 = X's value without the cut):
#: two boundaries coincide there and the limit has no derivative
DEGENERATE = 1e-6


@dataclass(frozen=True)
class _Eval:
    """X and the pieces of its derivatives at (b, w, z)."""

    b: float
    w: float
    z: complex
    GR: np.ndarray  # Z^-1 J^T (n, p)
    GL: np.ndarray  # J Z^-1 (p, n)
    H: np.ndarray  # (p, p)
    A: np.ndarray  # P + j w V
    lam: complex  # the eigenvalue of X nearest 0
    second: float  # |second nearest|
    y: np.ndarray  # left eigenvector (y^H X = lam y^H), scaled so that y^H u = 1
    u: np.ndarray  # right eigenvector
    ctl: Control | None = None  # the actuators' term at w (None without actuators)


def _evaluate(L: LoopMatrices, b: float, w: float, z: complex) -> _Eval | None:
    """X at (b, w, z) and its eigenvalue nearest 0 (None where X is not finite)."""
    from scipy.linalg import eig

    if not (np.isfinite(b) and np.isfinite(w) and np.isfinite(z)):
        return None
    ctl = control_at(L, w)
    GR, GL, H = receptances(L, w, ctl)
    A = L.P + 1j * w * L.V
    X = np.eye(H.shape[0]) + b * H @ (A + z * L.O)
    if not np.all(np.isfinite(X)):
        return None
    vals, vl, vr = eig(X, left=True, right=True)
    order = np.argsort(np.abs(vals))
    k = int(order[0])
    u = vr[:, k]
    y = vl[:, k]
    yu = np.vdot(y, u)
    second = float(np.abs(vals[order[1]])) if vals.size > 1 else np.inf
    return _Eval(b, w, z, GR, GL, H, A, complex(vals[k]), second, y / np.conj(yu), u, ctl)


def _d(e: _Eval, Y: np.ndarray) -> complex:
    """(2): y^H Y u / (y^H u)."""
    return complex(np.conj(e.y) @ Y @ e.u)


def _lam_b(L: LoopMatrices, e: _Eval) -> complex:
    return _d(e, e.H @ (e.A + e.z * L.O))


def _lam_w(L: LoopMatrices, e: _Eval) -> complex:
    """d lambda / dw at fixed z (dZ_c/dw = -2 w M + j C - dD_a/dw)."""
    dZ = -2 * e.w * L.M + 1j * L.C
    if e.ctl is not None:
        dZ = dZ - e.ctl.dDa
    Hw = -e.GL @ dZ @ e.GR
    return e.b * _d(e, Hw @ (e.A + e.z * L.O) + 1j * e.H @ L.V)


def _lam_z(L: LoopMatrices, e: _Eval) -> complex:
    return e.b * _d(e, e.H @ L.O)


@dataclass(frozen=True)
class CriticalPoint:
    """A point of the boundary where the limit is attained, with what its
    derivative needs.

    Attributes
    ----------
    kind : {"speed", "bottom", "static"}
        b_lim at a fixed delay (x = w), a minimum over delays (x = theta,
        the phase of z, with w held: envelope theorem), or a root at s = 0.
    b, w, z, T
        Width (m), chatter frequency (rad/s), z = e^{-j w T} on the unit
        circle, the delay (s; nan for a minimum over delays).
    index : int
        The speed's index in the study's delays (kind "speed"), else -1.
    residual : float
        |lambda| at the point after Newton's method (of order 1e-15).
    degenerate : bool
        A second eigenvalue of X vanishes too: two boundaries meet here
        (a symmetric structure), and the limit has no derivative.
    S : LoopMatrices
        The sensitivity matrices: db/dp = sum over blocks of S_X : dX/dp.
    converged : bool
        A branch minimum: the slope db/dw reached zero (False: the lowest
        point found, not a minimum; its derivative is not the minimum's).
    """

    kind: str
    b: float
    w: float
    z: complex
    T: float
    index: int
    residual: float
    degenerate: bool
    S: LoopMatrices
    converged: bool = True

    @property
    def frequency_hz(self) -> float:
        return self.w / (2 * np.pi)

    def derivative(self, d: LoopMatrices) -> float:
        """db/dp for the derivatives ``d`` of the loop's matrices, m per unit of p."""
        if self.degenerate:
            return float("nan")
        return float(sum(np.sum(s * x) for s, x in zip(self.S.blocks(), d.blocks(), strict=True)))

    def error_bound(self, tol: LoopMatrices) -> float:
        """The largest change of db/dp when every entry of dX/dp is off by at
        most the same entry of ``tol``."""
        if self.degenerate:
            return float("nan")
        return float(sum(np.sum(np.abs(s) * t) for s, t in zip(self.S.blocks(), tol.blocks(), strict=True)))


def _sensitivity_matrices(L: LoopMatrices, e: _Eval, kind: str, index: int, T: float) -> LoopMatrices:
    """S of :class:`CriticalPoint` at an evaluated point (module docstring)."""
    b, w, z = e.b, e.w, e.z
    lb = _lam_b(L, e)
    v1 = (e.A + z * L.O) @ e.u  # (A + z O) u
    yH = np.conj(e.y)
    r = yH @ e.GL  # y^H J Z^-1
    s = e.GR @ v1  # Z^-1 J^T (A + z O) u
    g = yH @ e.H  # y^H H
    rs = np.outer(r, s)
    G = {  # d lambda = b sum G_X : dX  (the part from each block)
        "M": w * w * rs,
        "C": -1j * w * rs,
        "K": -rs,
        "J": np.outer(yH, s) + np.outer(v1, r),
        "P": np.outer(g, e.u),
        "V": 1j * w * np.outer(g, e.u),
        "O": z * np.outer(g, e.u),
    }
    # the actuators: dZ_c = d(Fa diag(G) Sa), so d lambda = b sum (-r s^T) : dZ_c
    ctl = e.ctl
    if ctl is None:
        m = L.Pa.size
        zero = np.zeros(m, dtype=complex)
        G.update(Fa=np.zeros(L.Fa.shape, complex), Sa=np.zeros(L.Sa.shape, complex))
        G.update(Pa=zero, Va=zero, Oa=zero, Ta=zero, La=zero)
    else:
        R = -rs
        rho = np.einsum("ik,ij,kj->k", L.Fa, R, L.Sa)  # diag(Fa^T R Sa^T)
        G.update(
            Fa=(R @ L.Sa.T) * ctl.G[None, :],
            Sa=ctl.G[:, None] * (L.Fa.T @ R),
            Pa=rho * ctl.dP,
            Va=rho * ctl.dV,
            Oa=rho * ctl.dO,
            Ta=rho * ctl.dT,
            La=rho * ctl.dL,
        )
    lz = _lam_z(L, e)
    GT = np.zeros(L.T.size, dtype=complex)
    if kind == "static":
        scale = -1.0 / lb.real
        parts = {k: (b * v).real * scale for k, v in G.items()}
        return LoopMatrices(**parts, T=GT.real)
    if kind == "speed":
        lx = _lam_w(L, e) + lz * (-1j * T * z)
        if 0 <= index < GT.size:
            GT[index] = lz * (-1j * w * z)  # lambda_T (already carries the factor b)
    else:
        lx = 1j * z * lz
    den = float(np.imag(lb * np.conj(lx)))
    parts = {k: -np.imag(b * v * np.conj(lx)) / den for k, v in G.items()}
    return LoopMatrices(**parts, T=-np.imag(GT * np.conj(lx)) / den)


#: |lambda| (X is I + ... : of order 1 away from the boundary) at which Newton's method has found it
_SOLVED = 1e-9


def _newton(
    L: LoopMatrices, b: float, x: float, z_of: Any, lx_of: Any, iters: int = 40
) -> tuple[_Eval | None, float]:
    """Newton's method on lambda(b, x) = 0 in the real unknowns (b, x); None
    when it does not reach |lambda| < _SOLVED (no boundary point near the start)."""
    for _ in range(iters):
        w, z = z_of(x)
        e = _evaluate(L, b, w, z)
        if e is None:
            return None, x
        a = _lam_b(L, e)
        c = lx_of(e, x)
        Jm = np.array([[a.real, c.real], [a.imag, c.imag]])
        try:
            db, dx = np.linalg.solve(Jm, [-e.lam.real, -e.lam.imag])
        except np.linalg.LinAlgError:
            return None, x
        # a Newton step is capped at 5 % of the width: it must stay on its branch
        cap = 0.05 * abs(b)
        if abs(db) > cap:
            f = cap / abs(db)
            db, dx = db * f, dx * f
        if not (np.isfinite(db) and np.isfinite(dx)) or b + db <= 0:
            return None, x
        b, x = b + db, x + dx
        if abs(db) <= 4 * _EPS * abs(b) and abs(dx) <= 4 * _EPS * max(abs(x), 1.0):
            break
    w, z = z_of(x)
    e = _evaluate(L, b, w, z)
    return (e if e is not None and abs(e.lam) < _SOLVED else None), x


def at_delay(L: LoopMatrices, T: float, b: float, w: float, index: int = -1) -> CriticalPoint:
    """The boundary point at delay T nearest (b, w), b_lim's critical point
    at that speed (``index`` into ``L.T``, for a process field's dT/dp)."""

    def z_of(x: float) -> tuple[float, complex]:
        return x, complex(np.exp(-1j * x * T))

    def lx_of(e: _Eval, x: float) -> complex:
        return _lam_w(L, e) + _lam_z(L, e) * (-1j * T * e.z)

    e, _ = _newton(L, b, w, z_of, lx_of)
    if e is None:
        raise ArithmeticError(
            f"no boundary point near b = {b:.6g} m, {w / (2 * np.pi):.6g} Hz at T = {T:.6g} s: the lobe"
            " engine's limit is not a root of the loop's determinant"
        )
    return _point(L, e, "speed", index, T)


def at_frequency(L: LoopMatrices, w: float, b: float, theta: float) -> _Eval | None:
    """The boundary width at a fixed frequency w (the phase theta of z free),
    from (b, theta); None when there is none near it."""

    def z_of(x: float) -> tuple[float, complex]:
        return w, complex(np.exp(1j * x))

    def lx_of(e: _Eval, x: float) -> complex:
        return 1j * e.z * _lam_z(L, e)

    e, _ = _newton(L, b, theta, z_of, lx_of)
    return e


def _slope(L: LoopMatrices, e: _Eval) -> float:
    """db/dw along the branch with the phase of z free (the curve b(w))."""
    lb, lw = _lam_b(L, e), _lam_w(L, e)
    lt = 1j * e.z * _lam_z(L, e)
    den = float(np.imag(lb * np.conj(lt)))
    return float(-np.imag(lw * np.conj(lt)) / den) if den != 0 else float("nan")


def branch_minimum(L: LoopMatrices, b: float, w: float, z: complex, iters: int = 80) -> CriticalPoint:
    """The local minimum of the branch b(w) through (b, w, z): db/dw = 0 by
    the secant method on the exact slope (each trial frequency solved for
    b and the phase by Newton's method), steps of at most 0.5 % and halved
    while a trial frequency has no width near the previous one (the branch
    folds back there).  ``converged`` is False when no zero of the slope is
    reached (the point is then the lowest one found)."""
    e0 = at_frequency(L, w, b, float(np.angle(z)))
    if e0 is None:
        raise ArithmeticError(f"no boundary point near b = {b:.6g} m at {w / (2 * np.pi):.6g} Hz")
    g0 = _slope(L, e0)
    w0, w1 = w, w * (1 + 1e-7)
    e1 = at_frequency(L, w1, e0.b, float(np.angle(e0.z)))
    if e1 is None or not np.isfinite(g0):
        return _point(L, e0, "bottom", -1, float("nan"), converged=False)
    g1 = _slope(L, e1)
    converged = False
    for _ in range(iters):
        if not (np.isfinite(g1) and np.isfinite(g0)) or g1 == g0:
            break
        w2 = w1 - g1 * (w1 - w0) / (g1 - g0)
        w2 = min(max(w2, w1 * 0.995), w1 * 1.005)
        e2 = None
        for _ in range(30):  # back towards w1 while there is no width near e1's
            e2 = at_frequency(L, w2, e1.b, float(np.angle(e1.z)))
            if e2 is not None and abs(e2.b - e1.b) <= 0.1 * e1.b:
                break
            e2 = None
            w2 = w1 + 0.5 * (w2 - w1)
        if e2 is None:
            break
        w0, g0 = w1, g1
        w1, g1, e1 = w2, _slope(L, e2), e2
        if abs(w1 - w0) <= 8 * _EPS * w1 or (np.isfinite(g1) and abs(g1) * w1 <= 1e-12 * e1.b):
            converged = True
            break
    return _point(L, e1, "bottom", -1, float("nan"), converged=converged)


def static_point(L: LoopMatrices, b: float) -> CriticalPoint:
    """A real root at s = 0 (w = 0, z = 1): Newton on the real eigenvalue."""
    e = _evaluate(L, b, 0.0, 1.0 + 0j)
    for _ in range(40):
        if e is None:
            break
        lb = _lam_b(L, e).real
        if lb == 0:
            break
        db = -e.lam.real / lb
        b += db
        e = _evaluate(L, b, 0.0, 1.0 + 0j)
        if abs(db) <= 4 * _EPS * abs(b):
            break
    if e is None or abs(e.lam) >= _SOLVED:
        raise ArithmeticError(f"no static root near b = {b:.6g} m")
    return _point(L, e, "static", -1, float("nan"))


def _point(
    L: LoopMatrices, e: _Eval, kind: str, index: int, T: float, converged: bool = True
) -> CriticalPoint:
    S = _sensitivity_matrices(L, e, kind, index, T)
    return CriticalPoint(kind, e.b, e.w, e.z, T, index, abs(e.lam), e.second < DEGENERATE, S, converged)
