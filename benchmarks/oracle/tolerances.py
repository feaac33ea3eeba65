"""The tolerance of every recorded number, derived when it is recorded
(``record.py``; the test only reads them).  See ``record.py``'s docstring for
the rules and their reasons; the functions here compute them.

Notation: ``u = 2**-53`` is the unit round-off and ``gamma(n) = 3 n u``.  The
round-off model is componentwise: a computation on an n x n matrix X (formed
entry by entry, then solved by LU with partial pivoting or decomposed by a
balanced QR/QZ) returns the exact result of a neighbour X + dX with
|dX| <= gamma(n) |X| entry by entry (Higham, *Accuracy and Stability of
Numerical Algorithms*, 2nd ed., SIAM 2002: Thm. 9.4, |dA| <= gamma_{3n}
|L||U|, with |L||U| of the order of |A| for these diagonally heavy
matrices; Sec. 7.2 for the componentwise condition numbers used below).
The normwise model (|dX| <= gamma ||X||) is what a theorem guarantees for
the eigensolvers, but on the models' badly scaled coordinates (a beam's
rotations next to a slide's translations: stiffness entries from 1e7 to
1e11) it overstates the round-off of the low modes by 10^3-10^6, so it
would let through changes the oracle is there to catch.  The componentwise
bounds were checked against real changes of the operation order: the
recording replayed with OpenBLAS's Haswell, Sandybridge and Prescott kernels
and two threads (see record.py) stays within a few percent of them.  Every
tolerance is the difference allowed between TWO runs (the recording and the
check), so it is twice the bound of one run's distance to the exact result.

This module runs at recording time only, on the pre-move code, and uses its
internals where the public API does not expose a number the derivation needs
(the FRF's output/input vectors, the milling search's fit of the Poincare
samples, the spectral monodromy's matrices).
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np
import scipy.linalg as sla

U = 2.0**-53


def gamma(n: int) -> float:
    """Backward error of a dense factorisation of an n x n matrix (relative)."""
    return 3.0 * n * U


def nrm(X: np.ndarray) -> float:
    return float(np.linalg.norm(X, 2)) if np.size(X) else 0.0


def cw(y: np.ndarray, X: np.ndarray, x: np.ndarray) -> float:
    """|y|^T |X| |x| (X already nonnegative): the componentwise size of y^H dX x."""
    return float(np.abs(y) @ X @ np.abs(x))


# ============================================================================ loops
# The characteristic matrix F(s; b, T) of a delayed closed loop, its derivatives
# and the componentwise size of its rounded terms (|dF| <= gamma absF).


class StructLoop:
    """F(s) = s^2 M + s C + K + b J^T (Dl_P + s Dl_V + e^{-sT} Dl_O) J: a
    structure (M, C, K; n coordinates) cut through J (m x n) by CE matrices
    per metre of width (the engine's sign: D(s) = -J^T Dl(s) J at width b, and
    Delta = Z - D)."""

    def __init__(self, M: Any, C: Any, K: Any, J: Any, DlP: Any, DlV: Any, DlO: Any) -> None:
        self.M, self.C, self.K, self.J = (np.asarray(x, float) for x in (M, C, K, J))
        self.DlP, self.DlV, self.DlO = (np.asarray(x, float) for x in (DlP, DlV, DlO))
        self.n = self.M.shape[0]

    def _e(self, s: complex, T: float | None) -> complex:
        return 0.0 if T is None else complex(np.exp(-s * T))

    def F(self, s: complex, b: float, T: float | None) -> np.ndarray:
        D = self.DlP + s * self.DlV + self._e(s, T) * self.DlO
        return s * s * self.M + s * self.C + self.K + b * self.J.T @ D @ self.J

    def Fs(self, s: complex, b: float, T: float | None) -> np.ndarray:
        D = self.DlV - (0.0 if T is None else T) * self._e(s, T) * self.DlO
        return 2 * s * self.M + self.C + b * self.J.T @ D @ self.J

    def Fb(self, s: complex, b: float, T: float | None) -> np.ndarray:
        return self.J.T @ (self.DlP + s * self.DlV + self._e(s, T) * self.DlO) @ self.J

    def FT(self, s: complex, b: float, T: float | None) -> np.ndarray:
        return -b * s * self._e(s, T) * self.J.T @ self.DlO @ self.J

    def absF(self, s: complex, b: float, T: float | None) -> np.ndarray:
        """The componentwise size of F's terms: |dF| <= gamma |absF|."""
        a = abs(s)
        D = np.abs(self.DlP) + a * np.abs(self.DlV) + abs(self._e(s, T)) * np.abs(self.DlO)
        aJ = np.abs(self.J)
        return a * a * np.abs(self.M) + a * np.abs(self.C) + np.abs(self.K) + abs(b) * aJ.T @ D @ aJ


class PlantLoop:
    """F(s) = I + b H(s) (Dl_P + s Dl_V + e^{-sT} Dl_O) on the imaginary axis, H
    a measured FRF (the spline of chatterlab.lobes.measured_plant); its
    evaluation rounds relative to |H| (a cubic's few operations)."""

    def __init__(self, plant: Any) -> None:
        self.plant = plant
        self.DlP, self.DlV, self.DlO = plant.Dl_P, plant.Dl_V, plant.Dl_O
        self.n = self.DlP.shape[0]

    def H(self, s: complex) -> np.ndarray:
        return np.asarray(self.plant.H(np.array([s.imag])))[0]

    def _e(self, s: complex, T: float | None) -> complex:
        return 0.0 if T is None else complex(np.exp(-s * T))

    def D(self, s: complex, T: float | None) -> np.ndarray:
        return self.DlP + s * self.DlV + self._e(s, T) * self.DlO

    def F(self, s: complex, b: float, T: float | None) -> np.ndarray:
        return np.eye(self.n) + b * self.H(s) @ self.D(s, T)

    def Fs(self, s: complex, b: float, T: float | None) -> np.ndarray:
        w, h = s.imag, 1e-7 * abs(s.imag)
        dH_dw = (self.H(1j * (w + h)) - self.H(1j * (w - h))) / (2 * h)
        dD = self.DlV - (0.0 if T is None else T) * self._e(s, T) * self.DlO
        return b * (-1j * dH_dw @ self.D(s, T) + self.H(s) @ dD)

    def Fb(self, s: complex, b: float, T: float | None) -> np.ndarray:
        return self.H(s) @ self.D(s, T)

    def FT(self, s: complex, b: float, T: float | None) -> np.ndarray:
        return -b * s * self._e(s, T) * self.H(s) @ self.DlO

    def absF(self, s: complex, b: float, T: float | None) -> np.ndarray:
        """The componentwise size of F's rounded terms (b H D; I is exact)."""
        a = abs(s)
        D = np.abs(self.DlP) + a * np.abs(self.DlV) + abs(self._e(s, T)) * np.abs(self.DlO)
        return abs(b) * np.abs(self.H(s)) @ D


def loop_of_frozen(fz: Any, T: float | None, terms: str = "pdo") -> StructLoop:
    """The closed loop of a frozen structure: its A*, B*, C* and the CE maps
    and matrices of chatterlab.feedback at a width of 1 m (D is linear in b)."""
    import chatterlab as cl

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        close = cl.closed_loop if hasattr(cl, "closed_loop") else cl.feedback  # 0.3 / 0.2
        fb = close(fz, width=1.0, delay=T, terms=terms)  # type: ignore[arg-type]
        fb2 = close(fz, width=0.5, delay=T, terms=terms)  # type: ignore[arg-type]
    # D is linear in the width: the CE matrices at 1 m are the ones per metre
    for x, y in ((fb.Dl_P, fb2.Dl_P), (fb.Dl_V, fb2.Dl_V), (fb.Dl_O, fb2.Dl_O)):
        assert np.allclose(0.5 * x, y, rtol=1e-14, atol=0), "feedback not linear in the width"
    return StructLoop(fz.A, fz.B, fz.C, fb.J, fb.Dl_P, fb.Dl_V, fb.Dl_O)


def loop_of_tool(S: Any, milling: Any) -> StructLoop:
    """The ZOA loop of a ToolStructure (chatterlab.lobes.zoa_plant: Dl_P = H0,
    Dl_O = -H0 on the cut's coordinates r = Jr q)."""
    from chatterlab.lobes import zoa_plant

    p = zoa_plant(S, milling)
    _, Jr, _ = S.cut_basis
    return StructLoop(S.M, S.C, S.K, Jr, p.Dl_P, p.Dl_V, p.Dl_O)


# ============================================================================ roots


def root_condition(loop: Any, s: complex, b: float, T: float | None, check: float = 1e-6) -> dict[str, Any]:
    """First-order sensitivity of a root s of det F(s; b, T) = 0: with x, y
    the right and left null vectors, ds = -y^H dF x / y^H F_s x (Tisseur,
    Linear Algebra Appl. 309 (2000) 339-361, for nonlinear eigenvalue
    problems), so a round-off |dF| <= gamma |F's terms| moves it by at most
    gamma kappa, kappa = |y|^T absF |x| / |y^H F_s x| (the componentwise
    condition); ds/db and ds/dT likewise.  ``check``: sigma_min(F) must be
    this small relative to |y|^T absF |x| at a recorded root (the loop's
    conventions are the engine's)."""
    F = loop.F(s, b, T)
    Uu, sv, Vh = np.linalg.svd(F)
    x, y = Vh[-1].conj(), Uu[:, -1]
    size = cw(y, loop.absF(s, b, T), x)
    if not sv[-1] <= check * size:
        raise AssertionError(
            f"not a root: sigma_min / size = {sv[-1] / size:.2e} at s = {s}, b = {b}, T = {T}"
        )
    den = y.conj() @ loop.Fs(s, b, T) @ x
    return {
        "kappa": size / abs(den),
        "ds_db": -(y.conj() @ loop.Fb(s, b, T) @ x) / den,
        "ds_dT": -(y.conj() @ loop.FT(s, b, T) @ x) / den if T is not None else 0j,
        "residual": sv[-1] / size,
    }


#: Newton on det Delta (chatterlab.frequency._newton) stops when the step is below 1e-13 |lambda|
NEWTON_TOL = 1e-13
#: the lobe engine's regula falsi brackets the envelope's frequency to 1e-14 relative
#: (chatterlab.lobes._envelope._refine_crossings)
BRACKET_TOL = 1e-14


def root_tol(loop: Any, lam: complex, b: float, T: float | None) -> float:
    """|d lambda| allowed: Newton's stopping step plus the round-off floor,
    twice (two runs)."""
    c = root_condition(loop, lam, b, T)
    return 2.0 * (NEWTON_TOL * abs(lam) + gamma(loop.n) * c["kappa"])


def boundary_tol(loop: Any, omega: float, b: float, T: float) -> tuple[float, float]:
    """(|db|, |d omega|) allowed at an envelope point (b_lim, omega_c) at delay
    T: a root s = j omega at width b.  Round-off moves s by gamma kappa; the
    engine puts it back on the axis by moving b (Re ds = 0), so
    db_ro = gamma kappa / |Re ds/db| and domega_ro = gamma kappa (1 +
    |Im ds/db| / |Re ds/db|).  The regula falsi stops with omega within
    BRACKET_TOL omega of the crossing, on the boundary curve whose slope
    db/domega at fixed ... follows from Re ds = 0 along it (b and T moving):
    db/domega = 1 / (Im s_b - Im s_T Re s_b / Re s_T)."""
    c = root_condition(loop, 1j * omega, b, T)
    sb, sT = c["ds_db"], c["ds_dT"]
    e = gamma(loop.n) * c["kappa"]
    db_ro = e / abs(sb.real)
    dw_ro = e * (1.0 + abs(sb.imag) / abs(sb.real))
    slope = 1.0 / abs(sb.imag - sT.imag * sb.real / sT.real) if sT.real != 0 else 0.0
    db_stop = slope * BRACKET_TOL * omega
    return 2.0 * (db_ro + db_stop), 2.0 * (dw_ro + BRACKET_TOL * omega)


#: scipy.optimize.minimize_scalar(method="bounded") stops with its x within
#: tol2 = 2 (sqrt(eps) |x| + xatol / 3) of the minimiser (fminbound's test); the lobe
#: engine's absolute minimum calls it with xatol = 1e-10 omega
SQRT_EPS = math.sqrt(np.finfo(float).eps)


def absolute_minimum_tol(
    loop: Any, omega: float, b: float, lobes: Any, omega_hi: float | None = None
) -> tuple[float, float]:
    """(|db|, |d omega|) allowed at the absolute minimum (b*, omega*) of the
    boundary curve (min over omega, any delay).  The minimiser's location is
    known to tol2 (Brent's bounded search), so omega to 2 tol2 and b, flat
    there, to b'' tol2^2 / 2 (b'' from a parabola through the curve's samples
    nearest omega*, read from the diagram's lobes) plus the round-off shift
    of the curve at fixed omega: with the delay free, Re/Im of s_b db + s_T dT
    = -ds_ro give |db| <= gamma kappa |s_T| / |Im(s_b conj(s_T))|."""
    # the delay of the minimum: z = e^{-j omega T} from det(F0 + z F1) = 0, |z| nearest 1
    s = 1j * omega
    F0 = loop.F(s, b, None)  # without the delayed term
    F1 = b * (loop.J.T @ loop.DlO @ loop.J) if isinstance(loop, StructLoop) else b * loop.H(s) @ loop.DlO
    z = sla.eigvals(F0, -F1)
    z = z[np.isfinite(z)]
    zz = complex(z[np.argmin(np.abs(np.abs(z) - 1.0))])
    T = float((-np.angle(zz)) % (2 * np.pi)) / omega
    if T == 0.0:
        T = 2 * np.pi / omega
    c = root_condition(loop, s, b, T, check=1e-5)
    sb, sT = c["ds_db"], c["ds_dT"]
    e = gamma(loop.n) * c["kappa"]
    db_ro = e * abs(sT) / abs((sb * np.conj(sT)).imag)
    hi = omega if omega_hi is None else omega_hi
    tol2 = 2.0 * (SQRT_EPS * omega + 1e-10 * hi / 3.0)
    # the curve's curvature: a parabola through the three samples nearest omega*
    fw = np.concatenate([2 * np.pi * np.asarray(L.frequency_hz, float) for L in lobes])
    bw = np.concatenate([np.asarray(L.width, float) for L in lobes])
    ok = np.isfinite(fw) & np.isfinite(bw)
    fw, bw = fw[ok], bw[ok]
    order = np.argsort(np.abs(fw - omega))
    pick: list[int] = []
    for i in order:  # three distinct frequencies
        if all(abs(fw[i] - fw[j]) > 1e-9 * omega for j in pick):
            pick.append(i)
        if len(pick) == 3:
            break
    x, y = fw[pick] - omega, bw[pick]
    curv = abs(2.0 * np.polyfit(x, y, 2)[0])
    db_loc = 0.5 * curv * tol2**2
    return 2.0 * (db_ro + db_loc), 2.0 * tol2 + 2.0 * e


# ============================================================================ structure


def modes_tol(fz: Any, count: int) -> tuple[np.ndarray, np.ndarray]:
    """(|d f_i| Hz, |d zeta_i|) of chatterlab.modes (scipy.linalg.eigh(C, A),
    then zeta = phi^T B phi / 2 omega, phi A-normalised).  A componentwise
    perturbation E = dC - lambda dA, |E| <= gamma (|C| + lambda_i |A|), moves
    lambda_i by phi_i^T E phi_i and phi_i by sum_j phi_j (phi_j^T E phi_i) /
    (lambda_i - lambda_j) (first-order perturbation theory of the symmetric
    definite pencil), so phi_i^T B phi_i by 2 sum_j |phi_i^T B phi_j|
    |phi_j^T E phi_i| / |lambda_i - lambda_j|; with the normalisation's own
    round-off (gamma |phi|^T|A||phi| relative) and the product's (gamma
    |phi|^T|B||phi|)."""
    A, B, C = fz.A, fz.B, fz.C
    n = A.shape[0]
    g = gamma(n)
    lam, phi = sla.eigh(C, A)
    aA, aB, aC = np.abs(A), np.abs(B), np.abs(C)
    P = np.abs(phi)
    om = np.sqrt(np.abs(lam))
    df = np.zeros(count)
    dz = np.zeros(count)
    for i in range(count):
        Ei = g * (P.T @ (aC + abs(lam[i]) * aA) @ P[:, i])  # |phi_j^T E phi_i| <= Ei[j]
        dlam = Ei[i]
        Bij = np.abs(phi[:, i] @ B @ phi)
        others = np.arange(n) != i
        dq = 2.0 * float(np.sum(Bij[others] * Ei[others] / np.abs(lam[i] - lam[others])))
        q = float(phi[:, i] @ B @ phi[:, i])
        dq += g * float(P[:, i] @ aB @ P[:, i]) + abs(q) * g * float(P[:, i] @ aA @ P[:, i])
        df[i] = dlam / (2.0 * om[i]) / (2 * np.pi)
        zeta = q / (2 * om[i])
        dz[i] = dq / (2 * om[i]) + abs(zeta) * dlam / (2 * abs(lam[i]))
    return 2.0 * df, 2.0 * dz


def frf_tol(fz: Any, omega: np.ndarray, inputs: list[str], outputs: list[str], fb: Any) -> np.ndarray:
    """|dH_ij(omega)| of chatterlab.frf (direct: np.linalg.solve(Delta, B_i),
    then C_o X): H + dH = c_i^T (Delta + dDelta)^-1 b_j with |dDelta| <= gamma
    |Delta's terms|, so |dH_ij| <= gamma |Delta^-H c_i|^T |Delta's terms|
    |Delta^-1 b_j| (Skeel's componentwise bound)."""
    from chatterlab.frequency._frf import _rows

    Co = _rows(fz, outputs, "outputs")
    Bi = _rows(fz, inputs, "inputs").T
    n = fz.A.shape[0]
    out = np.empty((Co.shape[0], Bi.shape[1], omega.size))
    for k, w in enumerate(omega):
        s = 1j * w
        Z = s * s * fz.A + s * fz.B + fz.C
        aZ = abs(s) ** 2 * np.abs(fz.A) + abs(s) * np.abs(fz.B) + np.abs(fz.C)
        if fb is not None:
            Z = Z - fb(s)
            e = abs(np.exp(-s * fb.delay)) if fb.delay is not None else 0.0
            aZ = aZ + np.abs(fb.DP) + abs(s) * np.abs(fb.DV) + e * np.abs(fb.DO)
        X = np.abs(np.linalg.solve(Z, Bi.astype(complex)))
        Y = np.abs(np.linalg.solve(Z.conj().T, Co.T.astype(complex)))
        out[:, :, k] = gamma(n) * (Y.T @ aZ @ X)
    return 2.0 * out


# ============================================================================ milling (Floquet)


def _pencil(S: Any, mill: Any, rpm: float, depth: float, degree: int = 16) -> tuple[np.ndarray, ...]:
    """The spectral-element pencil U(a) X_new = V(a) X_old (chatterlab.frequency.SpectralMonodromy,
    default mesh for this depth) as U0, U1, V0, V1."""
    from chatterlab.frequency import SpectralMonodromy

    sm = SpectralMonodromy(S, mill, rpm, degree, depth_hint=depth)
    return sm.U0, sm.U1, sm.V0, sm.V1


def _eig_condition(
    Ap: np.ndarray, Bp: np.ndarray, mu: complex
) -> tuple[complex, float, np.ndarray, np.ndarray]:
    """The eigenvalue of A x = mu B x nearest mu, its componentwise condition
    |y|^T (|A| + |mu||B|) |x| / |y^H B x| and x, y."""
    w, vl, vr = sla.eig(Ap, Bp, left=True, right=True)
    fin = np.isfinite(w)
    k = int(np.argmin(np.where(fin, np.abs(w - mu), np.inf)))
    x, y = vr[:, k], vl[:, k]
    kap = cw(y, np.abs(Ap) + abs(w[k]) * np.abs(Bp), x) / abs(y.conj() @ Bp @ x)
    return complex(w[k]), float(kap), x, y


def spectral_multiplier_tol(S: Any, mill: Any, rpm: float, depth: float, mu: complex) -> dict[str, Any]:
    """|d mu| of a spectral-element multiplier, an eigenvalue of the pencil
    (V, U) of size N: gamma(N) times its componentwise condition; also
    d mu / d a = y^H (V1 - mu U1) x / y^H U x."""
    U0, U1, V0, V1 = _pencil(S, mill, rpm, depth)
    Up, Vp = U0 + depth * U1, V0 + depth * V1
    m, kap, x, y = _eig_condition(Vp, Up, mu)
    if abs(m - mu) > 1e-6 * max(abs(mu), 1e-3):
        raise AssertionError(f"spectral multiplier {mu} not reproduced ({m}) at {rpm} rpm, {depth} m")
    dmu_da = (y.conj() @ (V1 - m * U1) @ x) / (y.conj() @ Up @ x)
    return {"dmu": gamma(Up.shape[0]) * kap, "dmu_da": complex(dmu_da), "N": Up.shape[0]}


def spectral_crossing_tol(S: Any, mill: Any, rpm: float, a: float, mu0: float) -> float:
    """|da| of a flip (mu0 = -1) or fold (mu0 = +1) depth, which the search
    takes exactly from the real pencil (V0 - mu0 U0) x = -a (V1 - mu0 U1) x:
    gamma(N) times its componentwise eigenvalue condition."""
    U0, U1, V0, V1 = _pencil(S, mill, rpm, a)
    A_, B_ = V0 - mu0 * U0, -(V1 - mu0 * U1)
    m, kap, _, _ = _eig_condition(A_, B_, a)
    if abs(m - a) > 1e-5 * a:
        raise AssertionError(f"crossing depth {a} not reproduced ({m}) at {rpm} rpm")
    return gamma(A_.shape[0]) * kap


def sdm_multiplier_tol(
    S: Any, mill: Any, rpm: float, depth: float, mu: complex, steps: int
) -> dict[str, Any]:
    """|d mu| of a semi-discretisation multiplier: the eigenvalue of the
    monodromy Phi (chatterlab.frequency.sdm_monodromy), a product of ``steps``
    step matrices, each formed and multiplied with a backward error gamma(N):
    |dPhi| <= steps gamma(N) |Phi| (the partial products' |G_k|...|G_1| taken
    as |Phi|: the step matrices are near-identity shifts without
    cancellation), so |d mu| <= steps gamma(N) |y|^T |Phi| |x| / |y^H x|.
    d mu / d a by a central difference (1e-6 a)."""
    from chatterlab.frequency import sdm_monodromy

    Phi = sdm_monodromy(S, mill, rpm, depth, steps)
    N = Phi.shape[0]
    m, kap, _, _ = _eig_condition(Phi, np.eye(N), mu)
    if abs(m - mu) > 1e-9 * max(abs(mu), 1e-3):
        raise AssertionError(f"SDM multiplier {mu} not reproduced ({m})")
    h = 1e-6 * depth

    def top(a: float) -> complex:
        w = np.linalg.eigvals(sdm_monodromy(S, mill, rpm, a, steps))
        return complex(w[np.argmin(np.abs(w - m))])

    dmu_da = (top(depth + h) - top(depth - h)) / (2 * h)
    _, _, x, y = _eig_condition(Phi, np.eye(N), m)
    dmu = steps * gamma(N) * cw(y, np.abs(Phi), x) / abs(y.conj() @ x)
    del kap
    return {"dmu": dmu, "dmu_da": complex(dmu_da), "N": N}


# ============================================================================ time domain


def series_tol(y: np.ndarray, n_state: int) -> np.ndarray:
    """|dy_k| allowed for a linear(ised) step recurrence y_k: each step solves
    and multiplies with a backward error gamma(n_state) of the state, and the
    errors made up to step k add (the average-acceleration scheme does not
    amplify them beyond the growth of the solution itself, which the running
    maximum Y_k = max_{j<=k} |y_j| carries): |dy_k| <= k gamma Y_k, twice."""
    Y = np.maximum.accumulate(np.abs(y))
    k = np.arange(y.size)
    return 2.0 * gamma(n_state) * k * Y


def time_tol(t: np.ndarray) -> np.ndarray:
    """Times of the grid: t_k = k h or a running sum of h: (k + 1) u t_k, twice."""
    k = np.arange(t.size)
    return 2.0 * (k + 1) * U * np.abs(t)


def propagated(f: Any, y: np.ndarray, tol: np.ndarray) -> float:
    """First-order bound of |f(y + dy) - f(y)| over |dy_i| <= tol_i:
    sum_i |df/dy_i| tol_i, the gradient by forward differences of step
    100 tol_i (in the linear range: the same bound from steps of 10 tol_i
    must agree within a factor 2, which is checked), for a fit's output
    against its data: the growth rate of an envelope, a multiplier fitted to
    Poincare samples."""

    def bound(factor: float) -> float:
        f0 = f(y)
        flat = y.reshape(-1)
        tflat = np.broadcast_to(tol, y.shape).reshape(-1)
        total = 0.0
        for i in np.nonzero(tflat > 0)[0]:
            h = factor * tflat[i]
            yp = flat.copy()
            yp[i] += h
            total += abs(f(yp.reshape(y.shape)) - f0) / h * tflat[i]
        return float(total)

    b100, b10 = bound(100.0), bound(10.0)
    if not 0.5 <= b100 / b10 <= 2.0:
        raise AssertionError(f"the fit is not linear at the round-off scale: {b100:.3g} vs {b10:.3g}")
    return max(b100, b10)
