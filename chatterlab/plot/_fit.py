"""The modal fit of a measured FRF: the measured and fitted entry
(:func:`plot_modal_fit`) and the stabilisation diagram
(:func:`plot_stabilisation`).  They take the result objects of
:func:`chatterlab.structure.fit_modes` (duck-typed: plot knows nothing of
the analyses)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ._style import index_of


def plot_modal_fit(fit: Any, *, output: int | str = 0, input: int | str = 0, ax: Any = None) -> Any:
    """Measured and fitted magnitude and phase of one entry of a
    ``ModalFit`` against frequency (Hz), the fitted natural frequencies
    marked, on ``ax`` (a pair of Axes: magnitude, phase; default new);
    returns the pair."""
    import matplotlib.pyplot as plt

    o, i = index_of(fit.outputs, output), index_of(fit.inputs, input)
    if ax is None:
        _, ax = plt.subplots(2, 1, sharex=True, figsize=(8, 6), gridspec_kw={"height_ratios": [2, 1]})
    ax_m, ax_p = ax
    f = fit.omega / (2 * np.pi)
    Hf = fit.frf(fit.omega).data[o, i]
    Hm = fit.measured.data[o, i]
    ax_m.semilogy(f, np.abs(Hm), ".", ms=2, color="0.5", label="measured")
    ax_m.semilogy(f, np.abs(Hf), "-", color="tab:red", lw=1.2, label=f"fit ({fit.n_modes} modes)")
    ax_p.plot(f, np.degrees(np.angle(Hm)), ".", ms=2, color="0.5")
    ax_p.plot(f, np.degrees(np.angle(Hf)), "-", color="tab:red", lw=1.2)
    for fr in fit.frequency_hz:
        ax_m.axvline(fr, color="k", lw=0.6, ls=":")
    ax_m.set_ylabel(f"|{fit.outputs[o]} / {fit.inputs[i]}|  [m/N]")
    ax_p.set_ylabel("phase [deg]")
    ax_p.set_xlabel("frequency [Hz]")
    ax_m.legend(fontsize=8)
    ax_m.set_title(f"modal fit: error {100 * fit.quality.error:.2g} %, FRAC {fit.quality.frac[o, i]:.5f}")
    return ax


def plot_stabilisation(stab: Any, *, ax: Any = None, codes: tuple[int, int, int] = (0, 1, 2)) -> Any:
    """The stabilisation diagram of a ``Stabilisation``: the poles of every
    model order against frequency (Hz), marked new, stable in frequency, or
    stable in frequency and damping (``codes``: the status values of the
    three, as the fit numbers them), the chosen poles as dotted lines, over
    the measured magnitude; returns the Axes."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(8, 5))
    new, stable_f, stable = codes
    styles = {
        new: dict(marker="o", mfc="none", color="0.6", ms=4, label="new"),
        stable_f: dict(marker="d", mfc="none", color="tab:blue", ms=4, label="stable frequency"),
        stable: dict(marker="+", color="tab:red", ms=7, label="stable frequency and damping"),
    }
    for code, st in styles.items():
        f, o = [], []
        for p, lam, s in zip(stab.orders, stab.poles, stab.status, strict=True):
            sel = s == code
            f.extend(np.abs(lam[sel]) / (2 * np.pi))
            o.extend([p] * int(sel.sum()))
        ax.plot(f, o, ls="none", **st)
    for lam in stab.selected:
        ax.axvline(abs(lam) / (2 * np.pi), color="k", lw=0.8, ls=":")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("model order p")
    ax2 = ax.twinx()
    ax2.semilogy(stab.omega / (2 * np.pi), stab.magnitude, color="k", lw=0.8)
    ax2.set_ylabel("sum |H|  [m/N]")
    ax.set_xlim(stab.omega[0] / (2 * np.pi), stab.omega[-1] / (2 * np.pi))
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title(
        f"stabilisation: frequency {100 * stab.tol_frequency:g} %, damping {100 * stab.tol_damping:g} %"
    )
    return ax
