"""Stability lobes with process damping: the D-subdivision with the width b
and the delay T coupled through the cutting speed (docs/process-damping.md).

With process damping (:mod:`chatterlab.process._damping`) the ideal-derivative
term of the cut depends on the delay, D_V(T) = D_V + b g(T) W with
g(T) = C_pd / V(T), so a boundary point (s = jw) satisfies

    E(beta, T; w) = det(I + beta H(jw) [D_P + jw (D_V + g(T) W) + e^{-jwT} D_O]) = 0,   (1)

one complex equation in the two real unknowns beta (the width) and T at each
frequency w: for each w it is an equation in T whose beta follows, and its
solutions are the points where the lobes cross that frequency.  Unlike the
constant-gain case, the phase condition w T = psi + 2 pi k no longer gives T
explicitly, because psi itself moves with T through g(T); the solutions are
found exactly here, in two steps:

1. **Frozen gains on a lattice.**  At each gain g_l = rho^l of a geometric
   lattice (ratio ``RATIO``; only the cells the delays need, computed once and
   kept) the constant-gain boundary is found completely by the engine of
   :mod:`chatterlab.lobes._envelope` (exact widths per frequency, folds
   followed, band certified by the gain bound taken at the cell's top gain
   g_{l+1}, so that it holds for every g of the cell).  A delay T belongs to
   the cell with g_l <= g(T) < g_{l+1}.

2. **Exact continuation in the gain.**  Every lobe point and every envelope
   crossing found at the cell's floor gain is carried to the true gain g(T)
   by Newton's method on (1) itself, in ``HOMOTOPY_STEPS`` steps of the gain:
   at a fixed delay T (the envelope at a requested speed) the unknowns are
   (w, beta), at a fixed frequency w (a lobe's point) they are (beta, T)
   with g = g(T) and g'(T) in the Jacobian, so b and T are solved together,
   never iterated on a frozen speed.  The derivatives are
   dE = tr(adj(M) dM), M the matrix of (1), with dH/dw from the structure's
   pole-residue form.  Newton converges quadratically to round-off; a point
   whose continuation fails (a lobe that closes up between the floor gain
   and g(T): process damping makes the lobes at low speed closed curves that
   shrink and vanish) is dropped.

Completeness rests on the constant-gain engine at the floor gain and on one
property of the physics: damping only lifts the lower boundary, so the
widths at g(T) >= g_l are at least those at g_l (every lower bound that
proves an interval of the floor boundary free of a lower crossing holds at
g(T) too) and the lobes at g(T) are among those at g_l.  The diagram's
argument-principle checks (``verify``) count the roots of the exact loop at
each checked speed, independently of both steps.
"""

from __future__ import annotations

import math
from dataclasses import fields
from typing import Any

import numpy as np

from ..errors import InputError, check_width
from ..frequency._bounds import Band
from ..process._damping import DampingTerm
from ..structure._assembly import FrozenSystem
from ._band import _band
from ._envelope import Boundary as _ConstantBoundary
from ._envelope import _interval_candidates, _refine_rows
from ._lobe_set import _lobe_curves
from ._plant import Plant
from ._result import Lobe, LobeDiagram

__all__ = [
    "DampedBoundary",
    "DampedGeometry",
    "DampedLobeDiagram",
    "RATIO",
    "HOMOTOPY_STEPS",
    "LOBE_POINTS",
    "DENSE",
]

#: ratio g_{l+1} / g_l of the frozen-gain lattice
RATIO = 1.5
#: steps of the gain from the cell's floor to g(T) in the continuation
HOMOTOPY_STEPS = 4
_NEWTON = 12  #: Newton iterations at most at the last step of the gain (quadratic from a good start: 4..6)
#: points of a lobe (per cell) carried to the coupled gain: each is exact, the curve between is drawn
LOBE_POINTS = 64
#: a cell's lobes reach this factor into its neighbours' gains (curves drawn without gaps)
OVERLAP = RATIO**0.1
#: more lobes than this crossing the speed range: only those forming the envelope are kept as curves
DENSE = 400


# ---------------------------------------------------------------------------- the determinant and its derivatives
def _adj(M: np.ndarray) -> np.ndarray:
    """Adjugates of a stack of m x m matrices (closed form for m <= 3, else
    from the singular value decomposition: adj(M) = det(U V^H) V diag(prod_{j!=i} s_j) U^H,
    finite and accurate where M is singular, as on the boundary)."""
    m = M.shape[-1]
    if m == 1:
        return np.ones_like(M)
    if m == 2:
        out = np.empty_like(M)
        out[..., 0, 0], out[..., 1, 1] = M[..., 1, 1], M[..., 0, 0]
        out[..., 0, 1], out[..., 1, 0] = -M[..., 0, 1], -M[..., 1, 0]
        return out
    if m == 3:
        a, b, c = M[..., 0, 0], M[..., 0, 1], M[..., 0, 2]
        d, e, f = M[..., 1, 0], M[..., 1, 1], M[..., 1, 2]
        g, h, i = M[..., 2, 0], M[..., 2, 1], M[..., 2, 2]
        rows = [
            [e * i - f * h, c * h - b * i, b * f - c * e],
            [f * g - d * i, a * i - c * g, c * d - a * f],
            [d * h - e * g, b * g - a * h, a * e - b * d],
        ]
        return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)
    U, s, Vh = np.linalg.svd(M)
    c = np.stack([np.prod(np.delete(s, i, axis=-1), axis=-1) for i in range(m)], axis=-1)
    phase = np.linalg.det(U) * np.linalg.det(Vh)
    V = np.conj(np.swapaxes(Vh, -1, -2))
    return phase[..., None, None] * (V * c[..., None, :]) @ np.conj(np.swapaxes(U, -1, -2))


def _det(M: np.ndarray, adj: np.ndarray) -> np.ndarray:
    """det M from its adjugate (Laplace along the first row), or LAPACK for m > 3."""
    if M.shape[-1] > 3:
        return np.linalg.det(M)
    return np.einsum("nj,nj->n", M[:, 0, :], adj[:, :, 0])


class _Loop:
    """The matrices of Eq. (1) of the module on the rank of the structure.

    H(s) = sum_k L_k R_k / (s - p_k) + D maps into the column space of
    [L, D] and reads the row space of [R; D]: with orthonormal bases U, Y of
    them, H = U H_r Y^H and, by Sylvester's identity,
    det(I + beta H A) = det(I_rho + beta H_r (Y^H A U)): the same E on
    rho x rho matrices (a tool that moves along one direction of a three-axis
    coupling has rho = 1)."""

    def __init__(self, plant: Plant, W: np.ndarray) -> None:
        pr = plant.residues
        if pr is None:
            raise InputError(
                "process damping needs the structure's poles (a model or an LTI system): a measured FRF has none"
            )
        U = _range(np.hstack([pr.L, pr.D]))
        Y = _range(np.hstack([pr.R.T, pr.D.T]))
        if U.shape[1] != Y.shape[1]:  # keep one rank: the larger basis for both sides
            U = Y = _range(np.hstack([pr.L, pr.D, pr.R.T, pr.D.T]))
        Uh, Yh = U.conj().T, Y.conj().T
        self.p, self.L, self.R, self.D = pr.p, Uh @ pr.L, pr.R @ Y, Uh @ pr.D @ Y

        def red(X: np.ndarray) -> np.ndarray:
            return Yh @ X @ U

        self.P, self.V, self.O, self.W = red(plant.Dl_P), red(plant.Dl_V), red(plant.Dl_O), red(W)
        self.eye = np.eye(U.shape[1])

    def frf(self, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """H_r(jw) and dH_r/dw (N, rho, rho) from the pole-residue form:
        dH/dw = -j sum_k L_k R_k / (jw - p_k)^2."""
        s = 1j * np.asarray(omega, dtype=float)
        f = 1.0 / (s[:, None] - self.p[None, :])
        LR = self.L.T[:, :, None] * self.R[:, None, :]  # (K, rho, rho)
        H = np.einsum("nk,kij->nij", f, LR) + self.D
        dH = -1j * np.einsum("nk,kij->nij", f * f, LR)
        return H, dH

    def at_delay(
        self, w: np.ndarray, b: np.ndarray, T: np.ndarray, g: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """E and its derivatives in w and beta at fixed T, g (rows)."""
        H, dH = self.frf(w)
        z = np.exp(-1j * w * T)
        Vg = self.V[None] + g[:, None, None] * self.W[None]
        A = self.P[None] + 1j * w[:, None, None] * Vg + z[:, None, None] * self.O[None]
        dA = 1j * Vg - (1j * T * z)[:, None, None] * self.O[None]
        HA = H @ A
        M = self.eye + b[:, None, None] * HA
        adj = _adj(M)
        E = _det(M, adj)
        Eb = np.einsum("nij,nji->n", adj, HA)
        Ew = b * np.einsum("nij,nji->n", adj, dH @ A + H @ dA)
        return E, Ew, Eb

    def at_frequency(
        self, H: np.ndarray, w: np.ndarray, b: np.ndarray, T: np.ndarray, g: np.ndarray, dg: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """E and its derivatives in beta and T at fixed w (H = H_r(jw)), with
        the gain g(T) and its slope g'(T) (rows)."""
        z = np.exp(-1j * w * T)
        Vg = self.V[None] + g[:, None, None] * self.W[None]
        A = self.P[None] + 1j * w[:, None, None] * Vg + z[:, None, None] * self.O[None]
        dA = (1j * w * dg)[:, None, None] * self.W[None] - (1j * w * z)[:, None, None] * self.O[None]
        HA = H @ A
        M = self.eye + b[:, None, None] * HA
        adj = _adj(M)
        E = _det(M, adj)
        Eb = np.einsum("nij,nji->n", adj, HA)
        ET = b * np.einsum("nij,nji->n", adj, H @ dA)
        return E, Eb, ET


def _range(X: np.ndarray) -> np.ndarray:
    """An orthonormal basis (m, rho) of the column space of X."""
    u, sv, _ = np.linalg.svd(X, full_matrices=False)
    r = int(np.sum(sv > 1e-12 * max(float(sv[0]) if sv.size else 0.0, 1e-300)))
    return u[:, : max(r, 1)]


def _newton2(
    f: Any, x: np.ndarray, y: np.ndarray, cap_x: np.ndarray, cap_y: np.ndarray, iters: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Newton on Re, Im of a complex E(x, y) = 0 in two real unknowns for every
    row: ``f(x, y, rows)`` returns (E, E_x, E_y); steps capped at ``cap_x``,
    ``cap_y`` (absolute, per row).  A row has converged when its relative
    step r = max(|dx|/|x|, |dy|/|y|) falls below 4e-15, or, at the round-off
    floor of a badly conditioned row (a long delay makes e^{-jwT} turn fast),
    below 1e-9 without shrinking quadratically any more (r >= r_prev / 4)."""
    x, y = x.copy(), y.copy()
    ok = np.zeros(x.size, bool)
    prev = np.full(x.size, np.inf)
    active = np.ones(x.size, bool)
    for _ in range(iters):
        rows = np.nonzero(active)[0]
        if rows.size == 0:
            break
        E, Ex, Ey = f(x[rows], y[rows], rows)
        det = Ex.real * Ey.imag - Ey.real * Ex.imag
        with np.errstate(all="ignore"):
            dx = -(E.real * Ey.imag - Ey.real * E.imag) / det
            dy = -(Ex.real * E.imag - E.real * Ex.imag) / det
        bad = ~(np.isfinite(dx) & np.isfinite(dy))
        dx = np.clip(np.nan_to_num(dx), -cap_x[rows], cap_x[rows])
        dy = np.clip(np.nan_to_num(dy), -cap_y[rows], cap_y[rows])
        x[rows] += dx
        y[rows] += dy
        with np.errstate(all="ignore"):
            r = np.maximum(np.abs(dx) / np.abs(x[rows]), np.abs(dy) / np.abs(y[rows]))
        done = (r <= 4e-15) | ((r <= 1e-9) & (r >= 0.25 * prev[rows]))
        prev[rows] = r
        ok[rows[done]] = True
        active[rows[done | bad]] = False
    return x, y, ok


def _homotopy(solve: Any, n: int, retry: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Newton from the frozen solution straight to the coupled one
    (``solve(rows, steps)``); with ``retry``, the rows where that fails again
    in HOMOTOPY_STEPS steps of the gain."""
    x, y, ok = solve(np.arange(n), 1)
    redo = np.nonzero(~ok)[0]
    if redo.size and retry:
        x2, y2, ok2 = solve(redo, HOMOTOPY_STEPS)
        x[redo], y[redo], ok[redo] = x2, y2, ok2
    return x, y, ok


def continue_at_delay(
    loop: _Loop, T: np.ndarray, g0: np.ndarray, g1: np.ndarray, w: np.ndarray, b: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Carry boundary points (w, beta) at the delays T from the gain g0 to g1
    (exact at g0) by Newton on Eq. (1) in (w, beta).  Returns (w, beta, ok)."""

    def solve(sel: np.ndarray, steps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ok = np.ones(sel.size, bool)
        ws, bs = w[sel].copy(), b[sel].copy()
        for step in range(1, steps + 1):
            g = g0[sel] + (g1[sel] - g0[sel]) * step / steps
            last = step == steps

            def f(x: np.ndarray, y: np.ndarray, rows: np.ndarray, g: np.ndarray = g) -> Any:
                return loop.at_delay(x, y, T[sel][rows], g[rows])

            cap_w = np.minimum(0.02 * np.abs(ws), 0.25 * np.pi / T[sel])  # a quarter of z's half turn
            w1, b1, conv = _newton2(f, ws, bs, cap_w, 0.5 * np.abs(bs), _NEWTON if last else 6)
            ok &= (conv | (not last)) & np.isfinite(w1) & np.isfinite(b1) & (w1 > 0) & (b1 > 0)
            ws, bs = np.where(ok, w1, ws), np.where(ok, b1, bs)
        return ws, bs, ok

    return _homotopy(solve, T.size)


def continue_at_frequency(
    loop: _Loop, term: DampingTerm, w: np.ndarray, g0: np.ndarray, T: np.ndarray, b: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Carry lobe points (beta, T) at the frequencies w from the frozen gain
    g0 (exact there) to the coupled gain g(T) by Newton on Eq. (1) in
    (beta, T): the gain g0 + lambda (g(T) - g0), lambda stepped to 1.  Returns
    (beta, T, ok)."""
    H, _ = loop.frf(w)

    def solve(sel: np.ndarray, steps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ok = np.ones(sel.size, bool)
        bs, Ts = b[sel].copy(), T[sel].copy()
        for step in range(1, steps + 1):
            lam = step / steps
            last = step == steps

            def f(x: np.ndarray, y: np.ndarray, rows: np.ndarray, lam: float = lam) -> Any:
                g, dg = _gain_and_slope(term, y)
                r = sel[rows]
                return loop.at_frequency(H[r], w[r], x, y, g0[r] + lam * (g - g0[r]), lam * dg)

            b1, T1, conv = _newton2(
                f, bs, Ts, 0.5 * np.abs(bs), 0.25 * np.pi / w[sel], _NEWTON if last else 6
            )
            ok &= (conv | (not last)) & np.isfinite(b1) & np.isfinite(T1) & (b1 > 0) & (T1 > 0)
            bs, Ts = np.where(ok, b1, bs), np.where(ok, T1, Ts)
        return bs, Ts, ok

    # a lobe point whose Newton fails from the frozen one is near a fold, or its lobe closed
    # up between the gains: dropped (the curve is drawn through its neighbours)
    return _homotopy(solve, w.size, retry=False)


def _gain_and_slope(term: DampingTerm, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """g(T) and g'(T): 1/V is affine in T for every process (turning, milling,
    shaping; :mod:`chatterlab.process._damping`), so the central difference
    is exact up to round-off."""
    g = np.asarray(term.gain(T), dtype=float)
    h = 1e-4 * T
    dg = (np.asarray(term.gain(T + h), float) - np.asarray(term.gain(T - h), float)) / (2 * h)
    return g, dg


# ---------------------------------------------------------------------------- the boundary
class Boundary(_ConstantBoundary):
    """The stability boundary of one frozen configuration, computed once and
    evaluated at any delays (:meth:`envelope`): the constant-coefficient
    engine of :mod:`chatterlab.lobes._envelope`, or, when the model has
    ``[process_damping]`` (or ``damping=`` is given with a plant), a
    :class:`~chatterlab.lobes._damped.DampedBoundary`, whose width and delay
    are coupled through the cutting speed.  Same arguments and methods;
    ``Boundary(frozen, ...)`` returns the one the model needs."""

    def __new__(cls, frozen: FrozenSystem | None = None, *args: Any, **kw: Any) -> Boundary:
        if cls is Boundary and _damped(frozen, kw):
            return super().__new__(DampedBoundary)
        return super().__new__(cls)

    def __init__(
        self, frozen: FrozenSystem | None = None, *args: Any, damping: Any = None, **kw: Any
    ) -> None:
        super().__init__(frozen, *args, **kw)


def _damped(frozen: FrozenSystem | None, kw: dict[str, Any]) -> bool:
    """The boundary needs process damping: a ``damping=`` term, or the
    model's ``[process_damping]`` with the velocity terms on."""
    if kw.get("damping") is not None:
        return True
    if frozen is None or kw.get("plant") is not None or kw.get("terms", "pdo") != "pdo":
        return False
    from ..process._damping import damping_term

    return damping_term(frozen.model, kw.get("couplings")) is not None


class _Cell:
    """The constant-gain boundary at the floor g_l of one lattice cell."""

    def __init__(self, bd: Any, g: float, g_top: float, band: Band) -> None:
        self.bd, self.g, self.g_top, self.band = bd, g, g_top, band
        parts = bd.parts if bd.parts else [(bd, 1)]
        #: (the plant whose widths the segments hold, its segments)
        self.units = [(p.plant, p.segments) for p, _ in parts] if bd.parts else [(bd.plant, bd.segments)]


class DampedBoundary(Boundary):
    """The stability boundary of a frozen configuration (or a plant) with
    process damping: :class:`~chatterlab.lobes.Boundary` with the width and
    the delay coupled through the cutting speed (module docstring).
    ``Boundary(frozen, ...)`` of a model with ``[process_damping]`` is one.

    The constant-gain boundaries of the lattice cells are computed when a
    delay first needs them and kept, so :meth:`envelope` takes any delays.

    Attributes
    ----------
    term : DampingTerm
        The damping: W, the gain g(T) = C_pd / V(T).
    plant : Plant
        The structure and the cut without process damping (the term is
        added per gain).
    band : Band
        The union of the cells' bands used so far; certified when each is.
    """

    def __init__(
        self,
        frozen: Any,
        *,
        width_max: float,
        terms: str = "pdo",
        fmin: float | None = None,
        fmax: float | None = None,
        n_base: int | None = None,
        couplings: list[str] | None = None,
        plant: Plant | None = None,
        damping: DampingTerm | None = None,
    ) -> None:
        from ..process._damping import damping_term
        from ..process._loop import closed_loop_unwarned

        if terms != "pdo":
            raise InputError("process damping is a velocity term: lobes with it take terms='pdo'")
        self.frozen = frozen
        self.width_max = check_width(width_max, "width_max")
        term = damping
        if plant is None:
            if frozen is None:
                raise InputError("give a frozen system or a plant")
            loop = closed_loop_unwarned(frozen, width=1.0, delay=1.0, terms="pdo", couplings=couplings)
            term = term or damping_term(frozen.model, couplings)
            V = loop.Dl_V - (loop.damping.matrix(1.0) if loop.damping is not None else 0.0)
            plant = Plant.from_loop(loop)
            plant = Plant(plant.H, plant.poles, plant.Dl_P, V, plant.Dl_O, plant.residues)
        if term is None:
            raise InputError("a damped boundary needs the process damping term (damping=)")
        if plant.residues is None:
            raise InputError(
                "process damping needs the structure's poles (a model or an LTI system): a measured FRF has none"
            )
        self.plant, self.term = plant, term
        self.loop = _Loop(plant, term.W)
        self.fmin, self.fmax, self.n_base = fmin, fmax, n_base
        self.parts = []
        self.segments = []
        self.cells: dict[int, _Cell] = {}
        from ._boundary import static_width

        with np.errstate(all="ignore"):
            H0 = plant.H(np.array([0.0]))[0]
        self.static_width = static_width(H0, plant.Dl_P, plant.Dl_O, self.width_max)
        self._seen: list[tuple[float, float]] = []  # (width, chatter Hz) of every point computed

    # ------------------------------------------------------------------ cells
    @staticmethod
    def cell_index(g: np.ndarray) -> np.ndarray:
        """l with RATIO^l <= g < RATIO^(l+1)."""
        return np.floor(np.log(np.asarray(g, float)) / math.log(RATIO) + 1e-12).astype(int)

    def cell(self, l: int) -> _Cell:
        """The constant-gain boundary at g_l = RATIO^l, made once."""
        if l not in self.cells:
            g, g_top = RATIO**l, RATIO ** (l + 1)
            p = self.plant
            # the gain bound at the cell's top: ||D_V + g W|| <= ||D_V|| + g_top ||W|| for every g of the cell
            nV = float(np.linalg.norm(p.Dl_V, 2)) + g_top * float(np.linalg.norm(self.term.W, 2))
            bound = Plant(p.H, p.poles, p.Dl_P, nV * np.eye(p.Dl_P.shape[0]), p.Dl_O, p.residues)
            band = _band(bound, self.fmin, self.fmax, self.width_max)
            plant = Plant(p.H, p.poles, p.Dl_P, p.Dl_V + g * self.term.W, p.Dl_O, p.residues)
            bd = Boundary(
                None,
                width_max=self.width_max,
                fmin=band.lo / (2 * np.pi),
                fmax=max(band.hi, band.lo * (1 + 1e-12) + 1e-9) / (2 * np.pi),
                n_base=self.n_base,
                plant=plant,
            )
            self.cells[l] = _Cell(bd, g, g_top, band)
        return self.cells[l]

    @property
    def band(self) -> Band:  # type: ignore[override]
        cells = list(self.cells.values())
        if not cells:
            return Band(0.0, 0.0, True, "no delay evaluated yet")
        b = [c.band for c in cells]
        return Band(
            min(x.lo for x in b),
            max(x.hi for x in b),
            all(x.certified for x in b),
            f"{b[0].reason} (the gain bound of each of {len(b)} process-damping cells at its top gain)",
        )

    @property
    def folds(self) -> int:  # type: ignore[override]
        return int(sum(c.bd.folds for c in self.cells.values()))

    @property
    def n_frequencies(self) -> int:  # type: ignore[override]
        return int(max((c.bd.n_frequencies for c in self.cells.values()), default=0))

    # ------------------------------------------------------------------ the envelope
    def envelope(self, T: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """b_lim (m), chatter frequency (Hz) and lobe number at the delays T
        (s), each exact for the loop at its own cutting speed."""
        T = np.atleast_1d(np.asarray(T, dtype=float))
        return self.envelope_at(T, np.asarray(self.term.gain(T), dtype=float))

    def envelope_at(self, T: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Like :meth:`envelope` at the delays T with the gains g (N s/m^2)
        given: the limit of another C_pd (g = C_pd / V(T)) from the same
        cells, which depend on the gain only (the fit of C_pd uses it)."""
        T = np.atleast_1d(np.asarray(T, dtype=float))
        g = np.broadcast_to(np.asarray(g, dtype=float), T.shape)
        if not np.all(np.isfinite(g) & (g > 0)):
            raise InputError("process damping: a delay gives no positive finite cutting speed")
        cell = self.cell_index(g)
        b_lim = np.full(T.size, np.inf)
        w_lim = np.full(T.size, np.nan)
        for l in np.unique(cell):
            rows = np.nonzero(cell == l)[0]
            b, w = self._cell_envelope(self.cell(int(l)), T[rows], g[rows])
            b_lim[rows], w_lim[rows] = b, w
        chatter = w_lim / (2 * np.pi)
        lobe_k = np.where(np.isfinite(b_lim), np.floor(np.nan_to_num(w_lim) * T / (2 * np.pi)), -1).astype(
            int
        )
        if np.isfinite(self.static_width):
            st = self.static_width < b_lim
            b_lim[st], chatter[st], lobe_k[st] = self.static_width, 0.0, 0
        fin = np.isfinite(b_lim)
        self._seen += list(zip(b_lim[fin].tolist(), chatter[fin].tolist(), strict=True))
        return b_lim, chatter, lobe_k

    def _cell_envelope(self, c: _Cell, T: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The lowest crossing at each delay of one cell: the candidates of
        the floor boundary (lowest interpolated first, then every interval
        whose lower end is below the limit found), each refined exactly at the
        floor gain and carried to g(T)."""
        n = T.size
        best_b = np.full(n, np.inf)
        best_w = np.full(n, np.nan)
        cands = [(plant, _interval_candidates(sg, T)) for plant, segs in c.units for sg in segs]
        if not cands:
            return best_b, best_w
        r = np.arange(n)
        # first pass: the lowest interpolated crossing of each delay
        lowest = np.full(n, np.inf)
        pick = np.full((n, 2), -1)
        for ci, (_, cd) in enumerate(cands):
            j = np.argmin(cd.bc, axis=1)
            upd = cd.bc[r, j] < lowest
            lowest[upd] = cd.bc[r, j][upd]
            pick[upd] = np.stack([np.full(int(upd.sum()), ci), j[upd]], axis=1)
        self._refine(c, cands, T, g, r[np.isfinite(lowest)], pick[np.isfinite(lowest)], best_b, best_w)
        # second pass: every interval that could hold a lower crossing at g(T)
        # (its smaller end width at the floor gain is a lower bound there too)
        rows, which = [], []
        for ci, (_, cd) in enumerate(cands):
            ri, ji = np.nonzero(cd.has & (cd.lb < best_b[:, None] * (1 - 1e-12)))
            again = (pick[ri, 0] == ci) & (pick[ri, 1] == ji)
            rows.append(ri[~again])
            which.append(np.stack([np.full(int((~again).sum()), ci), ji[~again]], axis=1))
        if rows:
            self._refine(c, cands, T, g, np.concatenate(rows), np.concatenate(which), best_b, best_w)
        return best_b, best_w

    def _refine(
        self,
        c: _Cell,
        cands: list[Any],
        T: np.ndarray,
        g: np.ndarray,
        rows: np.ndarray,
        which: np.ndarray,
        best_b: np.ndarray,
        best_w: np.ndarray,
    ) -> None:
        """Refine the crossings (rows, (candidate set, interval)) at the floor
        gain, carry them to g(T) and keep each row's lowest."""
        if rows.size == 0:
            return
        w0 = np.full(rows.size, np.nan)
        b0 = np.full(rows.size, np.nan)
        good = np.zeros(rows.size, bool)
        for ci in np.unique(which[:, 0]):
            sel = np.nonzero(which[:, 0] == ci)[0]
            plant, cd = cands[int(ci)]
            w, b, ok = _refine_rows(plant, T[rows[sel]], cd.info(rows[sel], which[sel, 1]))
            w0[sel], b0[sel], good[sel] = w, b, ok
        idx = np.nonzero(good)[0]
        if idx.size == 0:
            return
        rr = rows[idx]
        w1, b1, ok = continue_at_delay(self.loop, T[rr], np.full(idx.size, c.g), g[rr], w0[idx], b0[idx])
        ok &= b1 <= self.width_max * (1 + 1e-9)
        for i in np.nonzero(ok)[0]:
            if b1[i] < best_b[rr[i]]:
                best_b[rr[i]], best_w[rr[i]] = b1[i], w1[i]

    # ------------------------------------------------------------------ the lobes
    def lobe_curves(self, T: np.ndarray, lobe_k: np.ndarray, proc: Any) -> tuple[list[Lobe], int]:
        """Every lobe in the range of the delays T (only those forming the
        envelope when more than ``DENSE`` cross it), as exact points of
        Eq. (1): the constant-gain lobes of each cell at the frequencies of
        its grid (at most ``LOBE_POINTS`` per lobe and cell, its lowest kept),
        each point carried to its own cutting speed."""
        T = np.asarray(T, dtype=float)
        Tlo, Thi = float(T.min()), float(T.max())
        glo, ghi = (float(x) for x in self.term.gain(np.array([Tlo, Thi])))
        Tlo_x = max(Tlo / 1.02, 0.5 * (Tlo + float(getattr(proc, "min_delay", 0.0))))
        pieces: list[tuple[_Cell, list[Lobe]]] = []
        ks_all: set[int] = set()
        for l in range(
            int(self.cell_index(np.array([glo]))[0]), int(self.cell_index(np.array([ghi]))[0]) + 1
        ):
            c = self.cell(l)
            # each cell's lobes overlap its neighbours' (a tenth of a cell in gain, a little
            # beyond the range at its ends) so that every lobe is drawn without a gap
            Ta, Tb = _delays_of_cell(self.term, c.g / OVERLAP, c.g_top * OVERLAP, Tlo_x, Thi * 1.02)
            if not Tb > Ta:
                continue
            lobes_c, _ = _lobe_curves(c.bd.segments, np.array([Ta, Tb]), lobe_k, proc, 1.0)
            ks_all.update(lb.k for lb in lobes_c)
            pieces.append((c, lobes_c))
        n_lobes = len(ks_all)
        envelope_ks = set(np.unique(lobe_k[lobe_k >= 0]).tolist())
        out: list[Lobe] = []
        for c, lobes_c in pieces:
            if n_lobes > DENSE:
                lobes_c = [lb for lb in lobes_c if lb.k in envelope_ks]
            if not lobes_c:
                continue
            take = [_sample(lb.width) for lb in lobes_c]
            sizes = [t.size for t in take]
            w = 2 * np.pi * np.concatenate([lb.frequency_hz[t] for lb, t in zip(lobes_c, take, strict=True)])
            b0 = np.concatenate([lb.width[t] for lb, t in zip(lobes_c, take, strict=True)])
            T0 = np.concatenate([lb.delay[t] for lb, t in zip(lobes_c, take, strict=True)])
            b1, T1, ok = continue_at_frequency(self.loop, self.term, w, np.full(w.size, c.g), T0, b0)
            ok &= (T1 >= Tlo_x) & (T1 <= Thi * 1.02) & (b1 <= self.width_max * (1 + 1e-9))
            start = 0
            for lb, size in zip(lobes_c, sizes, strict=True):
                sl = slice(start, start + size)
                start += size
                keep = ok[sl]
                if np.count_nonzero(keep) < 2:
                    continue
                Ts = T1[sl][keep]
                out.append(
                    Lobe(
                        lb.k,
                        lb.branch,
                        Ts,
                        np.asarray(proc.speed_for_delay(Ts)) if proc.kind != "delay" else Ts,
                        b1[sl][keep],
                        w[sl][keep] / (2 * np.pi),
                    )
                )
        for lb in out:
            j = int(np.argmin(lb.width))
            self._seen.append((float(lb.width[j]), float(lb.frequency_hz[j])))
        return out, n_lobes

    def absolute_minimum(self) -> dict[str, float]:
        """The smallest width of the boundary points computed so far (the
        envelope's delays and the lobes' points), m, and its chatter
        frequency: with process damping the widths rise with the delay, so
        the constant-gain asymptote of the lobes at low speed does not exist."""
        if not self._seen:
            return {"width": float("inf"), "chatter_hz": float("nan")}
        b, f = min(self._seen)
        return {"width": float(b), "chatter_hz": float(f)}


def _sample(width: np.ndarray) -> np.ndarray:
    """Indices of at most LOBE_POINTS points of a lobe, evenly along it, its
    ends and its lowest point among them."""
    n = width.size
    if n <= LOBE_POINTS:
        return np.arange(n)
    idx = np.linspace(0, n - 1, LOBE_POINTS - 1).round().astype(int)
    return np.unique(np.r_[idx, int(np.argmin(width))])


def _delays_of_cell(term: DampingTerm, g0: float, g1: float, Tlo: float, Thi: float) -> tuple[float, float]:
    """The delays in [Tlo, Thi] whose gain lies in [g0, g1] (g increases with T)."""
    from scipy.optimize import brentq

    def at(gx: float) -> float:
        glo, ghi = float(term.gain(Tlo)), float(term.gain(Thi))
        if gx <= glo:
            return Tlo
        if gx >= ghi:
            return Thi
        return float(brentq(lambda t: float(term.gain(t)) - gx, Tlo, Thi, xtol=1e-15 * Thi, rtol=1e-15))

    return at(g0), at(g1)


# ---------------------------------------------------------------------------- the diagram's geometry
class DampedGeometry:
    """What the plot draws of a diagram with process damping: every lobe as
    its own polyline of exact points (each lobe has its own phase: the
    constant-gain geometry of :mod:`chatterlab.lobes._curves`, one phase per
    branch for all its lobes, does not apply), and the lower envelope at any
    speed: the diagram's exact b_lim at its requested speeds, and between
    them the lowest lobe, linear in the delay between its exact points."""

    def __init__(self, d: Any) -> None:
        self.d = d
        self.curves = [_Curve(lb) for lb in d.lobes]
        self.delay_of = d.delay_of
        m = np.isfinite(d.b_lim) & (np.asarray(d.chatter_hz) == 0)
        self.static = float(np.min(d.b_lim[m])) if np.any(m) else float("inf")
        parts = [(lb.delay, lb.width, lb.frequency_hz) for lb in d.lobes if lb.delay.size >= 2]
        if parts:
            self.T0 = np.concatenate([p[0][:-1] for p in parts])
            self.T1 = np.concatenate([p[0][1:] for p in parts])
            self.b0 = np.concatenate([p[1][:-1] for p in parts])
            self.b1 = np.concatenate([p[1][1:] for p in parts])
            self.f0 = np.concatenate([p[2][:-1] for p in parts])
            self.f1 = np.concatenate([p[2][1:] for p in parts])
        else:
            self.T0 = self.T1 = self.b0 = self.b1 = self.f0 = self.f1 = np.zeros(0)

    def envelope_line(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The envelope at the speeds ``v`` (sorted): speed, width (m),
        chatter frequency (Hz)."""
        v = np.sort(np.asarray(v, dtype=float))
        T = np.asarray(self.delay_of(v), dtype=float)
        env = np.full(v.size, np.inf)
        fq = np.full(v.size, np.nan)
        if self.T0.size:
            o = np.argsort(T)
            Ts = T[o]
            lo, hi = np.minimum(self.T0, self.T1), np.maximum(self.T0, self.T1)
            i0 = np.searchsorted(Ts, lo, "left")
            i1 = np.searchsorted(Ts, hi, "right")
            cnt = np.maximum(i1 - i0, 0)
            seg = np.repeat(np.arange(lo.size), cnt)
            if seg.size:
                start = np.cumsum(cnt) - cnt
                gi = o[i0[seg] + np.arange(seg.size) - start[seg]]
                with np.errstate(divide="ignore", invalid="ignore"):
                    t = np.clip(
                        np.nan_to_num((T[gi] - self.T0[seg]) / (self.T1[seg] - self.T0[seg])), 0.0, 1.0
                    )
                val = self.b0[seg] + t * (self.b1[seg] - self.b0[seg])
                f = self.f0[seg] + t * (self.f1[seg] - self.f0[seg])
                order = np.lexsort((val, gi))
                gi, val, f = gi[order], val[order], f[order]
                first = np.r_[True, gi[1:] != gi[:-1]]
                env[gi[first]], fq[gi[first]] = val[first], f[first]
        # the requested speeds: the engine's exact limit
        sp = np.asarray(self.d.speed, dtype=float)
        pos = np.searchsorted(sp[np.argsort(sp)], v)
        srt = np.argsort(sp)
        hit = (pos < sp.size) & (sp[srt][np.minimum(pos, sp.size - 1)] == v)
        j = srt[np.minimum(pos, sp.size - 1)][hit]
        env[hit], fq[hit] = np.asarray(self.d.b_lim)[j], np.asarray(self.d.chatter_hz)[j]
        if np.isfinite(self.static):
            st = self.static < env
            env[st], fq[st] = self.static, 0.0
        return v, env, fq


class _Curve:
    """One lobe as the plot draws it (the attributes of
    :class:`chatterlab.lobes._curves.Curve` it reads)."""

    def __init__(self, lobe: Lobe) -> None:
        self.k, self.branch = lobe.k, lobe.branch
        self.speed, self.width = lobe.speed, lobe.width
        self.chain = _Chain(2 * np.pi * lobe.frequency_hz, lobe.width)


class _Chain:
    def __init__(self, omega: np.ndarray, width: np.ndarray) -> None:
        self.omega, self.width = omega, width


class DampedLobeDiagram(LobeDiagram):
    """A :class:`~chatterlab.lobes.LobeDiagram` with process damping: the same
    result, whose :meth:`geometry` draws each lobe as its own exact curve
    (:class:`DampedGeometry`)."""

    def geometry(self) -> Any:
        return DampedGeometry(self)

    def summary(self) -> str:
        """The diagram's summary with what its process damping is."""
        pd = self.meta.get("process_damping", {})
        line = (
            f"  process damping: C_pd = {pd.get('C_pd', float('nan')):g} N/m ({pd.get('model', 'linear')});"
            f" width and delay coupled through the cutting speed ({pd.get('cells', 0)} gain cells)"
        )
        return super().summary() + "\n" + line

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """The files of :class:`LobeDiagram` with the process damping's
        fields as attributes (``process_damping_C_pd`` N/m, ...)."""
        coords, data, attrs = super().dataset_parts()
        pd = self.meta.get("process_damping", {})
        attrs = {
            **attrs,
            **{f"process_damping_{k}": v for k, v in pd.items() if isinstance(v, int | float | str)},
        }
        return coords, data, attrs

    @classmethod
    def of(cls, d: LobeDiagram) -> DampedLobeDiagram:
        return cls(**{f.name: getattr(d, f.name) for f in fields(d)})
