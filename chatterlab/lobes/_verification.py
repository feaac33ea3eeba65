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

__all__ = ["verify_diagram", "multi_delay_count", "VERIFY_OFFSET"]

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
    sampled (a machine with actuators whose delay differs from the cut's:
    :func:`multi_delay_count`)."""
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
    # a loop with an actuator's own delay beside the cut's has several delays: counted
    # against the machine with its actuators (multi_delay_count), the rest as before
    multi = [k for k, sy in enumerate(systems) if sy.multi_delay]
    if not multi:
        counts = rhp_counts(systems)
    else:
        single = [k for k in range(len(systems)) if k not in set(multi)]
        got = dict(zip(single, rhp_counts([systems[k] for k in single]), strict=True))
        got.update((k, multi_delay_count(systems[k])) for k in multi)
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


# ---------------------------------------------------------------------------- several delays
class _Peeled:
    """The loop transfer of one delay peeled off a system with several:
    H(lam) = V_*^T Delta_c(lam)^-1 U_*, Delta_c the system without the
    delayed term of delay ``tau`` (the columns U_*, V_*), so that det Delta =
    det Delta_c det(I - H e^{-lam tau}).  It offers what the factored phase
    sampling of :mod:`chatterlab.frequency._phase_sampling` reads of a
    system: ``tau``, ``r``, ``transfer_fast`` and ``loop_eigenvalues``."""

    def __init__(self, ref: Any, U: np.ndarray, V: np.ndarray, tau: float) -> None:
        self.ref, self.U, self.V, self.tau = ref, U, V, float(tau)
        self.r = int(U.shape[1])

    def transfer_fast(self, lam: Any) -> np.ndarray:
        from ..frequency._delay_system import batched_solve

        lam = np.asarray(lam, dtype=complex)
        D = self.ref.delta(lam)
        X = batched_solve(D, np.broadcast_to(self.U.astype(complex), D.shape[:-1] + (self.r,)))
        return np.asarray(np.einsum("ki,...kj->...ij", self.V, X))

    def loop_eigenvalues(self, lam: Any) -> np.ndarray:
        H = self.transfer_fast(np.asarray(lam, dtype=complex))
        with np.errstate(all="ignore"):
            if self.r == 1:
                return np.asarray(H[:, :, 0])
            mu = np.full(H.shape[:2], np.nan + 0j)
            ok = np.all(np.isfinite(H), axis=(1, 2))
            if np.any(ok):
                mu[ok] = np.linalg.eigvals(H[ok])
            return mu


def multi_delay_count(sys: Any) -> Any:
    """The number of right-half-plane roots of a system with several delays
    (:attr:`chatterlab.frequency.DelaySystem.taus`), by the argument principle
    against the system without its longest delay.

    With U_*, V_* the columns of the longest delay tau_* and Delta_c the rest
    (the machine with its actuators and the cut's undelayed terms: fewer
    delays), det Delta = det Delta_c det(I - H e^{-lam tau_*}), H = V_*^T
    Delta_c^-1 U_* -> 0 as |lam| -> oo in Re lam >= 0 (Delta_c is of
    retarded type, its leading term lam^2 M).  So, along the imaginary axis
    (conjugate symmetry: from 0 upwards),

        Z(Delta) = Z(Delta_c) - (1/pi) Delta_0^oo arg det(I - H e^{-j w tau_*}),

    Z(Delta_c) counted the same way (:func:`chatterlab.frequency.rhp_count`,
    proven, once one delay is left), the phase of det(I - H e^{-j w tau_*})
    sampled by the factored route of :mod:`chatterlab.frequency._phase_sampling`
    (the step pi / (8 tau_*) where the spectral radius of H reaches 1/2,
    exact increments elsewhere, bisection while a wrapped increment exceeds
    pi/4) with H from a solve of Delta_c at each sample: sampled, not proven
    (``proven`` False).  A root of Delta_c on the axis makes it ``marginal``."""
    from dataclasses import replace as _replace

    from ..frequency._phase_sampling import MAX_SAMPLES, Sampler, band_end, initial_grid, phase_change, refine
    from ..frequency._winding import WindingResult, rhp_count

    taus = np.asarray(sys.taus, dtype=float)
    top = float(taus.max())
    cut = taus == top
    rest = ~cut
    r_taus = taus[rest]
    if np.all(r_taus == r_taus[0]):
        ref = _replace(sys, U=sys.U[:, rest], V=sys.V[:, rest], tau=float(r_taus[0]), taus=None, _cache={})
        ref = _replace(ref, B=_b_of(sys, rest), Cz=sys.Cz[rest], _cache={})
        zc = rhp_count(ref)
    else:
        ref = _replace(
            sys, U=sys.U[:, rest], V=sys.V[:, rest], tau=float(r_taus.max()), taus=r_taus, _cache={}
        )
        ref = _replace(ref, B=_b_of(sys, rest), Cz=sys.Cz[rest], _cache={})
        zc = multi_delay_count(ref)
    peeled = _Peeled(ref, sys.U[:, cut], sys.V[:, cut], top)
    p = np.concatenate([ref.delay_free_poles(), sys.open_loop_poles()])
    scale = max(float(np.max(np.abs(p))) if p.size else 1.0, 1e-300)
    what = f"Z = Z(without the {top:.4g} s delay) - winding"
    if zc.status != "converged":
        return _replace(zc, message=f"{what}: the system without it: {zc.message}", proven=False)
    W, found = band_end(peeled, "factored", None, p, scale)  # type: ignore[arg-type]
    if not found:
        return WindingResult(-1, zc.open_loop_count, 0, float("nan"), "not_converged",
                             f"{what}: |H| does not decay", W, zc.delay_free_count)  # fmt: skip
    pieces, n0, passive = initial_grid(peeled, "factored", W, p, scale, None)  # type: ignore[arg-type]
    if n0 > MAX_SAMPLES:
        return WindingResult(-1, zc.open_loop_count, 0, float("nan"), "not_converged",
                             f"{what}: {n0} samples needed up to {W:.4g} rad/s", W, zc.delay_free_count)  # fmt: skip
    F = Sampler(peeled, "factored", p, 0.0)  # type: ignore[arg-type]
    w, val, passive_iv, unresolved = refine(F, np.unique(np.concatenate(pieces)), passive)
    total, tail = phase_change(w, val, passive_iv, passive, top)
    winding = total / np.pi
    count_f = zc.count - winding
    count = int(round(count_f))
    absf = np.abs(val)
    status = "converged"
    notes = []
    if unresolved or (val.size and absf[0] <= 1e-12):
        status = "marginal"
        notes.append("a root lies on (or within ~1e-10 relative of) the imaginary axis")
    if abs(count_f - count) > 0.05 or abs(tail) > np.pi / 4:
        status = "not_converged"
        notes.append(f"winding {winding:.4g} is not an integer (tail phase {tail:.3g} rad)")
    notes.append(
        f"{count} RHP root(s): {what} = {zc.count} - ({winding:.4g}) with {w.size} samples on [0, {W:.4g}] rad/s"
        f" (several delays: the phase of det(I - H e^{{-j w {top:.4g}}}) sampled, not proven; the count"
        f" without it {'proven' if zc.proven else 'sampled'})"
    )
    fin = np.isfinite(val)
    return WindingResult(
        count=count,
        open_loop_count=zc.open_loop_count,
        n_samples=int(w.size),
        min_abs_det=float(absf[fin].min()) if np.any(fin) else float("nan"),
        status=status,
        message="; ".join(notes),
        omega_max=W,
        delay_free_count=zc.delay_free_count,
        winding=winding,
        proven=False,
    )


def _b_of(sys: Any, cols: np.ndarray) -> np.ndarray:
    """The input matrix of the delayed outputs kept (the columns ``cols``)."""
    return np.asarray(sys.B[:, cols])
