"""Design against chatter (issue 23): exact sensitivities of the stability
limit to any model field (``_sensitivity``, on the critical point of
``_critical`` and the matrix derivatives of ``_matrices``), tuned vibration
absorbers (``_absorber``), and active dampers with the paper's feedback
(``_active``: the co-design; ``_controlled``: the machine with its
actuators, its exact-delay roots and its lobes; ``_receptance``: the
receptance the cut sees), the min-max of both on ``_epigraph``."""

from __future__ import annotations

from ._absorber import (
    AbsorberDesign,
    den_hartog_tuning,
    real_part_tuning,
    tune_absorbers,
    with_absorber,
    without_absorbers,
)
from ._active import (
    ActiveDesign,
    Margins,
    confirm_active,
    design_active,
    force_required,
    loop_margins,
    with_actuator,
    without_actuators,
)
from ._confirm import ActiveConfirmation
from ._controlled import ControllerUnstable, controller_roots, design_lobes
from ._critical import CriticalPoint
from ._fields import design_fields, field_affinity, field_unit, field_value
from ._limits import Limits, branch_bottoms, limits_of, lobe_bottoms
from ._matrices import FieldDerivative, LoopMatrices, field_derivative, loop_matrices
from ._sensitivity import Sensitivity, sensitivity

__all__ = [
    "design_active",
    "ActiveDesign",
    "confirm_active",
    "ActiveConfirmation",
    "with_actuator",
    "without_actuators",
    "design_lobes",
    "controller_roots",
    "ControllerUnstable",
    "loop_margins",
    "Margins",
    "force_required",
    "branch_bottoms",
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
