"""Verification of a lobe diagram by the argument principle, a route
independent of the boundary computation: which speeds are checked and the
count of right-half-plane roots just below and above the envelope and at the
width ceiling.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..process._loop import closed_loop_unwarned
from ..structure._assembly import FrozenSystem
from ._result import LobeDiagram

__all__ = ["verify_diagram", "VERIFY_OFFSET"]

#: relative offset of the verification widths from the envelope
VERIFY_OFFSET = 1e-3


def verify_diagram(
    frozen: FrozenSystem, d: LobeDiagram, count: int, couplings: list[str] | None = None
) -> tuple[dict[str, Any], ...]:
    """The argument-principle checks of a diagram ``d`` computed on another
    route than the frozen system's own (a plant: the structure with a
    machine's actuators, :func:`chatterlab.design.design_lobes`), counted on
    the closed loops of ``frozen`` (:func:`_verify`)."""
    return _verify(frozen, d, count, couplings)


def _check_speeds(d: LobeDiagram, count: int) -> list[tuple[int, str]]:
    """Indices of the speeds checked and what is checked there.

    The global minimum (below and above the envelope), the highest local
    maxima of the sampled envelope (a lobe missed by the boundary search
    shows as a claim that is too high: the risk sits at the cusps between
    lobes), spread local minima (each a lobe's bottom), and the ends of every
    run of ``inf`` (checked at the width ceiling)."""
    b = d.b_lim
    fin = np.isfinite(b)
    out: list[tuple[int, str]] = []
    if np.any(fin):
        jmin = int(np.nanargmin(np.where(fin, b, np.nan)))
        out += [(jmin, "below"), (jmin, "above")]
        bb = np.where(fin, b, -np.inf)
        inner = np.arange(1, b.size - 1)
        peak = inner[(bb[inner] >= bb[inner - 1]) & (bb[inner] >= bb[inner + 1]) & fin[inner]]
        for j in ([0] if fin[0] else []) + ([b.size - 1] if fin[-1] else []):
            peak = np.append(peak, j)
        peak = peak[np.argsort(-b[peak])]
        out += [(int(j), "below") for j in peak[: max(count - 1, 0)] if int(j) != jmin]
        low = inner[(bb[inner] <= bb[inner - 1]) & (bb[inner] <= bb[inner + 1]) & fin[inner]]
        low = low[low != jmin]
        if low.size and count > 2:
            pick = low[np.linspace(0, low.size - 1, min(count // 2, low.size)).astype(int)]
            out += [(int(j), "below") for j in pick]
    inf = ~fin
    if np.any(inf):
        edges = np.nonzero(np.diff(np.r_[False, inf, False].astype(int)))[0]
        for a, e in zip(edges[::2], edges[1::2] - 1, strict=True):
            for j in {int(a), int(e), int((a + e) // 2)}:
                out.append((j, "ceiling"))
    return list(dict.fromkeys(out))


def _verify(
    frozen: FrozenSystem, d: LobeDiagram, count: int, couplings: list[str] | None
) -> tuple[dict[str, Any], ...]:
    """Check the diagram's claims by the argument principle, a route
    independent of the boundary computation: the number of closed-loop roots
    in the right half plane (:func:`chatterlab.frequency.rhp_count`) is
    0 just below the envelope (b = (1 - VERIFY_OFFSET) b_lim) and > 0 just
    above it; where the diagram says ``inf``, 0 at the width ceiling.  Each
    check says whether its count is ``proven`` (every phase increment bounded,
    see :func:`chatterlab.frequency._phase_sampling.certified_phase`) or only
    sampled (a machine with actuators whose delay differs from the cut's: its
    count samples det Delta directly, see :mod:`chatterlab.frequency._delay_system`)."""
    from ..frequency._delay_system import loop_systems
    from ..frequency._winding import rhp_counts

    where = []
    loops = []
    for j, kind in _check_speeds(d, count):
        if kind == "ceiling":
            b, expect = d.width_max, "stable"
        else:
            b = float(d.b_lim[j]) * (1 - VERIFY_OFFSET if kind == "below" else 1 + VERIFY_OFFSET)
            expect = "stable" if kind == "below" else "unstable"
        where.append((j, kind, b, expect))
        loops.append(
            closed_loop_unwarned(frozen, width=b, delay=float(d.delay[j]), terms=d.terms, couplings=couplings)
        )
    # the checks' systems share the structure's open-loop roots (and, without
    # proportional or velocity feedback, the delay-free loop's decomposition),
    # and their phases are certified together: each count is the one
    # rhp_count(loop) gives alone
    systems = loop_systems(loops)
    # a loop with an actuator's own delay beside the cut's has several delays: its phase is
    # sampled on det Delta itself (the factored form multiplies by one scalar delay), not proven
    multi = [k for k, sy in enumerate(systems) if sy.multi_delay]
    if not multi:
        counts = rhp_counts(systems)
    else:
        single = [k for k in range(len(systems)) if k not in set(multi)]
        got = dict(zip(single, rhp_counts([systems[k] for k in single]), strict=True))
        got.update(zip(multi, rhp_counts([systems[k] for k in multi], direct=True), strict=True))
        counts = [got[k] for k in range(len(systems))]
    out = []
    for (j, kind, b, expect), w in zip(where, counts, strict=True):
        if w.status != "converged":
            verdict = "undetermined"
        else:
            verdict = "stable" if w.count == 0 else "unstable"
        out.append(
            {
                "speed": float(d.speed[j]),
                "delay": float(d.delay[j]),
                "width": b,
                "kind": kind,
                "expected": expect,
                "verdict": verdict,
                "rhp_roots": int(w.count),
                # every phase increment bounded (factored form), not only sampled
                "proven": bool(w.proven),
                "agrees": verdict == expect,
            }
        )
    return tuple(out)
