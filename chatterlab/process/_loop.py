"""The closed loop: the frozen structure with the cutting process in it.

Every engine of chatterlab -- the closed-loop FRF, the characteristic roots
and the argument principle, the lobe engine's checks, the time-domain
verdict's roots -- consumes one value, :class:`ClosedLoop`: the structure's
matrices at one configuration (M, C, K: mass, damping, stiffness on the
independent coordinates, Eq. 2.16-2.18 of the seed paper, where they are
written A*, B*, C*), the map J from those coordinates to the coupling
elements' relative displacements r = J q (CE axes), and the cutting
process's matrices on r at the loop's width of cut b:

    E(s) = D(s) q(s),   D(s) = -J^T (P + s V + O e^{-sT}) J            (Eq. 2.23)

so that the characteristic matrix of the closed loop (Eq. 2.1) is

    Delta(s) = s^2 M + s C + K - D(s).

:func:`coupling_matrix` is the one evaluation of P + s V + O e^{-sT} in the
package; :meth:`ClosedLoop.D` and :meth:`ClosedLoop.Dl` are it in the two
coordinate systems.  The delayed term acts only through the few CE
coordinates, so D_O = -J^T O J is kept in factored form U V^T as well (rank 1
for the paper's shaping process: only the chip thickness is regenerated).

A speed becomes a delay in one place, the model's process kinematics
(:meth:`chatterlab.model.Process.delay`), through :func:`delay_for`.

References
----------
.. [1] E. Wittbrodt, K. J. Kaliński, "Transient vibration of unsteady linear
   closed loop systems" (the seed paper), Eqs. 2.1, 2.16-2.18, 2.22-2.25, 3.5.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Literal

import numpy as np

from ..errors import InputError, check_delay, check_speed, check_width, warn_width
from ..model._items import Process
from ..structure._assembly import FrozenSystem

__all__ = ["ClosedLoop", "closed_loop", "closed_loop_unwarned", "coupling_matrix", "delay_for", "TERMS"]

#: which feedback terms are on: the paper's cases (a) none, (b) proportional +
#: ideal derivative, (c) all three; "o": the delayed term only
TERMS = ("none", "pd", "pdo", "o")


def coupling_matrix(
    s: complex | np.ndarray, P: np.ndarray, V: np.ndarray, O: np.ndarray, delay: float | None
) -> np.ndarray:
    """P + s V + O e^{-sT}, shape ``s.shape + P.shape``: the one evaluation
    of the cutting process's feedback in chatterlab (without a delay, T =
    None, the delayed term is absent)."""
    sa = np.asarray(s, dtype=complex)
    e = np.exp(-sa * delay) if delay is not None else np.zeros_like(sa)
    return P + sa[..., None, None] * V + e[..., None, None] * O


@dataclass(frozen=True, eq=False)
class ClosedLoop:
    """The frozen structure under the cutting process at one (b, T).

    Attributes
    ----------
    frozen : FrozenSystem
        The structure at its configuration (names, points, modes).
    J : ndarray, shape (3 m, n)
        Stacked CE maps: the relative displacements of the m coupling
        elements in CE axes from the independent coordinates.
    Dl_P, Dl_V, Dl_O : ndarray, shape (3 m, 3 m)
        Block-diagonal CE matrices at width b, so that
        D(s) = -J^T (Dl_P + s Dl_V + Dl_O e^{-sT}) J.
    force : ndarray, shape (n,)
        Static (desired) CE forces as generalised forces, N.
    width : float
        Width of cut b, m.
    delay : float or None
        T, s (None when no delayed term is on).
    terms : str
        ``"none"``, ``"pd"``, ``"pdo"`` or ``"o"`` (delayed only).
    """

    frozen: FrozenSystem
    J: np.ndarray
    Dl_P: np.ndarray
    Dl_V: np.ndarray
    Dl_O: np.ndarray
    force: np.ndarray
    width: float
    delay: float | None
    terms: str

    # ------------------------------------------------------------- the structure
    @property
    def M(self) -> np.ndarray:
        """Mass matrix M (A* of Eq. 2.16), kg, (n, n)."""
        return self.frozen.A

    @property
    def C(self) -> np.ndarray:
        """Damping matrix C (B* of Eq. 2.17), N s/m, (n, n)."""
        return self.frozen.B

    @property
    def K(self) -> np.ndarray:
        """Stiffness matrix K (C* of Eq. 2.18), N/m, (n, n)."""
        return self.frozen.C

    @property
    def n(self) -> int:
        return int(self.J.shape[1])

    @property
    def position(self) -> float | None:
        return self.frozen.position

    # ------------------------------------------------------------- the process
    def Dl(self, s: complex | np.ndarray) -> np.ndarray:
        """The CE matrices P + s V + O e^{-sT}, shape (..., 3m, 3m), so
        that D(s) = -J^T Dl(s) J."""
        return coupling_matrix(s, self.Dl_P, self.Dl_V, self.Dl_O, self.delay)

    def D(self, s: complex | np.ndarray) -> np.ndarray:
        """D(s) on the independent coordinates, shape (..., n, n) (Eq. 2.23)."""
        return coupling_matrix(s, self.DP, self.DV, self.DO, self.delay)

    def __call__(self, s: complex | np.ndarray) -> np.ndarray:
        """D(s): see :meth:`D`."""
        return self.D(s)

    @cached_property
    def DP(self) -> np.ndarray:
        """Proportional feedback D_P = -J^T P J, N/m, (n, n)."""
        return -self.J.T @ self.Dl_P @ self.J

    @cached_property
    def DV(self) -> np.ndarray:
        """Ideal-derivative feedback D_V = -J^T V J, N s/m, (n, n)."""
        return -self.J.T @ self.Dl_V @ self.J

    @cached_property
    def DO(self) -> np.ndarray:
        """Delayed feedback D_O = -J^T O J, N/m, (n, n)."""
        return -self.J.T @ self.Dl_O @ self.J

    @cached_property
    def _factors(self) -> tuple[np.ndarray, np.ndarray]:
        n = self.n
        if not np.any(self.Dl_O):
            return np.zeros((n, 0)), np.zeros((n, 0))
        u, sv, vt = np.linalg.svd(-self.Dl_O)
        r = int(np.sum(sv > 1e-12 * sv[0]))
        return self.J.T @ (u[:, :r] * sv[:r]), self.J.T @ vt[:r].T

    @property
    def U(self) -> np.ndarray:
        """Left factor of D_O = U V^T, (n, r)."""
        return self._factors[0]

    @property
    def V(self) -> np.ndarray:
        """Right factor of D_O = U V^T, (n, r)."""
        return self._factors[1]

    @property
    def is_zero(self) -> bool:
        """No feedback at all (case a, or all CE matrices zero)."""
        return not (np.any(self.Dl_P) or np.any(self.Dl_V) or np.any(self.Dl_O))

    def at(self, *, width: float | None = None, delay: float | None = None) -> ClosedLoop:
        """The same loop at another width b (m) and/or delay T (s): the CE
        matrices scale with b (Eq. 3.5)."""
        f = 1.0 if width is None else check_width(width) / self.width
        T = self.delay if delay is None else check_delay(delay)
        if T is None and np.any(self.Dl_O):
            raise InputError("the delayed feedback term needs a delay")
        return ClosedLoop(
            self.frozen,
            self.J,
            f * self.Dl_P,
            f * self.Dl_V,
            f * self.Dl_O,
            f * self.force,
            self.width if width is None else float(width),
            T if np.any(self.Dl_O) else None,
            self.terms,
        )


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


def closed_loop(
    frozen: FrozenSystem,
    *,
    width: float,
    speed: float | None = None,
    delay: float | None = None,
    terms: Literal["none", "pd", "pdo", "o"] = "pdo",
    couplings: list[str] | None = None,
) -> ClosedLoop:
    """The structure with the model's coupling elements at width b.

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
    ClosedLoop
    """
    width = check_width(width)
    warn_width(width, [c.width_ref for c in frozen.model.couplings])
    return closed_loop_unwarned(
        frozen, width=width, speed=speed, delay=delay, terms=terms, couplings=couplings
    )


def closed_loop_unwarned(
    frozen: FrozenSystem,
    *,
    width: float,
    speed: float | None = None,
    delay: float | None = None,
    terms: Literal["none", "pd", "pdo", "o"] = "pdo",
    couplings: list[str] | None = None,
) -> ClosedLoop:
    """:func:`closed_loop` without its :class:`~chatterlab.errors.UnitWarning`:
    for chatterlab's own calls at widths it chose (a lobe diagram's
    argument-principle checks just above and below b_lim, at its width
    ceiling), which no user typed.  The unit warning belongs at the user's
    edge only: :func:`closed_loop` and the analyses that take a user's width."""
    from ._cutting import ce_maps

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
    return ClosedLoop(frozen, J, P, V, O, J.T @ F, float(width), T, terms)
