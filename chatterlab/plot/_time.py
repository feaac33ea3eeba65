"""Time histories and their spectra.

* :func:`plot_histories` -- outputs of one or more runs against time or the
  distance cut, one panel per output, each run in the same colour on every
  panel, the in-cut intervals shaded with a legend entry;
* :func:`plot_spectra` -- amplitude spectra of one output for several runs;
* :func:`plot_time_response` -- one run as an engineer reads it: tool-point
  displacement, cutting force, and the spectrum with the chatter frequency
  and the tooth-passing (regeneration) frequency and its harmonics marked;
* :func:`plot_outputs` -- rows of a generic response against time;
* :func:`plot_confirmation` -- the points of a time-domain confirmation of
  a lobe diagram over speed and width, as simulated.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ._style import axes_arg

#: one colour per run, the same on every panel and in the spectra
RUN_COLORS = ("tab:red", "tab:green", "tab:blue", "tab:purple", "tab:orange")


def run_title(sim: Any, feedbacks: Sequence[str] | None = None) -> str:
    """Model, width, delay (and speed when recorded) and feedback of a run
    (``feedbacks``: the cases of several runs drawn together, all named)."""
    parts = [f"b = {sim.width * 1e3:.4g} mm"]
    if getattr(sim, "delay", None):
        parts.append(f"T = {sim.delay:.4g} s")
    speed = (getattr(sim, "meta", None) or {}).get("speed")
    if speed is not None:
        parts.append(f"speed {speed:g}")
    parts.append("feedback " + (" / ".join(feedbacks) if feedbacks else str(sim.terms)))
    model = str(getattr(sim, "model", "") or "model not named")
    if "/" in model:  # a model file: its folder and name are enough
        from pathlib import PurePath

        model = str(PurePath(*PurePath(model).parts[-2:]))
    return f"{model}: " + ", ".join(parts)


def plot_histories(
    sims: Sequence[Any],
    names: Sequence[str],
    *,
    against: str = "time",
    labels: Sequence[str] | None = None,
    ax: Any = None,
    scale: float = 1e6,
    unit: str = "µm",
    title: str | None = None,
    axes: Any = None,
) -> Any:
    """Time histories of outputs (one panel per output, the runs overlaid),
    against time (s) or against the distance travelled in the cut (mm), as
    in the paper's Figs. 4-9.  Displacements shown in micrometres by default.
    Each run keeps its colour on every panel; the first run's in-cut
    intervals are shaded (legend entry "in the cut").  The title (default:
    the first run's model, width, delay and feedback) is on the top panel.
    ``ax`` is one Axes per output (``axes=`` a deprecated alias), or one
    Axes for the first output alone.  Returns the Axes (one per output, or
    the one given)."""
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    axes = axes_arg(ax, axes, "plot_histories")
    if axes is not None and hasattr(axes, "plot"):  # one Axes: the first output on it
        plot_histories(
            sims,
            list(names)[:1],
            against=against,
            labels=labels,
            ax=[axes],
            scale=scale,
            unit=unit,
            title=title,
        )
        return axes
    if axes is None:
        fig, axes = plt.subplots(
            len(names), 1, sharex=True, figsize=(8.5, 2.4 * len(names) + 0.6), squeeze=False
        )
        axes = axes[:, 0]
    for k, sim in enumerate(sims):
        lab = labels[k] if labels is not None else f"feedback {sim.terms}"
        if against == "distance":
            m = sim.window("last-cut")
            x = sim.cut_distance[m] * 1e3
        else:
            m = np.ones(sim.t.size, bool)
            x = sim.t
        for a, n in zip(axes, names, strict=False):
            a.plot(x, sim.data[n][m] * scale, lw=0.8, label=lab, color=RUN_COLORS[k % len(RUN_COLORS)])
    for a, n in zip(axes, names, strict=False):
        a.set_ylabel(f"{n} [{unit}]")
        a.grid(alpha=0.3)
    axes[-1].set_xlabel("distance of cutting s [mm]" if against == "distance" else "time [s]")
    handles, _ = axes[0].get_legend_handles_labels()
    if against == "time" and sims:
        s0 = sims[0]
        for a in axes:
            _shade_cut(a, s0.t, s0.in_cut)
        if np.any(s0.in_cut):
            handles.append(Patch(color="0.85", alpha=0.5, label="in the cut"))
    axes[0].legend(handles=handles, fontsize=8, loc="upper right")
    if sims and (title is None or title):
        cases = list(dict.fromkeys(str(s.terms) for s in sims)) if labels is None else None
        axes[0].set_title(
            title or run_title(sims[0], cases if cases and len(cases) > 1 else None), fontsize=9
        )
    return axes


def _shade_cut(ax: Any, t: np.ndarray, in_cut: np.ndarray) -> None:
    lo, hi = ax.get_ylim()
    ax.fill_between(
        t, lo, hi, where=np.asarray(in_cut) > 0, color="0.85", alpha=0.5, lw=0, zorder=0, gid="in-cut"
    )
    ax.set_ylim(lo, hi)


def plot_spectra(
    sims: Sequence[Any],
    name: str,
    *,
    labels: Sequence[str] | None = None,
    ax: Any = None,
    fmax: float = 300.0,
    window: Any = "last-cut",
    scale: float = 1e6,
    unit: str = "µm",
) -> Any:
    """Amplitude spectra of one output for several runs overlaid (the
    paper's Figs. 10-11), with the main peak of each run marked.  Returns
    the Axes."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(8, 3.8))
    for k, sim in enumerate(sims):
        f, a = sim.spectrum(name, window=window)
        m = f <= fmax
        lab = labels[k] if labels is not None else f"feedback {sim.terms}"
        col = RUN_COLORS[k % len(RUN_COLORS)]
        ax.plot(f[m], a[m] * scale, color=col, lw=1, label=lab)
        if np.any(m):
            j = int(np.argmax(a[m]))
            ax.annotate(
                f"{f[m][j]:.1f} Hz",
                (f[m][j], a[m][j] * scale),
                textcoords="offset points",
                xytext=(4, 2),
                fontsize=8,
                color=col,
            )
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"amplitude of {name} [{unit}]")
    ax.set_xlim(0, fmax)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return ax


def plot_time_response(
    sim: Any,
    output: str,
    *,
    force: str | np.ndarray | None = None,
    chatter_hz: float | None = None,
    tooth_hz: float | None = None,
    fmax: float | None = None,
    window: Any = "last-cut",
    ax: Any = None,
    title: str | None = None,
) -> Any:
    """One run: the tool-point displacement ``output`` (um) against time,
    the cutting force (N; ``force`` a recorded output name or an array on the
    run's time grid; panel omitted when None), and the amplitude spectrum of
    the displacement over ``window`` with the chatter frequency (``chatter_hz``,
    default the spectrum's highest peak) and the tooth-passing frequency
    (``tooth_hz``, default 1/T of the run's delay: the regeneration period)
    with its harmonics marked.  In-cut intervals are shaded.

    ``ax``: Axes (displacement, [force,] spectrum).  Returns the Axes, a
    tuple of 3 (or 2 without force)."""
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    nrow = 3 if force is not None else 2
    created = ax is None
    if ax is None:
        fig, ax = plt.subplots(nrow, 1, figsize=(8.5, 2.5 * nrow + 0.6))
    ax = tuple(ax)
    if created and force is not None:
        ax[1].sharex(ax[0])  # displacement and force on one time axis
    axd, axs = ax[0], ax[-1]
    t = np.asarray(sim.t, float)
    col = RUN_COLORS[0]
    axd.plot(t, np.asarray(sim.data[output]) * 1e6, lw=0.8, color=col, gid="displacement", label=output)
    axd.set_ylabel(f"{output} [µm]")
    axd.set_xlabel("time [s]")
    cut = Patch(color="0.85", alpha=0.5, label="in the cut")
    if force is not None:
        axf = ax[1]
        fv = np.asarray(sim.data[force] if isinstance(force, str) else force, float)
        flab = force if isinstance(force, str) else "cutting force"
        axf.plot(t, fv, lw=0.8, color="tab:blue", gid="force", label=flab)
        axf.set_ylabel(f"{flab} [N]")
        axf.set_xlabel("time [s]")
    for a in ax[:-1]:
        a.grid(alpha=0.3)
        _shade_cut(a, t, sim.in_cut)
        handles, _ = a.get_legend_handles_labels()
        a.legend(handles=handles + ([cut] if np.any(sim.in_cut) else []), fontsize=7, loc="upper right")
    _spectrum_panel(axs, sim, output, chatter_hz, tooth_hz, fmax, window, col)
    axd.set_title(title or run_title(sim), fontsize=9)
    return ax


def _spectrum_panel(
    ax: Any,
    sim: Any,
    output: str,
    chatter_hz: float | None,
    tooth_hz: float | None,
    fmax: float | None,
    window: Any,
    col: str,
) -> None:
    """The amplitude spectrum (um) with the chatter and tooth-passing lines."""
    f, a = sim.spectrum(output, window=window)
    a = np.asarray(a) * 1e6
    if tooth_hz is None and getattr(sim, "delay", None):
        tooth_hz = 1.0 / float(sim.delay)
    how = ""
    if chatter_hz is None and a.size > 1 and np.max(a[1:]) > 0:
        chatter_hz, how = float(f[1:][np.argmax(a[1:])]), " (highest peak)"
    top = fmax if fmax is not None else float(f[-1])
    if fmax is None and chatter_hz:
        top = min(float(f[-1]), 3.0 * chatter_hz)
    m = f <= top
    ax.plot(f[m], a[m], color=col, lw=1, gid="spectrum", label=f"{output}, window {window}")
    if chatter_hz:
        ax.axvline(
            chatter_hz,
            color="tab:red",
            ls="--",
            lw=1,
            gid="chatter",
            label=f"chatter {chatter_hz:.2f} Hz{how}",
        )
    if tooth_hz:
        n = int(top // tooth_hz)
        if 1 <= n <= 40:
            for k in range(1, n + 1):
                ax.axvline(k * tooth_hz, color="0.4", ls=":", lw=0.8, gid="tooth",
                           label=f"tooth passing 1/T = {tooth_hz:.3g} Hz and harmonics" if k == 1 else None)  # fmt: skip
        elif n > 40:
            ax.text(0.99, 0.97, f"tooth passing 1/T = {tooth_hz:.3g} Hz (harmonics {n} in view, not drawn)",
                    transform=ax.transAxes, ha="right", va="top", fontsize=7, gid="tooth")  # fmt: skip
        else:
            ax.text(0.99, 0.97, f"tooth passing 1/T = {tooth_hz:.3g} Hz (above the view)",
                    transform=ax.transAxes, ha="right", va="top", fontsize=7, gid="tooth")  # fmt: skip
    ax.set_xlim(0, top)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"amplitude of {output} [µm]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="center right")


def plot_cases(
    sims: Sequence[Any],
    names: Sequence[str],
    *,
    fmax: float = 300.0,
    window: Any = "last-cut",
    title: str | None = None,
) -> Any:
    """Several runs (the feedback cases of ``simulate --feedback all``) side
    by side, one column per run: the histories of ``names`` (µm, one row
    each, the in-cut intervals shaded) and the spectrum of the first output
    with its main peak labelled.  Panels of one row share their y axis, so
    the cases compare at a glance and no case hides another.  The figure's
    title names the model, the width, the delay and every case; each column
    is headed by its case.  Returns the Axes, an array (rows, columns)."""
    import matplotlib.pyplot as plt

    nr, nc = len(names) + 1, len(sims)
    fig, grid = plt.subplots(
        nr, nc, figsize=(4.2 * nc + 1.2, 2.3 * nr + 0.8), squeeze=False, sharey="row", layout="constrained"
    )
    for j, sim in enumerate(sims):
        col = RUN_COLORS[j % len(RUN_COLORS)]
        lab = f"feedback {sim.terms}"
        for i, n in enumerate(names):
            a = grid[i, j]
            a.plot(sim.t, np.asarray(sim.data[n]) * 1e6, lw=0.7, color=col, label=lab, gid="history")
            a.grid(alpha=0.3)
            a.set_xlabel("time [s]")
            if j == 0:
                a.set_ylabel(f"{n} [µm]")
        a = grid[-1, j]
        f, amp = sim.spectrum(names[0], window=window)
        m = f <= fmax
        a.plot(f[m], amp[m] * 1e6, color=col, lw=1, label=lab, gid="spectrum")
        if np.any(m):
            k = int(np.argmax(amp[m]))
            a.annotate(f"{f[m][k]:.1f} Hz", (f[m][k], amp[m][k] * 1e6), textcoords="offset points",
                       xytext=(5, -4), va="top", fontsize=8, color=col, gid="peak-label")  # fmt: skip
        a.set_xlim(0, fmax)
        a.set_xlabel("frequency [Hz]")
        a.grid(alpha=0.3)
        if j == 0:
            a.set_ylabel(f"amplitude of {names[0]} [µm]")
        grid[0, j].set_title(lab, fontsize=10, color=col)
    from matplotlib.patches import Patch

    for j, sim in enumerate(sims):  # shade once the shared y limits are final
        for i in range(len(names)):
            _shade_cut(grid[i, j], np.asarray(sim.t), sim.in_cut)
    if np.any(sims[0].in_cut):
        grid[0, 0].legend(
            handles=[Patch(color="0.85", alpha=0.5, label="in the cut")], fontsize=7, loc="lower right"
        )
    cases = [str(s.terms) for s in sims]
    fig.suptitle(title or run_title(sims[0], cases), fontsize=10)
    engine: Any = fig.get_layout_engine()  # constrained: set in plt.subplots above
    engine.set(h_pad=0.06, w_pad=0.06)
    from ._style import LAID_OUT

    fig.set_gid(LAID_OUT)
    return grid


def plot_outputs(
    t: np.ndarray,
    rows: np.ndarray,
    labels: Sequence[str],
    *,
    ylabel: str = "",
    ax: Any = None,
    **kwargs: Any,
) -> Any:
    """Rows of a response (n_rows, n_t) against time t (s), one line each
    with its label (``kwargs`` go to ``Axes.plot``).  Returns the Axes."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots()
    for row, lab in zip(np.atleast_2d(rows), labels, strict=True):
        ax.plot(t, row, label=lab, **kwargs)
    ax.set_xlabel("t [s]")
    ax.set_ylabel(ylabel)
    ax.legend()
    return ax


def plot_confirmation(conf: Any, *, ax: Any = None, **style: Any) -> Any:
    """The points of a :class:`chatterlab.lobes.Confirmation`: width (mm)
    against speed, a circle where the diagram says stable and a triangle
    where it says unstable, filled green when the simulation decayed, red
    when it grew, grey when it could not tell; a point that disagrees is
    ringed black.  ``style`` goes to ``Axes.scatter``.  Returns the Axes."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots()
    colours = {"stable": "tab:green", "unstable": "tab:red"}
    for expected, marker in (("stable", "o"), ("unstable", "^")):
        rows = [r for r in conf.rows if r["expected"] == expected]
        if not rows:
            continue
        ax.scatter(
            [r["speed"] for r in rows],
            [r["width"] * 1e3 for r in rows],
            marker=marker,
            c=[colours.get(r["classification"], "0.6") for r in rows],
            edgecolors=["k" if not r["agrees"] else "none" for r in rows],
            label=f"diagram: {expected}",
            **{"s": 40, **style},
        )
    ax.set_xlabel(f"speed [{conf.speed_unit}]" if conf.speed_unit else "speed")
    ax.set_ylabel("width of cut [mm]")
    ax.set_title(conf.summary_line(), fontsize=9)
    if conf.rows:
        ax.legend(fontsize=8)
    return ax
