"""Design against chatter (issue 23): exact sensitivities of the stability
limit to any model field (``_sensitivity``, on the critical point of
``_critical`` and the matrix derivatives of ``_matrices``), and tuned
vibration absorbers (``_absorber``)."""

from __future__ import annotations

from ._absorber import (
    AbsorberDesign,
    den_hartog_tuning,
    real_part_tuning,
    tune_absorbers,
    with_absorber,
    without_absorbers,
)
from ._critical import CriticalPoint
from ._fields import design_fields, field_affinity, field_unit, field_value
from ._limits import Limits, limits_of, lobe_bottoms
from ._matrices import FieldDerivative, LoopMatrices, field_derivative, loop_matrices
from ._sensitivity import Sensitivity, sensitivity

__all__ = [
    "tune_absorbers",
    "AbsorberDesign",
    "with_absorber",
    "without_absorbers",
    "den_hartog_tuning",
    "real_part_tuning",
    "sensitivity",
    "Sensitivity",
    "CriticalPoint",
    "Limits",
    "limits_of",
    "lobe_bottoms",
    "LoopMatrices",
    "FieldDerivative",
    "loop_matrices",
    "field_derivative",
    "design_fields",
    "field_value",
    "field_unit",
    "field_affinity",
]
