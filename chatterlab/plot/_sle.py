"""The surface location error under the lobes: the SLE (and the wall's
peak-to-valley) of the stable cuts against the spindle speed, the lobe
diagram's limit above it on the same speed axis, the speeds where the cut
chatters (no SLE) or is undetermined marked (:class:`chatterlab.frequency.SurfaceLocation`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ._lobe_panel import mesh_note

__all__ = ["plot_sle"]


def plot_sle(
    result: Any, *, lobes: Any = None, ax: Any = None, title: str | None = None, **style: Any
) -> Any:
    """Draw a :class:`~chatterlab.frequency.SurfaceLocation`: the SLE (um,
    positive: undercut) and the peak-to-valley of the wall against rpm, with
    the unstable speeds (chatter: no SLE) shaded red and the undetermined
    ones orange.  With ``lobes`` (a :class:`~chatterlab.lobes.LobeDiagram` on
    the same cut), a panel above on the same speed axis: its limit a_lim (mm)
    and the depth of the SLE as a horizontal line.

    Parameters
    ----------
    result : SurfaceLocation
    lobes : LobeDiagram, optional
    ax : Axes or (Axes, Axes), optional
        The SLE's Axes, or (lobes' Axes, SLE's Axes) with ``lobes``.
    title : str, optional

    Returns
    -------
    The SLE's Axes, or (ax_lobes, ax_sle) with ``lobes``.
    """
    import matplotlib.pyplot as plt

    if ax is None:
        if lobes is not None:
            _, (ax_l, ax_s) = plt.subplots(2, 1, sharex=True, figsize=(8.0, 6.5), height_ratios=(1.0, 1.2))
        else:
            _, ax_s = plt.subplots(figsize=(8.0, 4.0))
            ax_l = None
    elif lobes is not None:
        ax_l, ax_s = ax
    else:
        ax_l, ax_s = None, ax
    v = np.asarray(result.speeds, dtype=float)
    verdict = np.asarray(result.verdict).astype(str)
    ax_s.plot(v, result.sle * 1e6, lw=1.4, marker=".", ms=3, label="SLE (positive: undercut)", **style)
    ax_s.plot(
        v, result.peak_to_valley * 1e6, lw=1.0, ls="--", color="0.35", label="peak-to-valley of the wall"
    )
    ax_s.axhline(0.0, color="0.6", lw=0.6)
    dv = np.diff(v).min() / 2 if v.size > 1 else 1.0
    for code, colour, text in (
        ("unstable", "tab:red", "chatter (no SLE)"),
        ("undetermined", "orange", "undetermined"),
    ):
        first = True
        for x in v[verdict == code]:
            for a in (ax_s,) if ax_l is None else (ax_s, ax_l):
                a.axvspan(
                    x - dv,
                    x + dv,
                    color=colour,
                    alpha=0.25,
                    lw=0,
                    label=text if first and a is ax_s else None,
                )
            first = False
    ax_s.set_xlabel("spindle speed [rpm]")
    ax_s.set_ylabel("SLE, peak-to-valley [um]")
    ax_s.grid(alpha=0.3)
    ax_s.legend(fontsize=8, loc="best")
    head = title or (
        f"{result.name}: a_p = {result.depth * 1e3:.3g} mm, f_z = {result.feed * 1e3:.3g} mm, {result.side}"
        f"\n{result.how}"
    )
    if ax_l is None:
        ax_s.set_title(head, fontsize=10)
        ax_s.set_xlim(v.min(), v.max())
        return ax_s
    rpm = np.asarray(lobes.speed, dtype=float)
    lim = np.where(np.isfinite(lobes.b_lim), np.asarray(lobes.b_lim, dtype=float) * 1e3, np.nan)
    ax_l.plot(rpm, lim, lw=1.2, color="tab:blue", label=f"stability limit {lobes.limit_name}")
    ax_l.axhline(result.depth * 1e3, color="k", ls=":", lw=1.0, label="depth of the SLE")
    ax_l.set_ylabel(f"{lobes.limit_name} [mm]")
    ax_l.set_ylim(
        0.0, max(float(np.nanmax(lim)) if np.any(np.isfinite(lim)) else 0.0, result.depth * 1e3) * 1.1
    )
    ax_l.grid(alpha=0.3)
    ax_l.legend(fontsize=8, loc="upper left")
    ax_l.set_title(head, fontsize=10)
    ax_s.set_xlim(v.min(), v.max())
    return ax_l, ax_s


def plot_forced_orbit(result: Any, *, ax: Any = None, **style: Any) -> Any:
    """The periodic orbit of a :class:`~chatterlab.frequency.ForcedResponse`: the
    tool's x and y (um) over one period from a tooth's generation instant, the
    SLE marked at t = 0.  Returns the Axes."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(8.0, 4.0))
    t = (np.asarray(result.t) - result.t[0]) * 1e3
    ax.plot(t, np.asarray(result.x) * 1e6, label="x (feed)", **style)
    ax.plot(t, np.asarray(result.y) * 1e6, label="y", **style)
    ax.set_xlabel("time from the generation instant [ms]")
    ax.set_ylabel("tool displacement [um]")
    sle = "no SLE" if not np.isfinite(result.sle) else f"SLE {result.sle * 1e6:.4g} um"
    ax.set_title(
        f"{result.verdict} cut: {result.rpm:g} rpm, a_p = {result.depth * 1e3:.3g} mm; {sle}"
        f" ({result.multipliers.method}, {result.multipliers.resolution})",
        fontsize=10,
    )
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return ax


def plot_runout(result: Any, *, ax: Any = None, **style: Any) -> Any:
    """The vibration amplitude (um) of a :class:`~chatterlab.frequency.RunoutResponse`
    at the spindle frequency against rpm.  Returns the Axes."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(8.0, 4.0))
    v = np.asarray(result.speeds, float)
    ax.plot(v, np.asarray(result.amplitude) * 1e6, marker=".", **style)
    # speeds without an amplitude, marked on the bottom edge: chatter, or undetermined
    verdict = np.asarray(result.verdict).astype(str)
    edge = ax.get_xaxis_transform()
    for word, mk, colour, lab in (("unstable", "v", "tab:red", "chatter (no response)"),
                                  ("undetermined", "x", "tab:orange", "undetermined")):  # fmt: skip
        sel = verdict == word
        if np.any(sel):
            ax.plot(v[sel], np.full(int(sel.sum()), 0.03), ls="none", marker=mk, ms=7, color=colour,
                    transform=edge, clip_on=False, label=lab)  # fmt: skip
    if np.any(verdict != "stable"):
        ax.legend(fontsize=8)
    ax.set_xlabel("spindle speed [rpm]")
    ax.set_ylabel("amplitude at the spindle frequency [um]")
    mesh = getattr(result, "mesh", None)
    ax.set_title(  # a line above the mesh note (a model with beams) when there is one
        f"eccentricity {result.eccentricity * 1e6:.3g} um, b = {result.width * 1e3:.3g} mm" + ("\n" if mesh else ""),
        fontsize=10,
        loc="left" if mesh else "center",
    )  # fmt: skip
    ax.grid(alpha=0.3)
    mesh_note(ax, mesh)
    return ax
