"""A milling model file in the Floquet methods' terms.

A model with ``[process] kind = "milling"`` and a ``model = "milling"``
coupling (docs/model-format.md) holds a cutter description
(:class:`chatterlab.model.MillingCut`) and a structure.  The Floquet methods
(:mod:`chatterlab.frequency._floquet`, :mod:`chatterlab.lobes._milling`)
take a milling :class:`~chatterlab.process.ClosedLoop` (the structure's M,
C, K, the map J from its coordinates to the tool's x, y relative to the
workpiece, and the :class:`~chatterlab.process.Milling` cutter as its
process): this module is the one place that turns a model file into it
(:func:`milling_loop_of`), so the CLI and Python users reach the same numbers
from a model file.

The structure is the frozen configuration's independent coordinates:
M = A*, C = B*, K = C* (Eq. 2.23 without feedback) and J the first two rows
of the coupling's map (its CE axes 1 and 2: the feed x and the normal y of
the cutter).

Modal reduction (:func:`reduce_structure`).  The spectral Floquet method
resolves the highest pole of the structure (its elements are sized by
omega_max L), so a beam model's axial and high bending modes, which the cut
barely excites, would cost most of the work.  The structure is therefore
reduced (:meth:`chatterlab.structure.Structure.reduce`) by a Rayleigh-Ritz projection on the
undamped modes below f_keep augmented by the static residual of the tool
point (modal truncation augmentation; Dickens, Nakagawa & Wittbrodt,
Comput. Struct. 62 (1997) 985-998): the kept modes stay exact, the tool
point's static compliance is exact, and what is lost is the dynamics of
the truncated modes, whose error on the tool-point FRF over
[0, f_keep / 2] is computed and reported (``Reduction.frf_error``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import scipy.linalg as sla

from ..errors import InputError
from ..process import ClosedLoop, Milling, milling_loop

#: a direction of the cut this many times stiffer (static compliance) than the other is held rigid
RIGID_RATIO = 1e2

__all__ = [
    "milling_of",
    "milling_loop_of",
    "is_milling",
    "reduce_structure",
    "Reduction",
    "model_milling_loop",
]


def is_milling(model: Any) -> bool:
    """True for a model whose process is milling."""
    p = getattr(model, "process", None)
    return p is not None and p.kind == "milling"


def milling_of(model: Any) -> Milling:
    """The cutter of a model's ``[process] kind = "milling"`` as a
    :class:`~chatterlab.process.Milling` (SI units, radians)."""
    if not is_milling(model):
        raise InputError(f'{model.source}: its [process] is not milling (kind = "milling")')
    return Milling.from_cut(model.process.milling, model.process.speed)


def milling_loop_of(frozen: Any, coupling: str | None = None) -> ClosedLoop:
    """The frozen structure under the cutter of its model's ``model =
    "milling"`` coupling (``coupling`` names it when there are several), as
    the milling :class:`~chatterlab.process.ClosedLoop` the Floquet methods
    take; unreduced (see :func:`reduce_structure`)."""
    cms = [
        c
        for c in frozen.couplings()
        if c.coupling.kind == "milling" and (coupling is None or c.id == coupling)
    ]
    if len(cms) != 1:
        known = [c.id for c in frozen.couplings() if c.coupling.kind == "milling"]
        raise InputError(
            f'{frozen.model.source}: the Floquet methods take one model = "milling" coupling'
            f" (found {', '.join(known) or 'none'}); name it with coupling="
        )
    cm = cms[0]
    J = np.asarray(cm.J, dtype=float)[:2]
    if not np.any(J):
        raise InputError(f"{frozen.model.source}: the milling coupling's tool point does not move")
    return milling_loop(frozen.structure, milling_of(frozen.model), J, frozen=frozen)


@dataclass(frozen=True)
class Reduction:
    """What :func:`reduce_structure` kept and what it costs.

    ``kept``: modes kept (below ``f_keep``, Hz) of ``n_full`` coordinates,
    plus ``augment`` static residual vectors; ``frf_error``: the largest
    error of the tool-point FRF over ``[0, f_keep / 2]`` relative to its
    peak, against the full structure; ``omega_max``: the highest pole
    before and after, rad/s."""

    n_full: int
    kept: int
    augment: int
    f_keep: float
    frf_error: float
    omega_max_full: float
    omega_max: float
    rigid: int = 0  #: directions of the cut held rigid (over RIGID_RATIO times stiffer)

    def note(self) -> str:
        held = (
            f"; {self.rigid} direction(s) over {RIGID_RATIO:g} times stiffer held rigid" if self.rigid else ""
        )
        return (
            f"structure reduced from {self.n_full} coordinates to {self.kept} modes below"
            f" {self.f_keep:.4g} Hz + {self.augment} static vectors{held} (tool-point FRF error"
            f" {self.frf_error:.1e} of its peak up to {self.f_keep / 2:.4g} Hz; the error of a_lim is"
            " not bounded by it: compare another f_keep)"
        )


def reduce_structure(S: ClosedLoop, f_keep: float | None = None) -> tuple[ClosedLoop, Reduction]:
    """A milling loop whose structure is reduced to its undamped modes below
    ``f_keep`` (Hz) and the static residual of the tool point
    (:meth:`chatterlab.structure.Structure.reduce`), with what was kept and
    the truncation error.

    Default ``f_keep``: 4 x the highest natural frequency among the modes
    that carry at least 5 % of the tool point's static compliance (its
    trace over the cut's directions: the modes the cut can excite)."""
    lam, Phi = sla.eigh(S.K, S.M)  # mass-normalised: Phi^T M Phi = I
    lam = np.maximum(lam, np.finfo(float).tiny)
    f = np.sqrt(lam) / (2 * np.pi)
    # a direction of the cut RIGID_RATIO times stiffer than the other (a planar tool's axis) is held
    # rigid: its static residual would be a pseudo-mode far above the band that sets the spectral
    # mesh; what that drops is in the FRF error reported below (against the full structure)
    full_S = S
    G0 = S.J @ np.linalg.solve(S.K, S.J.T)
    g, U = np.linalg.eigh(0.5 * (G0 + G0.T))
    stiff = g < g.max() / RIGID_RATIO
    rigid = int(np.count_nonzero(stiff & (np.abs(g) > 0)))
    if np.any(stiff):
        Uf = U[:, ~stiff]
        S = replace(S, J=Uf @ (Uf.T @ S.J))
    if f_keep is None:
        contrib = np.sum((S.J @ Phi) ** 2, axis=0) / lam  # static compliance carried by each mode
        f_keep = 4.0 * float(f[contrib >= 0.05 * contrib.sum()].max())
    kept = int(np.count_nonzero(f < f_keep))
    full = float(full_S.omega_max)
    if kept >= S.n - S.J.shape[0] and not rigid:  # nothing to gain
        return S, Reduction(S.n, S.n, 0, float(f_keep), 0.0, full, full)
    red, T = S.structure.reduce(f_keep, S.J.T)
    R = replace(S, structure=red, J=S.J @ T, force=T.T @ S.force, frozen=None)
    # the error of everything done here, against the full structure and both directions
    w = 2 * np.pi * np.linspace(0.0, f_keep / 2, 400)
    H, Hr = full_S.frf(w), R.frf(w)
    err = float(np.max(np.abs(H - Hr)) / np.max(np.abs(H)))
    return R, Reduction(S.n, kept, R.n - kept, float(f_keep), err, full, float(R.omega_max), rigid)


def model_milling_loop(frozen: Any) -> tuple[ClosedLoop, Reduction | None]:
    """The milling loop of a model's frozen configuration as every route
    analyses it: :func:`milling_loop_of`, and a structural model (not modal,
    not given by matrices) reduced to the modes that matter
    (:func:`reduce_structure`; its :class:`Reduction`, None when not
    reduced)."""
    S = milling_loop_of(frozen)
    model = frozen.model
    if model.modes or model.is_matrix_model:
        return S, None
    return reduce_structure(S)
