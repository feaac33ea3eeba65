"""Every matplotlib line of chatterlab: plots take result objects, accept
``axes=`` and return the Axes.  Importing this package imports matplotlib."""

from __future__ import annotations

from ._plot import plot_atlas, plot_frf, plot_histories, plot_lobes, plot_nyquist, plot_spectra, savefig

__all__ = [
    "plot_frf",
    "plot_nyquist",
    "plot_lobes",
    "plot_atlas",
    "plot_histories",
    "plot_spectra",
    "savefig",
]
