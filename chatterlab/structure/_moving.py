"""Moving contacts: where a contact is on its track of beam elements
(:class:`_ContactRows`), and the low-rank reduction for a moving slide that
the time domain uses (:class:`MovingReduction`, reached through
:attr:`System.moving_reduction`).

References
----------
.. [1] E. Wittbrodt, K. J. Kaliński, "Transient vibration of unsteady linear
   closed loop systems", Eqs. (2.4)-(2.18).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from ..model._items import Beam, Model
from ._elements import beam_point_matrix

__all__ = ["MovingReduction"]


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


class _Structure(Protocol):
    """What :class:`MovingReduction` reads of a :class:`~chatterlab.structure.System`."""

    @property
    def model(self) -> Model: ...
    @property
    def i(self) -> np.ndarray: ...
    @property
    def d(self) -> np.ndarray: ...
    @property
    def M(self) -> np.ndarray: ...
    @property
    def L(self) -> np.ndarray: ...
    @property
    def K(self) -> np.ndarray: ...
    @property
    def n(self) -> int: ...
    @property
    def default_position(self) -> float | None: ...
    @property
    def _const_rows(self) -> np.ndarray: ...
    @property
    def _contacts(self) -> tuple[_ContactRows, ...]: ...
    def W(self, s: float | np.ndarray | None = None, order: int = 0) -> np.ndarray: ...


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

    def __init__(self, sy: _Structure) -> None:
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
