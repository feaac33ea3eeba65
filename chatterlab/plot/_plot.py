"""Plots (matplotlib is imported inside each function, never at import).

Every function returns the Axes it drew on so that a caller can restyle or
save; none calls ``plt.show()``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "plot_frf",
    "plot_nyquist",
    "plot_lobes",
    "plot_atlas",
    "plot_histories",
    "plot_spectra",
    "savefig",
]


def _index(names: Sequence[str], key: int | str) -> int:
    return names.index(key) if isinstance(key, str) else int(key)


def plot_frf(
    frfs: Sequence[Any],
    *,
    output: int | str = 0,
    input: int | str = 0,
    labels: Sequence[str] | None = None,
    axes: Any = None,
    title: str | None = None,
    peaks: int = 0,
) -> Any:
    """Magnitude (log scale) and phase (deg) of one or more FRFs against
    frequency in Hz, overlaid: the open- vs closed-loop comparison of the
    paper's Figs. 10-11.  Returns (ax_mag, ax_phase)."""
    import matplotlib.pyplot as plt

    if axes is None:
        fig, axes = plt.subplots(2, 1, sharex=True, figsize=(8, 6), gridspec_kw={"height_ratios": [2, 1]})
    ax_m, ax_p = axes
    for k, f in enumerate(frfs):
        o, i = _index(f.outputs, output), _index(f.inputs, input)
        z = f.data[o, i]
        lab = labels[k] if labels is not None else f.label
        (line,) = ax_m.semilogy(f.frequency_hz, np.abs(z), label=lab)
        ax_p.plot(f.frequency_hz, np.degrees(np.angle(z)), color=line.get_color())
        if peaks:
            for fp, mp in f.peaks(o, i, peaks):
                ax_m.annotate(f"{fp:.1f} Hz", (fp, mp), textcoords="offset points", xytext=(4, 4), fontsize=8)
    f0 = frfs[0]
    o, i = _index(f0.outputs, output), _index(f0.inputs, input)
    ax_m.set_ylabel(f"|{f0.outputs[o]} / {f0.inputs[i]}|  [{f0.unit}]")
    ax_p.set_ylabel("phase [deg]")
    ax_p.set_xlabel("frequency [Hz]")
    ax_p.set_yticks([-180, -90, 0, 90, 180])
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
    ax_m.legend()
    if title:
        ax_m.set_title(title)
    return axes


def plot_nyquist(omega: np.ndarray, det: np.ndarray, *, ax: Any = None, title: str | None = None) -> Any:
    """Nyquist plot of the loop determinant det(I - G D) for w from 0 up,
    mirrored for negative w; the critical point is the origin."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(5.5, 5.5))
    ax.plot(det.real, det.imag, lw=1, label="w > 0")
    ax.plot(det.real, -det.imag, lw=0.8, ls="--", label="w < 0")
    ax.plot([0], [0], "r+", ms=12, mew=2, label="origin")
    ax.plot([1], [0], "k.", label="open loop (1)")
    ax.set_xlabel("Re det(I - G D)")
    ax.set_ylabel("Im det(I - G D)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    if title:
        ax.set_title(title, fontsize=9)
    return ax


def savefig(ax_or_axes: Any, path: str, dpi: int = 130) -> None:
    """Save the figure holding the given Axes and close it.  The layout is
    tightened first unless the plot laid the figure out itself (figure gid
    ``LAID_OUT``)."""
    import matplotlib.pyplot as plt

    ax = ax_or_axes[0] if isinstance(ax_or_axes, list | tuple | np.ndarray) else ax_or_axes
    fig = ax.figure
    if fig.get_gid() != LAID_OUT:
        fig.tight_layout()
    # zlib level 1: several times faster than the default 6 on a dense figure, a little larger file
    extra = {"pil_kwargs": {"compress_level": 1}} if str(path).lower().endswith(".png") else {}
    fig.savefig(path, dpi=dpi, **extra)
    plt.close(fig)


#: gid of a figure whose plot function already tightened its layout (savefig skips it)
LAID_OUT = "chatterlab:laid-out"


# ============================================================ lobe diagrams

#: the envelope is evaluated at this many points per horizontal pixel ...
ENVELOPE_POINTS_PER_PIXEL = 4
#: ... of a figure saved at up to this resolution (savefig's default is 130 dpi)
ENVELOPE_DPI = 130
#: resolution at which lobe density is judged (savefig's default)
DISPLAY_DPI = 130
#: lobes are "denser than the plot can show" when more than one lobe bottom of
#: a branch falls within this many pixel columns
DENSE_PIXELS = 3
#: lobes shown in the zoom panel of a dense diagram (bottoms either side of the minimum)
ZOOM_LOBES = 3


@dataclass(frozen=True, eq=False)
class _Chain:
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
class _Curve:
    """One lobe: samples ``start:stop`` of a chain with T = (phi + 2 pi kk) / omega.
    ``k`` is the engine's lobe number at the lobe's bottom (the number in the
    summary, files and labels)."""

    k: int
    kk: int
    chain: _Chain
    start: int
    stop: int
    speed: np.ndarray  # at the samples (for drawing)

    @property
    def branch(self) -> int:
        return self.chain.branch

    @property
    def width(self) -> np.ndarray:
        return self.chain.width[self.start : self.stop]


def _speed_maps(d: Any) -> tuple[Any, Any]:
    """The process's speed as a function of the delay and its inverse,
    recovered from the diagram's own (delay, speed) pairs: 1/speed is affine
    in the delay for shaping (v = L / (T - L / v_r)) and turning (n = 60 / T),
    so the maps are exact there; speed = delay for a delay process; otherwise
    a monotone interpolation of the pairs."""
    T = np.concatenate([np.asarray(d.delay, float)] + [lb.delay for lb in d.lobes])
    v = np.concatenate([np.asarray(d.speed, float)] + [lb.speed for lb in d.lobes])
    ok = np.isfinite(T) & np.isfinite(v) & (v > 0) & (T > 0)
    T, v = T[ok], v[ok]

    def same(t: Any) -> np.ndarray:
        return np.asarray(t, float)

    if np.allclose(v, T, rtol=1e-12, atol=0):
        return same, same
    (a, c), *_ = np.linalg.lstsq(np.stack([T, np.ones_like(T)], axis=1), 1.0 / v, rcond=None)
    if np.max(np.abs((a * T + c) * v - 1.0)) < 1e-9:

        def speed(t: Any) -> np.ndarray:
            with np.errstate(divide="ignore"):
                s = 1.0 / (a * np.asarray(t, float) + c)
            return np.where(s > 0, s, np.nan)

        def delay(s: Any) -> np.ndarray:
            return (1.0 / np.asarray(s, float) - c) / a

        return speed, delay
    o = np.argsort(T)
    q = np.argsort(v)
    return (
        lambda t: np.interp(t, T[o], v[o], left=np.nan, right=np.nan),
        lambda s: np.interp(s, v[q], T[q], left=np.nan, right=np.nan),
    )


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


def _lobe_curves(d: Any) -> list[_Curve]:
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
    if not d.lobes:
        return []
    Tlo, Thi = float(np.min(d.delay)), float(np.max(d.delay))
    to_speed, _ = _speed_maps(d)
    branches: dict[int, list[Any]] = {}
    for lb in d.lobes:
        branches.setdefault(lb.branch, []).append(lb)
    chains = [(br, ch) for br in sorted(branches) for ch in _branch_chains(branches[br])]
    chains = _with_envelope_points(d, chains)
    out: list[_Curve] = []
    for br, ch in chains:
        w, b = ch[:, 0], ch[:, 2]
        phi = np.unwrap(ch[:, 1])
        pos = w > 0
        if not np.any(pos):
            continue
        u = _chord(w, 1.0 / b)
        chain = _Chain(br, u, w, phi, b, _tangent(w, u), _tangent(phi, u), _tangent(1.0 / b, u))
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
            out.append(_Curve(k_engine, int(K[r]), chain, c0, c1, sp))
    return out


def _static_width(d: Any) -> float:
    """The width of a root through s = 0 (every speed), where the diagram's
    envelope says so (chatter frequency 0), else inf."""
    m = np.isfinite(d.b_lim) & (np.asarray(d.chatter_hz) == 0)
    return float(np.min(d.b_lim[m])) if np.any(m) else float("inf")


class _Segments:
    """Every piece between two samples of every lobe, flattened, with the
    cubic Hermite data to evaluate it at any delay."""

    def __init__(self, curves: list[_Curve]) -> None:
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


def _envelope(
    segs: _Segments, v: np.ndarray, delay_of: Any, static: float = float("inf")
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
        i0 = np.searchsorted(Ts, lo, "left")
        i1 = np.searchsorted(Ts, hi, "right")
        cnt = np.maximum(i1 - i0, 0)
        seg = np.repeat(np.arange(segs.n), cnt)
        if seg.size:
            start = np.cumsum(cnt) - cnt
            gi = o[i0[seg] + np.arange(seg.size) - start[seg]]
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


def _envelope_line(
    segs: _Segments, v: np.ndarray, delay_of: Any, static: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The envelope on the grid ``v`` with its cusps added: where the active
    lobe changes between two grid speeds, the interval is subdivided, and
    the crossing of the two active pieces (as lines through the sub-points)
    is inserted, every added point evaluated exactly like the grid; the line
    reaches the cusps instead of cutting them off.  Returns speed, width (m),
    chatter frequency (Hz)."""
    env, fq, act = _envelope(segs, v, delay_of, static)
    j = np.nonzero((act[:-1] != act[1:]) & np.isfinite(env[:-1]) & np.isfinite(env[1:]))[0]
    if not j.size:
        return v, env, fq
    t = np.arange(1, CUSP_SUBDIVISION) / CUSP_SUBDIVISION
    sub = (v[j, None] + t[None, :] * (v[j + 1] - v[j])[:, None]).ravel()
    e2, f2, a2 = _envelope(segs, sub, delay_of, static)
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
            e3, f3, _ = _envelope(segs, x, delay_of, static)
            vv = np.concatenate([vv, x])
            o = np.argsort(vv, kind="stable")
            vv, ee, ff = vv[o], np.concatenate([ee, e3])[o], np.concatenate([ff, f3])[o]
    return vv, ee, ff


def _axes_pixels(ax: Any, dpi: float) -> float:
    fig = ax.figure
    return max(float(ax.get_position().width * fig.get_figwidth() * dpi), 50.0)


def _speed_grid(ax: Any, lo: float, hi: float, extra: np.ndarray) -> np.ndarray:
    """>= ENVELOPE_POINTS_PER_PIXEL points per pixel of the Axes (at
    ENVELOPE_DPI) over [lo, hi], plus the ``extra`` speeds inside."""
    n = int(np.ceil(ENVELOPE_POINTS_PER_PIXEL * _axes_pixels(ax, ENVELOPE_DPI) * 1.1)) + 1
    g = np.linspace(lo, hi, n)
    extra = extra[(extra >= lo) & (extra <= hi)]
    return np.unique(np.concatenate([g, extra]))


def _bottoms(curves: list[_Curve]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Speed and width (m) of each lobe's lowest sample, and its branch."""
    if not curves:
        return np.zeros(0), np.zeros(0), np.zeros(0, int)
    j = [int(np.argmin(c.width)) for c in curves]
    return (
        np.array([c.speed[i] for c, i in zip(curves, j, strict=True)]),
        np.array([c.width[i] for c, i in zip(curves, j, strict=True)]),
        np.array([c.branch for c in curves]),
    )


def _density(curves: list[_Curve], lo: float, hi: float, pixels: float) -> float:
    """Most lobe bottoms of one branch within DENSE_PIXELS pixel columns."""
    sp, _, br = _bottoms(curves)
    n = max(int(pixels), 1)
    worst = 0.0
    for b in np.unique(br):
        h, _ = np.histogram(sp[br == b], bins=n, range=(lo, hi))
        win = np.convolve(h, np.ones(DENSE_PIXELS), "valid") if n >= DENSE_PIXELS else h
        worst = max(worst, float(win.max()) if win.size else 0.0)
    return worst


def _zoom_range(curves: list[_Curve], d: Any, lo: float, hi: float) -> tuple[float, float]:
    """A speed range around the diagram's minimum holding about 2 ZOOM_LOBES + 1
    lobes of the branch that forms the envelope there."""
    vc = float(d.minimum["speed"]) if np.isfinite(d.minimum["speed"]) else 0.5 * (lo + hi)
    sp, wd, br = _bottoms(curves)
    if sp.size == 0:
        return lo, hi
    near = np.argsort(np.abs(sp - vc))[:4]
    b = br[near[np.argmin(wd[near])]]
    s = np.sort(sp[br == b])
    i = int(np.argmin(np.abs(s - vc)))
    a, e = max(i - ZOOM_LOBES, 0), min(i + ZOOM_LOBES, s.size - 1)
    pad = 0.5 * (s[e] - s[a]) / max(e - a, 1)
    return max(lo, s[a] - pad), min(hi, s[e] + pad)


def _model_name(d: Any) -> str:
    from pathlib import PurePath

    p = PurePath(str(d.model))
    return str(PurePath(*p.parts[-2:])) if len(p.parts) > 2 else str(p)


def _subtitle(d: Any) -> str:
    terms = {"pdo": "P + D + delayed (pdo)", "o": "delayed only (o)"}.get(d.terms, str(d.terms))
    pos = f"slide at s = {d.position:g} m" if d.position is not None else "fixed structure"
    lo, hi = d.band_hz
    band = f"chatter band {lo:.4g}-{hi:.4g} Hz " + ("proven complete" if d.band_certified else "NOT proven")
    if d.verified is None:
        ver = "not verified"
    else:
        ok = sum(c["agrees"] for c in d.checks)
        ver = f"verified {ok}/{len(d.checks)} checks" + ("" if d.verified else " -- CHECKS FAILED")
    return (
        f"{pos}; feedback {terms}; width ceiling {d.width_max * 1e3:g} mm\n{band}; {ver} (argument principle)"
    )


def _claim_spans(d: Any, vx: np.ndarray, env: np.ndarray) -> dict[int, list[tuple[float, float]]]:
    """Speed ranges of the claims that are not a boundary: where the drawn
    envelope is inf (no lobe below the ceiling), code 1 if the band is proven
    and 2 if not -- between the requested speeds too; code 3 (a check
    contradicts the diagram) half-way to the neighbouring requested speeds."""
    out: dict[int, list[tuple[float, float]]] = {}
    inf = ~np.isfinite(env)
    if np.any(inf):
        edges = np.nonzero(np.diff(np.r_[False, inf, False].astype(np.int8)))[0]
        code = 1 if d.band_certified else 2
        mid = 0.5 * (vx[1:] + vx[:-1])
        left, right = np.r_[vx[0], mid], np.r_[mid, vx[-1]]
        out[code] = [
            (float(left[a]), float(right[e - 1])) for a, e in zip(edges[::2], edges[1::2], strict=True)
        ]
    for a_, b_ in _requested_spans(d, 3):
        out.setdefault(3, []).append((a_, b_))
    return out


def _requested_spans(d: Any, which: int) -> list[tuple[float, float]]:
    """Speed ranges (half-way to the neighbours) of the requested speeds whose claim is ``which``."""
    v = np.asarray(d.speed, float)
    o = np.argsort(v)
    v, code = v[o], np.asarray(d.claim)[o]
    mid = 0.5 * (v[1:] + v[:-1])
    left, right = np.r_[v[0], mid], np.r_[mid, v[-1]]
    edges = np.nonzero(np.r_[True, code[1:] != code[:-1], True])[0]
    return [
        (float(left[a]), float(right[e - 1]))
        for a, e in zip(edges[:-1], edges[1:], strict=True)
        if int(code[a]) == which
    ]


def _draw_lobe_panel(
    ax: Any,
    d: Any,
    curves: list[_Curve],
    lo: float,
    hi: float,
    *,
    segs: _Segments,
    delay_of: Any,
    static: float,
    lobe_numbers: int,
    dense_ok: bool,
    references: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Lobes (one LineCollection), the exact envelope, the unstable region and
    the claims on one Axes over speeds [lo, hi].  Returns what was drawn."""
    from matplotlib.collections import LineCollection
    from matplotlib.patches import Patch

    ax.set_xlim(lo, hi)
    px = _axes_pixels(ax, DISPLAY_DPI)
    density = _density(curves, lo, hi, px)
    dense = dense_ok and density > 1
    vg = _speed_grid(ax, lo, hi, np.asarray(d.speed, float))
    vx, env, fq = _envelope_line(segs, vg, delay_of, static)
    em = env * 1e3
    fin = np.isfinite(em)
    top = d.width_max * 1e3
    peak = float(np.max(em[fin])) if np.any(fin) else top
    ytop = top if 1.2 * peak >= top else 1.2 * peak
    handles: list[Any] = []
    if not dense:  # dense lobes would only grey the unstable region: the band below says it
        polylines = [
            np.column_stack([c.speed, c.width * 1e3])
            for c in curves
            if c.speed.max() >= lo and c.speed.min() <= hi
        ]
        lc = LineCollection(polylines, colors="0.55", linewidths=0.6, zorder=1)
        lc.set_gid("lobes")
        ax.add_collection(lc)
        handles.append(lc)
        lc.set_label("lobes (each an exact boundary curve)")
    ax.fill_between(vx, np.where(fin, em, np.nan), ytop * 2, color="tab:red", alpha=0.15, lw=0, zorder=0)
    handles.append(Patch(color="tab:red", alpha=0.15, label="unstable (chatter)"))
    if dense:
        # the envelope within each pixel column: from its lowest point to its highest cusp
        cols = np.clip(((vx - lo) / (hi - lo) * px).astype(int), 0, int(px) - 1)
        e = np.where(fin, em, np.nan)
        starts = np.nonzero(np.r_[True, cols[1:] != cols[:-1]])[0]
        cmin = np.fmin.reduceat(e, starts)
        cmax = np.fmax.reduceat(e, starts)
        xc = lo + (cols[starts] + 0.5) / px * (hi - lo)
        band = ax.fill_between(xc, cmin, cmax, color="tab:red", alpha=0.55, lw=0, zorder=2)
        band.set_gid("lobe-band")
        handles.append(
            Patch(color="tab:red", alpha=0.55, label="b_lim sweeps this band within each pixel column")
        )
    (line,) = ax.plot(
        vx, em, color="tab:red", lw=0.5 if dense else 1.6, zorder=3, label="b_lim (exact lower envelope)"
    )
    line.set_gid("envelope")
    handles.append(line)
    a = d.absolute_minimum["width"] * 1e3
    if np.isfinite(a):
        (al,) = ax.plot(
            [lo, hi],
            [a, a],
            color="k",
            ls="--",
            lw=1,
            zorder=4,
            label=f"unconditional limit {a:.4g} mm ({d.absolute_minimum['chatter_hz']:.1f} Hz)",
        )
        handles.append(al)
    m = d.minimum
    if np.isfinite(m["width"]) and lo <= m["speed"] <= hi:
        (mk,) = ax.plot(
            [m["speed"]],
            [m["width"] * 1e3],
            "ko",
            ms=4.5,
            zorder=5,
            label=f"min of range {m['width'] * 1e3:.4g} mm at {m['speed']:.4g} {d.speed_unit}",
        )
        handles.append(mk)
    styles_ref = [("tab:green", ":"), ("k", ":"), ("tab:purple", "-.")]
    for i, (lab, ref) in enumerate((references or {}).items()):
        col, ls = styles_ref[i % len(styles_ref)]
        if np.ndim(ref) == 0:
            (rl,) = ax.plot([lo, hi], [float(ref) * 1e3] * 2, color=col, ls=ls, lw=1.2, zorder=4, label=lab)
        else:
            rv, rb = (np.asarray(x, float) for x in ref)
            (rl,) = ax.plot(rv, rb * 1e3, color=col, ls=ls, lw=1.2, zorder=4, label=lab)
        handles.append(rl)
    spans = _claim_spans(d, vx, em)
    trans = ax.get_xaxis_transform()
    styles: dict[int, dict[str, Any]] = {
        1: dict(
            y=(0.93, 1.0),
            hatch="////",
            fc="none",
            ec="tab:green",
            label=f"b_lim = inf: no chatter below the {top:g} mm ceiling",
        ),
        2: dict(
            y=(0.0, 1.0),
            hatch=None,
            fc="tab:orange",
            ec="none",
            label="undetermined: none found, band not proven",
        ),
        3: dict(y=(0.0, 1.0), hatch=None, fc="magenta", ec="none", label="contradicted by a check"),
    }
    for code, st in styles.items():
        for k, (x0, x1) in enumerate(spans.get(code, [])):
            if x1 < lo or x0 > hi:
                continue
            x0, x1 = max(x0, lo), min(x1, hi)
            if x1 <= x0:
                x1 = x0 + 1e-3 * (hi - lo)
            p = ax.fill_between(
                [x0, x1],
                st["y"][0],
                st["y"][1],
                transform=trans,
                facecolor=st["fc"],
                edgecolor=st["ec"],
                hatch=st["hatch"],
                alpha=0.35 if st["hatch"] is None else 1.0,
                lw=0,
                zorder=2.5,
                label=st["label"] if k == 0 else None,
            )
            p.set_gid(f"claim-{code}")
            if k == 0:
                handles.append(p)
    ax.set_ylim(0, ytop)
    labelled = _label_lobes(ax, curves, vx, em, lo, hi, ytop, lobe_numbers) if not dense else []
    return {
        "handles": handles,
        "dense": dense,
        "density": density,
        "speed": vx,
        "width": em,
        "freq": fq,
        "labelled": labelled,
        "ytop": ytop,
        "pixels": px,
    }


def _label_lobes(
    ax: Any,
    curves: list[_Curve],
    vx: np.ndarray,
    em: np.ndarray,
    lo: float,
    hi: float,
    ytop: float,
    most: int,
) -> list[int]:
    """Number the lobes whose bottoms lie on the envelope in view, lowest
    first, skipping any label that would overlap one already placed."""
    if not most or not curves:
        return []
    sp, wd, br = _bottoms(curves)
    wd = wd * 1e3
    env_at = np.interp(sp, vx, np.where(np.isfinite(em), em, np.inf))
    ok = (sp > lo) & (sp < hi) & (wd < ytop) & (wd <= env_at * (1 + 1e-3))
    multi = np.unique(br).size > 1
    placed: list[tuple[float, float, float, float]] = []
    out: list[int] = []
    tr = ax.transData
    for i in np.nonzero(ok)[0][np.argsort(wd[ok])]:
        c = curves[i]
        txt = f"{c.k}" + (f"/{c.branch}" if multi else "")
        x, y = tr.transform((sp[i], wd[i]))
        w = 6.0 * len(txt) + 6
        box = (x - w / 2, x + w / 2, y - 22, y - 4)
        if any(not (box[1] < p[0] or box[0] > p[1] or box[3] < p[2] or box[2] > p[3]) for p in placed):
            continue
        placed.append(box)
        ax.annotate(
            txt,
            (sp[i], wd[i]),
            textcoords="offset points",
            xytext=(0, -11),
            ha="center",
            fontsize=7,
            color="0.2",
            gid="lobe-label",
        )
        out.append(i)
        if len(out) >= most:
            break
    return out


def plot_lobes(
    diagram: Any,
    *,
    axes: Any = None,
    lobe_numbers: int = 8,
    title: str | None = None,
    references: Mapping[str, Any] | None = None,
) -> Any:
    """Stability lobe diagram: width of cut (mm) against speed.

    Draws every lobe (one LineCollection), the exact lower envelope of the
    lobes (the minimum over the lobe curves, linearly interpolated in speed,
    at >= 4 points per pixel with the cusps added), the unstable region above
    it, the unconditional limit, and where the diagram claims ``inf`` (hatched
    at the top), undetermined (orange) or contradicted (magenta) speeds.  When
    the lobes are denser than the pixels (more than one lobe of a branch
    within DENSE_PIXELS columns) it says so, shades the band the envelope
    sweeps within each pixel column (from the lobe bottoms to the cusps), and
    adds a panel zoomed on about 7 lobes around the minimum.  The bottom panel
    is the chatter frequency along the envelope.  The title names the model,
    position, feedback, ceiling, chatter band and the verification.

    Parameters
    ----------
    diagram : LobeDiagram
    axes : sequence of Axes, optional
        (ax_lobes, ax_freq) or (ax_lobes, ax_zoom, ax_freq); default: a new
        figure, with the zoom panel when the lobes are dense.
    lobe_numbers : int
        Most lobe numbers written per panel (0: none).
    title : str, optional
        First title line (default: the model); the second says position,
        feedback, ceiling, band and checks.
    references : mapping, optional
        Reference widths drawn on the lobe panels with a legend entry: label ->
        width (m, a horizontal line) or (speeds, widths in m) (a dotted curve).

    Returns
    -------
    (ax_lobes, ax_freq), or (ax_lobes, ax_zoom, ax_freq) when dense.
    """
    import matplotlib.pyplot as plt

    d = diagram
    v = np.asarray(d.speed, float)
    lo, hi = float(v.min()), float(v.max())
    if hi <= lo:
        lo, hi = lo * 0.95, hi * 1.05
    curves = _lobe_curves(d)
    static = _static_width(d)
    segs = _Segments(curves)
    delay_of = _speed_maps(d)[1] if d.lobes else (lambda s: np.asarray(s, float))
    created = axes is None
    if axes is None:
        # decide the layout on a figure of the final size (dpi of savefig: text is measured once)
        fig = plt.figure(figsize=(11.5, 6.5), dpi=130)
        dense = _density(curves, lo, hi, 0.695 * 11.5 * DISPLAY_DPI) > 1  # the panels' width
        axz: Any = None
        if dense:
            fig.set_size_inches(11.5, 9.5)  # legends right of the panels: the lobes fill the frame
            # fixed margins (the texts are ours): a tight layout costs 0.15 s of the main job
            gs = fig.add_gridspec(
                3,
                1,
                height_ratios=[3, 2.4, 1.1],
                left=0.06,
                right=0.755,
                top=0.925,
                bottom=0.05,
                hspace=0.36,
            )
            ax = fig.add_subplot(gs[0])
            axz = fig.add_subplot(gs[1])
            axf = fig.add_subplot(gs[2], sharex=ax)
            axes = (ax, axz, axf)
        else:
            ax, axf = fig.subplots(
                2,
                1,
                sharex=True,
                gridspec_kw={
                    "height_ratios": [3, 1.2],
                    "left": 0.06,
                    "right": 0.755,
                    "top": 0.885,
                    "bottom": 0.08,
                    "hspace": 0.2,
                },
            )
            axes = (ax, axf)
    axes = tuple(axes)
    ax, axf = axes[0], axes[-1]
    axz = axes[1] if len(axes) > 2 else None
    main = _draw_lobe_panel(
        ax,
        d,
        curves,
        lo,
        hi,
        segs=segs,
        delay_of=delay_of,
        static=static,
        lobe_numbers=lobe_numbers,
        dense_ok=True,
        references=references,
    )
    unit = d.speed_unit
    count = _lobe_count(curves, d)
    note = None
    if main["dense"]:
        import textwrap

        note = textwrap.fill(
            f"Lobes denser than the plot: up to {main['density']:.0f} lobe bottoms in {DENSE_PIXELS} pixel"
            " columns. Where dense, each pixel column shows the band b_lim sweeps in it, from the lobe"
            " bottoms to the cusps; "
            + (
                "individual lobes in the zoom below."
                if axz is not None
                else "pass three axes for a zoom panel."
            ),
            46,
        )
    if axz is not None:
        zlo, zhi = _zoom_range(curves, d, lo, hi) if main["dense"] else (lo, hi)
        zoom = _draw_lobe_panel(
            axz,
            d,
            curves,
            zlo,
            zhi,
            segs=segs,
            delay_of=delay_of,
            static=static,
            lobe_numbers=lobe_numbers,
            dense_ok=False,
            references=references,
        )
        axz.set_ylabel("width of cut b [mm]")
        axz.set_xlabel(f"{d.speed_name} [{unit}] (zoom)")
        axz.grid(alpha=0.3)
        ax.axvspan(zlo, zhi, facecolor="none", edgecolor="k", lw=0.8, zorder=6)
        ax.annotate(
            "zoom",
            (zhi, 0.02),
            xycoords=ax.get_xaxis_transform(),
            xytext=(3, 0),
            textcoords="offset points",
            ha="left",
            va="bottom",
            fontsize=7,
        )
        _lobe_legend(axz, zoom, curves, d, "outside", count)
        axz.set_title(f"zoom on {zlo:.5g}-{zhi:.5g} {unit} around the minimum: individual lobes", fontsize=8)
    if axz is not None or main["dense"]:
        leg = ax.legend(
            handles=main["handles"],
            loc="upper left",
            bbox_to_anchor=(1.01, 1.0),
            fontsize=6.5,
            framealpha=0.92,
            title=note,
            title_fontsize=6.5,
            alignment="left",
        )
        if note:
            leg.get_title().set_gid("dense-note")
    else:
        _lobe_legend(ax, main, curves, d, "outside", count)
    ax.set_ylabel("width of cut b [mm]")
    ax.grid(alpha=0.3)
    fin = np.isfinite(main["width"]) & (main["freq"] > 0)
    axf.plot(main["speed"][fin], main["freq"][fin], ".", ms=1, color="tab:blue", rasterized=True)
    axf.set_ylabel("chatter [Hz]")
    axf.set_xlabel(f"{d.speed_name} [{unit}]")
    axf.set_title("chatter frequency along the envelope", fontsize=8, loc="left")
    axf.grid(alpha=0.3)
    if axz is not None:
        ax.set_xlabel(f"{d.speed_name} [{unit}]")
    head = title if title is not None else f"{_model_name(d)}: stability lobes"
    ax.set_title(f"{head}\n{_subtitle(d)}", fontsize=9)
    if created:
        ax.figure.set_gid(LAID_OUT)
    return axes


def _lobe_count(curves: list[_Curve], d: Any) -> str:
    """The number of lobes drawn, said against the diagram's summary."""
    ks = {(c.k, c.branch) for c in curves}
    if not ks:
        return "no lobe below the width ceiling"
    kk = sorted(k for k, _ in ks)
    txt = f"{len(ks)} lobes in the speed range (k = {kk[0]}-{kk[-1]})"
    if len(ks) == len(d.lobes):
        return txt + ", as in the summary"
    return txt + f";\nthe summary's {len(d.lobes)} are those on the envelope at its {np.size(d.speed)} speeds"


def _lobe_legend(ax: Any, drawn: dict[str, Any], curves: list[_Curve], d: Any, loc: str, count: str) -> None:
    import textwrap

    from matplotlib.lines import Line2D

    handles = list(drawn["handles"])
    if curves:
        txt = count
        if drawn["labelled"]:
            multi = len({c.branch for c in curves}) > 1
            txt += "\nnumbers: lobe k" + ("/branch" if multi else "") + " at its bottom"
        if loc == "outside":
            txt = "\n".join(textwrap.fill(line, 46) for line in txt.split("\n"))
        handles.append(Line2D([], [], ls="none", label=txt))
    if loc == "outside":
        ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=6.5, framealpha=0.9)
    else:
        ax.legend(handles=handles, loc=loc, fontsize=6.5, framealpha=0.9, ncol=2)


def _atlas_model_name(result: Any, model: str | None) -> str:
    if model:
        return model
    attrs = getattr(result, "attrs", {}) or {}
    if attrs.get("model"):
        return str(attrs["model"])
    text = attrs.get("model_text")
    if text:
        import tomllib

        try:
            name = tomllib.loads(str(text)).get("model", {}).get("name")
        except tomllib.TOMLDecodeError:
            name = None
        if name:
            return str(name)
    return "model not named"


def plot_atlas(
    result: Any,
    process: Any = None,
    *,
    axes: Any = None,
    title: str | None = None,
    model: str | None = None,
    width_max: float | None = None,
    terms: str | None = None,
) -> Any:
    """Stability atlas: b_lim (mm) over speed x slide position as a map,
    above the worst case along the stroke (the minimum over positions).

    ``result`` is the :class:`~chatterlab.sweep._engine.SweepResult` of an atlas
    sweep (axes ``position``, ``speed``); ``model`` names it in the title
    (default: the result's ``model`` attribute or the name in its
    ``model_text``) and ``width_max`` (m) is the width ceiling: cells with
    b_lim = inf (no chatter below it) are grey, cells that failed
    (NaN) white, each with a legend entry; ``terms`` is the feedback (default:
    the result's ``terms`` attribute).  Returns (ax_map, ax_worst)."""
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    pos = np.asarray(result.grid.axes[0].values, float)
    v = np.asarray(result.grid.axes[1].values, float)
    unit = result.grid.axes[1].unit
    attrs = getattr(result, "attrs", {}) or {}
    wmax = width_max if width_max is not None else attrs.get("width_max_m")
    ceiling = f"the {float(wmax) * 1e3:g} mm ceiling" if wmax is not None else "the width ceiling"
    bl = np.asarray(result.data["b_lim"], float) * 1e3
    if axes is None:
        fig, axes = plt.subplots(
            2, 1, sharex=True, figsize=(8.5, 6.8), gridspec_kw={"height_ratios": [2, 1.3]}
        )
    ax, axw = axes
    speed_name = getattr(process, "speed_name", "speed")
    isinf, isnan = np.isinf(bl), np.isnan(bl)
    finite = np.where(np.isfinite(bl), bl, np.nan)
    anyfin = bool(np.any(np.isfinite(finite)))
    vmax = float(np.nanpercentile(finite, 95)) if anyfin else 1.0
    vmin = float(np.nanmin(finite)) if anyfin else 0.0
    extra: list[Any] = []
    if pos.size > 1:
        mesh = ax.pcolormesh(v, pos, finite, shading="nearest", cmap="viridis", vmin=vmin, vmax=vmax)
        # the colour bar outside the map's frame keeps both panels' speed axes aligned
        cax = ax.inset_axes((1.015, 0.0, 0.02, 1.0))
        cb = ax.figure.colorbar(mesh, cax=cax, extend="max" if np.nanmax(finite) > vmax else "neither")
        cb.set_label("b_lim [mm] (largest chatter-free width)")
        if np.any(isinf):
            ax.pcolor(
                *np.meshgrid(_cell_edges(v), _cell_edges(pos)),
                np.ma.masked_where(~isinf, np.ones_like(bl)),
                cmap=ListedColormap(["0.78"]),
                lw=0,
            )
            extra.append(Patch(facecolor="0.78", label=f"grey: b_lim = inf, no chatter below {ceiling}"))
        if np.any(isnan):
            extra.append(Patch(facecolor="white", edgecolor="0.4", label="not computed (task failed)"))
        ax.set_ylabel("slide position s [m]")
        if extra:
            ax.legend(handles=extra, loc="upper right", fontsize=7, framealpha=0.9)
    else:
        ax.plot(v, finite[0])
        ax.set_ylabel("b_lim [mm]")
    ax.set_xlabel(f"{speed_name} [{unit}]")
    ax.xaxis.set_tick_params(labelbottom=True)
    worst = np.min(np.where(isnan, np.inf, bl), axis=0)
    wfin = np.isfinite(worst)
    ytop = float(np.max(worst[wfin])) * 1.35 if np.any(wfin) else 1.0
    axw.plot(
        v,
        np.where(wfin, worst, np.nan),
        ".",
        ms=2.5,
        color="tab:red",
        label=f"worst case over positions, at the {v.size} sampled speeds (unstable above)",
    )
    if np.any(wfin):
        m = float(np.min(worst[wfin]))
        axw.axhline(m, color="k", ls="--", lw=1, label=f"smallest over the atlas {m:.4g} mm")
    axw.set_title(
        "worst case along the stroke, at the sampled speeds only: between them lobes may dip lower"
        " (see the lobe diagram)",
        fontsize=7.5,
        loc="left",
    )
    if np.any(~wfin):
        axw.fill_between(
            v,
            0.92,
            1.0,
            where=~wfin,
            transform=axw.get_xaxis_transform(),
            facecolor="none",
            edgecolor="tab:green",
            hatch="////",
            lw=0,
            label=f"inf at every position: no chatter below {ceiling}",
        )
    axw.set_ylim(0, ytop)
    axw.set_ylabel("worst b_lim [mm]")
    axw.set_xlabel(f"{speed_name} [{unit}]")
    axw.legend(fontsize=7, loc="upper right")
    axw.grid(alpha=0.3)
    name = _atlas_model_name(result, model)
    terms = terms or attrs.get("terms")
    sub = f"{pos.size} positions {pos.min():g}-{pos.max():g} m x {v.size} speeds"
    if terms:
        sub += f"; feedback {terms}"
    if wmax is not None:
        sub += f"; width ceiling {float(wmax) * 1e3:g} mm"
    head = title or f"{name}: stability atlas along the stroke"
    if title and name not in title:
        head = f"{name}: {title}"
    ax.set_title(f"{head}\n{sub}", fontsize=9)
    return axes


def _cell_edges(x: np.ndarray) -> np.ndarray:
    """Edges of cells centred on the sorted values x."""
    if x.size == 1:
        return np.array([x[0] - 0.5, x[0] + 0.5])
    mid = 0.5 * (x[1:] + x[:-1])
    return np.r_[x[0] - (mid[0] - x[0]), mid, x[-1] + (x[-1] - mid[-1])]


def plot_histories(
    sims: Sequence[Any],
    names: Sequence[str],
    *,
    against: str = "time",
    labels: Sequence[str] | None = None,
    axes: Any = None,
    scale: float = 1e6,
    unit: str = "um",
) -> Any:
    """Time histories of outputs (one panel per output, the runs overlaid),
    against time (s) or against the distance travelled in the cut (mm), as
    in the paper's Figs. 4-9.  Displacements shown in micrometres by default.
    Returns the Axes."""
    import matplotlib.pyplot as plt

    if axes is None:
        fig, axes = plt.subplots(
            len(names), 1, sharex=True, figsize=(8.5, 2.4 * len(names) + 0.6), squeeze=False
        )
        axes = axes[:, 0]
    for k, sim in enumerate(sims):
        lab = labels[k] if labels is not None else f"feedback {sim.terms}"
        if against == "distance":
            m = sim.window("last-cut")
            x = sim.cut_distance[m] * 1e3
        else:
            m = np.ones(sim.t.size, bool)
            x = sim.t
        for ax, n in zip(axes, names, strict=False):
            ax.plot(x, sim.data[n][m] * scale, lw=0.8, label=lab)
    for ax, n in zip(axes, names, strict=False):
        ax.set_ylabel(f"{n} [{unit}]")
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("distance of cutting s [mm]" if against == "distance" else "time [s]")
    axes[0].legend(fontsize=8, loc="upper right")
    if against == "time" and sims:
        s0 = sims[0]
        for ax in axes:
            cut = s0.in_cut.astype(float)
            lo, hi = ax.get_ylim()
            ax.fill_between(s0.t, lo, hi, where=cut > 0, color="0.85", alpha=0.5, lw=0, zorder=0)
            ax.set_ylim(lo, hi)
    return axes


def plot_spectra(
    sims: Sequence[Any],
    name: str,
    *,
    labels: Sequence[str] | None = None,
    ax: Any = None,
    fmax: float = 300.0,
    window: Any = "last-cut",
    scale: float = 1e6,
    unit: str = "um",
) -> Any:
    """Amplitude spectra of one output for several runs overlaid (the
    paper's Figs. 10-11), with the main peak of each run marked."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(8, 3.8))
    colors = ["tab:red", "tab:green", "tab:blue", "tab:purple", "tab:orange"]
    for k, sim in enumerate(sims):
        f, a = sim.spectrum(name, window=window)
        m = f <= fmax
        lab = labels[k] if labels is not None else f"feedback {sim.terms}"
        col = colors[k % len(colors)]
        ax.plot(f[m], a[m] * scale, color=col, lw=1, label=lab)
        if np.any(m):
            j = int(np.argmax(a[m]))
            ax.annotate(
                f"{f[m][j]:.1f} Hz",
                (f[m][j], a[m][j] * scale),
                textcoords="offset points",
                xytext=(4, 2),
                fontsize=8,
                color=col,
            )
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"amplitude of {name} [{unit}]")
    ax.set_xlim(0, fmax)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return ax
