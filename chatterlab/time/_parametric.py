"""The parametric problem of Eq. (2.28) for the Newmark integrator.

:class:`ParametricProblem` gives A(t), B(t), C(t), the delayed G(t) and the
force p(t) of

    Â q̈_i + B̂ q̇_i + Ĉ q_i = p̂(t, t - T)                              (2.28)

for the slide moving as the process kinematics say, from the structure's
moving reduction (:attr:`chatterlab.structure.System.moving_reduction`, or
Eq. 2.6 and Eqs. 2.16-2.18 through :meth:`System.W_derivatives` and
:meth:`System.reduced_matrices` when the model does not allow it) and the
coupling elements' maps; per segment between element joints the
coefficients are exact polynomials in the slide position
(:class:`_Polynomial`).  :class:`_ExtraForce` adds external loads and
prescribed ground motion (Eq. 2.19, the q_g terms of Eq. 2.27).

References
----------
.. [1] E. Wittbrodt, K. J. Kaliński, seed paper, Eqs. (2.15)-(2.28), (3.5)-(3.12).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from ..errors import InputError, check_width
from ..model._items import DIRECTIONS
from ..process._kinematics import ShapingKinematics, SteadyKinematics
from ..process._loop import ce_maps
from ..structure._assembly import MovingReduction, System
from ._problems import Sealed

__all__ = ["ParametricProblem", "FEEDBACK_CASES"]

#: the paper's three cases: (a) none, (b) proportional + ideal derivative, (c) + delayed
FEEDBACK_CASES = ("none", "pd", "pdo")


#: the families of coefficient matrices: name -> the weights they carry
#: (1, the slide speed v, v^2, the in-cut flag c, c v)
_FAMILIES = {
    "A": (("A0", "1"),),
    "B": (("B0", "1"), ("B1", "v"), ("Bce", "c")),
    "C": (("C0", "1"), ("C1", "v"), ("C2", "vv"), ("Cce0", "c"), ("Cce1", "cv")),
    "G": (("G", "c"),),
    "F": (("F", "c"),),
}


class _Polynomial:
    """Coefficient matrices as exact polynomials in the slide position.

    Between two element joints (for every contact at once), the contact
    rows of W are the beam point map of one element: cubic in s (the
    Timoshenko element's transverse displacement is cubic, its rotation
    quadratic).  Every part of Eq. (2.28) -- A*, the speed terms of B*, C*,
    the CE terms J_i^T D J_i, J_i^T D_V J_i', the delayed matrix and the
    desired force -- is then a polynomial of degree <= 6 in s on such a
    *segment*.  Each segment's parts are interpolated once, at ``degree + 1``
    Chebyshev points, from the exact (low-rank) evaluation and checked
    between the points; a chunk of steps then costs one small GEMM per
    matrix: ``[phi(s), v phi(s), c phi(s), ...] @ coefficients``.
    Memory: (segments visited) x (non-zero parts) x 7 x n_i^2 doubles.
    """

    def __init__(self, owner: ParametricProblem, degree: int = 6) -> None:
        self.owner = owner
        assert owner.fast is not None
        self.fast: MovingReduction = owner.fast
        self.deg = degree
        self.segments: dict[tuple[int, ...], Any] = {}
        self.n = owner.n

    def _basis(self, u: np.ndarray, deg: int) -> np.ndarray:
        Phi = np.empty((u.size, deg + 1))
        Phi[:, 0] = 1.0
        if deg >= 1:
            Phi[:, 1] = u
        for j in range(2, deg + 1):
            Phi[:, j] = 2.0 * u * Phi[:, j - 1] - Phi[:, j - 2]
        return Phi

    def _build(self, key: tuple[int, ...], s_seen: float) -> Any:
        lo, hi = self.fast.interval(key)
        if not hi - lo > 1e-9 * max(1.0, abs(hi), abs(lo)):
            lo = hi = s_seen
        deg = self.deg if hi > lo else 0
        mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
        nodes = np.cos(np.pi * (np.arange(deg + 1) + 0.5) / (deg + 1))  # Chebyshev points, open
        parts = self.owner._parts_direct(mid + half * nodes)
        Phi = self._basis(nodes, deg)
        inv = np.linalg.inv(Phi)
        coef: dict[str, np.ndarray] = {}
        for fam in _FAMILIES.values():
            for name, _ in fam:
                val = parts.get(name)
                if val is None:
                    continue
                flat = np.asarray(val).reshape(deg + 1, -1)
                if not np.any(flat):
                    continue
                c = inv @ flat
                # interpolation round-off far below the family's scale (and the
                # subnormal numbers it produces, which slow BLAS down 50-fold)
                c[np.abs(c) < 1e-15 * np.abs(flat).max()] = 0.0
                coef[name] = c
        # check between the interpolation points against the direct evaluation
        if deg > 0:
            u_chk = np.array([-0.97, -0.41, 0.13, 0.66, 0.99])
            direct = self.owner._parts_direct(mid + half * u_chk)
            Phc = self._basis(u_chk, deg)
            for name, val in direct.items():
                if name not in ("A0", "B0", "B1", "C0", "C1", "C2", "Bce", "Cce0", "Cce1", "G", "F"):
                    continue
                ref = np.zeros((u_chk.size, 1)) if val is None else np.asarray(val).reshape(u_chk.size, -1)
                got = Phc @ coef[name] if name in coef else np.zeros_like(ref)
                scale = max(np.abs(ref).max(), np.abs(got).max(), 1e-300)
                if np.abs(got - ref).max() > 1e-9 * scale:
                    return None  # not a polynomial of this degree: evaluate directly
        stacks = {}
        for out, fam in _FAMILIES.items():
            names = [(nm, w) for nm, w in fam if nm in coef]
            if names:
                stacks[out] = ([w for _, w in names], np.concatenate([coef[nm] for nm, _ in names], axis=0))
        return (mid, half, deg, stacks)

    def evaluate(self, s: np.ndarray, v: np.ndarray, cut: np.ndarray) -> dict[str, np.ndarray | None] | None:
        """A, B, C, G (m, n, n) and F (m, n), or None where a segment is not
        polynomial (the caller then evaluates directly)."""
        _, idxs, sides, _ = self.fast.locate(s)
        keys = np.stack(sum(([i, sd] for i, sd in zip(idxs, sides, strict=True)), []), axis=1)
        uniq, inv_idx = np.unique(keys, axis=0, return_inverse=True)
        inv_idx = inv_idx.reshape(-1)
        m, n = s.size, self.n
        groups = []
        for g, key_arr in enumerate(uniq):
            key = tuple(int(x) for x in key_arr)
            sel = np.nonzero(inv_idx == g)[0] if uniq.shape[0] > 1 else np.arange(m)
            if key not in self.segments:
                self.segments[key] = self._build(key, float(s[sel[0]]))
            if self.segments[key] is None:
                return None
            groups.append((sel, self.segments[key]))
        present = {name for _, seg in groups for name in seg[3]}
        out: dict[str, Any] = {name: None for name in _FAMILIES}
        for name in present:
            out[name] = np.empty((m, n if name == "F" else n * n))
        weights = {"1": None, "v": v, "vv": v * v, "c": cut, "cv": cut * v}
        for sel, (mid, half, deg, stacks) in groups:
            whole = sel.size == m
            u = (s[sel] - mid) / half if deg > 0 else np.zeros(sel.size)
            Phi = self._basis(u, deg)
            for name in present:
                if name not in stacks:
                    out[name][sel] = 0.0
                    continue
                ws, coef = stacks[name]
                D = np.concatenate([Phi if w == "1" else Phi * weights[w][sel, None] for w in ws], axis=1)
                if whole:
                    np.matmul(D, coef, out=out[name])
                else:
                    out[name][sel] = D @ coef
        return out


class ParametricProblem(Sealed):
    """The time-varying problem of Eq. (2.28) for :func:`chatterlab.time._newmark.newmark`.

    Parameters
    ----------
    system : System
    kinematics : ShapingKinematics or SteadyKinematics
    width : float
        Width of cut b, m (scales the CE matrices and desired forces).
    terms : {"none", "pd", "pdo"}
        Feedback terms (the paper's cases a, b, c).
    forces : bool
        Apply the desired cutting forces P0 while in the cut.
    method : {"auto", "polynomial", "direct"}
        How the coefficients are evaluated: ``"polynomial"`` interpolates
        them exactly per segment between element joints (the fast path,
        see :class:`_Polynomial`), ``"direct"`` evaluates the low-rank
        reduction (or Eq. 2.6 when the model has constraints on the contact
        coordinates) at every step; ``"auto"`` uses the polynomial where
        possible; ``"generic"`` evaluates Eq. 2.6 and Eqs. 2.16-2.18 at every
        step even where the low-rank reduction applies (the path of a model
        whose constraints tie other coordinates to a contact; for checks).
    t_end : float, default 0
        The end of the simulated span, s: the process's breakpoints (cut
        entry and exit, reversal) up to it are reported to the integrator.

    Notes
    -----
    The problem is immutable (:class:`~chatterlab.time._problems.Sealed`);
    it caches its last evaluation and the coefficient polynomials it built.
    """

    def __init__(
        self,
        system: System,
        kinematics: ShapingKinematics | SteadyKinematics,
        *,
        width: float,
        terms: str = "pdo",
        forces: bool = True,
        method: str = "auto",
        t_end: float = 0.0,
    ) -> None:
        if terms not in FEEDBACK_CASES:
            raise InputError(f"feedback must be one of {', '.join(FEEDBACK_CASES)} (got {terms!r})")
        width = check_width(width)
        if method not in ("auto", "polynomial", "direct", "generic"):
            raise InputError(f"method must be 'auto', 'polynomial', 'direct' or 'generic' (got {method!r})")
        self.system = system
        self.kin = kinematics
        self.n = len(system.i)
        J, P, V, O, F = ce_maps(system, width)
        self.J = J  # (3m, n_all) in CE axes
        self.Jd = J[:, system.d]
        self.Ji0 = J[:, system.i]
        self.P = P if terms != "none" else np.zeros_like(P)
        self.V = V if terms != "none" else np.zeros_like(V)
        self.O = O if terms == "pdo" else np.zeros_like(O)
        self.F = F if forces else np.zeros_like(F)
        self.terms = terms
        self.width = float(width)
        self._T = float(kinematics.delay) if terms == "pdo" else None
        self.t_end = float(t_end)
        self.fast = system.moving_reduction if method != "generic" else None
        if self.fast is not None:
            self.Jv = J[:, self.fast.dv]
            self.Ji_const = J @ self.fast.Tm  # (3k, n_i) with the contact columns' constant part
        self.poly = _Polynomial(self) if (self.fast is not None and method != "direct") else None
        if method == "polynomial" and self.poly is None:
            raise InputError(
                "method='polynomial' needs a movable model whose contact coordinates are tied to the "
                "structure only by their [[contact]] rows"
            )
        self._memo: tuple[bytes, tuple[Any, ...]] | None = None
        self.method_used: set[str] = set()  # a record of the evaluations, owned by the problem
        self._seal()

    # -- TimeVaryingProblem -------------------------------------------------
    def delay(self) -> float | None:
        return self._T

    def breakpoints(self) -> tuple[float, ...]:
        """Times where the tool enters or leaves the cut or the slide reverses
        (the coefficients and forces jump there), over the simulated span."""
        return self.kin.breakpoints(self.t_end) if isinstance(self.kin, ShapingKinematics) else ()

    def _positions(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
        """s, v, in-cut mask and whether s is a slide position (a model with
        a movable subsystem; a slide held still without a position sits at
        the model's default position)."""
        s, v, cut, _ = self.kin.state(t)
        if self.system.model.movable is None:
            return np.full(t.size, np.nan), np.zeros(t.size), cut, False
        if not np.all(np.isfinite(s)):
            pos = self.system.default_position
            s = np.full(t.size, float(pos) if pos is not None else 0.0)
            v = np.zeros(t.size)
        return s, v, cut, True

    def _parts_direct(self, s: np.ndarray) -> dict[str, Any]:
        """All parts of Eq. (2.28) at slide positions s, for unit slide speed
        and the tool in the cut (see :meth:`MovingReduction.parts`):
        A = A0, B = B0 + v B1 + c Bce, C = C0 + v C1 + v^2 C2 + c (Cce0 + v Cce1),
        G = c G, F = c F, with c the in-cut flag."""
        p: dict[str, Any]
        if self.fast is not None:
            p = self.fast.parts(s)
            Ji = self.Ji_const + self.Jv @ p["R0"]
            Jd1 = self.Jv @ p["R1"]
        else:
            sy = self.system
            W0, W1, W2 = self._W_direct(s)
            A, B, C = sy.reduced_matrices(W0, np.zeros_like(W0), np.zeros_like(W0))
            p = {"A0": A, "B0": B, "C0": C, "B1": None, "C1": None, "C2": None}
            if len(sy.d) and np.any(W1):
                B1, C1, C2 = sy.speed_parts(W0, W1, W2)
                p.update(B1=B1, C1=C1, C2=C2)
            Ji = (
                self.Ji0 + self.Jd @ W0
                if len(sy.d)
                else np.broadcast_to(self.Ji0, (s.size,) + self.Ji0.shape)
            )
            Jd1 = self.Jd @ W1 if len(sy.d) else np.zeros_like(Ji)
        JiT = np.transpose(Ji, (0, 2, 1))
        p["Ji"], p["Jd1"] = Ji, Jd1
        p["Bce"] = JiT @ self.V @ Ji if np.any(self.V) else None
        p["Cce0"] = JiT @ self.P @ Ji if np.any(self.P) else None
        p["Cce1"] = JiT @ self.V @ Jd1 if (np.any(self.V) and np.any(Jd1)) else None
        p["G"] = -(JiT @ self.O @ Ji) if self._T is not None else None
        p["F"] = np.einsum("mkn,k->mn", Ji, self.F) if np.any(self.F) else None
        return p

    def _W_direct(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        sy = self.system
        if sy.model.movable is None or not np.all(np.isfinite(s)):
            W0 = np.broadcast_to(sy.W(None), (s.size,) + (len(sy.d), len(sy.i)))
            Z = np.zeros(W0.shape)
            return np.array(W0), Z, Z
        return sy.W_derivatives(s)

    def _evaluate(self, t: np.ndarray) -> tuple[Any, ...]:
        """A, B, C, G (or None) and F at times t; the last call is memoised
        (newmark asks for the force and the matrices of the same steps)."""
        key = t.tobytes()
        if self._memo is not None and self._memo[0] == key:
            return self._memo[1]
        s, v, cut, moving = self._positions(t)
        c = cut.astype(float)
        res = None
        if self.poly is not None and moving:
            res = self.poly.evaluate(s, v, c)
        m, n = t.size, self.n
        if res is not None:
            self.method_used.add("polynomial")

            def mat(name: str) -> np.ndarray | None:
                x = res[name]
                return None if x is None else x.reshape(m, n, n)

            A = mat("A")
            B = mat("B")
            C = mat("C")
            G = mat("G") if self._T is not None else None
            F = res["F"] if res["F"] is not None else np.zeros((m, n))
            if G is None and self._T is not None:
                G = np.zeros((m, n, n))
            zero = np.zeros((m, n, n))
            A = zero if A is None else A
            B = zero if B is None else B
            C = zero if C is None else C
        else:
            self.method_used.add("direct")
            p = self._parts_direct(s)
            cc = c[:, None, None]
            vv = v[:, None, None]
            A = np.array(p["A0"])
            B = np.array(p["B0"])
            C = np.array(p["C0"])
            if p["B1"] is not None:
                B = B + vv * p["B1"]
            if p["C1"] is not None:
                C = C + vv * p["C1"]
            if p["C2"] is not None:
                C = C + vv**2 * p["C2"]
            if p["Bce"] is not None:
                B = B + cc * p["Bce"]
            if p["Cce0"] is not None:
                C = C + cc * p["Cce0"]
            if p["Cce1"] is not None:
                C = C + (cc * vv) * p["Cce1"]
            G = cc * p["G"] if p["G"] is not None else None
            F = c[:, None] * p["F"] if p["F"] is not None else np.zeros((m, n))
        out = (A, B, C, G, F)
        object.__setattr__(self, "_memo", (key, out))  # the problem's own cache
        return out

    def maps(self, t: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """``rows @ T(t)``: maps (m, k, n_i) from q_i to k quantities given as
        rows (k, n) over all coordinates, T(t) = [I; W(t)] (Eq. 2.5)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        rows = np.atleast_2d(np.asarray(rows, dtype=float))
        s, _, _, moving = self._positions(t)
        sy = self.system
        if self.fast is not None and moving:
            R0 = self.fast.rows(s, np.zeros(s.size), orders=1)[0]
            return rows @ self.fast.Tm + rows[:, self.fast.dv] @ R0
        base = np.broadcast_to(rows[:, sy.i], (t.size,) + rows[:, sy.i].shape)
        if not len(sy.d):
            return np.array(base)
        W0 = self._W_direct(s)[0]
        return base + rows[:, sy.d] @ W0

    def ce_map(self, t: np.ndarray) -> np.ndarray:
        """J_i(t): q_i -> CE relative displacements (m, 3k, n_i)."""
        return self.maps(t, self.J)

    def matrices(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        A, B, C, G, _ = self._evaluate(t)
        return A, B, C, G

    def force(self, t: np.ndarray) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return self._evaluate(t)[4]


class _ExtraForce(Sealed):
    """Generalised forces on q_i from external loads and prescribed motion of
    given coordinates (Eq. 2.19 and the q_g terms of Eq. 2.27)."""

    def __init__(
        self,
        prob: ParametricProblem,
        loads: Mapping[str, Callable[[np.ndarray], np.ndarray]] | None,
        ground: Mapping[str, Callable[[np.ndarray], Any]] | None,
    ) -> None:
        sy = prob.system
        self.prob = prob
        self.load_fns = [fn for fn in (loads or {}).values()]
        self.load_rows = np.array([_output_map(sy, name) for name in (loads or {})]).reshape(-1, sy.n)
        for name, fn in (loads or {}).items():
            if not callable(fn):
                raise InputError(f"load '{name}' must be a callable f(t) returning the force at the times t")
        given = {sy.names[k]: j for j, k in enumerate(sy.g)}
        self.g_cols: list[int] = []
        self.g_fns: list[Callable[[np.ndarray], Any]] = []
        for name, fn in (ground or {}).items():
            if name not in given:
                raise InputError(
                    f"ground_motion '{name}' is not a given coordinate (given: {', '.join(given) or 'none'});"
                    " prescribe motion only of the foundation or supported coordinates"
                )
            if not callable(fn):
                raise InputError(
                    f"ground_motion '{name}' must be a callable g(t) returning (q, q_dot, q_ddot)"
                )
            self.g_cols.append(int(sy.g[given[name]]))
            self.g_fns.append(fn)
        keep = np.array(sorted(set(sy.i.tolist()) | set(sy.d.tolist())), dtype=int)
        self.keep = keep
        g = np.array(self.g_cols, dtype=int)
        self.Mg, self.Lg, self.Kg = (X[np.ix_(keep, g)] for X in (sy.M, sy.L, sy.K))
        self.Jg = prob.J[:, g]
        self._seal()

    def _motion(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        q = np.zeros((len(self.g_fns), t.size))
        v = np.zeros_like(q)
        a = np.zeros_like(q)
        for k, fn in enumerate(self.g_fns):
            out = fn(t)
            if not (isinstance(out, tuple | list) and len(out) == 3):
                raise InputError("a ground_motion callable must return (q, q_dot, q_ddot)")
            q[k], v[k], a[k] = (np.broadcast_to(np.asarray(x, float), t.shape) for x in out)
        return q, v, a

    def __call__(self, t: np.ndarray) -> np.ndarray:
        prob, sy = self.prob, self.prob.system
        out = np.zeros((t.size, prob.n))
        if self.load_fns:
            f = np.array([np.broadcast_to(np.asarray(fn(t), float), t.shape) for fn in self.load_fns])
            out += np.einsum("mkn,km->mn", prob.maps(t, self.load_rows), f)
        if self.g_fns:
            q, v, a = self._motion(t)
            # Eq. (2.19): p* = -T^T (M_.g q_g'' + L_.g q_g' + K_.g q_g) over the kept coordinates
            rows = np.zeros((self.keep.size, sy.n))
            rows[np.arange(self.keep.size), self.keep] = 1.0
            Tt = prob.maps(t, rows)  # (m, n_kept, n_i)
            fk = -(self.Mg @ a + self.Lg @ v + self.Kg @ q)  # (n_kept, m)
            out += np.einsum("mkn,km->mn", Tt, fk)
            # Eq. (2.27): the coupling elements see the given coordinates' motion while cutting
            if self.Jg.size and (np.any(prob.P) or np.any(prob.V) or np.any(prob.O)):
                cut = prob.kin.state(t)[2].astype(float)
                dw = self.Jg @ q
                dwd = self.Jg @ v
                fce = prob.P @ dw + prob.V @ dwd
                if prob.delay() is not None:
                    qT = self._motion(t - prob.delay())[0]
                    fce = fce + prob.O @ (self.Jg @ qT)
                Ji = prob.maps(t, prob.J)  # (m, 3k, n_i)
                out -= cut[:, None] * np.einsum("mkn,km->mn", Ji, fce)
        return out


class _WithExtraForce(Sealed):
    """A problem whose force is the wrapped problem's plus an extra force."""

    def __init__(self, base: ParametricProblem, extra: _ExtraForce) -> None:
        self.base = base
        self.extra = extra
        self.n = base.n
        self._seal()

    def delay(self) -> float | None:
        return self.base.delay()

    def breakpoints(self) -> tuple[float, ...]:
        return self.base.breakpoints()

    def matrices(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        return self.base.matrices(t)

    def force(self, t: np.ndarray) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return self.base.force(t) + self.extra(t)


def _output_map(system: System, spec: str) -> np.ndarray:
    """Row over all coordinates for "POINT.DIR" (or a coordinate name)."""
    if spec in system.index:
        row = np.zeros(system.n)
        row[system.index[spec]] = 1.0
        return row
    name, _, d = spec.rpartition(".")
    if d not in DIRECTIONS or not name:
        raise InputError(f"output '{spec}' is not POINT.DIR with DIR one of {', '.join(DIRECTIONS)}")
    ref = system.resolve_point(name)
    return system.point_map(ref)[DIRECTIONS.index(d)]
