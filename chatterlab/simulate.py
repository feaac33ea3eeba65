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
so this is exact.  The integrator is :func:`chatterlab.newmark.newmark`.

References
----------
.. [1] E. Wittbrodt, K. J. Kaliński, seed paper, Eqs. (2.15)-(2.28), (3.5)-(3.12).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from .assembly import System
from .cutting import ce_maps
from .errors import InputError
from .kinematics import ShapingKinematics, SteadyKinematics, kinematics_for
from .model import DIRECTIONS
from .newmark import ConstantProblem, NewmarkOptions, TimeResponse, newmark

__all__ = ["ParametricProblem", "Simulation", "simulate", "FEEDBACK_CASES"]

#: the paper's three cases: (a) none, (b) proportional + ideal derivative, (c) + delayed
FEEDBACK_CASES = ("none", "pd", "pdo")


class _FastReduction:
    """A*, B*, C* and J_i for a moving slide, exploiting the structure.

    Only the rows of W that belong to moving contacts depend on s, and by
    direct substitution they are R_c(s) = P(xi(s)) T_e: the beam point map of
    the element under the contact times the (constant) map T_e from q_i to
    that element's nodal coordinates.  With T(s) = T0 + E R(s) (E selecting
    the contact rows) each reduced matrix is a constant part plus low-rank
    terms in R, R' v and R'' v^2 -- a few (n_i x 3k) products per step
    instead of Eq. (2.6) and a full reduction.  Exact; checked against the
    generic path when built.
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
        self.X0, self.Xv, self.Xvv = [], [], []
        for X in (sy.M, sy.L, sy.K):
            self.X0.append(Tm.T @ X @ Tm)
            self.Xv.append(Tm.T @ X[:, self.dv])
            self.Xvv.append(X[np.ix_(self.dv, self.dv)])
        self.n_i = n_i
        if self.ok:
            s_chk = np.array(sy.model.movable.range if sy.model.movable else [0.0, 0.0]) * np.array(
                [0.9, 1.0]
            ) + np.array([0.1 * (sy.model.movable.range[1] if sy.model.movable else 0.0), 0.0])
            s_chk = np.append(s_chk, s0)
            for sc in s_chk:
                R0, _, _ = self.rows(np.array([sc]), np.array([0.0]))
                ref = sy.W(float(sc))[self.pos_v]
                if not np.allclose(R0[0], ref, rtol=1e-9, atol=1e-12 * max(1.0, np.abs(ref).max())):
                    self.ok = False
                    break

    def rows(self, s: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Contact rows of W, dW/dt and d2W/dt2: each (m, 3k, n_i)."""
        from .elements import beam_point_matrix

        m = s.size
        k3 = 3 * len(self.sy._contacts)
        R = np.zeros((3, m, k3, self.n_i))
        for ci, c in enumerate(self.sy._contacts):
            x = c.x_ref + c.rate * (s - c.s_ref)
            inside = np.ones(m)
            if c.clamp:
                inside = ((x >= 0.0) & (x <= c.track_length)).astype(float)
                x = np.clip(x, 0.0, c.track_length)
            starts = np.array([e.start for e in c.elements])
            idx = np.clip(np.searchsorted(starts, x + 1e-12, side="right") - 1, 0, len(c.elements) - 1)
            for e_idx in np.unique(idx):
                el = c.elements[e_idx]
                sel = np.nonzero(idx == e_idx)[0]
                xi = np.clip((x[sel] - el.start) / el.length, 0.0, 1.0)
                sec = el.beam.section
                Te = self.Tm[el.cols]  # (6, n_i)
                for order in range(3):
                    P = beam_point_matrix(
                        el.xy_i,
                        el.xy_j,
                        xi,
                        c.offset,
                        E=sec.E,
                        G=sec.G,
                        A=sec.A,
                        I=sec.I,
                        kappa=sec.kappa,
                        order=order,
                    )
                    fac = (c.rate * v[sel]) ** order * (inside[sel] if order else 1.0)
                    R[order, sel, 3 * ci : 3 * ci + 3] = (P @ Te) * fac[:, None, None]
        # order the rows like self.dv
        own = np.concatenate([c.cols_self for c in self.sy._contacts])
        perm = np.array([int(np.nonzero(own == k)[0][0]) for k in self.dv], dtype=int)
        return R[0][:, perm], R[1][:, perm], R[2][:, perm]

    def reduce(self, s: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, ...]:
        R0, R1, R2 = self.rows(s, v)
        m = s.size
        R0t = np.transpose(R0, (0, 2, 1))
        out = []
        for X0, Xv, Xvv in zip(self.X0, self.Xv, self.Xvv, strict=True):
            if not np.any(Xv) and not np.any(Xvv):
                out.append(np.broadcast_to(X0, (m,) + X0.shape).copy())
                continue
            # one GEMM for the constant-times-stack product: (n, k) @ (k, m*n)
            XvR = np.transpose(np.tensordot(Xv, R0, axes=([1], [1])), (1, 0, 2))
            Y = XvR + np.transpose(XvR, (0, 2, 1))
            if np.any(Xvv):
                Y += R0t @ np.transpose(np.tensordot(Xvv, R0, axes=([1], [1])), (1, 0, 2))
            Y += X0
            out.append(Y)
        A, B, C = out
        if np.any(R1):
            Mv, Mvv = self.Xv[0], self.Xvv[0]
            Lv, Lvv = self.Xv[1], self.Xvv[1]
            if np.any(Mv) or np.any(Mvv):
                Mfac = Mv + R0t @ Mvv
                B = B + 2 * Mfac @ R1
                C = C + Mfac @ R2
            if np.any(Lv) or np.any(Lvv):
                C = C + (Lv + R0t @ Lvv) @ R1
        return A, B, C, R0, R1


class ParametricProblem:
    """The time-varying problem of Eq. (2.28) for :func:`chatterlab.newmark.newmark`.

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
    """

    def __init__(
        self,
        system: System,
        kinematics: ShapingKinematics | SteadyKinematics,
        *,
        width: float,
        terms: str = "pdo",
        forces: bool = True,
    ) -> None:
        if terms not in FEEDBACK_CASES:
            raise InputError(f"feedback must be one of {', '.join(FEEDBACK_CASES)} (got {terms!r})")
        if not (np.isfinite(width) and width > 0):
            raise InputError(f"width must be > 0 m (got {width!r})")
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
        self.fast = (
            _FastReduction(system) if (system.model.movable is not None and system._contacts) else None
        )
        if self.fast is not None and not self.fast.ok:
            self.fast = None
        if self.fast is not None:
            self.Jv = J[:, self.fast.dv]
            self.Ji_const = J @ self.fast.Tm  # (3k, n_i) with the contact columns' constant part

    # -- TimeVaryingProblem -------------------------------------------------
    def delay(self) -> float | None:
        return self._T

    def breakpoints(self) -> tuple[float, ...]:
        """Times where the tool enters or leaves the cut or the slide reverses
        (the coefficients and forces jump there), over the first 10^4 cycles."""
        return self.kin.breakpoints(self._t_end) if isinstance(self.kin, ShapingKinematics) else ()

    def _geometry(self, t: np.ndarray) -> tuple[np.ndarray, ...]:
        s, v, cut, _ = self.kin.state(t)
        sy = self.system
        if sy.model.movable is None or not np.all(np.isfinite(s)):
            W0 = np.broadcast_to(sy.W(None), (t.size,) + (len(sy.d), len(sy.i)))
            Z = np.zeros_like(W0)
            return W0, Z, Z, np.zeros(t.size), cut
        W0, W1, W2 = sy._W_all(s)
        return W0, W1 * v[:, None, None], W2 * (v**2)[:, None, None], v, cut

    def _ce(self, t: np.ndarray) -> tuple[np.ndarray, ...]:
        """A, B, C, J_i, J_dot and the in-cut mask at times t."""
        if self.fast is not None:
            s, v, cut, _ = self.kin.state(t)
            if np.all(np.isfinite(s)):
                A, B, C, R0, R1 = self.fast.reduce(s, v)
                return A, B, C, self.Ji_const + self.Jv @ R0, self.Jv @ R1, cut
        W0, Wd, Wdd, _, cut = self._geometry(t)
        A, B, C = _reduce(self.system, W0, Wd, Wdd)
        return A, B, C, self.Ji0 + self.Jd @ W0, self.Jd @ Wd, cut

    def ce_map(self, t: np.ndarray) -> np.ndarray:
        """J_i(t): q_i -> CE relative displacements (m, 3k, n_i)."""
        return self._ce(np.atleast_1d(np.asarray(t, float)))[3]

    def matrices(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        A, B, C, Ji, Jdot, cut = self._ce(t)
        c = cut.astype(float)[:, None, None]
        JiT = np.transpose(Ji, (0, 2, 1))
        if np.any(self.V):
            B = B + c * (JiT @ self.V @ Ji)
            C = C + c * (JiT @ self.V @ Jdot)
        if np.any(self.P):
            C = C + c * (JiT @ self.P @ Ji)
        G = -c * (JiT @ self.O @ Ji) if self._T is not None else None
        return A, B, C, G

    def force(self, t: np.ndarray) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if not np.any(self.F):
            return np.zeros((t.size, self.n))
        _, _, _, Ji, _, cut = self._ce(t)
        return cut.astype(float)[:, None] * np.einsum("mkn,k->mn", Ji, self.F)


def _reduce(
    sy: System, W0: np.ndarray, Wd: np.ndarray, Wdd: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A*, B*, C* of Eq. (2.16)-(2.18) from W, dW/dt, d2W/dt2 (batched)."""
    i, d = sy.i, sy.d
    out = []
    Wt = np.transpose(W0, (0, 2, 1))
    for X in (sy.M, sy.L, sy.K):
        Xii, Xid, Xdi, Xdd = X[np.ix_(i, i)], X[np.ix_(i, d)], X[np.ix_(d, i)], X[np.ix_(d, d)]
        out.append(Xii + Xid @ W0 + Wt @ Xdi + Wt @ Xdd @ W0)
    A, B, C = out
    if len(d) and np.any(Wd):
        Mid, Mdd = sy.M[np.ix_(i, d)], sy.M[np.ix_(d, d)]
        Lid, Ldd = sy.L[np.ix_(i, d)], sy.L[np.ix_(d, d)]
        B = B + 2 * (Mid + Wt @ Mdd) @ Wd
        C = C + (Lid + Wt @ Ldd) @ Wd + (Mid + Wt @ Mdd) @ Wdd
    return A, B, C


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
        from .signals import amplitude_spectrum

        m = self.window(window)
        return amplitude_spectrum(self.t[m], self._get(name)[m], window=taper)

    def growth(self, name: str, *, window: str | tuple[float, float] = "all", skip: float = 0.0) -> Any:
        """Exponential growth rate of the envelope of one output (1/s) with a
        decaying / steady / growing classification."""
        from .signals import growth_rate

        m = self.window(window) & (self.t >= self.t[0] + skip)
        return growth_rate(self.t[m], self._get(name)[m])

    def _get(self, name: str) -> np.ndarray:
        if name not in self.data:
            raise InputError(f"no output '{name}' (recorded: {', '.join(self.data)})")
        return self.data[name]

    def to_csv(self, path: Any) -> None:
        """Time histories: t [s], s [m], in_cut, cut distance [m], outputs."""
        import csv

        from ._io import text_out

        names = list(self.data)
        with text_out(path) as fh:
            w = csv.writer(fh)
            w.writerow(
                ["t [s]", "position [m]", "in_cut [-]", "cut_distance [m]"]
                + [f"{n} [{self.units.get(n, 'm')}]" for n in names]
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
                )

    def to_netcdf(self, path: str, attrs: dict[str, Any] | None = None) -> None:
        """netCDF with time as the coordinate (s) and every output as data."""
        from .netcdf import write_netcdf

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
        from .plot import plot_histories

        return plot_histories([self], names or list(self.data)[:2], against=against, axes=axes)


def _var(name: str) -> str:
    import re

    v = re.sub(r"[^0-9A-Za-z_]", "_", name)
    return v if not v[:1].isdigit() else f"v_{v}"


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
        natural frequency below 300 Hz, and at most T/20.
    outputs : list of str, optional
        ``"POINT.DIR"`` time histories to record (default: the first CE's
        points ``b`` along x and y — the paper's q1, q2 at RFE 5).
    forces : bool
        Apply the desired cutting forces while in the cut.

    Returns
    -------
    Simulation
    """
    mdl = system.model
    if not mdl.couplings:
        raise InputError(f"{mdl.source} has no [[coupling]]: a simulation of the cut needs one")
    if width is None:
        width = mdl.couplings[0].width_ref
    if not (isinstance(passes, int | np.integer) and passes >= 1):
        raise InputError(f"passes must be an integer >= 1 (got {passes!r})")
    kin = kinematics_for(mdl.process, speed=speed, delay=delay, position=position)
    T = float(kin.delay)
    if duration is None:
        duration = passes * T
    if not (np.isfinite(duration) and duration > 0):
        raise InputError(f"duration must be > 0 s (got {duration!r})")
    if step is None:
        from .modal import modes

        f = modes(system.at(position if isinstance(kin, SteadyKinematics) else None)).frequency_hz
        fmax = float(f[f < 300.0].max()) if np.any(f < 300.0) else float(f.min())
        step = min(1.0 / (20.0 * fmax), T / 20.0)
        # a whole number of steps between the process events (cut entry and
        # exit, reversal, one cycle) keeps them and the delayed samples on the grid
        unit = kin.grid_unit if isinstance(kin, ShapingKinematics) else T
        step = unit / math.ceil(unit / step)
    if not (np.isfinite(step) and step > 0):
        raise InputError(f"step must be > 0 s (got {step!r})")
    if feedback == "pdo" and step > T:
        raise InputError(
            f"step {step:g} s is larger than the delay T = {T:g} s: the delayed term needs h <= T; use a smaller --step"
        )
    prob = ParametricProblem(system, kin, width=float(width), terms=feedback, forces=forces)
    prob._t_end = float(duration)
    if isinstance(kin, SteadyKinematics):
        A, B, C, G = prob.matrices(np.array([0.0]))
        f0 = prob.force(np.array([0.0]))[0]
        run_prob: Any = ConstantProblem(
            A[0],
            B[0],
            C[0],
            force=(lambda t, f0=f0: np.broadcast_to(f0, (np.size(t), f0.size))),
            G=None if G is None else G[0],
            delay=prob.delay(),
        )
    else:
        run_prob = prob
    outs = list(outputs) if outputs is not None else _default_outputs(mdl)
    res = newmark(
        run_prob,
        (0.0, float(duration)),
        float(step),
        q0,
        options=options,
        record_every=record_every,
        progress=progress,
    )
    t = res.t
    s, v, cut, cd = kin.state(t)
    q = res.q  # (n_i, n_t)
    data: dict[str, np.ndarray] = {}
    units: dict[str, str] = {}
    W0 = prob._geometry(t)[0] if t.size else np.zeros((0, len(system.d), len(system.i)))
    for name in outs:
        row = _output_map(system, name)  # (n_all,)
        ri = (
            row[system.i][None, :] + np.einsum("k,mkn->mn", row[system.d], W0)
            if len(system.d)
            else row[system.i][None, :]
        )
        data[name] = np.einsum("mn,nm->m", np.broadcast_to(ri, (t.size, ri.shape[-1])), q)
        units[name] = "rad" if name.endswith(".rz") else "m"
    Ji = prob.Ji0 + prob.Jd @ W0 if len(system.d) else np.broadcast_to(prob.Ji0, (t.size,) + prob.Ji0.shape)
    dw = np.einsum("mkn,nm->km", Ji, q)
    for k, c in enumerate(mdl.couplings):
        for j in (0, 1):
            data[f"{c.id}.{j + 1}"] = dw[3 * k + j]
            units[f"{c.id}.{j + 1}"] = "m"
    return Simulation(
        t=t,
        data=data,
        position=s,
        in_cut=cut,
        cut_distance=cd,
        response=res,
        terms=feedback,
        width=float(width),
        delay=T,
        step=float(step),
        passes=int(passes),
        units=units,
        model=mdl.source,
        meta={"kinematics": type(kin).__name__},
    )


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
