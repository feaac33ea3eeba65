"""Plots of speed selection (:mod:`chatterlab.selection`): the recommended
cuts on the lobes over the removal rate against speed, the spectrum of a
recording with the spindle harmonics removed and the chatter peak, and the
chatter-frequency rule's speeds on the lobes.  They draw what the results
hold (no analysis here)."""

from __future__ import annotations

from typing import Any

import numpy as np

#: colours of the limits besides stability
_CAP_STYLE = {
    "ceiling": ("0.5", ":"),
    "max depth": ("tab:brown", "--"),
    "power": ("tab:purple", "-."),
    "torque": ("tab:olive", "-."),
}


def _two(ax: Any, figsize: tuple[float, float] = (9.0, 7.0)) -> tuple[Any, Any]:
    import matplotlib.pyplot as plt

    if ax is None:
        _, axs = plt.subplots(2, 1, figsize=figsize, sharex=True, gridspec_kw={"height_ratios": [2.2, 1.0]})
        return axs[0], axs[1]
    axs = list(np.ravel(np.asarray(ax, dtype=object)))
    if len(axs) != 2:
        raise ValueError("plot_recommendation draws on two Axes: pass ax=(top, bottom)")
    return axs[0], axs[1]


def plot_recommendation(rec: Any, *, ax: Any = None, title: str | None = None) -> tuple[Any, Any]:
    """Top: the stability limit against speed (the lobes' envelope, mm), the
    limit with the margin, every other limit (tool depth, power, torque,
    plug-in limits) and the largest width allowed (thick), with the ranked
    cuts marked 1, 2, ...; bottom: the removal rate of that width against
    speed (cm^3/min, or b/T in mm/s without the feed), the ranked cuts
    marked.  Returns the two Axes."""
    top, bot = _two(ax)
    v = np.asarray(rec.grid_speed, float)
    ve, env = np.asarray(rec.line_speed, float), np.asarray(rec.line_limit, float)
    env = np.asarray(env, float)
    shown = np.where(np.isfinite(env), env, np.nan) * 1e3
    top.plot(ve, shown, color="k", lw=1.1, label=f"stability limit {rec.limit_name}")
    if rec.margin > 0:
        top.plot(ve, shown * (1 - rec.margin), color="k", lw=0.8, ls="--",
                 label=f"with the margin ({rec.margin * 100:g} % below)")  # fmt: skip
    ymax = np.nanmax(
        np.r_[shown[np.isfinite(shown)], rec.grid_allowed[np.isfinite(rec.grid_allowed)] * 1e3, 0.0]
    )
    for name, cap in rec.caps.items():
        if name == "stability":
            continue
        c = np.asarray(cap, float)
        if not np.any(np.isfinite(c) & (c < 1.5 * max(ymax, 1e-12) / 1e3)):
            continue
        colour, ls = _CAP_STYLE.get(name, ("tab:cyan", "-."))
        top.plot(v, np.where(np.isfinite(c), c * 1e3, np.nan), color=colour, ls=ls, lw=1.0, label=name)
    top.plot(ve, np.asarray(rec.line_allowed, float) * 1e3, color="tab:green", lw=2.4, alpha=0.7,
             label="largest width allowed")  # fmt: skip
    scale, rate_label, use_mrr = _rate(rec)
    la = np.asarray(rec.line_allowed, float)
    y = rec.removal.mrr(la, ve) if use_mrr else rec.removal.width_rate(la, ve)
    bot.plot(ve, np.asarray(y, float) * scale, color="tab:green", lw=1.4)
    for i in range(rec.speed.size):
        s, w = float(rec.speed[i]), float(rec.width[i]) * 1e3
        y = float(rec.mrr[i] if use_mrr else rec.width_rate[i]) * scale
        for a, yy in ((top, w), (bot, y)):
            a.plot(s, yy, "o", ms=7, mfc="white", mec="tab:red", mew=1.6, zorder=5)
            a.annotate(str(i + 1), (s, yy), textcoords="offset points", xytext=(5, 5), fontsize=9,
                       color="tab:red", fontweight="bold")  # fmt: skip
    finite = shown[np.isfinite(shown)]
    hi = max(
        float(np.max(finite)) if finite.size else 0.0, float(np.max(rec.grid_allowed, initial=0.0)) * 1e3
    )
    top.set_ylim(0.0, 1.15 * hi if hi > 0 else 1.0)
    top.set_ylabel(f"{rec.width_name} [mm]")
    top.grid(alpha=0.3)
    top.legend(fontsize=8, loc="upper left", ncol=2)
    top.set_title(title or f"{rec.model}: the cuts to choose (ranked by removal rate)", fontsize=10)
    bot.set_ylabel(rate_label)
    bot.set_xlabel(f"{rec.speed_name} [{rec.speed_unit}]")
    bot.set_ylim(bottom=0.0)
    bot.grid(alpha=0.3)
    return top, bot


def _mrr(rec: Any) -> np.ndarray:
    return np.asarray(rec.removal.mrr(rec.grid_allowed, rec.grid_speed), float)


def _rate(rec: Any) -> tuple[float, str, bool]:
    """Scale, label and source of the removal-rate panel: the MRR where it is known, else b/T."""
    if rec.grid_speed.size and np.all(np.isfinite(_mrr(rec))):
        return 6e7, "MRR [cm³/min]", True
    return 1e3, "b/T [mm/s] (MRR per unit feed and cut length)", False


def plot_chatter_spectrum(
    cf: Any, *, ax: Any = None, title: str | None = None, fmax: float | None = None
) -> Any:
    """The amplitude spectrum of a recording (log scale) with the notches
    around the spindle harmonics shaded, the tooth-passing harmonics marked
    and the chatter peak annotated.  Returns the Axes."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(9.0, 3.8))
    f, a = np.asarray(cf.freq), np.asarray(cf.amp)
    top = fmax or (min(float(cf.band[1]), 3 * cf.frequency_hz) if cf.found else float(cf.band[1]))
    m = (f <= top) & (f > 0)
    ax.semilogy(f[m], np.maximum(a[m], 1e-300), color="k", lw=0.8, label="amplitude spectrum")
    h = m & cf.harmonic
    ax.fill_between(f[m], 0, 1, where=h[m], transform=ax.get_xaxis_transform(), color="tab:orange", alpha=0.2,
                    lw=0, label="spindle harmonics (removed)")  # fmt: skip
    ft = cf.tooth_hz
    for k in range(1, int(top // ft) + 1):
        ax.axvline(k * ft, color="tab:orange", lw=0.6, ls=":")
    if cf.found:
        ax.plot(cf.frequency_hz, cf.amplitude, "v", color="tab:red", ms=8,
                label=f"chatter {cf.frequency_hz:.1f} Hz ± {cf.resolution_hz:.2g} Hz")  # fmt: skip
    ax.set_xlim(0, top)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("amplitude")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, loc="upper right")
    name = str(cf.source).replace("\\", "/").rsplit("/", 1)[-1]
    ax.set_title(title or f"spectrum of {name}: tooth passing {ft:.4g} Hz (dotted)", fontsize=10)
    return ax


def plot_speed_rule(rule: Any, *, ax: Any = None, title: str | None = None) -> Any:
    """The chatter-frequency rule's speeds: on the lobes (with a model;
    the verdict's colour, the limit with the margin dashed) or on the speed
    axis alone, with the running speed; over the recording's spectrum when
    it came from one.  Returns the Axes (two when the spectrum is drawn:
    lobes first)."""
    import matplotlib.pyplot as plt

    two = rule.spectrum is not None
    if ax is None:
        if two:
            _, axs = plt.subplots(2, 1, figsize=(9.0, 7.0))
            lo, sp = axs[0], axs[1]
        else:
            _, lo = plt.subplots(figsize=(9.0, 4.2))
            sp = None
    else:
        axs = list(np.ravel(np.asarray(ax, dtype=object)))
        lo, sp = axs[0], (axs[1] if len(axs) > 1 else None)
    colours = {"stable": "tab:green", "within margin": "tab:orange", "unstable": "tab:red",
               "undetermined": "0.5", "limit": "tab:blue"}  # fmt: skip
    d = rule.diagram
    v = np.asarray(rule.speed, float)
    span = np.r_[v, rule.current_speed]
    if d is not None:
        geo = d.geometry() if getattr(d, "lobes", None) else None
        grid = np.linspace(0.8 * span.min(), 1.2 * span.max(), 1500)
        if geo is not None and geo.curves:
            vv, env, _ = geo.envelope_line(np.clip(grid, d.speed.min(), d.speed.max()))
            lo.plot(
                vv, np.where(np.isfinite(env), env * 1e3, np.nan), color="k", lw=1.0, label="stability limit"
            )
        top = np.nanmax(np.r_[rule.limit[np.isfinite(rule.limit)] * 1e3, 1e-3])
        for s, b, w, vd in zip(v, rule.limit, rule.width, rule.verdict, strict=True):
            y = b * 1e3 if np.isfinite(b) else top
            lo.plot(s, y, "o", color=colours[str(vd)], ms=8)
            if np.isfinite(w):
                lo.plot(s, w * 1e3, "_", color=colours[str(vd)], ms=14, mew=2)
        if rule.depth is not None:
            lo.axhline(
                rule.depth * 1e3,
                color="tab:red",
                lw=0.8,
                ls="--",
                label=f"depth cut {rule.depth * 1e3:.3g} mm",
            )
        lo.set_ylabel("limit and width allowed [mm]")
        lo.set_ylim(bottom=0.0)
    else:
        for s, vd in zip(v, rule.verdict, strict=True):
            lo.axvline(s, color=colours[str(vd)], lw=1.4)
        lo.set_yticks([])
    for j, s in zip(rule.waves, v, strict=True):
        lo.annotate(f"j={int(j)}", (s, 0), xycoords=("data", "axes fraction"), xytext=(3, 4),
                    textcoords="offset points", fontsize=8)  # fmt: skip
    lo.axvline(rule.current_speed, color="k", lw=1.0, ls=":", label="running speed")
    for vd, c in colours.items():
        if vd in set(map(str, rule.verdict)):
            lo.plot([], [], "o", color=c, label=vd)
    lo.set_xlabel(f"{rule.process.speed_name} [{rule.speed_unit}]")
    lo.legend(fontsize=8, loc="upper left")
    lo.grid(alpha=0.3)
    lo.set_title(
        title or f"{rule.model}: speeds with f_tooth = f_c / j, f_c = {rule.chatter_hz:.1f} Hz", fontsize=10
    )
    if sp is not None and rule.spectrum is not None:
        plot_chatter_spectrum(rule.spectrum, ax=sp)
        return lo, sp
    return lo
