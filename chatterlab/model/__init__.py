"""Model files -> :class:`Model`: the immutable machine description.

``_items``: the frozen dataclasses (bodies, beams, springs, couplings, the
process, ...); ``_reader``: the TOML reader (file, limits, variants and
parameter paths, :func:`build_model`), with one reader per table in
``_tables`` (structural tables), ``_points`` (points, springs, couplings,
the process) and ``_matrices`` ([matrices] and its files), on the typed
field access of ``_fields`` -- every problem one
:class:`~chatterlab.errors.ModelError` line; ``_geometry``: point positions
and the geometric checks.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_names

if TYPE_CHECKING:  # what type checkers and the API reference see; at run time, on first use
    from ._absorber import Absorber
    from ._geometry import (
        TrackPosition,
        body_centre,
        check_geometry,
        contact_track_position,
        is_movable,
        point_xy,
    )
    from ._items import (
        DIRECTIONS,
        GROUND,
        Attachment,
        Beam,
        Body,
        Constraint,
        Contact,
        Coupling,
        Machine,
        MatrixBlock,
        Mode,
        Model,
        Movable,
        Node,
        Point,
        PointRef,
        Process,
        Section,
        SpindleSpeedVariation,
        Spring,
        Support,
        machine_problem,
        spindle_speed_for,
        stroke_cycle,
        stroke_speed,
        tooth_period,
    )
    from ._reader import build_model, load_model, loads_model
    from ._uncertainty import (
        CorrelatedGroup,
        Marginal,
        UncertaintyTable,
        parameter_overrides,
        parameter_value,
        uncertainty_of,
    )

#: public name -> the module that holds it, imported on first use (PEP 562): a command
#: that needs one module of chatterlab.model does not load the others
_HOME = {
    "Absorber": "_absorber",
    **dict.fromkeys(
        (
            "TrackPosition",
            "body_centre",
            "check_geometry",
            "contact_track_position",
            "is_movable",
            "point_xy",
        ),
        "_geometry",
    ),
    **dict.fromkeys(
        (
            "DIRECTIONS",
            "GROUND",
            "Attachment",
            "Beam",
            "Body",
            "Constraint",
            "Contact",
            "Coupling",
            "Machine",
            "MatrixBlock",
            "Mode",
            "Model",
            "Movable",
            "Node",
            "Point",
            "PointRef",
            "Process",
            "Section",
            "SpindleSpeedVariation",
            "Spring",
            "Support",
            "machine_problem",
            "spindle_speed_for",
            "stroke_cycle",
            "stroke_speed",
            "tooth_period",
        ),
        "_items",
    ),
    **dict.fromkeys(
        (
            "build_model",
            "load_model",
            "loads_model",
        ),
        "_reader",
    ),
    **dict.fromkeys(
        (
            "CorrelatedGroup",
            "Marginal",
            "UncertaintyTable",
            "parameter_overrides",
            "parameter_value",
            "uncertainty_of",
        ),
        "_uncertainty",
    ),
}


__getattr__, __dir__ = lazy_names(__name__, _HOME)


__all__ = [
    "tooth_period",
    "spindle_speed_for",
    "stroke_cycle",
    "stroke_speed",
    "Body",
    "Node",
    "Section",
    "Beam",
    "PointRef",
    "Point",
    "Spring",
    "Attachment",
    "Support",
    "Contact",
    "Constraint",
    "Coupling",
    "Process",
    "Movable",
    "MatrixBlock",
    "Mode",
    "Model",
    "Absorber",
    "Machine",
    "SpindleSpeedVariation",
    "machine_problem",
    "UncertaintyTable",
    "Marginal",
    "CorrelatedGroup",
    "uncertainty_of",
    "parameter_value",
    "parameter_overrides",
    "DIRECTIONS",
    "GROUND",
    "load_model",
    "loads_model",
    "build_model",
    "TrackPosition",
    "body_centre",
    "contact_track_position",
    "point_xy",
    "check_geometry",
    "is_movable",
]
