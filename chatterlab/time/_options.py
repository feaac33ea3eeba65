"""Options and result of the Newmark integrator: :class:`NewmarkOptions`,
:class:`TimeResponse`, :class:`NewmarkStabilityWarning`."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from chatterlab.errors import InputError

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
class TimeResponse:
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
            if self.names is None or coord not in self.names:
                raise InputError(f"coord {coord!r} is not one of the output names {self.names}")
            return self.names.index(coord)
        i = int(coord)
        if not -self.q.shape[0] <= i < self.q.shape[0]:
            raise InputError(f"coord {coord} out of range for {self.q.shape[0]} outputs")
        return i

    def _field(self, name: str) -> FloatArray:
        if name not in ("q", "v", "a"):
            raise InputError(f"field must be 'q', 'v' or 'a' (got {name!r})")
        return getattr(self, name)

    def _series(self, coord: int | str, field_: str, t_min: float | None) -> tuple[FloatArray, FloatArray]:
        x = self._field(field_)[self._row(coord)]
        if t_min is None:
            return self.t, x
        sel = self.t >= t_min
        return self.t[sel], x[sel]

    def spectrum(
        self, coord: int | str = 0, *, field: str = "q", t_min: float | None = None, **kwargs: Any
    ) -> tuple[FloatArray, FloatArray]:
        """Amplitude spectrum of one output (see :func:`chatterlab.time._signals.amplitude_spectrum`).

        Returns ``(freq [Hz], amplitude [units of the field])``; ``t_min``
        [s] drops the start (e.g. the transient).
        """
        from chatterlab.time._signals import amplitude_spectrum

        t, x = self._series(coord, field, t_min)
        return amplitude_spectrum(t, x, **kwargs)

    def growth_rate(self, coord: int | str = 0, *, field: str = "q", **kwargs: Any) -> Any:
        """Envelope growth rate of one output (see :func:`chatterlab.time._signals.growth_rate`)."""
        from chatterlab.time._signals import growth_rate

        t, x = self._series(coord, field, None)
        return growth_rate(t, x, **kwargs)

    def _labels(self) -> list[str]:
        if self.names is not None:
            return list(self.names)
        return [f"out{i}" for i in range(self.q.shape[0])]

    def to_csv(self, path: str | Path, *, fields: Sequence[str] = ("q",)) -> Path:
        """Write ``t`` and the chosen fields as a wide CSV file (one row per time).

        Columns: ``t [s]`` then ``<field>:<name>`` for each output; SI units.
        """
        path = Path(path)
        cols = [self.t]
        header = ["t [s]"]
        for f in fields:
            arr = self._field(f)
            cols.extend(arr)
            header.extend(f"{f}:{name}" for name in self._labels())
        np.savetxt(
            path, np.column_stack(cols), delimiter=",", header=",".join(header), comments="", fmt="%.17g"
        )
        return path

    def to_netcdf(self, path: str | Path) -> Path:
        """Write the response with :func:`chatterlab.io._netcdf.write_netcdf` (dims output, time)."""
        try:
            from chatterlab.io._netcdf import write_netcdf
        except ImportError as exc:  # pragma: no cover - depends on the install
            raise ImportError(
                "TimeResponse.to_netcdf needs chatterlab.io._netcdf; use to_csv instead"
            ) from exc
        coords = {
            "output": (np.arange(self.q.shape[0]), "", "recorded output index"),
            "time": (self.t, "s", "time"),
        }
        data = {
            "q": (self.q, "SI", "displacement"),
            "v": (self.v, "SI", "velocity"),
            "a": (self.a, "SI", "acceleration"),
        }
        attrs = {
            "output_names": ",".join(self._labels()),
            "status": self.status,
            "message": self.message,
            "step_s": float(self.h),
            "n_steps": int(self.n_steps),
        }
        return write_netcdf(path, coords, data, attrs)

    def plot(
        self,
        coords: Sequence[int | str] | int | str | None = None,
        *,
        field: str = "q",
        ax: Any = None,
        **kwargs: Any,
    ) -> Any:
        """Plot outputs against time with matplotlib; returns the Axes."""
        from ..plot import plot_outputs

        rows = (
            range(self.q.shape[0])
            if coords is None
            else ([coords] if isinstance(coords, (int, str)) else list(coords))
        )
        arr = self._field(field)
        labels = self._labels()
        idx = [self._row(c) for c in rows]
        return plot_outputs(self.t, arr[idx], [labels[i] for i in idx], ylabel=field, ax=ax, **kwargs)
