"""Lobes with error bars: the probability of chatter from uncertain modes,
structures and cutting coefficients (docs/uncertainty.md).

A model file's ``[uncertainty]`` table (read by :mod:`chatterlab.model`)
gives fields distributions; :class:`InputSpace` is their joint
distribution as a map from the unit cube (``_space``); :class:`Design` the
sample points, randomised quasi-Monte Carlo or Monte Carlo, with the
matrices of a Sobol' analysis (``_design``); :func:`risk` computes a lobe
diagram per sample on the sweep engine and returns the
:class:`ProbabilisticLobes` (``_risk``, the task ``_task``, the result
``_result``); :func:`propagate` and :class:`Propagation` do the same for a
function that takes many points at once (``_propagate``); every estimate
is an :class:`Estimate` with its error (``_estimate``);
:func:`uncertain_modal_model` carries a modal fit's own uncertainty into a
modal model (``_fit``).
"""

from __future__ import annotations

from ._design import MAX_SAMPLES, Design
from ._estimate import Estimate, quantile_estimate, replicate_estimate, sobol_indices
from ._fit import uncertain_modal_model
from ._propagate import Propagation, propagate
from ._result import ProbabilisticLobes, RiskLimit
from ._risk import risk
from ._space import InputSpace

__all__ = [
    "risk",
    "ProbabilisticLobes",
    "RiskLimit",
    "InputSpace",
    "Design",
    "propagate",
    "Propagation",
    "Estimate",
    "replicate_estimate",
    "quantile_estimate",
    "sobol_indices",
    "uncertain_modal_model",
    "MAX_SAMPLES",
]
