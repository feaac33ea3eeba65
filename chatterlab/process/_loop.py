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

from dataclasses import dataclass, replace
from functools import cached_property
from typing import Any, Literal

import numpy as np

from ..errors import InputError, check_delay, check_nonneg, check_speed, check_width, warn_width
from ..model._items import Process
from ..structure._assembly import FrozenSystem
from ..structure._structure import Structure
from ._damping import LoopDamping, damping_term, milling_damping

__all__ = [
    "ClosedLoop",
    "closed_loop",
    "closed_loop_unwarned",
    "milling_loop",
    "coupling_matrix",
    "ce_maps",
    "delay_for",
    "TERMS",
    "Actuators",
    "actuators_of",
]

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
    """The structure under the cutting process at one (b, T).

    Attributes
    ----------
    structure : Structure
        M, C, K on the structure's coordinates (a frozen RDFEM configuration's
        independent ones: :attr:`FrozenSystem.structure`).
    J : ndarray, shape (p, n)
        The process's coordinates r = J q: the stacked relative displacements
        of the m coupling elements in CE axes (p = 3 m), or a milling tool's
        (x, y) relative to the workpiece (p = 2).
    Dl_P, Dl_V, Dl_O : ndarray, shape (p, p)
        The process's matrices on r at width b, so that
        D(s) = -J^T (Dl_P + s Dl_V + Dl_O e^{-sT}) J (for milling the
        time-averaged cut: Dl_P = b H0, Dl_O = -b H0, Eq. 2 of
        :mod:`chatterlab.process._milling`).
    force : ndarray, shape (n,)
        Static (desired) CE forces as generalised forces, N.
    width : float
        Width of cut b (milling: axial depth a_p), m.
    delay : float or None
        T, s (None when no delayed term is on, or for a milling loop not yet
        at a speed).
    terms : str
        ``"none"``, ``"pd"``, ``"pdo"`` or ``"o"`` (delayed only).
    frozen : FrozenSystem or None
        The model's configuration the structure comes from (points, names,
        positions), when there is one.
    process : Milling or None
        A periodic process (the rotating cutter, whose directional matrices
        the Floquet methods integrate over a period); None for a constant
        one (turning, shaping, a given delay).
    actuators : Actuators or None
        The machine's active dampers (``[[actuator]]``): a second coupling
        term of the same loop, with its own gains and delays, which does not
        scale with the width (:class:`Actuators`); :meth:`D` includes it,
        ``DP``, ``DV``, ``DO`` and ``Dl`` are the cutting process's alone.
    damping : LoopDamping or None
        Process damping (``[process_damping]``, :mod:`chatterlab.process._damping`):
        the ideal-derivative term b C_pd / V(T) W that ``Dl_V`` includes, at
        the cutting speed V of the loop's delay; :meth:`at` moves it with the
        width and the delay.  None: no process damping (``Dl_V`` is the
        coupling elements' alone).
    """

    structure: Structure
    J: np.ndarray
    Dl_P: np.ndarray
    Dl_V: np.ndarray
    Dl_O: np.ndarray
    force: np.ndarray
    width: float
    delay: float | None
    terms: str
    frozen: FrozenSystem | None = None
    process: Any = None
    actuators: Actuators | None = None
    damping: LoopDamping | None = None

    # ------------------------------------------------------------- the structure
    @property
    def M(self) -> np.ndarray:
        """Mass matrix M (A* of Eq. 2.16), kg, (n, n)."""
        return self.structure.M

    @property
    def C(self) -> np.ndarray:
        """Damping matrix C (B* of Eq. 2.17), N s/m, (n, n)."""
        return self.structure.C

    @property
    def K(self) -> np.ndarray:
        """Stiffness matrix K (C* of Eq. 2.18), N/m, (n, n)."""
        return self.structure.K

    @property
    def n(self) -> int:
        return int(self.J.shape[1])

    @property
    def name(self) -> str:
        """The structure's label (the model file)."""
        return self.structure.name

    @property
    def position(self) -> float | None:
        return self.frozen.position if self.frozen is not None else None

    @property
    def state_matrix(self) -> np.ndarray:
        """First-order matrix of the free structure, x = (q, q'), (2n, 2n)."""
        return self.structure.state_matrix

    @property
    def omega_max(self) -> float:
        """Largest |Im| of the free structure's poles, rad/s."""
        return self.structure.omega_max

    def stable(self) -> bool:
        """The structure without the process is asymptotically stable."""
        return self.structure.stable()

    def frf(self, omega: np.ndarray) -> np.ndarray:
        """The structure's receptance between the process's coordinates,
        J (K - w^2 M + j w C)^-1 J^T, m/N, shape (len(w), p, p)."""
        return self.structure.receptance(omega, self.J)

    @cached_property
    def cut_basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Ub, Jr, W): r = Ub (Jr q) with Jr (rho, n) of full row rank, and
        W = M^-1 Jr^T (n, rho): the process's coordinates on the rank they
        have (a 1-DOF milling tool moves along one of its two axes)."""
        U, s, Vt = np.linalg.svd(self.J, full_matrices=False)
        rho = int(np.sum(s > 1e-12 * max(s[0], 1e-300)))
        Ub = U[:, :rho]
        Jr = s[:rho, None] * Vt[:rho]
        W = np.linalg.solve(self.M, Jr.T)
        return Ub, Jr, W

    # ------------------------------------------------------------- the process
    def Dl(self, s: complex | np.ndarray) -> np.ndarray:
        """The CE matrices P + s V + O e^{-sT}, shape (..., p, p), so
        that D(s) = -J^T Dl(s) J."""
        self._needs_delay()
        return coupling_matrix(s, self.Dl_P, self.Dl_V, self.Dl_O, self.delay)

    def D(self, s: complex | np.ndarray) -> np.ndarray:
        """D(s) on the structure's coordinates, shape (..., n, n) (Eq. 2.23),
        the actuators' term (:meth:`Actuators.D`) included."""
        self._needs_delay()
        out = coupling_matrix(s, self.DP, self.DV, self.DO, self.delay)
        return out if self.actuators is None else out + self.actuators.D(s)

    def __call__(self, s: complex | np.ndarray) -> np.ndarray:
        """D(s): see :meth:`D`."""
        return self.D(s)

    def _needs_delay(self) -> None:
        if self.delay is None and np.any(self.Dl_O):
            raise InputError(
                "this loop has a delayed term but no delay yet: loop.at(speed=...) or at(delay=...)"
            )

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
        """No feedback at all (case a, or all CE matrices zero, and no actuator)."""
        return not (np.any(self.Dl_P) or np.any(self.Dl_V) or np.any(self.Dl_O)) and self.actuators is None

    @property
    def milling(self) -> Any:
        """The periodic process (a :class:`~chatterlab.process.Milling`), or
        an :class:`~chatterlab.errors.InputError` for a constant one."""
        if self.process is None:
            raise InputError("this closed loop has no periodic (milling) process")
        return self.process

    def at(
        self, *, width: float | None = None, delay: float | None = None, speed: float | None = None
    ) -> ClosedLoop:
        """The same loop at another width b (m) and/or delay T (s) (or, with
        a process, speed: its kinematics give T): the process's matrices
        scale with b (Eq. 3.5)."""
        f = 1.0 if width is None else check_width(width) / self.width
        if speed is not None:
            if delay is not None:
                raise InputError("give either speed or delay, not both")
            if self.process is None:
                raise InputError(
                    "a constant loop is moved to another speed by closed_loop(frozen, speed=...)"
                )
            delay = float(self.process.delay(check_speed(speed, unit=self.process.speed_unit)))
        T = self.delay if delay is None else check_delay(delay)
        b = self.width if width is None else float(width)
        Dl_V, damping = f * self.Dl_V, self.damping
        if damping is not None and delay is not None:
            # the process damping's gain follows the cutting speed of the new delay
            damping = LoopDamping(damping.term, float(delay))
            Dl_V = Dl_V + (damping.matrix(b) - self.damping.matrix(b))  # type: ignore[union-attr]
        return replace(
            self,
            Dl_P=f * self.Dl_P,
            Dl_V=Dl_V,
            Dl_O=f * self.Dl_O,
            force=f * self.force,
            width=b,
            delay=T if np.any(self.Dl_O) else None,
            damping=damping,
        )


def milling_loop(
    structure: Any,
    milling: Any,
    J: Any = None,
    *,
    width: float = 1.0,
    frozen: FrozenSystem | None = None,
    C_pd: float = 0.0,
) -> ClosedLoop:
    """A structure under a milling cutter: the closed loop the Floquet
    methods integrate (:func:`chatterlab.frequency.multipliers`,
    :func:`chatterlab.lobes.milling_lobes`).

    Parameters
    ----------
    structure : Structure
        M, C, K of the tool side (any coordinates).
    milling : Milling
        The cutter and the cut (its periodic directional matrices).
    J : array, shape (2, n), optional
        The tool's displacement (x, y) relative to the workpiece from the
        coordinates (feed along +x, see :mod:`chatterlab.process._milling`).
        Default: the coordinates named ``"x"`` and ``"y"`` (a
        :meth:`Structure.single_dof` is named ``"x"``).
    width : float
        The axial depth a_p, m, of the constant (time-averaged) part; the
        Floquet methods take the depth as their own argument.
    C_pd : float
        Process damping, N/m (``[process_damping] C_pd``): each tooth's flank
        damps the tool's velocity along its radial direction with
        a_p C_pd / V, V = pi D n / 60 (:mod:`chatterlab.process._damping`);
        the loop's ``Dl_V`` holds the averaged term.  0: none, or the
        ``[process_damping]`` of ``frozen``'s model when it has one.
    """
    if not isinstance(structure, Structure):
        raise InputError(
            f"milling_loop: structure must be a Structure (got {type(structure).__name__});"
            " Structure(M, C, K), Structure.single_dof(...) or frozen.structure"
        )
    n = structure.n
    if J is None:
        rows = []
        for axis in ("x", "y"):
            row = np.zeros(n)
            if axis in structure.names:
                row[structure.names.index(axis)] = 1.0
            rows.append(row)
        J = np.array(rows)
        if not np.any(J):
            raise InputError(
                f"milling_loop: {structure.name} has no coordinate named 'x' or 'y': give J (2 x {n}),"
                " the map from its coordinates to the tool's (x, y)"
            )
    J = np.atleast_2d(np.asarray(J, dtype=float))
    if J.shape != (2, n) or not np.all(np.isfinite(J)):
        raise InputError(f"structure J must be a finite 2 x {n} matrix mapping q to (x, y) (got {J.shape})")
    if not np.any(J):
        raise InputError(f"{structure.name}: the tool point does not move (J = 0)")
    width = check_width(width, "depth of cut a_p")
    H0 = width * milling.zoa()
    T = milling.tooth_period(milling.rpm) if milling.rpm else None
    V = np.zeros((2, 2))
    damping = None
    term = None
    if check_nonneg(C_pd, "process damping C_pd", "N/m") > 0.0:
        term = milling_damping(milling, C_pd)
    elif frozen is not None:  # the model's [process_damping] of its milling coupling
        term = damping_term(frozen.model, milling=milling)
    if term is not None:
        # the rubbing flanks' averaged term a_p C_pd / V W_0 (process._damping), V = pi D n / 60
        damping = LoopDamping(term, float("nan") if T is None else T)
        V = damping.matrix(float(width))
    return ClosedLoop(
        structure, J, H0, V, -H0, np.zeros(n), float(width), T, "pdo", frozen, milling, damping=damping
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
    damping = None
    term = damping_term(frozen.model, couplings) if terms in ("pd", "pdo") else None
    if term is not None:  # the flank's damping b C_pd / V W at the cutting speed of this delay
        Tv = T if T is not None else delay_for(frozen.model.process, speed=speed, delay=delay)
        damping = LoopDamping(term, float(Tv))  # type: ignore[arg-type]
        V = V + damping.matrix(float(width))
    return ClosedLoop(
        frozen.structure,
        J,
        P,
        V,
        O,
        J.T @ F,
        float(width),
        T,
        terms,
        frozen,
        actuators=actuators_of(frozen),
        damping=damping,
    )


# ---------------------------------------------------------------------------- the coupling elements
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


# ---------------------------------------------------------------------------- the actuators
@dataclass(frozen=True, eq=False)
class Actuators:
    """The machine's active dampers on the loop's coordinates
    (:mod:`chatterlab.model._actuator`): actuator k measures y_k = S[k] q and
    pushes with the generalised force B[:, k] f_k,

        f_k(s) = -G_k(s) y_k(s),   G_k(s) = (P_k + s V_k + O_k e^{-s T_k}) / (1 + s tau_k),

    G_k's numerator evaluated by :func:`coupling_matrix` (the paper's
    feedback with the actuator's own delay T_k), tau_k = 1 / (2 pi f_b) its
    bandwidth's time constant (0: none).  On the structure's coordinates the
    term is D_a(s) = -B diag(G(s)) S, added to the cutting process's D(s):
    Delta(s) = s^2 M + s C + K - D(s) - D_a(s).  Unlike the cut it does not
    scale with the width.

    Attributes
    ----------
    ids : tuple of str
    B : ndarray (n, m)
        Generalised forces of unit actuator forces (the force's point and
        direction, minus the reaction's).
    S : ndarray (m, n)
        The sensors' displacements along their directions.
    P, V, O : ndarray (m,)
        Gains: N/m, N s/m, N/m.
    delay : ndarray (m,)
        T_a of each delayed term, s (0: undelayed).
    lag : ndarray (m,)
        1 / (2 pi f_b), s (0: no bandwidth limit).
    force_limit : ndarray (m,)
        N (inf: none).
    """

    ids: tuple[str, ...]
    B: np.ndarray
    S: np.ndarray
    P: np.ndarray
    V: np.ndarray
    O: np.ndarray
    delay: np.ndarray
    lag: np.ndarray
    force_limit: np.ndarray

    @property
    def m(self) -> int:
        return len(self.ids)

    def gains(self, s: complex | np.ndarray) -> np.ndarray:
        """G_k(s), shape ``s.shape + (m,)``."""
        sa = np.asarray(s, dtype=complex)
        out = np.empty(sa.shape + (self.m,), dtype=complex)
        for k in range(self.m):
            Pk, Vk, Ok = (np.array([[x[k]]]) for x in (self.P, self.V, self.O))
            num = coupling_matrix(sa, Pk, Vk, Ok, float(self.delay[k]))[..., 0, 0]
            out[..., k] = num / (1.0 + sa * self.lag[k])
        return out

    def D(self, s: complex | np.ndarray) -> np.ndarray:
        """D_a(s) = -B diag(G(s)) S on the structure's coordinates, shape (..., n, n)."""
        g = self.gains(s)
        return -np.einsum("ik,...k,kj->...ij", self.B, g, self.S)


def actuators_of(frozen: FrozenSystem) -> Actuators | None:
    """The model's ``[[actuator]]`` items on the independent coordinates of
    ``frozen`` (None when it has none)."""
    acts = getattr(frozen.model, "actuators", ())
    if not acts:
        return None
    sy = frozen.system

    def along(ref: Any, angle: float) -> np.ndarray:
        T = frozen.expand(sy.point_map(ref, frozen.position))[:2]
        return np.array([np.cos(angle), np.sin(angle)]) @ T

    n = frozen.structure.n
    B = np.zeros((n, len(acts)))
    S = np.zeros((len(acts), n))
    for k, a in enumerate(acts):
        S[k] = along(a.sensor, a.sensor_angle)
        B[:, k] = along(a.at, a.angle)
        if a.reaction is not None:
            B[:, k] -= along(a.reaction, a.angle)

    def arr(name: str) -> np.ndarray:
        return np.array([float(getattr(a, name)) for a in acts])

    return Actuators(
        tuple(a.id for a in acts),
        B,
        S,
        arr("proportional_gain"),
        arr("velocity_gain"),
        arr("delayed_gain"),
        arr("delay"),
        arr("lag"),
        arr("force_limit"),
    )
