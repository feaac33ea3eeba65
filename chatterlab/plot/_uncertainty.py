"""Plots of a probabilistic lobe diagram (:mod:`chatterlab.uncertainty`):
the probability of chatter over (speed, width) with the quantile lobes and
a risk contour, and the Sobol' indices as bars."""

from __future__ import annotations

from typing import Any

import numpy as np

from ._style import cell_edges


def plot_risk(result: Any, *, ax: Any = None, risk: float | None = None, title: str | None = None,
              cmap: str = "RdYlGn_r", nominal: bool = True) -> Any:  # fmt: skip
    """The probability of chatter P(b_lim(v) <= b) as a map over speed and
    width (mm), the quantile lobes (the 5 % lobe, dashed, is where 95 % of
    the machines are still stable), the nominal lobe (thin black), the
    operating points with their probability, and with ``risk`` the risk
    contour: the largest width at each speed whose probability of chatter
    is at most ``risk``, on the safe side of its sampling error
    (:meth:`~chatterlab.uncertainty.ProbabilisticLobes.safe_width`).
    Returns the Axes."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(8.0, 4.8))
    v = np.asarray(result.speed, float)
    b_mm = 1e3 * np.asarray(result.width, float)
    P = result.p_chatter_map.T  # (widths, speeds)
    mesh = ax.pcolormesh(cell_edges(v), cell_edges(b_mm), P, cmap=cmap, vmin=0.0, vmax=1.0, shading="flat",
                         rasterized=True)  # fmt: skip
    ax.figure.colorbar(mesh, ax=ax, label="P(chatter)", pad=0.02)
    top = float(b_mm[-1])
    styles = {0: ("--", 1.4), 1: ("-", 1.8)}
    qv = np.asarray(result.quantiles.value)
    order = np.argsort(result.quantile_levels)
    for i in order:
        q = float(result.quantile_levels[i])
        ls, lw = styles.get(0 if q < 0.5 else 1 if q == 0.5 else 2, (":", 1.4))
        y = np.minimum(1e3 * qv[i], top)
        ax.plot(v, y, color="k", ls=ls, lw=lw, label=f"{100 * q:g} % lobe")
    if nominal:
        nom = result.nominal
        grid = np.searchsorted(result.all_speeds, v)
        ax.plot(v, np.minimum(1e3 * np.asarray(nom.b_lim, float)[grid], top), color="tab:blue", lw=0.8,
                label="nominal model")  # fmt: skip
    if risk is not None:
        w = 1e3 * result.safe_width(risk)
        ax.plot(
            v,
            np.minimum(w, top),
            color="tab:purple",
            lw=2.4,
            label=f"P(chatter) = {100 * risk:g} % (safe side)",
        )
    right = v.min() + 0.75 * (v.max() - v.min())
    for k, (pv, pb) in enumerate(result.points):
        e = result.p_chatter
        ax.plot(pv, 1e3 * pb, marker="o", ms=7, mfc="white", mec="k", ls="none")
        left = pv > right  # the label on the side with room
        ax.annotate(
            f"P(chatter) = {float(e.value[k]):.3f}\n[{max(float(e.low[k]), 0):.3f}, {min(float(e.high[k]), 1):.3f}]",
            (pv, 1e3 * pb), textcoords="offset points", xytext=(-8 if left else 8, 6), fontsize=7,
            ha="right" if left else "left", bbox={"boxstyle": "round", "fc": "white", "alpha": 0.8, "lw": 0.3},
        )  # fmt: skip
    ax.set_xlim(v.min(), v.max())
    ax.set_ylim(0.0, top)
    ax.set_xlabel(f"{result.process.speed_name} [{result.speed_unit}]")
    ax.set_ylabel(f"{result.limit_name.replace('_lim', '')} [mm]")
    ax.set_title(
        title
        or f"probabilistic lobes: {result.n_samples} samples, {100 * result.level:g} % intervals"
        f" (map error <= {float(np.nanmax(result.p_stable.half_width)):.2g})",
        fontsize=10,
    )
    ax.legend(fontsize=7, loc="upper left", framealpha=0.85)
    return ax


def plot_sobol(result: Any, *, ax: Any = None, output: str = "b_min", title: str | None = None) -> Any:
    """First-order (dark) and total (light) Sobol' indices of ``output``
    (``"b_min"``: the smallest limit; ``"chatter@k"``: chatter at operating
    point k) per factor, largest total first, with their confidence
    intervals as error bars: the factor to measure again is the top one.
    Returns the Axes."""
    import matplotlib.pyplot as plt

    from ..errors import InputError

    if output not in result.sobol:
        known = ", ".join(result.sobol) or "none: run risk(..., sensitivity=True)"
        raise InputError(f"no Sobol' indices of {output!r} (known: {known})")
    s1, st = result.sobol[output]
    names = list(result.factor_names)
    order = np.argsort(-np.nan_to_num(np.asarray(st.value), nan=-1.0))
    n = len(names)
    if ax is None:
        _, ax = plt.subplots(figsize=(7.5, 1.3 + 0.45 * max(n, 1)))
    y = np.arange(n)[::-1]
    h = 0.38
    for vals, e, off, colour, label in (
        (st.value, st.half_width, h / 2, "tab:orange", "total $S_{T,i}$"),
        (s1.value, s1.half_width, -h / 2, "tab:blue", "first order $S_i$"),
    ):
        vv = np.nan_to_num(np.asarray(vals, float)[order])
        ee = np.nan_to_num(np.asarray(e, float)[order])
        ax.barh(y + off, vv, height=h, color=colour, xerr=ee, capsize=2, label=label, error_kw={"lw": 0.8})
        for yi, val, err in zip(y + off, vv, ee, strict=True):
            ax.text(max(val + err, 0.0) + 0.01, yi, f"{val:.3f} \u00b1 {err:.3f}", va="center", fontsize=7)
    ax.set_yticks(y, [names[i] for i in order], fontsize=8)
    ax.axvline(0.0, color="k", lw=0.8)
    top = max([1.0] + [float(np.nanmax(np.asarray(e.value) + np.asarray(e.half_width))) for e in (s1, st)
                       if np.any(np.isfinite(e.value))])  # fmt: skip
    ax.set_xlim(-0.05, top + 0.25)
    ax.set_xlabel("share of the output's variance")
    what = (
        f"smallest {result.limit_name}"
        if output == "b_min"
        else f"chatter at point {int(output.split('@')[1]) + 1}"
    )
    ax.set_title(title or f"Sobol' indices of the {what} ({100 * result.level:g} % intervals)", fontsize=10)
    ax.legend(fontsize=8, loc="lower right")
    ax.grid(axis="x", alpha=0.3)
    return ax
