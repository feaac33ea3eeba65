"""Floquet multipliers of milling: a structure under the periodic,
regenerative cutting force of a :class:`~chatterlab.process.Milling` cutter.

The equation (tool point r = J q relative to the workpiece, Eq. 1 of
:mod:`chatterlab.process._milling`)

    M q'' + C q' + K q = -a_p J^T sum_j H_j(t) J [q(t) - q(t - tau_j)]      (1)

has coefficients periodic in T (:meth:`Milling.period`).  With the state
x = (q, q'), one period maps the history on [-T, 0] to the one on [0, T]; the
eigenvalues mu of this monodromy operator are the Floquet multipliers, and
(1) is asymptotically stable iff every |mu| < 1.  A multiplier leaving the
unit circle as a complex pair is a secondary Hopf (quasi-periodic chatter),
at mu = -1 a flip (period doubling), at mu = +1 a fold.

Two discretisations of the operator, each with an explicit accuracy knob:

``"spectral"`` (the reference).  Spectral-element collocation (Butcher et al.
2004; Lehotzky, Insperger & Stepan 2016): the period is cut at the
breakpoints where a tooth enters or leaves the cut, so the coefficients are
analytic on each piece; every piece where a tooth cuts is split into
``elements`` sub-elements carrying Chebyshev-Lobatto collocation of
``degree`` p, and where no tooth cuts the motion is free and solved exactly,
x(t) = e^{A t} x(0).  The delayed argument t - tau_j of a node in tooth j's
cut falls in tooth j-1's cut at the same angle: at a node of the same
sub-element for a uniform pitch, by spectral interpolation otherwise.
For a variable pitch the mesh also has the breakpoints shifted by each
delay (where the solution's fourth derivative jumps), so a delayed image
never straddles a jump of x''.  Unknowns and equations are scaled
(velocities in units of the highest pole frequency), which keeps U well
conditioned without changing the multipliers.  The error falls faster than
any power of p (geometrically); the result reports the change of the
critical multiplier when the degree is raised by ``CHECK_DEGREE`` as its
convergence check.

``"sdm"``.  First-order semi-discretisation (Insperger & Stepan 2004;
Insperger, Stepan & Turi 2008): ``steps`` steps per period, the
coefficients replaced by their exact mean over each step, the delayed
displacement interpolated linearly between the grid values, and each step
solved exactly.  Its multipliers converge as steps^-2.

The depth a_p enters the spectral matrices linearly, U(a) = U0 + a U1 and
V(a) = V0 + a V1 (without helix), so a search over a_p assembles once per
speed (:class:`SpectralMonodromy`).

References
----------
E. A. Butcher, H. Ma, E. Bueler, V. Averina, Z. Szabo, Stability of linear
time-periodic delay-differential equations via Chebyshev polynomials,
Int. J. Numer. Meth. Engng 59 (2004) 895-922.
D. Lehotzky, T. Insperger, G. Stepan, Extension of the spectral element
method for stability analysis of time-periodic delay-differential equations
with multiple and distributed delays, Commun. Nonlinear Sci. Numer. Simul.
35 (2016) 177-189.
T. Insperger, G. Stepan, Updated semi-discretization method for periodic
delay-differential equations with discrete delay, Int. J. Numer. Meth.
Engng 61 (2004) 117-141.
T. Insperger, G. Stepan, J. Turi, On the higher-order semi-discretizations
for periodic delayed systems, J. Sound Vib. 313 (2008) 334-341.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal

import numpy as np
import scipy.linalg as sla

from ..errors import InputError, check_count, check_nonneg, check_positive
from ..process import Milling

__all__ = [
    "ToolStructure",
    "Multipliers",
    "SpectralMonodromy",
    "multipliers",
    "sdm_monodromy",
    "classify",
    "CHECK_DEGREE",
    "DEGREE",
    "ELEMENT_SPAN",
    "chatter_frequency",
]

#: default mesh: sub-elements short enough that omega L <= ELEMENT_SPAN (omega: the highest
#: pole frequency, stiffened by the cut); with the default degree 16 the critical multiplier
#: of the Insperger-Stepan benchmark is then within ~1e-10 of its converged value
ELEMENT_SPAN = 5.0
#: above this many multipliers the spectral radius comes from Arnoldi iterations (measured:
#: 3x faster than the dense QR at 113, slower at 65)
ARNOLDI_MIN = 90
#: largest collocation system assembled (dense: 4 matrices of N^2 doubles, 0.5 GB at 4000)
MAX_UNKNOWNS = 4000
#: default polynomial degree of the spectral elements
DEGREE = 16
#: the convergence check of the spectral method raises the degree by this much
CHECK_DEGREE = 6
#: a multiplier within this angle of the real axis is a flip (pi) or fold (0)
REAL_ANGLE = 1e-6


# ============================================================================ the structure
@dataclass(frozen=True, eq=False)
class ToolStructure:
    """The structure seen by the cutter: M q'' + C q' + K q = J^T F, r = J q.

    Parameters
    ----------
    M, C, K : array, shape (n, n)
        Mass (kg), damping (N s/m) and stiffness (N/m) matrices.
    J : array, shape (2, n)
        Maps q to the tool's displacement r = (x, y) relative to the
        workpiece (feed along +x, see :mod:`chatterlab.process._milling`).
    name : str
        A label for results.
    """

    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    J: np.ndarray
    name: str = "structure"

    def __post_init__(self) -> None:
        M, C, K, J = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (self.M, self.C, self.K, self.J))
        n = M.shape[0]
        for nm, X in (("M", M), ("C", C), ("K", K)):
            if X.shape != (n, n) or not np.all(np.isfinite(X)):
                raise InputError(f"structure {nm} must be a finite {n} x {n} matrix (got shape {X.shape})")
        if J.shape != (2, n) or not np.all(np.isfinite(J)):
            raise InputError(
                f"structure J must be a finite 2 x {n} matrix mapping q to (x, y) (got {J.shape})"
            )
        for nm, X in (("M", M), ("C", C), ("K", K), ("J", J)):
            object.__setattr__(self, nm, X)

    @classmethod
    def single_dof(
        cls, mass: float, omega: float, zeta: float, direction: Literal["x", "y"] = "x"
    ) -> ToolStructure:
        """One mode along x (feed) or y: m x'' + 2 zeta m omega x' + m omega^2 x = F_x."""
        m = check_positive(mass, "mass", "kg")
        w = check_positive(omega, "natural frequency", "rad/s")
        z = check_nonneg(zeta, "damping ratio")
        if direction not in ("x", "y"):
            raise InputError(f"direction must be 'x' or 'y' (got {direction!r})")
        J = np.array([[1.0], [0.0]]) if direction == "x" else np.array([[0.0], [1.0]])
        return cls(
            np.array([[m]]), np.array([[2 * z * m * w]]), np.array([[m * w * w]]), J, f"1-DOF {direction}"
        )

    @classmethod
    def modal(
        cls,
        omega: np.ndarray,
        zeta: np.ndarray,
        stiffness: np.ndarray,
        shapes: np.ndarray,
        name: str = "modal",
    ) -> ToolStructure:
        """Modes in modal coordinates: omega (rad/s), damping ratios, modal
        stiffness k_k (N/m) and shapes (n_modes, 2), the (x, y) entries of
        each mode at the tool, so that r = shapes^T eta."""
        w = np.atleast_1d(np.asarray(omega, dtype=float))
        z = np.atleast_1d(np.asarray(zeta, dtype=float))
        k = np.atleast_1d(np.asarray(stiffness, dtype=float))
        S = np.atleast_2d(np.asarray(shapes, dtype=float))
        if not (w.shape == z.shape == k.shape and S.shape == (w.size, 2)):
            raise InputError(
                "modal: omega, zeta and stiffness need one value per mode and shapes (n_modes, 2)"
            )
        for i in range(w.size):
            check_positive(w[i], f"mode {i + 1} natural frequency", "rad/s")
            check_positive(k[i], f"mode {i + 1} stiffness", "N/m")
            check_nonneg(z[i], f"mode {i + 1} damping ratio")
        m = k / w**2
        return cls(np.diag(m), np.diag(2 * z * m * w), np.diag(k), S.T, name)

    @property
    def n(self) -> int:
        return self.M.shape[0]

    @cached_property
    def A(self) -> np.ndarray:
        """First-order matrix of x = (q, q'), (2n, 2n)."""
        n = self.n
        Mi = np.linalg.inv(self.M)
        return np.block([[np.zeros((n, n)), np.eye(n)], [-Mi @ self.K, -Mi @ self.C]])

    @cached_property
    def cut_basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Ub, Jr, W): r = Ub (Jr q) with Jr (rho, n) of full row rank, and
        W = M^-1 Jr^T (n, rho); the cutting term of (1) is W (Ub^T H Ub) Jr."""
        U, s, Vt = np.linalg.svd(self.J, full_matrices=False)
        rho = int(np.sum(s > 1e-12 * max(s[0], 1e-300)))
        Ub = U[:, :rho]
        Jr = s[:rho, None] * Vt[:rho]
        W = np.linalg.solve(self.M, Jr.T)
        return Ub, Jr, W

    @cached_property
    def omega_max(self) -> float:
        """Largest |Im| of the structure's poles, rad/s."""
        return float(np.max(np.abs(np.linalg.eigvals(self.A).imag), initial=0.0))

    def frf(self, omega: np.ndarray) -> np.ndarray:
        """H(j w) = J (K - w^2 M + j w C)^-1 J^T, m/N, shape (len(w), 2, 2)."""
        w = np.atleast_1d(np.asarray(omega, dtype=float))
        Z = self.K[None] - w[:, None, None] ** 2 * self.M[None] + 1j * w[:, None, None] * self.C[None]
        return self.J[None] @ np.linalg.solve(Z, np.broadcast_to(self.J.T, (w.size,) + self.J.T.shape))

    def stable(self) -> bool:
        return bool(np.all(np.linalg.eigvals(self.A).real < 0))

    def reduce(self, freq_max: float, check_hz: float | None = None) -> tuple[ToolStructure, float]:
        """The structure on its undamped modes below ``freq_max`` (Hz) plus the
        static residual at the tool, and the truncation error at the tool.

        The basis is the modes below ``freq_max`` and the part of the static
        deflections K^-1 J^T that those modes do not carry (residual
        flexibility), M-orthonormalised (a Ritz basis, so the reduced
        static compliance at the tool is exact).  The error returned is
        max |H(jw) - H_r(jw)| / max |H(jw)| over 400 frequencies up to
        ``check_hz`` (default freq_max / 2), H the FRF at the tool: all the
        Floquet problem sees of the structure is this response.
        """
        fmax = check_positive(freq_max, "freq_max", "Hz")
        fchk = check_positive(check_hz, "check_hz", "Hz") if check_hz is not None else fmax / 2
        w2, Phi = sla.eigh(self.K, self.M)
        keep = w2 < (2 * np.pi * fmax) ** 2
        P = Phi[:, keep]
        S = np.linalg.solve(self.K, self.J.T)  # static deflections under unit tool forces
        R = S - P @ (P.T @ (self.M @ S))  # what the kept modes do not carry
        rn = np.sqrt(np.maximum(np.einsum("ij,ik,kj->j", R, self.M, R), 0.0))
        R = R[:, rn > 1e-12 * np.sqrt(np.einsum("ij,ik,kj->j", S, self.M, S)).max()]
        R = R / np.sqrt(np.einsum("ij,ik,kj->j", R, self.M, R))  # unit M-norm, like the modes
        T = np.hstack([P, R])
        # M-orthonormal Ritz basis; drop directions the kept modes already span
        Mt = T.T @ self.M @ T
        lam, V = np.linalg.eigh(Mt)
        ok = lam > 1e-12 * lam.max()
        T = T @ (V[:, ok] / np.sqrt(lam[ok]))
        red = ToolStructure(
            T.T @ self.M @ T, T.T @ self.C @ T, T.T @ self.K @ T, self.J @ T, f"{self.name} (reduced)"
        )
        w = 2 * np.pi * np.linspace(0.0, fchk, 400)
        H, Hr = self.frf(w), red.frf(w)
        err = float(np.max(np.abs(H - Hr)) / np.max(np.abs(H)))
        return red, err


# ============================================================================ results
def classify(mu: complex) -> str:
    """'flip' (mu on the negative real axis), 'fold' (positive real axis) or
    'hopf' (a complex pair: secondary Hopf)."""
    ang = abs(np.angle(mu))
    if ang > math.pi - REAL_ANGLE:
        return "flip"
    if ang < REAL_ANGLE:
        return "fold"
    return "hopf"


@dataclass(frozen=True, eq=False)
class Multipliers:
    """Floquet multipliers of milling at one (rpm, a_p).

    Attributes
    ----------
    mu : ndarray of complex
        The multipliers found, largest modulus first (the discretisation's
        spurious zeros left out).
    critical : complex
        The multiplier of largest modulus.
    kind : str
        Its type: ``"hopf"`` (secondary Hopf, complex pair), ``"flip"``
        (period doubling, mu < 0) or ``"fold"`` (mu > 0).
    spectral_radius : float
        |critical|; stable iff < 1 (to the accuracy ``error``).
    stable : bool
        spectral_radius < 1.
    error : float
        Convergence check: |critical - critical at a higher resolution|
        (spectral: degree + CHECK_DEGREE; SDM: 2 x steps); nan if not run.
    frequency_hz : float
        Chatter frequency, Hz: of the frequencies |arg mu + 2 pi k| / T of the
        critical solution, the dominant harmonic of its eigenvector
        (spectral; :meth:`SpectralMonodromy.critical`), or the one nearest a
        structural pole (SDM).
    method, resolution : str
        ``"spectral"`` with "degree p x elements" or ``"sdm"`` with its steps.
    period : float
        T, s.
    """

    mu: np.ndarray
    critical: complex
    kind: str
    spectral_radius: float
    stable: bool
    error: float
    frequency_hz: float
    method: str
    resolution: str
    period: float
    rpm: float
    depth: float
    elapsed: float = 0.0
    meta: dict[str, float] = field(default_factory=dict)


def chatter_frequency(mu: complex, T: float, structure: ToolStructure) -> float:
    """The member of the family (arg mu + 2 pi k)/T nearest a structural
    pole's frequency (rad/s -> Hz)."""
    base = abs(np.angle(mu)) / T
    poles = np.abs(np.linalg.eigvals(structure.A).imag)
    poles = poles[poles > 0]
    if poles.size == 0:
        return base / (2 * np.pi)
    k = np.arange(-50, 51)
    cand = np.abs(base + 2 * np.pi * k / T)
    d = np.min(np.abs(cand[:, None] - poles[None, :]), axis=1)
    return float(cand[int(np.argmin(d))] / (2 * np.pi))


# ============================================================================ spectral elements
def _cheb(p: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Chebyshev-Lobatto nodes on [0, 1] (ascending), the differentiation
    matrix d/ds on [0, 1], and the barycentric weights."""
    k = np.arange(p + 1)
    x = -np.cos(np.pi * k / p)  # ascending on [-1, 1]
    c = np.ones(p + 1)
    c[0] = c[-1] = 2.0
    c = c * (-1.0) ** k
    X = x[:, None] - x[None, :]
    D = np.outer(c, 1.0 / c) / (X + np.eye(p + 1))
    D = D - np.diag(D.sum(axis=1))
    w = (-1.0) ** k
    w[0] *= 0.5
    w[-1] *= 0.5
    return (x + 1.0) / 2.0, 2.0 * D, w


def _bary(nodes: np.ndarray, w: np.ndarray, s: float) -> np.ndarray:
    """Weights of the polynomial interpolant at s (nodes on [0, 1])."""
    d = s - nodes
    hit = np.nonzero(np.abs(d) < 1e-14)[0]
    if hit.size:
        out = np.zeros(nodes.size)
        out[hit[0]] = 1.0
        return out
    q = w / d
    return q / q.sum()


@dataclass
class _Mesh:
    a: np.ndarray  # sub-element starts (S,)
    b: np.ndarray  # ends
    t0: float  # time origin
    T: float


def _mesh(
    milling: Milling,
    rpm: float,
    depth: float | None,
    elements: int | None,
    omega_max: float,
    span: float = ELEMENT_SPAN,
) -> _Mesh:
    T = milling.period(rpm)
    tb = milling.breakpoints(rpm, depth)
    if tb.size == 0:
        tb = np.array([0.0])
    if not milling.uniform:
        # the solution's second derivative jumps at a breakpoint b, its fourth at b + tau_j: with
        # those as element ends too, a delayed image t - tau_j never straddles a jump of x''
        shifted = np.mod(tb[:, None] + milling.delays(rpm)[None, :], T).ravel()
        tb = np.unique(np.r_[tb, shifted])
        tb = tb[np.r_[True, np.diff(tb) > 1e-9 * T]]
    ends = np.r_[tb, tb[0] + T]
    starts, stops = [], []
    for lo, hi in zip(ends[:-1], ends[1:], strict=True):
        mid = 0.5 * (lo + hi)
        if not np.any(milling.directional(mid, rpm, depth) != 0.0):
            continue
        L = hi - lo
        n_sub = elements if elements is not None else max(1, math.ceil(omega_max * L / span))
        e = lo + L * np.arange(n_sub + 1) / n_sub
        starts.extend(e[:-1])
        stops.extend(e[1:])
    a = np.array(starts)
    b = np.array(stops)
    t0 = float(a[0]) if a.size else 0.0
    return _Mesh(a, b, t0, T)


class SpectralMonodromy:
    """The spectral-element discretisation U(a) X_new = V(a) X_old of one
    period at one speed, assembled once; :meth:`at` gives the multipliers at
    any depth a_p (without helix U and V are affine in a_p).

    Parameters
    ----------
    structure, milling, rpm
        The problem.
    degree : int
        Polynomial degree p of each sub-element (>= 2).
    elements : int, optional
        Sub-elements per cutting piece (default: enough that
        omega_max L <= ELEMENT_SPAN on each, omega_max the structure's highest pole
        frequency, raised with the cutting stiffness at the depth given).
    span : float
        omega L of the default sub-elements (smaller: finer).
    depth : float, optional
        Needed with a helix (the coefficients then depend on a_p
        non-linearly and the matrices are built for this depth only).
    """

    def __init__(
        self,
        structure: ToolStructure,
        milling: Milling,
        rpm: float,
        degree: int = DEGREE,
        elements: int | None = None,
        depth: float | None = None,
        depth_hint: float | None = None,
        mesh: _Mesh | None = None,
        span: float = ELEMENT_SPAN,
    ) -> None:
        p = check_count(degree, "degree", 2)
        self.structure, self.milling, self.rpm, self.degree = structure, milling, float(rpm), p
        self.helix_depth = depth if milling.helix > 0 else None
        if milling.helix > 0 and depth is None:
            raise InputError("milling with a helix angle: give the depth of cut a_p (depth, m)")
        A = structure.A
        d = A.shape[0]
        n = structure.n
        Ub, Jr, W = structure.cut_basis
        # frequency scale for the default mesh: the structure's poles, stiffened by the cut
        a_h = depth_hint if depth_hint is not None else (depth if depth is not None else 0.0)
        om = structure.omega_max
        if a_h:
            Hs = np.abs(milling.zoa()).max() * milling.teeth  # crude bound of |sum H_j|
            kc = a_h * Hs * np.linalg.norm(W, 2) * np.linalg.norm(Jr, 2)
            # capped at twice the structure's: deeper, the convergence check says what is missed
            om = min(math.sqrt(om**2 + kc), 2.0 * om)
        if mesh is None:
            mesh = _mesh(milling, rpm, self.helix_depth, elements, om, span)
        self.mesh = mesh
        S = mesh.a.size
        self.n_sub = S
        T = mesh.T
        self.period = T
        taus = milling.delays(rpm)
        if S == 0:  # never in the cut: the free structure
            E = sla.expm(A * T)
            self.U0, self.U1 = np.eye(d), np.zeros((d, d))
            self.V0, self.V1 = E, np.zeros((d, d))
            self.cols = np.arange(d)
            return
        s_nodes, Dm, bw = _cheb(p)
        nn = p + 1
        N = S * nn * d
        if N > MAX_UNKNOWNS:
            raise InputError(
                f"spectral elements: {S} elements x {nn} nodes x {d} states = {N} unknowns exceed {MAX_UNKNOWNS};"
                " a period this long holds many vibrations of the highest mode: reduce the structure to the modes"
                " that matter (ToolStructure.reduce(freq_max)), lower the degree, or raise the spindle speed"
            )
        U0 = np.zeros((N, N))
        U1 = np.zeros((N, N))
        V0 = np.zeros((N, N))
        V1 = np.zeros((N, N))

        def blk(s: int, k: int) -> slice:
            i = (s * nn + k) * d
            return slice(i, i + d)

        t_nodes = mesh.a[:, None] + (mesh.b - mesh.a)[:, None] * s_nodes[None, :]
        expm_cache: dict[float, np.ndarray] = {}

        def expA(g: float) -> np.ndarray:
            key = round(g / T, 14)
            if key not in expm_cache:
                expm_cache[key] = sla.expm(A * g) if g > 0 else np.eye(d)
            return expm_cache[key]

        I_d = np.eye(d)
        qrows = slice(n, 2 * n)  # the q' equations
        for s in range(S):
            L = mesh.b[s] - mesh.a[s]
            # continuity with the previous sub-element, through the free gap between them
            r0 = blk(s, 0)
            U0[r0, r0] = I_d
            if s == 0:
                gap = mesh.a[0] + T - mesh.b[S - 1]
                V0[r0, blk(S - 1, p)] = expA(gap)
            else:
                gap = mesh.a[s] - mesh.b[s - 1]
                U0[r0, blk(s - 1, p)] = -expA(gap)
            # collocation at nodes 1..p
            tk = t_nodes[s, 1:]
            # the coefficients of this piece, continued to its ends (one-sided at a breakpoint)
            Hk = milling.directional_on(tk, rpm, 0.5 * (mesh.a[s] + mesh.b[s]), self.helix_depth)
            Hr = np.einsum("ai,kjab,bl->kjil", Ub, Hk, Ub)  # reduced (p, N, rho, rho)
            Bq_all = np.einsum("ni,kjil,lm->kjnm", W, Hr, Jr)  # (p, N, n, n): on q, in the q' rows
            e0 = s * nn * d
            rows = slice(e0 + d, e0 + nn * d)
            U0[rows, e0 : e0 + nn * d] += np.kron(Dm[1:, :] / L, I_d) - np.kron(np.eye(nn)[1:], A)
            for k in range(1, nn):
                r = blk(s, k)
                Bsum = Bq_all[k - 1].sum(axis=0)
                U1[r, blk(s, k)][qrows, :n] += Bsum
                for j in range(milling.teeth):
                    Bq = Bq_all[k - 1, j]
                    if not np.any(Bq):
                        continue
                    # delayed value x(t_k - tau_j)
                    td = t_nodes[s, k] - taus[j]
                    old = td <= mesh.t0 + 1e-12 * T  # x(t0) is the old period's end: keeps U bidiagonal
                    if old:
                        td += T
                    target = V1 if old else U1
                    sign = 1.0 if old else -1.0
                    if old and abs(td - t_nodes[s, k]) <= 1e-12 * T:  # one period back: the same node
                        target[r, blk(s, k)][qrows, :n] += Bq
                        continue
                    for col, wgt in self._locate(td, mesh, s_nodes, bw, p, d, expA):
                        target[r, col][qrows, :] += sign * (Bq @ wgt[:n, :])
        # scaling (it leaves the multipliers alone): velocities in units of omega_s = the highest
        # pole frequency, each equation divided by its largest natural size (1 for continuity of
        # q, omega_s for q' = v, omega_s^2 for the equations of motion); unscaled, U's condition
        # number reached 1e12 on a variable-pitch mesh and the multipliers scattered by 1e-7
        ws = max(structure.omega_max, 1.0 / T)
        unit = np.r_[np.ones(n), np.full(n, ws)]
        col = np.tile(unit, S * nn)
        row_c = np.r_[np.ones(n), np.full(n, 1.0 / ws)]  # continuity rows (node 0)
        row_e = np.r_[np.full(n, 1.0 / ws), np.full(n, 1.0 / ws**2)]  # collocation rows
        row = np.tile(np.r_[row_c, np.tile(row_e, p)], S)
        for X_ in (U0, U1, V0, V1):
            X_ *= row[:, None]
            X_ *= col[None, :]
        self.colscale = col
        self.U0, self.U1, self.V0, self.V1 = U0, U1, V0, V1
        used = np.nonzero(np.any(V0 != 0, axis=0) | np.any(V1 != 0, axis=0))[0]
        self.cols = used
        # block lower-bidiagonal U (every delayed value in the previous period: a uniform pitch)
        # is solved element by element, O(S (p d)^2 |cols|) instead of O((S p d)^3)
        b = nn * d
        allowed = np.zeros((N, N), dtype=bool)
        for s in range(S):
            allowed[s * b : (s + 1) * b, s * b : (s + 1) * b] = True
            if s > 0:
                allowed[s * b : s * b + d, (s - 1) * b + p * d : s * b] = True
        self.block = b if not np.any(((U0 != 0) | (U1 != 0)) & ~allowed) else 0

    @staticmethod
    def _locate(td, mesh, s_nodes, bw, p, d, expA):
        """(column slice, d x d weight) pairs giving x(td) from the nodes."""
        nn = p + 1
        tol = 1e-12 * mesh.T
        inside = np.nonzero((mesh.a - tol <= td) & (td <= mesh.b + tol))[0]
        if inside.size:
            s = int(inside[0])
            u = (td - mesh.a[s]) / (mesh.b[s] - mesh.a[s])
            wts = _bary(s_nodes, bw, min(max(u, 0.0), 1.0))
            out = []
            for l_ in np.nonzero(wts)[0]:
                i = (s * nn + int(l_)) * d
                out.append((slice(i, i + d), wts[l_] * np.eye(d)))
            return out
        before = np.nonzero(mesh.b <= td)[0]
        s = int(before[-1]) if before.size else mesh.a.size - 1
        g = td - mesh.b[s] if before.size else td + mesh.T - mesh.b[s]
        i = (s * nn + p) * d
        return [(slice(i, i + d), expA(g))]

    @property
    def size(self) -> int:
        return self.U0.shape[0]

    def _solve(self, a: float) -> np.ndarray:
        """X = U(a)^-1 V(a)[:, cols]."""
        Vc = (self.V0 + a * self.V1)[:, self.cols]
        b = getattr(self, "block", 0)
        if not b:
            return sla.solve(self.U0 + a * self.U1, Vc, check_finite=False)
        d = self.structure.A.shape[0]
        X = np.empty_like(Vc)
        for s in range(self.U0.shape[0] // b):
            sl = slice(s * b, (s + 1) * b)
            rhs = Vc[sl].copy()
            if s > 0:
                C = self.U0[s * b : s * b + d, s * b - d : s * b]
                rhs[:d] -= C @ X[s * b - d : s * b]
            X[sl] = np.linalg.solve(self.U0[sl, sl] + a * self.U1[sl, sl], rhs)
        return X

    def at(self, depth: float) -> np.ndarray:
        """The nonzero Floquet multipliers at depth a_p, largest modulus first."""
        a = float(depth)
        X = self._solve(a)
        mu = np.linalg.eigvals(X[self.cols])
        return mu[np.argsort(-np.abs(mu))]

    def radius(self, depth: float) -> float:
        """The spectral radius at depth a_p: the largest |mu|.  Above
        ``ARNOLDI_MIN`` multipliers it comes from ARPACK's implicitly
        restarted Arnoldi (6 largest, tolerance 1e-14, fixed start vector),
        else (or if ARPACK does not converge) from the dense eigenvalues."""
        X = self._solve(float(depth))[self.cols]
        if X.shape[0] > ARNOLDI_MIN:
            from scipy.sparse.linalg import ArpackNoConvergence, eigs

            try:
                w = eigs(X, k=6, which="LM", v0=np.ones(X.shape[0]), tol=1e-14, return_eigenvectors=False)
                return float(np.max(np.abs(w)))
            except ArpackNoConvergence:
                pass
        return float(np.max(np.abs(np.linalg.eigvals(X))))

    def critical(self, depth: float, samples: int = 128) -> tuple[complex, float]:
        """The critical multiplier at depth a_p and the frequency (Hz) of its
        solution's dominant harmonic.

        The Floquet solution is x(t) = e^{lambda t} p(t) with p T-periodic and
        lambda = ln(mu) / T; its frequencies are Im(lambda) + k 2 pi / T.  The
        eigenvector gives x on the nodes; x(t) on ``samples`` uniform times of
        the period (interpolated on the elements, propagated exactly across
        the free gaps), times e^{-lambda t}, is p(t), and the largest
        Fourier coefficient of its displacement at the tool picks k.
        """
        a = float(depth)
        X = self._solve(a)
        mu, vec = np.linalg.eig(X[self.cols])
        i = int(np.argmax(np.abs(mu)))
        m = complex(mu[i])
        x_new = (X @ vec[:, i]) * getattr(self, "colscale", 1.0)
        return m, self._dominant_hz(m, x_new, samples)

    def _dominant_hz(self, mu: complex, x_nodes: np.ndarray, samples: int) -> float:
        mesh = self.mesh
        T = self.period
        st = self.structure
        d = st.A.shape[0]
        n = st.n
        if mesh.a.size == 0 or mu == 0:
            return float(abs(np.angle(mu)) / T / (2 * np.pi))
        p = self.degree
        s_nodes, _, bw = _cheb(p)
        nodes = x_nodes.reshape(mesh.a.size, p + 1, d)
        t = mesh.t0 + T * np.arange(samples) / samples
        xs = np.empty((samples, d), dtype=complex)
        for k, tk in enumerate(t):
            inside = np.nonzero((mesh.a <= tk) & (tk <= mesh.b))[0]
            if inside.size:
                s_ = int(inside[0])
                w = _bary(s_nodes, bw, (tk - mesh.a[s_]) / (mesh.b[s_] - mesh.a[s_]))
                xs[k] = w @ nodes[s_]
            else:
                before = np.nonzero(mesh.b <= tk)[0]
                if before.size:
                    s_ = int(before[-1])
                    xs[k] = sla.expm(st.A * (tk - mesh.b[s_])) @ nodes[s_, p]
                else:  # before the first element: from the last one of the previous period
                    xs[k] = sla.expm(st.A * (tk + T - mesh.b[-1])) @ nodes[-1, p] / mu
        lam = np.log(complex(mu)) / T
        r = (st.J @ xs[:, :n].T).T  # (samples, 2) tool displacement
        per = r * np.exp(-lam * (t - mesh.t0))[:, None]
        c = np.fft.fft(per, axis=0)
        power = np.sum(np.abs(c) ** 2, axis=1)
        kk = int(np.argmax(power))
        k = kk if kk <= samples // 2 else kk - samples
        return float(abs(lam.imag + 2 * np.pi * k / T) / (2 * np.pi))


# ============================================================================ semi-discretisation
def _sdm_steps(A_i: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """e^{A dt}, int_0^dt e^{A(dt-s)} ds and int_0^dt e^{A(dt-s)} s ds (Van Loan)."""
    d = A_i.shape[0]
    Z = np.zeros((3 * d, 3 * d))
    Z[:d, :d] = A_i
    Z[:d, d : 2 * d] = np.eye(d)
    Z[d : 2 * d, 2 * d :] = np.eye(d)
    E = sla.expm(Z * dt)
    return E[:d, :d], E[:d, d : 2 * d], E[:d, 2 * d :]


def sdm_monodromy(
    structure: ToolStructure, milling: Milling, rpm: float, depth: float, steps: int = 40
) -> np.ndarray:
    """Monodromy matrix of first-order semi-discretisation (Insperger, Stepan
    & Turi 2008), ``steps`` steps per period, built as a product of dense
    step matrices (as the method's authors do).

    The state is (x_i, r_{i-1}, ..., r_{i-L}) with r = Jr q the cut
    coordinates; on step i the coefficients are their exact mean over the
    step and r(t - tau_j) is linear between its values at the step's ends,
    each interpolated linearly on the grid.  Helix is not supported (the
    spectral method takes it).
    """
    m = check_count(steps, "steps", 2)
    if milling.helix > 0:
        raise InputError("sdm: helix is not supported; use method='spectral'")
    a = check_nonneg(depth, "depth of cut a_p", "m")
    A = structure.A
    d = A.shape[0]
    n = structure.n
    Ub, Jr, W = structure.cut_basis
    rho = Jr.shape[0]
    T = milling.period(rpm)
    dt = T / m
    taus = milling.delays(rpm) / dt
    mj = np.floor(taus + 1e-9).astype(int)
    fj = np.clip(taus - mj, 0.0, None)
    if np.any(mj < 1):
        raise InputError(f"sdm: steps must make the step shorter than the shortest delay (steps >= {m * 2})")
    Lh = int(mj.max()) + 1  # history r_{i-1} .. r_{i-Lh}
    D = d + rho * Lh
    t = np.arange(m + 1) * dt
    Hm = milling.directional_mean(t[:-1], t[1:], rpm)  # (m, N, 2, 2)
    Hr = np.einsum("ai,kjab,bl->kjil", Ub, Hm, Ub)
    Phi = np.eye(D)
    # r at grid index i - k for k >= 0: k = 0 is Jr q_i (from x), k >= 1 history slot k - 1
    Jq = np.zeros((rho, d))
    Jq[:, :n] = Jr

    def r_cols(k: int) -> tuple[slice, np.ndarray]:
        if k == 0:
            return slice(0, d), Jq
        i = d + (k - 1) * rho
        return slice(i, i + rho), np.eye(rho)

    for i in range(m):
        Bsum = np.zeros((d, d))
        Gs = []
        for j in range(milling.teeth):
            Hj = Hr[i, j]
            if not np.any(Hj):
                continue
            Bq = np.zeros((d, rho))
            Bq[n:] = a * (W @ Hj)  # force term per unit r, q' rows
            Bsum[:, :n] += Bq @ Jr
            Gs.append((j, Bq))
        P, F1, F2 = _sdm_steps(A - Bsum, dt)
        G = np.zeros((D, D))
        G[:d, :d] = P
        for j, Bq in Gs:
            # r(t_i - tau_j) = (1 - f) r_{i-m_j} + f r_{i-m_j-1}; r(t_{i+1} - tau_j) likewise shifted by one
            c0 = (F1 - F2 / dt) @ Bq  # weight of u0 (value at the step start)
            c1 = (F2 / dt) @ Bq  # weight of u1 (value at the step end)
            for k, wgt in ((mj[j], 1 - fj[j]), (mj[j] + 1, fj[j])):
                if wgt:
                    sl, R = r_cols(int(k))
                    G[:d, sl] += wgt * c0 @ R
            for k, wgt in ((mj[j] - 1, 1 - fj[j]), (mj[j], fj[j])):
                if wgt:
                    sl, R = r_cols(int(k))
                    G[:d, sl] += wgt * c1 @ R
        # shift the history: new r_{i} = Jr q_i, r_{i-k} <- r_{i-k+1}
        G[d : d + rho, :d] = Jq
        for k in range(1, Lh):
            G[d + k * rho : d + (k + 1) * rho, d + (k - 1) * rho : d + k * rho] = np.eye(rho)
        Phi = G @ Phi
    return Phi


# ============================================================================ entry point
def multipliers(
    structure: ToolStructure,
    milling: Milling,
    rpm: float,
    depth: float,
    *,
    method: Literal["spectral", "sdm"] = "spectral",
    degree: int = DEGREE,
    elements: int | None = None,
    steps: int = 40,
    check: bool = True,
) -> Multipliers:
    """Floquet multipliers of milling at spindle speed ``rpm`` and depth ``depth`` (a_p, m).

    Parameters
    ----------
    structure : ToolStructure
    milling : Milling
    rpm : float
        Spindle speed, rpm.
    depth : float
        Axial depth of cut a_p, m (>= 0).
    method : {"spectral", "sdm"}
        Spectral-element collocation (reference) or first-order
        semi-discretisation.
    degree, elements : int
        Spectral: polynomial degree and sub-elements per cutting piece.
    steps : int
        SDM: steps per period.
    check : bool
        Also compute at a higher resolution (spectral: degree +
        CHECK_DEGREE; SDM: 2 x steps) and report the change of the critical
        multiplier as ``error``.

    Returns
    -------
    Multipliers

    References
    ----------
    See the module docstring.
    """
    t0 = time.perf_counter()
    a = check_nonneg(depth, "depth of cut a_p", "m")
    if method == "spectral":
        sm = SpectralMonodromy(structure, milling, rpm, degree, elements, depth=a, depth_hint=a)
        mu = sm.at(a)
        f_hz = sm.critical(a)[1]
        err = float("nan")
        if check:
            sm2 = SpectralMonodromy(
                structure, milling, rpm, degree + CHECK_DEGREE, depth=a, depth_hint=a, mesh=sm.mesh
            )
            err = float(abs(sm2.at(a)[0] - mu[0]))
        res = f"degree {degree} x {sm.n_sub} elements"
        T = sm.period
    elif method == "sdm":
        Phi = sdm_monodromy(structure, milling, rpm, a, steps)
        mu = np.linalg.eigvals(Phi)
        mu = mu[np.argsort(-np.abs(mu))]
        err = float("nan")
        if check:
            mu2 = np.linalg.eigvals(sdm_monodromy(structure, milling, rpm, a, 2 * steps))
            err = float(abs(mu2[np.argmax(np.abs(mu2))] - mu[0]))
        res = f"{steps} steps"
        T = milling.period(rpm)
        f_hz = chatter_frequency(complex(mu[0]), T, structure)
    else:
        raise InputError(f"method must be 'spectral' or 'sdm' (got {method!r})")
    mu = mu[np.abs(mu) > 1e-300]
    c = complex(mu[0])
    return Multipliers(
        mu=mu,
        critical=c,
        kind=classify(c),
        spectral_radius=abs(c),
        stable=bool(abs(c) < 1.0),
        error=err,
        frequency_hz=f_hz,
        method=method,
        resolution=res,
        period=T,
        rpm=float(rpm),
        depth=a,
        elapsed=time.perf_counter() - t0,
    )
