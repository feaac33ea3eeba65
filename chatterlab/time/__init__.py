"""Time domain: the generic Newmark solver (``_newmark``: the integrator;
``_problems``: what it integrates; ``_options``: its options and
:class:`TimeResponse`; ``_plan``: the checks and setup before the first
step), the parametric problem of Eq. 2.28 (``_parametric``) and the
simulation of a cut (``_simulate``), spectra and growth rates (``_signals``),
what every time-history result shares (``_history``: :class:`TimeHistory`),
milling with the tool leaving the cut (``_milling``)."""

from __future__ import annotations

from ._history import TimeHistory
from ._milling import MillingSimulation, default_steps_per_period, simulate_milling
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
    "TimeHistory",
    "newmark",
    "ParametricProblem",
    "Simulation",
    "simulate",
    "FEEDBACK_CASES",
    "MillingSimulation",
    "simulate_milling",
    "default_steps_per_period",
]
