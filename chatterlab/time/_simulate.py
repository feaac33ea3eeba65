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
so this is exact.  The integrator is :func:`chatterlab.time._newmark.newmark`
for the moving slide; a continuous cut (constant coefficients) runs by
default with the exponential step map :func:`chatterlab.time.exponential`,
its step chosen for an error target (``Integration.integrator``).

References
----------
.. [1] E. Wittbrodt, K. J. Kaliński, seed paper, Eqs. (2.15)-(2.28), (3.5)-(3.12).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar, Literal

import numpy as np

from ..errors import InputError, check_width, warn_width
from ..process._kinematics import ShapingKinematics, SteadyKinematics, kinematics_for
from ..structure._assembly import System
from ._history import TimeHistory
from ._indentation import MIN_LAND_STEPS, Flank, FlankRun, flank_run
from ._initial import initial_state
from ._newmark import ConstantProblem, TimeResponse, newmark
from ._options import Excitation, Initial, Integration, with_legacy
from ._parametric import FEEDBACK_CASES, ParametricProblem, _ExtraForce, _output_map, _WithExtraForce
from ._problems import Sealed
from ._signals import GrowthEstimate, TimeVerdict, amplitude_spectrum, peaks, time_verdict

__all__ = ["ParametricProblem", "Simulation", "simulate", "constant_loop", "FEEDBACK_CASES"]

#: steps per period of every relevant characteristic root, at least: the
#: period error (w h)^2 / 12 of average acceleration is then below 0.83 %
MIN_STEPS_PER_PERIOD = 20
#: the growth-rate error the default step aims at, as a fraction of what the
#: verdict must resolve: max(|rightmost Re|, log(1 + tol) / fitted span)
STEP_ERROR_FRACTION = 0.25
#: roots whose envelope, relative to the rightmost one's, falls by less than
#: this factor over the fitted span can still shape the fitted envelope
RELEVANT_DECAY = 100.0
#: the default step puts at least this many samples of the surface across the
#: indentation model's wear land (the flank's area; the check run at twice the
#: step keeps MIN_LAND_STEPS = 2 of them, eight moved the decay rate by < 1e-3
#: relative on the 1-DOF tool of tests/test_indentation.py)
LAND_STEPS = 8.0
#: the default step costs at most this many steps (the verdict then says
#: which step would decide it)
MAX_DEFAULT_STEPS = 2_000_000


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
    passes: float
    units: dict[str, str]
    model: str
    meta: dict[str, Any] = field(default_factory=dict)
    roots: np.ndarray | None = None
    roots_certain: bool = False
    _rerun: Any = field(default=None, repr=False, compare=False)
    _cache: dict[Any, Any] = field(default_factory=dict, repr=False, compare=False)

    spectrum_window: ClassVar[Any] = "last-cut"

    def verdict_skip(self) -> float:
        """Seconds dropped before a verdict's fit: one delay, at most 20 % of
        the run (:func:`growth_rate` then drops 20 % of the rest)."""
        return float(min(self.delay, 0.2 * float(self.t[-1]))) if self.t.size else 0.0

    def check_step(self) -> float:
        """The step of the verdict's check run: twice the run's step, or
        half of it when twice would exceed the delay (or a fifth of the run);
        half of it for the exponential step map."""
        h, T = float(self.step), float(self.delay)
        t_end = float(self.t[-1]) if self.t.size else 0.0
        if self.response.attrs.get("method") == "exponential":  # the check run is finer (a whole m per delay)
            return 0.5 * h
        if 2.0 * h > float(self.response.attrs.get("max_step", math.inf)):  # the wear land's samples
            return 0.5 * h
        return (
            2.0 * h
            if (self.terms != "pdo" or 2.0 * h <= T * (1 + 1e-12)) and 2 * h <= 0.2 * t_end
            else 0.5 * h
        )

    def _order(self) -> int:
        """The order of the run's scheme: 2 (Newmark) or the exponential step map's."""
        return (
            int(self.response.attrs.get("order", 2))
            if self.response.attrs.get("method") in ("exponential", "indentation")
            else 2
        )

    def verdict(self, name: str, *, tol: float = 0.05) -> TimeVerdict:
        """The time-domain verdict of one history of a continuous cut, with
        the integrator's own error.

        The envelope growth rate is fitted after :meth:`verdict_skip` (as
        :meth:`growth`); the same cut is run again at :meth:`check_step`
        (once, shared by every history) and Richardson's estimate for the
        scheme's order (2 for Newmark, ``p + 1`` for the exponential step
        map) gives the step error of the rate.  A class is
        claimed only when the rate +- (2 fit standard errors + step error)
        lies in it (:func:`chatterlab.time.time_verdict`).  The roots given
        to :func:`simulate` are compared with it (``contradiction``).

        Raises
        ------
        InputError
            A moving slide (no single growth rate), an unknown history, or
            a run too short for a fit.
        """
        if self._rerun is None or not np.asarray(self.in_cut, dtype=bool).all():
            raise InputError(
                "a time-domain verdict needs a continuous cut (simulate(..., delay=T) or position=s, or a"
                " turning process): a moving slide has no single growth rate"
            )
        key = ("verdict", name, float(tol))
        if key in self._cache:
            cached: TimeVerdict = self._cache[key]
            return cached
        h2 = self.check_step()
        delay = float(self.delay) if self.terms == "pdo" else 0.0
        if self.status == "diverged":
            none = GrowthEstimate(math.nan, "undetermined", math.nan, "the run diverged")
            v = time_verdict(
                name, none, None, self.step, h2, tol=tol, roots=self.roots, roots_certain=self.roots_certain,
                diverged=True, delay=delay, order=self._order(),
            )  # fmt: skip
        else:
            skip = self.verdict_skip()
            main = self.growth(name, window="all", skip=skip, tol=tol)
            check = None
            if math.isfinite(main.rate):
                chk = self._check_run(h2)
                if chk.status == "ok":
                    check = chk.growth(name, window="all", skip=skip, tol=tol)
            v = time_verdict(
                name, main, check, self.step, h2, frequency=self._main_frequency(name, main), tol=tol,
                roots=self.roots, roots_certain=self.roots_certain, delay=delay, order=self._order(),
            )  # fmt: skip
        v = self._finite_amplitude(v)
        self._cache[key] = v
        return v

    def _finite_amplitude(self, v: TimeVerdict) -> TimeVerdict:
        """A decay of the indentation model's nonlinear run is claimed only
        where the linearisation is the law and says so: the run must end in
        the near-linear regime (the flank's contact in its last quarter within
        the wear land and a tenth of it, beyond the sampling: the clearance
        face touching further is the finite amplitude where the damping grows
        with the amplitude, Eq. 5) and the linearisation's rightmost root must
        decay (given as ``roots``; a decay towards a limit cycle, the
        finite-amplitude stability of a linearly unstable cut, is not
        stability)."""
        a = self.response.attrs
        if a.get("method") != "indentation" or v.classification != "decaying":
            return v
        w = float(a["wear_land"])
        contact = np.asarray(a["flank_contact"])
        tail = contact[int(0.75 * contact.size) :]
        if tail.size and float(tail.max()) > 1.1 * w + float(a["speed"]) * self.step:
            why = (
                f"the flank's contact ({float(tail.max()) * 1e6:.3g} um) still reaches beyond the wear land"
                f" ({w * 1e6:.3g} um) in the last quarter of the run: a finite-amplitude decay; run longer"
            )
        elif self.roots is None or not self.roots.size:
            why = (
                "a decay of the nonlinear run is claimed against the linearisation's roots: give roots="
                " (chatterlab simulate computes them)"
            )
        elif float(self.roots.real.max()) >= 0.0:
            why = (
                f"the linearisation's rightmost root grows ({float(self.roots.real.max()):+.4g} 1/s): the decay"
                " may end on a limit cycle (finite-amplitude stability); run longer or from a smaller disturbance"
            )
        else:
            return v
        head = f"{v.name}: decaying; "
        text = v.message[len(head) :] if v.message.startswith(head) else v.message
        return replace(
            v,
            classification="undetermined",
            message=f"{v.name}: undetermined ({why}); the fit decays: {text}",
        )

    def _check_run(self, h2: float) -> Simulation:
        run = self._cache.get(("check", h2))
        if run is None:
            run = self._rerun(h2)
            self._cache[("check", h2)] = run
        out: Simulation = run
        return out

    def _main_frequency(self, name: str, g: GrowthEstimate) -> float:
        """The main spectral peak (Hz) of a history over the fitted window."""
        t0, t1 = g.t_fit
        m = (self.t >= t0) & (self.t <= t1)
        if np.count_nonzero(m) < 8 or not t1 > t0:
            return math.nan
        f, a = amplitude_spectrum(self.t[m], self.history(name)[m])
        fp, _ = peaks(f, a, 1, fmin=2.0 / (t1 - t0))
        return float(fp[0]) if fp.size else math.nan

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
            "title": "chatterlab transient simulation (Eq. 2.28, "
            + ("exponential step map" if self.response.attrs.get("method") == "exponential" else "Newmark")
            + ")",
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

    def plot(
        self,
        names: Sequence[str] | str | None = None,
        *,
        ax: Any = None,
        against: Literal["time", "distance"] = "time",
        **style: Any,
    ) -> Any:
        """Time histories (or against the cut distance) of outputs (default
        the first two), one panel each, the in-cut intervals shaded
        (:func:`chatterlab.plot.plot_histories`; ``style``: its ``labels``,
        ``scale``, ``unit``, ``title``, and ``axes=``, the deprecated alias of
        ``ax=``); returns the Axes.  One run with its force and spectrum:
        :func:`chatterlab.plot.plot_time_response`."""
        from ..plot import plot_histories

        chosen = (
            list(self.data)[:2] if names is None else ([names] if isinstance(names, str) else list(names))
        )
        return plot_histories([self], chosen, against=against, ax=ax, **style)


def simulate(
    system: System,
    *,
    feedback: Literal["none", "pd", "pdo"] = "pdo",
    width: float | None = None,
    speed: float | None = None,
    delay: float | None = None,
    position: float | None = None,
    outputs: str | list[str] | tuple[str, ...] | None = None,
    roots: Any = None,
    integration: Integration | None = None,
    initial: Initial | None = None,
    excitation: Excitation | None = None,
    **deprecated: Any,
) -> Simulation:
    """Simulation of the moving, delayed closed loop (Eq. 2.28): Newmark for
    the moving slide, the exponential step map for a continuous cut (the
    default ``Integration(integrator="auto")``).

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
    outputs : str or list of str, optional
        ``"POINT.DIR"`` time histories to record (default: the first CE's
        points ``b`` along x and y — the paper's q1, q2 at RFE 5; when ``b``
        is the ground, the body or node of its point ``a``).  In the netCDF file a
        name becomes a valid variable name (``"rfe5.x"`` -> ``rfe5_x``; the
        name itself is its ``long_name``).
    roots : RootsResult or array of complex, optional
        The characteristic roots (1/s) of the same frozen system, e.g.
        ``chatterlab.frequency.characteristic_roots`` on
        :func:`constant_loop`'s matrices: they set the default step of a
        continuous cut and are compared with :meth:`Simulation.verdict`.  A
        ``RootsResult`` that converged with a band proven to hold every root
        right of its rightmost one is *certain* (a contradiction can then be
        named); a bare array is shown only.
    integration : Integration, optional
        ``duration`` (s) or ``periods`` (stroke cycles, or delays of a
        continuous cut; default 2); ``step`` h (s; default: a twentieth of
        the period of the highest natural frequency below 300 Hz, and at most
        T/20; for a continuous cut with ``roots`` given, also fine enough
        for the chatter band: every relevant root (one whose envelope can
        still shape the fitted window) resolved with at least 20 steps per
        period and its growth rate within a quarter of what the verdict must
        resolve (:func:`chatter_step`), within 2 000 000 steps; rounded down
        so that the process events (cut entry and exit, reversal, one cycle)
        fall on the step grid); ``record_every``; ``method`` of the
        coefficients (:class:`ParametricProblem`; the results agree to
        rounding); ``scheme`` (:class:`NewmarkOptions`: gamma, beta,
        memory limits); ``progress(fraction)`` after each chunk of steps.
    initial : Initial, optional
        ``q0``, ``v0``: the displacement (m, rad) and velocity (m/s, rad/s)
        at t = 0, zero by default; either a vector over the independent
        coordinates, or ``{"POINT.DIR": value}`` (or a coordinate name): the
        named displacements are met by the static shape under forces at
        those points (the state minimising q^T C q, C the stiffness of the
        run at t = 0), the named velocities by the state right after
        impulses at those points (minimising v^T A v, A the mass matrix).
        ``history``: q_i(t) for t < 0, read by the delayed term
        (``feedback="pdo"``): ``None`` or ``"zero"`` (the default),
        ``"constant"`` (q0 held), a constant (n_i,) vector, a vectorised
        callable ``t -> (len(t), n_i)`` (``(len(t),)`` for one coordinate)
        or a table ``(t_k, q_k)`` with ``q_k`` of shape (len(t_k), n_i),
        ``t_k`` increasing and covering [-T, 0]: a not-a-knot cubic spline
        through 4 or more nodes (error O(dt^4) for a smooth history, dt the
        largest node spacing), linear through 2 or 3 (O(dt^2)).  Only values
        are read, no derivative.
    excitation : Excitation, optional
        ``cutting_forces``: apply the desired cutting forces while in the
        cut (default True).  ``loads``: external forces ``"POINT.DIR" ->
        f(t)`` (or a coordinate name), f a vectorised callable returning the
        force (N, or N m for ``rz``) at the times ``t`` (s), in global axes;
        a load on a moving contact travels with it.  ``ground_motion``:
        prescribed motion of given coordinates (Eq. 2.19), ``"ground.y" ->
        g(t)`` with g returning ``(q, q_dot, q_ddot)`` arrays at the times t
        (m, m/s, m/s^2 or rad...); it loads the structure through the
        stiffness, damping and mass couplings, and through the coupling
        elements' terms on given coordinates (Eq. 2.27) while cutting.
    **deprecated
        The 0.2 keywords ``passes``, ``duration``, ``step``, ``options``,
        ``record_every``, ``method``, ``progress`` (-> ``integration``),
        ``q0``, ``v0``, ``history`` (-> ``initial``), ``forces``, ``loads``,
        ``ground_motion`` (-> ``excitation``), accepted for one release with
        a DeprecationWarning.

    Returns
    -------
    Simulation
        ``meta["process_damping"]`` says which process-damping model ran.

    Notes
    -----
    The model's ``[process_damping]`` (with ``feedback`` ``"pd"`` or
    ``"pdo"``, as :func:`chatterlab.process.closed_loop`): ``C_pd`` adds
    ``b C_pd / V n n^T`` on the coupling's relative velocity at the cutting
    speed V of the delay (a moving slide: while in the cut); the indentation
    model (``K_sp``, ``wear_land``, ``clearance_deg``) integrates the flank's
    force on the displaced area (:func:`chatterlab.time._indentation.flank_run`)
    on a continuous cut, with Newmark, a step of at most w / (8 V) by
    default, and ``roots`` taken as the linearisation's (not certain).  See
    docs/process-damping.md.

    Raises
    ------
    InputError
        Bad arguments (non-positive width, duration or step; a step longer
        than the delay; the indentation model on a moving slide, with the
        exponential integrator, a history table, or a step the wear land
        holds fewer than two of; an unknown output; a delay history or a record above
        the memory limits of ``integration.scheme``; a stroke outside the
        movable range; a q0, v0 or history of the wrong shape, not finite,
        naming an unknown output, or a table not increasing or not covering
        [-T, 0]).
    """
    opt = with_legacy(
        "simulate",
        deprecated,
        LEGACY_SIMULATE,
        integration=integration,
        initial=initial,
        excitation=excitation,
    )
    cut = _Cut(system, feedback, width, speed, delay, position, outputs)
    return _simulate(cut, roots, opt["integration"], opt["initial"], opt["excitation"])


#: the 0.2 keywords :func:`simulate` still takes (see :data:`._options.LEGACY_KEYWORDS`)
LEGACY_SIMULATE = (
    "passes", "duration", "step", "options", "record_every", "method", "progress", "q0", "v0", "history",
    "forces", "loads", "ground_motion",
)  # fmt: skip


@dataclass(frozen=True)
class _Cut:
    """The cut :func:`simulate` runs: the system, the feedback case, the
    width and the kinematics' arguments, the outputs' names."""

    system: System
    feedback: Literal["none", "pd", "pdo"]
    width: float | None
    speed: float | None
    delay: float | None
    position: float | None
    outputs: str | list[str] | tuple[str, ...] | None


def _simulate(cut: _Cut, roots: Any, integ: Integration, init: Initial, exc: Excitation) -> Simulation:
    """:func:`simulate` with its options gathered."""
    system, feedback = cut.system, cut.feedback
    mdl = system.model
    periods = integ.periods if integ.periods is not None else 2
    width, kin = _check_run(system, feedback, cut.width, periods, cut.speed, cut.delay, cut.position)
    T = float(kin.delay)
    duration = integ.duration if integ.duration is not None else periods * T
    outputs = [cut.outputs] if isinstance(cut.outputs, str) else cut.outputs  # one point, as frf takes it
    outs = list(outputs) if outputs is not None else _default_outputs(mdl)
    out_rows = [_output_map(system, name) for name in outs]  # refuse unknown outputs before the run
    prob = ParametricProblem(
        system,
        kin,
        width=width,
        terms=feedback,
        forces=exc.cutting_forces,
        method=integ.method,
        t_end=duration,
    )
    lam, certain = _roots_of(roots)
    pd = _process_damping(prob)
    flank = pd.flank if pd is not None else None
    if flank is not None:
        certain = False  # the roots are the linearisation's: a nonlinear run may differ at finite amplitude
        if integ.integrator == "exponential":
            raise InputError(
                "integrator='exponential' needs a linear cut; the indentation model's flank force is"
                " nonlinear and integrates with Newmark: drop integrator='exponential' (--integrator)"
            )
    run_prob = _run_problem(prob, exc.loads, exc.ground_motion, pd if flank is None else None)
    integ = _scheme_for(integ, kin, run_prob, linear=flank is None)
    q0v, v0v, hist, initial = initial_state(prob, kin, init.q0, init.v0, init.history)
    if integ.integrator == "exponential":
        res, step, rule = _exponential_run(
            prob, kin, run_prob, integ, feedback, duration, q0v, v0v, hist, outs
        )
    elif flank is not None:
        step, rule = _time_step(system, kin, feedback, integ.step, cut.position, duration, prob, lam, pd)
        with _blas_limits():
            res = _flank_response(run_prob, flank, step, duration, q0v, v0v, hist, integ)
    else:
        step, rule = _time_step(system, kin, feedback, integ.step, cut.position, duration, prob, lam, pd)
        with _blas_limits():
            res = newmark(
                run_prob,
                (0.0, float(duration)),
                step,
                q0v,
                v0v,
                history=hist,
                options=integ.scheme,
                record_every=integ.record_every,
                progress=integ.progress,
            )
    data, units = _histories(prob, res, outs, out_rows)
    s, _, in_cut, cd = kin.state(res.t)
    rerun = None
    if isinstance(kin, SteadyKinematics):
        # the verdict's check run: the same cut at another step, every step recorded
        check = replace(integ, duration=duration, step=None, record_every=1, progress=None)
        same = replace(cut, outputs=outs)

        def rerun(h2: float) -> Simulation:
            return _simulate(same, None, replace(check, step=h2), init, exc)

    return Simulation(
        t=res.t,
        data=data,
        position=s,
        in_cut=in_cut,
        cut_distance=cd,
        response=res,
        terms=feedback,
        width=float(width),
        delay=T,
        step=step,
        passes=periods,
        units=units,
        model=mdl.source,
        meta={
            "kinematics": type(kin).__name__,
            "coefficients": "+".join(sorted(prob.method_used)),
            "initial_condition": initial,
            "step_rule": rule,
            "process_damping": pd.describe() if pd is not None else "none",
        },
        roots=lam,
        roots_certain=certain,
        _rerun=rerun,
    )


def _scheme_for(
    integ: Integration, kin: ShapingKinematics | SteadyKinematics, problem: Any, *, linear: bool = True
) -> Integration:
    """``integ`` with its scheme decided: ``"auto"`` is the exponential step
    map for a linear continuous cut whose step is not given, when the problem
    has constant coefficients and a force without breakpoints (the step map
    interpolates the force across a step), and Newmark otherwise (the moving
    slide's coefficients change with the slide's position; the indentation
    model's flank force is nonlinear).  An error target ``rtol`` given to a
    Newmark run is refused (Newmark takes a step, not a tolerance)."""
    name = integ.integrator
    if name == "auto":
        bp = getattr(problem, "breakpoints", None)
        smooth = not (callable(bp) and len(tuple(bp())))
        constant = isinstance(kin, SteadyKinematics) and bool(getattr(problem, "time_invariant", False))
        name = "exponential" if linear and constant and smooth and integ.step is None else "newmark"
    if name == "newmark" and integ.rtol is not None:
        why = (
            "integrator='newmark'"
            if integ.integrator == "newmark"
            else "a moving slide"
            if not isinstance(kin, SteadyKinematics)
            else "a given step"
            if integ.step is not None
            else "the indentation model's nonlinear flank force"
            if not linear
            else "a force with breakpoints"
        )
        raise InputError(
            f"rtol is the exponential step map's error target; this run integrates with Newmark ({why}):"
            " drop rtol"
        )
    return replace(integ, integrator=name)


def _exponential_run(
    prob: ParametricProblem,
    kin: ShapingKinematics | SteadyKinematics,
    run_prob: Any,
    integ: Integration,
    feedback: str,
    duration: float,
    q0v: np.ndarray,
    v0v: np.ndarray,
    hist: Any,
    outs: list[str],
) -> tuple[TimeResponse, float, str]:
    """A continuous cut by :func:`exponential`: its step chosen for
    ``integ.rtol`` on the histories the run records (the CE relative
    displacements and the outputs), or ``integ.step``; ``(response, step, rule)``."""
    from ._exponential import DEFAULT_RTOL, exponential

    if not isinstance(kin, SteadyKinematics):
        raise InputError(
            "integrator='exponential' needs constant coefficients, a continuous cut (delay= or position=, or "
            "turning); the moving slide runs with integrator='newmark'"
        )
    rows = np.vstack([prob.J] + [_output_map(prob.system, name)[None, :] for name in outs])
    control = prob.maps(np.array([0.0]), rows)[0]
    with _blas_limits():
        res = exponential(
            run_prob,
            (0.0, float(duration)),
            q0v,
            v0v,
            rtol=float(integ.rtol if integ.rtol is not None else DEFAULT_RTOL),
            h=integ.step,
            record_every=integ.record_every,
            history=hist,
            control=control,
            divergence_limit=float(integ.scheme.divergence_limit),
        )
    a = res.attrs
    if integ.step is not None:
        rule = f"given, {a['steps_per_delay']} steps per delay (exponential step map, order {a['order']})"
    else:
        est = a["error_estimate"]
        said = (
            f"estimated error {est:.2g}"
            if est is not None and math.isfinite(est)
            else "no error estimate: the run diverged"
        )
        rule = (
            f"exponential step map of order {a['order']}: {a['steps_per_delay']} steps per delay for rtol = "
            f"{float(integ.rtol if integ.rtol is not None else DEFAULT_RTOL):g} ({said}, {a['tries']} {'try' if a['tries'] == 1 else 'tries'})"
        )
    if feedback != "pdo" and integ.step is None:
        rule = f"exponential step map, exact without a delayed term: {res.n_steps} steps record the run"
    return res, float(res.h), rule


def _check_run(
    system: System,
    feedback: str,
    width: float | None,
    periods: Any,
    speed: float | None,
    delay: float | None,
    position: float | None,
) -> tuple[float, ShapingKinematics | SteadyKinematics]:
    """The cut's arguments of :func:`simulate` checked: ``(width, kinematics)``."""
    mdl = system.model
    if feedback not in FEEDBACK_CASES:
        raise InputError(f"feedback must be one of {', '.join(FEEDBACK_CASES)} (got {feedback!r})")
    if not mdl.couplings:
        raise InputError(f"{mdl.source} has no [[coupling]]: a simulation of the cut needs one")
    if width is None:
        width = mdl.couplings[0].width_ref
    width = check_width(width)
    warn_width(width, [c.width_ref for c in mdl.couplings])
    if (
        isinstance(periods, bool)
        or not isinstance(periods, int | float | np.integer | np.floating)
        or not periods > 0
    ):
        raise InputError(f"passes (integration periods) must be a number > 0 (got {periods!r})")
    return width, _kinematics(system, speed, delay, position)


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
    prob: ParametricProblem,
    roots: np.ndarray | None,
    pd: _ProcessDamping | None = None,
) -> tuple[float, str]:
    """The step h, s, and how it was chosen: the given one, or a twentieth
    of the period of the highest natural frequency below 300 Hz and at most
    T/20 -- for a continuous cut with roots also :func:`chatter_step`, with
    the indentation model's flank also :data:`LAND_STEPS` steps across the
    wear land -- rounded down so that the process events fall on the step
    grid; checked against the delay and the duration."""
    T = float(kin.delay)
    rule = "given"
    if step is None:
        from ..structure._modal import modes

        f = modes(system.at(position if isinstance(kin, SteadyKinematics) else None)).frequency_hz
        fmax = float(f[f < 300.0].max()) if np.any(f < 300.0) else float(f.min())
        step = min(1.0 / (20.0 * fmax), T / 20.0)
        rule = f"1/20 of the period of {fmax:.6g} Hz (the highest mode below 300 Hz), at most T/20"
        if isinstance(kin, SteadyKinematics) and roots is not None and roots.size:
            A, B, C, G, _ = _constant_matrices(prob, pd)
            h_c, why = chatter_step(A, B, C, G, T, roots, fit_span(duration, T))
            if h_c < step:
                step, rule = h_c, why
            else:
                rule += f"; the chatter band needs no finer step ({why})"
        flank = pd.flank if pd is not None else None
        if flank is not None and flank.land_steps(step) < LAND_STEPS:
            step = flank.wear_land / (LAND_STEPS * flank.speed)
            rule += f"; {LAND_STEPS:g} steps across the wear land (the flank's area)"
            if duration / step > MAX_DEFAULT_STEPS:
                step = duration / MAX_DEFAULT_STEPS
                rule += (
                    f"; limited to {MAX_DEFAULT_STEPS} steps (h = {step:.4g} s): the verdict says the step"
                    " that would decide it"
                )
        # a whole number of steps between the process events (cut entry and
        # exit, reversal, one cycle) keeps them and the delayed samples on the grid
        unit = kin.grid_unit if isinstance(kin, ShapingKinematics) else T
        if unit < 0.25 * step:  # events on a grid much finer than needed: keep the cycle on it only
            unit = T
        step = unit / math.ceil(unit / step)
    step = float(step)
    if pd is not None and pd.flank is not None:
        pd.flank.check_step(step, "step")
    if feedback == "pdo" and step > T * (1 + 1e-12):
        raise InputError(
            f"step {step:g} s is larger than the delay T = {T:g} s: the delayed term needs h <= T; "
            "use a smaller step (--step)"
        )
    if step > duration * (1 + 1e-12):
        raise InputError(f"step {step:g} s is longer than the duration {duration:g} s")
    return step, rule


def fit_span(duration: float, delay: float) -> float:
    """The time a verdict's fit spans, s: the run after one delay (at most
    20 % of the run), less :func:`growth_rate`'s 20 % of the rest."""
    return 0.8 * (duration - min(delay, 0.2 * duration))


def growth_error_coefficient(
    A: np.ndarray, B: np.ndarray, C: np.ndarray, G: np.ndarray | None, T: float, lam: complex
) -> complex:
    """``c`` of Newmark's (average acceleration) root error ``c h^2`` at the
    characteristic root ``lam`` of ``det(lam^2 A + lam B + C - G e^{-lam T}) = 0``.

    The scheme is the trapezoidal rule: an undelayed term sees the discrete
    root ``l`` through ``s = (2/h) tanh(l h/2) = l - l^3 h^2/12 + O(h^4)``
    (no amplitude error for undamped free vibration, the period elongation
    ``(w h)^2/12``), while the delayed sample ``q(t - T)`` is exact on the
    grid, ``e^{-l T}``.  With ``u``, ``v`` the left and right null vectors of
    ``Delta(lam)``, first-order perturbation of ``Delta(l) - P'(l) l^3 h^2/12 = 0``
    gives ``l - lam = h^2 lam^3 (u* P' v) / (12 u* Delta' v)``, ``P' = 2 lam A
    + B``, ``Delta' = P' + T G e^{-lam T}``.  Without a delay ``Delta' = P'``
    and ``c = lam^3/12``: for ``lam = j w`` purely imaginary (the period
    error only).  With a delay the period error shifts the phase of the
    regeneration and so moves the growth rate: ``Re c``."""
    P = lam * lam * A + lam * B + C
    dP = 2.0 * lam * A + B
    dD = dP.astype(complex)
    if G is not None:
        e = np.exp(-lam * T)
        P = P - G * e
        dD = dD + T * G * e
    U, _, Vh = np.linalg.svd(P)
    u, v = U[:, -1], Vh[-1].conj()
    den = u.conj() @ dD @ v
    if den == 0:
        return complex(math.inf)
    return complex(lam**3 * (u.conj() @ dP @ v) / (12.0 * den))


def chatter_step(
    A: np.ndarray,
    B: np.ndarray,
    C: np.ndarray,
    G: np.ndarray | None,
    T: float,
    roots: np.ndarray,
    span: float,
    tol: float = 0.05,
) -> tuple[float, str]:
    """The step that resolves the chatter band, s, and why.

    The relevant roots are those whose envelope, relative to the rightmost
    root's ``exp(sigma0 t)``, falls by less than ``RELEVANT_DECAY`` over the
    fitted ``span``.  Each gets at least ``MIN_STEPS_PER_PERIOD`` steps per
    period and a growth-rate error ``|Re c| h^2`` (:func:`growth_error_coefficient`)
    of at most ``eps + (sigma0 - Re lam)/2``, ``eps = STEP_ERROR_FRACTION *
    max(|sigma0|, log(1 + tol)/span)``: the rightmost root within a quarter of
    the rate the verdict must tell from zero (or of the smallest one the fit
    can resolve), a root further left by half its distance from it, so that
    its discrete image cannot overtake the rightmost.  The number of steps per period of the highest
    relevant root follows."""
    lam = np.asarray(roots, dtype=complex).reshape(-1)
    lam = lam[np.isfinite(lam)]
    if lam.size == 0 or not span > 0:
        return math.inf, "no roots"
    s0 = float(lam.real.max())
    rel = lam[lam.real >= s0 - math.log(RELEVANT_DECAY) / span]
    target = STEP_ERROR_FRACTION * max(abs(s0), math.log1p(tol) / span)
    h, why = math.inf, ""
    for z in rel:
        w = abs(z.imag)
        c = growth_error_coefficient(A, B, C, G, T, complex(z.real, w))
        # a root left of the rightmost may move by half its distance from it:
        # its discrete image then neither overtakes nor reaches the rightmost
        allowed = target + 0.5 * (s0 - float(z.real))
        h_err = math.sqrt(allowed / abs(c.real)) if c.real != 0 and math.isfinite(c.real) else math.inf
        h_res = 2.0 * math.pi / (MIN_STEPS_PER_PERIOD * w) if w > 0 else math.inf
        hz = min(h_err, h_res)
        if hz < h:
            h = hz
            n = 2.0 * math.pi / (w * hz) if w > 0 else math.inf
            why = (
                f"{n:.3g} steps per period of the root {z.real:+.4g} 1/s at {w / 2 / math.pi:.6g} Hz"
                f" ({len(rel)} relevant root(s)): growth-rate error {abs(c.real) * hz * hz:.3g} 1/s,"
                f" allowed {allowed:.3g} 1/s"
            )
    if len(rel) == lam.size and lam.size > 1:
        why += f"; all {lam.size} roots given are relevant: roots further left may need a finer step"
    return h, why


def _constant_matrices(
    prob: ParametricProblem, pd: _ProcessDamping | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None, float]:
    """``(A, B, C, G, T)`` of a continuous cut at t = 0 (constant in time),
    with the process damping's linear term (the indentation model's
    small-vibration equivalent) in B."""
    A, B, C, G = prob.matrices(np.array([0.0]))
    B0 = np.array(B[0])
    if pd is not None:
        B0 = B0 + pd.linear_B(prob)
    return (
        np.array(A[0]),
        B0,
        np.array(C[0]),
        None if G is None else np.array(G[0]),
        float(prob.kin.delay),
    )


def constant_loop(
    system: System,
    *,
    feedback: Literal["none", "pd", "pdo"] = "pdo",
    width: float | None = None,
    speed: float | None = None,
    delay: float | None = None,
    position: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None, float] | None:
    """The matrices :func:`simulate` integrates for a continuous cut,
    ``A q'' + B q' + C q = p + G q(t - T)``: ``(A, B, C, G, T)`` (``G`` None
    without the delayed term), or None when the slide moves (no frozen
    system).  Their characteristic roots (``chatterlab.frequency.make_system(A,
    B, C, DO=G, tau=T)``) are those of the very system the run integrates."""
    width, kin = _check_run(system, feedback, width, 1, speed, delay, position)
    if not isinstance(kin, SteadyKinematics):
        return None
    prob = ParametricProblem(system, kin, width=float(width), terms=feedback, forces=False)
    return _constant_matrices(prob, _process_damping(prob))


def _roots_of(roots: Any) -> tuple[np.ndarray | None, bool]:
    """The roots given to :func:`simulate` (upper half plane, 1/s) and
    whether they are certain: a converged search whose band is proven to
    hold every root right of the rightmost one found."""
    if roots is None:
        return None, False
    arr = getattr(roots, "roots", roots)
    lam = np.asarray(arr, dtype=complex).reshape(-1)
    if lam.size and not np.all(np.isfinite(lam)):
        raise InputError("roots must be finite complex numbers (1/s)")
    lam = np.where(lam.imag < 0, lam.conj(), lam)
    lam = lam[np.argsort(-lam.real, kind="stable")]
    certain = bool(
        lam.size
        and getattr(roots, "converged", False)
        and float(getattr(roots, "complete_above", math.nan)) < float(lam.real.max())
    )
    return lam, certain


@dataclass(frozen=True, eq=False)
class _ProcessDamping:
    """The model's ``[process_damping]`` in a run at the cut's delay T
    (:func:`chatterlab.process._damping.damping_term`, the one the closed
    loop takes): the linear term ``b C_pd / V(T) W`` on the CE coordinates
    (the indentation model's small-vibration equivalent C_pd = K_sp w^2 / 4)
    and, for the indentation model, its flank on q_i."""

    term: Any
    speed: float
    ce_matrix: np.ndarray
    flank: Flank | None

    def linear_B(self, prob: ParametricProblem) -> np.ndarray:
        """``J_i^T (b g W) J_i`` on q_i at t = 0 (a continuous cut), N s/m."""
        Ji = prob.ce_map(np.array([0.0]))[0]
        out: np.ndarray = Ji.T @ self.ce_matrix @ Ji
        return out

    def describe(self) -> str:
        """Which model the run took, in one line."""
        t = self.term
        g = t.C_pd / self.speed
        if self.flank is None:
            return f"linear, C_pd = {t.C_pd:.6g} N/m at V = {self.speed:.4g} m/s (C_pd / V = {g:.4g} N s/m^2)"
        return (
            f"indentation, K_sp = {t.K_sp:.4g} N/m^3, wear land {t.wear_land * 1e6:.4g} um, clearance"
            f" {math.degrees(t.clearance):.4g} deg at V = {self.speed:.4g} m/s (small-vibration equivalent"
            f" C_pd = K_sp w^2/4 = {t.C_pd:.4g} N/m)"
        )


def _process_damping(prob: ParametricProblem) -> _ProcessDamping | None:
    """The process damping of the run of ``prob`` (None without it, with a
    zero C_pd, or with ``feedback="none"``, as :func:`chatterlab.process.closed_loop`)."""
    from ..process._damping import damping_term, penetration

    mdl = prob.system.model
    if prob.terms not in ("pd", "pdo") or getattr(mdl, "process_damping", None) is None:
        return None
    term = damping_term(mdl)
    if term is None:
        return None
    T = float(prob.kin.delay)
    V = float(term.speed(T))
    flank = None
    if term.indentation:
        if not isinstance(prob.kin, SteadyKinematics):
            raise InputError(
                "the indentation model of [process_damping] runs on a continuous cut: hold the slide with"
                " delay= or position= (--delay T or --position S), or give C_pd for the moving slide"
            )
        Ji = prob.ce_map(np.array([0.0]))[0]
        row = penetration(mdl) @ Ji[term.block]
        flank = Flank(row, prob.width, V, term.K_sp, term.wear_land, term.clearance)
    return _ProcessDamping(term, V, term.matrix(T, prob.width), flank)


class _WithProcessDamping(Sealed):
    """A moving slide's problem with the linear process damping while in
    the cut, on the rate of the relative displacement dw = J_i(t) q as the
    coupling's own D_V (Eq. 2.28): B(t) + c J_i^T (b g W) J_i and
    C(t) + c v J_i^T (b g W) dJ_i/ds (c the in-cut flag, v the slide's speed;
    a shaper's work speed, and so g, is constant along the stroke)."""

    def __init__(self, base: Any, prob: ParametricProblem, ce_matrix: np.ndarray) -> None:
        self.base = base
        self.prob = prob
        self.ce_matrix = ce_matrix
        self.n = base.n
        self._seal()

    def delay(self) -> float | None:
        out: float | None = self.base.delay()
        return out

    def breakpoints(self) -> tuple[float, ...]:
        out: tuple[float, ...] = self.base.breakpoints()
        return out

    def matrices(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        A, B, C, G = self.base.matrices(t)
        s, v, cut, moving = self.prob._positions(t)
        parts = self.prob._parts_direct(s)  # J_i(s) and dJ_i/ds, as the coupling's own D_V takes them
        Ji = np.asarray(parts["Ji"])
        JiT_D = np.transpose(Ji, (0, 2, 1)) @ self.ce_matrix
        c = np.asarray(cut, dtype=float)[:, None, None]
        B = B + c * (JiT_D @ Ji)
        if moving and np.any(parts["Jd1"]):  # the rate of dw = J_i q includes dJ_i/dt q = v dJ_i/ds q
            C = C + (c * np.asarray(v, dtype=float)[:, None, None]) * (JiT_D @ np.asarray(parts["Jd1"]))
        return A, B, C, G

    def force(self, t: np.ndarray) -> np.ndarray:
        out: np.ndarray = self.base.force(t)
        return out


def _flank_response(
    run_prob: ConstantProblem,
    flank: Flank,
    step: float,
    duration: float,
    q0v: np.ndarray,
    v0v: np.ndarray,
    hist: Any,
    integ: Integration,
) -> TimeResponse:
    """A continuous cut with the indentation model's flank
    (:func:`chatterlab.time._indentation.flank_run` on the run's constant
    matrices) as the :class:`TimeResponse` the histories are read from."""
    import time

    if hist is not None and not isinstance(hist, np.ndarray):
        raise InputError(
            "history: the indentation model reads the surface before t = 0 from a constant history: give"
            " None, 'zero', 'constant' or a vector"
        )
    wall0 = time.perf_counter()
    sch = integ.scheme
    run: FlankRun = flank_run(
        (run_prob.M, run_prob.C, run_prob.K, run_prob.G), run_prob.delay(), run_prob.force, flank,
        h=step, t_end=duration, q0=q0v, v0=v0v, history=hist, gamma=float(sch.gamma), beta=float(sch.beta),
        divergence_limit=float(sch.divergence_limit), progress=integ.progress,
    )  # fmt: skip
    wall = time.perf_counter() - wall0
    rec = slice(None, None, int(integ.record_every))
    return TimeResponse(
        t=run.t[rec].copy(),
        q=run.q[rec].T.copy(),
        v=run.v[rec].T.copy(),
        a=run.a[rec].T.copy(),
        names=None,
        status=run.status,
        message=run.message + f" in {wall:.3g} s",
        n_steps=run.t.size - 1,
        wall_time=wall,
        h=step,
        attrs={
            "gamma": float(sch.gamma),
            "beta": float(sch.beta),
            "delay": run_prob.delay(),
            "method": "indentation",
            "order": 2,
            "max_step": flank.wear_land / (MIN_LAND_STEPS * flank.speed),
            "wear_land": flank.wear_land,
            "speed": flank.speed,
            "flank_force": run.flank[rec].copy(),
            "flank_contact": run.contact[rec].copy(),
        },
    )


def _run_problem(
    prob: ParametricProblem,
    loads: Mapping[str, Callable[[np.ndarray], np.ndarray]] | None,
    ground_motion: Mapping[str, Callable[[np.ndarray], Any]] | None,
    pd: _ProcessDamping | None = None,
) -> Any:
    """What newmark integrates: the parametric problem (with the external
    loads and ground motion added, and the linear process damping while in
    the cut), or for steady kinematics its constant matrices at t = 0
    (factored once)."""
    extra = _ExtraForce(prob, loads, ground_motion) if (loads or ground_motion) else None
    if not isinstance(prob.kin, SteadyKinematics):
        base: Any = prob if extra is None else _WithExtraForce(prob, extra)
        return base if pd is None else _WithProcessDamping(base, prob, pd.ce_matrix)
    A, B, C, G = prob.matrices(np.array([0.0]))
    if pd is not None:
        B = B + pd.linear_B(prob)[None]
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
