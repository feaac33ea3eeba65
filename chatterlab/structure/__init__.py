"""Model -> System: RDFEM elements, assembly, the constraints W(s) of the
moving slide, the frozen configuration, real and complex modes; the
structure's response (:class:`FRF`, modelled or measured), its modal fit
and receptance coupling."""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_names

if TYPE_CHECKING:  # what type checkers and the API reference see; at run time, on first use
    from ._assembly import CouplingMatrices, FrozenSystem, System, assemble
    from ._complex import ComplexModes, complex_modes, dynamic_receptance, modal_response, taylor_terms
    from ._elements import (
        beam_local_mass,
        beam_local_stiffness,
        beam_matrices,
        beam_point_matrix,
        beam_rotation,
        beam_shape,
        rigid_point_matrix,
        rotation3,
    )
    from ._fit import FitQuality, ModalFit, Stabilisation, fit_modes
    from ._frf import FRF
    from ._modal import Modes, modes, rigid_body_description
    from ._rcsa import (
        Joint,
        JointFit,
        couple,
        couple_tool,
        identify_joint,
        receptance,
        rotations_from_translations,
        tool_model,
    )
    from ._structure import Structure

#: public name -> the module that holds it, imported on first use (PEP 562): a command
#: that needs one module of chatterlab.structure does not load the others
_HOME = {
    **dict.fromkeys(
        (
            "CouplingMatrices",
            "FrozenSystem",
            "System",
            "assemble",
        ),
        "_assembly",
    ),
    **dict.fromkeys(
        (
            "ComplexModes",
            "complex_modes",
            "dynamic_receptance",
            "modal_response",
            "taylor_terms",
        ),
        "_complex",
    ),
    **dict.fromkeys(
        (
            "beam_local_mass",
            "beam_local_stiffness",
            "beam_matrices",
            "beam_point_matrix",
            "beam_rotation",
            "beam_shape",
            "rigid_point_matrix",
            "rotation3",
        ),
        "_elements",
    ),
    **dict.fromkeys(
        (
            "FitQuality",
            "ModalFit",
            "Stabilisation",
            "fit_modes",
        ),
        "_fit",
    ),
    "FRF": "_frf",
    **dict.fromkeys(
        (
            "Modes",
            "modes",
            "rigid_body_description",
        ),
        "_modal",
    ),
    **dict.fromkeys(
        (
            "Joint",
            "JointFit",
            "couple",
            "couple_tool",
            "identify_joint",
            "receptance",
            "rotations_from_translations",
            "tool_model",
        ),
        "_rcsa",
    ),
    "Structure": "_structure",
}


__getattr__, __dir__ = lazy_names(__name__, _HOME)


__all__ = [
    "beam_local_stiffness",
    "beam_local_mass",
    "beam_shape",
    "beam_rotation",
    "beam_matrices",
    "beam_point_matrix",
    "rigid_point_matrix",
    "rotation3",
    "ComplexModes",
    "complex_modes",
    "dynamic_receptance",
    "modal_response",
    "taylor_terms",
    "Structure",
    "System",
    "FrozenSystem",
    "CouplingMatrices",
    "assemble",
    "Modes",
    "modes",
    "rigid_body_description",
    "fit_modes",
    "ModalFit",
    "FitQuality",
    "Stabilisation",
    "Joint",
    "JointFit",
    "couple",
    "couple_tool",
    "identify_joint",
    "receptance",
    "rotations_from_translations",
    "tool_model",
    "FRF",
]
