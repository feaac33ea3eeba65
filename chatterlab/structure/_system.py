"""The assembled system (built by :func:`~chatterlab.structure.assemble`).

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

from dataclasses import dataclass, field
from functools import cached_property
from types import MappingProxyType
from typing import Any

import numpy as np

from ..errors import InputError
from ..model._geometry import body_centre, point_xy
from ..model._items import DIRECTIONS, GROUND, Coupling, Model, PointRef
from ._complex import ComplexModes
from ._elements import beam_point_matrix, rigid_point_matrix, rotation3
from ._moving import MovingReduction, _ContactRows
from ._structure import Structure

__all__ = ["System", "FrozenSystem", "CouplingMatrices"]


@dataclass(frozen=True)
class CouplingMatrices:
    """A coupling element seen from the reduced (independent) coordinates.

    ``J`` maps q_i to the CE's relative displacement dw = w_a - w_b in CE
    axes (3, n_i).  The CE's contribution to D(s) of Eq. (2.23), at width b,
    is ``-(b / width_ref) J^T (DP + s DV + DO e^{-sT}) J``; its static force is
    ``(b / width_ref) J^T forces`` (the closed loop computes them:
    :func:`chatterlab.process.closed_loop`).
    """

    id: str
    J: np.ndarray
    DP: np.ndarray
    DV: np.ndarray
    DO: np.ndarray
    forces: np.ndarray
    width_ref: float
    coupling: Coupling


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
        if ref.kind == "coords" and ref.weights:  # a modal model: u = sum_k phi_k eta_k
            for r, entries in enumerate(ref.weights):
                for cname, w in entries:
                    T[r, self.index[cname]] += w
            return T
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
    def structure(self) -> Structure:
        """The configuration as the engines take a structure: M = A*, C = B*,
        K = C* (Eq. 2.16-2.18) on the independent coordinates, named."""
        return Structure(self.A, self.B, self.C, self.names, str(self.model.source))

    @property
    def complex_modes(self) -> ComplexModes:
        """Complex modes of s^2 A* + s B* + C* (computed once per configuration)."""
        return self.structure.complex_modes

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

    def with_process(self, model: Model) -> FrozenSystem:
        """This configuration with the cut and the kinematics of ``model``: a
        model that differs from this one only in ``[[coupling]]`` and
        ``[process]`` fields, which enter neither the mass, damping and
        stiffness matrices nor the constraints (the caller's promise; the
        uncertainty and sweep tasks vary a cutting coefficient this way).
        The structure's matrices, its complex modes and its reduction are
        this one's (the same arrays, computed once); the coupling maps are
        ``model``'s."""
        from dataclasses import replace

        out = FrozenSystem(replace(self.system, model=model), self.position, self.A, self.B, self.C, self.W)
        out.__dict__["structure"] = self.structure  # the cached property: the modes come with it
        return out

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
