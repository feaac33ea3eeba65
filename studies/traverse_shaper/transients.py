"""Transient vibration of the traverse shaper: the paper's Figs. 4-11.

The seed paper (Wittbrodt & Kalinski, Sec. 3-4) integrates Eq. (2.28) for
the shaper with the slide moving (v_w = 0.5 m/s, v_l = 2 m/s), the cutting
process as a coupling element (Table 3, b = 2 mm) and three feedback cases:

* (a) ``none``: no feedback, only the desired forces F_z, F_y (red);
* (b) ``pd``: proportional + ideal derivative (inner modulation, green);
* (c) ``pdo``: + delayed (outer modulation, regeneration, blue).

It plots q1 = x51 and q2 = x52 (RFE 5, the tool/workpiece contact point,
``rfe5.x`` and ``rfe5.y`` here) against the distance of cutting (Figs. 4-9)
and their spectra (Figs. 10-11), and reports: without feedback a dominant
peak at 74 Hz in both directions; with P + D only a 69 Hz peak in q1, about
40 % lower, the q2 peak almost gone; with the delayed term a new peak at
78 Hz.

This study runs the three cases over several stroke cycles (zero history:
the delayed term acts from the second pass on), at a converged step and at
the paper's own step h = 1.4e-3 s, and compares.  The average-acceleration
Newmark method maps an undamped mode of frequency f to

    f~ = atan(pi f h) / (pi h)                      (period elongation)

which at h = 1.4e-3 s puts the 76.28 Hz first mode at 73.6 Hz and the
83.34 Hz second one at 79.9 Hz.

Run: ``python studies/traverse_shaper/transients.py`` prints the tables and
writes ``docs/figures/transients_*.png``; ``tests/test_transients_study.py``
imports :func:`run` and checks the robust numbers.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

import chatterlab as cl
from chatterlab.time import Integration
from chatterlab.time._signals import amplitude_spectrum, peaks
from chatterlab.time._simulate import Simulation, simulate

HERE = Path(__file__).resolve().parent
MODEL = HERE / "model.toml"
FIGURES = HERE.parents[1] / "docs" / "figures"

#: the paper's integration step, s (Sec. 3)
PAPER_STEP = 1.4e-3
#: the converged step: the 76 Hz mode's period error (w h)^2/12 = 5e-5 (0.004 Hz); from
#: 5e-5 to 2.5e-5 s the peaks move by 0.01 Hz and the last-pass amplitudes by < 4 %
#: (by up to 20 % from 1e-4 s: the light damping keeps the ringing of earlier passes,
#: so their phase matters)
CONVERGED_STEP = 5.0e-5
#: the paper's discussion (Sec. 4): dominant peaks, Hz
PAPER_PEAKS = {"a": 74.0, "b": 69.0, "c": 78.0}
#: case -> (feedback terms, colour of Figs. 10-11, label)
CASES = {
    "a": ("none", "red", "(a) no feedback"),
    "b": ("pd", "green", "(b) proportional + ideal derivative"),
    "c": ("pdo", "blue", "(c) + delayed"),
}
OUTPUTS = ("rfe5.x", "rfe5.y")  # the paper's q1 = x51, q2 = x52


def warped(f_hz: np.ndarray | float, h: float) -> np.ndarray:
    """Frequency (Hz) at which the average-acceleration Newmark scheme with
    step h shows an undamped mode of frequency f: (2/h) atan(w h/2) / (2 pi)."""
    return np.arctan(np.pi * np.asarray(f_hz, float) * h) / (np.pi * h)


def passes_in_cut(sim: Simulation) -> list[slice]:
    """Index ranges of the record where the tool is in the cut, one per pass."""
    m = sim.in_cut
    starts = np.nonzero(m & ~np.concatenate([[False], m[:-1]]))[0]
    stops = np.nonzero(m & ~np.concatenate([m[1:], [False]]))[0] + 1
    return [slice(int(a), int(b)) for a, b in zip(starts, stops, strict=True)]


def pass_spectrum(sim: Simulation, name: str, sl: slice) -> tuple[np.ndarray, np.ndarray]:
    """Amplitude spectrum (Hz, m) of one pass in the cut (Hann, linear trend
    removed: the static deflection under the mean cutting force)."""
    return amplitude_spectrum(sim.t[sl], sim.data[name][sl])


def spectral_peaks(f: np.ndarray, a: np.ndarray, n: int = 4) -> list[tuple[float, float]]:
    """The n largest peaks above 20 Hz, (Hz, m), at least 2 Hz apart."""
    fp, ap = peaks(f, a, n, fmin=20.0, min_separation=2.0)
    return [(float(x), float(y)) for x, y in zip(fp, ap, strict=True)]


def near(pk: list[tuple[float, float]], lo: float, hi: float) -> tuple[float, float]:
    """The largest peak in [lo, hi] Hz, or (nan, 0)."""
    sel = [p for p in pk if lo <= p[0] <= hi]
    return max(sel, key=lambda p: p[1]) if sel else (math.nan, 0.0)


def run(
    *,
    passes: int = 3,
    width: float = 0.002,
    speed: float = 0.5,
    step: float = CONVERGED_STEP,
    paper_step: float | None = PAPER_STEP,
    growth_passes: int = 10,
    growth_step: float = 2.0e-4,
    keep: bool = True,
) -> dict[str, Any]:
    """Simulate the three cases and collect the study's numbers.

    Parameters
    ----------
    passes : int
        Stroke cycles of each run (T = 1.5 s each); the spectra are of the
        first and of the last pass in the cut (0.5 m at 0.5 m/s: 1 s, i.e.
        a 1 Hz resolution with a Hann window).
    width, speed : float
        Width of cut b (m) and work speed v_w (m/s): Table 3.
    step, paper_step : float
        The converged step and the paper's (None to skip the latter).
    growth_passes, growth_step : int, float
        A longer run of cases (b) and (c) for the pass-to-pass growth
        (0 to skip).
    keep : bool
        Keep the Simulation objects (for the figures).

    Returns
    -------
    dict with ``modes`` (the frozen structure's first natural frequencies),
    ``runs[step_label][case]`` (peaks of the first and last pass for q1 and
    q2, peak-to-peak per pass, the mean deflection, steps/s), ``warp`` (the
    predicted and measured shift at the paper's step), ``growth``.
    """
    system = cl.assemble(cl.load_model(MODEL))
    f_modes = cl.modes(system.at(None), count=4).frequency_hz
    steps = {"converged": step}
    if paper_step is not None:
        steps["paper"] = paper_step
    runs: dict[str, dict[str, Any]] = {}
    for label, h in steps.items():
        runs[label] = {}
        for case, (terms, _, _) in CASES.items():
            sim = simulate(
                system,
                feedback=terms,
                width=width,
                speed=speed,
                integration=Integration(periods=passes, step=h),
            )
            if sim.status != "ok":  # pragma: no cover - a diverged run is reported, not plotted
                raise RuntimeError(f"case {case} at h = {h}: {sim.message}")
            cuts = passes_in_cut(sim)
            entry: dict[str, Any] = {
                "h": h,
                "steps_per_s": sim.response.n_steps / max(sim.response.wall_time, 1e-12),
                "message": sim.message,
            }
            for name in OUTPUTS:
                for which, sl in (("first", cuts[0]), ("last", cuts[-1])):
                    f, a = pass_spectrum(sim, name, sl)
                    entry[(which, name)] = spectral_peaks(f, a)
                    band = f <= 300.0
                    entry[("spectrum", which, name)] = (f[band], a[band])
                x = sim.data[name]
                entry[("p2p", name)] = np.array([np.ptp(x[sl]) for sl in cuts])
                entry[("mean", name)] = float(np.mean(x[cuts[-1]]))
            if keep:
                entry["sim"] = sim
            runs[label][case] = entry
    out: dict[str, Any] = {"modes": f_modes, "runs": runs, "passes": passes, "width": width, "speed": speed}
    if paper_step is not None:
        # the step-induced shift: the converged peaks of case (a) mapped by the formula,
        # against the peaks measured at the paper's step
        rows = []
        for name, (lo, hi) in (("rfe5.x", (70.0, 80.0)), ("rfe5.y", (80.0, 90.0))):
            fc = near(runs["converged"]["a"][("last", name)], lo, hi)[0]
            pred = float(warped(fc, paper_step))
            meas = near(runs["paper"]["a"][("last", name)], pred - 2.0, pred + 2.0)[0]
            rows.append({"output": name, "converged": fc, "predicted": pred, "measured": meas})
        for k in range(2):
            rows.append(
                {
                    "output": f"mode {k + 1}",
                    "converged": float(f_modes[k]),
                    "predicted": float(warped(f_modes[k], paper_step)),
                    "measured": math.nan,
                }
            )
        out["warp"] = rows
    if growth_passes:
        g = {}
        for case in ("b", "c"):
            sim = simulate(
                system,
                feedback=CASES[case][0],
                width=width,
                speed=speed,
                integration=Integration(periods=growth_passes, step=growth_step),
            )
            cuts = passes_in_cut(sim)
            g[case] = {name: np.array([np.ptp(sim.data[name][sl]) for sl in cuts]) for name in OUTPUTS}
        cuts = passes_in_cut(sim)
        g["c_last_peaks"] = {
            name: spectral_peaks(*pass_spectrum(sim, name, cuts[-1]), n=3) for name in OUTPUTS
        }
        pp = g["c"]["rfe5.y"]
        ratio = pp[-3:] / pp[-4:-1]
        g["ratio_per_pass"] = float(np.exp(np.mean(np.log(ratio))))
        g["rate"] = math.log(g["ratio_per_pass"]) / (sim.delay)
        out["growth"] = g
    return out


def report(r: dict[str, Any]) -> str:
    """The tables printed by the script (and quoted in docs/time-domain.md)."""
    lines = [
        f"traverse shaper, b = {r['width'] * 1e3:g} mm, v_w = {r['speed']:g} m/s, {r['passes']} passes "
        "(zero history), spectra of one pass in the cut (Hann, 1 s)",
        "frozen structure (s = 0.85 m): " + ", ".join(f"{f:.2f}" for f in r["modes"]) + " Hz",
    ]
    for label, rr in r["runs"].items():
        h = next(iter(rr.values()))["h"]
        lines.append(f"\nstep h = {h:g} s ({label}); peaks above 20 Hz: Hz (amplitude um)")
        lines.append(f"  {'case':28s} {'pass':5s} {'q1 = rfe5.x':34s} {'q2 = rfe5.y':34s}")
        for case, e in rr.items():
            for which in ("first", "last"):
                cells = []
                for name in OUTPUTS:
                    pk = e[(which, name)][:3]
                    cells.append(", ".join(f"{f:6.2f} ({a * 1e6:5.2f})" for f, a in pk))
                lines.append(f"  {CASES[case][2]:28s} {which:5s} {cells[0]:34s} {cells[1]:34s}")
            pp = e[("p2p", "rfe5.x")] * 1e6
            lines.append(
                f"  {'':28s} peak-to-peak q1 per pass: " + ", ".join(f"{x:.1f}" for x in pp) + " um; "
                f"{e['steps_per_s']:.0f} steps/s"
            )
    if "warp" in r:
        lines.append(f"\nstep-induced shift at h = {PAPER_STEP:g} s: f~ = atan(pi f h)/(pi h)")
        for w in r["warp"]:
            meas = "" if math.isnan(w["measured"]) else f", measured {w['measured']:.2f} Hz"
            lines.append(
                f"  {w['output']:8s}: {w['converged']:.2f} Hz -> predicted {w['predicted']:.2f} Hz{meas}"
            )
    lines.append("\ncomparison with the paper's discussion (see summarize()):")
    lines.extend(comparison(r))
    if "growth" in r:
        g = r["growth"]
        lines.append(
            "\ngrowth over the passes, peak-to-peak q2 (um): (b) "
            + ", ".join(f"{x * 1e6:.0f}" for x in g["b"]["rfe5.y"])
            + "\n                                            (c) "
            + ", ".join(f"{x * 1e6:.0f}" for x in g["c"]["rfe5.y"])
            + f"\n  case (c): x{g['ratio_per_pass']:.2f} per pass (sigma = {g['rate']:+.3f} 1/s): "
            "regenerative chatter at b = 2 mm; last pass peaks q1 "
            + ", ".join(f"{f:.2f} Hz" for f, _ in g["c_last_peaks"]["rfe5.x"])
            + "; q2 "
            + ", ".join(f"{f:.2f} Hz" for f, _ in g["c_last_peaks"]["rfe5.y"])
        )
    return "\n".join(lines)


def summarize(rr: dict[str, Any]) -> dict[str, Any]:
    """The numbers the paper's discussion is about, for one step.

    * (a): the dominant peaks of q1 and q2 in the first pass (the response
      to the force switched on at the cut entry, from rest);
    * (b) against (a), first pass: the dominant q1 peak, its amplitude
      relative to (a)'s dominant q1 peak, and what is left of (a)'s dominant
      q2 peak (the largest (b) peak within 2 Hz of it);
    * (c) against (b), last pass (the delayed term acts from the second
      pass): for q1 and q2, among the three largest peaks of (c) in
      60-100 Hz, the one that grew most relative to the spectrum of (b) at
      the same frequency: (Hz, amplitude m, growth factor).
    """
    a, b, c = rr["a"], rr["b"], rr["c"]
    ax, ay = a[("first", "rfe5.x")][0], a[("first", "rfe5.y")][0]
    bx = b[("first", "rfe5.x")][0]
    by = near(b[("first", "rfe5.y")], ay[0] - 2.0, ay[0] + 2.0)
    out: dict[str, Any] = {
        "h": a["h"],
        "a_q1": ax,
        "a_q2": ay,
        "b_q1": bx,
        "b_q1_change": bx[1] / ax[1] - 1.0,
        "b_q2_left": by,
        "b_q2_change": by[1] / ay[1] - 1.0,
    }
    for name, key in (("rfe5.x", "c_q1"), ("rfe5.y", "c_q2")):
        fc, ac = c[("spectrum", "last", name)]
        fb, ab = b[("spectrum", "last", name)]
        fp, apk = peaks(fc, ac, 3, fmin=60.0, min_separation=2.0)
        fp, apk = fp[fp <= 100.0], apk[fp <= 100.0]
        grow = apk / np.interp(fp, fb, ab)
        k = int(np.argmax(grow))
        out[key] = (float(fp[k]), float(apk[k]), float(grow[k]))
    return out


def comparison(r: dict[str, Any]) -> list[str]:
    out = []
    for rr in r["runs"].values():
        sm = summarize(rr)
        out.append(
            f"  h = {sm['h']:g} s: (a) {sm['a_q1'][0]:.1f} / {sm['a_q2'][0]:.1f} Hz [paper 74 / 74 Hz];"
            f" (b) q1 {sm['b_q1'][0]:.1f} Hz, {100 * sm['b_q1_change']:+.0f} %, q2 peak {100 * sm['b_q2_change']:+.0f} %"
            f" [paper 69 Hz, -40 %, q2 almost gone]; (c) grows most at {sm['c_q1'][0]:.1f} Hz (q1, x{sm['c_q1'][2]:.1f})"
            f" and {sm['c_q2'][0]:.1f} Hz (q2, x{sm['c_q2'][2]:.1f}) [paper new peak 78 Hz]"
        )
    return out


def plot(r: dict[str, Any], outdir: Path = FIGURES) -> list[Path]:
    """Figs. 4-9 (time plots), 10-11 (spectra), the step comparison and the
    pass-to-pass growth; returns the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    outdir.mkdir(parents=True, exist_ok=True)
    written = []
    conv = r["runs"]["converged"]
    paper = r["runs"].get("paper")
    for name, q, figs in (("rfe5.x", "q1 = x51", "Figs. 4-6"), ("rfe5.y", "q2 = x52", "Figs. 7-9")):
        fig, axs = plt.subplots(3, 1, sharex=True, figsize=(8.0, 7.0))
        for ax, (case, (_, color, lab)) in zip(axs, CASES.items(), strict=True):
            sim = conv[case]["sim"]
            cuts = passes_in_cut(sim)
            for k, sl in enumerate(cuts):
                last = k == len(cuts) - 1
                ax.plot(
                    sim.cut_distance[sl],
                    sim.data[name][sl] * 1e6,
                    color=color if last else "0.6",
                    lw=0.8 if last else 0.5,
                    label=f"pass {k + 1}" if (last or k == 0) else None,
                )
            ax.set_ylabel(f"{q} [um]")
            ax.set_title(lab, fontsize=9, loc="left")
            ax.legend(fontsize=7, loc="lower right")
        axs[-1].set_xlabel("distance of cutting s [m]")
        fig.suptitle(
            f"traverse shaper, {q} ({name}) vs distance of cutting ({figs}); b = 2 mm, v_w = 0.5 m/s, "
            f"h = {conv['a']['h']:g} s",
            fontsize=9,
        )
        fig.tight_layout()
        p = outdir / f"transients_time_{name[-1]}.png"
        fig.savefig(p, dpi=120)
        plt.close(fig)
        written.append(p)
    for name, q, figno in (("rfe5.x", "q1 = x51", "Fig. 10"), ("rfe5.y", "q2 = x52", "Fig. 11")):
        rows = [("converged", conv)] + ([("paper", paper)] if paper is not None else [])
        fig, axs = plt.subplots(len(rows), 1, figsize=(8.0, 3.2 * len(rows)), squeeze=False)
        for ax, (label, rr) in zip(axs[:, 0], rows, strict=True):
            for case, (_, color, lab) in CASES.items():
                sim = rr[case]["sim"]
                f, a = pass_spectrum(sim, name, passes_in_cut(sim)[-1])
                ax.plot(f, a * 1e6, color=color, lw=0.9, label=lab)
            for cse, fp in PAPER_PEAKS.items():
                ax.axvline(fp, color=CASES[cse][1], ls=":", lw=0.8)
            ax.set_xlim(40, 160)
            ax.set_ylabel(f"|{q}| [um]")
            ax.set_title(
                f"h = {rr['a']['h']:g} s ({label}); dotted: the paper's 74 / 69 / 78 Hz",
                fontsize=9,
                loc="left",
            )
            ax.legend(fontsize=7)
        axs[-1, 0].set_xlabel("frequency [Hz]")
        fig.suptitle(f"spectrum of {q} ({name}), last pass in the cut ({figno})", fontsize=9)
        fig.tight_layout()
        p = outdir / f"transients_spectrum_{name[-1]}.png"
        fig.savefig(p, dpi=120)
        plt.close(fig)
        written.append(p)
    if paper is not None:
        fig, axs = plt.subplots(1, 2, figsize=(9.0, 3.4))
        for ax, name in zip(axs, OUTPUTS, strict=True):
            for rr, color in ((conv, "k"), (paper, "tab:orange")):
                sim = rr["a"]["sim"]
                f, a = pass_spectrum(sim, name, passes_in_cut(sim)[0])
                ax.plot(f, a * 1e6, color=color, lw=0.9, label=f"h = {rr['a']['h']:g} s")
            for k, fm in enumerate(r["modes"][:2]):
                ax.axvline(fm, color="k", ls=":", lw=0.7)
                ax.axvline(float(warped(fm, PAPER_STEP)), color="tab:orange", ls="--", lw=0.7)
                ax.annotate(
                    f"{fm:.1f}->{float(warped(fm, PAPER_STEP)):.1f}",
                    (float(warped(fm, PAPER_STEP)), 0),
                    xytext=(2, 4 + 12 * k),
                    textcoords="offset points",
                    fontsize=7,
                )
            ax.set_xlim(60, 95)
            ax.set_xlabel("frequency [Hz]")
            ax.set_title(f"case (a), {name}, first pass", fontsize=9)
            ax.legend(fontsize=7)
        axs[0].set_ylabel("amplitude [um]")
        fig.suptitle("the paper's step moves the modes: f~ = atan(pi f h)/(pi h) (dashed)", fontsize=9)
        fig.tight_layout()
        p = outdir / "transients_step.png"
        fig.savefig(p, dpi=120)
        plt.close(fig)
        written.append(p)
    if "growth" in r:
        g = r["growth"]
        fig, ax = plt.subplots(figsize=(6.0, 3.4))
        for case in ("b", "c"):
            for name, mk in zip(OUTPUTS, ("o", "s"), strict=True):
                y = g[case][name] * 1e6
                ax.semilogy(
                    np.arange(1, y.size + 1), y, marker=mk, color=CASES[case][1], label=f"({case}) {name}"
                )
        ax.set_xlabel("pass")
        ax.set_ylabel("peak-to-peak in the cut [um]")
        ax.set_title(
            f"regeneration: case (c) grows x{g['ratio_per_pass']:.2f} per pass at b = 2 mm", fontsize=9
        )
        ax.legend(fontsize=7)
        fig.tight_layout()
        p = outdir / "transients_growth.png"
        fig.savefig(p, dpi=120)
        plt.close(fig)
        written.append(p)
    return written


if __name__ == "__main__":
    res = run()
    print(report(res))
    for path in plot(res):
        print(f"wrote {path}")
