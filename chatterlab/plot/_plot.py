"""Plots (matplotlib is imported inside each function, never at import).

Every function returns the Axes it drew on so that a caller can restyle or
save; none calls ``plt.show()``.
"""

from __future__ import annotations

from collections.abc import Sequence
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
    """Save the figure holding the given Axes and close it."""
    import matplotlib.pyplot as plt

    ax = ax_or_axes[0] if isinstance(ax_or_axes, list | tuple | np.ndarray) else ax_or_axes
    fig = ax.figure
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)


def plot_lobes(diagram: Any, *, axes: Any = None, lobe_numbers: int = 8, title: str | None = None) -> Any:
    """Stability lobe diagram: b_lim (mm) against speed with the unstable
    region shaded and lobe numbers, above the chatter frequency (Hz) along the
    envelope.  Returns (ax_lobes, ax_freq)."""
    import matplotlib.pyplot as plt

    d = diagram
    if axes is None:
        fig, axes = plt.subplots(
            2, 1, sharex=True, figsize=(8.5, 6.5), gridspec_kw={"height_ratios": [3, 1.2]}
        )
    ax, axf = axes
    v = d.speed
    b = d.b_lim * 1e3
    fin = np.isfinite(b)
    top = d.width_max * 1e3
    # lobes are "dense" when several lobes fall between two sampled speeds
    dv = float(np.median(np.abs(np.diff(v)))) if v.size > 1 else 0.0
    kk = d.lobe[d.lobe >= 0]
    dense = v.size > 1 and kk.size > 1 and (kk.max() - kk.min()) > 0.5 * v.size
    bb = np.where(fin, b, top)
    ax.fill_between(v, bb, top, color="tab:red", alpha=0.15, lw=0, label="unstable (chatter)", zorder=0)
    if dense:
        spacing = (v.max() - v.min()) / max(1, kk.max() - kk.min())
        ax.plot(
            v, bb, color="tab:red", lw=0.7, marker=".", ms=3, zorder=3, label="b_lim at the sampled speeds"
        )
        a = d.absolute_minimum["width"] * 1e3
        if np.isfinite(a):
            ax.axhline(
                a,
                color="k",
                ls="--",
                lw=1,
                label=f"b_lim,min over all speeds {a:.3g} mm ({d.absolute_minimum['chatter_hz']:.1f} Hz)",
            )
        ax.text(
            0.01,
            0.97,
            f"lobes denser than the speed grid: one lobe every ~{spacing:.2g} {d.speed_unit}",
            transform=ax.transAxes,
            fontsize=8,
            va="top",
        )
    else:
        for lb in d.lobes:
            order = np.argsort(lb.speed)
            ax.plot(lb.speed[order], lb.width[order] * 1e3, color="0.65", lw=0.6, zorder=1)
        ax.plot(v, bb, color="tab:red", lw=1.8, label="b_lim (stability boundary)", zorder=3)
    if np.isfinite(d.minimum["width"]):
        ax.plot(
            [d.minimum["speed"]],
            [d.minimum["width"] * 1e3],
            "ko",
            ms=5,
            zorder=4,
            label=f"min {d.minimum['width'] * 1e3:.3g} mm @ {d.minimum['speed']:.4g} {d.speed_unit}",
        )
    # lobe numbers at the envelope's local minima, spread over the range
    if lobe_numbers and fin.sum() > 2 and not dense:
        loc = np.nonzero((b[1:-1] <= b[:-2]) & (b[1:-1] <= b[2:]) & fin[1:-1])[0] + 1
        loc = loc[np.argsort(b[loc])]
        picked: list[int] = []
        for j in loc:
            if all(abs(v[j] - v[p]) > 0.06 * (v.max() - v.min()) for p in picked):
                picked.append(int(j))
            if len(picked) >= lobe_numbers:
                break
        for i in picked:
            ax.annotate(
                f"k={d.lobe[i]}",
                (v[i], b[i]),
                textcoords="offset points",
                xytext=(0, -12),
                ha="center",
                fontsize=7,
            )
    del dv
    ax.set_ylim(0, top)
    ax.set_xlim(v.min(), v.max())
    ax.set_ylabel("width of cut b [mm]")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(alpha=0.3)
    axf.plot(v[fin], d.chatter_hz[fin], ".", ms=2.5, color="tab:blue")
    axf.set_ylabel("chatter [Hz]")
    axf.set_xlabel(f"{d.speed_name} [{d.speed_unit}]")
    axf.grid(alpha=0.3)
    ttl = title
    if ttl is None:
        ttl = f"{d.model}: stability lobes ({d.terms})"
        if d.position is not None:
            ttl += f", s = {d.position:g} m"
    ax.set_title(ttl, fontsize=10)
    return axes


def plot_atlas(result: Any, process: Any = None, *, axes: Any = None, title: str | None = None) -> Any:
    """Stability atlas: b_lim (mm) over speed x slide position as a map,
    above the worst case along the stroke (the minimum over positions).
    ``result`` is the :class:`~chatterlab.sweep._engine.SweepResult` of an atlas
    sweep (axes ``position``, ``speed``).  Returns (ax_map, ax_worst)."""
    import matplotlib.pyplot as plt

    pos = np.asarray(result.grid.axes[0].values)
    v = np.asarray(result.grid.axes[1].values)
    unit = result.grid.axes[1].unit
    bl = np.asarray(result.data["b_lim"]) * 1e3
    if axes is None:
        fig, axes = plt.subplots(
            2, 1, sharex=True, figsize=(8.5, 6.5), gridspec_kw={"height_ratios": [2, 1.3]}
        )
    ax, axw = axes
    finite = np.where(np.isfinite(bl), bl, np.nan)
    vmax = float(np.nanpercentile(finite, 95)) if np.any(np.isfinite(finite)) else 1.0
    if pos.size > 1:
        mesh = ax.pcolormesh(
            v, pos, finite, shading="nearest", cmap="viridis", vmin=np.nanmin(finite), vmax=vmax
        )
        ax.figure.colorbar(mesh, ax=ax, label="b_lim [mm]")
        ax.set_ylabel("slide position s [m]")
    else:
        ax.plot(v, finite[0])
        ax.set_ylabel("b_lim [mm]")
    worst = np.nanmin(finite, axis=0)
    axw.fill_between(
        v,
        worst,
        np.nanmax(worst) * 1.1,
        color="tab:red",
        alpha=0.15,
        lw=0,
        label="unstable somewhere on the stroke",
    )
    axw.plot(v, worst, color="tab:red", lw=1, label="worst case over positions")
    axw.set_ylim(0, np.nanmax(worst) * 1.1 if np.any(np.isfinite(worst)) else 1)
    axw.set_ylabel("b_lim [mm]")
    axw.set_xlabel(f"{getattr(process, 'speed_name', 'speed')} [{unit}]")
    axw.legend(fontsize=8, loc="upper right")
    axw.grid(alpha=0.3)
    ax.set_title(title or "stability atlas along the stroke", fontsize=10)
    return axes


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
