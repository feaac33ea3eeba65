"""Frequency domain: open- and closed-loop FRFs, characteristic roots of the
delay equation, the argument-principle count, the stability verdict and the
gain bounds that prove a searched band complete."""

from __future__ import annotations

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
from ._floquet_ssv import ssv_monodromy, ssv_multipliers
from ._floquet_ssv_limit import SsvLimits, SsvLimitTask, ssv_limit, ssv_limits
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

__all__ = [
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
