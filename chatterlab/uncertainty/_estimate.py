"""Estimates with their sampling error, from R independent replicates.

Every estimate of :mod:`chatterlab.uncertainty` is computed on each
replicate (R independent randomisations of the same point set, n points
each) and on all of them; the R replicate values ``theta_r`` are i.i.d.,
so

    se = sd(theta_1 .. theta_R) / sqrt(R),
    interval: estimate +- t_{R-1, (1+level)/2} se

(Student's t with R - 1 degrees of freedom: the replicate means of a
randomised QMC rule are close to normal for n of a few tens and more [1]).
The estimate of a mean or a probability is the mean of the replicate
values (= the mean over all R n samples); a quantile is read from all
samples pooled, its error from the replicate quantiles.

Sobol' indices [2, 3] from the matrices A, B, AB_i (:mod:`._design`),
per replicate, V the variance of f over A and B together:

    S_i  = mean( f(B) (f(AB_i) - f(A)) ) / V          (Saltelli et al. 2010, eq. (b) of Table 2)
    ST_i = mean( (f(A) - f(AB_i))^2 ) / (2 V)          (Jansen 1999)

References
----------
.. [1] P. L'Ecuyer, M. K. Nakayama, A. B. Owen, B. Tuffin, "Confidence
   intervals for randomized quasi-Monte Carlo estimators", Proc. Winter
   Simulation Conference, 2023.
.. [2] I. M. Sobol', "Global sensitivity indices for nonlinear mathematical
   models and their Monte Carlo estimates", Math. Comput. Simul. 55,
   271-280, 2001.
.. [3] A. Saltelli et al., Comput. Phys. Commun. 181, 259-270, 2010;
   M. J. W. Jansen, "Analysis of variance designs for model output",
   Comput. Phys. Commun. 117, 35-43, 1999.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "Estimate",
    "replicate_estimate",
    "t_factor",
    "quantile_estimate",
    "sobol_indices",
    "p_stable_replicates",
]


@dataclass(frozen=True, eq=False)
class Estimate:
    """An estimate (array or scalar) with its standard error and the
    confidence interval at ``level`` (``low``, ``high``)."""

    value: Any
    se: Any
    low: Any
    high: Any
    level: float

    @property
    def half_width(self) -> Any:
        """Half the width of the confidence interval."""
        return 0.5 * (np.asarray(self.high) - np.asarray(self.low))

    def __repr__(self) -> str:
        if np.ndim(self.value) == 0:
            return f"Estimate({float(self.value):.6g} +- {float(self.half_width):.3g} at {self.level:g})"
        return f"Estimate(shape {np.shape(self.value)}, level {self.level:g})"


def t_factor(replicates: int, level: float) -> float:
    """Student's t quantile t_{R-1, (1+level)/2}."""
    from scipy import stats

    return float(stats.t.ppf(0.5 * (1.0 + level), replicates - 1))


def replicate_estimate(values: Any, level: float = 0.95, estimate: Any = None) -> Estimate:
    """The estimate of replicate values ``values`` (R, ...): their mean (or
    ``estimate`` when given: a pooled estimate of the same quantity), the
    standard error sd/sqrt(R) and the t interval at ``level``."""
    v = np.asarray(values, float)
    R = v.shape[0]
    mean = v.mean(axis=0) if estimate is None else np.asarray(estimate, float)
    with np.errstate(invalid="ignore"):
        se = v.std(axis=0, ddof=1) / np.sqrt(R)
    h = t_factor(R, level) * se
    return Estimate(mean, se, mean - h, mean + h, level)


def quantile_estimate(samples: Any, q: Any, level: float = 0.95) -> Estimate:
    """Quantiles ``q`` of ``samples`` (R, n, ...) over the sample axes: from
    all R n samples pooled (the inverse of the empirical distribution
    function: the smallest sample value x with F_n(x) >= q, so an ``inf``
    -- no boundary up to the ceiling -- is a value like any other), the
    error from the R replicate quantiles.  Shape (len(q), ...)."""
    s = np.asarray(samples, float)
    q = np.atleast_1d(np.asarray(q, float))
    R, n = s.shape[:2]
    pooled = np.quantile(s.reshape(R * n, *s.shape[2:]), q, axis=0, method="inverted_cdf")
    per = np.stack([np.quantile(s[r], q, axis=0, method="inverted_cdf") for r in range(R)])
    with np.errstate(invalid="ignore"):
        se = np.where(np.isfinite(per).all(axis=0), per.std(axis=0, ddof=1), np.nan) / np.sqrt(R)
    h = t_factor(R, level) * se
    return Estimate(pooled, se, pooled - h, pooled + h, level)


def sobol_indices(fA: Any, fB: Any, fAB: Any, level: float = 0.95) -> tuple[Estimate, Estimate]:
    """First-order and total Sobol' indices of each factor, with their errors.

    Parameters
    ----------
    fA, fB : array (R, n)
        The output on the matrices A and B of each replicate.
    fAB : array (k, R, n)
        The output on AB_i (A with factor i from B).

    Returns
    -------
    (first, total) : Estimate, Estimate
        Arrays of length k; nan where the output does not vary in a
        replicate (V = 0: every index is then undefined).
    """
    fA, fB, fAB = (np.asarray(x, float) for x in (fA, fB, fAB))
    V = np.concatenate([fA, fB], axis=1).var(axis=1, ddof=1)  # (R,)
    with np.errstate(invalid="ignore", divide="ignore"):
        s1 = np.mean(fB[None] * (fAB - fA[None]), axis=2) / V[None]  # (k, R)
        st = 0.5 * np.mean((fA[None] - fAB) ** 2, axis=2) / V[None]
    s1 = np.where(V[None] > 0, s1, np.nan)
    st = np.where(V[None] > 0, st, np.nan)
    return replicate_estimate(s1.T, level), replicate_estimate(st.T, level)


def p_stable_replicates(b_lim: np.ndarray, widths: np.ndarray) -> np.ndarray:
    """P(b < b_lim) per replicate, speed and width: (R, speeds, widths) from
    the samples' limits (R, n, speeds); NaN (undetermined) at a speed where a
    sample's limit is NaN (its diagram establishes nothing there, or its task
    failed): such a sample is neither stable nor chattering."""
    R, n, nv = b_lim.shape
    out = np.empty((R, nv, widths.size))
    for r in range(R):
        for v in range(nv):
            s = np.sort(b_lim[r, :, v])
            out[r, v] = (n - np.searchsorted(s, widths, side="right")) / n
    return np.where(np.isnan(b_lim).any(axis=1)[:, :, None], np.nan, out)
