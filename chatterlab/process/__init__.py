"""The cutting process as feedback D(s) = D_P + s D_V + D_O e^{-sT} and the
closed loop it makes with the structure (:class:`ClosedLoop`, the value every
engine consumes); the kinematics (speed <-> delay, the slide's motion) and
milling (the rotating cutter's periodic directional matrices); process
damping (the flank's speed-dependent ideal-derivative term, ``_damping``);
spindle-speed variation (the speed program and its time-varying delay, ``_ssv``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_names

if TYPE_CHECKING:  # what type checkers and the API reference see; at run time, on first use
    from ._damping import DampingTerm, LoopDamping, damping_term, milling_damping
    from ._kinematics import ShapingKinematics, SteadyKinematics, kinematics_for
    from ._loop import TERMS, ClosedLoop, ce_maps, closed_loop, coupling_matrix, delay_for, milling_loop
    from ._milling import Milling
    from ._ssv import SpeedVariation, VaryingDelayLoop, VaryingSpeedMilling, ssv_loop, varying_milling

#: public name -> the module that holds it, imported on first use (PEP 562): a command
#: that needs one module of chatterlab.process does not load the others
_HOME = {
    **dict.fromkeys(
        (
            "DampingTerm",
            "LoopDamping",
            "damping_term",
            "milling_damping",
        ),
        "_damping",
    ),
    **dict.fromkeys(
        (
            "ShapingKinematics",
            "SteadyKinematics",
            "kinematics_for",
        ),
        "_kinematics",
    ),
    **dict.fromkeys(
        (
            "TERMS",
            "ClosedLoop",
            "ce_maps",
            "closed_loop",
            "coupling_matrix",
            "delay_for",
            "milling_loop",
        ),
        "_loop",
    ),
    "Milling": "_milling",
    **dict.fromkeys(
        (
            "SpeedVariation",
            "VaryingDelayLoop",
            "VaryingSpeedMilling",
            "ssv_loop",
            "varying_milling",
        ),
        "_ssv",
    ),
}


__getattr__, __dir__ = lazy_names(__name__, _HOME)


__all__ = [
    "ClosedLoop",
    "closed_loop",
    "milling_loop",
    "coupling_matrix",
    "delay_for",
    "ce_maps",
    "TERMS",
    "ShapingKinematics",
    "SteadyKinematics",
    "kinematics_for",
    "Milling",
    "DampingTerm",
    "LoopDamping",
    "damping_term",
    "milling_damping",
    "SpeedVariation",
    "VaryingSpeedMilling",
    "varying_milling",
    "VaryingDelayLoop",
    "ssv_loop",
]
