"""One sample, one lobe diagram: the task the sweep engine maps over the
grid (sample, speed).

A grid point's ``sample`` is an evaluation id, ``(replicate, matrix, row)``
packed into one integer (:func:`pack`); the first call for a sample draws
its input point (:class:`~._design.Design`), maps it to field values
(:class:`~._space.InputSpace`), builds the model with those values and
computes its lobe diagram -- with its argument-principle checks -- at every
speed, through the one entry point :func:`chatterlab.lobes.lobes`; the row
is cached in the worker, and the calls for the other speeds of the sample
read it (the engine's chunks hold whole samples).

What samples share is computed once per worker: when only the cut is
uncertain (fields of ``[[coupling]]`` and ``[process]``), the structure --
its assembly, its reduced matrices at the position, its complex modes -- is
the nominal model's, and each sample only swaps the process in
(:meth:`~chatterlab.structure.FrozenSystem.with_process`).
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..model import parameter_overrides
from ..model._items import Model
from ._design import Design
from ._space import InputSpace

__all__ = ["LobeSampleTask", "OUTPUTS", "pack", "unpack", "process_only"]

#: what a task returns per (sample, speed), with units
OUTPUTS = {
    "b_lim": ("m", "limit width of cut of the sample (milling: axial depth)"),
    "chatter_frequency": ("Hz", "chatter frequency at the limit"),
    "claim": ("1", "what the sample's diagram claims (LobeDiagram.CLAIMS)"),
    "b_min": ("m", "the sample's smallest limit over the speed range"),
    "b_abs_min": ("m", "the sample's smallest boundary width over all speeds (nan where not known)"),
    "verified": ("1", "1: every argument-principle check agreed; 0: one contradicted; nan: none ran"),
}

#: parameter kinds that leave the structure as it is (the cut and its kinematics)
_PROCESS_KINDS = ("coupling", "process")

_ROWS: OrderedDict[tuple[Any, ...], dict[str, np.ndarray]] = OrderedDict()
_SHARED: OrderedDict[tuple[Any, ...], Any] = OrderedDict()


def pack(replicate: int, matrix: int, row: int, matrices: int, rows: int) -> int:
    """The evaluation id of (replicate, matrix, row) in a run of ``matrices``
    matrices and ``rows`` rows per replicate at most."""
    return (replicate * matrices + matrix) * rows + row


def unpack(eid: int, matrices: int, rows: int) -> tuple[int, int, int]:
    r_m, row = divmod(int(eid), rows)
    r, m = divmod(r_m, matrices)
    return r, m, row


def process_only(paths: tuple[str, ...]) -> bool:
    """True when every uncertain field belongs to the cut (``[[coupling]]``,
    ``[process]``): the structure is the same in every sample."""
    return all(p.split(".", 1)[0] in _PROCESS_KINDS for p in paths)


@dataclass(frozen=True, eq=False)
class LobeSampleTask:
    """The lobe diagram of sample ``sample`` at ``speed`` (see the module docstring)."""

    model: Model
    space: InputSpace
    design: Design
    rows: int  #: rows per replicate at most (the evaluation ids' stride)
    speeds: tuple[float, ...]  #: every speed computed, in the process's unit
    width_max: float
    position: float | None = None
    options: tuple[tuple[str, Any], ...] = ()
    share: bool = True  #: reuse the structure when only the cut is uncertain
    key: str = field(default="", repr=False)  #: the run's fingerprint (checkpoints; the shared structure)
    run_id: str = field(default="", repr=False)  #: this run (the rows cached in a worker serve it only)

    def values(self, eid: int) -> dict[str, float]:
        """The field values of an evaluation."""
        r, mat, row = unpack(eid, self.design.matrices, self.rows)
        u = self.design.points(r, mat, np.array([row]))
        return dict(zip(self.space.paths, self.space.transform(u)[0].tolist(), strict=True))

    def model_of(self, values: dict[str, float]) -> Model:
        """The model with the sampled field values."""
        return self.model.with_parameters(parameter_overrides(self.model, values))

    def diagram(self, eid: int) -> Any:
        """The sample's lobe diagram (through :func:`chatterlab.lobes.lobes`)."""
        from ..lobes import lobes

        mdl = self.model_of(self.values(eid))
        v = np.asarray(self.speeds, float)
        opts = dict(self.options)
        if self._shared_route():
            frozen = self._nominal_frozen().with_process(mdl)
            return lobes(frozen, v, width_max=self.width_max, **opts)
        return lobes(mdl, v, width_max=self.width_max, position=self.position, **opts)

    def row(self, eid: int) -> dict[str, np.ndarray]:
        key = (self.run_id, int(eid))
        hit = _ROWS.get(key)
        if hit is not None:
            _ROWS.move_to_end(key)
            return hit
        from ..selection._recommend import stable_width

        d = self.diagram(eid)
        n = len(self.speeds)
        ver = d.verified
        absmin = d.absolute_minimum.get("width", np.nan) if d.absolute_minimum else np.nan
        # the limits on the diagram's own claim: NaN (undetermined) where it establishes nothing -- no
        # boundary in a band not proven, contradicted by a check, the zeroth-order approximation's --
        # never counted as stable; nor is its minimum over the speeds then
        known = np.isfinite(stable_width(d)[0])
        out = {
            "b_lim": np.where(known, np.asarray(d.b_lim, float), np.nan),
            "chatter_frequency": np.asarray(d.chatter_hz, float),
            "claim": np.asarray(d.claim, float),
            "b_min": np.full(n, float(d.minimum["width"]) if known.all() else np.nan),
            "b_abs_min": np.full(n, float(absmin)),
            "verified": np.full(n, np.nan if ver is None else float(ver)),
        }
        _ROWS[key] = out
        if len(_ROWS) > 64:
            _ROWS.popitem(last=False)
        return out

    def __call__(self, sample: float, speed: float) -> dict[str, float]:
        row = self.row(int(sample))
        j = self._index()[float(speed)]
        return {k: float(v[j]) for k, v in row.items()}

    # ------------------------------------------------------------------ shared work
    def _index(self) -> dict[float, int]:
        idx = self.__dict__.get("_idx")
        if idx is None:
            idx = {float(v): j for j, v in enumerate(self.speeds)}
            object.__setattr__(self, "_idx", idx)
        return idx

    def _shared_route(self) -> bool:
        """The D-subdivision route of a structural, matrix or modal model
        whose uncertain fields are all the cut's."""
        m = self.model
        milling = m.process is not None and m.process.kind == "milling"
        return self.share and m.frf is None and not milling and process_only(self.space.paths)

    def _nominal_frozen(self) -> Any:
        key = (self.key, self.position)
        hit = _SHARED.get(key)
        if hit is None:
            from ..structure import assemble

            hit = assemble(self.model).at(self.position)
            hit.complex_modes  # noqa: B018 -- computed once, shared by the samples
            _SHARED[key] = hit
            if len(_SHARED) > 4:
                _SHARED.popitem(last=False)
        return hit

    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        state.pop("_idx", None)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
