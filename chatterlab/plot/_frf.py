"""Frequency response functions and the Nyquist plots of the cutting loop.

* :func:`plot_frf` -- magnitude and phase (or real and imaginary part) of one
  or more FRFs against frequency in Hz (one entry, or every entry), open and
  closed loop overlaid, the resonances labelled without overlap (what
  ``FRF.plot`` draws);
* :func:`plot_nyquist` -- the loop determinant det(I - G D) about its
  critical point, the origin, with the region around it zoomed;
* :func:`plot_loop_nyquist` -- the eigenvalue loci of the loop per unit width,
  with the critical point -1/b and the width b* at which a locus touches it
  (:func:`touching_width`), each locus followed through the frequencies
  (:func:`track_loci`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ._style import LAID_OUT, axes_arg, index_of


def _frf_label(f: Any) -> str:
    """The FRF's own label with the width and delay of a closed loop."""
    lab = str(f.label)
    if getattr(f, "closed_loop", False):
        if getattr(f, "width", None):
            lab += f", b = {f.width * 1e3:.4g} mm"
        if getattr(f, "delay", None):
            lab += f", T = {f.delay:.4g} s"
    return lab


def plot_frf(
    frfs: Sequence[Any],
    *,
    output: int | str | None = 0,
    input: int | str | None = 0,
    labels: Sequence[str] | None = None,
    ax: Any = None,
    title: str | None = None,
    peaks: int = 0,
    part: str = "bode",
    axes: Any = None,
) -> Any:
    """One or more FRFs against frequency in Hz, overlaid: the open- vs
    closed-loop comparison of the paper's Figs. 10-11.

    ``output`` / ``input`` (index or name) pick the entry of each FRF; both
    None draw every entry of every FRF (outputs outer, inputs inner; the
    legend names each ``OUT / IN``).  ``part="bode"``: magnitude (log scale)
    above the phase in degrees, unwrapped along frequency (a delayed loop's
    phase does not wrap at +-180 deg) where the grid follows it;
    ``part="reim"``: real above imaginary part.  ``peaks`` > 0 labels that
    many resonances of each curve (refined peak frequencies, in the curve's
    colour, stacked where they would overlap).  A closed-loop curve's legend
    entry says its width and delay, a ``title`` gets the slide position when
    the FRF has one.  ``ax`` is a pair of Axes (``axes=`` a deprecated
    alias).  Returns the Axes (ax_top, ax_bottom)."""
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MultipleLocator

    if part not in ("bode", "reim"):
        raise ValueError(f"plot_frf: part must be 'bode' or 'reim', got {part!r}")
    axes = axes_arg(ax, axes, "plot_frf")
    if axes is None:
        fig, axes = plt.subplots(2, 1, sharex=True, figsize=(8, 6), gridspec_kw={"height_ratios": [2, 1]})
    ax_m, ax_p = axes
    every = output is None and input is None
    curves = []  # (frf, output index, input index, legend)
    for k, f in enumerate(frfs):
        if every:
            for o, on in enumerate(f.outputs):
                for i, inn in enumerate(f.inputs):
                    pre = f"{labels[k]}: " if labels is not None else ""
                    curves.append((f, o, i, f"{pre}{on} / {inn}"))
        else:
            o, i = index_of(f.outputs, output or 0), index_of(f.inputs, input or 0)
            curves.append((f, o, i, labels[k] if labels is not None else _frf_label(f)))
    marks: list[tuple[float, float, Any]] = []
    wrapped = part == "bode" and not all(_unwrappable(f.data[o, i]) for f, o, i, _ in curves)
    for f, o, i, lab in curves:
        z = f.data[o, i]
        if part == "bode":
            (line,) = ax_m.semilogy(f.frequency_hz, np.abs(z), label=lab, gid="magnitude")
            ph = np.angle(z) if wrapped else np.unwrap(np.angle(z))
            style = {"ls": "none", "marker": ".", "ms": 1.5} if wrapped else {}  # no vertical jumps at ±180
            ax_p.plot(f.frequency_hz, np.degrees(ph), color=line.get_color(), gid="phase", **style)
        else:
            (line,) = ax_m.plot(f.frequency_hz, z.real, label=lab, gid="real")
            ax_p.plot(f.frequency_hz, z.imag, color=line.get_color(), gid="imag")
        if peaks:
            for fp, mp in f.peaks(o, i, peaks):
                zp = np.interp(fp, f.frequency_hz, z.real) if part == "reim" else mp
                marks.append((fp, float(zp), line.get_color()))
    f0, o, i, _ = curves[0]
    pair = "H" if every else f"{f0.outputs[o]} / {f0.inputs[i]}"
    if part == "bode":
        ax_m.set_ylabel(f"|{pair}|  [{f0.unit}]")
        if wrapped:  # too few points per turn of the phase to follow it: the principal value
            ax_p.set_ylabel("phase [deg], in ±180°")
            ax_p.set_ylim(-190, 190)
            ax_p.yaxis.set_major_locator(MultipleLocator(90))
        else:
            ax_p.set_ylabel("phase [deg] (unwrapped)")
            lo, hi = ax_p.get_ylim()
            ax_p.yaxis.set_major_locator(
                MultipleLocator(90 if hi - lo <= 720 else 180 * np.ceil((hi - lo) / 1440))
            )
    else:
        ax_m.set_ylabel(f"Re {pair}  [{f0.unit}]")
        ax_p.set_ylabel(f"Im {pair}  [{f0.unit}]")
    ax_p.set_xlabel("frequency [Hz]")
    for a in axes:
        a.grid(True, which="both", alpha=0.3)
    if marks and part == "bode":
        lo, hi = ax_m.get_ylim()
        ax_m.set_ylim(lo, hi * (hi / lo) ** 0.15)  # headroom for the peak labels
    _label_peaks(ax_m, marks)
    # the legend above the frame, where no curve or peak label can be under it
    rows = int(np.ceil(len(curves) / 2))
    ax_m.legend(loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=2, fontsize=8, frameon=False)
    pos = getattr(f0, "position", None)
    if title:
        where = f"\nslide at s = {pos:g} m" if pos is not None else ""
        ax_m.set_title(title + where, pad=6 + 14 * rows, fontsize=10 if where else None)
    return axes


#: an unwrapped phase is trusted when no step between neighbouring frequencies exceeds this (deg)
UNWRAP_STEP_DEG = 60.0


def _unwrappable(z: np.ndarray) -> bool:
    """Whether the frequency grid follows the phase of z closely enough to
    unwrap it: every step of the unwrapped phase below UNWRAP_STEP_DEG.  A
    delayed loop on a coarse grid (e^{-j w T} turning once per 1/T Hz over a
    few points) is not, and np.unwrap there adds spurious whole turns (the
    +1440 deg of issue 20)."""
    ph = np.degrees(np.unwrap(np.angle(np.asarray(z))))
    return ph.size < 2 or float(np.max(np.abs(np.diff(ph)))) < UNWRAP_STEP_DEG


def plot_frf_pairs(frfs: Sequence[Any], *, title: str | None = None, peaks: int = 0) -> Any:
    """Every (output, input) pair of the FRFs, one magnitude/phase pair of
    panels each (outputs outer, inputs inner), the curves of ``frfs``
    overlaid as in :func:`plot_frf`; each pair's title is ``title`` with the
    pair.  Returns the Axes, an array (2 * pairs,)."""
    import matplotlib.pyplot as plt

    f0 = frfs[0]
    pairs = [(o, i) for o in f0.outputs for i in f0.inputs]
    fig = plt.figure(figsize=(8, 5.4 * len(pairs)), layout="constrained")
    made: Any = fig.subfigures(len(pairs), 1, hspace=0.04)  # one SubFigure, or an array of them
    subs = np.atleast_1d(made)
    axs = []
    for sf, (o, i) in zip(subs, pairs, strict=True):
        pair = sf.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1]})
        plot_frf(
            frfs,
            output=o,
            input=i,
            ax=pair,
            title=f"{title}: {o} / {i}" if title else f"{o} / {i}",
            peaks=peaks,
        )
        axs.extend(pair)
    fig.set_gid(LAID_OUT)
    return np.array(axs, dtype=object)


def _label_peaks(ax: Any, marks: list[tuple[float, float, Any]]) -> None:
    """Write each peak's frequency next to it, moving a label up in steps of
    one text line while it would overlap a label already placed."""
    if not marks:
        return
    ax.get_xlim(), ax.get_ylim()  # the autoscaled limits, before reading transData
    tr = ax.transData
    pt = ax.figure.dpi / 72.0  # pixels per point
    placed: list[tuple[float, float, float, float]] = []
    for fp, yp, col in sorted(marks, key=lambda m: (m[0], -m[1])):
        txt = f"{fp:.1f} Hz"
        x, y = tr.transform((fp, yp))
        w, h = 5.2 * len(txt) * pt, 11 * pt  # a label of fontsize 8
        dy = 4.0
        for _ in range(8):
            box = (x + 4 * pt, x + 4 * pt + w, y + dy * pt, y + dy * pt + h)
            if not any(
                not (box[1] < p[0] or box[0] > p[1] or box[3] < p[2] or box[2] > p[3]) for p in placed
            ):
                break
            dy += 11
        placed.append(box)
        ax.annotate(
            txt,
            (fp, yp),
            textcoords="offset points",
            xytext=(4, dy),
            fontsize=8,
            color=col,
            gid="peak-label",
            arrowprops={"arrowstyle": "-", "color": col, "lw": 0.5} if dy > 4 else None,
        )


def plot_nyquist(
    omega: np.ndarray,
    det: np.ndarray,
    *,
    ax: Any = None,
    title: str | None = None,
    verdict: str | None = None,
    zoom: bool = True,
) -> Any:
    """Nyquist plot of the loop determinant det(I - G D) for w from 0 up,
    mirrored for negative w; the critical point is the origin.

    The point of closest approach to the origin is marked with its frequency
    (Hz), and with ``zoom`` a second frame beside the plot (an inset Axes
    outside its frame; inside its upper right corner when ``ax`` is given)
    shows the region around the origin, a square of
    half-side 3 times the closest distance, where the encirclement is
    decided.  ``verdict`` (e.g. the stability result's summary) is written
    in the corner.  Returns the Axes (the main one; the inset has gid
    ``nyquist-zoom``)."""
    import matplotlib.pyplot as plt

    beside = ax is None  # a figure of our own has room for the zoom beside the plot
    if ax is None:
        fig = plt.figure(figsize=(10, 5.2) if zoom else (5.5, 5.5))
        # with the zoom: the main plot on the left half, the zoom beside it (outside its frame)
        ax = fig.add_axes((0.08, 0.1, 0.4, 0.8)) if zoom else fig.add_subplot()
        if zoom:
            fig.set_gid(LAID_OUT)
    omega, det = np.asarray(omega, float), np.asarray(det, complex)
    j = int(np.argmin(np.abs(det)))
    near = float(np.abs(det[j]))
    fj = omega[j] / (2 * np.pi)

    def draw(a: Any, legend: bool) -> None:
        a.plot(det.real, det.imag, lw=1, color="tab:blue", label="ω > 0" if legend else None, gid="nyquist")
        a.plot(
            det.real,
            -det.imag,
            lw=0.8,
            ls="--",
            color="tab:orange",
            label="ω < 0 (mirror)" if legend else None,
        )
        a.plot([0], [0], "r+", ms=12, mew=2, label="critical point (origin)" if legend else None)
        a.plot(
            [det[j].real],
            [det[j].imag],
            "o",
            mfc="none",
            mec="tab:red",
            ms=7,
            label=f"closest: |det| = {near:.3g} at {fj:.2f} Hz" if legend else None,
            gid="closest",
        )

    draw(ax, True)
    ax.plot([1], [0], "k.", label="open loop (1)")
    ax.set_xlabel("Re det(I - G D)")
    ax.set_ylabel("Im det(I - G D)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left", fontsize=7)
    if zoom and near > 0:
        r = 3.0 * near
        axi = ax.inset_axes((1.18, 0.0, 1.0, 1.0) if beside else (0.6, 0.6, 0.38, 0.38))
        axi.set_gid("nyquist-zoom")
        draw(axi, False)
        from matplotlib.patches import Rectangle

        ax.add_patch(Rectangle((-r, -r), 2 * r, 2 * r, fill=False, ec="k", lw=0.8, zorder=5))
        axi.set_xlim(-r, r)
        axi.set_ylim(-r, r)
        axi.set_aspect("equal")
        axi.tick_params(labelsize=7)
        axi.grid(alpha=0.3)
        axi.set_xlabel("Re det(I - G D)", fontsize=7)
        axi.set_ylabel("Im det(I - G D)", fontsize=7)
        axi.set_title(f"zoom on the origin: ±{r:.2g} (3 × the closest distance)", fontsize=8)
    if verdict:
        ax.text(
            0.02,
            0.98,
            verdict,
            transform=ax.transAxes,
            va="top",
            fontsize=8,
            bbox={"fc": "white", "ec": "0.6", "alpha": 0.9},
            gid="verdict",
        )
    if title:
        ax.set_title(title, fontsize=9)
    return ax


def track_loci(loop: np.ndarray) -> np.ndarray:
    """Columns of ``loop`` (n_freq, m) reordered so that each column follows
    one locus: eigenvalues come in no particular order at each frequency,
    so where the nearest neighbours of one sample's values in the previous
    sample are not in the same columns, the columns are matched by the
    permutation of least total distance (all m! for m <= 6, greedily above),
    and the matchings are composed along frequency."""
    from itertools import permutations

    L = np.asarray(loop, complex)
    L = L.reshape(L.shape[0], -1)
    n, m = L.shape
    if m == 1 or n < 2:
        return L
    d = np.abs(L[1:, :, None] - L[:-1, None, :])  # d[j, a, b]: next a to previous b
    steps = np.nonzero(np.any(np.argmin(d, axis=2) != np.arange(m), axis=1))[0]
    perms = list(permutations(range(m))) if m <= 6 else None
    order = np.arange(m)  # the raw column holding each tracked locus
    out = np.empty_like(L)
    start = 0
    for j in steps.tolist():
        out[start : j + 1] = L[start : j + 1][:, order]
        if perms is not None:
            cost = [sum(d[j, a, p[a]] for a in range(m)) for p in perms]
            match = np.array(perms[int(np.argmin(cost))])  # next a <- previous match[a]
        else:
            match = np.argmin(d[j], axis=1)
        nxt = np.empty(m, int)
        nxt[match] = np.arange(m)  # previous b -> next nxt[b]
        order = nxt[order]
        start = j + 1
    out[start:] = L[start:][:, order]
    return out


def touching_width(omega: np.ndarray, loop: np.ndarray) -> tuple[float, float]:
    """The smallest width b* > 0 at which a locus of the loop per unit width
    reaches the critical point -1/b, and its frequency (Hz): over the
    crossings of the negative real axis (a sign change of Im between two
    samples of one tracked locus (:func:`track_loci`), Re interpolated
    linearly there), b* = -1 / Re.  (inf, nan) when no locus crosses it in
    the sampled band."""
    omega = np.asarray(omega, float)
    L = track_loci(np.asarray(loop, complex).reshape(omega.size, -1))
    im, re = L.imag, L.real
    s = np.nonzero((im[:-1] * im[1:] <= 0) & (im[:-1] != im[1:]))
    j, c = s
    t = im[j, c] / (im[j, c] - im[j + 1, c])
    x = re[j, c] + t * (re[j + 1, c] - re[j, c])
    w = omega[j] + t * (omega[j + 1] - omega[j])
    neg = x < 0
    if not np.any(neg):
        return float("inf"), float("nan")
    b = -1.0 / x[neg]
    k = int(np.argmin(b))
    return float(b[k]), float(w[neg][k] / (2 * np.pi))


def plot_loop_nyquist(
    omega: np.ndarray,
    loop: np.ndarray,
    *,
    width: float,
    ax: Any = None,
    title: str | None = None,
) -> Any:
    """Nyquist plot of the cutting loop per unit width.

    ``loop`` (n_freq,) or (n_freq, m), complex: the eigenvalues lambda_i(jw)
    of the loop matrix per unit width, 1/m, so that det(I - G D) =
    prod_i (1 + b lambda_i) at width b (m); for one coupling direction it is
    the oriented FRF times the cutting stiffness and the regeneration factor.
    The critical point of width ``width`` is -1/b; the loci reach it when
    b = b* (:func:`touching_width`), marked with its frequency.  For b < b*
    no locus reaches -1/b in the plotted band (and nothing is said about
    frequencies outside it).  Returns the Axes."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(5.5, 5.5))
    omega = np.asarray(omega, float)
    L = track_loci(np.asarray(loop, complex).reshape(omega.size, -1))
    for c in range(L.shape[1]):
        lab = "ω > 0" + (f" (locus {c + 1})" if L.shape[1] > 1 else "")
        ax.plot(L[:, c].real, L[:, c].imag, lw=1, label=lab, gid="locus")
        ax.plot(L[:, c].real, -L[:, c].imag, lw=0.6, ls="--", color="0.6")
    crit = -1.0 / width
    ax.plot(
        [crit],
        [0],
        "r+",
        ms=12,
        mew=2,
        label=f"critical point -1/b, b = {width * 1e3:.4g} mm",
        gid="critical",
    )
    bstar, fstar = touching_width(omega, L)
    f0, f1 = omega[0] / (2 * np.pi), omega[-1] / (2 * np.pi)
    if np.isfinite(bstar):
        ax.plot(
            [-1.0 / bstar],
            [0],
            "ko",
            ms=5,
            label=f"touches at b* = {bstar * 1e3:.4g} mm ({fstar:.2f} Hz)",
            gid="touching",
        )
        ok = width < bstar
        note = (
            f"b {'<' if ok else '>='} b*: "
            + ("no locus reaches -1/b" if ok else "a locus has passed -1/b")
            + f"\nin {f0:.4g}-{f1:.4g} Hz"
        )
    else:
        note = f"no locus crosses the negative real axis\nin {f0:.4g}-{f1:.4g} Hz"
    ax.text(0.02, 0.98, note, transform=ax.transAxes, va="top", fontsize=8, gid="verdict",
            bbox={"fc": "white", "ec": "0.6", "alpha": 0.9})  # fmt: skip
    ax.axhline(0, color="0.3", lw=0.5)
    ax.set_xlabel("Re λ [1/m]")
    ax.set_ylabel("Im λ [1/m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left", fontsize=7)
    ax.set_title(title or "loop per unit width: det(I - G D) = ∏(1 + b λ)", fontsize=9)
    return ax
