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
from typing import Any, ClassVar, Literal

import numpy as np

from ..errors import InputError, check_positive, check_width, warn_width
from ..process._kinematics import ShapingKinematics, SteadyKinematics, kinematics_for
from ..structure._assembly import System
from ._history import TimeHistory
from ._initial import initial_state
from ._newmark import ConstantProblem, NewmarkOptions, TimeResponse, newmark
from ._parametric import FEEDBACK_CASES, ParametricProblem, _ExtraForce, _output_map, _WithExtraForce

__all__ = ["ParametricProblem", "Simulation", "simulate", "FEEDBACK_CASES"]


@dataclass(frozen=True, eq=False)
class Simulation(TimeHistory):
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
    response : TimeResponse
        The integrator's result (``q``, ``v``, ``a`` of the independent
        coordinates) the histories were computed from.

    Its histories (:class:`~chatterlab.time._history.TimeHistory`: spectrum,
    growth, CSV, netCDF, plot) are ``position``, ``in_cut``,
    ``cut_distance`` and those of ``data``; :meth:`window` adds the windows
    ``"cut"`` and ``"last-cut"`` (the default of :meth:`spectrum`).
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

    spectrum_window: ClassVar[Any] = "last-cut"

    @property
    def status(self) -> str:
        return self.response.status

    @property
    def message(self) -> str:
        return self.response.message

    def histories(self) -> dict[str, tuple[np.ndarray, str, str]]:
        """The process state (``position`` m, ``in_cut`` flag, ``cut_distance``
        m), then the outputs and CE displacements of ``data``."""
        out: dict[str, tuple[np.ndarray, str, str]] = {
            "position": (self.position, "m", "slide position s"),
            "in_cut": (np.asarray(self.in_cut, dtype=bool), "1", "tool in the cut"),
            "cut_distance": (self.cut_distance, "m", "distance travelled in the cut"),
        }
        out.update((n, (arr, self.units.get(n, "m"), n)) for n, arr in self.data.items())
        return out

    def window(self, which: str | tuple[float, float] = "last-cut") -> np.ndarray:
        """Boolean mask of a time window: ``"last-cut"`` (the last pass in the
        cut), ``"cut"`` (every pass in the cut), ``"all"``, or (t0, t1)."""
        if which == "cut":
            return np.asarray(self.in_cut, dtype=bool).copy()
        if which == "last-cut":
            m = np.asarray(self.in_cut, dtype=bool)
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
        if isinstance(which, tuple) or which == "all":
            return super().window(which)
        raise InputError(f"window must be 'last-cut', 'cut', 'all' or (t0, t1), got {which!r}")

    def file_attrs(self) -> dict[str, Any]:
        a: dict[str, Any] = {
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
        return a

    def plot(  # type: ignore[override]
        self,
        names: list[str] | None = None,
        *,
        against: Literal["time", "distance"] = "time",
        ax: Any = None,
        axes: Any = None,
    ) -> Any:
        """Time histories (or against the cut distance) of outputs, one panel
        each, the in-cut intervals shaded (``axes=`` is a deprecated alias of
        ``ax=``); returns the Axes.  One run with its force and spectrum:
        :func:`chatterlab.plot.plot_time_response`."""
        from ..plot import plot_histories

        return plot_histories([self], names or list(self.data)[:2], against=against, ax=ax, axes=axes)


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
    outputs: str | list[str] | tuple[str, ...] | None = None,
    forces: bool = True,
    options: NewmarkOptions | None = None,
    q0: Any = None,
    v0: Any = None,
    history: Any = None,
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
    outputs : str or list of str, optional
        ``"POINT.DIR"`` time histories to record (default: the first CE's
        points ``b`` along x and y — the paper's q1, q2 at RFE 5; when ``b``
        is the ground, the body or node of its point ``a``).  In the netCDF file a
        name becomes a valid variable name (``"rfe5.x"`` -> ``rfe5_x``; the
        name itself is its ``long_name``).
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
    q0, v0 : array (n_i,) or mapping, optional
        Initial displacement (m, rad) and velocity (m/s, rad/s) at t = 0;
        zero by default.  Either a vector over the independent coordinates,
        or ``{"POINT.DIR": value}`` (or a coordinate name): the named
        displacements are met by the static shape under forces at those
        points (the state minimising q^T C q, C the stiffness of the run at
        t = 0), the named velocities by the state right after impulses at
        those points (minimising v^T A v, A the mass matrix).
    history : optional
        q_i(t) for t < 0, read by the delayed term (``feedback="pdo"``):
        ``None`` or ``"zero"`` (the default), ``"constant"`` (q0 held), a
        constant (n_i,) vector, a vectorised callable ``t -> (len(t), n_i)``
        (``(len(t),)`` for one coordinate) or a table ``(t_k, q_k)`` with
        ``q_k`` of shape (len(t_k), n_i), ``t_k`` increasing and covering
        [-T, 0]: a not-a-knot cubic spline through 4 or more nodes (error
        O(dt^4) for a smooth history, dt the largest node spacing), linear
        through 2 or 3 (O(dt^2)).  Only values are read, no derivative.
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
        the memory limits of ``options``; a stroke outside the movable range;
        a q0, v0 or history of the wrong shape, not finite, naming an unknown
        output, or a table not increasing or not covering [-T, 0]).
    """
    mdl = system.model
    width, duration, step, kin = _check_run(
        system, feedback, width, passes, duration, step, speed, delay, position
    )
    T = float(kin.delay)
    if duration is None:
        duration = passes * T
    if isinstance(outputs, str):  # one point, as frf(inputs="rfe5.x") takes it
        outputs = [outputs]
    outs = list(outputs) if outputs is not None else _default_outputs(mdl)
    out_rows = [_output_map(system, name) for name in outs]  # refuse unknown outputs before the run
    step = _time_step(system, kin, feedback, step, position, duration)
    prob = ParametricProblem(system, kin, width=float(width), terms=feedback, forces=forces, method=method)
    prob._t_end = float(duration)
    run_prob = _run_problem(prob, loads, ground_motion)
    q0v, v0v, hist, initial = initial_state(prob, kin, q0, v0, history)
    with _blas_limits():
        res = newmark(
            run_prob,
            (0.0, float(duration)),
            step,
            q0v,
            v0v,
            history=hist,
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
        meta={
            "kinematics": type(kin).__name__,
            "coefficients": "+".join(sorted(prob.method_used)),
            "initial_condition": initial,
        },
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
    warn_width(width, [c.width_ref for c in mdl.couplings])
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
    of a few tens); the integrator's own worker threads use the second core
    (:func:`chatterlab._threads.one_blas_thread`)."""
    from .._threads import one_blas_thread

    return one_blas_thread()


def _default_outputs(mdl: Any) -> list[str]:
    c = mdl.couplings[0]
    tgt = (
        c.b.target if c.b.kind in ("body", "node") else (c.a.target if c.a.kind in ("body", "node") else None)
    )
    if tgt is None:
        return []
    return [f"{tgt}.x", f"{tgt}.y"]
