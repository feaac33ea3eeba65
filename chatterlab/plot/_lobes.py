"""The stability lobe diagram: layout, the zoom panel of a dense diagram,
the chatter frequency along the envelope, legends and titles."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ._lobe_panel import DENSE_PIXELS, DISPLAY_DPI, draw_lobe_panel, lobe_density, mesh_note, zoom_range
from ._style import LAID_OUT, axes_arg, new_figure


def plot_lobes(
    diagram: Any,
    *,
    ax: Any = None,
    lobe_numbers: int = 8,
    title: str | None = None,
    references: Mapping[str, Any] | None = None,
    axes: Any = None,
    **style: Any,
) -> Any:
    """Stability lobe diagram: the limit width (mm) against speed.

    Draws every lobe (one LineCollection), the exact lower envelope of the
    lobes (the minimum over the lobe curves, linearly interpolated in speed,
    at >= 4 points per pixel with the cusps added), the unstable region above
    it, the unconditional limit, and where the diagram claims ``inf`` (hatched
    at the top), undetermined (orange) or contradicted (magenta) speeds.  When
    the lobes are denser than the pixels (more than one lobe of a branch
    within DENSE_PIXELS columns) it says so, shades the band the envelope
    sweeps within each pixel column (from the lobe bottoms to the cusps), and
    adds a panel zoomed on about 7 lobes around the minimum.  The bottom panel
    is the chatter frequency along the envelope.  The title names the model,
    position, feedback, ceiling, chatter band and the verification.

    Parameters
    ----------
    diagram : LobeDiagram
    ax : sequence of Axes, optional
        (ax_lobes, ax_freq) or (ax_lobes, ax_zoom, ax_freq); default: a new
        figure, with the zoom panel when the lobes are dense.  ``axes=`` is a
        deprecated alias.
    lobe_numbers : int
        Most lobe numbers written per panel (0: none).
    title : str, optional
        First title line (default: the model); the second says position,
        feedback, ceiling, band and checks.
    references : mapping, optional
        Reference widths drawn on the lobe panels with a legend entry: label ->
        width (m, a horizontal line) or (speeds, widths in m) (a dotted curve).

    Returns
    -------
    The Axes, a tuple: (ax_lobes, ax_freq), or (ax_lobes, ax_zoom, ax_freq) when dense;
    for a diagram of Floquet limits (no lobe curves) one Axes.
    """
    ax_arg = axes_arg(ax, axes, "plot_lobes")
    d = diagram
    if not d.lobes and getattr(d, "floquet", False):  # limits without lobe curves: Floquet multipliers
        from ._milling import plot_milling_lobes

        return plot_milling_lobes(d, ax=ax_arg, title=title, **style)
    v = np.asarray(d.speed, float)
    lo, hi = float(v.min()), float(v.max())
    if hi <= lo:
        lo, hi = lo * 0.95, hi * 1.05
    geometry = d.geometry()
    curves = geometry.curves
    created = ax_arg is None
    # a measured FRF's lobes are not exact curves: no zoom on them (see draw_lobe_panel)
    measured = bool(getattr(d, "band_measured", False))
    panels = _new_lobe_figure([] if measured else curves, lo, hi) if ax_arg is None else tuple(ax_arg)
    ax, axf = panels[0], panels[-1]
    axz = panels[1] if len(panels) > 2 else None

    def panel(a: Any, plo: float, phi: float, dense_ok: bool) -> dict[str, Any]:
        return draw_lobe_panel(
            a,
            d,
            curves,
            plo,
            phi,
            geometry=geometry,
            lobe_numbers=lobe_numbers,
            dense_ok=dense_ok,
            references=references,
        )

    main = panel(ax, lo, hi, True)
    count = _lobe_count(curves, d)
    note = _dense_note(main, axz is not None)
    if axz is not None:
        zlo, zhi = zoom_range(curves, d, lo, hi) if main["dense"] else (lo, hi)
        zoom = panel(axz, zlo, zhi, False)
        _finish_zoom(ax, axz, d, zlo, zhi)
        _lobe_legend(axz, zoom, curves, d, "outside", count)
    if axz is not None or main["dense"]:
        _dense_legend(ax, main, note)
    else:
        _lobe_legend(ax, main, curves, d, "outside", count)
    ax.set_ylabel(f"{d.width_name} [mm]")
    ax.grid(alpha=0.3)
    _frequency_panel(axf, main, d)
    mesh_note(axf, getattr(d, "meta", None))
    if axz is not None:
        ax.set_xlabel(f"{d.speed_name} [{d.speed_unit}]")
    head = title if title is not None else f"{_model_name(d)}: stability lobes"
    ax.set_title(f"{head}\n{_subtitle(d)}", fontsize=9)
    if created:
        ax.figure.set_gid(LAID_OUT)
    return panels


def _new_lobe_figure(curves: list[Any], lo: float, hi: float) -> tuple[Any, ...]:
    """A new figure laid out for the diagram: (ax_lobes, ax_freq), or
    (ax_lobes, ax_zoom, ax_freq) when the lobes are denser than the pixels.
    The layout is decided on a figure of the final size (dpi of savefig: text
    is measured once), with fixed margins (the texts are ours): a tight layout
    costs 0.15 s of the main job."""
    fig = new_figure(figsize=(11.5, 6.5), dpi=130)
    dense = lobe_density(curves, lo, hi, 0.695 * 11.5 * DISPLAY_DPI) > 1  # the panels' width
    if dense:
        fig.set_size_inches(11.5, 9.5)  # legends right of the panels: the lobes fill the frame
        gs = fig.add_gridspec(
            3,
            1,
            height_ratios=[3, 2.4, 1.1],
            left=0.06,
            right=0.755,
            top=0.925,
            bottom=0.05,
            hspace=0.36,
        )
        ax = fig.add_subplot(gs[0])
        axz = fig.add_subplot(gs[1])
        axf = fig.add_subplot(gs[2], sharex=ax)
        return (ax, axz, axf)
    ax, axf = fig.subplots(
        2,
        1,
        sharex=True,
        gridspec_kw={
            "height_ratios": [3, 1.2],
            "left": 0.06,
            "right": 0.755,
            "top": 0.885,
            "bottom": 0.08,
            "hspace": 0.2,
        },
    )
    return (ax, axf)


def _dense_note(main: dict[str, Any], has_zoom: bool) -> str | None:
    """The legend title of a dense diagram: what the band shows."""
    if not main["dense"]:
        return None
    import textwrap

    return textwrap.fill(
        f"{main['density']:.0f} lobes per {DENSE_PIXELS} pixels: each column shows the band the"
        " limit sweeps" + ("; single lobes in the zoom" if has_zoom else ""),
        34,
    )


def _dense_legend(ax: Any, main: dict[str, Any], note: str | None) -> None:
    """The main panel's legend beside a zoom panel or over dense lobes, with the note as its title."""
    leg = ax.legend(
        *_with_labels(main["handles"]),
        loc="upper left",
        bbox_to_anchor=(1.01, 1.0),
        fontsize=6.5,
        framealpha=0.92,
        title=note,
        title_fontsize=6.5,
        alignment="left",
    )
    if note:
        leg.get_title().set_gid("dense-note")


def _finish_zoom(ax: Any, axz: Any, d: Any, zlo: float, zhi: float) -> None:
    """Labels of the zoom panel, and its span marked on the main panel."""
    unit = d.speed_unit
    axz.set_ylabel("width of cut b [mm]")
    axz.set_xlabel(f"{d.speed_name} [{unit}] (zoom)")
    axz.grid(alpha=0.3)
    ax.axvspan(zlo, zhi, facecolor="none", edgecolor="k", lw=0.8, zorder=6)
    ax.annotate(
        "zoom",
        (zhi, 0.02),
        xycoords=ax.get_xaxis_transform(),
        xytext=(3, 0),
        textcoords="offset points",
        ha="left",
        va="bottom",
        fontsize=7,
    )
    axz.set_title(f"zoom on {zlo:.5g}-{zhi:.5g} {unit} around the minimum: individual lobes", fontsize=8)


def _frequency_panel(axf: Any, main: dict[str, Any], d: Any) -> None:
    """The chatter frequency along the envelope drawn on the main panel."""
    fin = np.isfinite(main["width"]) & (main["freq"] > 0)
    axf.plot(main["speed"][fin], main["freq"][fin], ".", ms=1, color="tab:blue", rasterized=True)
    axf.set_ylabel("chatter frequency [Hz]", fontsize=8)
    axf.set_xlabel(f"{d.speed_name} [{d.speed_unit}]")
    axf.set_title("chatter frequency along the envelope", fontsize=8, loc="left")
    axf.grid(alpha=0.3)


def _lobe_count(curves: list[Any], d: Any) -> str:
    """The number of lobes drawn, said against the diagram's summary."""
    ks = {(c.k, c.branch) for c in curves}
    if not ks:
        return "no lobe below the width ceiling"
    kk = sorted(k for k, _ in ks)
    return f"{len(ks)} lobes, k = {kk[0]}-{kk[-1]}"


def _lobe_legend(ax: Any, drawn: dict[str, Any], curves: list[Any], d: Any, loc: str, count: str) -> None:
    import textwrap

    from matplotlib.lines import Line2D

    handles = list(drawn["handles"])
    if curves:
        txt = count
        if drawn["labelled"]:
            multi = len({c.branch for c in curves}) > 1
            txt += "\nlabel " + ("k/branch" if multi else "k") + ": lobe number k at its bottom"
            if multi:
                txt += "\n" + _branch_modes(curves)
        if loc == "outside":
            txt = "\n".join(textwrap.fill(line, 34) for line in txt.split("\n"))
        handles.append(Line2D([], [], ls="none", label=txt))
    if loc == "outside":
        ax.legend(*_with_labels(handles), loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=6.5,
                  framealpha=0.9)  # fmt: skip
    else:
        ax.legend(*_with_labels(handles), loc=loc, fontsize=6.5, framealpha=0.9, ncol=2)


def _with_labels(handles: list[Any]) -> tuple[list[Any], list[str]]:
    """Handles and their labels (a tuple handle, drawn as its artists
    overlaid, takes the label of its first)."""
    return handles, [(h[0] if isinstance(h, tuple) else h).get_label() for h in handles]


def _branch_modes(curves: list[Any]) -> str:
    """Which mode each branch is: its chatter frequency where its width is least."""
    chains = {c.branch: c.chain for c in curves}
    parts = []
    if len(chains) > 4:
        return f"{len(chains)} branches (the modes of the structure)"
    for b in sorted(chains):
        ch = chains[b]
        f = float(ch.omega[int(np.argmin(ch.width))]) / (2 * np.pi)
        parts.append(f"branch {b}: {f:.4g} Hz")
    return "; ".join(parts)


def _model_name(d: Any) -> str:
    from pathlib import PurePath

    p = PurePath(str(d.model))
    return str(PurePath(*p.parts[-2:])) if len(p.parts) > 2 else str(p)


def _subtitle(d: Any) -> str:
    terms = {"pdo": "P + D + delayed (pdo)", "o": "delayed only (o)"}.get(d.terms, str(d.terms))
    pos = f"slide at s = {d.position:g} m" if d.position is not None else "fixed structure"
    lo, hi = d.band_hz
    band = f"chatter band {lo:.4g}-{hi:.4g} Hz " + ("proven complete" if d.band_certified else "NOT proven")
    if d.verified is None:
        ver = "not verified"
    else:
        ok = sum(c["agrees"] for c in d.checks)
        ver = f"verified {ok}/{len(d.checks)} checks" + ("" if d.verified else " -- CHECKS FAILED")
    pd = getattr(d, "meta", {}).get("process_damping")
    if pd:  # the flank's damping: the lobes couple width and delay through the cutting speed
        terms += f" + process damping C_pd = {pd['C_pd']:.3g} N/m"
    return (
        f"{pos}; feedback {terms}; width ceiling {d.width_max * 1e3:g} mm\n{band}; {ver} (argument principle)"
    )
