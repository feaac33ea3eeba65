"""The geometry of a lobe diagram: its lobes as exact curves, and their
lower envelope at any speed (:class:`LobeGeometry`, from
:meth:`chatterlab.lobes.LobeDiagram.geometry`; the lobe plot draws it).

A branch of the stability boundary is one curve (omega, phi(omega),
width(omega)); its lobes are T(omega) = (phi + 2 pi k) / omega.  The
diagram samples each branch on the engine's frequency grid; here the
samples are put back in curve order (:func:`lobe_curves`), every lobe is
interpolated between them (cubic Hermite in a chord parameter,
:class:`Segments`), and the lower envelope over all lobes is evaluated at
any speed (:func:`envelope`, :func:`envelope_line` with the cusps).  The
speed of a delay comes from the diagram's own process (its kinematics), never
from a fit.  No matplotlib here: the plot only draws what this computes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True, eq=False)
class Chain:
    """One branch of the boundary as a run of samples in curve order:
    ``omega`` (rad/s), ``phi`` (rad, continuous), ``width`` (m), a chord
    parameter ``u`` and the derivatives along it of omega, phi and 1/width
    (the cubic Hermite data between samples)."""

    branch: int
    u: np.ndarray
    omega: np.ndarray
    phi: np.ndarray
    width: np.ndarray
    domega: np.ndarray
    dphi: np.ndarray
    dinv: np.ndarray


@dataclass(frozen=True, eq=False)
class Curve:
    """One lobe: samples ``start:stop`` of a chain with T = (phi + 2 pi kk) / omega.
    ``k`` is the engine's lobe number at the lobe's bottom (the number in the
    summary, files and labels)."""

    k: int
    kk: int
    chain: Chain
    start: int
    stop: int
    speed: np.ndarray  # at the samples (for drawing)

    @property
    def branch(self) -> int:
        return self.chain.branch

    @property
    def width(self) -> np.ndarray:
        return self.chain.width[self.start : self.stop]


def _branch_chains(lbs: list[Any]) -> list[np.ndarray]:
    """The samples of one branch in their order along the curve, as chains of
    rows (omega, phi, width): the lobes list the branch's samples in curve
    order (a fold turns the frequency back, so frequency order is not curve
    order); their consecutive pairs are the branch's links."""
    from graphlib import TopologicalSorter

    f = np.concatenate([lb.frequency_hz for lb in lbs])
    b = np.concatenate([lb.width for lb in lbs])
    w = 2 * np.pi * f
    T = np.concatenate([lb.delay for lb in lbs])
    k = np.concatenate([np.full(lb.delay.size, lb.k) for lb in lbs])
    phi = np.mod(w * T - 2 * np.pi * k, 2 * np.pi)
    # one id per sample of the branch (the same (frequency, width) in every lobe)
    _, first, ids = np.unique(np.column_stack([f, b]), axis=0, return_index=True, return_inverse=True)
    ids = ids.ravel()
    same_lobe = np.ones(f.size - 1, bool)
    same_lobe[np.cumsum([lb.delay.size for lb in lbs])[:-1] - 1] = False
    edges = np.unique(np.column_stack([ids[:-1], ids[1:]])[same_lobe], axis=0)
    succ: dict[int, set[int]] = {i: set() for i in range(first.size)}
    for a_, e_ in edges.tolist():
        succ[e_].add(a_)
    order = np.array(list(TopologicalSorter(succ).static_order()), dtype=int)
    rows = np.column_stack([w[first], phi[first], b[first]])[order]
    links = set(map(tuple, edges.tolist()))
    cut = [j + 1 for j in range(order.size - 1) if (int(order[j]), int(order[j + 1])) not in links]
    return [c for c in np.split(rows, cut) if len(c) >= 2]


def _chord(w: np.ndarray, b: np.ndarray) -> np.ndarray:
    """A parameter along a branch: the cumulative chord length in
    (w, width), each scaled by its range (a fold turns w back, the chord does not)."""
    sw = max(float(np.ptp(w)), 1e-300)
    sb = max(float(np.ptp(b)), 1e-300)
    h = np.hypot(np.diff(w) / sw, np.diff(b) / sb)
    return np.r_[0.0, np.cumsum(np.maximum(h, 1e-15))]


def _tangent(y: np.ndarray, u: np.ndarray) -> np.ndarray:
    """dy/du per sample (second-order differences on the uneven parameter, one-sided at the ends)."""
    return np.gradient(y, u) if y.size > 2 else np.full_like(y, (y[-1] - y[0]) / (u[-1] - u[0]))


def _with_envelope_points(d: Any, chains: list[tuple[int, np.ndarray]]) -> list[tuple[int, np.ndarray]]:
    """Add the envelope's refined points to the branches.  The diagram's
    b_lim at each requested speed is an exact boundary point (w, phi =
    w T mod 2 pi, width): each joins the branch segment it lies on (nearest
    by linear interpolation in w, within 20 % in width and 0.3 rad in phase),
    so the curves pass through the exact envelope where the engine refined it."""
    f = np.asarray(d.chatter_hz, float)
    ok = np.isfinite(d.b_lim) & np.isfinite(f) & (f > 0)
    if not np.any(ok) or not chains:
        return chains
    W = 2 * np.pi * f[ok]
    P = np.mod(W * np.asarray(d.delay, float)[ok], 2 * np.pi)
    B = np.asarray(d.b_lim, float)[ok]
    best = np.full(W.size, np.inf)
    where = np.full((W.size, 2), -1)
    tpos = np.zeros(W.size)
    for ci, (_, ch) in enumerate(chains):
        w0, w1 = ch[:-1, 0], ch[1:, 0]
        p0 = ch[:-1, 1]
        dp = np.mod(ch[1:, 1] - p0 + np.pi, 2 * np.pi) - np.pi
        b0, b1 = ch[:-1, 2], ch[1:, 2]
        inseg = (W[:, None] > np.minimum(w0, w1)[None, :]) & (W[:, None] < np.maximum(w0, w1)[None, :])
        r, j = np.nonzero(inseg)
        if not r.size:
            continue
        t = (W[r] - w0[j]) / (w1[j] - w0[j])
        eb = np.abs((b0[j] + t * (b1[j] - b0[j])) / B[r] - 1)
        ep = np.abs(np.mod(p0[j] + t * dp[j] - P[r] + np.pi, 2 * np.pi) - np.pi)
        score = np.where((eb < 0.2) & (ep < 0.3), eb + ep, np.inf)
        for rr, jj, sc, tt in zip(r.tolist(), j.tolist(), score.tolist(), t.tolist(), strict=True):
            if sc < best[rr]:
                best[rr], where[rr], tpos[rr] = sc, (ci, jj), tt
    out = []
    for ci, (br, ch) in enumerate(chains):
        m = (where[:, 0] == ci) & np.isfinite(best) & (tpos > 1e-9) & (tpos < 1 - 1e-9)
        if np.any(m):
            key = np.r_[np.arange(len(ch), dtype=float), where[m, 1] + tpos[m]]
            rows = np.vstack([ch, np.column_stack([W[m], P[m], B[m]])])
            ch = rows[np.argsort(key, kind="stable")]
        out.append((br, ch))
    return out


def lobe_curves(d: Any) -> list[Curve]:
    """Every lobe of every branch whose delay falls in the diagram's delay
    range, as runs of samples along the branch.

    A branch is one curve (w, beta(w), phi(w)) of the boundary; its lobes are
    T(w) = (phi(w) + 2 pi k) / w for the integers k.  The diagram's lobes
    sample it on the frequency grid; the union of their samples, in curve
    order, restores the branch, from which every lobe is drawn -- also those
    a dense diagram does not carry (it keeps only the lobes on the envelope
    at the requested speeds).  phi is unwrapped along the branch so that a
    lobe continues through the point where the engine's phase wraps (there
    its number k steps by one).  Each run keeps one sample beyond the delay
    range at either end so that it reaches the ends of the range."""
    if not d.lobes and not getattr(d, "branches", ()):
        return []
    Tlo, Thi = float(np.min(d.delay)), float(np.max(d.delay))
    to_speed = d.speed_of
    if getattr(d, "branches", ()):  # the boundary itself, complete (a dense diagram keeps few lobes)
        chains = [(int(a[0, 0]), a[:, 1:]) for a in d.branches]
    else:  # restored from the lobes' samples
        branches: dict[int, list[Any]] = {}
        for lb in d.lobes:
            branches.setdefault(lb.branch, []).append(lb)
        chains = [(br, ch) for br in sorted(branches) for ch in _branch_chains(branches[br])]
    chains = _with_envelope_points(d, chains)
    out: list[Curve] = []
    for br, ch in chains:
        w, b = ch[:, 0], ch[:, 2]
        phi = np.unwrap(ch[:, 1])
        pos = w > 0
        if not np.any(pos):
            continue
        u = _chord(w, 1.0 / b)
        chain = Chain(br, u, w, phi, b, _tangent(w, u), _tangent(phi, u), _tangent(1.0 / b, u))
        kmin = int(np.floor(np.min(w[pos] * Tlo - phi[pos]) / (2 * np.pi)))
        kmax = int(np.ceil(np.max(w[pos] * Thi - phi[pos]) / (2 * np.pi)))
        K = np.arange(kmin, kmax + 1)
        with np.errstate(divide="ignore", invalid="ignore"):
            Tk = (phi[None, :] + 2 * np.pi * K[:, None]) / w[None, :]  # (lobes, samples)
        inside = pos[None, :] & (Tk >= Tlo) & (Tk <= Thi)
        grow = inside.copy()
        grow[:, 1:] |= inside[:, :-1]
        grow[:, :-1] |= inside[:, 1:]
        grow &= pos[None, :] & (Tk > 0)
        edge = np.diff(np.pad(grow, ((0, 0), (1, 1))).astype(np.int8), axis=1)
        rs, cs = np.nonzero(edge == 1)  # runs start ...
        _, ce = np.nonzero(edge == -1)  # ... and end (exclusive), row by row
        for r, c0, c1 in zip(rs.tolist(), cs.tolist(), ce.tolist(), strict=True):
            if c1 - c0 < 2:
                continue
            sp = to_speed(Tk[r, c0:c1])
            if not np.all(np.isfinite(sp)):
                continue
            j = c0 + int(np.argmin(b[c0:c1]))
            k_engine = int(K[r]) + int(np.floor(phi[j] / (2 * np.pi)))
            if k_engine < 0:
                continue
            out.append(Curve(k_engine, int(K[r]), chain, c0, c1, sp))
    return out


def static_width(d: Any) -> float:
    """The width of a root through s = 0 (every speed), where the diagram's
    envelope says so (chatter frequency 0), else inf."""
    m = np.isfinite(d.b_lim) & (np.asarray(d.chatter_hz) == 0)
    return float(np.min(d.b_lim[m])) if np.any(m) else float("inf")


class Segments:
    """Every piece between two samples of every lobe, flattened, with the
    cubic Hermite data to evaluate it at any delay."""

    def __init__(self, curves: list[Curve]) -> None:
        chains = list({id(c.chain): c.chain for c in curves}.values())
        offset = {
            id(ch): o for ch, o in zip(chains, np.cumsum([0] + [ch.u.size for ch in chains]), strict=False)
        }

        def cat(name: str) -> np.ndarray:
            return np.concatenate([getattr(ch, name) for ch in chains]) if chains else np.zeros(0)

        self.w, self.p, self.b = cat("omega"), cat("phi"), cat("width")
        self.dw, self.dp, self.dg, u = cat("domega"), cat("dphi"), cat("dinv"), cat("u")
        # segment i runs from sample g[i] to g[i] + 1 of the concatenated chains, on lobe kk[i]
        starts = np.array([offset[id(c.chain)] + c.start for c in curves], dtype=int)
        counts = np.array([c.stop - c.start - 1 for c in curves], dtype=int)
        self.n = int(counts.sum())
        first = np.cumsum(counts) - counts
        self.g = np.repeat(starts - first, counts) + np.arange(self.n)
        self.kk = np.repeat(np.array([2 * np.pi * c.kk for c in curves]), counts)
        self.h = (u[1:] - u[:-1]) if u.size else u
        with np.errstate(divide="ignore", invalid="ignore"):
            self.T0 = (self.p[self.g] + self.kk) / self.w[self.g]
            self.T1 = (self.p[self.g + 1] + self.kk) / self.w[self.g + 1]

    @staticmethod
    def _herm(t: np.ndarray, y0: Any, y1: Any, m0: Any, m1: Any) -> tuple[np.ndarray, np.ndarray]:
        t2, t3 = t * t, t * t * t
        y = (2 * t3 - 3 * t2 + 1) * y0 + (t3 - 2 * t2 + t) * m0 + (-2 * t3 + 3 * t2) * y1 + (t3 - t2) * m1
        dy = (6 * t2 - 6 * t) * (y0 - y1) + (3 * t2 - 4 * t + 1) * m0 + (3 * t2 - 2 * t) * m1
        return y, dy

    def at(self, s: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Width (m) and frequency (Hz) of segments ``s`` at delays ``T``, and
        whether the delay lies on the segment: solve w(t) T = phi(t) + 2 pi kk
        for t in [0, 1] by Newton from the linear root."""
        g, kk = self.g[s], self.kk[s]
        h = self.h[g]
        w0, w1, p0, p1 = self.w[g], self.w[g + 1], self.p[g], self.p[g + 1]
        F0, F1 = w0 * T - p0 - kk, w1 * T - p1 - kk
        den = F0 - F1
        t = np.clip(np.where(den != 0, F0 / np.where(den != 0, den, 1.0), 0.5), 0.0, 1.0)
        dw0, dw1, dp0, dp1 = self.dw[g] * h, self.dw[g + 1] * h, self.dp[g] * h, self.dp[g + 1] * h
        for _ in range(4):
            w, dw = self._herm(t, w0, w1, dw0, dw1)
            p, dp = self._herm(t, p0, p1, dp0, dp1)
            F, dF = w * T - p - kk, dw * T - dp
            t = np.clip(t - np.where(dF != 0, F / np.where(dF != 0, dF, 1.0), 0.0), 0.0, 1.0)
        w, _ = self._herm(t, w0, w1, dw0, dw1)
        p, _ = self._herm(t, p0, p1, dp0, dp1)
        ok = np.abs(w * T - p - kk) <= 1e-9 * np.maximum(np.abs(p + kk), 1.0)
        inv, _ = self._herm(t, 1.0 / self.b[g], 1.0 / self.b[g + 1], self.dg[g] * h, self.dg[g + 1] * h)
        return 1.0 / inv, w / (2 * np.pi), ok


def envelope(
    segs: Segments, v: np.ndarray, delay_of: Any, static: float = float("inf")
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lower envelope of the lobes at the sorted speeds ``v``: the minimum,
    over every lobe segment whose delays bracket the speed's delay, of the
    segment's width there.  Returns the width (m, inf where no lobe lies
    below the ceiling), the chatter frequency (Hz) and the active segment
    (-1: none)."""
    n = v.size
    env, fq, act = np.full(n, np.inf), np.full(n, np.nan), np.full(n, -1)
    T = np.asarray(delay_of(v), float)
    if segs.n:
        o = np.argsort(T)
        Ts = T[o]
        lo = np.minimum(segs.T0, segs.T1)
        hi = np.maximum(segs.T0, segs.T1)
        near = np.flatnonzero((hi >= Ts[0]) & (lo <= Ts[-1]))  # the segments over these delays (a zoom: few)
        i0 = np.searchsorted(Ts, lo[near], "left")
        i1 = np.searchsorted(Ts, hi[near], "right")
        cnt = np.maximum(i1 - i0, 0)
        seg = np.repeat(near, cnt)
        if seg.size:
            pos = np.repeat(np.arange(near.size), cnt)  # each pair's place in `near`
            start = np.cumsum(cnt) - cnt
            gi = o[i0[pos] + np.arange(seg.size) - start[pos]]
            val, f, ok = segs.at(seg, T[gi])
            gi, val, f, seg = gi[ok], val[ok], f[ok], seg[ok]
            order = np.lexsort((val, gi))
            gi, val, f, seg = gi[order], val[order], f[order], seg[order]
            first = np.r_[True, gi[1:] != gi[:-1]]
            g = gi[first]
            env[g], act[g], fq[g] = val[first], seg[first], f[first]
    if np.isfinite(static):
        st = static < env
        env[st], fq[st], act[st] = static, 0.0, -1
    return env, fq, act


#: sub-points added between two grid speeds where the active lobe changes
CUSP_SUBDIVISION = 4


def envelope_line(
    segs: Segments, v: np.ndarray, delay_of: Any, static: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The envelope on the grid ``v`` with its cusps added: where the active
    lobe changes between two grid speeds, the interval is subdivided, and
    the crossing of the two active pieces (as lines through the sub-points)
    is inserted, every added point evaluated exactly like the grid; the line
    reaches the cusps instead of cutting them off.  Returns speed, width (m),
    chatter frequency (Hz)."""
    env, fq, act = envelope(segs, v, delay_of, static)
    j = np.nonzero((act[:-1] != act[1:]) & np.isfinite(env[:-1]) & np.isfinite(env[1:]))[0]
    if not j.size:
        return v, env, fq
    t = np.arange(1, CUSP_SUBDIVISION) / CUSP_SUBDIVISION
    sub = (v[j, None] + t[None, :] * (v[j + 1] - v[j])[:, None]).ravel()
    e2, f2, a2 = envelope(segs, sub, delay_of, static)
    vv = np.concatenate([v, sub])
    ee, ff, aa = np.concatenate([env, e2]), np.concatenate([fq, f2]), np.concatenate([act, a2])
    o = np.argsort(vv, kind="stable")
    vv, ee, ff, aa = vv[o], ee[o], ff[o], aa[o]
    # the crossing of the pieces active at either end of each changing interval
    c = np.nonzero((aa[:-1] != aa[1:]) & (aa[:-1] >= 0) & (aa[1:] >= 0))[0]
    if c.size:
        x0, x1 = vv[c], vv[c + 1]
        T0, T1 = delay_of(x0), delay_of(x1)
        A, B = aa[c], aa[c + 1]
        a1, _, okA = segs.at(A, T1)
        b0, _, okB = segs.at(B, T0)
        sa = (a1 - ee[c]) / (x1 - x0)
        sb = (ee[c + 1] - b0) / (x1 - x0)
        with np.errstate(divide="ignore", invalid="ignore"):
            x = x0 + (b0 - ee[c]) / (sa - sb)
        keep = okA & okB & np.isfinite(x) & (x > x0) & (x < x1)
        x = np.unique(x[keep])
        if x.size:
            e3, f3, _ = envelope(segs, x, delay_of, static)
            vv = np.concatenate([vv, x])
            o = np.argsort(vv, kind="stable")
            vv, ee, ff = vv[o], np.concatenate([ee, e3])[o], np.concatenate([ff, f3])[o]
    return vv, ee, ff


@dataclass(frozen=True, eq=False)
class LobeGeometry:
    """A diagram's lobes as curves and what evaluates their lower envelope:
    ``curves`` (every lobe in the speed range, :func:`lobe_curves`),
    ``segments`` (:class:`Segments`), ``static`` (the width of a root through
    s = 0 at every speed, inf: none) and ``delay_of`` (the process's delay
    at a speed)."""

    curves: list[Curve]
    segments: Segments
    static: float
    delay_of: Any

    @classmethod
    def of(cls, d: Any) -> LobeGeometry:
        curves = lobe_curves(d)
        return cls(curves, Segments(curves), static_width(d), d.delay_of)

    def envelope_line(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The envelope at the sorted speeds ``v`` with its cusps: speed,
        width (m), chatter frequency (Hz) (:func:`envelope_line`)."""
        return envelope_line(self.segments, v, self.delay_of, self.static)
