"""One panel of a lobe diagram: the lobes, the exact envelope, the unstable
region, the limits and the claims, drawn over a speed range."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

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


def axes_pixels(ax: Any, dpi: float) -> float:
    fig = ax.figure
    return max(float(ax.get_position().width * fig.get_figwidth() * dpi), 50.0)


def _speed_grid(ax: Any, lo: float, hi: float, extra: np.ndarray) -> np.ndarray:
    """>= ENVELOPE_POINTS_PER_PIXEL points per pixel of the Axes (at
    ENVELOPE_DPI) over [lo, hi], plus the ``extra`` speeds inside."""
    n = int(np.ceil(ENVELOPE_POINTS_PER_PIXEL * axes_pixels(ax, ENVELOPE_DPI) * 1.1)) + 1
    g = np.linspace(lo, hi, n)
    extra = extra[(extra >= lo) & (extra <= hi)]
    return np.unique(np.concatenate([g, extra]))


def bottoms(curves: list[Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Speed and width (m) of each lobe's lowest sample, and its branch."""
    if not curves:
        return np.zeros(0), np.zeros(0), np.zeros(0, int)
    j = [int(np.argmin(c.width)) for c in curves]
    return (
        np.array([c.speed[i] for c, i in zip(curves, j, strict=True)]),
        np.array([c.width[i] for c, i in zip(curves, j, strict=True)]),
        np.array([c.branch for c in curves]),
    )


def lobe_density(curves: list[Any], lo: float, hi: float, pixels: float) -> float:
    """Most lobe bottoms of one branch within DENSE_PIXELS pixel columns."""
    sp, _, br = bottoms(curves)
    n = max(int(pixels), 1)
    worst = 0.0
    for b in np.unique(br):
        h, _ = np.histogram(sp[br == b], bins=n, range=(lo, hi))
        win = np.convolve(h, np.ones(DENSE_PIXELS), "valid") if n >= DENSE_PIXELS else h
        worst = max(worst, float(win.max()) if win.size else 0.0)
    return worst


def zoom_range(curves: list[Any], d: Any, lo: float, hi: float) -> tuple[float, float]:
    """A speed range around the diagram's minimum holding about 2 ZOOM_LOBES + 1
    lobes of the branch that forms the envelope there."""
    vc = float(d.minimum["speed"]) if np.isfinite(d.minimum["speed"]) else 0.5 * (lo + hi)
    sp, wd, br = bottoms(curves)
    if sp.size == 0:
        return lo, hi
    near = np.argsort(np.abs(sp - vc))[:4]
    b = br[near[np.argmin(wd[near])]]
    s = np.sort(sp[br == b])
    i = int(np.argmin(np.abs(s - vc)))
    a, e = max(i - ZOOM_LOBES, 0), min(i + ZOOM_LOBES, s.size - 1)
    pad = 0.5 * (s[e] - s[a]) / max(e - a, 1)
    return max(lo, s[a] - pad), min(hi, s[e] + pad)


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


def draw_lobe_panel(
    ax: Any,
    d: Any,
    curves: list[Any],
    lo: float,
    hi: float,
    *,
    geometry: Any,
    lobe_numbers: int,
    dense_ok: bool,
    references: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Lobes (one LineCollection), the exact envelope, the unstable region and
    the claims on one Axes over speeds [lo, hi].  Returns what was drawn."""
    ax.set_xlim(lo, hi)
    px = axes_pixels(ax, DISPLAY_DPI)
    density = lobe_density(curves, lo, hi, px)
    dense = dense_ok and density > 1
    measured = bool(getattr(d, "band_measured", False))
    if measured:
        # a measured FRF's lobes are curves through noisy samples, and noise
        # breaks them into pieces the plot cannot join: between the requested
        # speeds their minimum could miss a lobe and draw a "pocket" that is
        # not there (a review found 17 mm spikes over a 0.42 mm limit), so the
        # envelope is the engine's b_lim at the requested speeds, nothing between
        v = np.asarray(d.speed, float)
        o = np.argsort(v)
        keep = (v[o] >= lo) & (v[o] <= hi)
        vx, env, fq = (
            v[o][keep],
            np.asarray(d.b_lim, float)[o][keep],
            np.asarray(d.chatter_hz, float)[o][keep],
        )
        dense = False
    else:
        vg = _speed_grid(ax, lo, hi, np.asarray(d.speed, float))
        vx, env, fq = geometry.envelope_line(vg)
    em = env * 1e3
    fin = np.isfinite(em)
    top = d.width_max * 1e3
    peak = float(np.max(em[fin])) if np.any(fin) else top
    ytop = top if 1.2 * peak >= top else 1.2 * peak
    handles = _draw_lobes_and_envelope(ax, curves, lo, hi, vx, em, ytop, px, dense, measured, d.limit_name)
    handles += _draw_limits(ax, d, lo, hi, references)
    # a model with beams whose finer mesh has a limit where this one ends at the ceiling
    # (lobes._mesh_error), or whose mesh was not checked (--no-mesh-check)
    handles += _draw_claims(ax, _claim_spans(d, vx, em), lo, hi, top, mesh_claim(getattr(d, "meta", None)))
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


def _draw_lobes_and_envelope(
    ax: Any,
    curves: list[Any],
    lo: float,
    hi: float,
    vx: np.ndarray,
    em: np.ndarray,
    ytop: float,
    px: float,
    dense: bool,
    measured: bool = False,
    limit: str = "b_lim",
) -> list[Any]:
    """The lobes (unless dense), the unstable region above the envelope
    ``em`` (mm at speeds ``vx``), the band the envelope sweeps per pixel
    column (when dense) and the envelope line (for a measured FRF: b_lim at
    the requested speeds, marked).  Returns the legend handles."""
    from matplotlib.collections import LineCollection
    from matplotlib.patches import Patch

    fin = np.isfinite(em)
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
        lc.set_label(
            "lobes through the measured samples" if measured else "lobes (each an exact boundary curve)"
        )
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
        handles.append(Patch(color="tab:red", alpha=0.55, label="band swept within a pixel column"))
    if measured:
        (line,) = ax.plot(vx, em, ".-", color="tab:red", lw=0.8, ms=2.5, zorder=3,
                          label=f"{limit} at the requested speeds (measured FRF)")  # fmt: skip
    else:
        (line,) = ax.plot(
            vx,
            em,
            color="tab:red",
            lw=0.5 if dense else 1.6,
            zorder=3,
            label=f"{limit} (exact lower envelope)",
        )
    line.set_gid("envelope")
    handles.append(line)
    return handles


def _draw_limits(ax: Any, d: Any, lo: float, hi: float, references: Mapping[str, Any] | None) -> list[Any]:
    """The unconditional limit, the minimum of the range and the reference
    widths.  Returns the legend handles."""
    handles: list[Any] = []
    a = d.absolute_minimum["width"] * 1e3
    if np.isfinite(a):
        (al,) = ax.plot(
            [lo, hi],
            [a, a],
            color="k",
            ls="--",
            lw=1,
            zorder=4,
            label=f"unconditional limit {a:.4g} mm",
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
            label=f"minimum {m['width'] * 1e3:.4g} mm at {m['speed']:.4g} {d.speed_unit}",
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
    return handles


def mesh_claim(meta: Any) -> str:
    """What a figure adds to its claims of no chatter below the ceiling from a
    model with beams' mesh check (lobes._mesh_error; a diagram's ``meta`` or
    an atlas's ``attrs``): "not confirmed" where the mesh twice as fine finds
    a limit at some of them, "not checked" where that check was not run
    (``mesh_estimated`` = 0), else ""."""
    meta = meta or {}
    if meta.get("mesh_free_speeds_fine_limited") or meta.get("mesh_free_points_fine_limited"):
        return "not confirmed"
    return "not checked" if meta.get("mesh_estimated") == 0 else ""


#: the keys of the smallest limit's relative error bound: a lobe diagram's, a milling one's, ssv's
_MIN_BOUNDS = ("mesh_absolute_min_error_bound", "mesh_min_error_bound", "mesh_error_bound")


def mesh_note(ax: Any, meta: Any) -> None:
    """A model with beams: the discretisation error the result carries
    (lobes._mesh_error; a diagram's ``meta``), right of the Axes' title, so
    that the figure says what its mesh costs in accuracy -- or that it was
    not estimated (``mesh_estimated`` = 0)."""
    meta = meta or {}
    if meta.get("mesh_estimated") == 0:  # --no-mesh-check, lobes(mesh_error=False)
        ax.set_title(
            "beam mesh: discretisation error not estimated", fontsize=7, loc="right", color="tab:red"
        )
        return
    if "mesh_beam_elements" not in meta:
        return
    # the smallest limit's bound (a diagram, milling, ssv), the amplitude's (a runout response)
    bound = next((meta[k] for k in _MIN_BOUNDS if k in meta), None)
    amp = meta.get("mesh_amplitude_error_bound_max")
    env = meta.get("mesh_envelope_change_median")
    lost = meta.get("mesh_undetermined_points", meta.get("mesh_undetermined_speeds", 0)) or 0
    parts = [f"beam mesh of {meta['mesh_beam_elements']} elements"]
    if bound is not None and np.isfinite(bound):
        parts.append(f"minimum within {bound:.0%}")
    if amp is not None and np.isfinite(amp):
        parts.append(f"amplitude within {amp:.0%}")
    if env is not None and np.isfinite(env):
        parts.append(f"envelope moves {env:.0%} (median) on a mesh twice as fine")
    if lost:
        parts.append(f"{lost} undetermined on a mesh twice as fine")
    warn = (env or 0) > 0.01 or (bound or 0) > 0.01 or (amp or 0) > 0.01 or lost > 0
    ax.set_title("; ".join(parts), fontsize=7, loc="right", color="tab:red" if warn else "0.3")


def _draw_claims(
    ax: Any,
    spans: dict[int, list[tuple[float, float]]],
    lo: float,
    hi: float,
    top: float,
    mesh: str = "",
) -> list[Any]:
    """The claims that are not a boundary, as spans of speed: inf (hatched at
    the top), undetermined (orange), contradicted (magenta).  ``mesh``: "not
    confirmed" when the mesh twice as fine has a limit where this diagram
    has none below the ceiling, "not checked" when that mesh was not run,
    and the legend says so.  Returns the legend handles (one per kind
    drawn)."""
    handles: list[Any] = []
    trans = ax.get_xaxis_transform()
    styles: dict[int, dict[str, Any]] = {
        1: dict(
            y=(0.93, 1.0),
            hatch="////",
            fc="none",
            ec="tab:green",
            label=f"no chatter below the {top:g} mm ceiling"
            + (f"\n({mesh} on a mesh twice as fine)" if mesh else ""),
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
        drawn: list[tuple[float, float]] = []  # the spans clipped to [lo, hi]
        for x0, x1 in spans.get(code, []):
            if x1 < lo or x0 > hi:
                continue
            x0, x1 = max(x0, lo), min(x1, hi)
            if x1 <= x0:
                x1 = x0 + 1e-3 * (hi - lo)
            first = not drawn
            drawn.append((x0, x1))
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
                label=st["label"] if first else None,
            )
            p.set_gid(f"claim-{code}")
            if first:
                handles.append(p)
        if code == 1 and drawn:
            # a span of one speed is a pixel or two wide: mark each on the top edge too
            xs = [0.5 * (a + b) for a, b in drawn]
            (mk,) = ax.plot(xs, [1.0] * len(xs), "v", color="tab:green", ms=6, transform=trans,
                            clip_on=False, zorder=7, gid="claim-1-marker")  # fmt: skip
            handles[-1] = (handles[-1], mk)
    return handles


def _label_lobes(
    ax: Any,
    curves: list[Any],
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
    sp, wd, br = bottoms(curves)
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
