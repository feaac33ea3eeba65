"""Frequency response functions and the Nyquist plot of the loop."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ._style import axes_arg, index_of


def plot_frf(
    frfs: Sequence[Any],
    *,
    output: int | str = 0,
    input: int | str = 0,
    labels: Sequence[str] | None = None,
    ax: Any = None,
    title: str | None = None,
    peaks: int = 0,
    axes: Any = None,
) -> Any:
    """Magnitude (log scale) and phase (deg) of one or more FRFs against
    frequency in Hz, overlaid: the open- vs closed-loop comparison of the
    paper's Figs. 10-11.  ``ax`` is a pair of Axes (``axes=`` a deprecated
    alias).  Returns the Axes (ax_mag, ax_phase)."""
    import matplotlib.pyplot as plt

    axes = axes_arg(ax, axes, "plot_frf")
    if axes is None:
        fig, axes = plt.subplots(2, 1, sharex=True, figsize=(8, 6), gridspec_kw={"height_ratios": [2, 1]})
    ax_m, ax_p = axes
    for k, f in enumerate(frfs):
        o, i = index_of(f.outputs, output), index_of(f.inputs, input)
        z = f.data[o, i]
        lab = labels[k] if labels is not None else f.label
        (line,) = ax_m.semilogy(f.frequency_hz, np.abs(z), label=lab)
        ax_p.plot(f.frequency_hz, np.degrees(np.angle(z)), color=line.get_color())
        if peaks:
            for fp, mp in f.peaks(o, i, peaks):
                ax_m.annotate(f"{fp:.1f} Hz", (fp, mp), textcoords="offset points", xytext=(4, 4), fontsize=8)
    f0 = frfs[0]
    o, i = index_of(f0.outputs, output), index_of(f0.inputs, input)
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

