"""Assembly: Model -> System.

A :class:`System` holds the matrices of the *decoupled* system (Eq. 2.13 of
the seed paper: every subsystem described in its own frame, so M, L, K do not
change as the slide moves), the partition of the coordinates into independent
q_i, dependent q_d and given q_g (Eq. 2.2), and the constraint equations
(Eq. 2.4) from which ``W(s)`` of q_d = W q_i follows by Eq. 2.6.  All the
configuration dependence lives in W(s).

:meth:`System.at` freezes a configuration and returns a
:class:`FrozenSystem` with the reduced A*, B*, C* (Eq. 2.16-2.18) that the
frequency-domain analyses use; :meth:`System.reduce` gives the same matrices
for a moving slide (dW/dt = W'(s) v, d2W/dt2 = W''(s) v^2 + W'(s) a) for the
time-domain solver.

Matrices are dense numpy arrays: the models this package targets (machine
tools in the RDFEM) have tens to a few thousand coordinates, where dense
LAPACK is faster than sparse solvers and the frequency-domain work is done
on modally reduced matrices anyway.

References
----------
.. [1] E. Wittbrodt, K. J. Kaliński, "Transient vibration of unsteady linear
   closed loop systems", Eqs. (2.2)-(2.18).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import cached_property
from types import MappingProxyType
from typing import Any

import numpy as np

from ..errors import InputError, ModelError
from ..model._geometry import beam_axes, body_centre, point_xy
from ..model._items import DIRECTIONS, GROUND, Beam, Coupling, Model, PointRef
from ._complex import ComplexModes, complex_modes
from ._elements import beam_matrices, beam_point_matrix, rigid_point_matrix, rotation3

__all__ = ["System", "FrozenSystem", "CouplingMatrices", "MovingReduction", "assemble"]


@dataclass(frozen=True)
class _Element:
    """One (sub-)element of a beam track: where it starts and its nodes."""

    beam: Beam
    start: float  # distance of its first node from the track start, m
    length: float
    xy_i: np.ndarray
    xy_j: np.ndarray
    cols: np.ndarray  # 6 coordinate indices

    def point_matrix(self, xi: np.ndarray, offset: float, order: int = 0) -> np.ndarray:
        """``beam_point_matrix`` of this element: (m, 3, 6)."""
        sec = self.beam.section
        return beam_point_matrix(
            self.xy_i, self.xy_j, xi, offset, E=sec.E, G=sec.G, A=sec.A, I=sec.I, kappa=sec.kappa, order=order
        )


@dataclass(frozen=True)
class _ContactRows:
    cols_self: np.ndarray  # 3 indices of the contact's own coordinates
    elements: tuple[_Element, ...]
    x_ref: float  # along-track coordinate at s = s_ref
    s_ref: float
    rate: float  # d(along-track)/ds
    offset: float
    track_length: float
    id: str
    clamp: bool

    def locate(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Where the contact is at configurations s: along-track coordinate x
        (m), element index, side (-1 before the track, 0 on it, +1 beyond;
        clamped contacts wait at the end) and the element coordinate xi."""
        x = self.x_ref + self.rate * (s - self.s_ref)
        side = np.zeros(s.size, dtype=int)
        if self.clamp:
            side = np.where(x < 0.0, -1, np.where(x > self.track_length, 1, 0))
            x = np.clip(x, 0.0, self.track_length)
        starts = np.array([e.start for e in self.elements])
        lens = np.array([e.length for e in self.elements])
        idx = np.clip(np.searchsorted(starts, x + 1e-12, side="right") - 1, 0, len(self.elements) - 1)
        xi = np.clip((x - starts[idx]) / lens[idx], 0.0, 1.0)
        return x, idx, side, xi


@dataclass(frozen=True)
class CouplingMatrices:
    """A coupling element seen from the reduced (independent) coordinates.

    ``J`` maps q_i to the CE's relative displacement dw = w_a - w_b in CE
    axes (3, n_i).  The CE's contribution to D(s) of Eq. (2.23), at width b,
    is ``-(b / width_ref) J^T (DP + s DV + DO e^{-sT}) J``; its static force is
    ``(b / width_ref) J^T forces``.
    """

    id: str
    J: np.ndarray
    DP: np.ndarray
    DV: np.ndarray
    DO: np.ndarray
    forces: np.ndarray
    width_ref: float
    coupling: Coupling

    def scaled(self, width: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(DP, DV, DO) of the CE (3, 3) at width b (m)."""
        f = width / self.width_ref
        return f * self.DP, f * self.DV, f * self.DO

    def global_feedback(self, width: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The CE's contribution to D_P, D_V, D_O of Eq. (2.23) in reduced
        coordinates (each (n_i, n_i)), at width b (m): E = D q."""
        DP, DV, DO = self.scaled(width)
        return (-self.J.T @ DP @ self.J, -self.J.T @ DV @ self.J, -self.J.T @ DO @ self.J)


@dataclass(frozen=True, eq=False)
class System:
    """Assembled matrices and coordinate map of a model.

    Attributes
    ----------
    names : tuple of str
        All coordinates, ``"<item>.<x|y|rz>"`` (or the matrix model's names).
    i, d, g : ndarray of int
        Indices of the independent, dependent and given coordinates (Eq. 2.2).
    M, L, K : ndarray, shape (n, n)
        Inertia, damping and stiffness of the decoupled system (Eq. 2.13),
        over all coordinates.
    """

    model: Model
    names: tuple[str, ...]
    i: np.ndarray
    d: np.ndarray
    g: np.ndarray
    M: np.ndarray
    L: np.ndarray
    K: np.ndarray
    _const_rows: np.ndarray = field(repr=False)  # (r0, n) constant constraint rows
    _contacts: tuple[_ContactRows, ...] = field(repr=False)
    _elements: MappingProxyType = field(repr=False)  # beam id -> tuple[_Element]
    index: MappingProxyType = field(repr=False)

    # ---------------------------------------------------------------- coordinates
    @property
    def n(self) -> int:
        return len(self.names)

    @property
    def names_i(self) -> tuple[str, ...]:
        return tuple(self.names[k] for k in self.i)

    @property
    def names_d(self) -> tuple[str, ...]:
        return tuple(self.names[k] for k in self.d)

    @property
    def names_g(self) -> tuple[str, ...]:
        return tuple(self.names[k] for k in self.g)

    @property
    def default_position(self) -> float | None:
        return self.model.movable.position if self.model.movable is not None else None

    def summary(self) -> dict[str, Any]:
        """Item and coordinate counts (what ``chatterlab check`` prints)."""
        out = self.model.summary()
        out.update(
            {
                "coordinates": self.n,
                "independent": len(self.i),
                "dependent": len(self.d),
                "given": len(self.g),
            }
        )
        if self.model.movable is not None:
            mv = self.model.movable
            out["movable bodies"] = list(mv.bodies)
            out["position"] = mv.position
            out["range"] = list(mv.range)
        return out

    # ---------------------------------------------------------------- constraints
    def positions(self, s: float | np.ndarray | None) -> np.ndarray:
        """Configurations s as a 1-D array (None: the model's position),
        refused outside the movable range or when not finite."""
        if s is None:
            s = self.default_position if self.default_position is not None else 0.0
        arr = np.atleast_1d(np.asarray(s, dtype=float))
        if self.model.movable is not None and arr.size:
            lo, hi = self.model.movable.range
            bad = (arr < lo - 1e-9) | (arr > hi + 1e-9)
            if np.any(bad):
                raise InputError(
                    f"position {arr[bad][0]:g} m is outside the movable range [{lo:g}, {hi:g}] m of "
                    f"{self.model.source}; choose a position inside it or widen [movable] range"
                )
        if not np.all(np.isfinite(arr)):
            raise InputError("position must be finite")
        return arr

    def constraint_matrix(self, s: float | np.ndarray | None = None, order: int = 0) -> np.ndarray:
        """The constraint matrix [W_i W_d W_g] of Eq. (2.4) over all
        coordinates, or its ``order``-th derivative with respect to s.

        Returns an array of shape (m, r, n) for m configurations.
        """
        sa = self.positions(s)
        m = sa.size
        r0 = self._const_rows.shape[0]
        r = r0 + 3 * len(self._contacts)
        G = np.zeros((m, r, self.n))
        if order == 0:
            G[:, :r0, :] = self._const_rows
        for k, c in enumerate(self._contacts):
            rows = slice(r0 + 3 * k, r0 + 3 * k + 3)
            if order == 0:
                G[:, rows, c.cols_self] = np.eye(3)
            _, idx, side, xi = c.locate(sa)
            inside = (side == 0).astype(float)
            for e_idx in np.unique(idx):
                el = c.elements[e_idx]
                sel = np.nonzero(idx == e_idx)[0]
                P = el.point_matrix(xi[sel], c.offset, order)
                scale = c.rate**order * inside[sel] if order else np.ones(sel.size)
                G[np.ix_(sel, np.arange(rows.start, rows.stop), el.cols)] -= P * scale[:, None, None]
        return G

    def W(self, s: float | np.ndarray | None = None, order: int = 0) -> np.ndarray:
        """W(s) of q_d = W q_i (Eq. 2.6), or its derivative d^k W / ds^k.

        Parameters
        ----------
        s : float or array, optional
            Configuration (slide position, m).  Default: the model's position.
        order : {0, 1, 2}

        Returns
        -------
        ndarray, shape (n_d, n_i) for a scalar s, (m, n_d, n_i) for an array.
        """
        scalar = s is None or np.ndim(s) == 0
        Ws = self.W_derivatives(s)[order]
        return Ws[0] if scalar else Ws

    def W_derivatives(self, s: float | np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """W, W', W'' (each (m, n_d, n_i)) by Eq. (2.6) and its derivatives.

        With the constraints G_i q_i + G_d q_d = 0 holding identically in s,
        W = -(G_d^T G_d)^-1 G_d^T G_i, W' = -P (G_i' + G_d' W) and
        W'' = -P (G_i'' + 2 G_d' W' + G_d'' W) with P = (G_d^T G_d)^-1 G_d^T.
        """
        sa = self.positions(s)
        nd, ni = len(self.d), len(self.i)
        if nd == 0:
            z = np.zeros((sa.size, 0, ni))
            return z, z, z
        G0 = self.constraint_matrix(sa, 0)
        Gd = np.ascontiguousarray(G0[:, :, self.d])
        Gi = np.ascontiguousarray(G0[:, :, self.i])
        GdT = np.ascontiguousarray(np.transpose(Gd, (0, 2, 1)))
        Pt = np.linalg.solve(GdT @ Gd, GdT)  # (m, nd, r): (G_d^T G_d)^-1 G_d^T
        W0 = -(Pt @ Gi)
        if not self._contacts:
            z = np.zeros_like(W0)
            return W0, z, z
        G1 = self.constraint_matrix(sa, 1)
        G2 = self.constraint_matrix(sa, 2)
        G1d = np.ascontiguousarray(G1[:, :, self.d])
        W1 = -(Pt @ (np.ascontiguousarray(G1[:, :, self.i]) + G1d @ W0))
        W2 = -(
            Pt
            @ (
                np.ascontiguousarray(G2[:, :, self.i])
                + 2 * (G1d @ W1)
                + np.ascontiguousarray(G2[:, :, self.d]) @ W0
            )
        )
        return W0, W1, W2

    # ---------------------------------------------------------------- reduction
    def reduce(
        self,
        s: float | np.ndarray | None = None,
        velocity: float | np.ndarray = 0.0,
        acceleration: float | np.ndarray = 0.0,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A*, B*, C* of Eq. (2.16)-(2.18) for the slide at s moving with
        ``velocity`` ds/dt (m/s) and ``acceleration`` (m/s^2).

        Returns arrays of shape (n_i, n_i) for scalar s, else (m, n_i, n_i).
        """
        scalar = s is None or np.ndim(s) == 0
        W0, W1, W2 = self.W_derivatives(s)
        v = np.atleast_1d(np.asarray(velocity, float))[:, None, None]
        a = np.atleast_1d(np.asarray(acceleration, float))[:, None, None]
        A, B, C = self.reduced_matrices(W0, W1 * v, W2 * v**2 + W1 * a)
        if scalar:
            return A[0], B[0], C[0]
        return A, B, C

    def reduced_matrices(
        self, W: np.ndarray, W_dot: np.ndarray, W_ddot: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A*, B*, C* of Eq. (2.16)-(2.18) from W, dW/dt and d2W/dt2, each
        (m, n_d, n_i); returns (m, n_i, n_i) each."""
        i, d = self.i, self.d
        Wt = np.transpose(W, (0, 2, 1))
        out = []
        for X in (self.M, self.L, self.K):
            Xii, Xid, Xdi, Xdd = X[np.ix_(i, i)], X[np.ix_(i, d)], X[np.ix_(d, i)], X[np.ix_(d, d)]
            out.append(Xii + Xid @ W + Wt @ Xdi + Wt @ Xdd @ W)
        A, B, C = out
        if len(d) and (np.any(W_dot) or np.any(W_ddot)):
            Mid, Mdd = self.M[np.ix_(i, d)], self.M[np.ix_(d, d)]
            Lid, Ldd = self.L[np.ix_(i, d)], self.L[np.ix_(d, d)]
            B = B + 2 * (Mid + Wt @ Mdd) @ W_dot
            C = C + (Lid + Wt @ Ldd) @ W_dot + (Mid + Wt @ Mdd) @ W_ddot
        return A, B, C

    def speed_parts(
        self, W: np.ndarray, W1: np.ndarray, W2: np.ndarray
    ) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]:
        """B1, C1, C2 of B* = B0 + v B1, C* = C0 + v C1 + v^2 C2 (Eq. 2.17-2.18
        with dW/dt = W' v, d2W/dt2 = W'' v^2), from W, W' = dW/ds and
        W'' = d2W/ds2 (each (m, n_d, n_i)); a part that vanishes is None."""
        i, d = self.i, self.d
        Wt = np.transpose(W, (0, 2, 1))
        Mid, Mdd = self.M[np.ix_(i, d)], self.M[np.ix_(d, d)]
        Lid, Ldd = self.L[np.ix_(i, d)], self.L[np.ix_(d, d)]
        Mfac = Mid + Wt @ Mdd
        Lfac = Lid + Wt @ Ldd
        B1 = 2 * Mfac @ W1 if np.any(Mfac) else None
        C2 = Mfac @ W2 if np.any(Mfac) else None
        C1 = Lfac @ W1 if np.any(Lfac) else None
        return B1, C1, C2

    @cached_property
    def moving_reduction(self) -> MovingReduction | None:
        """The low-rank reduction for a moving slide (:class:`MovingReduction`),
        or None when the model has no moving contact or its constraints do not
        allow it (then use :meth:`W_derivatives` and :meth:`reduced_matrices`)."""
        if self.model.movable is None or not self._contacts:
            return None
        mr = MovingReduction(self)
        return mr if mr.ok else None

    def at(self, s: float | None = None) -> FrozenSystem:
        """Freeze the configuration: the slide held at ``s`` (m; default the
        model's ``[movable] position``)."""
        pos = None if self.default_position is None and s is None else float(self.positions(s)[0])
        A, B, C = self.reduce(pos)
        W0 = self.W(pos)
        return FrozenSystem(self, pos, A, B, C, W0)

    # ---------------------------------------------------------------- points
    def point_map(self, ref: PointRef, s: float | None = None) -> np.ndarray:
        """Map (3, n) from all coordinates to the global (u, v, theta) of a
        point (rows for ``coords`` points of matrix models are zero where the
        point names no coordinate)."""
        T = np.zeros((3, self.n))
        mdl = self.model
        if ref.kind == "coords":
            for r, cname in enumerate(ref.coords):
                if cname:
                    T[r, self.index[cname]] = 1.0
            return T
        if ref.kind == "ground":
            if mdl.is_matrix_model:
                return T  # the foundation does not move: a zero map
            cols = [self.index[f"{GROUND}.{d}"] for d in DIRECTIONS]
            T[:, cols] = rigid_point_matrix(np.array(ref.offset))
            return T
        if ref.kind in ("body", "node"):
            cols = [self.index[f"{ref.target}.{d}"] for d in DIRECTIONS]
            if ref.kind == "body":
                arm = point_xy(mdl, ref, s) - body_centre(mdl, ref.target, s)
            else:
                arm = np.array(ref.offset)
            T[:, cols] = rigid_point_matrix(arm)
            return T
        # a fixed point on a beam
        for el in self._elements[ref.target]:
            if el.start - 1e-12 <= ref.distance <= el.start + el.length + 1e-12:
                break
        xi = min(max((ref.distance - el.start) / el.length, 0.0), 1.0)
        sec = el.beam.section
        P = beam_point_matrix(
            el.xy_i, el.xy_j, xi, ref.offset[1], E=sec.E, G=sec.G, A=sec.A, I=sec.I, kappa=sec.kappa
        )
        T[:, el.cols] = P[0]
        return T

    def resolve_point(self, name: str) -> PointRef:
        """The :class:`PointRef` of a point, body, contact or node name."""
        mdl = self.model
        for p in mdl.points:
            if p.id == name:
                return p.ref
        if name == GROUND:
            return PointRef("ground", GROUND)
        if any(b.id == name for b in mdl.bodies) or any(c.id == name for c in mdl.contacts):
            return PointRef("body", name, label=name)
        if any(n.id == name for n in mdl.nodes):
            return PointRef("node", name, label=name)
        known = [p.id for p in mdl.points] + [b.id for b in mdl.bodies] + [c.id for c in mdl.contacts]
        known += [n.id for n in mdl.nodes]
        if mdl.is_matrix_model:
            known += list(self.names)
        raise InputError(f"unknown point '{name}' in {mdl.source} (known: {', '.join(known)})")

    @cached_property
    def coupling_maps(self) -> tuple[tuple[Coupling, np.ndarray], ...]:
        out = []
        for c in self.model.couplings:
            J = self.point_map(c.a) - self.point_map(c.b)
            out.append((c, rotation3(c.angle).T @ J))
        return tuple(out)


@dataclass(frozen=True, eq=False)
class FrozenSystem:
    """The system at one configuration: reduced A*, B*, C* (n_i x n_i) on the
    independent coordinates, as used by FRFs, modes, roots and lobes."""

    system: System
    position: float | None
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    W: np.ndarray

    @property
    def model(self) -> Model:
        return self.system.model

    @cached_property
    def complex_modes(self) -> ComplexModes:
        """Complex modes of s^2 A* + s B* + C* (computed once per configuration)."""
        return complex_modes(self.A, self.B, self.C)

    @property
    def names(self) -> tuple[str, ...]:
        """Independent coordinate names (the order of the rows of A*)."""
        return self.system.names_i

    @property
    def n(self) -> int:
        return self.A.shape[0]

    def expand(self, T: np.ndarray) -> np.ndarray:
        """Restrict a map over all coordinates (k, n) to independent ones
        (k, n_i) through q_d = W q_i (given coordinates are zero)."""
        sy = self.system
        return T[:, sy.i] + T[:, sy.d] @ self.W

    def point(self, name: str) -> np.ndarray:
        """Map (3, n_i) from q_i to the global (u, v, theta) of a point."""
        sy = self.system
        return self.expand(sy.point_map(sy.resolve_point(name), self.position))

    def dof(self, spec: str) -> np.ndarray:
        """Row (n_i,) giving one response quantity: ``"POINT.DIR"`` with DIR
        one of x, y, rz, or (matrix models) a coordinate name."""
        sy = self.system
        if spec in sy.index and sy.model.is_matrix_model:
            T = np.zeros((1, sy.n))
            T[0, sy.index[spec]] = 1.0
            if sy.index[spec] in set(sy.g.tolist()):
                raise InputError(f"'{spec}' is a given (prescribed) coordinate; it has no response")
            return self.expand(T)[0]
        name, _, direction = spec.rpartition(".")
        if not name or direction not in DIRECTIONS:
            raise InputError(
                f"'{spec}' is not POINT.DIRECTION: write e.g. 'tool.x' with a direction among {', '.join(DIRECTIONS)}"
            )
        ref = sy.resolve_point(name)
        row = self.expand(sy.point_map(ref, self.position))[DIRECTIONS.index(direction)]
        if not np.any(row):
            raise InputError(f"'{spec}' does not move: it names no independent coordinate")
        return row

    def couplings(self) -> tuple[CouplingMatrices, ...]:
        """The model's coupling elements in reduced coordinates."""
        out = []
        for c, J in self.system.coupling_maps:
            out.append(
                CouplingMatrices(
                    c.id,
                    self.expand(J),
                    np.array(c.DP, float),
                    np.array(c.DV, float),
                    np.array(c.DO, float),
                    np.array(c.forces, float),
                    c.width_ref,
                    c,
                )
            )
        return tuple(out)


class MovingReduction:
    """A*, B*, C* and the contact rows of W for a moving slide, exploiting
    the structure (the fast path of the time domain; :meth:`System.moving_reduction`).

    Only the rows of W that belong to moving contacts depend on s, and by
    direct substitution they are R_c(s) = P(xi(s)) T_e: the beam point map of
    the element under the contact times the (constant) map T_e from q_i to
    that element's nodal coordinates.  With T(s) = T0 + E R(s) (E selecting
    the contact rows) each reduced matrix is a constant part plus low-rank
    terms in R, R' v and R'' v^2 -- a few (n_i x 3k) products per step
    instead of Eq. (2.6) and a full reduction.  Exact; checked against
    :meth:`System.W` when built (``ok``).

    Attributes
    ----------
    dv : ndarray of int
        The contact coordinates (columns over all coordinates).
    pos_v : ndarray of int
        Their rows in W.
    Tm : ndarray (n, n_i)
        Map q_i -> all coordinates with the contact rows zeroed (T0).
    ok : bool
        Whether the low-rank form holds for this system (the constant
        constraint rows do not involve contact coordinates, and it equals W).
    """

    def __init__(self, sy: System) -> None:
        self.sy = sy
        d = list(sy.d)
        cset = {int(k) for c in sy._contacts for k in c.cols_self}
        self.dv = np.array([k for k in d if k in cset], dtype=int)  # contact coordinates
        self.pos_v = np.array([d.index(k) for k in self.dv], dtype=int)  # their rows in W
        s0 = sy.default_position
        W0 = sy.W(s0)
        # map q_i -> all coordinates with the contact rows zeroed (constant part)
        Tm = np.zeros((sy.n, len(sy.i)))
        Tm[sy.i, np.arange(len(sy.i))] = 1.0
        Tm[sy.d] = W0
        Tm[self.dv] = 0.0
        self.Tm = Tm
        # the constant rows must not involve contact coordinates
        rows = sy._const_rows
        self.ok = not (rows.size and np.any(rows[:, self.dv]))
        n_i = len(sy.i)
        self.X0: list[np.ndarray] = []
        self.Xv: list[np.ndarray] = []
        self.Xvv: list[np.ndarray] = []
        for X in (sy.M, sy.L, sy.K):
            self.X0.append(Tm.T @ X @ Tm)
            self.Xv.append(np.ascontiguousarray(Tm.T @ X[:, self.dv]))
            self.Xvv.append(np.ascontiguousarray(X[np.ix_(self.dv, self.dv)]))
        self.nz_v = [bool(np.any(a)) for a in self.Xv]
        self.nz_vv = [bool(np.any(a)) for a in self.Xvv]
        self.n_i = n_i
        own = np.concatenate([c.cols_self for c in sy._contacts])
        self._perm = np.array([int(np.nonzero(own == k)[0][0]) for k in self.dv], dtype=int)
        # per contact and element: T_e (6, n_i), and the beam point-map constants
        self._Te = [[Tm[el.cols] for el in c.elements] for c in sy._contacts]
        if self.ok and sy.model.movable is not None:
            lo, hi = sy.model.movable.range
            s_chk = np.array([lo, lo + 0.1 * (hi - lo), 0.5 * (lo + hi), 0.9 * hi + 0.1 * lo, hi])
            if s0 is not None:
                s_chk = np.append(s_chk, s0)
            R0 = self.rows(s_chk, np.zeros(s_chk.size), orders=1)[0]
            ref = sy.W(s_chk)[:, self.pos_v]
            if not np.allclose(R0, ref, rtol=1e-9, atol=1e-12 * max(1.0, np.abs(ref).max())):
                self.ok = False

    def locate(
        self, s: np.ndarray
    ) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
        """Per contact: along-track x, element index, side (-1 before the
        track, 0 on it, +1 beyond; clamped contacts only) and xi."""
        xs, idxs, sides, xis = [], [], [], []
        for c in self.sy._contacts:
            x, idx, side, xi = c.locate(s)
            xs.append(x)
            idxs.append(idx)
            sides.append(side)
            xis.append(xi)
        return xs, idxs, sides, xis

    def interval(self, key: tuple[int, ...]) -> tuple[float, float]:
        """The slide positions (within the movable range) where every contact
        c stays on element ``key[2 c]`` with side ``key[2 c + 1]`` (as
        :meth:`locate` gives them): the segment on which W is polynomial."""
        mv = self.sy.model.movable
        lo, hi = tuple(mv.range) if mv is not None else (0.0, 0.0)
        for ci, c in enumerate(self.sy._contacts):
            e_idx, side = key[2 * ci], key[2 * ci + 1]
            if side < 0:
                xa, xb = -np.inf, 0.0
            elif side > 0:
                xa, xb = c.track_length, np.inf
            else:
                el = c.elements[e_idx]
                xa, xb = el.start, el.start + el.length
            if c.rate == 0.0:
                continue
            sa = c.s_ref + (xa - c.x_ref) / c.rate
            sb = c.s_ref + (xb - c.x_ref) / c.rate
            lo, hi = max(lo, min(sa, sb)), min(hi, max(sa, sb))
        return lo, hi

    def rows(
        self, s: np.ndarray, v: np.ndarray, orders: int = 3
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Contact rows of W, dW/dt and d2W/dt2: each (m, 3k, n_i) (only the
        first ``orders`` are computed; the others are zero)."""

        s = np.atleast_1d(np.asarray(s, dtype=float))
        v = np.broadcast_to(np.asarray(v, dtype=float), s.shape)
        m = s.size
        k3 = 3 * len(self.sy._contacts)
        R = np.zeros((3, m, k3, self.n_i))
        _, idxs, sides, xis = self.locate(s)
        for ci, c in enumerate(self.sy._contacts):
            idx, xi = idxs[ci], xis[ci]
            inside = (sides[ci] == 0).astype(float)
            for e_idx in np.unique(idx):
                el = c.elements[e_idx]
                sel = np.nonzero(idx == e_idx)[0]
                Te = self._Te[ci][e_idx]
                for order in range(orders):
                    P = el.point_matrix(xi[sel], c.offset, order)
                    fac = (c.rate * v[sel]) ** order * (inside[sel] if order else 1.0)
                    R[order, sel, 3 * ci : 3 * ci + 3] = (P @ Te) * fac[:, None, None]
        # order the rows like self.dv
        return R[0][:, self._perm], R[1][:, self._perm], R[2][:, self._perm]

    def parts(self, s: np.ndarray) -> dict[str, Any]:
        """The reduced matrices split by their dependence on the slide speed v:

        A = A0,  B = B0 + v B1,  C = C0 + v C1 + v^2 C2   (Eq. 2.16-2.18)

        with B1 = 2 (M_id + W^T M_dd) W',  C1 = (L_id + W^T L_dd) W',
        C2 = (M_id + W^T M_dd) W'' (W' = dW/ds, W'' = d2W/ds2), plus the
        contact rows R0 = W and R1 = W' (each (m, 3k, n_i)).  Parts that
        vanish identically are None.
        """
        s = np.atleast_1d(np.asarray(s, dtype=float))
        m = s.size
        R0, R1, R2 = self.rows(s, np.ones(m))
        R0t = np.ascontiguousarray(np.transpose(R0, (0, 2, 1)))  # (m, n, k)
        n, k = self.n_i, R0.shape[1]
        out: dict[str, Any] = {"R0": R0, "R1": R1}
        base = []
        for X0, Xv, Xvv, nzv, nzvv in zip(self.X0, self.Xv, self.Xvv, self.nz_v, self.nz_vv, strict=True):
            if not (nzv or nzvv):
                base.append(np.broadcast_to(X0, (m,) + X0.shape))
                continue
            Y = np.empty((m, n, n))
            if nzv:
                # one GEMM for the constant-times-stack product: (m n, k) @ (k, n)
                Y[:] = (R0t.reshape(m * n, k) @ Xv.T).reshape(m, n, n)
                Y += np.transpose(Y, (0, 2, 1)).copy()
            else:
                Y[:] = 0.0
            if nzvv:
                Y += (R0t.reshape(m * n, k) @ Xvv).reshape(m, n, k) @ R0
            Y += X0
            base.append(Y)
        out["A0"], out["B0"], out["C0"] = base
        out["B1"] = out["C1"] = out["C2"] = None
        nzM = self.nz_v[0] or self.nz_vv[0]
        nzL = self.nz_v[1] or self.nz_vv[1]
        if nzM and (np.any(R1) or np.any(R2)):
            Mfac = self.Xv[0][None] + (R0t @ self.Xvv[0] if self.nz_vv[0] else 0.0)
            out["B1"] = 2.0 * (Mfac @ R1)
            out["C2"] = Mfac @ R2
        if nzL and np.any(R1):
            Lfac = self.Xv[1][None] + (R0t @ self.Xvv[1] if self.nz_vv[1] else 0.0)
            out["C1"] = Lfac @ R1
        return out

    def reduce(self, s: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, ...]:
        """A*, B*, C* (Eq. 2.16-2.18) and the contact rows of W and dW/dt at
        slide positions s moving with ds/dt = v."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        v = np.broadcast_to(np.asarray(v, dtype=float), s.shape)
        p = self.parts(s)
        vv = v[:, None, None]
        A = np.array(p["A0"])
        B = np.array(p["B0"]) + (vv * p["B1"] if p["B1"] is not None else 0.0)
        C = np.array(p["C0"])
        if p["C1"] is not None:
            C = C + vv * p["C1"]
        if p["C2"] is not None:
            C = C + vv**2 * p["C2"]
        return A, B, C, p["R0"], vv * p["R1"]


# ===================================================================== assembly


def assemble(model: Model) -> System:
    """Assemble a :class:`System` from a :class:`Model`.

    Raises
    ------
    ModelError
        When the constraints do not determine the dependent coordinates
        (W_d^T W_d singular), or a coordinate is both dependent and given.
    """
    if model.is_matrix_model:
        return _assemble_matrices(model)
    src = model.source
    names = _coordinate_names(model)
    index = {nm: k for k, nm in enumerate(names)}
    n = len(names)

    def cols(item: str) -> np.ndarray:
        return np.array([index[f"{item}.{d}"] for d in DIRECTIONS])

    M, L, K, elements = _element_matrices(model, n, cols)
    given: set[int] = set(cols(GROUND).tolist())
    dependent: dict[int, str] = {}

    def mark_dependent(k: int, why: str) -> None:
        if k in dependent:
            raise ModelError(
                f"coordinate '{names[k]}' is made dependent twice ({dependent[k]} and {why}); remove one",
                source=src,
                item=why,
            )
        dependent[k] = why

    rows = _constraint_rows(model, index, n, cols, given, mark_dependent)
    contact_rows = _contact_rows(model, elements, cols, mark_dependent)

    overlap = sorted(set(dependent) & given)
    if overlap:
        k = overlap[0]
        raise ModelError(
            f"coordinate '{names[k]}' is both given (a support or ground attachment) and dependent"
            f" ({dependent[k]}); remove one of them",
            source=src,
        )
    d_idx = np.array(sorted(dependent), dtype=int)
    g_idx = np.array(sorted(given), dtype=int)
    i_idx = np.array([k for k in range(n) if k not in dependent and k not in given], dtype=int)

    for X in (M, L, K):
        X[:] = 0.5 * (X + X.T)
    for X in (M, L, K):
        X.setflags(write=False)
    const_rows = np.array(rows).reshape(len(rows), n)
    sysm = System(
        model=model,
        names=tuple(names),
        i=i_idx,
        d=d_idx,
        g=g_idx,
        M=M,
        L=L,
        K=K,
        _const_rows=const_rows,
        _contacts=tuple(contact_rows),
        _elements=MappingProxyType(elements),
        index=MappingProxyType(index),
    )
    sysm = _springs_into(sysm)
    _check_constraints(sysm)
    _check_mass(sysm)
    return sysm


def _coordinate_names(model: Model) -> list[str]:
    """All coordinates: bodies, contacts, nodes, inner beam nodes, the ground."""
    names: list[str] = []
    for b in model.bodies:
        names += [f"{b.id}.{d}" for d in DIRECTIONS]
    for c in model.contacts:
        names += [f"{c.id}.{d}" for d in DIRECTIONS]
    for nd in model.nodes:
        names += [f"{nd.id}.{d}" for d in DIRECTIONS]
    for bm in model.beams:
        for j in range(1, bm.elements):
            names += [f"{bm.id}#{j}.{d}" for d in DIRECTIONS]
    names += [f"{GROUND}.{d}" for d in DIRECTIONS]
    return names


def _element_matrices(
    model: Model, n: int, cols: Callable[[str], np.ndarray]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, tuple[_Element, ...]]]:
    """M, L, K of the decoupled system (Eq. 2.13): rigid bodies and beam
    elements, and each beam's elements."""
    M = np.zeros((n, n))
    L = np.zeros((n, n))
    K = np.zeros((n, n))

    for b in model.bodies:
        c3 = cols(b.id)
        M[c3, c3] += (b.mass, b.mass, b.inertia)

    elements: dict[str, tuple[_Element, ...]] = {}
    for bm in model.beams:
        p0, e, Lb = beam_axes(model, bm)
        ids = [bm.nodes[0]] + [f"{bm.id}#{j}" for j in range(1, bm.elements)] + [bm.nodes[1]]
        h = Lb / bm.elements
        els = []
        for j in range(bm.elements):
            xy_i = p0 + j * h * e
            xy_j = p0 + (j + 1) * h * e
            c6 = np.concatenate([cols(ids[j]), cols(ids[j + 1])])
            sec = bm.section
            Me, Le, Ke = beam_matrices(
                xy_i, xy_j, E=sec.E, G=sec.G, A=sec.A, I=sec.I, kappa=sec.kappa, rho=sec.rho, eta=sec.eta
            )
            ix = np.ix_(c6, c6)
            M[ix] += Me
            L[ix] += Le
            K[ix] += Ke
            els.append(_Element(bm, j * h, h, xy_i, xy_j, c6))
        elements[bm.id] = tuple(els)
    return M, L, K, elements


def _constraint_rows(
    model: Model,
    index: dict[str, int],
    n: int,
    cols: Callable[[str], np.ndarray],
    given: set[int],
    mark_dependent: Callable[[int, str], None],
) -> list[np.ndarray]:
    """The constant constraint rows (attachments to bodies, [[constraint]]
    equations); supports and ground attachments add to ``given``."""
    rows: list[np.ndarray] = []
    for s_ in model.supports:
        if s_.target in index:  # pragma: no cover - coordinate supports are matrix-model only
            given.add(index[s_.target])
            continue
        for d in s_.dofs:
            given.add(index[f"{s_.target}.{d}"])

    for a in model.attachments:
        nc = cols(a.node)
        if a.body == GROUND:
            given.update(nc.tolist())
            continue
        bc = cols(a.body)
        arm = node_xy_of(model, a.node) - body_centre(model, a.body)
        R = rigid_point_matrix(arm)
        for r in range(3):
            row = np.zeros(n)
            row[nc[r]] = 1.0
            row[bc] -= R[r]
            rows.append(row)
            mark_dependent(int(nc[r]), f'[[attachment]] "{a.id}"')

    for con in model.constraints:
        for dname in con.dependent:
            mark_dependent(index[dname], f'[[constraint]] "{con.id}"')
        for eq in con.equations:
            row = np.zeros(n)
            for cname, coef in eq:
                row[index[cname]] += coef
            rows.append(row)
    return rows


def _contact_rows(
    model: Model,
    elements: dict[str, tuple[_Element, ...]],
    cols: Callable[[str], np.ndarray],
    mark_dependent: Callable[[int, str], None],
) -> list[_ContactRows]:
    """Each contact's track (its beams' elements end to end) and where it is
    on it as the slide moves."""
    contact_rows = []
    mv = model.movable
    for c in model.contacts:
        for k in cols(c.id):
            mark_dependent(int(k), f'[[contact]] "{c.id}"')
        track: list[_Element] = []
        start = 0.0
        for bid in c.beams:
            for el in elements[bid]:
                track.append(_Element(el.beam, start + el.start, el.length, el.xy_i, el.xy_j, el.cols))
            start += beam_axes(model, next(b for b in model.beams if b.id == bid))[2]
        beams0 = next(b for b in model.beams if b.id == c.beams[0])
        p0, e, _ = beam_axes(model, beams0)
        s_ref = mv.position if mv is not None else 0.0
        x_ref = float((body_centre(model, c.follows, s_ref) - p0) @ e) + c.shift
        rate = float(np.array(mv.direction) @ e) if mv is not None else 0.0
        contact_rows.append(
            _ContactRows(
                cols(c.id), tuple(track), x_ref, s_ref, rate, c.offset, start, c.id, c.outside == "clamp"
            )
        )
    return contact_rows


def node_xy_of(model: Model, nid: str) -> np.ndarray:
    for nd in model.nodes:
        if nd.id == nid:
            return np.array(nd.xy, float)
    raise KeyError(nid)


def _springs_into(sy: System) -> System:
    """Add the spring-damping elements to K and L (their maps do not depend
    on s: check_geometry refuses springs that mix moving and fixed parts)."""
    K = np.array(sy.K)
    L = np.array(sy.L)
    for sp in sy.model.springs:
        Jl = rotation3(sp.angle).T @ (sy.point_map(sp.a) - sy.point_map(sp.b))
        K += Jl.T @ np.diag(sp.c) @ Jl
        L += Jl.T @ np.diag(sp.d) @ Jl
    K = 0.5 * (K + K.T)
    L = 0.5 * (L + L.T)
    K.setflags(write=False)
    L.setflags(write=False)
    return replace(sy, K=K, L=L)


def _check_constraints(sy: System) -> None:
    if len(sy.d) == 0:
        return
    G = sy.constraint_matrix(None)[0]
    Gd = G[:, sy.d]
    N = Gd.T @ Gd
    w, V = np.linalg.eigh(N)
    tol = 1e-10 * max(1.0, w.max())
    if w.min() <= tol:
        v = V[:, 0]
        culprits = [sy.names[sy.d[k]] for k in np.argsort(-np.abs(v))[:4] if abs(v[k]) > 1e-3]
        # name the [[constraint]] items that declared the undetermined coordinates
        owners = [
            f'[[constraint]] "{c.id}"'
            for c in sy.model.constraints
            if any(x in c.dependent for x in culprits)
        ]
        raise ModelError(
            ("dependent: " if owners else "")
            + "the constraint equations do not determine the dependent coordinates"
            f" {', '.join(culprits)} (W_d^T W_d of Eq. 2.6 is singular); give each dependent"
            " coordinate an equation in which it appears, and no dependent coordinate twice",
            source=sy.model.source,
            item=", ".join(owners)
            or ("[[constraint]]" if sy.model.constraints else "[[contact]]/[[attachment]]"),
            field="dependent" if owners else None,
        )
    # Eq. 2.6 is the least-squares solution of W_i + W_d W = 0; it solves the
    # constraints only if they are consistent.  More equations than dependent
    # coordinates that also tie independent coordinates together would
    # otherwise give a silent compromise W.
    W = sy.W(None)
    res = np.abs(G[:, sy.i] + Gd @ W).max(axis=1) if len(sy.i) else np.zeros(G.shape[0])
    scale = np.abs(G).max(axis=1) * max(1.0, float(np.abs(W).max(initial=0.0)))
    bad = np.nonzero(res > 1e-9 * scale)[0]
    if bad.size:
        mdl = sy.model
        owners = [f'[[attachment]] "{a.id}"' for a in mdl.attachments if a.body != GROUND for _ in range(3)]
        owners += [f'[[constraint]] "{c.id}"' for c in mdl.constraints for _ in c.equations]
        owners += [f'[[contact]] "{c.id}"' for c in mdl.contacts for _ in range(3)]
        items = list(dict.fromkeys(owners[k] for k in bad if k < len(owners)))
        raise ModelError(
            "equations: the constraint equations cannot all hold: together they also tie"
            " independent coordinates to each other, so no W satisfies W_i + W_d W = 0 (Eq. 2.6);"
            " drop the redundant equation or declare one more coordinate dependent",
            source=mdl.source,
            item=", ".join(items) or "[[constraint]]",
            field="equations",
        )


def _check_mass(sy: System) -> None:
    A = sy.reduce(None)[0]
    try:
        np.linalg.cholesky(A)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(A)
        v = V[:, 0]
        culprits = [sy.names_i[k] for k in np.argsort(-np.abs(v))[:3]]
        raise ModelError(
            f"the reduced inertia matrix A* is singular: coordinates {', '.join(culprits)} carry no mass;"
            " give the body a mass or make its coordinates dependent",
            source=sy.model.source,
        ) from None


def _assemble_matrices(model: Model) -> System:
    mb = model.matrices
    assert mb is not None
    names = list(mb.coordinates)
    index = {nm: k for k, nm in enumerate(names)}
    given = sorted({index[g] for g in mb.given} | {index[s.target] for s in model.supports})
    i_idx = np.array([k for k in range(len(names)) if k not in given], dtype=int)
    sysm = System(
        model=model,
        names=tuple(names),
        i=i_idx,
        d=np.zeros(0, dtype=int),
        g=np.array(given, dtype=int),
        M=mb.M,
        L=mb.L,
        K=mb.K,
        _const_rows=np.zeros((0, len(names))),
        _contacts=(),
        _elements=MappingProxyType({}),
        index=MappingProxyType(index),
    )
    if len(i_idx) == 0:
        raise ModelError(
            "every coordinate is given (fixed): nothing can move; remove some from [matrices] given / [[support]]",
            source=model.source,
            item="[matrices]",
            field="given",
        )
    # springs between named-coordinate points add to L and K (e.g. a joint added to an imported model)
    return _springs_into(sysm) if model.springs else sysm
