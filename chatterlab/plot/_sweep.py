"""Sweep results: one output over a 1-D or 2-D grid, and the stability map.

* :func:`plot_sweep` -- a line over one free axis or a colour map over two,
  widths and lengths in mm, every axis with its unit, a title naming the
  model and the point held fixed; the ``stable`` output goes to
  :func:`plot_stability_map`;
* :func:`plot_stability_map` -- a 2-D stability chart whose cells are
  categories, each a colour *and* a hatching with a legend entry and count:
  stable (proven), chatter, undetermined, not computed.  Never a continuous
  colour bar for a yes/no answer.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..errors import InputError
from ._style import cell_edges, model_of

#: the categories of a stability map: code -> (name, colour, hatch)
STATUS = {
    0: ("stable (proven)", "#4daf4a", None),
    1: ("chatter", "#e41a1c", "xx"),
    2: ("undetermined", "#ff9f1c", ".."),
    3: ("not computed", "white", "//"),
}
_WORDS = {"stable": 0, "unstable": 1, "chatter": 1, "marginal": 2, "undetermined": 2, "": 3, "failed": 3}


def status_codes(status: Any) -> np.ndarray:
    """Codes of :data:`STATUS` from verdict words ("stable", "unstable" /
    "chatter", "undetermined" / "marginal", "" / "failed") or numbers (1.0:
    stable, 0.0: chatter, NaN: not computed, or the codes themselves given as
    integers)."""
    a = np.asarray(status)
    if a.dtype.kind in "USO":
        bad = sorted({str(w) for w in a.ravel()} - set(_WORDS))
        if bad:
            raise InputError(
                f"stability map: unknown status {bad[0]!r}; use one of {', '.join(map(repr, _WORDS))}"
            )
        return np.vectorize(lambda w: _WORDS[str(w)], otypes=[int])(a)
    if a.dtype.kind in "iu":
        return a.astype(int)
    f = a.astype(float)
    return np.where(np.isnan(f), 3, np.where(f > 0.5, 0, 1)).astype(int)


def plot_stability_map(
    x: np.ndarray,
    y: np.ndarray,
    status: Any,
    *,
    xlabel: str = "",
    ylabel: str = "",
    ax: Any = None,
    title: str | None = None,
    names: Mapping[int, str] | None = None,
) -> Any:
    """A stability chart over the cells centred on ``x`` (columns) and ``y``
    (rows): ``status`` (len(y), len(x)) as :func:`status_codes` reads it.
    Each category is one collection (gid ``status-<code>``) with its own
    colour and hatching and a legend entry with its cell count; ``names``
    renames categories (e.g. ``{1: "not stable (chatter or undetermined)"}``
    when the data cannot tell chatter from undetermined).  Returns the Axes."""
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    if ax is None:
        _, ax = plt.subplots(figsize=(9.5, 5))
    x, y = np.asarray(x, float), np.asarray(y, float)
    code = status_codes(status)
    if code.shape != (y.size, x.size):
        raise InputError(f"stability map: status has shape {code.shape}, the grid ({y.size}, {x.size})")
    X, Y = np.meshgrid(cell_edges(x), cell_edges(y))
    handles = []
    for c, (name, color, hatch) in STATUS.items():
        n = int(np.sum(code == c))
        if not n:
            continue
        pc = ax.pcolor(
            X,
            Y,
            np.ma.masked_where(code != c, np.ones(code.shape)),
            cmap=ListedColormap([color]),
            hatch=hatch,
            edgecolor="0.25",
            lw=0,
        )
        pc.set_gid(f"status-{c}")
        label = (names or {}).get(c, name)
        handles.append(Patch(facecolor=color, edgecolor="0.25", hatch=hatch, label=f"{label} ({n} cells)"))
    ax.set_xlim(X[0, 0], X[0, -1])
    ax.set_ylim(Y[0, 0], Y[-1, 0])
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    if title:
        ax.set_title(title, fontsize=9)
    return ax


def _display(name: str, unit: str) -> tuple[float, str]:
    """Scale and unit shown for a quantity: lengths in mm, else as given."""
    return (1e3, "mm") if unit == "m" and name not in ("position",) else (1.0, unit)


def plot_sweep(
    result: Any,
    output: str,
    *,
    ax: Any = None,
    x: str | None = None,
    at: Mapping[str, float] | None = None,
    title: str | None = None,
) -> Any:
    """One output of a :class:`~chatterlab.sweep.SweepResult`: a line over a
    1-D grid (or with all axes but one held ``at`` values), a colour map over
    two free axes (abscissa ``x``, default the last free axis).  Widths and
    other lengths (unit m) are shown in mm (the slide position stays in m);
    every axis label carries its unit; ``inf`` values are drawn at the top of
    a line plot and hatched on a map, each with a legend entry.  The
    ``stable`` output is drawn as a :func:`plot_stability_map`.  The title
    names the model and the values held fixed.  Returns the Axes."""
    import matplotlib.pyplot as plt

    arr = np.asarray(result[output], dtype=float)
    at = dict(at or {})
    names = [a.name for a in result.grid.axes]
    for name in at:
        if name not in names:
            raise InputError(
                f"plot_sweep: at={{{name!r}: ...}} names no grid axis (axes: {', '.join(names)})"
            )
    sel: list[Any] = []
    free: list[Any] = []
    for a in result.grid.axes:
        if a.name in at:
            sel.append(int(np.argmin(np.abs(np.asarray(a.values, float) - float(at[a.name])))))
        else:
            sel.append(slice(None))
            free.append(a)
    sub = arr[tuple(sel)]
    if not 1 <= len(free) <= 2:
        raise InputError(
            f"plot_sweep({output!r}): {len(free)} free axes {[a.name for a in free]}; hold all "
            "but one or two fixed with at={name: value}"
        )
    if ax is None:
        _, ax = plt.subplots(figsize=(9.5, 5) if len(free) == 2 else (7, 4))
    unit = (getattr(result, "units", {}) or {}).get(output, "")
    long = (getattr(result, "long_names", {}) or {}).get(output, output)
    ys, yu = _display(output, unit)

    def axis(a: Any) -> tuple[np.ndarray, str]:
        s, u = _display(a.name, a.unit)
        return np.asarray(a.values, float) * s, a.name + (f" [{u}]" if u else "")

    if len(free) == 2:
        xa = free[1] if x is None else next((a for a in free if a.name == x), None)
        if xa is None:
            raise InputError(f"plot_sweep: x={x!r} is not a free axis ({', '.join(a.name for a in free)})")
        ya = free[0] if xa is free[1] else free[1]
        c = sub if xa is free[1] else sub.T
        (xv, xl), (yv, yl) = axis(xa), axis(ya)
        if output == "stable":
            plot_stability_map(xv, yv, c, xlabel=xl, ylabel=yl, ax=ax,
                               names={1: "not stable (chatter or undetermined)"})  # fmt: skip
        else:
            _sweep_map(ax, xv, yv, c * ys, f"{long}" + (f" [{yu}]" if yu else ""))
            ax.set_xlabel(xl)
            ax.set_ylabel(yl)
    elif output == "stable":  # one row of cells: still a verdict per cell, not a 0-1 line
        xv, xl = axis(free[0])
        plot_stability_map(xv, np.zeros(1), sub[None, :], xlabel=xl, ax=ax,
                           names={1: "not stable (chatter or undetermined)"})  # fmt: skip
        ax.set_yticks([])
    else:
        xv, xl = axis(free[0])
        _sweep_line(ax, xv, sub * ys, long + (f" [{yu}]" if yu else ""))
        ax.set_xlabel(xl)
    fixed = ", ".join(f"{k} = {v:g}" for k, v in at.items())
    ax.set_title(title or f"{model_of(result)}: {long}" + (f" at {fixed}" if fixed else ""), fontsize=9)
    return ax


def _sweep_line(ax: Any, xv: np.ndarray, yv: np.ndarray, label: str) -> None:
    fin = np.isfinite(yv)
    ax.plot(xv, np.where(fin, yv, np.nan), marker="." if yv.size < 60 else None, gid="sweep-line")
    if np.any(np.isposinf(yv)):
        ax.plot(xv[np.isposinf(yv)], np.full(int(np.isposinf(yv).sum()), 1.0), "^", color="tab:green",
                transform=ax.get_xaxis_transform(), clip_on=False, label="inf (drawn at the top)")  # fmt: skip
        ax.legend(fontsize=7)
    ax.set_ylabel(label)
    ax.grid(alpha=0.3)


def _sweep_map(ax: Any, xv: np.ndarray, yv: np.ndarray, c: np.ndarray, label: str) -> None:
    from matplotlib.patches import Patch

    mesh = ax.pcolormesh(xv, yv, np.ma.masked_invalid(c), shading="auto")
    mesh.set_gid("sweep-map")
    ax.figure.colorbar(mesh, ax=ax, label=label)
    extra = []
    if np.any(np.isinf(c)):
        X, Y = np.meshgrid(cell_edges(xv), cell_edges(yv))
        ax.pcolor(X, Y, np.ma.masked_where(~np.isinf(c), np.ones(c.shape)), cmap="Greys", vmin=0, vmax=4,
                  hatch="//", lw=0)  # fmt: skip
        extra.append(Patch(facecolor="0.85", hatch="//", label="inf"))
    if np.any(np.isnan(c)):
        extra.append(Patch(facecolor="white", edgecolor="0.4", label="not computed (NaN)"))
    if extra:
        ax.legend(handles=extra, fontsize=7, loc="upper right")
