"""The matrices of the closed loop as functions of one model field, and
their derivatives with respect to it.

The boundary of the lobe diagram depends on a field p only through the
structure's M(p), C(p), K(p) on the independent coordinates, the map J(p)
to the coupling-element coordinates, the CE matrices P(p), V(p), O(p) at
b = 1 m, -- at a given speed -- the delay T(p) of the process kinematics,
and the actuators' maps, gains, delays and bandwidths (:class:`LoopMatrices`).  The model is immutable: a field is
changed by building the model again (``Model.with_parameter``), so these
matrices are available at any p, not as closed forms of p.  Their
derivatives:

* **affine fields** (a spring's stiffness or damping, a mass, a density,
  Young's modulus with G from nu, a cutting coefficient: the table of
  :func:`chatterlab.design.field_affinity`, each entry confirmed by a
  vanishing second difference in tests/test_design_sensitivity.py): one
  difference over a large step h = |p|/4 (or 1 for a field at 0) is exact
  up to round-off eps |Y| / (h |dY|), which is reported;
* **fields the table does not know** are *tested*: the second difference
  ``Y(p+h) - 2 Y(p) + Y(p-h)`` must vanish to round-off (relative 1e-9 of
  the block's size) in every block for the central difference over h = |p|/4
  to be taken as exact; else they are treated as below;
* **other fields** (a section's I or A, Poisson's ratio, an angle, an
  absorber's frequency): the central difference with the derived step
  h = (3 eps)^(1/3) |p| that balances its truncation error h^2 Y^(3) / 6
  against round-off eps |Y| / h (relative error ~ eps^(2/3) ~ 4e-11), and
  that truncation term estimated from the third difference
  ``Y(p+2h) - 3 Y(p+h) + 3 Y(p) - Y(p-h) = h^3 Y^(3)``, which is reported.

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
from ..process._loop import Actuators
from ..structure import assemble
from ._fields import field_affinity, field_unit, field_value

__all__ = ["LoopMatrices", "FieldDerivative", "loop_matrices", "matrices_of", "field_derivative"]

_EPS = float(np.finfo(float).eps)
_AFFINE_TOL = 1e-9  #: relative size of a second difference accepted as round-off (affine field)


def structure_matrices(loop: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(M, C, K) of a closed loop: the one place this package reads them."""
    return loop.M, loop.C, loop.K


@dataclass(frozen=True)
class LoopMatrices:
    """What the boundary depends on: M, C, K (n, n) on the independent
    coordinates, J (p, n) to the CE coordinates, the CE matrices P, V, O
    (p, p) at b = 1 m, the delays T (s) at the speeds of the study, and the
    machine's actuators (:class:`chatterlab.process.Actuators`, m of them;
    empty blocks without): their force map Fa (n, m), sensor map Sa (m, n),
    gains Pa, Va, Oa (m,), delays Ta (m,) and bandwidth time constants La
    (m,), which add -Fa diag(G(s)) Sa to the loop's D(s)."""

    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    J: np.ndarray
    P: np.ndarray
    V: np.ndarray
    O: np.ndarray
    T: np.ndarray
    Fa: np.ndarray
    Sa: np.ndarray
    Pa: np.ndarray
    Va: np.ndarray
    Oa: np.ndarray
    Ta: np.ndarray
    La: np.ndarray

    @property
    def actuators(self) -> Actuators | None:
        """The actuators as :class:`chatterlab.process.Actuators` (None without)."""
        m = self.Pa.size
        if m == 0:
            return None
        ids = tuple(f"a{k}" for k in range(m))
        inf = np.full(m, np.inf)
        return Actuators(ids, self.Fa, self.Sa, self.Pa, self.Va, self.Oa, self.Ta, self.La, inf)

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
    return matrices_of(loop, model.process, speeds)


def matrices_of(loop: Any, process: Any = None, speeds: np.ndarray | None = None) -> LoopMatrices:
    """The :class:`LoopMatrices` of a closed loop at b = 1 m (its CE matrices
    are taken as they are), with the delays of ``process`` at ``speeds``."""
    M, C, K = structure_matrices(loop)
    proc = process
    if speeds is None or proc is None:
        T = np.zeros(0)
    elif proc.kind == "delay":
        T = np.asarray(speeds, dtype=float).copy()
    else:
        T = np.asarray(proc.delay(np.asarray(speeds, dtype=float)), dtype=float)
    a = loop.actuators
    n = M.shape[0]
    if a is None:
        act: tuple[np.ndarray, ...] = (np.zeros((n, 0)), np.zeros((0, n))) + (np.zeros(0),) * 5
    else:
        act = (a.B, a.S, a.P, a.V, a.O, a.delay, a.lag)
    return LoopMatrices(
        *(np.array(x, dtype=float) for x in (M, C, K, loop.J, loop.Dl_P, loop.Dl_V, loop.Dl_O, T, *act))
    )


@dataclass(frozen=True)
class FieldDerivative:
    """d/dp of the :class:`LoopMatrices` for one field.

    ``d`` is the derivative used; ``alt`` a second estimate whose distance
    from ``d`` estimates d's truncation error: for a tested affine field the
    other difference (one-sided or over twice the step), for a non-affine one
    the central difference corrected by its truncation term estimated from a
    third difference, for an affine field of the format's table ``d`` itself
    (no truncation).  ``roundoff`` estimates the round-off of each entry of
    ``d``: 8 eps |Y| / |h|.  ``method`` is
    ``"affine"`` or ``"central"``; ``step`` the h used (field unit).
    """

    path: str
    value: float
    unit: str
    d: LoopMatrices
    alt: LoopMatrices
    method: str
    step: float
    evaluations: int
    roundoff: LoopMatrices | None = None


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

    ``affine`` (default: what :func:`~chatterlab.design.field_affinity`
    says of the field): True takes one difference over a large step (exact
    for an affine map), False the central difference with the derived step,
    None tests the field first (a vanishing second difference)."""
    p0 = field_value(model, path)
    if affine is None:
        affine = field_affinity(model, path)
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

    def result(d: LoopMatrices, alt: LoopMatrices, method: str, h: float) -> FieldDerivative:
        return FieldDerivative(path, p0, field_unit(path), d, alt, method, abs(h), n_eval, _roundoff(X0, h))

    if p0 == 0 and affine:  # an affine field at 0: the difference to p = 1, rescaled if too small
        h, Xh = _zero_step(at, X0, path, p0)
        if Xh is None:  # the field changes nothing: every derivative is zero
            z = X0.combine([0.0], [X0])
            return result(z, z, "affine", 0.0)
        d = Xh.combine([1 / h, -1 / h], [Xh, X0])
        return result(d, d, "affine", h)
    scale = abs(p0) if p0 != 0 else _scale(at, X0)
    if scale == 0.0:
        z = X0.combine([0.0], [X0])
        return result(z, z, "affine", 0.0)
    if affine is not False:
        h = 0.25 * scale
        Xp = at(p0 + h)
        if Xp is None:  # the edge of the field's range above: step down instead
            h = -h
            Xp = at(p0 + h)
        if Xp is None:
            raise InputError(f"field '{path}' = {p0:g}: the model cannot be built around this value")
        forward = Xp.combine([1 / h, -1 / h], [Xp, X0])
        if affine:  # affine by the format: the difference is exact up to round-off
            return result(forward, forward, "affine", h)
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
            return result(d, alt, "affine", h)
    # not affine: the central difference with the step that balances its truncation error
    # h^2 Y^(3) / 6 against round-off eps |Y| / h, and that truncation term estimated from the
    # third difference Y(p + 2h) - 3 Y(p + h) + 3 Y(p) - Y(p - h) = h^3 Y^(3) (+ O(h^4))
    h = (3 * _EPS) ** (1 / 3) * scale
    Xm, Xp, X2 = at(p0 - h), at(p0 + h), at(p0 + 2 * h)
    if Xm is None or Xp is None or X2 is None:
        raise InputError(
            f"field '{path}' = {p0:g} lies at the edge of its valid range: the model cannot be built at"
            f" {p0:g} - {h:.3g} .. {p0:g} + {2 * h:.3g}, so the field has no two-sided derivative here"
        )
    d = Xp.combine([0.5 / h, -0.5 / h], [Xp, Xm])
    third = Xp.combine([1.0, -3.0, 3.0, -1.0], [X2, Xp, X0, Xm])
    alt = d.combine([1.0, -1.0 / (6 * h)], [d, third])  # d - h^2 Y^(3) / 6
    return result(d, alt, "central", h)


def _roundoff(X0: LoopMatrices, h: float) -> LoopMatrices:
    """An estimate of the round-off of a difference quotient of the blocks
    over the step h, entry by entry: 8 eps |Y| / |h| (a few roundings of each
    entry in the model's assembly, divided by the step; 0 for a zero step)."""
    hh = abs(h)
    return LoopMatrices(*(8 * _EPS * np.abs(Y) / hh if hh else np.zeros_like(Y) for Y in X0.blocks()))


def _zero_step(at: Any, X0: LoopMatrices, path: str, p0: float) -> tuple[float, LoopMatrices | None]:
    """For an affine field at 0: (h, Y(h)) with h = 1, or, when that changes the
    matrices by less than 1e-6 of their size (round-off above 1e-10 of the
    difference), the step that changes them by a quarter of it."""
    h, X1 = 1.0, at(1.0)
    if X1 is None:
        h, X1 = -1.0, at(-1.0)
    if X1 is None:
        raise InputError(
            f"field '{path}' = {p0:g}: the model cannot be built at +-1; give it a nonzero value"
        )
    rel = _relative_change(X0, X1)
    if rel == 0:
        return h, None
    if rel < 1e-6:
        h = h * 0.25 / rel
        X1 = at(h)
        if X1 is None:
            raise InputError(f"field '{path}' = {p0:g}: the model cannot be built at {h:g}")
    return h, X1


def _relative_change(X0: LoopMatrices, X1: LoopMatrices) -> float:
    rel = 0.0
    for a, b in zip(X1.blocks(), X0.blocks(), strict=True):
        nb = float(np.abs(b).max(initial=0.0))
        if nb > 0:
            rel = max(rel, float(np.abs(a - b).max(initial=0.0)) / nb)
    return rel


def _scale(at: Any, X0: LoopMatrices) -> float:
    """A scale for a field whose value is 0 (not known to be affine): the
    step that changes the matrices by about a quarter of their size (probed
    at p = 1; 0 when the field changes nothing)."""
    X1 = at(1.0)
    if X1 is None:
        X1 = at(-1.0)
        if X1 is None:
            raise InputError("a field at 0 whose model cannot be built at +-1: give it a nonzero value")
    rel = _relative_change(X0, X1)
    return 0.0 if rel == 0 else 0.25 / rel


def _vanishes(second: LoopMatrices, evaluated: list[LoopMatrices]) -> bool:
    """Each block of a second difference is round-off of the blocks it came from."""
    for k, blk in enumerate(second.blocks()):
        size = max(float(np.abs(e.blocks()[k]).max(initial=0.0)) for e in evaluated)
        if float(np.abs(blk).max(initial=0.0)) > _AFFINE_TOL * size:
            return False
    return True
