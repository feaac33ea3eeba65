"""The fit of the process-damping coefficient: the lobes at the fitted C_pd
with the cutting tests marked (stable, chatter, onset)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ._lobes import plot_lobes
from ._style import savefig


def plot_fit_damping(fit: Any, diagram: Any, path: str | None = None, *, title: str | None = None) -> Any:
    """The lobe diagram at the fitted C_pd (``diagram``, a
    :class:`~chatterlab.lobes.LobeDiagram`) with the tests of ``fit`` (a
    :class:`~chatterlab.lobes._fit_damping.DampingFit`): stable cuts as
    green circles, chattering ones as red crosses, onsets as black diamonds.
    Returns the Axes of :func:`plot_lobes`; with ``path``, saves and closes."""
    head = title or f"lobes at the fitted C_pd = {fit.C_pd:.4g} N/m and the cutting tests"
    axes = plot_lobes(diagram, title=head)
    ax = axes[0] if isinstance(axes, tuple) else axes
    marks = {"stable": ("o", "tab:green", "stable cut"), "chatter": ("x", "tab:red", "chattering cut"),
             "onset": ("D", "black", "measured chatter onset")}  # fmt: skip
    for res, (m, c, label) in marks.items():
        sel = np.asarray(fit.result) == res
        if np.any(sel):
            ax.plot(np.asarray(fit.speed)[sel], np.asarray(fit.width)[sel] * 1e3, m, color=c, ms=6,
                    mfc="none" if m == "o" else c, mew=1.5, ls="none", label=label, zorder=6)  # fmt: skip
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=6.5, framealpha=0.9)
    top = float(np.max(fit.width)) * 1e3 * 1.3
    lo, hi = ax.get_ylim()
    ax.set_ylim(lo, max(hi, top))
    if path is not None:
        savefig(axes, path)
    return axes
