"""Shared by every plot: the axes keyword, saving a figure, cell edges.

Every plot function of chatterlab takes ``ax=`` (one Axes, or a sequence of
Axes for a multi-panel plot, in the order its docstring gives) and returns
what it drew on; none calls ``plt.show()``.  matplotlib is imported inside
the functions, never at import.
"""

from __future__ import annotations

import sys
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import Any

import numpy as np

#: gid of a figure whose plot function already tightened its layout (savefig skips it)
LAID_OUT = "chatterlab:laid-out"


def axes_arg(ax: Any, axes: Any, func: str) -> Any:
    """The Axes a plot draws on: ``ax``, or the deprecated ``axes=`` alias
    (with a DeprecationWarning); both given is an error."""
    if axes is None:
        return ax
    if ax is not None:
        raise TypeError(f"{func}: pass the Axes once, as ax= (axes= is its deprecated alias)")
    warnings.warn(f"{func}(axes=...) is deprecated; pass ax=", DeprecationWarning, stacklevel=3)
    return axes


def index_of(names: Sequence[str], key: int | str) -> int:
    """Position of ``key`` (a name or an index) in ``names``."""
    return names.index(key) if isinstance(key, str) else int(key)


def cell_edges(x: np.ndarray) -> np.ndarray:
    """Edges of cells centred on the sorted values x."""
    if x.size == 1:
        return np.array([x[0] - 0.5, x[0] + 0.5])
    mid = 0.5 * (x[1:] + x[:-1])
    return np.r_[x[0] - (mid[0] - x[0]), mid, x[-1] + (x[-1] - mid[-1])]


#: [True] while figures are made only to be saved (:func:`headless`)
_HEADLESS = [False]


@contextmanager
def headless() -> Iterator[None]:
    """Figures made inside (by :func:`new_figure`) are only saved, never
    shown: the command line's ``--plot``.  They are matplotlib Figures on the
    Agg canvas, the canvas pyplot gives them under the Agg backend and the one
    every PNG is printed with, so the file is the same; pyplot, its backend
    resolution and its figure manager are not loaded (0.02 s of the README
    main job).  A program that imported pyplot keeps pyplot's figures."""
    before = _HEADLESS[0]
    _HEADLESS[0] = True
    try:
        yield
    finally:
        _HEADLESS[0] = before


def new_figure(**kwargs: Any) -> Any:
    """A new figure (``matplotlib.figure.Figure`` keywords): pyplot's, so that
    ``plt.show()`` shows it, except inside :func:`headless` when pyplot is
    not loaded."""
    if _HEADLESS[0] and "matplotlib.pyplot" not in sys.modules:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        fig = Figure(**kwargs)
        FigureCanvasAgg(fig)
        return fig
    import matplotlib.pyplot as plt

    return plt.figure(**kwargs)


def savefig(ax_or_axes: Any, path: str, dpi: int = 130) -> None:
    """Save the figure holding the given Axes and close it (pyplot's, if
    pyplot made it).  The layout is tightened first unless the plot laid the
    figure out itself (figure gid ``LAID_OUT``)."""
    ax = np.ravel(ax_or_axes)[0] if isinstance(ax_or_axes, list | tuple | np.ndarray) else ax_or_axes
    fig = ax.figure
    while getattr(fig, "figure", fig) is not fig:  # a subfigure: the figure holding it
        fig = fig.figure
    if fig.get_gid() != LAID_OUT:
        fig.tight_layout()
    # zlib level 1: several times faster than the default 6 on a dense figure, a little larger file
    extra = {"pil_kwargs": {"compress_level": 1}} if str(path).lower().endswith(".png") else {}
    fig.savefig(path, dpi=dpi, **extra)
    plt = sys.modules.get("matplotlib.pyplot")
    if plt is not None:  # a figure made without pyplot is not in its list: nothing to close
        plt.close(fig)


def model_of(result: Any) -> str:
    """The name of the model a result was computed on, from its attributes
    (``model``, or the ``[model] name`` of the ``model_text`` it carries)."""
    attrs = getattr(result, "attrs", {}) or {}
    if attrs.get("model"):
        return str(attrs["model"])
    text = attrs.get("model_text")
    if text:
        import tomllib

        try:
            name = tomllib.loads(str(text)).get("model", {}).get("name")
        except tomllib.TOMLDecodeError:
            name = None
        if name:
            return str(name)
    return "model not named"
