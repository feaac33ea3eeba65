"""Natural frequencies and mode shapes.

* :func:`plot_mode_shapes` -- each mode drawn on the structure in the x-y
  plane: the deformed beams, bodies and springs over the undeformed ones,
  one panel per mode, the frequency in the legend;
* :func:`plot_frequencies` -- the natural frequencies as bars, optionally
  against reference values.

The mode-shape plot works on plain data (``Modes.drawing()`` makes it), so
that this module knows nothing of models.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

#: the largest displacement of a mode is drawn as this fraction of the structure's size
DRAWN_AMPLITUDE = 0.08

_STYLE = {
    "beam": {"lw": 1.8, "ls": "-", "marker": None},
    "spring": {"lw": 0.9, "ls": "--", "marker": "x"},
    "body": {"lw": 0.0, "ls": "none", "marker": "s"},
}


def _get(d: Any, key: str) -> Any:
    return d[key] if isinstance(d, Mapping) else getattr(d, key)


def mode_scale(drawing: Any, k: int) -> float:
    """The factor applied to mode ``k``'s displacements: its largest (u, v)
    over all members is drawn as DRAWN_AMPLITUDE of the structure's size
    (the larger side of the undeformed bounding box)."""
    members = _get(drawing, "members")
    xy = np.concatenate([np.asarray(_get(m, "xy"), float) for m in members])
    size = float(np.max(np.ptp(xy, axis=0))) or 1.0
    peak = max(float(np.max(np.hypot(*np.moveaxis(np.asarray(_get(m, "shape"))[k], -1, 0)))) for m in members)
    return DRAWN_AMPLITUDE * size / peak if peak > 0 else 0.0


def plot_mode_shapes(
    drawing: Any,
    *,
    modes: Sequence[int] | None = None,
    ax: Any = None,
    title: str | None = None,
) -> Any:
    """The mode shapes on the structure: for each mode (0-based indices
    ``modes``, default every mode of the drawing) one panel with the undeformed
    structure in grey and the deformed one in colour (xy + scale * shape,
    the scale of :func:`mode_scale`, said in the legend with the frequency).
    Beams are lines, springs dashed lines with their ends crossed (a spring
    to the ground is drawn at its other end), bodies squares at their centres.

    ``drawing``: ``members`` (each with ``kind``, ``id``, ``xy`` (n, 2) in m
    and ``shape`` (k, n, 2)), ``frequency_hz`` (k,), optionally ``model`` and
    ``position`` -- what ``Modes.drawing()`` returns.  ``ax``: one Axes per
    mode.  Returns the Axes (a tuple, one per mode; the deformed lines of
    mode k carry gid ``mode-k``, the undeformed ones ``undeformed``)."""
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    f = np.asarray(_get(drawing, "frequency_hz"), float)
    idx = list(range(f.size)) if modes is None else [int(k) for k in modes]
    if ax is None:
        nc = min(len(idx), 3 if len(idx) <= 9 else 4)
        nr = int(np.ceil(len(idx) / nc))
        fig, grid = plt.subplots(nr, nc, figsize=(4.2 * nc, 3.6 * nr + 0.5), squeeze=False)
        for a in grid.ravel()[len(idx) :]:
            a.set_visible(False)
        ax = grid.ravel()[: len(idx)]
    ax = tuple(np.ravel(ax))
    members = _get(drawing, "members")
    for a, k in zip(ax, idx, strict=True):
        s = mode_scale(drawing, k)
        for m in members:
            kind = _get(m, "kind")
            st = _STYLE.get(kind, _STYLE["beam"])
            xy = np.asarray(_get(m, "xy"), float)
            d = xy + s * np.asarray(_get(m, "shape"), float)[k]
            a.plot(xy[:, 0], xy[:, 1], color="0.7", lw=st["lw"], ls=st["ls"], marker=st["marker"], ms=5,
                   gid="undeformed", zorder=1)  # fmt: skip
            a.plot(d[:, 0], d[:, 1], color="tab:blue", lw=st["lw"], ls=st["ls"], marker=st["marker"], ms=5,
                   gid=f"mode-{k}", zorder=2)  # fmt: skip
        handles = [
            Line2D([], [], color="tab:blue", lw=1.8, label=f"mode {k + 1}: {f[k]:.2f} Hz (x{s:.3g})"),
            Line2D([], [], color="0.7", lw=1.8, label="undeformed"),
        ]
        a.legend(handles=handles, fontsize=7, loc="best")
        a.set_aspect("equal", adjustable="datalim")
        a.set_xlabel("x [m]")
        a.set_ylabel("y [m]")
        a.grid(alpha=0.3)
    if isinstance(drawing, Mapping):
        name, pos = drawing.get("model"), drawing.get("position")
    else:
        name, pos = getattr(drawing, "model", None), getattr(drawing, "position", None)
    head = title or f"{name or 'model not named'}: mode shapes"
    if pos is not None:
        head += f", slide at s = {pos:g} m"
    ax[0].figure.suptitle(head + " (displacements scaled as in each legend)", fontsize=9)
    return ax


def plot_frequencies(
    frequency_hz: np.ndarray,
    *,
    reference: np.ndarray | None = None,
    ax: Any = None,
    label: str | None = None,
    damping_ratio: np.ndarray | None = None,
    title: str | None = None,
) -> Any:
    """Bar chart of the natural frequencies (Hz), one bar per mode with its
    frequency (and damping ratio ``damping_ratio``, when given) written on
    it; against ``reference`` values a second bar per mode and a legend
    (``label`` names the computed bars, default "computed").  Without a
    reference there is one kind of bar and no legend.  Returns the Axes."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(max(5.0, 1.0 + 0.9 * np.size(frequency_hz)), 3.8))
    fr = np.asarray(frequency_hz, float)
    k = np.arange(1, fr.size + 1)
    w = 0.38 if reference is not None else 0.6
    bars = ax.bar(
        k - (w / 2 if reference is not None else 0), fr, w, label=label or "computed", gid="computed"
    )
    zeta = None if damping_ratio is None else np.asarray(damping_ratio, float)
    for j, b in enumerate(bars):
        txt = f"{fr[j]:.4g} Hz" + ("" if zeta is None else f"\nζ = {zeta[j]:.3g}")
        ax.annotate(txt, (b.get_x() + b.get_width() / 2, b.get_height()), textcoords="offset points",
                    xytext=(0, 3), ha="center", va="bottom", fontsize=8, gid="frequency-label")  # fmt: skip
    if reference is not None:
        ref = np.asarray(reference)[: fr.size]
        ax.bar(np.arange(1, ref.size + 1) + w / 2, ref, w, label="reference", gid="reference")
        ax.legend(fontsize=8, loc="upper left")
    top = max(
        float(np.max(fr)) if fr.size else 1.0, float(np.max(reference)) if reference is not None else 0.0
    )
    ax.set_ylim(0, top * 1.25)  # room for the labels
    ax.set_xlabel("mode")
    ax.set_ylabel("natural frequency [Hz]")
    ax.set_xticks(k)
    ax.grid(axis="y", alpha=0.3)
    if title:
        ax.set_title(title, fontsize=10)
    return ax
