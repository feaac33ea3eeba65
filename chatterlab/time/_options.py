"""Options and result of the Newmark integrator: :class:`NewmarkOptions`,
:class:`TimeResponse`, :class:`NewmarkStabilityWarning`; the option objects
of a simulation (:class:`Integration`, :class:`Initial`,
:class:`Excitation`), which :func:`chatterlab.time.simulate` and
:func:`chatterlab.time.simulate_milling` take instead of twenty keywords."""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np

from chatterlab.errors import InputError, check_count, check_positive

from ._history import TimeHistory
from ._problems import FloatArray


class NewmarkStabilityWarning(UserWarning):
    """The chosen Newmark parameters are only conditionally stable."""


# =========================================================================== options & result


@dataclass(frozen=True)
class NewmarkOptions:
    """Parameters of the Newmark integrator.

    Attributes
    ----------
    gamma, beta : float
        Newmark parameters.  Default ``1/2, 1/4``: average acceleration
        (trapezoidal rule), unconditionally stable, second order, no numerical
        damping.  Following Bathe & Wilson (1976) the scheme is called
        unconditionally stable when ``gamma >= 1/2`` and
        ``beta >= (gamma + 1/2)^2 / 4``; ``gamma > 1/2`` adds numerical damping
        and lowers the order to one.  ``beta < gamma/2`` is only conditionally
        stable (``w_max h < (gamma/2 - beta)^(-1/2)``) and gives a
        :class:`NewmarkStabilityWarning`.  ``beta <= 0`` (explicit) and
        ``gamma < 1/2`` (negative numerical damping: spurious growth, the worst
        possible error for a chatter prediction) are refused.
    chunk : int or None
        Steps whose matrices are prepared together.  ``None`` picks about
        ``2**18 / n**2`` (2 MB per stack of matrices), within [16, 4096].
    workers : int, default 2
        Background threads preparing the next chunks (matrices, batched
        inverse) while the current one is stepped; 0 prepares them in the
        calling thread.  The batched LAPACK calls release the GIL, so two
        workers keep two cores busy.  The problem's ``matrices``/``force``
        are called under a lock (one call at a time), so a
        problem object need not be thread-safe.
    divergence_limit : float, default 1e12
        ``max |q|`` (units of ``q``: m, rad) beyond which the run stops with
        ``status="diverged"``.
    max_history_bytes : int, default 2 GiB
        Memory allowed for the stored state history (needed for the delay).
    max_output_bytes : int, default 4 GiB
        Memory allowed for the recorded ``q, v, a``.
    """

    gamma: float = 0.5
    beta: float = 0.25
    chunk: int | None = None
    workers: int = 2
    divergence_limit: float = 1e12
    max_history_bytes: int = 2 * 1024**3
    max_output_bytes: int = 4 * 1024**3

    def __post_init__(self) -> None:
        g, b = self.gamma, self.beta
        if not (isinstance(g, (int, float)) and math.isfinite(g)):
            raise InputError(f"NewmarkOptions.gamma must be a finite number (got {g!r})")
        if not (isinstance(b, (int, float)) and math.isfinite(b)):
            raise InputError(f"NewmarkOptions.beta must be a finite number (got {b!r})")
        if b <= 0.0:
            raise InputError(
                f"NewmarkOptions.beta must be > 0 (got {b}); beta = 0 is the explicit central "
                "difference scheme, which this implicit solver does not implement; use the "
                "default beta = 1/4"
            )
        if g < 0.5:
            raise InputError(
                f"NewmarkOptions.gamma must be >= 1/2 (got {g}); gamma < 1/2 adds negative "
                "numerical damping, i.e. spurious growth that would be mistaken for chatter"
            )
        if self.chunk is not None and (
            isinstance(self.chunk, bool) or not isinstance(self.chunk, (int, np.integer)) or self.chunk < 1
        ):
            raise InputError(f"NewmarkOptions.chunk must be a positive integer or None ({self.chunk!r})")
        if (
            isinstance(self.workers, bool)
            or not isinstance(self.workers, (int, np.integer))
            or self.workers < 0
        ):
            raise InputError(f"NewmarkOptions.workers must be an integer >= 0 ({self.workers!r})")
        if not (self.divergence_limit > 0):
            raise InputError(f"NewmarkOptions.divergence_limit must be > 0 (got {self.divergence_limit!r})")
        for name in ("max_history_bytes", "max_output_bytes"):
            if not getattr(self, name) > 0:
                raise InputError(f"NewmarkOptions.{name} must be > 0")

    @property
    def unconditionally_stable(self) -> bool:
        """``gamma >= 1/2`` and ``beta >= (gamma + 1/2)^2 / 4`` (Bathe & Wilson)."""
        return self.gamma >= 0.5 and self.beta >= (self.gamma + 0.5) ** 2 / 4.0 - 1e-15

    @property
    def critical_omega_h(self) -> float:
        """Stability limit of ``w h`` for an undamped mode (``inf`` when ``beta >= gamma/2``)."""
        if self.beta >= self.gamma / 2.0:
            return math.inf
        return 1.0 / math.sqrt(self.gamma / 2.0 - self.beta)


@dataclass(frozen=True, eq=False)
class TimeResponse(TimeHistory):
    """Result of :func:`newmark`.

    Attributes
    ----------
    t : ndarray, shape (n_t,)
        Recorded times [s].
    q, v, a : ndarray, shape (n_out, n_t)
        Displacement [m, rad], velocity [m/s, rad/s] and acceleration
        [m/s^2, rad/s^2] at the recorded output coordinates.
    names : tuple of str or None
        Names of the ``n_out`` outputs.
    status : str
        ``"ok"``, ``"diverged"`` (non-finite state or ``|q|`` beyond
        ``divergence_limit``; the data stop before it), ``"interrupted"``
        (KeyboardInterrupt: the data computed so far) or ``"stopped"``
        (the ``callback`` asked to stop).
    message : str
        Human-readable account of the run (and of any stability caveat).
    n_steps : int
        Number of steps integrated.
    wall_time : float
        Wall-clock time of the integration [s].
    h : float
        Step [s].

    Its histories (:class:`~chatterlab.time._history.TimeHistory`: spectrum,
    growth, CSV, netCDF, plot) are named ``"q:NAME"``, ``"v:NAME"`` and
    ``"a:NAME"`` for each output (``NAME``: its name, or ``out0``, ``out1``,
    ... without names); an output's name or index alone means its
    displacement ``q``.
    """

    t: FloatArray
    q: FloatArray
    v: FloatArray
    a: FloatArray
    names: tuple[str, ...] | None
    status: str
    message: str
    n_steps: int
    wall_time: float
    h: float = math.nan
    attrs: dict[str, Any] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def _row(self, coord: int | str) -> int:
        if isinstance(coord, str):
            labels = self._labels()
            if coord not in labels:
                raise InputError(f"coord {coord!r} is not one of the output names {self.names}")
            return labels.index(coord)
        i = int(coord)
        if not -self.q.shape[0] <= i < self.q.shape[0]:
            raise InputError(f"coord {coord} out of range for {self.q.shape[0]} outputs")
        return i

    def _labels(self) -> list[str]:
        if self.names is not None:
            return list(self.names)
        return [f"out{i}" for i in range(self.q.shape[0])]

    def _name(self, coord: int | str, field: str = "q") -> str:
        if field not in _FIELDS:
            raise InputError(f"field must be 'q', 'v' or 'a' (got {field!r})")
        return f"{field}:{self._labels()[self._row(coord)]}"

    def histories(self) -> dict[str, tuple[np.ndarray, str, str]]:
        """``"q:NAME"``, then ``"v:NAME"``, ``"a:NAME"``, of every output
        (unit left empty: m or rad, m/s or rad/s, ... by coordinate)."""
        return {
            f"{f}:{lab}": (row, "", f"{long_name} of {lab}")
            for f, long_name in _FIELDS.items()
            for lab, row in zip(self._labels(), getattr(self, f), strict=True)
        }

    def history(self, name: int | str) -> np.ndarray:
        """One history: ``"q:NAME"`` (``v``, ``a``), or an output's name or
        index for its displacement."""
        if isinstance(name, str) and name[:2] in ("q:", "v:", "a:") and name not in self._labels():
            return getattr(self, name[0])[self._row(name[2:])]
        return self.q[self._row(name)]

    def file_attrs(self) -> dict[str, Any]:
        return {
            "output_names": ",".join(self._labels()),
            "status": self.status,
            "message": self.message,
            "step_s": float(self.h),
            "n_steps": int(self.n_steps),
        }

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """Dimensions ``(output, time)``: ``q``, ``v``, ``a`` (units ``SI``:
        m or rad by coordinate), the output names in the ``output_names``
        attribute."""
        coords = {
            "output": (np.arange(self.q.shape[0]), "", "recorded output index"),
            "time": (self.t, "s", "time"),
        }
        data = {f: (getattr(self, f), "SI", long_name) for f, long_name in _FIELDS.items()}
        return coords, data, self.file_attrs()

    def growth_rate(self, coord: int | str = 0, *, field: str = "q", **kwargs: Any) -> Any:
        """Deprecated: :meth:`growth` (its ``skip`` is in seconds, as for
        every time history).  This keeps the old meaning: ``kwargs`` go to
        :func:`chatterlab.time.growth_rate` on the whole history (``skip`` a
        fraction of it)."""
        import warnings

        from ._signals import growth_rate

        warnings.warn(
            "TimeResponse.growth_rate is deprecated; use growth(name, skip=seconds, ...), the method "
            "of every time-history result",
            DeprecationWarning,
            stacklevel=2,
        )
        return growth_rate(self.t, self.history(self._name(coord, field)), **kwargs)

    def to_csv(
        self, path: str | Path, names: Sequence[str] | None = None, *, fields: Sequence[str] = ("q",)
    ) -> Path | None:
        """Write ``t [s]``, the chosen fields of every output as columns
        ``<field>:<name>`` (SI units) -- or the histories ``names`` -- and the
        run's ``status``, one row per time, round-trip exact
        (:meth:`TimeHistory.to_csv`)."""
        if names is None:
            names = [self._name(i, f) for f in fields for i in range(self.q.shape[0])]
        return super().to_csv(path, names=names)

    def plot(
        self, names: Sequence[str] | str | None = None, *, ax: Any = None, field: str = "q", **style: Any
    ) -> Any:
        """Plot outputs (names or indices; default all) against time; returns the Axes."""
        picked: Any = names
        rows = (
            range(self.q.shape[0])
            if picked is None
            else ([picked] if isinstance(picked, (int, str)) else list(picked))
        )
        chosen = [self._name(c, field) for c in rows]
        labels = [n.split(":", 1)[1] for n in chosen]
        return super().plot(chosen, labels=labels, ylabel=field, ax=ax, **style)


#: the recorded fields of a TimeResponse and their long names
_FIELDS = {"q": "displacement", "v": "velocity", "a": "acceleration"}


# =========================================================================== the options of a simulation


#: the smallest error target of the exponential step map: round-off (1e-16 per step, grown over
#: the run's steps) bounds what it can reach; below, it would only take more steps
RTOL_MIN = 1e-12


def check_rtol(rtol: Any) -> float:
    """The exponential step map's error target, checked: a number in [RTOL_MIN, 1)."""
    if isinstance(rtol, bool) or not isinstance(rtol, (int, float)) or not RTOL_MIN <= float(rtol) < 1.0:
        raise InputError(
            f"rtol must be a number in [{RTOL_MIN:g}, 1), e.g. 1e-3 (got {rtol!r}): round-off bounds what"
            " a step map can reach"
        )
    return float(rtol)


#: the schemes of a simulation (:attr:`Integration.integrator`)
INTEGRATORS = ("auto", "newmark", "exponential")


@dataclass(frozen=True)
class Integration:
    """How a simulation is integrated: its length, its step and the scheme.

    Attributes
    ----------
    duration : float, optional
        Simulated time, s (overrides ``periods``).
    periods : float, optional
        The length in the process's own periods: stroke cycles or delays of
        a cut (:func:`~chatterlab.time.simulate`, default 2), spindle
        revolutions of a milling run (:func:`~chatterlab.time.simulate_milling`,
        default 50).
    step : float, optional
        Time step h, s (:func:`~chatterlab.time.simulate`; default: its step
        rule).
    steps_per_period : int, optional
        Steps per mean tooth period (:func:`~chatterlab.time.simulate_milling`;
        default: the period-error rule).
    record_every : int, default 1
        Record every k-th step (:func:`~chatterlab.time.simulate`).
    method : {"auto", "polynomial", "direct", "generic"}
        How the coefficients of Eq. 2.28 are evaluated
        (:class:`~chatterlab.time.ParametricProblem`).
    scheme : NewmarkOptions
        gamma, beta, worker threads, divergence and memory limits (Newmark).
    progress : callable, optional
        ``progress(fraction)`` after each chunk of steps (Newmark).
    integrator : {"auto", "newmark", "exponential"}, default "auto"
        The scheme of :func:`~chatterlab.time.simulate`: the exponential
        step map (:func:`~chatterlab.time.exponential`, order 6, its step
        chosen for ``rtol``) or the seed paper's Newmark.  ``"auto"`` takes
        the exponential step map for a continuous cut (constant
        coefficients: ``delay=`` or ``position=``, or turning) whose
        ``step`` is not given, and Newmark otherwise (the moving slide, a
        given step); ``"exponential"`` with a ``step`` runs the step map at
        that step.
    rtol : float, optional
        The relative error of the recorded histories (each relative to its
        largest value) the exponential step map's step is chosen for
        (default 1e-3); refused for a run that integrates with Newmark.
    """

    duration: float | None = None
    periods: float | None = None
    step: float | None = None
    steps_per_period: int | None = None
    record_every: int = 1
    method: Literal["auto", "polynomial", "direct", "generic"] = "auto"
    scheme: NewmarkOptions = field(default_factory=NewmarkOptions)
    progress: Callable[[float], Any] | None = field(default=None, compare=False)
    integrator: Literal["auto", "newmark", "exponential"] = "auto"
    rtol: float | None = None

    def __post_init__(self) -> None:
        if self.integrator not in INTEGRATORS:
            raise InputError(
                f"integrator must be one of {', '.join(repr(i) for i in INTEGRATORS)} (got {self.integrator!r})"
            )
        if self.rtol is not None:
            check_rtol(self.rtol)
        if self.duration is not None:
            object.__setattr__(self, "duration", check_positive(self.duration, "duration", "s"))
        if self.periods is not None:
            check_positive(self.periods, "periods")  # kept as given: an int stays an int (stroke cycles)
        if self.step is not None:
            object.__setattr__(self, "step", check_positive(self.step, "step", "s"))
        if self.steps_per_period is not None:
            spp = check_count(self.steps_per_period, "steps_per_period (steps per tooth period)")
            object.__setattr__(self, "steps_per_period", spp)
        r = self.record_every
        if isinstance(r, bool) or not isinstance(r, (int, np.integer)) or r < 1:
            raise InputError(f"record_every must be a positive integer (got {r!r})")
        if self.method not in ("auto", "polynomial", "direct", "generic"):
            raise InputError(
                f"method must be 'auto', 'polynomial', 'direct' or 'generic' (got {self.method!r})"
            )
        if not isinstance(self.scheme, NewmarkOptions):
            raise InputError(f"scheme must be a NewmarkOptions (got {type(self.scheme).__name__})")


@dataclass(frozen=True)
class Initial:
    """Where a simulation starts: ``q0``, ``v0`` at t = 0 and the history
    before it (read by the delayed term).  Each is checked by the function
    it is given to (its accepted forms: :func:`~chatterlab.time.simulate`);
    None is zero."""

    q0: Any = None
    v0: Any = None
    history: Any = None


@dataclass(frozen=True)
class Excitation:
    """What loads a cut besides its feedback: the desired cutting forces
    (``cutting_forces``), external ``loads`` ``{"POINT.DIR": f(t)}`` (N, N m)
    and a prescribed ``ground_motion`` ``{"ground.y": g(t) -> (q, q', q'')}``
    (see :func:`~chatterlab.time.simulate`)."""

    cutting_forces: bool = True
    loads: Mapping[str, Callable[[np.ndarray], np.ndarray]] | None = None
    ground_motion: Mapping[str, Callable[[np.ndarray], Any]] | None = None


#: the 0.2 keywords of simulate / simulate_milling -> (option object, its field)
LEGACY_KEYWORDS: dict[str, tuple[str, str]] = {
    "duration": ("integration", "duration"),
    "passes": ("integration", "periods"),
    "revolutions": ("integration", "periods"),
    "step": ("integration", "step"),
    "steps_per_period": ("integration", "steps_per_period"),
    "record_every": ("integration", "record_every"),
    "method": ("integration", "method"),
    "options": ("integration", "scheme"),
    "progress": ("integration", "progress"),
    "q0": ("initial", "q0"),
    "v0": ("initial", "v0"),
    "history": ("initial", "history"),
    "forces": ("excitation", "cutting_forces"),
    "loads": ("excitation", "loads"),
    "ground_motion": ("excitation", "ground_motion"),
}


def with_legacy(who: str, given: dict[str, Any], allowed: Sequence[str], **objects: Any) -> dict[str, Any]:
    """The option objects of ``who`` (``objects``: name -> the object given
    or None) with the 0.2 keywords ``given`` (those in ``allowed``) moved
    into them, with a DeprecationWarning naming the new form; an unknown
    keyword is a TypeError, as Python's own."""
    defaults = {"integration": Integration, "initial": Initial, "excitation": Excitation}
    out = {name: (defaults[name]() if obj is None else obj) for name, obj in objects.items()}
    for name, obj in out.items():
        if not isinstance(obj, defaults[name]):
            raise InputError(f"{name} must be a {defaults[name].__name__} (got {type(obj).__name__})")
    unknown = [k for k in given if k not in allowed]
    if unknown:
        raise TypeError(f"{who}() got an unexpected keyword argument {unknown[0]!r}")
    moved: dict[str, dict[str, Any]] = {}
    for key, value in given.items():
        target, name = LEGACY_KEYWORDS[key]
        moved.setdefault(target, {})[name] = value
    for target, values in moved.items():
        out[target] = replace(out[target], **values)
    if given:
        hint = ", ".join(
            f"{k}= -> {LEGACY_KEYWORDS[k][0]}={type(out[LEGACY_KEYWORDS[k][0]]).__name__}({LEGACY_KEYWORDS[k][1]}=...)"
            for k in given
        )
        warnings.warn(f"{who}: the keywords {hint} (0.2) are deprecated", DeprecationWarning, stacklevel=3)
    return out
