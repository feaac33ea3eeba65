"""What every time-history result shares: :class:`TimeHistory`.

A time-history result is a set of named, uniformly sampled histories on one
time axis ``t`` (s), with the status of the run that produced it.  The
generic Newmark solver's :class:`~chatterlab.time.TimeResponse` (``q``,
``v``, ``a`` per output), a cut's :class:`~chatterlab.time.Simulation`
(named outputs and the process state) and a milling run's
:class:`~chatterlab.time.MillingSimulation` (the tool point, forces, chips,
Poincare samples and the verdict) are levels of it; all inherit this one
implementation of

* :meth:`TimeHistory.spectrum` -- the amplitude spectrum of one history over
  a time window (:func:`chatterlab.time.amplitude_spectrum`);
* :meth:`TimeHistory.growth` -- the envelope growth rate of one history
  (:func:`chatterlab.time.growth_rate`);
* ``to_xarray`` / ``to_netcdf`` / ``to_json`` -- the one result protocol
  (:class:`chatterlab.io.Result`) on :meth:`TimeHistory.dataset_parts`: an
  :class:`xarray.Dataset` with a ``time`` coordinate (s) and ``units`` on
  every variable, a netCDF-4 file written by :func:`chatterlab.io.write_netcdf`
  (returns the path), strict JSON;
* :meth:`TimeHistory.to_csv` -- one wide CSV writer for every time history:
  ``t [s]``, one column per history (``name [unit]``), the run's status in
  the last column; every number written as the shortest decimal that reads
  back to the same double (round-trip exact, like
  :func:`chatterlab.io.write_csv`); returns the path;
* :meth:`TimeHistory.plot` -- histories against time through
  :func:`chatterlab.plot.plot_outputs` (``plot(names, ax=None, **style)``,
  returns the Axes).  A result may draw its own figure by default
  (a milling run: vibration, forces and Poincare samples) with the same
  signature: no result narrows it.

How a result plugs in
---------------------
The class is a mixin for a frozen dataclass: it has no fields of its own.
The result provides ``t`` (n_t,) in s, ``status`` and ``message``; its
histories either come from a class attribute ::

    history_fields: ClassVar[dict[str, tuple[str, str]]] = {
        "x": ("m", "tool displacement x"), "Fx": ("N", "cutting force x"), ...}

naming attributes of shape (n_t,) (or (k, n_t): rows ``name.1`` ...
``name.k``) with their unit and long name, or from an override of
:meth:`TimeHistory.histories`.  Optional hooks: :meth:`TimeHistory.window`
(named time windows beyond ``"all"`` and ``(t0, t1)``),
:meth:`TimeHistory.file_attrs` (global attributes of the files) and
:meth:`TimeHistory.dataset_parts` (another layout of the netCDF file).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from ..errors import InputError
from ..io import Result

__all__ = ["TimeHistory", "netcdf_name"]

FloatArray = NDArray[Any]
#: one history: (values (n_t,), unit, long name)
History = tuple[np.ndarray, str, str]


def netcdf_name(name: str) -> str:
    """A history's name as a netCDF variable: every character other than a
    letter, digit or underscore replaced by ``_`` (``rfe5.x`` -> ``rfe5_x``),
    ``v_`` prefixed to a leading digit."""
    v = re.sub(r"[^0-9A-Za-z_]", "_", name)
    return v if not v[:1].isdigit() else f"v_{v}"


class TimeHistory(Result):
    """Mixin of the time-history results: spectrum, growth, files and plot.

    See the module docstring for what a result provides.  Every method
    reads histories through :meth:`history`, so a subclass only says what
    its histories are; the files come from :meth:`dataset_parts` through
    the one result protocol (:class:`chatterlab.io.Result`), except the CSV,
    whose layout is the time history's own (one row per time, the run's
    status on every row).
    """

    #: attribute name -> (unit, long name) of the histories stored as attributes
    history_fields: ClassVar[dict[str, tuple[str, str]]] = {}
    #: time window of :meth:`spectrum` when none is given
    spectrum_window: ClassVar[Any] = "all"

    # ------------------------------------------------------------------ what a result provides

    def histories(self) -> dict[str, History]:
        """``name -> (values (n_t,), unit, long_name)`` of every history, in
        file order (default: the attributes named in ``history_fields``, a
        2-D one as rows ``name.1`` ... ``name.k``)."""
        out: dict[str, History] = {}
        for attr, (unit, long_name) in self.history_fields.items():
            arr = np.asarray(getattr(self, attr))
            if arr.ndim == 1:
                out[attr] = (arr, unit, long_name)
            else:
                for j, row in enumerate(arr.reshape(-1, arr.shape[-1])):
                    out[f"{attr}.{j + 1}"] = (row, unit, f"{long_name} {j + 1}")
        return out

    def history(self, name: str) -> np.ndarray:
        """One history, shape (n_t,), by name (an InputError lists the names)."""
        hist = self.histories()
        if name not in hist:
            raise InputError(f"no history {name!r} (recorded: {', '.join(hist)})")
        return hist[name][0]

    def window(self, which: str | tuple[float, float] = "all") -> np.ndarray:
        """Boolean mask of a time window: ``"all"`` or ``(t0, t1)`` (s, both ends included)."""
        t = self._time()
        if isinstance(which, tuple):
            if len(which) != 2:
                raise InputError(f"a time window is (t0, t1) in s (got {which!r})")
            return (t >= which[0]) & (t <= which[1])
        if which == "all":
            return np.ones(t.size, bool)
        raise InputError(f"window must be 'all' or (t0, t1) in s (got {which!r})")

    def file_attrs(self) -> dict[str, Any]:
        """Global attributes of the files: at least the run's ``status`` and ``message``."""
        return {"status": self._status(), "message": str(getattr(self, "message", ""))}

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """``(coords, data, attrs)`` for :func:`chatterlab.io.make_dataset`:
        ``time`` (s) and one variable per history (:func:`netcdf_name` of its
        name, the name itself as ``long_name`` when it had to change; a flag
        stored as 0/1 in float64)."""
        data: dict[str, Any] = {}
        for name, (values, unit, long_name) in self.histories().items():
            var = netcdf_name(name)
            if var in data:
                raise InputError(f"histories {name!r} and another one are both stored as {var!r}")
            arr = values.astype(float) if values.dtype == bool else values
            data[var] = (arr, unit, name if var != name else long_name)
        return {"time": (self._time(), "s", "time")}, data, self.file_attrs()

    # ------------------------------------------------------------------ shared behaviour

    def spectrum(
        self,
        name: str,
        *,
        window: str | tuple[float, float] | None = None,
        taper: str | None = "hann",
        **kwargs: Any,
    ) -> tuple[FloatArray, FloatArray]:
        """Single-sided amplitude spectrum of one history over a time window.

        Parameters
        ----------
        name : str
            The history.
        window : str or (t0, t1), optional
            Time window (:meth:`window`); default ``spectrum_window`` of the class.
        taper : str or None, default "hann"
            Spectral window (:func:`scipy.signal.get_window` name) with
            coherent-gain correction.
        **kwargs
            ``detrend``, ``pad`` of :func:`chatterlab.time.amplitude_spectrum`.

        Returns
        -------
        freq : ndarray
            Hz.
        amplitude : ndarray
            Units of the history: a sine of amplitude ``a`` shows a peak ``a``.
        """
        from ._signals import amplitude_spectrum

        which = self.spectrum_window if window is None else window
        m = _one_run(self.window(which), which)
        return amplitude_spectrum(self._time()[m], self.history(name)[m], window=taper, **kwargs)

    def growth(
        self,
        name: str,
        *,
        window: str | tuple[float, float] = "all",
        skip: float = 0.0,
        **kwargs: Any,
    ) -> Any:
        """Exponential growth rate of the envelope of one history.

        Parameters
        ----------
        name : str
            The history.
        window : str or (t0, t1), default "all"
            Time window (:meth:`window`).
        skip : float, default 0
            Seconds dropped from the start of the run (the transient) before
            the window is fitted.
        **kwargs
            ``method``, ``tol``, ``t_min``, ``t_max`` of
            :func:`chatterlab.time.growth_rate` (whose default also drops
            the first 20 % of what it is given, unless ``t_min`` is set).

        Returns
        -------
        GrowthEstimate
            ``rate`` [1/s], ``classification`` (decaying / steady / growing /
            undetermined), ``r2``, ``message``.
        """
        from ._signals import growth_rate

        if not (isinstance(skip, (int, float)) and math.isfinite(skip) and skip >= 0):
            raise InputError(f"skip must be a time >= 0 in s (got {skip!r})")
        t = self._time()
        m = _one_run(self.window(window) & (t >= t[0] + skip), window)
        return growth_rate(t[m], self.history(name)[m], **kwargs)

    def to_csv(self, path: Any, names: Sequence[str] | None = None) -> Path | None:
        """Write ``t [s]``, the histories ``names`` (default: all) as
        ``name [unit]`` columns (a dimensionless unit ``1`` as ``[-]``, a flag
        as 0/1) and a last column ``status`` (the run's status on every row,
        so that the file alone says whether it can be trusted).  Numbers are
        the shortest decimals that read back to the same doubles.  ``path``
        is a file name (written atomically) or an open text stream."""
        hist = self.histories()
        names = list(hist) if names is None else list(names)
        for n in names:
            if n not in hist:
                raise InputError(f"no history {n!r} (recorded: {', '.join(hist)})")
        cols = [(f"{n} [{_csv_unit(hist[n][1])}]" if hist[n][1] else n, hist[n][0]) for n in names]
        return write_history_csv(path, self._time(), cols, self._status())

    def plot(self, names: Sequence[str] | str | None = None, *, ax: Any = None, **style: Any) -> Any:
        """Histories against time, one line each, through
        :func:`chatterlab.plot.plot_outputs`: ``names`` (default all),
        ``style`` -- ``labels`` (one per history), ``ylabel`` (default the
        common unit) and anything ``Axes.plot`` takes.  Returns the Axes."""
        from ..plot import plot_outputs

        hist = self.histories()
        names = list(hist) if names is None else ([names] if isinstance(names, str) else list(names))
        rows = np.array([self.history(n) for n in names]).reshape(len(names), -1)
        labels = style.pop("labels", None)
        ylabel = style.pop("ylabel", None)
        if ylabel is None:
            units = {hist[n][1] for n in names}
            ylabel = f"[{units.pop()}]" if len(units) == 1 else ""
        return plot_outputs(
            self._time(), rows, list(labels) if labels is not None else names, ylabel=ylabel, ax=ax, **style
        )

    # ------------------------------------------------------------------ helpers

    def _time(self) -> np.ndarray:
        return np.asarray(getattr(self, "t"))  # noqa: B009 - a mixin: t is the result's field

    def _status(self) -> str:
        return str(getattr(self, "status", ""))


def _csv_unit(unit: str) -> str:
    return "-" if unit == "1" else unit


def write_history_csv(
    path: Any, t: np.ndarray, columns: Sequence[tuple[str, np.ndarray]], status: str
) -> Path | None:
    """The CSV writer of every time history: ``t [s]``, the ``(header,
    values)`` columns, ``status``; one row per time; floats as their
    shortest round-trip decimal (``repr``), booleans and integers as
    integers.  ``path``: a file name (written atomically through
    :func:`chatterlab.io.text_out`; returned) or an open text stream."""
    import csv

    from ..io import text_out

    data = [np.asarray(t, dtype=float)] + [np.asarray(v) for _, v in columns]
    for head, v in columns:
        if v.shape != data[0].shape:
            raise InputError(f"CSV column {head!r} has shape {v.shape}, the time axis {data[0].shape}")
    block = 65536
    with text_out(path) as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["t [s]"] + [h for h, _ in columns] + ["status"])
        for j0 in range(0, data[0].size, block):
            part = [_py(a[j0 : j0 + block]) for a in data]
            part.append([status] * len(part[0]))
            w.writerows(zip(*part, strict=True))
    return None if hasattr(path, "write") else Path(path)


def _py(a: np.ndarray) -> list[Any]:
    """Python numbers (``float.__repr__`` is the shortest round-trip decimal)."""
    if a.dtype == bool:
        return a.astype(np.int8).tolist()
    return a.tolist()


def _one_run(mask: np.ndarray, which: Any) -> np.ndarray:
    """``mask`` if it selects one contiguous run of samples; a window of
    several runs with gaps between them (``"cut"`` over several passes) is
    refused: a spectrum or a growth rate needs uniformly spaced samples."""
    starts = np.count_nonzero(mask[1:] & ~mask[:-1]) + int(bool(mask.size and mask[0]))
    if starts > 1:
        raise InputError(
            f"window {which!r} selects {starts} separate stretches of time (passes in the cut with gaps"
            " between them); a spectrum or growth rate needs one: use window='last-cut' or (t0, t1) in s"
        )
    return mask
