"""Transient simulation of the parametric closed loop (Eq. 2.28).

The slide moves (``W = W(s(t))``), the cutting force feeds back with
proportional, ideal-derivative and delayed terms while the tool is in the cut,
and the desired cutting forces load the structure:

    Â q̈_i + B̂ q̇_i + Ĉ q_i = p̂(t, t - T)                              (2.28)

with, for the coupling element's map J_i(t) = J_i + J_d W(t) from q_i to the
relative displacement dw in CE axes and J̇ = J_d Ẇ,

    Â = A*(t),                       B̂ = B*(t) + J_iᵀ D_V J_i,
    Ĉ = C*(t) + J_iᵀ D_P J_i + J_iᵀ D_V J̇,
    p̂ = J_iᵀ P0 - J_iᵀ D_O J_i q_i(t - T)

(A*, B*, C* of Eq. 2.16-2.18 with Ẇ = W'(s) v, Ẅ = W''(s) v²; the feedback
terms are Eq. 2.27 written through the CE, with E = -Jᵀ Dl J q; all CE terms
are switched off outside the cut).  The delayed term uses W(t), as in the
paper: for shaping the slide is at the same position one stroke cycle earlier,
so this is exact.  The integrator is :func:`chatterlab.time._newmark.newmark`.

References
----------
.. [1] E. Wittbrodt, K. J. Kaliński, seed paper, Eqs. (2.15)-(2.28), (3.5)-(3.12).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from ..errors import InputError, check_positive, check_width
from ..model._items import DIRECTIONS
from ..process._cutting import ce_maps
from ..process._kinematics import ShapingKinematics, SteadyKinematics, kinematics_for
from ..structure._assembly import MovingReduction, System
from ._newmark import ConstantProblem, NewmarkOptions, TimeResponse, newmark

__all__ = ["ParametricProblem", "Simulation", "simulate", "FEEDBACK_CASES"]

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


class ParametricProblem:
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
        possible.
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
    ) -> None:
        if terms not in FEEDBACK_CASES:
            raise InputError(f"feedback must be one of {', '.join(FEEDBACK_CASES)} (got {terms!r})")
        width = check_width(width)
        if method not in ("auto", "polynomial", "direct"):
            raise InputError(f"method must be 'auto', 'polynomial' or 'direct' (got {method!r})")
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
        self._t_end = 0.0
        self.fast = system.moving_reduction
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
        self.method_used: set[str] = set()

    # -- TimeVaryingProblem -------------------------------------------------
    def delay(self) -> float | None:
        return self._T

    def breakpoints(self) -> tuple[float, ...]:
        """Times where the tool enters or leaves the cut or the slide reverses
        (the coefficients and forces jump there), over the simulated span."""
        return self.kin.breakpoints(self._t_end) if isinstance(self.kin, ShapingKinematics) else ()

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
        self._memo = (key, out)
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


@dataclass(frozen=True, eq=False)
class Simulation:
    """A transient run: named time histories and the process state.

    Attributes
    ----------
    t : ndarray, shape (n_t,)
        Recorded times, s.
    data : dict of str -> ndarray (n_t,)
        Time histories of the requested outputs (``"rfe5.x"``: m; ``"rz"``:
        rad) and of the CE relative displacements ``"<ce>.1"``, ``"<ce>.2"``
        (m, in CE axes: q_z and dh for the shaper).
    position : ndarray (n_t,)
        Slide position s, m.
    in_cut : ndarray of bool (n_t,)
    cut_distance : ndarray (n_t,)
        Distance travelled in the cut, m (NaN outside).
    """

    t: np.ndarray
    data: dict[str, np.ndarray]
    position: np.ndarray
    in_cut: np.ndarray
    cut_distance: np.ndarray
    response: TimeResponse
    terms: str
    width: float
    delay: float
    step: float
    passes: int
    units: dict[str, str]
    model: str
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def status(self) -> str:
        return self.response.status

    @property
    def message(self) -> str:
        return self.response.message

    def window(self, which: str | tuple[float, float] = "last-cut") -> np.ndarray:
        """Boolean mask of a time window: ``"last-cut"`` (the last pass in the
        cut), ``"cut"`` (every pass in the cut), ``"all"``, or (t0, t1)."""
        if isinstance(which, tuple):
            return (self.t >= which[0]) & (self.t <= which[1])
        if which == "all":
            return np.ones(self.t.size, bool)
        if which == "cut":
            return self.in_cut.copy()
        if which == "last-cut":
            m = self.in_cut
            if not m.any():
                return np.ones(self.t.size, bool)
            starts = np.nonzero(m & ~np.concatenate([[False], m[:-1]]))[0]
            out = np.zeros(self.t.size, bool)
            j = starts[-1]
            k = j
            while k < m.size and m[k]:
                k += 1
            out[j:k] = True
            return out
        raise InputError(f"window must be 'last-cut', 'cut', 'all' or (t0, t1), got {which!r}")

    def spectrum(
        self, name: str, *, window: str | tuple[float, float] = "last-cut", taper: str = "hann"
    ) -> tuple[np.ndarray, np.ndarray]:
        """Single-sided amplitude spectrum (Hz, unit of the signal) of one
        output over a time window (mean and trend removed, Hann window with
        coherent-gain correction)."""
        from ._signals import amplitude_spectrum

        m = self.window(window)
        return amplitude_spectrum(self.t[m], self._get(name)[m], window=taper)

    def growth(self, name: str, *, window: str | tuple[float, float] = "all", skip: float = 0.0) -> Any:
        """Exponential growth rate of the envelope of one output (1/s) with a
        decaying / steady / growing classification."""
        from ._signals import growth_rate

        m = self.window(window) & (self.t >= self.t[0] + skip)
        return growth_rate(self.t[m], self._get(name)[m])

    def _get(self, name: str) -> np.ndarray:
        if name not in self.data:
            raise InputError(f"no output '{name}' (recorded: {', '.join(self.data)})")
        return self.data[name]

    def to_csv(self, path: Any) -> None:
        """Time histories: t [s], s [m], in_cut, cut distance [m], outputs,
        and the run's status (``ok``, ``diverged``, ``interrupted``) in the
        last column, so that the file alone says whether it can be trusted."""
        import csv

        from ..io._files import text_out

        names = list(self.data)
        status = self.status
        with text_out(path) as fh:
            w = csv.writer(fh)
            w.writerow(
                ["t [s]", "position [m]", "in_cut [-]", "cut_distance [m]"]
                + [f"{n} [{self.units.get(n, 'm')}]" for n in names]
                + ["status"]
            )
            for k in range(self.t.size):
                w.writerow(
                    [
                        f"{self.t[k]:.9g}",
                        f"{self.position[k]:.9g}",
                        int(self.in_cut[k]),
                        f"{self.cut_distance[k]:.9g}",
                    ]
                    + [f"{self.data[n][k]:.9g}" for n in names]
                    + [status]
                )

    def to_netcdf(self, path: str, attrs: dict[str, Any] | None = None) -> None:
        """netCDF with time as the coordinate (s) and every output as data."""
        from ..io._netcdf import write_netcdf

        data = {
            "position": (self.position, "m", "slide position s"),
            "in_cut": (self.in_cut.astype(float), "1", "tool in the cut"),
            "cut_distance": (self.cut_distance, "m", "distance travelled in the cut"),
        }
        for n, arr in self.data.items():
            data[_var(n)] = (arr, self.units.get(n, "m"), n)
        a = {
            "title": "chatterlab transient simulation (Newmark, Eq. 2.28)",
            "model": self.model,
            "feedback": self.terms,
            "width_m": self.width,
            "delay_s": self.delay,
            "step_s": self.step,
            "passes": self.passes,
            "status": self.status,
            "message": self.message,
        }
        a.update(self.meta)
        a.update(attrs or {})
        write_netcdf(path, coords={"time": (self.t, "s")}, data=data, attrs=a)

    def plot(
        self,
        names: list[str] | None = None,
        *,
        against: Literal["time", "distance"] = "time",
        axes: Any = None,
    ) -> Any:
        """Time histories (or against the cut distance) of outputs, one panel
        each; returns the Axes."""
        from ..plot._plot import plot_histories

        return plot_histories([self], names or list(self.data)[:2], against=against, axes=axes)


def _var(name: str) -> str:
    import re

    v = re.sub(r"[^0-9A-Za-z_]", "_", name)
    return v if not v[:1].isdigit() else f"v_{v}"


class _ExtraForce:
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


class _WithExtraForce:
    """A problem whose force is the wrapped problem's plus an extra force."""

    def __init__(self, base: ParametricProblem, extra: _ExtraForce) -> None:
        self.base = base
        self.extra = extra
        self.n = base.n

    def delay(self) -> float | None:
        return self.base.delay()

    def breakpoints(self) -> tuple[float, ...]:
        return self.base.breakpoints()

    def matrices(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        return self.base.matrices(t)

    def force(self, t: np.ndarray) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return self.base.force(t) + self.extra(t)


def simulate(
    system: System,
    *,
    feedback: Literal["none", "pd", "pdo"] = "pdo",
    width: float | None = None,
    speed: float | None = None,
    delay: float | None = None,
    position: float | None = None,
    passes: int = 2,
    duration: float | None = None,
    step: float | None = None,
    outputs: list[str] | tuple[str, ...] | None = None,
    forces: bool = True,
    options: NewmarkOptions | None = None,
    q0: np.ndarray | None = None,
    progress: Any = None,
    record_every: int = 1,
    method: Literal["auto", "polynomial", "direct"] = "auto",
    loads: Mapping[str, Callable[[np.ndarray], np.ndarray]] | None = None,
    ground_motion: Mapping[str, Callable[[np.ndarray], Any]] | None = None,
) -> Simulation:
    """Newmark simulation of the moving, delayed closed loop (Eq. 2.28).

    Parameters
    ----------
    system : System
        The assembled model.
    feedback : {"none", "pd", "pdo"}
        The paper's cases (a) no feedback, (b) proportional + ideal
        derivative, (c) + delayed.
    width : float, optional
        Width of cut b, m (default: the first coupling's ``width_ref``).
    speed : float, optional
        Work speed (shaping, m/s) or spindle speed (turning, rpm).
    delay : float, optional
        Delay T, s: holds the slide still (at ``position``) and cuts continuously.
    position : float, optional
        Hold the slide at s (m) instead of running stroke cycles.
    passes : int
        Number of stroke cycles (shaping) or delay periods (steady) simulated
        when ``duration`` is not given.
    duration : float, optional
        Simulated time, s.
    step : float, optional
        Time step h, s.  Default: a twentieth of the period of the highest
        natural frequency below 300 Hz, and at most T/20, rounded down so
        that the process events (cut entry and exit, reversal, one cycle)
        fall on the step grid.
    outputs : list of str, optional
        ``"POINT.DIR"`` time histories to record (default: the first CE's
        points ``b`` along x and y — the paper's q1, q2 at RFE 5).
    forces : bool
        Apply the desired cutting forces while in the cut.
    loads : mapping, optional
        External forces: ``"POINT.DIR" -> f(t)`` (or a coordinate name), f a
        vectorised callable returning the force (N, or N m for ``rz``) at the
        times ``t`` (s), in global axes.  A load on a moving contact travels
        with it.
    ground_motion : mapping, optional
        Prescribed motion of given coordinates (Eq. 2.19): ``"ground.y" -> g(t)``
        with g returning ``(q, q_dot, q_ddot)`` arrays at the times t (m, m/s,
        m/s^2 or rad...).  It loads the structure through the stiffness,
        damping and mass couplings, and through the coupling elements' terms
        on given coordinates (Eq. 2.27) while cutting.
    options : NewmarkOptions, optional
        Integrator parameters and memory limits.
    q0 : array (n_i,), optional
        Initial displacement of the independent coordinates (the delay
        history is zero).
    progress : callable, optional
        ``progress(fraction)`` after each chunk of steps.
    record_every : int
        Record every k-th step.
    method : {"auto", "polynomial", "direct"}
        Coefficient evaluation (see :class:`ParametricProblem`); the results
        agree to rounding.

    Returns
    -------
    Simulation

    Raises
    ------
    InputError
        Bad arguments (non-positive width, duration or step; a step longer
        than the delay; an unknown output; a delay history or a record above
        the memory limits of ``options``; a stroke outside the movable range).
    """
    mdl = system.model
    width, duration, step, kin = _check_run(
        system, feedback, width, passes, duration, step, speed, delay, position
    )
    T = float(kin.delay)
    if duration is None:
        duration = passes * T
    outs = list(outputs) if outputs is not None else _default_outputs(mdl)
    out_rows = [_output_map(system, name) for name in outs]  # refuse unknown outputs before the run
    step = _time_step(system, kin, feedback, step, position, duration)
    prob = ParametricProblem(system, kin, width=float(width), terms=feedback, forces=forces, method=method)
    prob._t_end = float(duration)
    run_prob = _run_problem(prob, loads, ground_motion)
    with _blas_limits():
        res = newmark(
            run_prob,
            (0.0, float(duration)),
            step,
            q0,
            options=options,
            record_every=record_every,
            progress=progress,
        )
    data, units = _histories(prob, res, outs, out_rows)
    s, _, cut, cd = kin.state(res.t)
    return Simulation(
        t=res.t,
        data=data,
        position=s,
        in_cut=cut,
        cut_distance=cd,
        response=res,
        terms=feedback,
        width=float(width),
        delay=T,
        step=step,
        passes=int(passes),
        units=units,
        model=mdl.source,
        meta={"kinematics": type(kin).__name__, "coefficients": "+".join(sorted(prob.method_used))},
    )


def _check_run(
    system: System,
    feedback: str,
    width: float | None,
    passes: Any,
    duration: float | None,
    step: float | None,
    speed: float | None,
    delay: float | None,
    position: float | None,
) -> tuple[float, float | None, float | None, ShapingKinematics | SteadyKinematics]:
    """The arguments of :func:`simulate` checked: ``(width, duration, step, kinematics)``."""
    mdl = system.model
    if feedback not in FEEDBACK_CASES:
        raise InputError(f"feedback must be one of {', '.join(FEEDBACK_CASES)} (got {feedback!r})")
    if not mdl.couplings:
        raise InputError(f"{mdl.source} has no [[coupling]]: a simulation of the cut needs one")
    if width is None:
        width = mdl.couplings[0].width_ref
    width = check_width(width)
    if not (isinstance(passes, int | np.integer) and not isinstance(passes, bool) and passes >= 1):
        raise InputError(f"passes must be an integer >= 1 (got {passes!r})")
    if duration is not None:
        duration = check_positive(duration, "duration", "s")
    if step is not None:
        step = check_positive(step, "step", "s")
    return width, duration, step, _kinematics(system, speed, delay, position)


def _kinematics(
    system: System, speed: float | None, delay: float | None, position: float | None
) -> ShapingKinematics | SteadyKinematics:
    """The process kinematics, its stroke and position checked against the movable range."""
    mdl = system.model
    kin = kinematics_for(mdl.process, speed=speed, delay=delay, position=position)
    if isinstance(kin, ShapingKinematics) and mdl.movable is not None:
        lo, hi = mdl.movable.range
        a, b = kin.range
        tol = 1e-9 * max(1.0, abs(lo), abs(hi))
        if a < lo - tol or b > hi + tol:
            raise InputError(
                f"the stroke runs over s = [{a:g}, {b:g}] m (start {kin.start:g} m, run-in + cut + coast "
                f"{kin.stroke:g} m) but the movable range is [{lo:g}, {hi:g}] m; fix [process] start/direction "
                "or widen [movable] range"
            )
    if position is not None and mdl.movable is not None:
        system.positions(position)  # refuses a position outside the movable range
    return kin


def _time_step(
    system: System,
    kin: ShapingKinematics | SteadyKinematics,
    feedback: str,
    step: float | None,
    position: float | None,
    duration: float,
) -> float:
    """The step h, s: the given one, or a twentieth of the period of the
    highest natural frequency below 300 Hz and at most T/20, rounded down
    so that the process events fall on the step grid; checked against the
    delay and the duration."""
    T = float(kin.delay)
    if step is None:
        from ..structure._modal import modes

        f = modes(system.at(position if isinstance(kin, SteadyKinematics) else None)).frequency_hz
        fmax = float(f[f < 300.0].max()) if np.any(f < 300.0) else float(f.min())
        step = min(1.0 / (20.0 * fmax), T / 20.0)
        # a whole number of steps between the process events (cut entry and
        # exit, reversal, one cycle) keeps them and the delayed samples on the grid
        unit = kin.grid_unit if isinstance(kin, ShapingKinematics) else T
        if unit < 0.25 * step:  # events on a grid much finer than needed: keep the cycle on it only
            unit = T
        step = unit / math.ceil(unit / step)
    step = float(step)
    if feedback == "pdo" and step > T * (1 + 1e-12):
        raise InputError(
            f"step {step:g} s is larger than the delay T = {T:g} s: the delayed term needs h <= T; "
            "use a smaller step (--step)"
        )
    if step > duration * (1 + 1e-12):
        raise InputError(f"step {step:g} s is longer than the duration {duration:g} s")
    return step


def _run_problem(
    prob: ParametricProblem,
    loads: Mapping[str, Callable[[np.ndarray], np.ndarray]] | None,
    ground_motion: Mapping[str, Callable[[np.ndarray], Any]] | None,
) -> Any:
    """What newmark integrates: the parametric problem (with the external
    loads and ground motion added), or for steady kinematics its constant
    matrices at t = 0 (factored once)."""
    extra = _ExtraForce(prob, loads, ground_motion) if (loads or ground_motion) else None
    if not isinstance(prob.kin, SteadyKinematics):
        return prob if extra is None else _WithExtraForce(prob, extra)
    A, B, C, G = prob.matrices(np.array([0.0]))
    f0 = np.array(prob.force(np.array([0.0]))[0])
    force: Any = f0
    if extra is not None:

        def force(tt: np.ndarray, f0: np.ndarray = f0, extra: _ExtraForce = extra) -> np.ndarray:
            return f0[None, :] + extra(np.atleast_1d(tt))

    return ConstantProblem(
        A[0],
        B[0],
        C[0],
        force=force,
        G=None if G is None else G[0],
        delay=prob.delay(),
    )


def _histories(
    prob: ParametricProblem, res: TimeResponse, outs: list[str], out_rows: list[np.ndarray]
) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """The named time histories (requested outputs, then the CE relative
    displacements) from q_i and their units."""
    t, q = res.t, res.q  # q: (n_i, n_t)
    nce = prob.J.shape[0]
    rows = np.vstack([prob.J] + [r[None, :] for r in out_rows]) if out_rows else prob.J
    vals = np.empty((rows.shape[0], t.size))
    blk = 4096
    for j0 in range(0, t.size, blk):
        sl = slice(j0, min(j0 + blk, t.size))
        Mp = prob.maps(t[sl], rows)  # (m, k, n_i)
        vals[:, sl] = np.einsum("mkn,nm->km", Mp, q[:, sl])
    data: dict[str, np.ndarray] = {}
    units: dict[str, str] = {}
    for j, name in enumerate(outs):
        data[name] = vals[nce + j]
        units[name] = "rad" if name.endswith(".rz") else "m"
    for k, c in enumerate(prob.system.model.couplings):
        for j in (0, 1):
            data[f"{c.id}.{j + 1}"] = vals[3 * k + j]
            units[f"{c.id}.{j + 1}"] = "m"
    return data, units


def _blas_limits() -> Any:
    """Single-threaded BLAS while integrating: every product is small (n_i
    of a few tens), so threads gain nothing, and on shared cores a
    multi-threaded call waits for a time slice (10x slower and erratic).
    The integrator's own worker threads use the second core."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - optional
        import contextlib

        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


def _default_outputs(mdl: Any) -> list[str]:
    c = mdl.couplings[0]
    tgt = (
        c.b.target if c.b.kind in ("body", "node") else (c.a.target if c.a.kind in ("body", "node") else None)
    )
    if tgt is None:
        return []
    return [f"{tgt}.x", f"{tgt}.y"]


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
