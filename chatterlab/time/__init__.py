"""Time domain: one Newmark core (``_core``: the scheme, the delayed
history, the step loop; ``_contact``: its unilateral coupling -- an implicit
force with an active set, the instants a gap crosses zero located) under
every Newmark integration: the generic solver (``_newmark``: :func:`newmark`;
``_problems``: what it integrates; ``_plan``: the checks and setup before
the first step), the parametric problem of Eq. 2.28 (``_parametric``) and
the simulation of a cut (``_simulate``, ``_initial``), milling with the tool
leaving the cut (``_milling``: :func:`simulate_milling`; ``_milling_cut``:
the cut as the core's coupling; ``_milling_verdict``, ``_milling_result``);
the option objects and :class:`TimeResponse` (``_options``), spectra and
growth rates (``_signals``), and what every time-history result shares
(``_history``: :class:`TimeHistory`); the exponential step map of a
time-invariant loop (``_exponential``: :func:`exponential`, selected in
:func:`simulate` by ``Integration(integrator="exponential")``)."""

from __future__ import annotations

from ._exponential import exponential
from ._history import TimeHistory
from ._indentation import IndentationResponse, simulate_indentation
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
from ._options import Excitation, Initial, Integration
from ._signals import GrowthEstimate, amplitude_spectrum, growth_rate, peaks
from ._simulate import FEEDBACK_CASES, ParametricProblem, Simulation, simulate

__all__ = [
    "simulate_indentation",
    "IndentationResponse",
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
    "exponential",
    "ParametricProblem",
    "Simulation",
    "simulate",
    "FEEDBACK_CASES",
    "Integration",
    "Initial",
    "Excitation",
    "MillingSimulation",
    "simulate_milling",
    "default_steps_per_period",
]
