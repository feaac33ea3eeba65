"""Characteristic roots in the complex plane and Floquet multipliers on the
unit circle: where stability is decided."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["plot_roots", "plot_multipliers"]


def plot_roots(roots: Any, *, ax: Any = None, title: str | None = None, **style: Any) -> Any:
    """The rightmost characteristic roots (a ``RootsResult`` or a
    ``Stability``'s): real part (1/s) against frequency Im/2pi (Hz), the
    imaginary axis (the stability boundary) drawn, roots right of it red.
    Returns the Axes."""
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(7.0, 4.5))
    lam = np.asarray(roots.roots, dtype=complex)
    f = lam.imag / (2 * np.pi)
    ax.axvline(0.0, color="0.3", lw=1.0, label="imaginary axis (stability boundary)")
    unstable = lam.real > 0
    kw = {"ls": "none", "marker": "x", "ms": 7, **style}
    if np.any(~unstable):
        ax.plot(lam.real[~unstable], f[~unstable], color="tab:blue", label="stable roots", **kw)
    if np.any(unstable):
        ax.plot(lam.real[unstable], f[unstable], color="tab:red", label="roots right of the axis", **kw)
    ax.set_xlabel("real part Re λ [1/s]")
    ax.set_ylabel("frequency Im λ / 2π [Hz]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    if title:
        ax.set_title(title, fontsize=10)
    return ax


def plot_multipliers(m: Any, *, ax: Any = None, title: str | None = None, **style: Any) -> Any:
    """Floquet multipliers (a ``Multipliers``) in the complex plane with the
    unit circle (|mu| = 1: the stability boundary), the critical one marked
    with its type.  Returns the Axes."""
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(5.5, 5.5))
    t = np.linspace(0.0, 2 * np.pi, 361)
    ax.plot(np.cos(t), np.sin(t), color="0.3", lw=1.0, label="unit circle |μ| = 1")
    mu = np.asarray(m.mu, dtype=complex)
    kw = {"ls": "none", "marker": "x", "ms": 6, **style}
    ax.plot(mu.real, mu.imag, color="tab:blue", label="multipliers", **kw)
    c = complex(m.critical)
    ax.plot([c.real], [c.imag], ls="none", marker="o", mfc="none", ms=11, color="tab:red",
            label=f"critical: |μ| = {abs(c):.6f} ({m.kind})")  # fmt: skip
    r = max(1.05, float(np.max(np.abs(mu), initial=1.0)) * 1.05)
    ax.set_xlim(-r, r)
    ax.set_ylim(-r, r)
    ax.set_aspect("equal")
    ax.set_xlabel("Re μ")
    ax.set_ylabel("Im μ")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")
    if title:
        ax.set_title(title, fontsize=10)
    return ax
