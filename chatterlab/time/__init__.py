"""Time domain: the generic Newmark solver (``_newmark``), the parametric
problem of Eq. 2.28 and the simulation of a cut (``_simulate``), spectra and
growth rates (``_signals``)."""

from __future__ import annotations

from ._newmark import (
    CallbackProblem,
    ConstantProblem,
    NewmarkOptions,
    NewmarkStabilityWarning,
    PiecewiseProblem,
    TimeResponse,
    TimeVaryingProblem,
    newmark,
)
from ._signals import GrowthEstimate, amplitude_spectrum, growth_rate, peaks
from ._simulate import FEEDBACK_CASES, ParametricProblem, Simulation, simulate

__all__ = [
    "GrowthEstimate",
    "amplitude_spectrum",
    "growth_rate",
    "peaks",
    "TimeVaryingProblem",
    "ConstantProblem",
    "CallbackProblem",
    "PiecewiseProblem",
    "NewmarkOptions",
    "NewmarkStabilityWarning",
    "TimeResponse",
    "newmark",
    "ParametricProblem",
    "Simulation",
    "simulate",
    "FEEDBACK_CASES",
]
