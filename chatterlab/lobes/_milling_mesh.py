"""The discretisation error of a milling diagram of a tool with beams
(docs/milling.md, "The beam mesh"; docs/lobes.md, Eqs. M1-M5): the
smallest limit and every speed that ends at the ceiling searched again on
the mesh twice as fine.  The turning/shaping diagram's is
:mod:`chatterlab.lobes._mesh_error`."""

from __future__ import annotations

import dataclasses
import time
from typing import Any

import numpy as np

from ..model._mesh import MeshEstimate, limit_line, mesh_record, mesh_words
from ..structure._assembly import assemble
from ._mesh_error import estimated
from ._milling import milling_lobes
from ._milling_model import model_milling_loop
from ._result import LobeDiagram

__all__ = ["milling_with_mesh_error"]


def milling_with_mesh_error(
    ml: LobeDiagram, model: Any, position: float | None, rpm: Any, **search: Any
) -> LobeDiagram:
    """A milling diagram of a model with beams with its discretisation
    error in ``meta`` (docs/milling.md, "The beam mesh"; docs/lobes.md,
    Eqs. M1-M5): the limit at the speed of the smallest a_lim computed again
    on :meth:`Model.with_finer_mesh` (its change and the bound of Eq. M3),
    and every speed with no limit below the ceiling (a claim of stability)
    searched again there.  The other speeds are not: a Floquet search costs
    seconds per speed on an FE tool, and the line says which were checked.

    ``ml``: the diagram of ``model`` at ``position`` over ``rpm``;
    ``search``: its search options (:func:`chatterlab.lobes.milling_lobes`),
    so that both meshes are searched alike (default: its method and depth
    ceiling)."""
    search.setdefault("depth_max", float(ml.width_max))
    if ml.method in ("spectral", "sdm"):
        search.setdefault("method", ml.method)
    search.pop("progress", None)

    t0 = time.perf_counter()
    basis = np.asarray(ml.basis).astype(str)
    und = basis == "undetermined"
    fin = np.isfinite(ml.b_lim) & ~und
    free = ~np.isfinite(ml.b_lim) & ~und  # "no instability found up to the ceiling"
    idx = np.nonzero(free)[0].tolist()
    j = int(np.argmin(np.where(fin, ml.b_lim, np.inf))) if fin.any() else -1
    if j >= 0:
        idx = sorted({j, *idx})
    meta: dict[str, Any] = mesh_record(model)
    if not idx:  # every speed undetermined: nothing claimed to check
        meta["mesh"] = (
            f"mesh: {mesh_words(model)}; every speed undetermined on this mesh: not checked twice as fine"
        )
        return dataclasses.replace(ml, meta={**estimated(ml.meta), **meta})
    S2 = model_milling_loop(assemble(model.with_finer_mesh()).at(position))[0]
    fine = milling_lobes(S2, np.asarray(rpm, float)[idx], **search)
    at = dict(zip(idx, np.asarray(fine.b_lim, float).tolist(), strict=True))
    parts = []
    lim = ml.limit_name
    if j >= 0:
        est = MeshEstimate(float(ml.b_lim[j]), at[j])
        meta.update({
            "mesh_check_speed_rpm": float(rpm[j]),
            "mesh_fine_min_m": at[j],
            "mesh_min_change": float(est.relative_change),
            "mesh_min_error_bound": float(est.relative_bound),
        })  # fmt: skip
        parts.append(limit_line(model, f"{lim} at {float(rpm[j]):g} rpm", float(ml.b_lim[j]), at[j]))
    if free.any():
        k = np.nonzero(free)[0]
        found = [at[i] for i in k.tolist() if np.isfinite(at[i])]
        meta["mesh_free_speeds"] = int(k.size)
        meta["mesh_free_speeds_fine_limited"] = len(found)
        if found:
            text = (
                f"at {len(found)} of the {k.size} speeds with no {lim} below the ceiling, the mesh twice as fine"
                f" finds one (smallest {min(found) * 1e3:.4g} mm): their stability is not established"
            )
        else:
            text = f"the {k.size} speeds with no {lim} below the ceiling have none on the mesh twice as fine either"
        parts.append(text if parts else f"mesh: {mesh_words(model)}; {text}")
    meta["mesh_seconds"] = time.perf_counter() - t0
    meta["mesh"] = "; ".join(parts) + "; the other speeds were not computed twice as fine"
    return dataclasses.replace(ml, meta={**estimated(ml.meta), **meta})
