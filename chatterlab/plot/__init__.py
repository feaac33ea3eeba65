"""Every matplotlib line of chatterlab: plots take result objects (or plain
arrays), accept ``ax=`` and return the Axes they drew on (a tuple of Axes for
a multi-panel plot; each docstring says which).  matplotlib is imported
inside the functions, so importing this package is light.

One module per subject: ``_lobes`` (with ``_lobe_panel``; the geometry it
draws is the diagram's own, :meth:`chatterlab.lobes.LobeDiagram.geometry`;
``_milling`` for a diagram of Floquet limits), ``_atlas``, ``_frf`` (FRF, Nyquist of the determinant and
of the loop), ``_fit`` (a modal fit, its stabilisation diagram), ``_time`` (histories, spectra, one run's response), ``_modes``
(mode shapes on the structure, frequencies), ``_sweep`` (any output, the
stability map), ``_design`` (sensitivities, lobes before and after), ``_uncertainty``
(probabilistic lobes, Sobol' indices), ``_recommend`` (the speeds to choose, a
recording's spectrum), ``_style`` (the ``ax=`` keyword, ``savefig``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_names

if TYPE_CHECKING:  # what type checkers and the API reference see; at run time, on first use
    from ._atlas import plot_atlas
    from ._design import plot_lobes_compare, plot_sensitivity
    from ._fit import plot_modal_fit, plot_stabilisation
    from ._frf import plot_frf, plot_loop_nyquist, plot_nyquist, touching_width, track_loci
    from ._lobes import plot_lobes
    from ._modes import plot_frequencies, plot_mode_shapes
    from ._recommend import plot_chatter_spectrum, plot_recommendation, plot_speed_rule
    from ._roots import plot_multipliers, plot_roots
    from ._sle import plot_sle
    from ._ssv import plot_ssv
    from ._style import headless, new_figure, savefig
    from ._sweep import plot_stability_map, plot_sweep
    from ._time import plot_cases, plot_histories, plot_outputs, plot_spectra, plot_time_response
    from ._uncertainty import plot_risk, plot_sobol

#: public name -> the module that holds it, imported on first use (PEP 562): a command
#: that needs one module of chatterlab.plot does not load the others
_HOME = {
    "plot_atlas": "_atlas",
    **dict.fromkeys(
        (
            "plot_lobes_compare",
            "plot_sensitivity",
        ),
        "_design",
    ),
    **dict.fromkeys(
        (
            "plot_modal_fit",
            "plot_stabilisation",
        ),
        "_fit",
    ),
    **dict.fromkeys(
        (
            "plot_frf",
            "plot_loop_nyquist",
            "plot_nyquist",
            "touching_width",
            "track_loci",
        ),
        "_frf",
    ),
    "plot_lobes": "_lobes",
    **dict.fromkeys(
        (
            "plot_frequencies",
            "plot_mode_shapes",
        ),
        "_modes",
    ),
    **dict.fromkeys(
        (
            "plot_chatter_spectrum",
            "plot_recommendation",
            "plot_speed_rule",
        ),
        "_recommend",
    ),
    **dict.fromkeys(
        (
            "plot_multipliers",
            "plot_roots",
        ),
        "_roots",
    ),
    "plot_sle": "_sle",
    "plot_ssv": "_ssv",
    **dict.fromkeys(("headless", "new_figure", "savefig"), "_style"),
    **dict.fromkeys(
        (
            "plot_stability_map",
            "plot_sweep",
        ),
        "_sweep",
    ),
    **dict.fromkeys(
        (
            "plot_cases",
            "plot_histories",
            "plot_outputs",
            "plot_spectra",
            "plot_time_response",
        ),
        "_time",
    ),
    **dict.fromkeys(
        (
            "plot_risk",
            "plot_sobol",
        ),
        "_uncertainty",
    ),
}


__getattr__, __dir__ = lazy_names(__name__, _HOME)


__all__ = [
    "plot_frf",
    "plot_modal_fit",
    "plot_stabilisation",
    "plot_nyquist",
    "plot_loop_nyquist",
    "touching_width",
    "track_loci",
    "plot_lobes",
    "plot_lobes_compare",
    "plot_sensitivity",
    "plot_atlas",
    "plot_histories",
    "plot_cases",
    "plot_spectra",
    "plot_time_response",
    "plot_outputs",
    "plot_mode_shapes",
    "plot_roots",
    "plot_multipliers",
    "plot_frequencies",
    "plot_sweep",
    "plot_stability_map",
    "plot_risk",
    "plot_sobol",
    "plot_recommendation",
    "plot_chatter_spectrum",
    "plot_speed_rule",
    "savefig",
    "headless",
    "new_figure",
    "plot_ssv",
    "plot_sle",
]
