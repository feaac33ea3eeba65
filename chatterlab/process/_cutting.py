"""The model's coupling elements stacked for the cutting process: :func:`ce_maps`.

Each coupling element (CE) of the model contributes, at width of cut b,

    D(s) = -(b / b_ref) J^T (D_P,l + s D_V,l + D_O,l e^{-sT}) J       (Eq. 2.23, 3.5)

to the feedback matrix of the reduced (independent) coordinates, where J
maps q to the CE's relative displacement dw = w_a - w_b in CE axes.  The
closed loop that uses them is :class:`chatterlab.process.ClosedLoop`
(:mod:`chatterlab.process._loop`); the time domain stacks them over all
coordinates for the moving slide (Eq. 2.28).

Which terms are switched on follows the paper's three cases: ``"none"`` (a,
no feedback), ``"pd"`` (b, proportional + ideal derivative: inner
modulation) and ``"pdo"`` (c, + delayed: inner and outer modulation).
"""

from __future__ import annotations

from typing import Any

import numpy as np

# the closed loop's names under their 0.2 spelling, for the callers not yet moved
from ._loop import TERMS, delay_for
from ._loop import ClosedLoop as Feedback
from ._loop import closed_loop as feedback
from ._loop import closed_loop_unwarned as feedback_unwarned

__all__ = ["Feedback", "feedback", "feedback_unwarned", "delay_for", "ce_maps", "TERMS"]


def ce_maps(system: Any, width: float, couplings: list[str] | None = None) -> tuple[np.ndarray, ...]:
    """The coupling elements stacked over *all* coordinates: J (3m, n)
    mapping q to the CE relative displacements in CE axes, the block-diagonal
    D_P, D_V, D_O (3m, 3m) at width b, and the desired forces P0 (3m,) at
    width b.  ``couplings`` selects CEs by id (default: all)."""
    maps = [(c, Jc) for c, Jc in system.coupling_maps if couplings is None or c.id in couplings]
    m = len(maps)
    H0 = _milling_zoa(system.model) if any(c.kind == "milling" for c, _ in maps) else None
    J = np.zeros((3 * m, system.n))
    P = np.zeros((3 * m, 3 * m))
    V = np.zeros_like(P)
    O = np.zeros_like(P)
    F = np.zeros(3 * m)
    for k, (c, Jc) in enumerate(maps):
        sl = slice(3 * k, 3 * k + 3)
        f = width / c.width_ref
        J[sl] = Jc
        if c.kind == "milling":  # the cutter's time-averaged feedback, per metre of a_p
            assert H0 is not None
            P[3 * k : 3 * k + 2, 3 * k : 3 * k + 2] = width * H0
            O[3 * k : 3 * k + 2, 3 * k : 3 * k + 2] = -width * H0
        else:
            P[sl, sl] = f * np.array(c.DP)
            V[sl, sl] = f * np.array(c.DV)
            O[sl, sl] = f * np.array(c.DO)
        F[sl] = f * np.array(c.forces)
    return J, P, V, O, F


def _milling_zoa(model: Any) -> np.ndarray:
    """H0 of the model's cutter (N/m^2, 2x2): a ``model = "milling"``
    coupling feeds the frequency-domain engines the zeroth-order (averaged)
    cut, F = -a_p H0 [dw(t) - dw(t - tau)] on the tool: D_P = H0 and
    D_O = -H0 per metre of a_p in the feed (CE axis 1) / normal (CE axis 2)
    plane (Altintas & Budak 1995; :meth:`chatterlab.process.Milling.zoa`)."""
    from ._milling import Milling

    return Milling.from_cut(model.process.milling).zoa()
