"""The discretisation error of a lobe diagram of a model with beams.

The absolute minimum b_lim (and the envelope at the diagram's delays) is
computed again on the mesh twice as fine (:meth:`Model.with_finer_mesh`)
with the same boundary engine (:class:`~chatterlab.lobes.Boundary`, no
argument-principle checks: they confirm a boundary, they do not move it),
and the bound of :mod:`chatterlab.model._mesh` (docs/lobes.md, Eq. M3) is
put in the diagram's ``meta``: the summary prints it as one line and the
netCDF file carries it as attributes (``mesh_*``).
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any

import numpy as np

from ..frequency._delay_system import single_threaded
from ..model._mesh import MeshEstimate, converged_tail, envelope_record, mesh_record, mesh_words, pct
from ..structure._assembly import FrozenSystem, assemble
from ._damped import Boundary
from ._result import LobeDiagram

__all__ = ["with_mesh_error", "mesh_line", "not_estimated"]


@single_threaded
def with_mesh_error(
    diagram: LobeDiagram,
    frozen: FrozenSystem,
    *,
    fmin: float | None = None,
    fmax: float | None = None,
    couplings: list[str] | None = None,
) -> LobeDiagram:
    """``diagram`` (computed on ``frozen``) with its discretisation error in
    ``meta`` when the model has beams; unchanged otherwise.

    meta (SI): ``mesh_beam_elements``; ``mesh_fine_beam_elements``;
    ``mesh_fine_absolute_min_m`` (the absolute minimum on h/2);
    ``mesh_absolute_min_change`` (its change, relative to the minimum on h);
    ``mesh_absolute_min_error_bound`` (Eq. M3, relative); ``mesh_order``
    (the order p assumed); ``mesh_envelope_change_median`` and ``_max``
    (|b_{h/2} - b_h| / b_h over the ``mesh_envelope_speeds`` speeds where
    both meshes have a limit below the ceiling: a change, not a bound --
    where the lobe that sets the envelope changes between the meshes the
    asymptotic model of Eq. M1 does not hold per speed); ``mesh_seconds``
    (the cost); ``mesh_free_speeds`` (speeds with no limit below the
    ceiling on h: a claim of no chatter) and ``mesh_free_speeds_fine_limited``
    (how many of them have a limit on h/2: the claim is not established
    there); ``mesh`` (the line)."""
    model = frozen.model
    if not model.beams:
        return diagram
    t0 = time.perf_counter()
    fine = model.with_finer_mesh()
    fz = assemble(fine).at(frozen.position)
    bd = Boundary(
        fz, width_max=diagram.width_max, terms=diagram.terms, fmin=fmin, fmax=fmax, couplings=couplings
    )
    b_fine, _, _ = bd.envelope(np.asarray(diagram.delay, float))
    am = bd.absolute_minimum()
    est = MeshEstimate(diagram.absolute_minimum["width"], am["width"])
    # the speeds that end at the ceiling (a claim of no chatter below it) where the finer mesh has a limit
    free = np.isinf(np.asarray(diagram.b_lim, float)) & (
        np.asarray(diagram.kind).astype(str) != "undetermined"
    )
    meta: dict[str, Any] = {
        **mesh_record(model),
        "mesh_fine_absolute_min_m": float(am["width"]),
        "mesh_fine_absolute_min_chatter_hz": float(am["chatter_hz"]),
        "mesh_absolute_min_change": float(est.relative_change),
        "mesh_absolute_min_error_bound": float(est.relative_bound),
        **envelope_record(diagram.b_lim, b_fine, free, "speeds"),
    }
    meta["mesh_seconds"] = time.perf_counter() - t0
    meta["mesh"] = mesh_line(meta, model, diagram.limit_name)
    return dataclasses.replace(diagram, meta={**estimated(diagram.meta), **meta})


def estimated(meta: dict[str, Any]) -> dict[str, Any]:
    """``meta`` without the mark of :func:`not_estimated`: a diagram computed
    without its mesh check and given it afterwards."""
    return {k: v for k, v in meta.items() if k != "mesh_estimated"}


def not_estimated(
    model: Any, how: str = "lobes(..., mesh_error=True) or the lobes command estimate it"
) -> dict[str, Any]:
    """The meta of a diagram of a model with beams computed without its mesh
    check (:func:`with_mesh_error`, :func:`milling_with_mesh_error`): the
    summary's line that says what it does not say (``how``: how to have it
    estimated) and ``mesh_estimated = 0``, from which the figure says it
    too."""
    return {
        "mesh": f"mesh: {mesh_words(model)}; its discretisation error was not estimated ({how})",
        "mesh_estimated": 0,
    }


def mesh_line(meta: dict[str, Any], model: Any, limit: str = "b_lim") -> str:
    """The summary's line: the minimum on the mesh twice as fine, the bound
    of the error of this diagram's minimum, and how far its envelope moves."""
    b2 = meta["mesh_fine_absolute_min_m"]
    if not np.isfinite(b2):
        head = f"twice as fine: no {limit} below the ceiling; no estimate of the minimum's error"
    elif not np.isfinite(meta["mesh_absolute_min_error_bound"]):  # a minimum on h/2 only
        head = (
            f"twice as fine: min {limit} {b2 * 1e3:.4g} mm, where this mesh has none below the ceiling:"
            " this diagram is not converged"
        )
    else:
        head = (
            f"twice as fine: min {limit} {b2 * 1e3:.4g} mm ({pct(meta['mesh_absolute_min_change'], '+')}),"
            f" discretisation error of this diagram's minimum <= {pct(meta['mesh_absolute_min_error_bound'])}"
        )
    env = ""
    if np.isfinite(meta["mesh_envelope_change_median"]):
        env = (
            f"; its envelope moves by {pct(meta['mesh_envelope_change_median'])} (median over"
            f" {meta['mesh_envelope_speeds']} speeds), up to {pct(meta['mesh_envelope_change_max'])}"
        )
    lost = ""
    if meta.get("mesh_free_speeds_fine_limited"):
        lost = (
            f"; at {meta['mesh_free_speeds_fine_limited']} of the {meta['mesh_free_speeds']} speeds with no {limit}"
            " below the ceiling the mesh twice as fine finds one: their stability is not established"
        )
    return f"mesh: {mesh_words(model)}; {head}{env}{lost}{converged_tail(model)}"
