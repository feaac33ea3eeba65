"""Stability limits under spindle-speed variation: the limit against the mean
speed, one curve per (RVA, RVF), the constant speed (RVA = 0) drawn black."""

from __future__ import annotations

from typing import Any

import numpy as np

from ._lobe_panel import mesh_note


def plot_ssv(result: Any, ax: Any = None, *, title: str | None = None, **style: Any) -> Any:
    """The limits of an :class:`~chatterlab.frequency.SsvLimits` against the mean
    speed (mm), one line per (RVA, RVF); returns the Axes."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(8.0, 4.5))
    speeds = np.asarray(result.speeds, dtype=float)
    b = np.asarray(result.b_lim, dtype=float)
    cmap = plt.get_cmap("viridis")
    pairs = [(j, k) for j in range(len(result.rva)) for k in range(len(result.rvf))]
    varied = [p for p in pairs if result.rva[p[0]] != 0.0]
    top = ax.get_xaxis_transform()  # x in data, y in axes: the marks of no limit sit on the top edge
    marked = {"inf": False, "nan": False}
    for j, k in pairs:
        a, f = float(result.rva[j]), float(result.rvf[k])
        y = np.where(np.isfinite(b[:, j, k]), b[:, j, k], np.nan) * 1e3
        if a == 0.0:
            if k > 0:
                continue  # the constant speed does not depend on RVF: drawn once
            c: Any = "k"
            ax.plot(speeds, y, color=c, lw=1.6, marker=".", ms=5, label="constant speed", **style)
        else:
            c = cmap(varied.index((j, k)) / max(len(varied) - 1, 1) * 0.85)
            ax.plot(speeds, y, color=c, lw=1.2, marker=".", ms=4, label=f"RVA {a:g}, RVF {f:g}", **style)
        # no limit below the ceiling (a claim of no chatter), and undetermined (NaN: e.g. a claim
        # the mesh twice as fine contradicts): marked, not dropped
        for kind, sel, mk, lab in (("inf", np.isposinf(b[:, j, k]), "^", "no limit below the ceiling"),
                                   ("nan", np.isnan(b[:, j, k]), "x", "undetermined")):  # fmt: skip
            if np.any(sel):
                ax.plot(speeds[sel], np.full(int(sel.sum()), 0.97), ls="none", marker=mk, ms=7,
                        color=c if kind == "inf" else "tab:red", transform=top, clip_on=False,
                        label=None if marked[kind] else lab)  # fmt: skip
                marked[kind] = True
    ax.set_xlabel(f"mean speed [{result.speed_unit}]")
    ax.set_ylabel(f"{result.limit_name} [mm]")
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    mesh = getattr(result, "mesh", None)
    ax.set_title(  # a line above the mesh note (a model with beams) when there is one
        (title or f"stability limit under {result.shape} spindle-speed variation") + ("\n" if mesh else ""),
        fontsize=10,
        loc="left" if mesh else "center",
    )  # fmt: skip
    if speeds.size == 1:  # one mean speed: a visible span around it
        ax.set_xlim(speeds[0] * 0.95, speeds[0] * 1.05)
    mesh_note(ax, mesh)
    return ax
