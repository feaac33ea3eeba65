"""Design plots: the ranked sensitivity bar chart, the lobes of two
designs (before and after a change) on one axis, and an active damper's
trade-off of limit against actuator force."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np


def plot_sensitivity(
    labels: Sequence[str],
    values: Any,
    *,
    ax: Any = None,
    xlabel: str = "sensitivity",
    units: Sequence[str] | None = None,
    title: str | None = None,
) -> Any:
    """Horizontal bars, one per field, the first label at the top: green
    where the change raises the limit, red where it lowers it, the value
    written at the end of each bar.  ``units`` (optional) are appended to
    the labels.  Returns the Axes."""
    import matplotlib.pyplot as plt

    vals = np.asarray(values, dtype=float)
    n = len(labels)
    if ax is None:
        _, ax = plt.subplots(figsize=(8.0, 1.2 + 0.32 * max(n, 1)))
    y = np.arange(n)[::-1]
    colours = np.where(np.nan_to_num(vals) >= 0, "tab:green", "tab:red")
    ax.barh(y, np.nan_to_num(vals), color=colours, height=0.7)
    names = [f"{lb} [{u}]" if units and u else lb for lb, u in zip(labels, units or [""] * n, strict=True)]
    ax.set_yticks(y, names, fontsize=8)
    span = float(np.nanmax(np.abs(vals))) if n and np.any(np.isfinite(vals)) else 1.0
    for yi, v in zip(y, vals, strict=True):
        if np.isfinite(v):
            ax.text(v + (0.01 * span if v >= 0 else -0.01 * span), yi, f"{v:.3g}", va="center",
                    ha="left" if v >= 0 else "right", fontsize=7)  # fmt: skip
    ax.axvline(0.0, color="k", lw=0.8)
    ax.set_xlim(
        -1.25 * span if np.any(vals < 0) else -0.05 * span, 1.25 * span if np.any(vals > 0) else 0.05 * span
    )
    ax.set_xlabel(xlabel)
    ax.set_title(title or "sensitivity of the stability limit", fontsize=10)
    ax.grid(axis="x", alpha=0.3)
    return ax


def plot_lobes_compare(
    diagrams: Sequence[Any],
    labels: Sequence[str],
    *,
    ax: Any = None,
    title: str | None = None,
    minima: bool = True,
) -> Any:
    """The lower envelopes (limit in mm against speed) of several lobe
    diagrams on one axis, each with its absolute minimum as a dashed line
    of the same colour, labelled with its value (``minima``).  Diagrams
    from :func:`chatterlab.lobes.lobes` on the same speeds and process; each
    envelope is the diagram's exact one (``LobeDiagram.geometry()``).
    Returns the Axes."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(8.0, 4.5))
    colours = ["tab:red", "tab:blue", "tab:green", "tab:purple", "tab:orange"]
    lo = min(float(np.min(d.speed)) for d in diagrams)
    hi = max(float(np.max(d.speed)) for d in diagrams)
    v = np.linspace(lo, hi, 4000)
    top = 0.0
    for k, (d, lb) in enumerate(zip(diagrams, labels, strict=True)):
        c = colours[k % len(colours)]
        geo = d.geometry()
        vv, env, _ = geo.envelope_line(v) if geo.curves else (d.speed, d.b_lim, d.chatter_hz)
        env = np.asarray(env, dtype=float)
        ax.plot(vv, env * 1e3, color=c, lw=1.2, label=lb)
        fin = env[np.isfinite(env)]
        top = max(top, float(fin.max()) if fin.size else 0.0)
        a = float(d.absolute_minimum["width"])
        if minima and np.isfinite(a):
            ax.axhline(a * 1e3, color=c, lw=0.9, ls="--", label=f"{lb}: absolute minimum {a * 1e3:.4g} mm")
    ax.set_xlim(lo, hi)
    ax.set_ylim(0.0, 1.1 * top * 1e3 if top > 0 else 1.0)
    d0 = diagrams[0]
    ax.set_xlabel(f"{d0.speed_name} [{d0.speed_unit}]")
    ax.set_ylabel(f"{d0.limit_name} [mm]")
    ax.set_title(title or "stability lobes: before and after", fontsize=10)
    ax.legend(fontsize=8, loc="upper right")
    ax.grid(alpha=0.3)
    return ax


def plot_tradeoff(
    force: Any,
    width: Any,
    *,
    ax: Any = None,
    bare: float | None = None,
    design: float | None = None,
    chosen: tuple[float, float] | None = None,
    title: str | None = None,
) -> Any:
    """The trade-off of an active damper: a width to cut at (mm) against the
    least actuator force (N) that cutting there needs, with the bare
    structure's limit and the design width as horizontal lines and the
    chosen design marked (``chosen`` = (its force at the design width N, its
    limit m)).  Points the optimiser did not reach are left out (nan).
    Returns the Axes."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(6.0, 4.5))
    f = np.asarray(force, dtype=float)
    w = np.asarray(width, dtype=float)
    ok = np.isfinite(w) & np.isfinite(f)
    order = np.argsort(f[ok])
    ax.plot(
        f[ok][order],
        w[ok][order] * 1e3,
        "o-",
        color="tab:blue",
        lw=1.2,
        ms=4,
        label="least force to cut at the width",
    )
    if bare is not None and np.isfinite(bare):
        ax.axhline(
            bare * 1e3, color="tab:red", ls="--", lw=0.9, label=f"without actuator: {bare * 1e3:.4g} mm"
        )
    if design is not None and np.isfinite(design):
        ax.axhline(design * 1e3, color="0.4", ls=":", lw=0.9, label=f"design width {design * 1e3:.4g} mm")
    if chosen is not None and np.all(np.isfinite(chosen)):
        ax.plot([chosen[0]], [chosen[1] * 1e3], "*", color="tab:green", ms=11, label="optimised design")
    if np.any(ok):
        from matplotlib.ticker import NullFormatter

        ax.set_xscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())  # decades labelled only: no overprinted minor labels
    ax.set_xlabel("actuator force [N]")
    ax.set_ylabel("width cut [mm]")
    ax.set_title(title or "width against actuator effort", fontsize=10)
    ax.legend(fontsize=8, loc="lower right")
    ax.grid(alpha=0.3, which="both")
    return ax
