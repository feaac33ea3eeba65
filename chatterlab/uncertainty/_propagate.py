"""Sample outputs arranged by replicate, and their estimates:
:class:`Propagation`; :func:`propagate` fills one from a function that
evaluates many input points at once (a closed form, a surrogate).

A lobe diagram per sample goes through the sweep engine instead
(:func:`chatterlab.uncertainty.risk`), which fills the same arrays.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import InputError
from ._design import Design, check_samples, rows_per_replicate
from ._estimate import Estimate, quantile_estimate, replicate_estimate, sobol_indices
from ._space import InputSpace

__all__ = ["Propagation", "propagate"]


@dataclass(frozen=True, eq=False)
class Propagation:
    """Outputs of a sampled model, by replicate.

    Attributes
    ----------
    space : InputSpace
    design : Design
    n : int
        Rows (points) per replicate.
    outputs : dict
        ``name -> array (R, n, ...)``: the output on the matrix A.
    matrices : dict
        With ``design.sensitivity``: ``name -> array (k + 1, R, n, ...)``,
        the output on B and on each AB_i.
    level : float
        Confidence level of the intervals.
    """

    space: InputSpace
    design: Design
    n: int
    outputs: dict[str, np.ndarray]
    matrices: dict[str, np.ndarray] = field(default_factory=dict)
    level: float = 0.95

    @property
    def samples(self) -> int:
        """Samples of the input distribution (R n; the sensitivity matrices not counted)."""
        return self.design.replicates * self.n

    def _get(self, name: str) -> np.ndarray:
        if name not in self.outputs:
            raise InputError(f"no output {name!r} (outputs: {', '.join(self.outputs)})")
        return self.outputs[name]

    def mean(self, name: str) -> Estimate:
        """The expected value of an output (a probability, for a 0/1 output)."""
        return replicate_estimate(self._get(name).mean(axis=1), self.level)

    def probability(self, name: str, threshold: float, *, below: bool = True) -> Estimate:
        """P(output < threshold) (or > with ``below=False``)."""
        y = self._get(name)
        return replicate_estimate(((y < threshold) if below else (y > threshold)).mean(axis=1), self.level)

    def quantile(self, name: str, q: Any) -> Estimate:
        """Quantiles of an output (:func:`._estimate.quantile_estimate`)."""
        return quantile_estimate(self._get(name), q, self.level)

    def sobol(
        self, name: str, transform: Callable[[np.ndarray], np.ndarray] | None = None
    ) -> tuple[Estimate, Estimate]:
        """First-order and total Sobol' indices of an output (scalar per
        sample), one per factor of the space; ``transform`` maps the output
        first (e.g. an indicator)."""
        if not self.design.sensitivity:
            raise InputError("Sobol' indices need the sensitivity matrices: sample with sensitivity=True")
        f = transform or (lambda y: y)
        A = f(self._get(name))
        M = f(self.matrices[name])
        return sobol_indices(A, M[0], M[1:], self.level)


def propagate(
    func: Callable[[dict[str, np.ndarray]], Mapping[str, Any]],
    space: InputSpace,
    *,
    samples: int,
    replicates: int = 8,
    seed: int = 0,
    method: str = "qmc",
    sensitivity: bool = False,
    factors: Mapping[str, Any] | None = None,
    level: float = 0.95,
) -> Propagation:
    """Sample ``space`` and evaluate ``func`` on all points of each matrix at once.

    Parameters
    ----------
    func : callable
        ``func({path: values (N,)}) -> {name: array (N, ...)}``.
    space : InputSpace
    samples : int
        The budget: R replicates of the power of two of rows nearest to
        samples / R.
    replicates, seed, method, sensitivity
        As :class:`Design`.
    factors : mapping, optional
        Named groups of fields as the Sobol' factors
        (:meth:`InputSpace.sensitivity_factors`).
    level : float
        Confidence level of the intervals (0.95).
    """
    design = Design(space.dims, space.sensitivity_factors(factors)[0], replicates, seed, method, sensitivity)  # type: ignore[arg-type]
    n = rows_per_replicate(check_samples(samples, replicates), replicates)
    rows = np.arange(n)
    outs: dict[str, list[list[np.ndarray]]] = {}
    for mat in range(design.matrices):
        for r in range(replicates):
            x = space.transform(design.points(r, mat, rows))
            res = func({p: x[:, i] for i, p in enumerate(space.paths)})
            for name, y in res.items():
                outs.setdefault(name, [[] for _ in range(design.matrices)])[mat].append(np.asarray(y, float))
    A = {k: np.stack(v[0]) for k, v in outs.items()}
    M = (
        {k: np.stack([np.stack(v[m]) for m in range(1, design.matrices)]) for k, v in outs.items()}
        if sensitivity
        else {}
    )
    return Propagation(space, design, n, A, M, level)
