"""Stability lobes: the D-subdivision boundary found completely
(``_boundary``), the entry point :func:`lobes` (``_diagram``), its result
(``_result``), the structure as a plant (``_plant``), the chatter band
(``_band``), the envelope (``_envelope``), the argument-principle checks
(``_verification``), time-domain confirmation (``_confirm``),
python-control structures (``_control``), a measured FRF as the structure
(``_measured``), milling lobes by Floquet multipliers (``_milling``,
``_milling_search``, a model file in their terms: ``_milling_model``).

The diagram is computed by :func:`lobes` (``from chatterlab.lobes import lobes``,
or ``chatterlab.lobes(...)``: the subpackage is callable), the one entry point
for every structure and process (``_entry``).
"""

from __future__ import annotations

import sys
import types
from typing import TYPE_CHECKING, Any

from .._lazy import lazy_names

if TYPE_CHECKING:  # what type checkers and the API reference see; at run time, on first use
    from ._confirm import Confirmation, confirm
    from ._control import closed_loop_lti, coupling_matrices, lobes_lti, lti_plant
    from ._diagram import Boundary, Lobe, LobeDiagram, Plant, boundary
    from ._entry import lobes
    from ._measured import lobes_measured, lobes_model_frf, measured_plant, model_frf, regenerative_matrices
    from ._milling import milling_lobes, zoa_plant
    from ._milling_model import Reduction, is_milling, milling_loop_of, milling_of, reduce_structure
    from ._result import ProcessNames

#: public name -> the module that holds it, imported on first use (PEP 562): a command
#: that needs one module of chatterlab.lobes does not load the others
_HOME = {
    **dict.fromkeys(
        (
            "Confirmation",
            "confirm",
        ),
        "_confirm",
    ),
    **dict.fromkeys(
        (
            "closed_loop_lti",
            "coupling_matrices",
            "lobes_lti",
            "lti_plant",
        ),
        "_control",
    ),
    **dict.fromkeys(
        (
            "Boundary",
            "Lobe",
            "LobeDiagram",
            "Plant",
            "boundary",
        ),
        "_diagram",
    ),
    "lobes": "_entry",
    **dict.fromkeys(
        (
            "lobes_measured",
            "lobes_model_frf",
            "measured_plant",
            "model_frf",
            "regenerative_matrices",
        ),
        "_measured",
    ),
    **dict.fromkeys(
        (
            "milling_lobes",
            "zoa_plant",
        ),
        "_milling",
    ),
    **dict.fromkeys(
        (
            "Reduction",
            "is_milling",
            "milling_loop_of",
            "milling_of",
            "reduce_structure",
        ),
        "_milling_model",
    ),
    "ProcessNames": "_result",
}


__getattr__, __dir__ = lazy_names(__name__, _HOME)


__all__ = [
    "Lobe",
    "LobeDiagram",
    "ProcessNames",
    "Boundary",
    "Plant",
    "lobes",
    "boundary",
    "Confirmation",
    "confirm",
    "lti_plant",
    "lobes_lti",
    "closed_loop_lti",
    "coupling_matrices",
    "measured_plant",
    "lobes_measured",
    "lobes_model_frf",
    "model_frf",
    "regenerative_matrices",
    "Reduction",
    "is_milling",
    "milling_of",
    "reduce_structure",
    "milling_loop_of",
    "milling_lobes",
    "zoa_plant",
]


class _CallableModule(types.ModuleType):
    """``chatterlab.lobes(...)`` is :func:`lobes`: the subpackage and its entry
    point share a name, and the call reads as the style guide writes it."""

    def __call__(self, *args: Any, **kwargs: Any) -> LobeDiagram:
        from ._entry import lobes as entry

        return entry(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
