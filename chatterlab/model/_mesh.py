"""The discretisation error of a result of a model with beams.

A ``[[beam]]`` is divided into ``elements`` equal Timoshenko elements of
length h; a result f (a limit width, a natural frequency, a stability
margin) computed on that mesh is f_h.  The mesh twice as fine is
:meth:`Model.with_finer_mesh` (every beam's count doubled, through the
model's own override path: no second assembly).  With the change
``d = f_{h/2} - f_h`` and the asymptotic error model

    f_h = f + C h^p + o(h^p),  p >= P_MIN = 1                       (docs/lobes.md, Eq. M1)

the error of the result on h is

    |f_h - f| = |d| / (1 - 2^-p) <= |d| / (1 - 2^-P_MIN) = 2 |d|    (Eq. M3)

(docs/lobes.md, "The discretisation error of a result").  p >= 1 is the
lowest order the bundled shaper shows: springs and contacts inside elements
make the Timoshenko element's shear strain jump, which costs rate 1; a
smooth mode converges at rate 2 (studies/traverse_shaper/mesh_convergence.py).
The bound assumes the asymptotic regime: the two meshes on the same side of
the limit, the higher-order terms small.  Before it (a lobe that changes
order between the meshes) it is an estimate, not a proof.

:func:`mesh_verdict` combines two stability verdicts, on h and on h/2,
so that a claim survives only if neither the finer mesh nor the error of
its margin contradicts it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "P_MIN",
    "MeshEstimate",
    "bound_factor",
    "mesh_verdict",
    "mesh_words",
    "converged_variant",
    "pct",
    "limit_line",
    "width_verdict",
    "converged_tail",
    "mesh_record",
    "envelope_record",
]

#: the lowest order of convergence assumed (point loads inside elements)
P_MIN = 1.0


def bound_factor(order: float = P_MIN) -> float:
    """1 / (1 - 2^-p): the error of the result on h per unit change on h/2 (2 at p = 1)."""
    if not order > 0:
        raise ValueError(f"order must be > 0, got {order!r}")
    return 1.0 / (1.0 - 2.0**-order)


@dataclass(frozen=True)
class MeshEstimate:
    """A result on h (``coarse``) and on h/2 (``fine``), and the bound on
    the error of the coarse one (Eq. M3).  Works elementwise on arrays; inf
    or nan in either gives a nan bound (no estimate: a limit at the ceiling)."""

    coarse: Any
    fine: Any
    order: float = P_MIN

    @property
    def change(self) -> Any:
        """d = f_{h/2} - f_h."""
        with np.errstate(invalid="ignore"):
            return np.asarray(self.fine, float) - np.asarray(self.coarse, float)

    @property
    def relative_change(self) -> Any:
        """d / |f_h|."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.change / np.abs(np.asarray(self.coarse, float))

    @property
    def bound(self) -> Any:
        """|d| / (1 - 2^-p): the largest error of the coarse result (nan where
        either value is not finite)."""
        d = self.change
        with np.errstate(invalid="ignore"):
            return np.where(np.isfinite(d), np.abs(d) * bound_factor(self.order), np.nan)

    @property
    def relative_bound(self) -> Any:
        """The bound relative to |f_h|."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.bound / np.abs(np.asarray(self.coarse, float))


def mesh_record(model: Any, prefix: str = "mesh_") -> dict[str, Any]:
    """The facts every mesh record starts with: the beam elements on this
    mesh and on the one twice as fine (:meth:`Model.with_finer_mesh`), and
    the order p assumed by the bound (``prefix`` before each key: ``mesh_``
    for file attributes and ``meta``, none inside a JSON ``mesh`` member)."""
    return {
        f"{prefix}beam_elements": model.beam_elements,
        f"{prefix}fine_beam_elements": model.with_finer_mesh().beam_elements,
        f"{prefix}order": P_MIN,
    }


def envelope_record(coarse: Any, fine: Any, free: Any, points: str) -> dict[str, Any]:
    """How far a set of limits moves on the mesh twice as fine (``coarse``,
    ``fine``: SI arrays of the same shape, inf at the ceiling): the median
    and largest |fine - coarse| / coarse where both are finite (a change,
    not a bound) and their count, and of the points ``free`` (a mask: a
    claim of no chatter below the ceiling) how many have a limit on the
    finer mesh.  Keys ``mesh_envelope_change_median``, ``_max``,
    ``mesh_envelope_<points>``, ``mesh_free_<points>``,
    ``mesh_free_<points>_fine_limited`` (``points``: "speeds", "points")."""
    env = np.abs(MeshEstimate(coarse, fine).relative_change)
    env = env[np.isfinite(env)]
    free = np.asarray(free, bool)
    return {
        "mesh_envelope_change_median": float(np.median(env)) if env.size else float("nan"),
        "mesh_envelope_change_max": float(env.max()) if env.size else float("nan"),
        f"mesh_envelope_{points}": int(env.size),
        f"mesh_free_{points}": int(np.count_nonzero(free)),
        f"mesh_free_{points}_fine_limited": int(
            np.count_nonzero(free & np.isfinite(np.asarray(fine, float)))
        ),
    }


def mesh_words(model: Any) -> str:
    """ "6 beam elements" (every beam's count summed)."""
    n = model.beam_elements
    return f"{n} beam element{'s' * (n != 1)}"


def converged_variant(model: Any) -> str | None:
    """The model file's variant named ``converged``, when the model is the
    file's default (no variant: one variant is applied at a time, so from
    another one -- the shaper's ``printed`` -- it would change more than the
    mesh); None otherwise.  What the advice names."""
    try:
        variants = json.loads(model.raw).get("variant", {}) if model.raw else {}
    except (ValueError, AttributeError):
        return None
    return "converged" if "converged" in variants and model.variant is None else None


def pct(x: float, sign: str = "") -> str:
    """A fraction as a percentage: one decimal from 1 % up (7.7%, 193.0%), two
    significant digits below (0.012%)."""
    return f"{x:{sign}.1%}" if abs(x) >= 0.01 else f"{x * 100:{sign}.2g}%"


def limit_line(
    model: Any, name: str, coarse: float, fine: float, unit: str = "mm", scale: float = 1e3, tail: bool = True
) -> str:
    """One line on a limit (a width, a depth: SI ``coarse`` on h, ``fine`` on
    h/2) for a command's summary: the value on the mesh twice as fine, its
    change and the bound of the coarse value's error (Eq. M3), or why there
    is no bound (a limit at the ceiling on either mesh).  Shown in ``unit``
    (``scale`` units per SI unit); ``tail``: end with the advice to use the
    file's converged variant (:func:`converged_tail`), or leave it to the
    caller, who adds more first."""
    e = MeshEstimate(coarse, fine)
    if not np.isfinite(fine) and not np.isfinite(coarse):
        head = f"twice as fine: no {name} below the ceiling either; no estimate of its error"
    elif not np.isfinite(fine):
        head = f"twice as fine: no {name} below the ceiling, where this mesh has one: this result is not converged"
    elif not np.isfinite(coarse):
        head = (
            f"twice as fine: {name} {fine * scale:.4g} {unit}, where this mesh has none below the ceiling:"
            " this result is not converged"
        )
    else:
        head = (
            f"twice as fine: {name} {fine * scale:.4g} {unit} ({pct(float(e.relative_change), '+')}),"
            f" discretisation error of this {name} <= {pct(float(e.relative_bound))}"
        )
    return f"mesh: {mesh_words(model)}; {head}{converged_tail(model) if tail else ''}"


def width_verdict(model: Any, width: float, limit: float, fine_limit: float) -> tuple[str, str]:
    """The verdict on a cut of ``width`` (or depth) against the stability
    limit ``limit`` on h and ``fine_limit`` on h/2 (SI; inf: none below the
    ceiling searched), and one line why: the limit's analogue of
    :func:`mesh_verdict`.

    * ``stable`` on both meshes (width below both limits) with the margin
      limit - width larger than the limit's error bound 2 |fine - limit|
      (Eq. M3): ``stable``;
    * ``unstable`` on both (width at or above both limits) with
      width - limit beyond the bound: ``unstable``;
    * otherwise (the meshes disagree, the margin is inside the bound, or
      one limit is at the ceiling and the other not, or either is NaN: the
      lobes establish nothing there): ``undetermined``.
    Both limits at the ceiling: ``stable`` as far as the ceiling searched
    (the caller's claim about the ceiling stands)."""
    advice = _advice(model)
    if np.isnan(limit) or np.isnan(fine_limit):
        where = "on this mesh" if np.isnan(limit) else "on a mesh twice as fine"
        return "undetermined", f"mesh: the lobes {where} establish nothing at this speed: {advice}"
    on_h = "stable" if width < limit else "unstable"
    on_h2 = "stable" if width < fine_limit else "unstable"
    if not np.isfinite(limit) and not np.isfinite(fine_limit):
        return (
            "stable",
            f"mesh: {mesh_words(model)}; no limit below the ceiling on this mesh or one twice as fine",
        )
    if on_h != on_h2:
        return "undetermined", f"mesh: {on_h} on this mesh, {on_h2} on a mesh twice as fine: {advice}"
    if np.isinf(limit) or np.isinf(fine_limit):  # one at the ceiling: the limit's error is not bounded
        none, other = ("this mesh", fine_limit) if np.isinf(limit) else ("a mesh twice as fine", limit)
        return "undetermined", (
            f"mesh: {on_h} on this mesh and on one twice as fine, but no limit below the ceiling on {none}"
            f" and {other * 1e3:.4g} mm on the other: the limit's discretisation error is not bounded: {advice}"
        )
    e = MeshEstimate(limit, fine_limit)
    bound = float(e.bound)
    if not np.isfinite(bound) or bound >= abs(limit - width):
        return "undetermined", (
            f"mesh: {on_h} on this mesh and on one twice as fine, but the limit is only"
            f" {pct(abs(limit - width) / abs(limit))} of itself {'above' if limit > width else 'below'} the cut,"
            f" inside its discretisation error <= {pct(float(e.relative_bound))}: {advice}"
        )
    return on_h, (
        f"mesh: {mesh_words(model)}; also {on_h2} on a mesh twice as fine; the limit's discretisation error"
        f" <= {pct(float(e.relative_bound))}, less than its distance to the cut"
    )


def converged_tail(model: Any) -> str:
    """ "; a converged mesh: --variant converged" when the model file has that variant (else "")."""
    v = converged_variant(model)
    return f"; a converged mesh: --variant {v}" if v else ""


def _advice(model: Any) -> str:
    v = converged_variant(model)
    return "refine the beams" + (f" or use the {v} variant (--variant {v})" if v else " (elements = N)")


def mesh_verdict(
    model: Any, verdict: str, margin: float, fine_verdict: str, fine_margin: float
) -> tuple[str, str]:
    """The verdict of a model with beams from its verdict and margin on h and
    on h/2 (margin: the rightmost real part, 1/s, negative when stable), and
    one line why.

    * the two verdicts differ: ``undetermined``;
    * they agree but the margin's error bound (Eq. M3) reaches the margin
      (|a_h| <= 2 |a_{h/2} - a_h|): ``undetermined`` -- the sign of the
      margin on the continuum is not established;
    * otherwise the verdict stands.
    An undetermined coarse verdict stays undetermined."""
    advice = _advice(model)
    if verdict == "undetermined":
        return verdict, f"mesh: {mesh_words(model)}; undetermined already on this mesh"
    if fine_verdict != verdict:
        return "undetermined", (
            f"mesh: {verdict} on this mesh, {fine_verdict} on a mesh twice as fine: {advice}"
        )
    e = MeshEstimate(margin, fine_margin)
    bound = float(e.bound)
    if not np.isfinite(bound) or bound >= abs(margin):
        return "undetermined", (
            f"mesh: {verdict} on this mesh and on one twice as fine, but the margin {margin:.4g} 1/s"
            f" is within its discretisation error <= {bound:.2g} 1/s (twice its change {float(e.change):+.2g}"
            f" 1/s on the finer mesh): {advice}"
        )
    return verdict, (
        f"mesh: {mesh_words(model)}; also {fine_verdict} on a mesh twice as fine (margin {fine_margin:.4g}"
        f" 1/s); the margin's discretisation error <= {bound:.2g} 1/s, below |margin|"
    )
