"""Plots (matplotlib is imported inside each function, never at import).

Every function returns the Axes it drew on so that a caller can restyle or
save; none calls ``plt.show()``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["plot_frf", "plot_nyquist", "savefig"]


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
        ax.set_title(title)
    return ax


def savefig(ax_or_axes: Any, path: str, dpi: int = 130) -> None:
    """Save the figure holding the given Axes and close it."""
    import matplotlib.pyplot as plt

    ax = ax_or_axes[0] if isinstance(ax_or_axes, list | tuple | np.ndarray) else ax_or_axes
    fig = ax.figure
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
