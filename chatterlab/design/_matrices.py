"""The matrices of the closed loop as functions of one model field, and
their derivatives with respect to it.

The boundary of the lobe diagram depends on a field p only through the
structure's M(p), C(p), K(p) on the independent coordinates, the map J(p)
to the coupling-element coordinates, the CE matrices P(p), V(p), O(p) at
b = 1 m, and -- at a given speed -- the delay T(p) of the process
kinematics (:class:`LoopMatrices`).  The model is immutable: a field is
changed by building the model again (``Model.with_parameter``), so these
matrices are available at any p, not as closed forms of p.  Their
derivatives:

* **affine fields** (a spring's stiffness or damping, a mass, a density,
  Young's modulus with G from nu, a cutting coefficient): one central
  difference over a large step h = |p|/4 is exact up to round-off.  The map
  is *tested* to be affine on the same evaluations: the second difference
  ``X(p+h) - 2 X(p) + X(p-h)`` must vanish to round-off (relative 1e-9 of
  the block's size) in every block, else the field is treated as below;
* **other fields** (a section's I or A, Poisson's ratio, an absorber's
  frequency): the fourth-order central difference
  ``[8 (X(p+h) - X(p-h)) - (X(p+2h) - X(p-2h))] / 12 h`` with the derived
  step h = eps^(1/5) |p| that balances its truncation error h^4 X^(5) / 30
  against round-off eps |X| / h (relative error ~ eps^(4/5) ~ 3e-13).

The complex-step method (p + j h) would be exact for any smooth field, but
the model reader and the assembly are not complex-safe (a field is checked
as a real number in a plausible range, and the assembly works in real
arithmetic), so it is not used.  Only the *matrices* are differenced: the
boundary itself never is (:mod:`chatterlab.design._critical` differentiates
it exactly).

References
----------
.. [1] J. R. R. A. Martins, P. Sturdza, J. J. Alonso, "The complex-step
   derivative approximation", ACM Trans. Math. Software 29 (2003) 245-262.
.. [2] W. H. Press et al., *Numerical Recipes*, 3rd ed., Cambridge, 2007,
   sec. 5.7 (step of a finite difference: truncation against round-off).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, fields
from typing import Any, Literal

import numpy as np

from ..errors import ChatterlabError, InputError, UnitWarning
from ..model import Model
from ..process import closed_loop
from ..structure import assemble
from ._fields import field_unit, field_value

__all__ = ["LoopMatrices", "FieldDerivative", "loop_matrices", "field_derivative"]

_EPS = float(np.finfo(float).eps)
_AFFINE_TOL = 1e-9  #: relative size of a second difference accepted as round-off (affine field)


def structure_matrices(loop: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(M, C, K) of a closed loop: the one place this package reads them."""
    return loop.M, loop.C, loop.K


@dataclass(frozen=True)
class LoopMatrices:
    """What the boundary depends on: M, C, K (n, n) on the independent
    coordinates, J (p, n) to the CE coordinates, the CE matrices P, V, O
    (p, p) at b = 1 m, and the delays T (s) at the speeds of the study."""

    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    J: np.ndarray
    P: np.ndarray
    V: np.ndarray
    O: np.ndarray
    T: np.ndarray

    def blocks(self) -> tuple[np.ndarray, ...]:
        return tuple(getattr(self, f.name) for f in fields(self))

    def combine(self, coeffs: list[float], others: list[LoopMatrices]) -> LoopMatrices:
        """sum_i coeffs[i] others[i], block by block."""
        out = [
            sum(c * x for c, x in zip(coeffs, blocks, strict=True))
            for blocks in zip(*(o.blocks() for o in others), strict=True)
        ]
        return LoopMatrices(*[np.asarray(x) for x in out])


def loop_matrices(
    model: Model,
    *,
    position: float | None = None,
    speeds: np.ndarray | None = None,
    terms: Literal["pdo", "o"] = "pdo",
    couplings: list[str] | None = None,
) -> LoopMatrices:
    """The :class:`LoopMatrices` of a model at a slide position, with the
    delays at ``speeds`` (process unit)."""
    frozen = assemble(model).at(position)
    with warnings.catch_warnings():  # b = 1 m is the reference of beta, not a user's width
        warnings.simplefilter("ignore", UnitWarning)
        loop = closed_loop(frozen, width=1.0, delay=1.0, terms=terms, couplings=couplings)
    M, C, K = structure_matrices(loop)
    proc = model.process
    if speeds is None or proc is None:
        T = np.zeros(0)
    elif proc.kind == "delay":
        T = np.asarray(speeds, dtype=float).copy()
    else:
        T = np.asarray(proc.delay(np.asarray(speeds, dtype=float)), dtype=float)
    return LoopMatrices(
        *(np.array(x, dtype=float) for x in (M, C, K, loop.J, loop.Dl_P, loop.Dl_V, loop.Dl_O, T))
    )


@dataclass(frozen=True)
class FieldDerivative:
    """d/dp of the :class:`LoopMatrices` for one field.

    ``d`` is the derivative used; ``alt`` a second, less accurate estimate
    (affine: the one-sided difference; otherwise the second-order central
    difference) whose distance from ``d`` bounds the error of the less
    accurate one -- the propagated difference is reported as the error
    estimate of a sensitivity.  ``method`` is ``"affine"`` or
    ``"central-4"``; ``step`` the h used (field unit).
    """

    path: str
    value: float
    unit: str
    d: LoopMatrices
    alt: LoopMatrices
    method: str
    step: float
    evaluations: int


def field_derivative(
    model: Model,
    path: str,
    *,
    base: LoopMatrices | None = None,
    position: float | None = None,
    speeds: np.ndarray | None = None,
    terms: Literal["pdo", "o"] = "pdo",
    couplings: list[str] | None = None,
    affine: bool | None = None,
) -> FieldDerivative:
    """d/dp of the loop's matrices for the field ``path`` (module docstring).

    ``affine=True`` skips the test of affinity (a field known to enter
    linearly, e.g. an absorber's stiffness): one forward difference over a
    large step; ``False`` goes straight to the fourth-order difference."""
    p0 = field_value(model, path)
    kw: dict[str, Any] = {"position": position, "speeds": speeds, "terms": terms, "couplings": couplings}
    X0 = base if base is not None else loop_matrices(model, **kw)
    n_eval = 0

    def at(p: float) -> LoopMatrices | None:
        nonlocal n_eval
        n_eval += 1
        try:
            X = loop_matrices(model.with_parameter(path, p), **kw)
        except ChatterlabError:
            return None  # outside the field's valid range
        if any(a.shape != b.shape for a, b in zip(X.blocks(), X0.blocks(), strict=True)):
            raise InputError(
                f"field '{path}': changing it changes the model's coordinates; it has no derivative"
            )
        return X

    scale = abs(p0) if p0 != 0 else _unit_step(at, X0)
    if scale == 0.0:  # the field changes nothing: every derivative is zero
        z = X0.combine([0.0], [X0])
        return FieldDerivative(path, p0, field_unit(path), z, z, "affine", 0.0, n_eval)
    if affine is not False:
        h = 0.25 * scale
        Xp = at(p0 + h)
        if Xp is None:  # the edge of the field's range above: step down instead
            h = -h
            Xp = at(p0 + h)
        if Xp is None:
            raise InputError(f"field '{path}' = {p0:g}: the model cannot be built around this value")
        forward = Xp.combine([1 / h, -1 / h], [Xp, X0])
        if affine:  # known to enter linearly: the difference is exact
            return FieldDerivative(path, p0, field_unit(path), forward, forward, "affine", h, n_eval)
        Xm = at(p0 - h)
        if Xm is not None:  # central: X(p - h), X(p), X(p + h)
            three = [Xm, X0, Xp]
            d, alt = Xp.combine([0.5 / h, -0.5 / h], [Xp, Xm]), forward
        else:  # one-sided at the edge of the range: X(p), X(p + h), X(p + 2h)
            X2 = at(p0 + 2 * h)
            if X2 is None:
                raise InputError(f"field '{path}' = {p0:g}: the model cannot be built around this value")
            three = [X0, Xp, X2]
            d, alt = forward, X2.combine([0.5 / h, -0.5 / h], [X2, X0])
        if _vanishes(Xp.combine([1.0, -2.0, 1.0], three), three):
            return FieldDerivative(path, p0, field_unit(path), d, alt, "affine", abs(h), n_eval)
    h = _EPS**0.2 * scale
    got = [at(p0 + k * h) for k in (-2, -1, 1, 2)]
    pts = [x for x in got if x is not None]
    if len(pts) < 4:
        raise InputError(
            f"field '{path}' = {p0:g} lies at the edge of its valid range: the model cannot be built at"
            f" {p0:g} +- {2 * h:.3g}, so the field has no two-sided derivative here"
        )
    m2, m1, p1, p2 = pts
    d = p1.combine([8 / (12 * h), -8 / (12 * h), -1 / (12 * h), 1 / (12 * h)], [p1, m1, p2, m2])
    alt = p1.combine([0.5 / h, -0.5 / h], [p1, m1])
    return FieldDerivative(path, p0, field_unit(path), d, alt, "central-4", h, n_eval)


def _unit_step(at: Any, X0: LoopMatrices) -> float:
    """A scale for a field whose value is 0: the step that changes the
    matrices by about a quarter of their size (probed at p = 1; 0 when the
    field changes nothing)."""
    X1 = at(1.0)
    if X1 is None:
        X1 = at(-1.0)
        if X1 is None:
            raise InputError("a field at 0 whose model cannot be built at +-1: give it a nonzero value")
    rel = 0.0
    for a, b in zip(X1.blocks(), X0.blocks(), strict=True):
        nb = float(np.abs(b).max(initial=0.0))
        if nb > 0:
            rel = max(rel, float(np.abs(a - b).max(initial=0.0)) / nb)
    return 0.0 if rel == 0 else 0.25 / rel


def _vanishes(second: LoopMatrices, evaluated: list[LoopMatrices]) -> bool:
    """Each block of a second difference is round-off of the blocks it came from."""
    for k, blk in enumerate(second.blocks()):
        size = max(float(np.abs(e.blocks()[k]).max(initial=0.0)) for e in evaluated)
        if float(np.abs(blk).max(initial=0.0)) > _AFFINE_TOL * size:
            return False
    return True
