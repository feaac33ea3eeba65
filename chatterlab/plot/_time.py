"""Time histories and their spectra."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ._style import axes_arg


def plot_histories(
    sims: Sequence[Any],
    names: Sequence[str],
    *,
    against: str = "time",
    labels: Sequence[str] | None = None,
    ax: Any = None,
    scale: float = 1e6,
    unit: str = "um",
    axes: Any = None,
) -> Any:
    """Time histories of outputs (one panel per output, the runs overlaid),
    against time (s) or against the distance travelled in the cut (mm), as
    in the paper's Figs. 4-9.  Displacements shown in micrometres by default.
    ``ax`` is one Axes per output (``axes=`` a deprecated alias).  Returns
    the Axes (one per output)."""
    import matplotlib.pyplot as plt

    axes = axes_arg(ax, axes, "plot_histories")
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
