"""Where the samples are: randomised quasi-Monte Carlo (scrambled Sobol'
points, R independent scramblings) or plain Monte Carlo, and the matrices
of a variance-based sensitivity analysis.

**Randomised QMC** [1, 2].  Replicate ``r`` is the scrambled Sobol' sequence
of ``scipy.stats.qmc.Sobol`` (Owen's linear matrix scrambling with a digital
shift) seeded by ``(seed, r)``; its first ``n = 2^m`` points are a (t, m,
s)-net whatever ``m``, so an estimate on ``n`` points per replicate is
unbiased, and the spread of the R replicate estimates gives its standard
error: an error bar that needs no assumption on the integrand, unlike the
sequence's own discrepancy bound.  Doubling ``n`` keeps the points already
computed (the sequence is extended, not redrawn), which is what the
stopping rule uses.

**Monte Carlo** (``method="mc"``): replicate ``r`` is the PCG64 stream
seeded by ``(seed, r)``, ``n`` rows of it; the same estimators apply.

**Sensitivity** [3].  With ``sensitivity=True`` each replicate's points have
``2 d`` coordinates: the first ``d`` are the matrix A, the last ``d`` the
matrix B, and ``AB_i`` is A with the coordinates of factor ``i`` taken
from B; a run evaluates A, B and every ``AB_i`` (``k + 2`` evaluations per
row for ``k`` factors).

Every point is a pure function of ``(seed, replicate, matrix, row)``: any
process computes the same floats, in any order.

References
----------
.. [1] A. B. Owen, "Scrambling Sobol' and Niederreiter-Xing points", J.
   Complexity 14, 466-489, 1998.
.. [2] P. L'Ecuyer, C. Lemieux, "Recent advances in randomized quasi-Monte
   Carlo methods", in *Modeling Uncertainty*, Springer, 2002, 419-474.
.. [3] A. Saltelli, P. Annoni, I. Azzini, F. Campolongo, M. Ratto, S.
   Tarantola, "Variance based sensitivity analysis of model output. Design
   and estimator for the total sensitivity index", Comput. Phys. Commun.
   181, 259-270, 2010.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ..errors import InputError

__all__ = ["Design", "MAX_SAMPLES"]

#: the most samples a run takes (each a lobe diagram: 0.05-1 s of a core)
MAX_SAMPLES = 1_000_000

_BLOCKS: OrderedDict[tuple[int, int, int, str], np.ndarray] = OrderedDict()


@dataclass(frozen=True)
class Design:
    """The sample points of a run.

    Parameters
    ----------
    dims : int
        Dimensions of the input space (one per uncertain field).
    factor_dims : tuple of tuple of int
        The dimensions of each factor (:meth:`InputSpace.factor_dims`).
    replicates : int
        Independent randomisations R (>= 2: their spread is the error bar).
    seed : int
        The run's seed (>= 0).
    method : {"qmc", "mc"}
        Scrambled Sobol' points or pseudo-random ones.
    sensitivity : bool
        Evaluate the matrices B and AB_i too (Sobol' indices).
    """

    dims: int
    factor_dims: tuple[tuple[int, ...], ...]
    replicates: int = 8
    seed: int = 0
    method: Literal["qmc", "mc"] = "qmc"
    sensitivity: bool = False

    def __post_init__(self) -> None:
        if self.method not in ("qmc", "mc"):
            raise InputError(f"method must be 'qmc' or 'mc' (got {self.method!r})")
        if isinstance(self.replicates, bool) or not isinstance(self.replicates, int) or self.replicates < 2:
            raise InputError(
                f"replicates must be a whole number >= 2 (got {self.replicates!r}): the spread of independent"
                " replicates is the error bar"
            )
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise InputError(f"seed must be a whole number >= 0 (got {self.seed!r})")
        if self.dims < 1:
            raise InputError("the input space has no dimension: name at least one uncertain field")

    @property
    def matrices(self) -> int:
        """Evaluations per row: 1 (A), or k + 2 (A, B, AB_1 .. AB_k) with sensitivity."""
        return len(self.factor_dims) + 2 if self.sensitivity else 1

    @property
    def width(self) -> int:
        """Coordinates of one point: d, or 2 d with sensitivity."""
        return 2 * self.dims if self.sensitivity else self.dims

    def unit(self, replicate: int, rows: np.ndarray) -> np.ndarray:
        """The points ``rows`` of replicate ``replicate``: (len(rows), width)."""
        rows = np.asarray(rows, dtype=np.int64)
        need = int(rows.max()) + 1 if rows.size else 0
        key = (self.seed, replicate, self.width, self.method)
        block = _BLOCKS.get(key)
        if block is None or block.shape[0] < need:
            block = self._block(replicate, need)
            _BLOCKS[key] = block
            if len(_BLOCKS) > 64:
                _BLOCKS.popitem(last=False)
        else:
            _BLOCKS.move_to_end(key)
        return block[rows]

    def _block(self, replicate: int, need: int) -> np.ndarray:
        """The first 2^m >= ``need`` points of the replicate (a prefix of its sequence)."""
        m = max(int(np.ceil(np.log2(max(need, 1)))), 0)
        rng = np.random.default_rng([self.seed, replicate])
        if self.method == "mc":
            return rng.random((2**m, self.width))
        from scipy.stats import qmc

        return qmc.Sobol(self.width, scramble=True, rng=rng).random_base2(m)

    def points(self, replicate: int, matrix: int, rows: np.ndarray) -> np.ndarray:
        """Points of matrix ``matrix`` (0 A, 1 B, 2 + i AB_i) of a replicate:
        (len(rows), dims), ordered as the input space's dimensions."""
        u = self.unit(replicate, rows)
        d = self.dims
        if matrix == 0:
            return u[:, :d]
        if not self.sensitivity or not 0 <= matrix < self.matrices:
            raise InputError(f"matrix {matrix} is not in this design ({self.matrices} matrices)")
        if matrix == 1:
            return u[:, d:]
        out = u[:, :d].copy()
        cols = list(self.factor_dims[matrix - 2])
        out[:, cols] = u[:, [d + c for c in cols]]
        return out


def rows_per_replicate(samples: int, replicates: int) -> int:
    """Rows per replicate for a budget of ``samples``: the power of two
    nearest (in ratio) to samples / replicates, at least 2."""
    target = samples / replicates
    m = max(1, int(np.round(np.log2(max(target, 1.0)))))
    return 2**m


def check_samples(samples: object, replicates: int) -> int:
    """A sample count: a whole number from 2 replicates of 2 points up to
    :data:`MAX_SAMPLES`; one line naming the fix otherwise."""
    import numbers

    if isinstance(samples, bool) or not isinstance(samples, numbers.Real) or samples != samples:
        raise InputError(f"samples must be a whole number (got {samples!r})")
    x = float(samples)
    if x != int(x):
        raise InputError(f"samples must be a whole number (got {samples!r})")
    n = int(x)
    least = 2 * replicates
    if n < least:
        raise InputError(
            f"samples must be at least {least} ({replicates} replicates of 2 points; got {n}): the error bar"
            " comes from the spread of the replicates"
        )
    if n > MAX_SAMPLES:
        raise InputError(
            f"samples {n:g} is more than the largest accepted, {MAX_SAMPLES:g} (each sample is a lobe"
            " diagram: 0.05-1 s of a core); ask for fewer, or a tolerance (tol) that stops earlier"
        )
    return n
