"""Frequency domain: open- and closed-loop FRFs, characteristic roots of the
delay equation, the argument-principle count, the stability verdict and the
gain bounds that prove a searched band complete."""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_names

if TYPE_CHECKING:  # what type checkers and the API reference see; at run time, on first use
    from ._bounds import Band, PoleResidue, certified_band
    from ._floquet import (
        CHECK_DEGREE,
        DEGREE,
        ELEMENT_SPAN,
        Multipliers,
        SpectralMonodromy,
        chatter_frequency,
        classify,
        multipliers,
        sdm_monodromy,
    )
    from ._floquet_spectral import QuasiStatic, split_structure
    from ._floquet_ssv import ssv_monodromy, ssv_multipliers
    from ._floquet_ssv_limit import SsvLimits, SsvLimitTask, ssv_limit, ssv_limits, ssv_limits_at
    from ._forced import (
        ForcedResponse,
        RunoutResponse,
        SurfaceLocation,
        forced_response,
        generation_angle,
        runout_response,
        surface_location,
    )
    from ._frf import (
        FRF,
        ComplexModes,
        complex_modes,
        frequencies,
        frf,
        loop_determinant,
        loop_eigenvalues,
        resonance_grid,
    )
    from ._roots import (
        AXIS_GRID_MAX,
        WINDOW_MAX,
        DelaySystem,
        RootsResult,
        certified_top,
        characteristic_roots,
        chebyshev_nodes,
        loop_system,
        make_first_order_system,
        make_system,
        newton_refine,
    )
    from ._stability import MARGINAL_TOL, Stability, loop_band, stability
    from ._winding import WindingResult, rhp_count

#: public name -> the module that holds it, imported on first use (PEP 562): a command
#: that needs one module of chatterlab.frequency does not load the others
_HOME = {
    **dict.fromkeys(
        (
            "Band",
            "PoleResidue",
            "certified_band",
        ),
        "_bounds",
    ),
    **dict.fromkeys(
        (
            "CHECK_DEGREE",
            "DEGREE",
            "ELEMENT_SPAN",
            "Multipliers",
            "SpectralMonodromy",
            "chatter_frequency",
            "classify",
            "multipliers",
            "sdm_monodromy",
        ),
        "_floquet",
    ),
    **dict.fromkeys(
        (
            "QuasiStatic",
            "split_structure",
        ),
        "_floquet_spectral",
    ),
    **dict.fromkeys(
        (
            "ssv_monodromy",
            "ssv_multipliers",
        ),
        "_floquet_ssv",
    ),
    **dict.fromkeys(
        (
            "SsvLimits",
            "SsvLimitTask",
            "ssv_limit",
            "ssv_limits",
            "ssv_limits_at",
        ),
        "_floquet_ssv_limit",
    ),
    **dict.fromkeys(
        (
            "ForcedResponse",
            "RunoutResponse",
            "SurfaceLocation",
            "forced_response",
            "generation_angle",
            "runout_response",
            "surface_location",
        ),
        "_forced",
    ),
    **dict.fromkeys(
        (
            "FRF",
            "ComplexModes",
            "complex_modes",
            "frequencies",
            "frf",
            "loop_determinant",
            "loop_eigenvalues",
            "resonance_grid",
        ),
        "_frf",
    ),
    **dict.fromkeys(
        (
            "AXIS_GRID_MAX",
            "WINDOW_MAX",
            "DelaySystem",
            "RootsResult",
            "certified_top",
            "characteristic_roots",
            "chebyshev_nodes",
            "loop_system",
            "make_first_order_system",
            "make_system",
            "newton_refine",
        ),
        "_roots",
    ),
    **dict.fromkeys(
        (
            "MARGINAL_TOL",
            "Stability",
            "loop_band",
            "stability",
        ),
        "_stability",
    ),
    **dict.fromkeys(
        (
            "WindingResult",
            "rhp_count",
        ),
        "_winding",
    ),
}


__getattr__, __dir__ = lazy_names(__name__, _HOME)


__all__ = [
    "QuasiStatic",
    "split_structure",
    "Band",
    "PoleResidue",
    "certified_band",
    "FRF",
    "frf",
    "frequencies",
    "loop_determinant",
    "loop_eigenvalues",
    "resonance_grid",
    "ComplexModes",
    "complex_modes",
    "RootsResult",
    "DelaySystem",
    "make_system",
    "make_first_order_system",
    "loop_system",
    "characteristic_roots",
    "newton_refine",
    "chebyshev_nodes",
    "WindingResult",
    "rhp_count",
    "Stability",
    "stability",
    "loop_band",
    "certified_top",
    "AXIS_GRID_MAX",
    "WINDOW_MAX",
    "MARGINAL_TOL",
    "Multipliers",
    "multipliers",
    "SpectralMonodromy",
    "sdm_monodromy",
    "ssv_multipliers",
    "ssv_monodromy",
    "ssv_limit",
    "ssv_limits",
    "ssv_limits_at",
    "SsvLimits",
    "SsvLimitTask",
    "classify",
    "chatter_frequency",
    "CHECK_DEGREE",
    "DEGREE",
    "ELEMENT_SPAN",
    "ForcedResponse",
    "SurfaceLocation",
    "RunoutResponse",
    "forced_response",
    "surface_location",
    "runout_response",
    "generation_angle",
]
