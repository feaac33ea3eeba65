"""The lobe diagram of a Floquet method (milling): a_lim against spindle
speed, Hopf and flip lobes told apart, the unstable side shaded, what was
searched stated.  Drawn by :func:`chatterlab.plot.plot_lobes` for a diagram
without lobe curves."""

from __future__ import annotations

from typing import Any

import numpy as np

from ._lobe_panel import mesh_note

__all__: list[str] = []

#: colours of the lobe types (secondary Hopf, flip = period doubling, fold)
KIND_COLOURS = {"hopf": "tab:blue", "flip": "tab:red", "fold": "tab:purple"}


def plot_milling_lobes(
    ml: Any, *, ax: Any = None, label: str | None = None, title: str | None = None, **kw: Any
) -> Any:
    """Draw a Floquet :class:`~chatterlab.lobes.LobeDiagram`: the limit depth a_lim
    (mm) against rpm as one line, its points coloured by the type of the
    critical multiplier (Hopf: quasi-periodic chatter; flip: period
    doubling), the region above shaded as unstable, and speeds where no
    instability was found up to ``depth_max`` marked at the top.  With
    ``ax`` given, only the line and its markers are added (for overlays of
    several methods).  Returns the Axes."""
    overlay = ax is not None
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(9.0, 5.0))
    rpm = np.asarray(ml.speed, dtype=float)
    a = np.where(np.isfinite(ml.b_lim), ml.b_lim * 1e3, np.nan)
    (line,) = ax.plot(rpm, a, lw=1.2, label=label or f"{ml.method} ({ml.resolution})", **kw)
    kinds = np.asarray(ml.kind).astype(str)
    for kind, colour in KIND_COLOURS.items():
        sel = kinds == kind
        if np.any(sel):
            ax.plot(rpm[sel], a[sel], ls="none", marker="o", ms=3, color=colour,
                    label=None if overlay else f"{kind} lobe ({'period doubling' if kind == 'flip' else 'quasi-periodic' if kind == 'hopf' else 'mu = +1'})")  # fmt: skip
    top = ml.width_max * 1e3
    inf = ~np.isfinite(ml.b_lim) & (np.asarray(ml.kind).astype(str) != "undetermined")
    if np.any(inf):
        ax.plot(rpm[inf], np.full(inf.sum(), top), ls="none", marker="^", ms=4, color=line.get_color(),
                label=None if overlay else f"no instability found up to {top:g} mm")  # fmt: skip
    if not overlay:
        ax.fill_between(rpm, np.where(np.isfinite(a), a, top), top, color="0.85", step=None, label="unstable")
        ax.set_ylim(0, top * 1.05)
        ax.set_xlim(rpm.min(), rpm.max())
        ax.set_xlabel(f"{ml.speed_name} [{ml.speed_unit}]")
        ax.set_ylabel(f"limit axial depth {ml.limit_name} [mm]")
        ax.set_title(
            title
            or f"{_short(ml.model)}\n{ml.method}, {ml.resolution}; depths scanned every {ml.scan_step * 1e3:.3g} mm",
            fontsize=10,
        )
        ax.grid(alpha=0.3)
        mesh_note(ax, getattr(ml, "meta", None))
    ax.legend(fontsize=8, loc="upper right")
    return ax


def _short(name: str) -> str:
    """A model file named by its folder and name (not the full path)."""
    from pathlib import Path

    p = Path(str(name))
    return f"{p.parent.name}/{p.name}" if p.suffix == ".toml" and p.parent.name else str(name)
