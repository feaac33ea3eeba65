"""The names of the former single plot module, kept for the callers that
import them from here (``from ..plot._plot import savefig``): the plots now
live in one module per subject (``_lobes``, ``_atlas``, ``_frf``, ``_time``,
...); import them from :mod:`chatterlab.plot`."""

from __future__ import annotations

from ._atlas import plot_atlas
from ._frf import plot_frf, plot_nyquist
from ._lobes import plot_lobes
from ._style import LAID_OUT, savefig
from ._time import plot_histories, plot_spectra

__all__ = [
    "plot_frf",
    "plot_nyquist",
    "plot_lobes",
    "plot_atlas",
    "plot_histories",
    "plot_spectra",
    "savefig",
    "LAID_OUT",
]
