"""The boundary curve of one frozen configuration and its lower envelope:
the branches of (beta, z) on the frequency grid followed around their folds
(:func:`boundary`), :class:`Boundary` (computed once, evaluated at any
delays), the regula-falsi refinement of the envelope on the phase condition,
and the smallest width over all delays.

Decoupled loops (:func:`decouple`).  When a constant invertible S makes
S^-1 H(s) S, S^-1 D_P S, S^-1 D_V S and S^-1 D_O S block diagonal with the
same blocks (a tool with identical, or identically oriented, modes in x and y
under an isotropic cut: D_O = -K_f I), the characteristic determinant
factors,

    det(I + beta H (A + z O)) = prod_b det(I + beta H_b (A_b + z O_b)),

and the boundary is the union of the blocks' boundaries.  S comes from a
generic element of the commutant {X : X Y = Y X} of those matrices (H at
sample frequencies): its eigenspaces are invariant under every Y.  Each
block is a loop of lower rank (rank one: the exact polynomial Q of
:mod:`chatterlab.lobes._boundary`), so a symmetric tool no longer gives the
rank-two resultant its four-fold roots (where |nu_1| = |nu_2| = 1 together) or
a nearly symmetric one its clusters of four; two blocks that are equal give
the same lobes, and are computed once (the coincident families merged).
The factorisation is checked on the pole-residue form (the off-block part
of every residue, summed over coincident poles, and of the feedthrough is
zero to round-off); where it does not hold, the loop is searched whole.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np

from .._minimize import bounded_minimum
from ..errors import InputError, check_width
from ..frequency._bounds import Band, PoleResidue
from ..process._loop import closed_loop_unwarned
from ..structure._assembly import FrozenSystem
from ._band import _band, _grid
from ._boundary import Ops, delayed_factors, link, refine_folds, static_width
from ._plant import Plant, _nearest_width, _ops, _solve_beta, _widths_between, _z_at

__all__ = ["Boundary", "boundary"]


@dataclass(frozen=True)
class _Segment:
    branch: int
    omega: np.ndarray
    beta: np.ndarray
    z: np.ndarray
    idx: np.ndarray  # frequency indices into the grid


def boundary(plant: Plant, omega: np.ndarray, beta_max: float) -> tuple[Ops, list[_Segment], int]:
    """Every boundary solution (beta, z) on a frequency grid (refined at the
    folds of the curve), organised into continuous branches that follow the
    curve around its folds.  Returns the operators on the final grid, the
    branches and the number of folds located."""

    def make(w: np.ndarray) -> Ops:
        return _ops(plant, w)

    w, xs, folds = refine_folds(make, omega, beta_max)
    ops = make(w)
    segs: list[_Segment] = []
    chains = link(xs)
    for j, ch in enumerate(chains):
        if len(ch) < 2:
            continue
        fi = np.array([c[0] for c in ch])
        beta = np.array([xs[f][k] for f, k in ch]) * beta_max
        z = _z_at(ops, beta, fi)
        segs.append(_Segment(j, w[fi], beta, z, fi))
    return ops, segs, folds


def _refine_crossings(
    plant: Plant,
    T: np.ndarray,
    k: np.ndarray,
    w0: np.ndarray,
    w1: np.ndarray,
    h0: np.ndarray,
    h1: np.ndarray,
    b0: np.ndarray,
    b1: np.ndarray,
    psi0: np.ndarray,
    psi1: np.ndarray,
    iters: int = 60,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Solve h(w) = w T - psi(w) - 2 pi k = 0 in [w0, w1] by regula falsi
    (Illinois), with beta and psi = -arg z re-solved exactly near the branch
    at each trial frequency.  ``h0``, ``h1`` are the (exact) end values."""
    blo = np.minimum(b0, b1) / 1.5
    bhi = np.maximum(b0, b1) * 1.5
    wa, wb, ha, hb = w0.copy(), w1.copy(), h0.copy(), h1.copy()
    beta = np.where(h1 != h0, b0 + (b1 - b0) * h0 / (h0 - h1), 0.5 * (b0 + b1))
    w = np.where(h1 != h0, w0 - h0 * (w1 - w0) / (h1 - h0), 0.5 * (w0 + w1))
    ok = np.ones(T.size, bool)
    active = np.ones(T.size, bool)
    last = np.zeros(T.size)
    for _ in range(iters):
        idx = np.nonzero(active)[0]
        if idx.size == 0:
            break
        wa_, wb_, ha_, hb_ = wa[idx], wb[idx], ha[idx], hb[idx]
        wt = np.where(hb_ != ha_, wb_ - hb_ * (wb_ - wa_) / (hb_ - ha_), 0.5 * (wa_ + wb_))
        wt = np.clip(wt, np.minimum(wa_, wb_), np.maximum(wa_, wb_))
        ops = _ops(plant, wt)
        frac = (wt - w0[idx]) / np.where(w1[idx] != w0[idx], w1[idx] - w0[idx], 1.0)
        target = b0[idx] + (b1[idx] - b0[idx]) * frac
        psi_guess = psi0[idx] + (psi1[idx] - psi0[idx]) * frac
        best_b, best_z = _nearest_width(ops, blo[idx], bhi[idx], target)
        good = np.isfinite(best_b)
        ok[idx[~good]] = False
        active[idx[~good]] = False
        psi = -np.angle(best_z)
        psi = psi + 2 * np.pi * np.round((psi_guess - psi) / (2 * np.pi))
        ht = wt * T[idx] - psi - 2 * np.pi * k[idx]
        w[idx] = np.where(good, wt, w[idx])
        beta[idx] = np.where(good, best_b, beta[idx])
        same = np.sign(ht) == np.sign(ha_)
        lst = last[idx]
        new_wa = np.where(same, wt, wa_)
        new_ha = np.where(same, ht, np.where(lst == -1, 0.5 * ha_, ha_))
        new_wb = np.where(same, wb_, wt)
        new_hb = np.where(same, np.where(lst == 1, 0.5 * hb_, hb_), ht)
        last[idx] = np.where(same, 1, -1)
        wa[idx], ha[idx], wb[idx], hb[idx] = new_wa, new_ha, new_wb, new_hb
        done = (np.abs(wb[idx] - wa[idx]) <= 1e-14 * np.abs(wt)) | (ht == 0)
        active[idx[done & good]] = False
    return w, beta, ok


def _refine_rows(plant: Plant, T: np.ndarray, info: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_refine_crossings` on candidate rows (k, w0, w1, h0, h1, b0, b1, psi0, psi1)."""
    k, w0, w1, h0, h1, b0, b1, psi0, psi1 = info.T
    return _refine_crossings(plant, T, k, w0, w1, h0, h1, b0, b1, psi0, psi1)


@dataclass(frozen=True)
class _Candidates:
    """Integer crossings of F = (w T - psi) / 2 pi on each interval of a branch
    (rows: delays, columns: intervals)."""

    sg: _Segment
    psi: np.ndarray
    kc: np.ndarray
    Fa: np.ndarray
    Fb: np.ndarray
    has: np.ndarray
    bc: np.ndarray  # interpolated width of the lowest crossing (inf: none)
    lb: np.ndarray  # smaller end width: a lower bound of any crossing

    def info(self, ri: np.ndarray, ji: np.ndarray) -> np.ndarray:
        """Rows k, w0, w1, h0, h1, b0, b1, psi0, psi1 for :func:`_refine_crossings`."""
        sg, kk = self.sg, self.kc[ri, ji]
        return np.stack(
            [
                kk,
                sg.omega[ji],
                sg.omega[ji + 1],
                2 * np.pi * (self.Fa[ri, ji] - kk),
                2 * np.pi * (self.Fb[ri, ji] - kk),
                sg.beta[ji],
                sg.beta[ji + 1],
                self.psi[ji],
                self.psi[ji + 1],
            ],
            axis=1,
        )


def _interval_candidates(sg: _Segment, T: np.ndarray) -> _Candidates:
    psi = -np.unwrap(np.angle(sg.z))
    F = (sg.omega[None, :] * T[:, None] - psi[None, :]) / (2 * np.pi)  # (nT, L)
    Fa, Fb = F[:, :-1], F[:, 1:]
    ba, bb = sg.beta[:-1], sg.beta[1:]
    lo_end_is_a = (ba <= bb)[None, :]
    inc = Fb >= Fa
    Flo, Fhi = np.minimum(Fa, Fb), np.maximum(Fa, Fb)
    k_lo = np.floor(Flo) + 1.0  # smallest integer in (Flo, Fhi]
    k_hi = np.floor(Fhi)
    kc = np.where(lo_end_is_a, np.where(inc, k_lo, k_hi), np.where(inc, k_hi, k_lo))
    has = k_hi >= k_lo
    den = np.where(Fb != Fa, Fb - Fa, 1.0)
    t = np.clip((kc - Fa) / den, 0.0, 1.0)
    bc = np.where(has, ba[None, :] + t * (bb - ba)[None, :], np.inf)
    lb = np.broadcast_to(np.minimum(ba, bb)[None, :], bc.shape)
    return _Candidates(sg, psi, kc, Fa, Fb, has, bc, lb)


def _check_damped(plant: Plant, frozen: FrozenSystem | None) -> None:
    """A structural pole on (or right of) the imaginary axis: the structure
    alone is not asymptotically stable, its receptance is infinite on the
    axis, and no width is chatter-free with certainty -- refuse, naming the
    mode, instead of failing inside the boundary solver."""
    lam = plant.poles
    if lam.size == 0:
        return
    bad = lam.real >= -1e-12 * np.maximum(np.abs(lam), 1.0)
    if np.any(bad):
        k = int(np.argmax(bad))
        src = frozen.model.source if frozen is not None else "the plant"
        raise InputError(
            f"{src}: the structure has an undamped or unstable mode at {abs(lam[k].imag) / (2 * np.pi):.6g} Hz"
            f" (pole {lam[k]:.6g} 1/s): stability lobes need every mode damped; add damping (a spring's d,"
            " a beam's eta, a mode's damping_ratio > 0) or hold the free coordinate"
        )


def _check_terms(terms: str) -> None:
    if terms not in ("pdo", "o"):
        raise InputError("terms must be 'pdo' or 'o': lobes need the delayed (regenerative) term")


class Boundary:
    """The stability boundary of one frozen configuration, computed once on a
    frequency grid and evaluated at any delays (:meth:`envelope`).

    Used by :func:`lobes` and, cached per slide position, by the stability
    atlas sweep.

    Attributes
    ----------
    band : Band
        The chatter-frequency band searched (rad/s) and its certificate: with
        ``band.certified`` no boundary point with width <= ``width_max``
        exists outside it (gain bound, :mod:`chatterlab.frequency._bounds`).
    folds : int
        Folds of the boundary curve located (and followed) on the grid.
    static_width : float
        Smallest width (m) with a root at s = 0, for every delay (inf: none).
    """

    def __init__(
        self,
        frozen: FrozenSystem | None,
        *,
        width_max: float,
        terms: Literal["pdo", "o"] = "pdo",
        fmin: float | None = None,
        fmax: float | None = None,
        n_base: int | None = None,
        couplings: list[str] | None = None,
        plant: Plant | None = None,
    ) -> None:
        _check_terms(terms)
        self.frozen = frozen
        self.width_max = check_width(width_max, "width_max")
        if plant is None:
            if frozen is None:
                raise InputError("give a frozen system or a plant")
            # the loop at b = 1 m (a reference, not a user's width): beta is the width in m
            plant = Plant.from_loop(
                closed_loop_unwarned(frozen, width=1.0, delay=1.0, terms=terms, couplings=couplings)
            )
        elif terms == "o":
            plant = plant.with_terms_o()
        self.plant = plant
        if not np.any(plant.Dl_O):
            raise InputError("the coupling elements have no delayed term (DO = 0): there are no lobes")
        _check_damped(plant, frozen)
        blocks = decouple(plant)
        #: the independent loops searched, each with how many equal blocks it stands for
        self.parts: list[tuple[Boundary, int]] = []
        if blocks is None:
            self.band = _band(plant, fmin, fmax, self.width_max)
            if self.band.hi > self.band.lo:
                self.omega = _grid(plant, self.band.lo, self.band.hi, n_base or 2000)
                self.ops, self.segments, self.folds = boundary(plant, self.omega, self.width_max)
            else:  # the gain bound excludes every frequency
                self.omega = np.zeros(0)
                self.ops, self.segments, self.folds = _ops(plant, self.omega), [], 0
            self.n_frequencies = int(self.ops.omega.size)
        else:
            self.parts = [
                (Boundary(None, width_max=self.width_max, fmin=fmin, fmax=fmax, n_base=n_base, plant=bp), k)
                for bp, k in blocks
            ]
            self._combine_parts()
        with np.errstate(all="ignore"):
            H0 = plant.H(np.array([0.0]))[0]
        self.static_width = static_width(H0, plant.Dl_P, plant.Dl_O, self.width_max)

    def _combine_parts(self) -> None:
        """Band, grid, branches and folds of the decoupled loops, as one boundary."""
        parts = [bd for bd, _ in self.parts]
        bands = [bd.band for bd in parts]
        self.band = Band(
            min(b.lo for b in bands),
            max(b.hi for b in bands),
            all(b.certified for b in bands),
            bands[0].reason
            + f" (each of {len(parts)} decoupled loop(s); {sum(k for _, k in self.parts)} blocks)",
        )
        self.omega = np.unique(np.concatenate([bd.omega for bd in parts]))
        self.ops = parts[0].ops
        self.n_frequencies = int(sum(bd.n_frequencies for bd in parts))
        self.segments = []
        for bd in parts:
            off = len(self.segments) and (max(sg.branch for sg in self.segments) + 1)
            self.segments += [replace(sg, branch=sg.branch + off) for sg in bd.segments]
        self.folds = int(sum(bd.folds for bd in parts))

    def envelope(self, T: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """b_lim (m), chatter frequency (Hz) and lobe number at delays T (s).

        On each grid interval of each branch, F(w) = (w T - psi(w)) / 2 pi
        crosses the integers k between its end values; with beta monotone on
        the interval (folds are grid points) the lowest crossing is the integer
        nearest the lower-beta end, and its width is at least the smaller end
        value.  The best interpolated candidate is refined first; then every
        other interval whose smaller end lies below that refined width is
        refined too, so a crossing whose linear interpolation was poor cannot
        be lost."""
        plant = self.plant
        T = np.atleast_1d(np.asarray(T, dtype=float))
        if self.parts:
            return self._envelope_of_parts(T)
        nT = T.size
        cand = [_interval_candidates(sg, T) for sg in self.segments]
        best = np.full(nT, np.inf)
        info = np.zeros((nT, 9))  # k, w0, w1, h0, h1, b0, b1, psi0, psi1
        r = np.arange(nT)
        first = np.full((nT, 2), -1)  # (branch, interval) refined in the first pass
        for ci, c in enumerate(cand):
            j = np.argmin(c.bc, axis=1)
            bmin = c.bc[r, j]
            upd = bmin < best
            if np.any(upd):
                best[upd] = bmin[upd]
                info[upd] = c.info(r[upd], j[upd])
                first[upd] = np.stack([np.full(int(upd.sum()), ci), j[upd]], axis=1)
        b_lim = np.full(nT, np.inf)
        chatter = np.full(nT, np.nan)
        h = np.nonzero(np.isfinite(best))[0]
        if h.size:
            w, beta, ok = _refine_rows(plant, T[h], info[h])
            b_lim[h] = np.where(ok, beta, best[h])
            chatter[h] = w / (2 * np.pi)
            # second pass: every interval that could hold a lower crossing (not
            # the one just refined: the same rows give the same result)
            rows, infos = [], []
            for ci, c in enumerate(cand):
                ri, ji = np.nonzero(c.has & (c.lb < b_lim[:, None] * (1 - 1e-12)))
                again = (first[ri, 0] == ci) & (first[ri, 1] == ji)
                ri, ji = ri[~again], ji[~again]
                if ri.size:
                    rows.append(ri)
                    infos.append(c.info(ri, ji))
            if rows:
                ri = np.concatenate(rows)
                inf_ = np.concatenate(infos)
                w2, beta2, ok2 = _refine_rows(plant, T[ri], inf_)
                for i in np.nonzero(ok2)[0]:
                    if beta2[i] < b_lim[ri[i]]:
                        b_lim[ri[i]], chatter[ri[i]] = beta2[i], w2[i] / (2 * np.pi)
        lobe_k = np.where(
            np.isfinite(b_lim), np.floor(2 * np.pi * np.nan_to_num(chatter) * T / (2 * np.pi)), -1
        )
        lobe_k = lobe_k.astype(int)
        if np.isfinite(self.static_width):
            # a root through s = 0 bounds every delay at the same width
            st = self.static_width < b_lim
            b_lim[st], chatter[st], lobe_k[st] = self.static_width, 0.0, 0
        return b_lim, chatter, lobe_k

    def _envelope_of_parts(self, T: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The lowest of the decoupled loops' envelopes (each refined on its own
        loop), then the static width of the whole."""
        b_lim = np.full(T.size, np.inf)
        chatter = np.full(T.size, np.nan)
        lobe_k = np.full(T.size, -1)
        for bd, _ in self.parts:
            b, c, k = bd.envelope(T)
            low = b < b_lim
            b_lim[low], chatter[low], lobe_k[low] = b[low], c[low], k[low]
        if np.isfinite(self.static_width):
            st = self.static_width < b_lim
            b_lim[st], chatter[st], lobe_k[st] = self.static_width, 0.0, 0
        return b_lim, chatter, lobe_k

    def absolute_minimum(self) -> dict[str, float]:
        """Smallest boundary width over all delays: ``width`` (m), ``chatter_hz``."""
        if self.parts:
            mins = [bd.absolute_minimum() for bd, _ in self.parts]
            return min(mins, key=lambda m: m["width"])
        return _absolute_minimum(self.plant, self.segments, 1.0)


def _absolute_minimum(plant: Plant, segs: list[_Segment], b_ref: float) -> dict[str, float]:
    if not segs:
        return {"width": float("inf"), "chatter_hz": float("nan")}
    cand = [(float(sg.beta.min()), sg, int(np.argmin(sg.beta))) for sg in segs]
    bmin, sg, j = min(cand, key=lambda c: c[0])
    # bounded Brent refinement of min over w of beta(w) between the neighbouring samples
    if 0 < j < sg.omega.size - 1:

        def f(w: float) -> float:
            ops = _ops(plant, np.array([w]))
            lo, hi = np.array([bmin / 2]), np.array([bmin * 2])
            if ops.Vt.shape[0] == 1:  # rank one: every width in [lo, hi], the roots of Q
                _, bb, _ = _widths_between(ops, lo, hi)
            else:
                _, bb, _ = _solve_beta(ops, lo, hi, n_grid=8)
            return float(bb.min()) if bb.size else np.inf

        a, c = sorted((float(sg.omega[j - 1]), float(sg.omega[j + 1])))
        if not c > a:
            return {"width": bmin * b_ref, "chatter_hz": float(sg.omega[j] / (2 * np.pi))}
        w_min, b_min, _ = bounded_minimum(f, a, c, xatol=1e-10 * c)
        if np.isfinite(b_min) and b_min <= bmin:
            return {"width": float(b_min) * b_ref, "chatter_hz": float(w_min) / (2 * np.pi)}
    return {"width": bmin * b_ref, "chatter_hz": float(sg.omega[j] / (2 * np.pi))}


# ---------------------------------------------------------------------------- decoupled loops

_COMMUTE_TOL = 1e-10  #: relative singular value below which X commutes with every matrix
_BLOCK_TOL = 1e-9  #: relative size of an off-block part accepted as round-off


def _sample_frequencies(plant: Plant) -> np.ndarray:
    """Frequencies (rad/s) where H is sampled for the commutant: every
    resonance, and points between and beyond them."""
    wn = np.abs(plant.poles.imag)
    top = max(float(wn.max()) if wn.size else 1.0, 1.0)
    pts = np.concatenate([np.unique(wn[wn > 0]), top * np.array([0.013, 0.17, 0.61, 1.37, 2.9])])
    if plant.grid is not None and plant.grid.size:
        pts = np.concatenate([pts, plant.grid[:: max(1, plant.grid.size // 16)]])
    return np.unique(pts[pts > 0])


def _commutant(mats: list[np.ndarray]) -> np.ndarray:
    """A basis (k, m, m) of the real matrices X with X Y = Y X for every Y."""
    m = mats[0].shape[0]
    eye = np.eye(m)
    rows: list[np.ndarray] = []
    for Y in mats:
        sc = float(np.linalg.norm(Y))
        if sc == 0.0:
            continue
        Yn = Y / sc
        # vec(X Y - Y X) = (Y^T kron I - I kron Y) vec(X), column-major vec
        Kx = np.kron(Yn.T, eye) - np.kron(eye, Yn)
        rows += [Kx.real, Kx.imag] if np.iscomplexobj(Kx) else [Kx]
    A = np.concatenate(rows)
    _, sv, vt = np.linalg.svd(A)
    sv = np.r_[sv, np.zeros(vt.shape[0] - sv.size)]
    null = vt[sv <= _COMMUTE_TOL * max(sv[0], 1e-300)]
    return null.reshape(-1, m, m).transpose(0, 2, 1)  # undo the column-major vec


def _eigenspaces(X: np.ndarray) -> list[np.ndarray] | None:
    """Real bases (m, k_b) of the eigenspaces of X (a complex pair's two
    together), or None when X is defective or its eigenvectors ill-conditioned."""
    lam, V = np.linalg.eig(X)
    scale = max(float(np.max(np.abs(lam))), 1e-300)
    groups: list[list[int]] = []
    for i in np.argsort(lam.real + 1e-3 * np.abs(lam.imag)):
        for g in groups:
            j = g[0]
            if (
                abs(lam[i].real - lam[j].real) <= 1e-6 * scale
                and abs(abs(lam[i].imag) - abs(lam[j].imag)) <= 1e-6 * scale
            ):
                g.append(int(i))
                break
        else:
            groups.append([int(i)])
    bases = []
    for g in groups:
        Vg = V[:, g]
        B = np.concatenate([Vg.real, Vg.imag], axis=1)
        u, sv, _ = np.linalg.svd(B, full_matrices=False)
        k = int(np.sum(sv > 1e-8 * sv[0]))
        if k != len(g):
            return None
        bases.append(u[:, :k])
    S = np.concatenate(bases, axis=1)
    if S.shape[1] != X.shape[0] or np.linalg.cond(S) > 1e8:
        return None
    return bases


def _off_block(Y: np.ndarray, Tinv: np.ndarray, S: np.ndarray, sizes: list[int]) -> float:
    """Size of the off-block part of S^-1 Y S relative to ||Y||."""
    Z = Tinv @ Y @ S
    mask = np.ones(Z.shape, bool)
    o = 0
    for k in sizes:
        mask[o : o + k, o : o + k] = False
        o += k
    return float(np.linalg.norm(Z[mask])) / max(float(np.linalg.norm(Y)), 1e-300)


def _residues_block_diagonal(pr: PoleResidue, Tinv: np.ndarray, S: np.ndarray, sizes: list[int]) -> bool:
    """The off-block parts of the residues vanish, summed over coincident
    poles (a degenerate pair may split its residue between any two modes),
    and of the feedthrough: then S^-1 H(s) S is block diagonal for every s."""
    p = pr.p
    if not p.size:
        return True
    scale = float(np.max(pr.norms())) or 1.0
    order = np.lexsort((p.imag, p.real))
    ps = p[order]
    tol = 1e-8 * max(float(np.max(np.abs(p))), 1e-300)
    start = np.r_[0, np.nonzero(np.abs(np.diff(ps)) > tol)[0] + 1]
    ends = np.r_[start[1:], ps.size]
    for a, b in zip(start, ends, strict=True):
        idx = order[a:b]
        Rsum = pr.L[:, idx] @ pr.R[idx, :]
        if _off_block(Rsum, Tinv, S, sizes) * max(float(np.linalg.norm(Rsum)), 1e-300) > _BLOCK_TOL * scale:
            return False
    if pr.D.size and np.any(pr.D):
        return _off_block(pr.D, Tinv, S, sizes) <= _BLOCK_TOL
    return True


def decouple(plant: Plant) -> list[tuple[Plant, int]] | None:
    """The independent loops of a plant whose delayed term has rank > 1, each
    with the number of equal blocks it stands for; None when the loop does
    not decouple (or has a rank-one delayed term: nothing to gain).

    See the module docstring for the argument."""
    _, Vt = delayed_factors(plant.Dl_O)
    if Vt.shape[0] < 2 or plant.measured_band is not None:
        return None
    w = _sample_frequencies(plant)
    with np.errstate(all="ignore"):
        Hs = plant.H(w)
    if not np.all(np.isfinite(Hs)):
        return None
    mats = [*Hs, plant.Dl_P, plant.Dl_V, plant.Dl_O]
    basis = _commutant(mats)
    if basis.shape[0] < 2:
        return None  # only multiples of I commute: one block
    rng = np.random.default_rng(20181)
    best = None
    for attempt in range(6):
        X = np.tensordot(rng.standard_normal(basis.shape[0]), basis, axes=1)
        if attempt == 0 and all(np.allclose(Y, Y.T, rtol=1e-12, atol=0) for Y in mats):
            X = X + X.T  # the commutant of symmetric matrices is closed under transposition
        bases = _eigenspaces(X)
        if bases is not None and (best is None or len(bases) > len(best)):
            best = bases
    if best is None or len(best) < 2:
        return None
    S = np.concatenate(best, axis=1)
    Tinv = np.linalg.inv(S)
    sizes = [b.shape[1] for b in best]
    if any(_off_block(Y, Tinv, S, sizes) > _BLOCK_TOL for Y in mats):
        return None
    if plant.residues is not None and not _residues_block_diagonal(plant.residues, Tinv, S, sizes):
        return None
    out: list[tuple[Plant, int]] = []
    keys: list[tuple[np.ndarray, ...]] = []
    o = 0
    nO = float(np.linalg.norm(plant.Dl_O))
    for k in sizes:
        Sb, Tb = S[:, o : o + k], Tinv[o : o + k]
        o += k
        Ob = Tb @ plant.Dl_O @ Sb
        if float(np.linalg.norm(Ob)) <= 1e-12 * nO:
            continue  # no delayed term: no lobes from this block
        bp = _block_plant(plant, Sb, Tb)
        key = (Tb @ Hs @ Sb, bp.Dl_P, bp.Dl_V, bp.Dl_O)
        for i, other in enumerate(keys):
            if other[0].shape == key[0].shape and all(
                np.allclose(x, y, rtol=1e-9, atol=1e-12 * max(float(np.max(np.abs(x))), 1e-300))
                for x, y in zip(key, other, strict=True)
            ):
                out[i] = (out[i][0], out[i][1] + 1)
                break
        else:
            keys.append(key)
            out.append((bp, 1))
    return out if out else None


def _block_plant(plant: Plant, Sb: np.ndarray, Tb: np.ndarray) -> Plant:
    """The loop of one block: H_b = T_b H S_b, its CE matrices and pole-residue
    form, and only the poles it sees."""
    H = plant.H

    def Hb(omega: np.ndarray) -> np.ndarray:
        return Tb @ H(omega) @ Sb

    def real(x: np.ndarray) -> np.ndarray:
        return np.real_if_close(Tb @ x @ Sb, tol=1e6).real

    pr = plant.residues
    poles = plant.poles
    pb: Any = None
    if pr is not None:
        L, R = Tb @ pr.L, pr.R @ Sb
        n = np.linalg.norm(L, axis=0) * np.linalg.norm(R, axis=1)
        seen = n > 1e-12 * max(float(n.max(initial=0.0)), 1e-300)
        pb = PoleResidue(pr.p[seen], L[:, seen], R[seen], Tb @ pr.D @ Sb)
        poles = pr.p[seen]
    return Plant(Hb, poles, real(plant.Dl_P), real(plant.Dl_V), real(plant.Dl_O), pb)
