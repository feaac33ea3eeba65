"""The stability atlas: b_lim over speed x slide position, and the worst
case along the stroke."""

from __future__ import annotations

from typing import Any

import numpy as np

from ._lobe_panel import mesh_claim
from ._style import axes_arg, cell_edges, model_of


def _atlas_model_name(result: Any, model: str | None) -> str:
    """The model's name, or its file's stem (never a path in a title)."""
    from pathlib import PurePath

    name = model or model_of(result)
    return PurePath(name).stem if name.endswith(".toml") else name


def plot_atlas(
    result: Any,
    process: Any = None,
    *,
    ax: Any = None,
    title: str | None = None,
    model: str | None = None,
    width_max: float | None = None,
    terms: str | None = None,
    axes: Any = None,
) -> Any:
    """Stability atlas: b_lim (mm) over speed x slide position as a map,
    above the worst case along the stroke (the minimum over positions).

    ``result`` is the :class:`~chatterlab.sweep.SweepResult` of an atlas
    sweep (axes ``position``, ``speed``); ``model`` names it in the title
    (default: the result's ``model`` attribute or the name in its
    ``model_text``) and ``width_max`` (m) is the width ceiling: cells with
    b_lim = inf (no chatter below it) are grey, cells that failed
    (NaN) white, each with a legend entry; ``terms`` is the feedback (default:
    the result's ``terms`` attribute).  ``ax`` is a pair of Axes (``axes=``
    a deprecated alias).  Returns the Axes (ax_map, ax_worst)."""
    import matplotlib.pyplot as plt

    ax = axes_arg(ax, axes, "plot_atlas")
    pos = np.asarray(result.grid.axes[0].values, float)
    v = np.asarray(result.grid.axes[1].values, float)
    unit = result.grid.axes[1].unit
    attrs = getattr(result, "attrs", {}) or {}
    wmax = width_max if width_max is not None else attrs.get("width_max_m")
    ceiling = f"the {float(wmax) * 1e3:g} mm ceiling" if wmax is not None else "the width ceiling"
    mesh = mesh_claim(attrs)  # a model with beams: the claims of no chatter on the mesh twice as fine
    if mesh:
        ceiling += f" ({mesh} on a mesh twice as fine)"
    bl = np.asarray(result.data["b_lim"], float) * 1e3
    created = ax is None
    if ax is None:
        fig, ax = plt.subplots(2, 1, sharex=True, figsize=(8.5, 7.0), gridspec_kw={"height_ratios": [2, 1.3]})
    axm, axw = ax
    speed_name = getattr(process, "speed_name", "speed")
    _atlas_map(axm, pos, v, bl, ceiling)
    axm.set_xlabel(f"{speed_name} [{unit}]")
    axm.xaxis.set_tick_params(labelbottom=True)
    _atlas_worst(axw, v, bl, ceiling)
    axw.set_xlabel(f"{speed_name} [{unit}]")
    name = _atlas_model_name(result, model)
    terms = terms or attrs.get("terms")
    sub = f"{pos.size} positions {pos.min():g}-{pos.max():g} m x {v.size} speeds"
    if terms:
        sub += f"; feedback {terms}"
    if wmax is not None:
        sub += f"; width ceiling {float(wmax) * 1e3:g} mm"
    head = title or f"{name}: stability atlas along the stroke"
    if title and name not in title:
        head = f"{name}: {title}"
    if created:  # the title above the figure, the map's legend between them: nothing overlaps
        axm.figure.suptitle(f"{head}\n{sub}", fontsize=9)
        axm.figure.subplots_adjust(top=0.87)
    else:
        axm.set_title(f"{head}\n{sub}", fontsize=9)
    return ax


def _atlas_map(ax: Any, pos: np.ndarray, v: np.ndarray, bl: np.ndarray, ceiling: str) -> None:
    """b_lim (mm) over (speed, position) as a colour map; inf cells grey and
    failed (NaN) cells white, each with a legend entry.  One position: a line."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    isinf, isnan = np.isinf(bl), np.isnan(bl)
    finite = np.where(np.isfinite(bl), bl, np.nan)
    if pos.size <= 1:
        ax.plot(v, finite[0])
        ax.set_ylabel("b_lim [mm]")
        return
    anyfin = bool(np.any(np.isfinite(finite)))
    vmax = float(np.nanpercentile(finite, 95)) if anyfin else 1.0
    vmin = float(np.nanmin(finite)) if anyfin else 0.0
    extra: list[Any] = []
    ax.set_facecolor("0.55")  # a failed (NaN) cell shows the background: the grey of its legend entry
    mesh = ax.pcolormesh(v, pos, finite, shading="nearest", cmap="viridis", vmin=vmin, vmax=vmax)
    # the colour bar outside the map's frame keeps both panels' speed axes aligned
    cax = ax.inset_axes((1.015, 0.0, 0.02, 1.0))
    cb = ax.figure.colorbar(mesh, cax=cax, extend="max" if np.nanmax(finite) > vmax else "neither")
    cb.set_label("b_lim [mm] (largest chatter-free width)")
    if np.any(isinf):  # white with black hatching: stands out from every colour of the map
        cells = ax.pcolor(
            *np.meshgrid(cell_edges(v), cell_edges(pos)),
            np.ma.masked_where(~isinf, np.ones_like(bl)),
            cmap=ListedColormap(["white"]),
            edgecolors="none",
            hatch="////",
        )
        cells.set_gid("atlas-inf")
        extra.append(
            Patch(facecolor="white", edgecolor="black", hatch="////", label=f"no chatter below {ceiling}")
        )
    if np.any(isnan):
        extra.append(Patch(facecolor="0.55", label="not computed (task failed)"))
    ax.set_ylabel("slide position s [m]")
    if extra:  # above the map, outside it: no cell is covered
        ax.legend(handles=extra, loc="lower left", bbox_to_anchor=(0.0, 1.0), fontsize=7, framealpha=0.9,
                  ncol=len(extra), borderaxespad=0.2)  # fmt: skip


def _atlas_worst(axw: Any, v: np.ndarray, bl: np.ndarray, ceiling: str) -> None:
    """The worst case over positions (mm) at the sampled speeds, the smallest
    over the atlas, and the speeds where every position is inf (hatched)."""
    worst = np.min(np.where(np.isnan(bl), np.inf, bl), axis=0)
    wfin = np.isfinite(worst)
    ytop = float(np.max(worst[wfin])) * 1.35 if np.any(wfin) else 1.0
    axw.plot(
        v,
        np.where(wfin, worst, np.nan),
        ".",
        ms=2.5,
        color="tab:red",
        label=f"worst case over positions, at the {v.size} sampled speeds (unstable above)",
    )
    if np.any(wfin):
        m = float(np.min(worst[wfin]))
        axw.axhline(m, color="k", ls="--", lw=1, label=f"smallest over the atlas {m:.4g} mm")
    axw.set_title(
        "worst case along the stroke, at the sampled speeds only: between them lobes may dip lower"
        " (see the lobe diagram)",
        fontsize=7.5,
        loc="left",
    )
    if np.any(~wfin):
        axw.fill_between(
            v,
            0.92,
            1.0,
            where=~wfin,
            transform=axw.get_xaxis_transform(),
            facecolor="none",
            edgecolor="tab:green",
            hatch="////",
            lw=0,
            label=f"inf at every position: no chatter below {ceiling}",
        )
    axw.set_ylim(0, ytop)
    axw.set_ylabel("worst b_lim [mm]")
    axw.legend(fontsize=7, loc="upper right")
    axw.grid(alpha=0.3)
