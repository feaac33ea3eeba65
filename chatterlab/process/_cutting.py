"""The cutting process as feedback: D(s) = D_P + s D_V + D_O e^{-sT}.

Each coupling element (CE) of the model contributes, at width of cut b,

    D(s) = -(b / b_ref) J^T (D_P,l + s D_V,l + D_O,l e^{-sT}) J       (Eq. 2.23, 3.5)

to the feedback matrix of the reduced (independent) coordinates, where J
maps q_i to the CE's relative displacement dw = w_a - w_b in CE axes.  With
the sign of Eq. (2.1), the closed-loop characteristic matrix is

    Delta(s) = s^2 A* + s (B* - D_V) + C* - D_P - D_O e^{-sT}.

The delayed term acts only through the few CE coordinates, so D_O is kept in
factored form U V^T (rank 1 for the paper's shaping process: only the chip
thickness is regenerated).

Which terms are switched on follows the paper's three cases: ``"none"`` (a,
no feedback), ``"pd"`` (b, proportional + ideal derivative: inner
modulation) and ``"pdo"`` (c, + delayed: inner and outer modulation).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from ..errors import InputError, check_delay, check_speed, check_width, warn_width
from ..model._items import Process
from ..structure._assembly import FrozenSystem

__all__ = ["Feedback", "feedback", "delay_for", "ce_maps", "TERMS"]

TERMS = ("none", "pd", "pdo", "o")


@dataclass(frozen=True, eq=False)
class Feedback:
    """D(s) of the whole system in reduced coordinates at one (b, T).

    Attributes
    ----------
    DP, DV, DO : ndarray, shape (n_i, n_i)
        Proportional, ideal-derivative and delayed feedback matrices (E = D q).
    U, V : ndarray, shape (n_i, r)
        Low-rank factors with DO = U V^T.
    J : ndarray, shape (3 m, n_i)
        Stacked CE maps (relative displacements of the m CEs).
    Dl : callable
        ``Dl(s)`` -> (3m, 3m) block-diagonal CE matrices at width b, so that
        D(s) = -J^T Dl(s) J.
    force : ndarray, shape (n_i,)
        Static (desired) CE forces as generalised forces, N.
    width : float
        Width of cut b, m.
    delay : float or None
        T, s (None when no delayed term is on).
    terms : str
        ``"none"``, ``"pd"``, ``"pdo"`` or ``"o"`` (delayed only).
    """

    DP: np.ndarray
    DV: np.ndarray
    DO: np.ndarray
    U: np.ndarray
    V: np.ndarray
    J: np.ndarray
    Dl_P: np.ndarray
    Dl_V: np.ndarray
    Dl_O: np.ndarray
    force: np.ndarray
    width: float
    delay: float | None
    terms: str

    @property
    def n(self) -> int:
        return self.DP.shape[0]

    def __call__(self, s: complex | np.ndarray) -> np.ndarray:
        """D(s), shape (n_i, n_i) or (len(s), n_i, n_i)."""
        sa = np.asarray(s, dtype=complex)
        e = np.exp(-sa * self.delay) if self.delay is not None else np.zeros_like(sa)
        out = self.DP + sa[..., None, None] * self.DV + e[..., None, None] * self.DO
        return out

    def Dl(self, s: complex | np.ndarray) -> np.ndarray:
        """The CE matrices Dl(s) (3m, 3m), so that D(s) = -J^T Dl(s) J."""
        sa = np.asarray(s, dtype=complex)
        e = np.exp(-sa * self.delay) if self.delay is not None else np.zeros_like(sa)
        return self.Dl_P + sa[..., None, None] * self.Dl_V + e[..., None, None] * self.Dl_O

    @property
    def is_zero(self) -> bool:
        return not (np.any(self.DP) or np.any(self.DV) or np.any(self.DO))


def delay_for(
    process: Process | None, *, speed: float | None = None, delay: float | None = None
) -> float | None:
    """The delay T (s) from a speed through the process kinematics, or as
    given.  Exactly one of ``speed`` and ``delay`` may be given; with
    neither, the process's default speed is used."""
    if speed is not None and delay is not None:
        raise InputError("give either speed or delay, not both")
    if delay is not None:
        return check_delay(delay)
    if process is None:
        if speed is not None:
            raise InputError(
                "the model has no [process] table, so a speed cannot be turned into a delay; give the delay T"
            )
        return None
    if speed is not None:
        speed = check_speed(speed, unit=process.speed_unit)
    return float(process.delay(speed))


def feedback(
    frozen: FrozenSystem,
    *,
    width: float,
    speed: float | None = None,
    delay: float | None = None,
    terms: Literal["none", "pd", "pdo", "o"] = "pdo",
    couplings: list[str] | None = None,
) -> Feedback:
    """Feedback matrices of the model's coupling elements at width b.

    Parameters
    ----------
    frozen : FrozenSystem
        The configuration (``system.at(s)``).
    width : float
        Width of cut b, m (> 0).  CE matrices scale with b / width_ref.
    speed, delay : float, optional
        The cutting speed in the process's unit (shaping: m/s, turning: rpm)
        or the delay T in s.  Needed when the delayed term is on.
    terms : {"pdo", "pd", "o", "none"}
        Which feedback terms: the paper's case (c), (b), delayed only, (a).
    couplings : list of str, optional
        CE ids to include (default: all).

    Returns
    -------
    Feedback
    """
    width = check_width(width)
    warn_width(width, [c.width_ref for c in frozen.model.couplings])
    return feedback_unwarned(frozen, width=width, speed=speed, delay=delay, terms=terms, couplings=couplings)


def feedback_unwarned(
    frozen: FrozenSystem,
    *,
    width: float,
    speed: float | None = None,
    delay: float | None = None,
    terms: Literal["none", "pd", "pdo", "o"] = "pdo",
    couplings: list[str] | None = None,
) -> Feedback:
    """:func:`feedback` without its :class:`~chatterlab.errors.UnitWarning`:
    for chatterlab's own calls at widths it chose (a lobe diagram's
    argument-principle checks just above and below b_lim, at its width
    ceiling), which no user typed.  The unit warning belongs at the user's
    edge only: :func:`feedback` and the analyses that take a user's width."""
    if terms not in TERMS:
        raise InputError(f"terms must be one of {', '.join(TERMS)} (got {terms!r})")
    width = check_width(width)
    known = [c.id for c in frozen.model.couplings]
    if not known:
        raise InputError(
            f"{frozen.model.source} has no [[coupling]] element: the cutting process needs one"
            " (see docs/model-format.md)"
        )
    if couplings is not None:
        for cid in couplings:
            if cid not in known:
                raise InputError(f"unknown coupling '{cid}' (known: {', '.join(known)})")
    n = frozen.n
    J_all, P, V, O, F = ce_maps(frozen.system, float(width), couplings)
    J = frozen.expand(J_all)
    if terms == "none":
        P, V, O = (np.zeros_like(P),) * 3
    elif terms == "pd":
        O = np.zeros_like(O)
    elif terms == "o":
        P, V = np.zeros_like(P), np.zeros_like(V)
    T = delay_for(frozen.model.process, speed=speed, delay=delay) if np.any(O) else None
    if np.any(O) and T is None:
        raise InputError("the delayed feedback term needs a delay: give speed or delay")
    # low-rank factors of DO = -J^T O J = U V^T
    if np.any(O):
        u, sv, vt = np.linalg.svd(-O)
        r = int(np.sum(sv > 1e-12 * sv[0]))
        U = J.T @ (u[:, :r] * sv[:r])
        Vf = J.T @ vt[:r].T
    else:
        U = np.zeros((n, 0))
        Vf = np.zeros((n, 0))
    return Feedback(
        DP=-J.T @ P @ J,
        DV=-J.T @ V @ J,
        DO=-J.T @ O @ J,
        U=U,
        V=Vf,
        J=J,
        Dl_P=P,
        Dl_V=V,
        Dl_O=O,
        force=J.T @ F,
        width=float(width),
        delay=T,
        terms=terms,
    )


def ce_maps(system: Any, width: float, couplings: list[str] | None = None) -> tuple[np.ndarray, ...]:
    """The coupling elements stacked over *all* coordinates: J (3m, n)
    mapping q to the CE relative displacements in CE axes, the block-diagonal
    D_P, D_V, D_O (3m, 3m) at width b, and the desired forces P0 (3m,) at
    width b.  ``couplings`` selects CEs by id (default: all)."""
    maps = [(c, Jc) for c, Jc in system.coupling_maps if couplings is None or c.id in couplings]
    m = len(maps)
    J = np.zeros((3 * m, system.n))
    P = np.zeros((3 * m, 3 * m))
    V = np.zeros_like(P)
    O = np.zeros_like(P)
    F = np.zeros(3 * m)
    for k, (c, Jc) in enumerate(maps):
        sl = slice(3 * k, 3 * k + 3)
        f = width / c.width_ref
        J[sl] = Jc
        P[sl, sl] = f * np.array(c.DP)
        V[sl, sl] = f * np.array(c.DV)
        O[sl, sl] = f * np.array(c.DO)
        F[sl] = f * np.array(c.forces)
    return J, P, V, O, F
