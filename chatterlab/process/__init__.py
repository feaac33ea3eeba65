"""The cutting process as feedback D(s) = D_P + s D_V + D_O e^{-sT}: the
coupling matrices in reduced coordinates and the kinematics (speed <-> delay,
the slide's motion)."""

from __future__ import annotations

from ._cutting import TERMS, Feedback, ce_maps, delay_for, feedback
from ._kinematics import ShapingKinematics, SteadyKinematics, kinematics_for
from ._milling import Milling

__all__ = [
    "Feedback",
    "feedback",
    "delay_for",
    "ce_maps",
    "TERMS",
    "ShapingKinematics",
    "SteadyKinematics",
    "kinematics_for",
    "Milling",
]
