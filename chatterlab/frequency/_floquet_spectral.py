"""Spectral-element collocation of the monodromy operator of milling
(:class:`SpectralMonodromy`): the reference method of
:mod:`chatterlab.frequency._floquet` (see its docstring for the method and
references), with the mesh of sub-elements between the cut's breakpoints."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ..errors import InputError, check_count
from ..process import Milling
from ..process._loop import ClosedLoop

__all__ = ["SpectralMonodromy", "CHECK_DEGREE", "DEGREE", "ELEMENT_SPAN"]

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
    loop, rpm
        The problem: the structure under the cutter (a milling
        :class:`~chatterlab.process.ClosedLoop`, ``loop.process`` the cutter)
        and the spindle speed (rpm).
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
        loop: ClosedLoop,
        rpm: float,
        degree: int = DEGREE,
        elements: int | None = None,
        depth: float | None = None,
        depth_hint: float | None = None,
        mesh: _Mesh | None = None,
        span: float = ELEMENT_SPAN,
    ) -> None:
        p = check_count(degree, "degree", 2)
        milling = loop.milling
        self.structure, self.milling, self.rpm, self.degree = loop, milling, float(rpm), p
        self.helix_depth = depth if milling.helix > 0 else None
        if milling.helix > 0 and depth is None:
            raise InputError("milling with a helix angle: give the depth of cut a_p (depth, m)")
        A = loop.state_matrix
        d = A.shape[0]
        om = self._mesh_omega(depth, depth_hint)
        if mesh is None:
            mesh = _mesh(milling, rpm, self.helix_depth, elements, om, span)
        self.mesh = mesh
        S = mesh.a.size
        self.n_sub = S
        T = mesh.T
        self.period = T
        if S == 0:  # never in the cut: the free structure
            E = sla.expm(A * T)
            self.U0, self.U1 = np.eye(d), np.zeros((d, d))
            self.V0, self.V1 = E, np.zeros((d, d))
            self.cols = np.arange(d)
            return
        U0, U1, V0, V1 = self._assemble()
        self._scale(U0, U1, V0, V1)
        self.U0, self.U1, self.V0, self.V1 = U0, U1, V0, V1
        used = np.nonzero(np.any(V0 != 0, axis=0) | np.any(V1 != 0, axis=0))[0]
        self.cols = used
        self.block = self._block_size()

    def _mesh_omega(self, depth: float | None, depth_hint: float | None) -> float:
        """Frequency scale for the default mesh: the structure's poles, stiffened by the cut."""
        structure, milling = self.structure, self.milling
        _, Jr, W = structure.cut_basis
        a_h = depth_hint if depth_hint is not None else (depth if depth is not None else 0.0)
        om = structure.omega_max
        if a_h:
            Hs = np.abs(milling.zoa()).max() * milling.teeth  # crude bound of |sum H_j|
            kc = a_h * Hs * np.linalg.norm(W, 2) * np.linalg.norm(Jr, 2)
            # capped at twice the structure's: deeper, the convergence check says what is missed
            om = min(math.sqrt(om**2 + kc), 2.0 * om)
        return om

    def _assemble(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """U0 + a U1 (this period's nodes) and V0 + a V1 (the last period's),
        unscaled: continuity across each free gap, collocation at nodes 1..p."""
        structure, milling, mesh, p = self.structure, self.milling, self.mesh, self.degree
        rpm = self.rpm
        A = structure.state_matrix
        d = A.shape[0]
        n = structure.n
        Ub, Jr, W = structure.cut_basis
        S = mesh.a.size
        T = mesh.T
        taus = milling.delays(rpm)
        s_nodes, Dm, bw = _cheb(p)
        nn = p + 1
        N = S * nn * d
        if N > MAX_UNKNOWNS:
            raise InputError(
                f"spectral elements: {S} elements x {nn} nodes x {d} states = {N} unknowns exceed {MAX_UNKNOWNS};"
                " a period this long holds many vibrations of the highest mode: reduce the structure to the modes"
                " that matter (chatterlab.lobes.reduce_structure), lower the degree, or raise the spindle speed"
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
        return U0, U1, V0, V1

    def _scale(self, U0: np.ndarray, U1: np.ndarray, V0: np.ndarray, V1: np.ndarray) -> None:
        """Scale the four matrices in place and keep the column scale."""
        structure, S, p, T = self.structure, self.mesh.a.size, self.degree, self.period
        n, nn = structure.n, p + 1
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

    def _block_size(self) -> int:
        """The rows of one element when U is block lower-bidiagonal, else 0."""
        U0, U1, p, S = self.U0, self.U1, self.degree, self.mesh.a.size
        d = self.structure.state_matrix.shape[0]
        N = U0.shape[0]
        nn = p + 1
        # block lower-bidiagonal U (every delayed value in the previous period: a uniform pitch)
        # is solved element by element, O(S (p d)^2 |cols|) instead of O((S p d)^3)
        b = nn * d
        allowed = np.zeros((N, N), dtype=bool)
        for s in range(S):
            allowed[s * b : (s + 1) * b, s * b : (s + 1) * b] = True
            if s > 0:
                allowed[s * b : s * b + d, (s - 1) * b + p * d : s * b] = True
        return b if not np.any(((U0 != 0) | (U1 != 0)) & ~allowed) else 0

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
        return self._solve_rhs(a, (self.V0 + a * self.V1)[:, self.cols])

    def _solve_rhs(self, a: float, Vc: np.ndarray) -> np.ndarray:
        """U(a)^-1 Vc (element by element where U is block bidiagonal)."""
        b = getattr(self, "block", 0)
        if not b:
            return sla.solve(self.U0 + a * self.U1, Vc, check_finite=False)
        d = self.structure.state_matrix.shape[0]
        X = np.empty_like(Vc)
        for s in range(self.U0.shape[0] // b):
            sl = slice(s * b, (s + 1) * b)
            rhs = Vc[sl].copy()
            if s > 0:
                C = self.U0[s * b : s * b + d, s * b - d : s * b]
                rhs[:d] -= C @ X[s * b - d : s * b]
            X[sl] = np.linalg.solve(self.U0[sl, sl] + a * self.U1[sl, sl], rhs)
        return X

    def tangent(self, depth: float) -> tuple[np.ndarray, np.ndarray]:
        """The nonzero Floquet multipliers mu_k at depth a_p and their
        derivatives d mu_k / d a_p (without helix: U and V affine in a_p).

        With X(a) = U(a)^-1 V(a) the monodromy, dX/da = U^-1 (V1 - U1 X)
        exactly, and for a simple eigenvalue d mu = y^H (dX/da) x / (y^H x)
        with x, y its right and left eigenvectors (first-order perturbation
        theory, e.g. Golub & Van Loan, Matrix Computations, sec. 7.2.2), here
        as the diagonal of W^-1 (dX/da) W with W the right eigenvectors (the
        rows of W^-1 are the left ones, normalised to y^H x = 1).  At a
        defective multiplier (two real multipliers meeting) y^H x = 0 and the
        derivative is infinite: a singular W gives inf, a nearly singular one
        huge rates, which a caller must read as "moves arbitrarily fast
        here"."""
        if self.helix_depth is not None:
            raise InputError("tangent: with a helix the matrices are not affine in a_p")
        a = float(depth)
        cols = self.cols
        Xf = self._solve(a)
        X = Xf[cols]
        mu, vr = np.linalg.eig(X)
        dX = self._solve_rhs(a, self.V1[:, cols] - self.U1 @ Xf)[cols]
        # the rows of vr^-1 are the left eigenvectors scaled so that y^H x = 1
        try:
            dmu = np.einsum("kj,jk->k", np.linalg.solve(vr, dX), vr)
        except np.linalg.LinAlgError:  # defective: no first-order rate
            dmu = np.full(mu.shape, np.inf + 0j)
        # nearly defective: the rates are huge (|W^-1| ~ 1/gap), which the search reads as fast
        dmu = np.where(np.isfinite(dmu), dmu, np.inf)
        order = np.argsort(-np.abs(mu))
        return mu[order], dmu[order]

    def unit_depths(self, z: float, depth_max: float) -> np.ndarray:
        """Every depth a_p in (0, depth_max] at which the discretised
        monodromy has the multiplier z = +1 (fold) or -1 (flip), ascending.

        A multiplier z at depth a is det(V(a) - z U(a)) = 0, with
        V - z U = P0 + a P1 affine in a (P0 = V0 - z U0, P1 = V1 - z U1).  P1
        is nonzero only on the r rows where the cut acts, P1 = E P1[rows]; by
        Sylvester's identity det(P0 + a P1) = det(P0) det(I_r + a M) with
        M = P1[rows] P0^-1 E, so the depths are -1/nu for the real eigenvalues
        nu < 0 of the real r x r matrix M: all of them, from one eigenproblem,
        no sampling (P0 is regular: the free structure, damped, has no
        multiplier on the unit circle).  An eigenvalue within 1e-6 (relative)
        of the real axis is taken as real: a double root (a multiplier
        touching z) is split by rounding into a pair ~sqrt(eps) apart, and
        counting a touch as a crossing errs on the safe side."""
        P1 = self.V1 - z * self.U1
        rows = np.nonzero(np.any(P1 != 0.0, axis=1))[0]
        if rows.size == 0:
            return np.zeros(0)
        P0 = self.V0 - z * self.U0
        E = np.zeros((P0.shape[0], rows.size))
        E[rows, np.arange(rows.size)] = 1.0
        M = P1[rows] @ sla.solve(P0, E, check_finite=False)
        nu = np.linalg.eigvals(M)
        real = (np.abs(nu.imag) <= 1e-6 * np.abs(nu)) & (nu.real < 0.0)
        a = -1.0 / nu.real[real]
        return np.sort(a[a <= depth_max])

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
        d = st.state_matrix.shape[0]
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
                    xs[k] = sla.expm(st.state_matrix * (tk - mesh.b[s_])) @ nodes[s_, p]
                else:  # before the first element: from the last one of the previous period
                    xs[k] = sla.expm(st.state_matrix * (tk + T - mesh.b[-1])) @ nodes[-1, p] / mu
        lam = np.log(complex(mu)) / T
        r = (st.J @ xs[:, :n].T).T  # (samples, 2) tool displacement
        per = r * np.exp(-lam * (t - mesh.t0))[:, None]
        c = np.fft.fft(per, axis=0)
        power = np.sum(np.abs(c) ** 2, axis=1)
        kk = int(np.argmax(power))
        k = kk if kk <= samples // 2 else kk - samples
        return float(abs(lam.imag + 2 * np.pi * k / T) / (2 * np.pi))
