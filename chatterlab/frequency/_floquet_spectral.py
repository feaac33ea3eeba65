"""Spectral-element collocation of the monodromy operator of milling
(:class:`SpectralMonodromy`): the reference method of
:mod:`chatterlab.frequency._floquet` (see its docstring for the method and
references), with the mesh of sub-elements between the cut's breakpoints.

The discretisation and its factored form
----------------------------------------
One period is cut into sub-elements where a tooth cuts (free gaps between
them are solved exactly, x(t) = e^{A t} x(0)); element s carries
Chebyshev-Lobatto collocation of degree p_s.  Its unknowns are the states at
its nodes; the cut enters the collocation equations only through the force
on the tool at the nodes 1..p_s, F_i = -a_p [H_i r_i - sum_j H_j(t_i)
r(t_i - tau_j)] (r = C x the cut coordinates, H_i = sum_j H_j(t_i)).  The
collocation equations are therefore U(a) X = V(a) z with U(a) = U0 + a U1,
V(a) = V0 + a V1 affine in a_p (Butcher et al. 2004), and U1, V1 of rank
rho (the cut's rank) per node.  Instead of assembling and solving these
N x N systems at every depth, the free structure's part U0 (block
lower-bidiagonal: element by element) is solved once per speed, for the
state carried over from the last period and for a unit force at every node,
and the cut is eliminated in the m_f = rho x (nodes) force unknowns:

    X(a) = X0 + a P (I + a K)^-1 Q                                           (1)

where z (size k) holds what the next period needs of the last one (the
state at its end and the cut coordinates at the nodes a delayed argument
falls on), X0 the free structure's map of z, P the response of z to the
nodal forces, K the nodal forces' response to themselves through the
structure and the cut, Q the forces' dependence on z.  (1) is exact (a
Woodbury identity of U(a)^-1 V(a), restricted to z, which has the same
nonzero eigenvalues), and:

* d X / d a = P (I + a K)^-2 Q exactly, with the same factorisation;
* the depths with a multiplier mu = z0 are a = -1/nu for the eigenvalues nu
  of K + Q (X0 - z0 I)^-1 P (m_f x m_f; :meth:`SpectralMonodromy.unit_depths`);
* every evaluation at a depth costs O(m_f^2 k) and an eigenproblem of size
  k, independent of the number of collocation unknowns N;
* a structure whose high modes respond quasi-statically enters through an
  extra compliance in K and P (:class:`QuasiStatic`) without resolving
  them in time (:func:`split_structure`).

The mesh: a piece between breakpoints is one element of degree chosen from
its length (``degree=None``: the solution there oscillates omega L / 2 pi
times, omega the highest pole frequency; Chebyshev interpolation of such a
solution converges once p exceeds ~ omega L e / 4, geometrically after,
:func:`auto_degree`), split only when that degree would exceed
``P_MAX``; or, with an explicit degree, sub-elements with omega L <= span.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import Any

import numpy as np
import scipy.linalg as sla

from ..errors import InputError, check_count
from ..process import Milling
from ..process._damping import milling_rubbing
from ..process._loop import ClosedLoop

__all__ = [
    "SpectralMonodromy",
    "QuasiStatic",
    "split_structure",
    "split_frequency",
    "needs_split",
    "auto_degree",
    "spectral_mesh",
    "CHECK_DEGREE",
    "DEGREE",
    "ELEMENT_SPAN",
]

#: free multipliers (a_p = 0) this close, relative to the largest, are one repeated eigenvalue
#: (a symmetric tool's: equal to rounding, ~1e-15), whose rates are those of the projected
#: derivative (:meth:`SpectralMonodromy._tangent_free`)
REPEATED = 1e-10
#: ... if semisimple: its eigenvectors' condition number at most this (defective, Jordan
#: blocks: LAPACK's vectors nearly parallel, condition ~ eps^-1/2 and beyond)
SEMISIMPLE = 1e6
#: default mesh with an explicit degree: sub-elements short enough that omega L <= ELEMENT_SPAN
#: (omega: the highest pole frequency, stiffened by the cut); with the degree 16 the critical
#: multiplier of the Insperger-Stepan benchmark is then within ~1e-10 of its converged value
ELEMENT_SPAN = 5.0
#: above this many multipliers the spectral radius comes from Arnoldi iterations on (1)
ARNOLDI_MIN = 160
#: largest discretisation set up: nodal states x (force unknowns + carried state), in doubles
MAX_ENTRIES = 6e7
#: default polynomial degree of the spectral elements (explicit-degree meshes)
DEGREE = 16
#: the convergence check of the spectral method raises the degree by this much
CHECK_DEGREE = 6
#: degrees of the automatic mesh: at least P_MIN; a piece that would need more than P_MAX is split
P_MIN, P_MAX = 10, 48


# ============================================================================ spectral elements
@lru_cache(maxsize=64)
def _cheb(p: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Chebyshev-Lobatto nodes on [0, 1] (ascending), the differentiation
    matrix d/ds on [0, 1], and the barycentric weights (read-only, cached)."""
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
    out = ((x + 1.0) / 2.0, 2.0 * D, w)
    for a in out:
        a.setflags(write=False)
    return out


def _bary(nodes: np.ndarray, w: np.ndarray, s: np.ndarray | float) -> np.ndarray:
    """Weights of the polynomial interpolant at s (nodes on [0, 1]), shape s.shape + (p+1,)."""
    s = np.asarray(s, dtype=float)
    d = s[..., None] - nodes
    hit = np.abs(d) < 1e-14
    with np.errstate(divide="ignore", invalid="ignore"):
        q = w / d
        q = q / q.sum(axis=-1, keepdims=True)
    on = hit.any(axis=-1)
    return np.where(on[..., None], hit.astype(float), q)


def auto_degree(omega_L: float, tol: float) -> int:
    """Collocation degree for an element over which the solution turns by
    omega L radians, aiming at a relative error ~tol of the multipliers.

    Chebyshev interpolation of e^{i omega t} on an element of length L has
    coefficients ~ J_k(omega L / 2) (Bessel), which fall below eps once
    (e omega L / 4k)^k < eps: for k beyond e omega L / 4 the fall is
    geometric, a decade per ~log10(4k / (e omega L))^-1 degrees.  The rule
    solves (e omega L / 4 p)^p = tol for p with a margin of 6 degrees for the
    solution's other components (the coefficients' own variation, the cut's
    stiffening) and the factor the limit's sensitivity adds, measured on the
    benchmark at 5000-25000 rpm and full immersion (tests/test_milling_speed.py
    checks the error it gives)."""
    wl = max(float(omega_L), 1e-3)
    goal = math.log(1.0 / max(tol, 1e-15))
    # no p <= e omega L / 4 passes (its base is <= 1): start above them
    p = min(max(P_MIN - 6, 2, int(math.e * wl / 4.0)), 200)
    while p < 200:
        base = 4.0 * p / (math.e * wl)
        if base > 1.0 and p * math.log(base) >= goal:
            break
        p += 1
    return max(P_MIN, p + 1 + math.ceil(wl / 10.0))


@dataclass(frozen=True)
class _Mesh:
    a: np.ndarray  # sub-element starts (S,)
    b: np.ndarray  # ends
    t0: float  # time origin
    T: float
    deg: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))  # degree per element (S,)

    def raised(self, by: int) -> _Mesh:
        """The same elements, every degree raised by ``by`` (the convergence check)."""
        return replace(self, deg=self.deg + int(by))

    def finer(self) -> _Mesh:
        """Every element split in two, same degrees (a refinement of the mesh)."""
        mid = 0.5 * (self.a + self.b)
        a = np.ravel(np.column_stack([self.a, mid]))
        b = np.ravel(np.column_stack([mid, self.b]))
        return replace(self, a=a, b=b, deg=np.repeat(self.deg, 2))


@lru_cache(maxsize=256)
def _pieces(
    milling: Milling, rpm: float, depth: float | None
) -> tuple[float, tuple[tuple[float, float], ...]]:
    """The period and its pieces between breakpoints where a tooth cuts (cached: a search
    builds several meshes per speed)."""
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
    mids = 0.5 * (ends[:-1] + ends[1:])
    cut = np.any(milling.directional(mids, rpm, depth) != 0.0, axis=(-3, -2, -1))
    return T, tuple((float(lo), float(hi)) for lo, hi, c in zip(ends[:-1], ends[1:], cut, strict=True) if c)


def _mesh(
    milling: Milling,
    rpm: float,
    depth: float | None,
    elements: int | None,
    omega_max: float,
    span: float,
    degree: int | None,
    tol: float,
) -> _Mesh:
    T, pieces = _pieces(milling, float(rpm), depth)
    starts: list[float] = []
    stops: list[float] = []
    degs: list[int] = []
    for lo, hi in pieces:
        L = hi - lo
        wl = omega_max * L
        if elements is not None:
            n_sub, p = elements, int(degree if degree is not None else DEGREE)
        elif degree is not None:
            n_sub, p = max(1, math.ceil(wl / span)), int(degree)
        else:
            n_sub = 1
            while auto_degree(wl / n_sub, tol) > P_MAX:
                n_sub += 1
            p = auto_degree(wl / n_sub, tol)
        e = lo + L * np.arange(n_sub + 1) / n_sub
        starts.extend(e[:-1])
        stops.extend(e[1:])
        degs.extend([p] * n_sub)
    a = np.array(starts)
    b = np.array(stops)
    t0 = float(a[0]) if a.size else 0.0
    return _Mesh(a, b, t0, T, np.array(degs, dtype=int))


def spectral_mesh(
    loop: ClosedLoop,
    rpm: float,
    degree: int | None = DEGREE,
    elements: int | None = None,
    *,
    depth: float | None = None,
    depth_hint: float | None = None,
    span: float = ELEMENT_SPAN,
    tol: float = 1e-10,
) -> _Mesh:
    """The mesh :class:`SpectralMonodromy` builds with these arguments (cheap: a
    search compares meshes before setting one up)."""
    milling = loop.milling
    helix_depth = depth if milling.helix > 0 else None
    om = _mesh_omega(loop, depth, depth_hint)
    return _mesh(milling, float(rpm), helix_depth, elements, om, span, degree, tol)


def _mesh_omega(loop: ClosedLoop, depth: float | None, depth_hint: float | None) -> float:
    """Frequency scale for the default mesh: the structure's poles, stiffened by the cut."""
    a_h = depth_hint if depth_hint is not None else (depth if depth is not None else 0.0)
    om, per_depth = _stiffening(loop)
    if a_h:
        # capped at twice the structure's: deeper, the convergence check says what is missed
        om = min(math.sqrt(om**2 + a_h * per_depth), 2.0 * om)
    return max(om, 1e-9)


@lru_cache(maxsize=32)
def _stiffening(loop: ClosedLoop) -> tuple[float, float]:
    """The structure's highest pole frequency (rad/s) and a bound of the cut's added
    stiffness per unit mass and depth, |sum_j H_j| |W| |Jr| (1/(s^2 m))."""
    milling = loop.milling
    _, Jr, W = loop.cut_basis
    Hs = np.abs(milling.zoa()).max() * milling.teeth  # crude bound of |sum H_j|
    return float(loop.omega_max), float(Hs * np.linalg.norm(W, 2) * np.linalg.norm(Jr, 2))


# ============================================================================ quasi-static modes
@dataclass(frozen=True)
class QuasiStatic:
    """A structure split into the modes below a frequency, integrated in
    time, and the rest, which respond quasi-statically (:func:`split_structure`).

    ``loop``: the milling loop on the kept modes (mass-normalised modal
    coordinates, the damping projected); ``compliance``: the static
    compliance of the other modes between the cut's coordinates r = Jr q
    (rho x rho, m/N), added to the kept modes' response at every instant
    (the static residual of modal truncation augmentation, here exact and
    massless: no pseudo-frequency to resolve in time); ``kept``,
    ``n_full``, ``f_split``: what was kept (Hz for the frequency)."""

    loop: ClosedLoop
    compliance: np.ndarray
    kept: int
    n_full: int
    f_split: float

    def note(self) -> str:
        return (
            f"{self.kept} of {self.n_full} modes integrated (below {self.f_split:.4g} Hz), the others"
            " quasi-static (their exact static compliance at the tool)"
        )


def split_structure(loop: ClosedLoop, f_split: float) -> QuasiStatic:
    """The loop's structure as its undamped modes below ``f_split`` (Hz) plus
    the exact static compliance of all the others at the cut (see
    :class:`QuasiStatic`).

    The kept modes are exact (Rayleigh-Ritz on eigenvectors of (K, M)); the
    others' static compliance Jr (K^-1 - Phi_k Lambda_k^-1 Phi_k^T) Jr^T is
    exact (Dickens, Nakagawa & Wittbrodt, Comput. Struct. 62 (1997) 985-998,
    without the residual's pseudo-mass); what is neglected is their dynamic
    amplification 1/(1 - (w/w_j)^2) - 1 ~ (w/w_j)^2 at the frequencies w
    the cut drives, and their damping's coupling to the kept modes."""
    C, K = loop.C, loop.K
    _, Jr, _ = loop.cut_basis
    lam, Phi = _modes(loop)
    keep = np.sqrt(lam) < 2 * np.pi * f_split
    if not np.any(keep):
        keep[0] = True
    P = Phi[:, keep]
    static = Jr @ np.linalg.solve(K, Jr.T)
    JP = Jr @ P
    G = static - JP @ (JP / lam[keep]).T
    from ..structure import Structure

    red = Structure(np.eye(P.shape[1]), P.T @ C @ P, np.diag(lam[keep]), (), f"{loop.name} (modes)")
    rl = replace(loop, structure=red, J=loop.J @ P, force=P.T @ loop.force, frozen=None)
    n_kept = int(np.count_nonzero(keep))
    return QuasiStatic(rl, 0.5 * (G + G.T), n_kept, loop.n, float(f_split))


@lru_cache(maxsize=8)
def _modes(loop: ClosedLoop) -> tuple[np.ndarray, np.ndarray]:
    """Undamped modes of the loop's structure: omega^2 ascending and mass-normalised shapes."""
    lam, Phi = sla.eigh(loop.K, loop.M)
    return np.maximum(lam, np.finfo(float).tiny), Phi


#: the modes carrying at least this share of the cut's static compliance are the significant ones
SIGNIFICANT = 0.05
#: modes above this many times the highest significant one may respond quasi-statically
SPLIT_RATIO = 4.0
#: a discretisation with more multipliers than this (at the slowest speed, deepest cut) splits
SPLIT_SIZE = 200


def split_frequency(loop: ClosedLoop) -> float | None:
    """SPLIT_RATIO times the highest natural frequency (Hz) among the modes
    that carry at least SIGNIFICANT of the static compliance at the cut (its
    trace over the cut's coordinates: the modes the cut can excite); None
    when no mode lies above it (nothing to split)."""
    _, Jr, _ = loop.cut_basis
    lam, Phi = _modes(loop)
    contrib = np.sum((Jr @ Phi) ** 2, axis=0) / lam
    f = np.sqrt(lam) / (2 * np.pi)
    f_split = SPLIT_RATIO * float(f[contrib >= SIGNIFICANT * contrib.sum()].max())
    return f_split if f.max() > f_split else None


def needs_split(loop: ClosedLoop, rpm: float, depth: float, tol: float) -> float | None:
    """The split frequency (Hz) when the structure's own discretisation at
    ``rpm`` and cuts to ``depth`` would have more than SPLIT_SIZE
    multipliers and some modes may respond quasi-statically; else None."""
    f = split_frequency(loop)
    if f is None:
        return None
    mesh = spectral_mesh(loop, rpm, None, depth_hint=depth, tol=tol)
    _, Jr, _ = loop.cut_basis
    k = 2 * loop.n + int(mesh.deg.sum()) * Jr.shape[0]
    return f if k > SPLIT_SIZE else None


#: free-flight exponentials kept across discretisations (a search and its check at one speed share
#: their gaps); keyed by the scaled state matrix's bytes and the gap
_EXPM: dict[tuple[bytes, float], np.ndarray] = {}


def _expm(key: bytes, Ah: np.ndarray, g: float) -> np.ndarray:
    """e^{Ah g} (read-only), from the cache when the same matrix (``key``: a
    digest of its bytes and shape) and gap were seen."""
    k = (key, g)
    E = _EXPM.get(k)
    if E is None:
        if len(_EXPM) > 64:
            _EXPM.clear()
        E = sla.expm(Ah * g)
        E.setflags(write=False)
        _EXPM[k] = E
    return E


# ============================================================================ the monodromy
class SpectralMonodromy:
    """The spectral-element discretisation of one period at one speed in
    the factored form (1) of the module docstring, set up once; :meth:`at`,
    :meth:`tangent`, :meth:`radius` give the multipliers at any depth a_p
    (without helix, (1) holds at every depth; with a helix the coefficients
    depend on a_p and the set-up is for ``depth`` only).

    Parameters
    ----------
    loop, rpm
        The problem: the structure under the cutter (a milling
        :class:`~chatterlab.process.ClosedLoop`, ``loop.process`` the cutter)
        and the spindle speed (rpm).
    degree : int, optional
        Polynomial degree p of each sub-element (>= 2); None: chosen per
        element for the accuracy ``tol`` (:func:`auto_degree`).
    elements : int, optional
        Sub-elements per cutting piece (default: enough that
        omega_max L <= ``span`` on each with an explicit degree, one per
        piece below degree ``P_MAX`` with the automatic one; omega_max the
        structure's highest pole frequency, raised with the cutting
        stiffness at ``depth_hint``).
    depth : float, optional
        Needed with a helix (the matrices are then built for this depth).
    mesh : optional
        The elements and degrees of another discretisation (its ``mesh``,
        e.g. ``sm.mesh.raised(CHECK_DEGREE)``); ``degree`` is then not used.
    span : float
        omega L of the sub-elements of an explicit degree (smaller: finer).
    tol : float
        The accuracy the automatic degree aims at (relative, multipliers).
    quasi_static : QuasiStatic, optional
        The structure split into integrated modes and a quasi-static rest
        (:func:`split_structure`); ``loop`` then gives the cut's coordinates only.
    """

    def __init__(
        self,
        loop: ClosedLoop,
        rpm: float,
        degree: int | None = DEGREE,
        elements: int | None = None,
        depth: float | None = None,
        depth_hint: float | None = None,
        mesh: _Mesh | None = None,
        span: float = ELEMENT_SPAN,
        *,
        tol: float = 1e-10,
        quasi_static: QuasiStatic | None = None,
    ) -> None:
        if degree is not None:
            check_count(degree, "degree", 2)
        self.quasi_static = quasi_static
        self.loop = loop
        # the cut's coordinates r = Ub^T (x, y) are the loop's: with a quasi-static rest the kept
        # modes may not span them all (a planar tool's stiff axis has no mode below the split)
        Ub, Jr, W = loop.cut_basis
        if quasi_static is not None:
            loop = quasi_static.loop
            Jr = Ub.T @ loop.J
            W = np.linalg.solve(loop.M, Jr.T)
        self._cut = (Ub, Jr, W)
        milling = loop.milling
        self.structure, self.milling, self.rpm = loop, milling, float(rpm)
        # process damping: the rubbing teeth's -a_p g W(t) r' (None without it: today's equations)
        self._rubbing = milling_rubbing(self.loop, self.rpm)
        self.helix_depth = depth if milling.helix > 0 else None
        if milling.helix > 0 and depth is None:
            raise InputError("milling with a helix angle: give the depth of cut a_p (depth, m)")
        if mesh is None:
            om = _mesh_omega(loop, depth, depth_hint)
            mesh = _mesh(milling, float(rpm), self.helix_depth, elements, om, span, degree, tol)
        self.mesh = mesh
        self.degree = int(mesh.deg.max()) if mesh.deg.size else int(degree or DEGREE)
        self.n_sub = int(mesh.a.size)
        self.period = mesh.T
        self._eigs: dict[float, tuple[complex, np.ndarray]] = {}
        self._setup()
        self._I = np.eye(self.m_f)

    # ------------------------------------------------------------------ set-up
    def _setup(self) -> None:
        loop, milling, mesh = self.structure, self.milling, self.mesh
        A = loop.state_matrix
        d = A.shape[0]
        n = loop.n
        Ub, Jr, W = self._cut
        rho = Jr.shape[0]
        S = mesh.a.size
        T = mesh.T
        self.d, self.rho = d, rho
        # scaled states x^ = (q, q' / ws): A^ = S^-1 A S has entries ~ ws, the collocation rows are
        # divided by ws (U's condition number ~1e4 instead of 1e12 unscaled)
        ws = max(loop.omega_max, 1.0 / T)
        sc = np.ones(2 * n)
        sc[n:] = ws
        self.ws, self.state_scale = ws, sc
        Ah = A * sc[None, :] / sc[:, None]
        Bh = np.zeros((d, rho))
        Bh[n:] = W / ws
        Ch = np.zeros((rho, d))
        Ch[:, :n] = Jr
        Chv = np.zeros((rho, d))  # r' = Jr q' = ws Jr x^_v: the velocity the flanks damp
        Chv[:, n:] = ws * Jr
        self._Ah, self._Ch, self._Chv = Ah, Ch, Chv
        if S == 0:  # never in the cut: the free structure
            E = sla.expm(Ah * T)
            self.k, self.m_f = d, 0
            self.X0 = E
            self.P = np.zeros((d, 0))
            self.K = np.zeros((0, 0))
            self.Q = np.zeros((0, d))
            self.Q2 = None
            self._nmap_z = np.zeros((0, d))
            self._nmap_f = np.zeros((0, 0))
            self.z_blocks: list[tuple[str, int, int]] = [("x", -1, 0)]
            return
        deg = mesh.deg
        nn = deg + 1
        node_off = np.zeros(S + 1, dtype=int)  # first node of each element
        np.cumsum(nn, out=node_off[1:])
        f_off = np.zeros(S + 1, dtype=int)  # first force node (collocation node 1) of each element
        np.cumsum(deg, out=f_off[1:])
        Nn = int(node_off[-1])
        m_nodes = int(f_off[-1])
        m_f = m_nodes * rho
        if Nn * d * (d + m_f) > MAX_ENTRIES:
            raise InputError(
                f"spectral elements: {S} elements, {Nn} nodes x {d} states x {m_f} nodal forces exceed"
                f" {MAX_ENTRIES:.0e} entries; a period this long holds many vibrations of the highest mode"
                " integrated: split the structure (its quasi-static modes) or raise the spindle speed"
            )
        self.m_f = m_f
        # ---- node times and the cut's coefficients there (one-sided at an element's ends)
        t_nodes = [mesh.a[s] + (mesh.b[s] - mesh.a[s]) * _cheb(int(deg[s]))[0] for s in range(S)]
        self.t_nodes = t_nodes
        teeth = milling.teeth
        taus = milling.delays(self.rpm)
        Hn = np.empty((m_nodes, teeth, rho, rho))
        for s in range(S):
            Hk = milling.directional_on(
                t_nodes[s][1:], self.rpm, 0.5 * (mesh.a[s] + mesh.b[s]), self.helix_depth
            )
            Hn[f_off[s] : f_off[s + 1]] = np.einsum("ai,kjab,bl->kjil", Ub, Hk, Ub)
        self._Hn = Hn
        # the rubbing flanks at the force nodes, g sum_j W_j(t_i) on r (process damping), or None
        Hd = None
        if self._rubbing is not None:
            g, rub = self._rubbing
            Hd = np.empty((m_nodes, rho, rho))
            for s in range(S):
                Wk = rub.directional_on(
                    t_nodes[s][1:], self.rpm, 0.5 * (mesh.a[s] + mesh.b[s]), self.helix_depth
                )
                Hd[f_off[s] : f_off[s + 1]] = g * np.einsum("ai,kjab,bl->kil", Ub, Wk, Ub)
        self._Hd = Hd
        # ---- the free structure, element by element: nodal states from the state entering each
        # element (d) and the unit forces at its nodes 1..p (rho each): x^ = Phi x0 + Gam F
        expm_cache: dict[float, np.ndarray] = {}
        a_key = hashlib.blake2b(Ah.tobytes(), digest_size=16).digest() + bytes(str(Ah.shape), "ascii")

        def expA(g: float) -> np.ndarray:
            key = round(g / T, 14)
            if key not in expm_cache:
                expm_cache[key] = _expm(a_key, Ah, float(g)) if g > 0 else np.eye(d)
            return expm_cache[key]

        self._expA = expA
        I_d = np.eye(d)
        nmap_z = np.empty((Nn * d, d))  # nodal states from the last period's end state x^_end
        nmap_f = np.zeros((Nn * d, m_f))  # and from the nodal forces
        enter_z = expA(mesh.a[0] + T - mesh.b[S - 1])  # element 0 starts from the old period's end
        enter_f = np.zeros((d, m_f))
        for s in range(S):
            p = int(deg[s])
            L = mesh.b[s] - mesh.a[s]
            _, Dm, _ = _cheb(p)
            B4 = np.zeros((p + 1, d, p + 1, d))
            B4[0, :, 0, :] = I_d
            B4[1:] = (Dm[1:, None, :, None] / (L * ws)) * I_d[None, :, None, :]
            idx = np.arange(1, p + 1)
            B4[idx, :, idx, :] -= Ah / ws
            blk = B4.reshape((p + 1) * d, (p + 1) * d)
            rhs = np.zeros(((p + 1) * d, d + p * rho))
            rhs[:d, :d] = I_d
            # node k's force (columns d + k rho ...) drives its own collocation rows (k + 1) d ...
            rhs[d:, d:].reshape(p, d, p, rho)[idx - 1, :, idx - 1, :] = Bh / ws
            sol = np.linalg.solve(blk, rhs)
            Phi, Gam = sol[:, :d], sol[:, d:]
            rows = slice(node_off[s] * d, node_off[s + 1] * d)
            nmap_z[rows] = Phi @ enter_z
            nmap_f[rows] = Phi @ enter_f
            nmap_f[rows, f_off[s] * rho : f_off[s + 1] * rho] += Gam
            if s + 1 < S:
                E = expA(mesh.a[s + 1] - mesh.b[s])
                last = slice(node_off[s + 1] * d - d, node_off[s + 1] * d)
                enter_z = E @ nmap_z[last]
                enter_f = E @ nmap_f[last]
        self._nmap_z, self._nmap_f = nmap_z, nmap_f
        self._node_off, self._f_off = node_off, f_off
        GF = self._quasi_static_response(m_f)
        if milling.uniform:
            self._uniform_cut(nmap_z, nmap_f, Hn, GF)
        else:
            self._general_cut(nmap_z, nmap_f, Hn, t_nodes, taus, GF)
        if Hd is not None:
            self._rubbing_flanks(nmap_z, nmap_f, Hd)

    def _rubbing_flanks(self, nmap_z: np.ndarray, nmap_f: np.ndarray, Hd: np.ndarray) -> None:
        """Process damping in the factored form (1): the force at node i gets
        -a_p Hd_i r'_i (Hd_i = g sum_j W_j(t_i), r' the cut coordinates' velocity,
        no delay), one more term of the nodal forces' equations, affine in a_p
        like the cut's own: K += Hd r'(F) and Q -= Hd r'(x^_end) (the velocity
        at the node per unit nodal force and per unit carried end state).  With
        a quasi-static rest the velocity includes its G dF/dt, F differentiated
        on each element's collocation polynomial (:meth:`_quasi_static_rate`)."""
        S, d, rho = self.mesh.a.size, self.d, self.rho
        deg, node_off = self.mesh.deg, self._node_off
        Nn = int(node_off[-1])
        m_f = self.m_f
        m_nodes = m_f // rho
        xnode = np.concatenate([node_off[s] + np.arange(1, int(deg[s]) + 1) for s in range(S)])
        Chv = self._Chv
        VZ = np.einsum("rd,ndk->nrk", Chv, nmap_z.reshape(Nn, d, d)[xnode])  # (m, rho, d)
        VX = np.einsum("rd,ndk->nrk", Chv, nmap_f.reshape(Nn, d, m_f)[xnode])  # (m, rho, m_f)
        GV = self._quasi_static_rate()
        if GV is not None:
            VX = VX + GV.reshape(m_nodes, rho, m_f)
        self.K = self.K + np.einsum("nrs,nsk->nrk", Hd, VX).reshape(m_f, m_f)
        Q = self.Q.copy()
        Q[:, :d] -= np.einsum("nrs,nsk->nrk", Hd, VZ).reshape(m_f, d)
        self.Q = Q

    def _quasi_static_rate(self) -> np.ndarray | None:
        """d/dt of the quasi-static modes' r = G F at the force nodes per unit nodal
        forces (m_f x m_f, block diagonal by element), the forces a polynomial on each
        element through its nodes 1..p (node 0 its continuation, as :meth:`_general_cut`
        reads it); None without a quasi-static rest."""
        qs = self.quasi_static
        if qs is None:
            return None
        mesh = self.mesh
        blocks = []
        for s in range(mesh.a.size):
            p = int(mesh.deg[s])
            nodes, Dm, _ = _cheb(p)
            inner = nodes[1:]
            bw1 = 1.0 / np.array([np.prod(inner[i] - np.delete(inner, i)) for i in range(p)])
            e0 = _bary(inner, bw1, 0.0)  # F at node 0 from the forces at nodes 1..p
            Dn = (Dm[1:, 1:] + np.outer(Dm[1:, 0], e0)) / (mesh.b[s] - mesh.a[s])
            blocks.append(np.kron(Dn, qs.compliance))
        return sla.block_diag(*blocks) if blocks else np.zeros((0, 0))

    def _quasi_static_response(self, m_f: int) -> np.ndarray | None:
        """r of the quasi-static modes at the force nodes per unit nodal forces (m_f x m_f,
        block diagonal: G F_i); None without a quasi-static rest."""
        qs = self.quasi_static
        return None if qs is None else np.kron(np.eye(m_f // self.rho), qs.compliance)

    def _uniform_cut(
        self, nmap_z: np.ndarray, nmap_f: np.ndarray, Hn: np.ndarray, GF: np.ndarray | None
    ) -> None:
        """The cut's part of (1) for a uniform pitch: every force node reads its own r one
        period back, so z = (x^_end, r at every force node) and, with H_i = sum_j H_j(t_i),
        P = (x^_end, C x^_i + (GF F)_i) per unit force, K = H P_r, Q = H (-C x^_i from x^_end, I)."""
        S, d, rho = self.mesh.a.size, self.d, self.rho
        deg, node_off = self.mesh.deg, self._node_off
        Nn = int(node_off[-1])
        m_nodes = Hn.shape[0]
        m_f = m_nodes * rho
        xnode = np.concatenate([node_off[s] + np.arange(1, int(deg[s]) + 1) for s in range(S)])
        Ch = self._Ch
        CZ = np.einsum("rd,ndk->nrk", Ch, nmap_z.reshape(Nn, d, d)[xnode])  # (m, rho, d)
        CX = np.einsum("rd,ndk->nrk", Ch, nmap_f.reshape(Nn, d, m_f)[xnode])  # (m, rho, m_f)
        if GF is not None:
            CX = CX + GF.reshape(m_nodes, rho, m_f)
        Hsum = Hn.sum(axis=1)  # (m, rho, rho)
        k_z = d + m_f
        last = slice((Nn - 1) * d, Nn * d)
        self.P = np.vstack([nmap_f[last], CX.reshape(m_f, m_f)])
        X0 = np.zeros((k_z, k_z))
        X0[:d, :d] = nmap_z[last]
        X0[d:, :d] = CZ.reshape(m_f, d)
        self.X0 = X0
        self.K = np.einsum("nrs,nsk->nrk", Hsum, CX).reshape(m_f, m_f)
        Q = np.zeros((m_f, k_z))
        Q[:, :d] = -np.einsum("nrs,nsk->nrk", Hsum, CZ).reshape(m_f, d)
        Qr = Q[:, d:].reshape(m_nodes, rho, m_nodes, rho)
        idx = np.arange(m_nodes)
        Qr[idx, :, idx, :] = Hsum
        self.Q = Q
        self.k = k_z
        self.z_blocks = [("x", S - 1, 0)] + [("r", s, k) for s in range(S) for k in range(1, int(deg[s]) + 1)]
        self._zindex = {key: (0 if i == 0 else d + (i - 1) * rho) for i, key in enumerate(self.z_blocks)}

    def _general_cut(
        self,
        nmap_z: np.ndarray,
        nmap_f: np.ndarray,
        Hn: np.ndarray,
        t_nodes: list[np.ndarray],
        taus: np.ndarray,
        GF: np.ndarray | None,
    ) -> None:
        """The cut's part of (1) for any pitch: each delayed argument located in the mesh."""
        mesh, milling, d, rho = self.mesh, self.milling, self.d, self.rho
        S, T, deg = mesh.a.size, mesh.T, mesh.deg
        node_off, f_off = self._node_off, self._f_off
        Nn = int(node_off[-1])
        m_f = self.m_f
        teeth = milling.teeth
        Ch = self._Ch
        I_d = np.eye(d)
        # ---- what the next period needs of this one (z) and the cut's equations
        # F + a (Lx x^ + LF F + Lz z) = 0 at every force node; z_new = Rx x^ + RF F.  z holds
        # ("x", s, 0): the state at the end of element s, and ("r", s, l): r at node l of element s
        end_key = ("x", S - 1, 0)
        zb: list[tuple[str, int, int]] = [end_key]  # the period's end state first
        zindex: dict[tuple[str, int, int], int] = {end_key: 0}
        zsize = [d]

        def zcol(key: tuple[str, int, int]) -> int:
            if key not in zindex:
                zindex[key] = sum(zsize)
                zb.append(key)
                zsize.append(d if key[0] == "x" else rho)
            return zindex[key]

        s_nodes_cache = {int(p): _cheb(int(p)) for p in set(deg.tolist())}

        def x_rows(s2: int, l2: int) -> slice:
            j0 = (int(node_off[s2]) + l2) * d
            return slice(j0, j0 + d)

        def r_forces(s2: int, l2: int) -> list[tuple[int, float]]:
            """The nodal forces (index, weight) of F at node l2 of element s2: itself at a
            collocation node; at node 0 the collocation polynomial of nodes 1..p continued to it."""
            if l2 >= 1:
                return [(int(f_off[s2]) + l2 - 1, 1.0)]
            nodes, _, _ = s_nodes_cache[int(deg[s2])]
            inner = nodes[1:]
            bw1 = 1.0 / np.array([np.prod(inner[i] - np.delete(inner, i)) for i in range(inner.size)])
            e = _bary(inner, bw1, 0.0)
            return [(int(f_off[s2]) + i, float(e[i])) for i in range(inner.size)]

        Lx = np.zeros((m_f, Nn * d))
        LF = np.zeros((m_f, m_f))
        Lz_entries: list[tuple[int, int, np.ndarray]] = []  # (row, z column, rho x width block)
        tol_t = 1e-12 * T
        uniform = milling.uniform
        for s in range(S):
            p = int(deg[s])
            for k in range(1, p + 1):
                i = int(f_off[s]) + k - 1
                ri = slice(i * rho, (i + 1) * rho)
                Hsum = Hn[i].sum(axis=0)
                Lx[ri, x_rows(s, k)] += Hsum @ Ch
                if GF is not None:
                    LF[ri] += Hsum @ GF[ri]
                for j in range(teeth):
                    Hj = Hn[i, j]
                    if not np.any(Hj):
                        continue
                    td = t_nodes[s][k] - taus[j]
                    old = td <= mesh.t0 + tol_t  # x(t0) is the old period's end: keeps U bidiagonal
                    if old:
                        td += T
                    if old and uniform and abs(td - t_nodes[s][k]) <= tol_t:  # one period back: the same node
                        Lz_entries.append((i, zcol(("r", s, k)), -Hj))
                        continue
                    for kind, s2, l2, wgt in self._locate(td, s_nodes_cache):
                        # wgt maps the referenced quantity (r at a node, or the state at an element's
                        # end) to r(td)
                        if old:
                            Lz_entries.append((i, zcol((kind, s2, l2)), -Hj @ wgt))
                        elif kind == "r":
                            Lx[ri, x_rows(s2, l2)] -= Hj @ (wgt @ Ch)
                            if GF is not None:
                                for i2, e2 in r_forces(s2, l2):
                                    LF[ri] -= e2 * (Hj @ (wgt @ GF[i2 * rho : (i2 + 1) * rho]))
                        else:  # an element's end state, across a free gap
                            Lx[ri, x_rows(s2, int(deg[s2]))] -= Hj @ wgt
        k_z = int(sum(zsize))
        Lz = np.zeros((m_f, k_z))
        for i, c, blk_ in Lz_entries:
            Lz[i * rho : (i + 1) * rho, c : c + blk_.shape[1]] += blk_
        Rx = np.zeros((k_z, Nn * d))
        RF = np.zeros((k_z, m_f))
        for key, c in zindex.items():
            kind, s2, l2 = key
            if kind == "x":
                Rx[c : c + d, x_rows(s2, int(deg[s2]))] = I_d
            else:
                Rx[c : c + rho, x_rows(s2, l2)] = Ch
                if GF is not None:
                    for i2, e2 in r_forces(s2, l2):
                        RF[c : c + rho] += e2 * GF[i2 * rho : (i2 + 1) * rho]
        self.z_blocks = zb
        self._zindex = zindex
        self.k = k_z
        # ---- the factored form (1)
        self.K = Lx @ nmap_f + LF
        Qm = Lz.copy()
        Qm[:, :d] += Lx @ nmap_z
        self.Q = -Qm
        self.P = Rx @ nmap_f + RF
        X0 = np.zeros((k_z, k_z))
        X0[:, :d] = Rx @ nmap_z
        self.X0 = X0

    def _locate(self, td: float, cache: dict[int, Any]) -> list[tuple[str, int, int, np.ndarray]]:
        """What x(td) is made of: [(kind, element, node, weight)] with kind "r" (the cut
        coordinates at a node, weight rho x rho) or "x" (an element's end state, weight
        rho x d: r(td) = C e^{A g} x_end)."""
        mesh = self.mesh
        tol = 1e-12 * mesh.T
        inside = np.nonzero((mesh.a - tol <= td) & (td <= mesh.b + tol))[0]
        I_r = np.eye(self.rho)
        if inside.size:
            s = int(inside[0])
            p = int(mesh.deg[s])
            s_nodes, _, bw = cache[p]
            u = (td - mesh.a[s]) / (mesh.b[s] - mesh.a[s])
            wts = _bary(s_nodes, bw, min(max(u, 0.0), 1.0))
            return [("r", s, int(l_), wts[l_] * I_r) for l_ in np.nonzero(wts)[0]]
        before = np.nonzero(mesh.b <= td)[0]
        s = int(before[-1]) if before.size else mesh.a.size - 1
        g = td - mesh.b[s] if before.size else td + mesh.T - mesh.b[s]
        return [("x", s, 0, self._Ch @ self._expA(g))]

    # ------------------------------------------------------------------ evaluation
    @property
    def size(self) -> int:
        """Number of multipliers of the discretisation (the size k of z)."""
        return int(self.k)

    @property
    def unknowns(self) -> int:
        """Collocation unknowns N (nodal states) of the discretisation."""
        return int(self._nmap_z.shape[0])

    def monodromy(self, depth: float) -> np.ndarray:
        """The k x k monodromy matrix X(a_p) of (1)."""
        a = float(depth)
        if self.m_f == 0:
            return self.X0.copy()
        W = np.linalg.solve(np.eye(self.m_f) + a * self.K, self.Q)
        return self.X0 + a * (self.P @ W)

    def _batch(self, depths: np.ndarray, derivative: bool) -> tuple[np.ndarray, np.ndarray | None]:
        a = np.asarray(depths, dtype=float)
        k = self.k
        if self.m_f == 0:
            X = np.broadcast_to(self.X0, (a.size, k, k)).copy()
            return X, (np.zeros_like(X) if derivative else None)
        Ms = np.eye(self.m_f)[None] + a[:, None, None] * self.K[None]
        W = np.linalg.solve(Ms, np.broadcast_to(self.Q, (a.size,) + self.Q.shape))
        X = self.X0[None] + a[:, None, None] * (self.P[None] @ W)
        if not derivative:
            return X, None
        dX = self.P[None] @ np.linalg.solve(Ms, W)
        return X, dX

    def tangents(self, depths: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """:meth:`tangent` at several depths in one batch (the same numbers); the
        eigenvectors are kept for :meth:`critical` at those depths."""
        a = np.atleast_1d(np.asarray(depths, dtype=float))
        if a.size == 1 or not a.all():  # a = 0: see _tangent_free
            return [self._tangent_one(float(x)) for x in a]
        X, dX_ = self._batch(a, True)
        assert dX_ is not None
        dX = dX_
        mu, vr = np.linalg.eig(X)
        try:  # the rows of vr^-1 are the left eigenvectors scaled so that y^H x = 1
            dmu = np.einsum("nkj,njk->nk", np.linalg.solve(vr, dX.astype(vr.dtype)), vr)
        except np.linalg.LinAlgError:  # one of them defective: each on its own
            return [_derivatives(mu[i], vr[i], dX[i]) for i in range(X.shape[0])]
        dmu = np.where(np.isfinite(dmu), dmu, np.inf)
        order = np.argsort(-np.abs(mu), axis=1)
        mu = np.take_along_axis(mu, order, axis=1)
        dmu = np.take_along_axis(dmu, order, axis=1)
        if len(self._eigs) > 256:
            self._eigs.clear()
        for i, x in enumerate(a):
            j = int(order[i, 0])
            self._eigs[float(x)] = (complex(mu[i, 0]), vr[i][:, j])
        return [(mu[i], dmu[i]) for i in range(a.size)]

    def _tangent_one(self, a: float) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`tangents` at one depth with plain 2-D LAPACK calls and no batch
        bookkeeping (the same numbers: one depth costs little more than its
        eigenproblem); at a = 0 :meth:`_tangent_free`."""
        if a == 0.0:
            free = self._tangent_free()
            if free is not None:
                return free
        if self.m_f:
            Minv = np.linalg.inv(self._I + a * self.K)
            W = Minv @ self.Q
            X = self.X0 + a * (self.P @ W)
            dX = self.P @ (Minv @ W)
        else:
            X, dX = self.X0, np.zeros_like(self.X0)
        mu, vr = np.linalg.eig(X)
        try:
            dmu = np.einsum("kj,jk->k", np.linalg.solve(vr, dX.astype(vr.dtype)), vr)
        except np.linalg.LinAlgError:
            dmu = np.full(mu.shape, np.inf + 0j)
        dmu = np.where(np.isfinite(dmu), dmu, np.inf)
        order = np.argsort(-np.abs(mu))
        if len(self._eigs) > 256:
            self._eigs.clear()
        self._eigs[a] = (complex(mu[order[0]]), vr[:, order[0]])
        return mu[order], dmu[order]

    def _tangent_free(self) -> tuple[np.ndarray, np.ndarray] | None:
        """:meth:`tangent` at a = 0, where multipliers are repeated (None if X0 is
        not of the form below: both cut set-ups build it so).

        The free map reads only the carried end state: X0 = [[C_d, 0], [C_r, 0]]
        (d columns, C_d = the state's map over one period, regular), so
        det(X0 - z I) = det(C_d - z I) (-z)^(k-d): the free multipliers lam
        (eigenvalues of C_d) and 0 with multiplicity k - d, semisimple (the kernel
        {z_d = 0} has dimension k - d).  At a repeated semisimple multiplier the
        rates of the multipliers leaving it are the eigenvalues of the projected
        derivative Y^H X'(0) V, V and Y^H right and left bases of the eigenspace
        with Y^H V = I (Kato, Perturbation Theory for Linear Operators, 1966, ch. II
        sec. 2.3 and 5.4; Lancaster, Numer. Math. 6, 1964), the same for every
        basis (a similarity); the diagonal of W^-1 X' W that one eigendecomposition
        gives depends on the basis LAPACK picks (on the 1-DOF benchmark at full
        immersion it was about half the true rates of the zeros).  Here X'(0) = P Q;

        * 0: V = [0; I], Y^H = [-C_r C_d^-1, I] (Y^H X0 = 0), so the k - d rates
          are the eigenvalues of X'_rr - C_r C_d^-1 X'_dr (r: the rows/columns
          after d);
        * lam, right eigenvector [x_d; C_r x_d / lam], left [y_d; 0] with y_d
          C_d's: y_d^H X'_d. x / y_d^H x_d, or for a repeated lam (a symmetric
          tool: every free multiplier twice) by :func:`_repeated_rates`.

        This is first order (mu = mu0 + a nu + o(a)); where the projected
        derivative is itself defective (the zeros' often is: its eigenvectors
        have condition numbers 1e8-1e13 on the benchmarks) the remainder is
        o(a) but not O(a^2), and at the depths the search steps it dominates
        (docs/milling.md, "The rates at a = 0")."""
        d, k = self.d, self.k
        X0 = self.X0
        Cd, Cr = X0[:d, :d], X0[d:, :d]
        lam, vd = np.linalg.eig(Cd)
        if np.any(X0[:, d:]) or not np.all(lam != 0.0):
            return None
        dX = self.P @ self.Q  # P (I + a K)^-2 Q at a = 0
        x = np.vstack([vd, (Cr @ vd) / lam])
        try:
            Zd = np.linalg.solve(vd, dX[:d].astype(vd.dtype))  # y_d^H X'_d. (y_d^H x_d = 1)
        except np.linalg.LinAlgError:  # C_d defective: the plain route (inf rates)
            return None
        rate = _repeated_rates(lam, x, Zd, np.einsum("kj,jk->k", Zd, x))
        try:
            nu = np.linalg.eigvals(dX[d:, d:] - Cr @ np.linalg.solve(Cd, dX[:d, d:]))
        except np.linalg.LinAlgError:
            # C_d singular in floating point (a mode so damped that its free multiplier underflows to 0,
            # e.g. the tool_cantilever end mill at 12 beam elements): that multiplier joins the zeros and
            # the projection above does not apply; the plain route, whose first interval rests on its
            # right end's evaluation (docs/milling.md, "The rates at a = 0")
            return None
        if not np.all(np.isfinite(nu)):
            return None
        mu = np.concatenate([lam, np.zeros(k - d, dtype=lam.dtype)])
        dmu = np.concatenate([rate, nu.astype(complex)])
        dmu = np.where(np.isfinite(dmu), dmu, np.inf)
        order = np.argsort(-np.abs(mu))
        if len(self._eigs) > 256:
            self._eigs.clear()
        top = x[:, order[0]]
        self._eigs[0.0] = (complex(mu[order[0]]), top / np.linalg.norm(top))
        return mu[order], dmu[order]

    def tangent(self, depth: float) -> tuple[np.ndarray, np.ndarray]:
        """The Floquet multipliers mu_k at depth a_p and their derivatives
        d mu_k / d a_p (without helix: (1) holds at every depth).

        With X(a) the monodromy (1), dX/da = P (I + a K)^-2 Q exactly, and
        for a simple eigenvalue d mu = y^H (dX/da) x / (y^H x) with x, y its
        right and left eigenvectors (first-order perturbation theory, e.g.
        Golub & Van Loan, Matrix Computations, sec. 7.2.2), here as the
        diagonal of W^-1 (dX/da) W with W the right eigenvectors (the rows
        of W^-1 are the left ones, normalised to y^H x = 1).  At a defective
        multiplier (two real multipliers meeting) y^H x = 0 and the
        derivative is infinite: a singular W gives inf, a nearly singular
        one huge rates, which a caller must read as "moves arbitrarily fast
        here".  At a = 0, where multipliers repeat, the rates of the multipliers
        leaving them (:meth:`_tangent_free`)."""
        if self.helix_depth is not None:
            raise InputError("tangent: with a helix the matrices are not affine in a_p")
        return self.tangents(np.array([float(depth)]))[0]

    def _shifted_solve(self, z: float, B: np.ndarray) -> np.ndarray:
        """(X0 - z I)^-1 B.  The free map X0 = [C 0] reads only the carried end state
        (its first d columns; the rest of z enters through the cut), so by Woodbury's
        identity (X0 - z I)^-1 = -(I + C (z I_d - C_d)^-1 E^T) / z, C_d the first d rows
        of C and E^T B the first d rows of B: a d x d solve instead of a k x k one."""
        d = self.d
        if np.any(self.X0[:, d:]):  # not of that form: the plain solve
            return np.linalg.solve(self.X0 - z * np.eye(self.k), B)
        C = self.X0[:, :d]
        y = np.linalg.solve(z * np.eye(d) - C[:d], B[:d])
        return -(B + C @ y) / z

    def unit_depths(self, z: float, depth_max: float) -> np.ndarray:
        """Every depth a_p in (0, depth_max] at which the discretised
        monodromy has the multiplier z = +1 (fold) or -1 (flip), ascending.

        With (1), det(X(a) - z I) = det(X0 - z I) det(I + a M) / det(I + a K)
        with M = K + Q (X0 - z I)^-1 P (Sylvester's determinant identity), so
        the depths are -1/nu for the real eigenvalues nu < 0 of the real
        m_f x m_f matrix M: all of them, from one eigenproblem, no sampling
        (X0 - z I is regular: the free structure, damped, has no multiplier
        on the unit circle).  An eigenvalue within 1e-6 (relative) of the
        real axis is taken as real: a double root (a multiplier touching z)
        is split by rounding into a pair ~sqrt(eps) apart, and counting a
        touch as a crossing errs on the safe side."""
        if self.m_f == 0:
            return np.zeros(0)
        Mz = self.K + self.Q @ self._shifted_solve(z, self.P)
        nu = np.linalg.eigvals(Mz)
        real = (np.abs(nu.imag) <= 1e-6 * np.abs(nu)) & (nu.real < 0.0)
        a = -1.0 / nu.real[real]
        return np.sort(a[a <= depth_max])

    def at(self, depth: float) -> np.ndarray:
        """The Floquet multipliers at depth a_p, largest modulus first."""
        mu = np.linalg.eigvals(self.monodromy(depth))
        return mu[np.argsort(-np.abs(mu))]

    def radius(self, depth: float) -> float:
        """The spectral radius at depth a_p: the largest |mu|.  Above
        ``ARNOLDI_MIN`` multipliers it comes from ARPACK's implicitly
        restarted Arnoldi on (1) applied as an operator (6 largest, tolerance
        1e-14, fixed start vector), else (or if ARPACK does not converge)
        from the dense eigenvalues."""
        a = float(depth)
        if self.k > ARNOLDI_MIN and self.m_f:
            from scipy.sparse.linalg import ArpackNoConvergence, LinearOperator, eigs

            lu = sla.lu_factor(np.eye(self.m_f) + a * self.K, check_finite=False)
            X0, P, Q = self.X0, self.P, self.Q

            def mv(v: np.ndarray) -> np.ndarray:
                v = np.ravel(v)
                return X0 @ v + a * (P @ sla.lu_solve(lu, Q @ v, check_finite=False))

            op = LinearOperator((self.k, self.k), matvec=mv, dtype=float)
            try:
                w = eigs(op, k=6, which="LM", v0=np.ones(self.k), tol=1e-14, return_eigenvectors=False)
                return float(np.max(np.abs(w)))
            except ArpackNoConvergence:
                pass
        return float(np.max(np.abs(np.linalg.eigvals(self.monodromy(a)))))

    def nodal_states(self, depth: float, z: np.ndarray, load: np.ndarray | None = None) -> np.ndarray:
        """The states at every node (N_nodes, d, physical units) of the period
        that follows the data z of the last one at depth a_p (with ``load``: the
        static force per unit depth at the force nodes of :meth:`forced`)."""
        a = float(depth)
        z = np.asarray(z)
        if load is None:
            F = a * np.linalg.solve(np.eye(self.m_f) + a * self.K, self.Q @ z) if self.m_f else np.zeros(0)
        else:
            F = a * np.linalg.solve(np.eye(self.m_f) + a * self.K, self.Q @ z + load)
        x = self._nmap_z @ z[: self.d] + self._nmap_f @ F
        return x.reshape(-1, self.d) * self.state_scale

    @property
    def force_nodes(self) -> tuple[np.ndarray, np.ndarray]:
        """The collocation nodes that carry a nodal force (nodes 1..p of every
        element), in the order of the force unknowns: their times (s) and a time
        inside their element (which teeth cut there: the one-sided limit at an
        element's end), shape (m_nodes,) each."""
        mesh = self.mesh
        times = [self.t_nodes[s][1:] for s in range(mesh.a.size)]
        mids = [np.full(int(mesh.deg[s]), 0.5 * (mesh.a[s] + mesh.b[s])) for s in range(mesh.a.size)]
        if not times:
            return np.zeros(0), np.zeros(0)
        return np.concatenate(times), np.concatenate(mids)

    def forced(self, depth: float, load: np.ndarray) -> np.ndarray:
        """The periodic solution under a T-periodic static cutting force: the
        fixed point z* of the one-period map of this discretisation.

        With a static force a_p f_i at the force nodes (``load``: f_i in the
        cut's coordinates, per unit depth, length m_f), the collocation
        equations' force unknowns are F = -a_p H (r - r_old) + a_p f, i.e.
        (I + a K) F = a (Q z + f), and the next period's data is
        z' = X0 z + P F = X(a) z + a P (I + a K)^-1 f.  The fixed point
        solves (I - X(a)) z* = a P (I + a K)^-1 f: the same matrices as the
        multipliers (1), one more right-hand side; regular unless a
        multiplier is 1.  Returns z* (length :attr:`size`); the states over
        the period are :meth:`nodal_states` with the same ``load``."""
        a = float(depth)
        f = np.asarray(load, dtype=float)
        if f.shape != (self.m_f,):
            raise InputError(
                f"forced: the load must have one value per nodal force ({self.m_f}), got {f.shape}"
            )
        if self.m_f == 0:
            return np.zeros(self.k)
        b = a * (self.P @ np.linalg.solve(np.eye(self.m_f) + a * self.K, f))
        return np.linalg.solve(np.eye(self.k) - self.monodromy(a), b)

    def states_at(self, x_nodes: np.ndarray, t: np.ndarray, mu: complex = 1.0) -> np.ndarray:
        """The states x(t) (len(t), d) of the solution with these nodal states
        (:meth:`nodal_states`) at times t within one period from the mesh's
        origin: interpolated on the elements, propagated exactly across the
        free gaps (e^{A g} by A's eigenvectors, or one matrix exponential per
        sample where they are ill-conditioned); a gap before the first element
        starts from the last element's end a period earlier, divided by ``mu``
        (a Floquet solution's multiplier; 1 for a periodic one)."""
        mesh = self.mesh
        T = self.period
        A = self.structure.state_matrix
        t = np.asarray(t, dtype=float)
        samples = t.size
        xs = np.zeros((samples, self.d), dtype=complex)
        done = np.zeros(samples, dtype=bool)
        off = self._node_off
        for s in range(mesh.a.size):
            inside = (~done) & (mesh.a[s] <= t) & (t <= mesh.b[s])
            if np.any(inside):
                s_nodes, _, bw = _cheb(int(mesh.deg[s]))
                w = _bary(s_nodes, bw, (t[inside] - mesh.a[s]) / (mesh.b[s] - mesh.a[s]))
                xs[inside] = w @ x_nodes[off[s] : off[s + 1]]
                done |= inside
        rest = np.nonzero(~done)[0]
        if rest.size:
            ends = (
                np.searchsorted(mesh.b, t[rest], side="right") - 1
            )  # the element before (-1: the last, a period ago)
            x_end = np.stack([x_nodes[off[s_ + 1] - 1] for s_ in range(mesh.a.size)])
            g = np.where(ends >= 0, t[rest] - mesh.b[ends], t[rest] + T - mesh.b[-1])
            src = x_end[ends] / np.where(ends >= 0, 1.0, mu)[:, None]
            lam_A, V, well = self._modes_A()
            if well:
                c = np.linalg.solve(V, src.T)  # (d, samples)
                xs[rest] = (V @ (np.exp(lam_A[:, None] * g[None, :]) * c)).T
            else:
                for j, k_ in enumerate(rest):
                    xs[k_] = sla.expm(A * g[j]) @ src[j]
        return xs

    def _modes_A(self) -> tuple[np.ndarray, np.ndarray, bool]:
        """The state matrix's eigenvalues and eigenvectors, and whether the latter are well
        conditioned (cond < 1e8), computed once per structure (:func:`_state_modes`)."""
        return _state_modes(self.structure)

    def critical(self, depth: float, samples: int = 128, near: float = 0.0) -> tuple[complex, float]:
        """The critical multiplier at depth a_p and the frequency (Hz) of its
        solution's dominant harmonic.

        The Floquet solution is x(t) = e^{lambda t} p(t) with p T-periodic and
        lambda = ln(mu) / T; its frequencies are Im(lambda) + k 2 pi / T.  The
        eigenvector gives x on the nodes (that of a depth :meth:`tangents` evaluated
        within ``near`` of a_p when there is one: the limit's frequency from its last
        Newton iterate); x(t) on ``samples`` uniform times of
        the period (interpolated on the elements, propagated exactly across
        the free gaps), times e^{-lambda t}, is p(t), and the largest
        Fourier coefficient of its displacement at the tool picks k.
        """
        a = float(depth)
        seen = [x for x in self._eigs if abs(x - a) <= near]
        if seen:  # a depth evaluated within ``near`` of a_p: its top multiplier and eigenvector
            a = min(seen, key=lambda x: abs(x - float(depth)))
            m, v = self._eigs[a]
        else:
            mu, vec = np.linalg.eig(self.monodromy(a))
            i = int(np.argmax(np.abs(mu)))
            m, v = complex(mu[i]), vec[:, i]
        return m, self._dominant_hz(m, self.nodal_states(a, v) if self.m_f else None, samples)

    def _dominant_hz(self, mu: complex, x_nodes: np.ndarray | None, samples: int) -> float:
        mesh = self.mesh
        T = self.period
        st = self.structure
        n = st.n
        if x_nodes is None or mesh.a.size == 0 or mu == 0:
            return float(abs(np.angle(mu)) / T / (2 * np.pi))
        t = mesh.t0 + T * np.arange(samples) / samples
        xs = self.states_at(x_nodes, t, mu)
        lam = np.log(complex(mu)) / T
        r = (st.J @ xs[:, :n].T).T  # (samples, 2) tool displacement
        per = r * np.exp(-lam * (t - mesh.t0))[:, None]
        c = np.fft.fft(per, axis=0)
        power = np.sum(np.abs(c) ** 2, axis=1)
        kk = int(np.argmax(power))
        k = kk if kk <= samples // 2 else kk - samples
        return float(abs(lam.imag + 2 * np.pi * k / T) / (2 * np.pi))


@lru_cache(maxsize=32)
def _state_modes(loop: ClosedLoop) -> tuple[np.ndarray, np.ndarray, bool]:
    """:meth:`SpectralMonodromy._modes_A` of a structure, cached (every speed of a diagram
    reads the same ones)."""
    lam_A, V = np.linalg.eig(loop.state_matrix)
    for x in (lam_A, V):
        x.setflags(write=False)
    return lam_A, V, bool(np.linalg.cond(V) < 1e8)


def _repeated_rates(mu: np.ndarray, vr: np.ndarray, Z: np.ndarray, dmu: np.ndarray) -> np.ndarray:
    """The first-order rates ``dmu`` (the diagonal of Z vr, Z the rows of vr^-1 times
    X') with those of every repeated multiplier replaced by the eigenvalues of its
    projected derivative Z[g] vr[:, g] (:meth:`SpectralMonodromy._tangent_free`; g the
    multipliers within ``REPEATED`` of each other, assigned in any order: they are
    equal).  Defective (the group's eigenvectors dependent, condition number above
    ``SEMISIMPLE``: Jordan blocks, multipliers moving like a^(1/j), no finite rate):
    left as they are, huge or inf, which the search reads as "moves arbitrarily
    fast" (it certifies nothing from there)."""
    tol = REPEATED * float(np.abs(mu).max())
    out = dmu.copy()
    done = np.zeros(mu.size, dtype=bool)
    for i in range(mu.size):
        if done[i]:
            continue
        g = np.nonzero(~done & (np.abs(mu - mu[i]) <= tol))[0]
        done[g] = True
        if g.size < 2:
            continue
        V = vr[:, g]
        if not np.linalg.cond(V) <= SEMISIMPLE:
            continue
        out[g] = np.linalg.eigvals(Z[g] @ V)
    return out


def _derivatives(mu: np.ndarray, vr: np.ndarray, dX: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The multipliers (largest modulus first) and their first-order rates from
    the right eigenvectors ``vr`` and the derivative ``dX`` of the matrix."""
    try:
        dmu = np.einsum("kj,jk->k", np.linalg.solve(vr, dX), vr)
    except np.linalg.LinAlgError:  # defective: no first-order rate
        dmu = np.full(mu.shape, np.inf + 0j)
    # nearly defective: the rates are huge (|W^-1| ~ 1/gap), which the search reads as fast
    dmu = np.where(np.isfinite(dmu), dmu, np.inf)
    order = np.argsort(-np.abs(mu))
    return mu[order], dmu[order]
