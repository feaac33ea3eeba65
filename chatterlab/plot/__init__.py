"""Every matplotlib line of chatterlab: plots take result objects (or plain
arrays), accept ``ax=`` and return the Axes they drew on (a tuple of Axes for
a multi-panel plot; each docstring says which).  matplotlib is imported
inside the functions, so importing this package is light.

One module per subject: ``_lobes`` (with ``_lobe_panel`` and the geometry in
``_envelope``), ``_atlas``, ``_frf`` (FRF, Nyquist), ``_time`` (histories,
spectra), ``_style`` (the ``ax=`` keyword, ``savefig``)."""

from __future__ import annotations

from ._atlas import plot_atlas
from ._frf import plot_frf, plot_nyquist
from ._lobes import plot_lobes
from ._style import savefig
from ._time import plot_histories, plot_spectra

__all__ = [
    "plot_frf",
    "plot_nyquist",
    "plot_lobes",
    "plot_atlas",
    "plot_histories",
    "plot_spectra",
    "savefig",
]
