"""The stability limit under spindle-speed variation: the width b_lim (milling:
depth a_lim) at a mean speed, RVA and RVF, from the Floquet multipliers of
:mod:`chatterlab.frequency._floquet_ssv`, and its sweep over
(speed, RVA, RVF) through the sweep engine (:class:`SsvLimitTask`, picklable).

The search.  rho(b), the spectral radius at width b, is evaluated on the
scan b_k = k width_max / scan, k = 1..scan; the first sample with rho >= 1
and the stable one before it bracket a crossing, refined by Brent's method
to ``rtol``.  Its basis is ``"scan"``: under SSV rho(b) is not monotonic
(the multipliers of a time-periodic loop move with b along no rule that
bounds them between samples), so an unstable band narrower than the scan
step between two stable samples would be missed; a finer scan narrows what
can hide.  b_lim is inf where no sample up to ``width_max`` is unstable.

The classic finding (Sexton & Stone 1978; Insperger & Stepan 2004; Zatarain
et al. 2008): the variation raises the limit at low speed, where many
vibrations fit in one revolution (high lobe numbers) and the phase between
the inner and the outer modulation is scrambled; at the high-speed lobes it
does not help, and may lower the limit.

References
----------
J. S. Sexton, B. J. Stone, The stability of machining with continuously
varying spindle speed, Annals of the CIRP 27 (1978) 321-326.
T. Insperger, G. Stepan, J. Vib. Control 10 (2004) 1835-1855; M. Zatarain et
al., CIRP Annals 57 (2008) 379-384 (see :mod:`chatterlab.frequency._floquet_ssv`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar

import numpy as np

from ..errors import InputError, check_count, check_positive, check_width
from ..io import Result
from ..process import ClosedLoop, SpeedVariation
from ..process._loop import closed_loop_unwarned
from ._floquet import classify
from ._floquet_ssv import ssv_multipliers, ssv_split

__all__ = ["SsvLimits", "SsvLimitTask", "ssv_limit", "ssv_limits", "ssv_limits_at", "SCAN", "KIND_CODES"]

#: default scan samples over (0, width_max]
SCAN = 20
#: the critical multiplier's type as a number (netCDF/CSV): 0 none found
KIND_CODES = {"": 0.0, "hopf": 1.0, "flip": 2.0, "fold": 3.0}


def ssv_limit(
    loop: ClosedLoop,
    speed: float | None,
    variation: SpeedVariation,
    *,
    width_max: float,
    scan: int = SCAN,
    rtol: float = 1e-6,
    method: str = "spectral",
    degree: int | None = None,
    steps: int | None = None,
    span: float | None = None,
    split: float | None = None,
) -> dict[str, Any]:
    """b_lim at one mean speed under ``variation`` (module docstring).

    Parameters
    ----------
    loop : ClosedLoop
        Milling loop, or turning/shaping at the mean speed's delay.
    speed : float or None
        Mean speed (rpm for milling).
    variation : SpeedVariation
        The program.
    width_max : float
        Largest width searched, m.
    scan, rtol : int, float
        Scan samples; Brent's relative tolerance.
    method, degree, steps, span, split
        As :func:`chatterlab.frequency.ssv_multipliers` (``split``: Hz, the structure's
        quasi-static split, set up once for the search).

    Returns
    -------
    dict
        ``b_lim`` (m, inf: none up to width_max), ``mu`` (the critical multiplier there),
        ``chatter_frequency`` (Hz), ``kind``, ``evaluations``, ``basis`` ("scan"); with a
        split also ``split_error`` (:func:`~chatterlab.frequency._floquet_ssv.split_error`
        at the limit).
    """
    wmax = check_width(width_max, "width_max")
    n = check_count(scan, "scan", 2)
    opts: dict[str, Any] = {"method": method, "check": False}
    if degree is not None:
        opts["degree"] = degree
    if steps is not None:
        opts["steps"] = steps
    if span is not None:
        opts["span"] = float(span)
    qs = ssv_split(loop, split)
    if qs is not None:
        opts["split"] = qs
    count = 0

    def rho(b: float) -> float:
        nonlocal count
        count += 1
        return float(ssv_multipliers(loop, speed, b, variation, **opts).spectral_radius)

    prev_b = 0.0  # the structure alone is stable
    for k in range(1, n + 1):
        b = wmax * k / n
        f = rho(b) - 1.0
        if f >= 0.0:
            from scipy.optimize import brentq  # here: import chatterlab stays light

            lo = prev_b if prev_b > 0.0 else 1e-9 * wmax
            if prev_b == 0.0 and rho(lo) >= 1.0:
                root = lo
            else:
                root = float(
                    brentq(lambda x: rho(x) - 1.0, lo, b, xtol=rtol * lo, rtol=4 * np.finfo(float).eps)
                )
            m = ssv_multipliers(loop, speed, root, variation, **opts)
            count += 1
            out = {
                "b_lim": root,
                "mu": complex(m.critical),
                "chatter_frequency": float(m.frequency_hz),
                "kind": classify(complex(m.critical)),
                "evaluations": count,
                "basis": "scan",
            }
            if qs is not None:
                out["split_error"] = float(m.meta["split_error"])
            return out
        prev_b = b
    return {
        "b_lim": math.inf,
        "mu": complex(math.nan, 0.0),
        "chatter_frequency": math.nan,
        "kind": "",
        "evaluations": count,
        "basis": "scan",
    }


@dataclass(frozen=True)
class SsvLimitTask:
    """b_lim at a grid point (speed, rva, rvf): the picklable task of an SSV sweep.

    ``loop`` is a milling :class:`~chatterlab.process.ClosedLoop` (speeds in rpm)
    or a turning/shaping one at any delay, moved to each speed's delay by
    ``process`` (the model's process kinematics, ``delay(speed)``); build it with
    :meth:`of`, which drops what does not pickle (the model's configuration)."""

    loop: ClosedLoop
    process: Any = None
    shape: str = "sine"
    width_max: float = 1e-3
    scan: int = SCAN
    rtol: float = 1e-6
    method: str = "spectral"
    degree: int | None = None
    steps: int | None = None
    span: float | None = None
    split: float | None = None

    OUTPUTS: ClassVar[dict[str, str]] = {"b_lim": "m", "chatter_frequency": "Hz", "kind": "1"}

    @classmethod
    def of(cls, source: Any, **options: Any) -> SsvLimitTask:
        """The task for a milling loop or a turning/shaping model's configuration
        (a :class:`~chatterlab.structure.FrozenSystem`)."""
        if isinstance(source, ClosedLoop):
            if source.process is None and source.frozen is None:
                raise InputError("ssv limits: a turning/shaping loop needs its model (give the FrozenSystem)")
            loop, process = source, None if source.process is not None else source.frozen.model.process  # type: ignore[union-attr]
        else:
            model = getattr(source, "model", None)
            if model is None or model.process is None:
                raise InputError(
                    "ssv limits: give a milling loop or a model's configuration with a [process] table"
                    f" (got {type(source).__name__})"
                )
            w = float(options.get("width_max", 1e-3))
            loop, process = (
                closed_loop_unwarned(source, width=w, speed=float(model.process.speed)),
                model.process,
            )
        return cls(replace(loop, frozen=None), process, **options)

    def loop_at(self, speed: float) -> ClosedLoop:
        if self.process is None:
            return self.loop
        return self.loop.at(delay=float(self.process.delay(speed)))

    def __call__(self, speed: float, rva: float, rvf: float) -> dict[str, float]:
        v = SpeedVariation(float(rva), float(rvf), self.shape)
        r = ssv_limit(
            self.loop_at(float(speed)), float(speed), v, width_max=self.width_max, scan=self.scan,
            rtol=self.rtol, method=self.method, degree=self.degree, steps=self.steps, span=self.span,
            split=self.split,
        )  # fmt: skip
        out = {
            "b_lim": r["b_lim"],
            "chatter_frequency": r["chatter_frequency"],
            "kind": KIND_CODES[r["kind"]],
        }
        if self.split is not None:
            out["split_error"] = float(r.get("split_error", math.nan))  # nan: no limit found
        return out


@dataclass(frozen=True, eq=False)
class SsvLimits(Result):
    """Stability limits under spindle-speed variation over (speed, RVA, RVF).

    Attributes
    ----------
    speeds, rva, rvf : ndarray
        The grid: mean speeds (the process's unit), relative amplitudes, relative
        frequencies.
    b_lim : ndarray, shape (speeds, rva, rvf)
        The limit width (milling: depth), m; inf where none was found up to
        ``width_max``.
    chatter_frequency : ndarray
        Hz, at the limit.
    kind : ndarray
        The critical multiplier's type (KIND_CODES).
    shape, method, basis : str
        The wave, the Floquet discretisation, the search's basis ("scan").
    width_max : float
        The searched range, m.
    speed_unit, limit_name : str
        The process's names ("rpm", "b_lim" / "a_lim").
    """

    speeds: np.ndarray
    rva: np.ndarray
    rvf: np.ndarray
    b_lim: np.ndarray
    chatter_frequency: np.ndarray
    kind: np.ndarray
    shape: str
    method: str
    width_max: float
    scan: int
    speed_unit: str = "rpm"
    limit_name: str = "b_lim"
    basis: str = "scan"
    meta: dict[str, Any] = field(default_factory=dict)

    def gain(self) -> np.ndarray:
        """b_lim / b_lim at RVA = 0 (the constant speed), shape (speeds, rva, rvf);
        an InputError when the grid has no RVA = 0."""
        zero = np.nonzero(self.rva == 0.0)[0]
        if zero.size == 0:
            raise InputError("the SSV limits hold no RVA = 0 (the constant speed) to compare with")
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.b_lim / self.b_lim[:, zero[:1], :]

    def table(self) -> str:
        """The limits as the command line prints them (mm)."""
        lines = [
            f"{self.limit_name} under {self.shape} spindle-speed variation ({self.method}, basis {self.basis}:"
            f" {self.scan} scan widths to {self.width_max * 1e3:g} mm)"
        ]
        if "split_hz" in self.meta:
            err = np.asarray(self.meta["split_error"], dtype=float)
            worst = float(np.nanmax(err)) if np.any(np.isfinite(err)) else math.nan
            where = (
                f"<= {worst:.2g} in the chatter band at the limits found"
                if math.isfinite(worst)
                else "not estimated (no limit found)"
            )
            lines.append(
                f"modes above {self.meta['split_hz']:g} Hz quasi-static: their error on the delayed loop's"
                f" transfer {where}"
            )
        head = f"{'speed [' + self.speed_unit + ']':>14}  {'RVA':>6}  {'RVF':>8}  {self.limit_name + ' [mm]':>12}"
        lines.append(head)
        for i, s in enumerate(self.speeds):
            for j, a in enumerate(self.rva):
                for k, f in enumerate(self.rvf):
                    b = self.b_lim[i, j, k]
                    shown = f"> {self.width_max * 1e3:g}" if not np.isfinite(b) else f"{b * 1e3:.6g}"
                    lines.append(f"{s:14.6g}  {a:6.3g}  {f:8.4g}  {shown:>12}")
        return "\n".join(lines)

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """Coordinates speed, rva, rvf; the limit and its chatter frequency and type (with a
        quasi-static split, its error estimate at each limit and the split frequency)."""
        coords, data, attrs = (
            {
                "speed": (np.asarray(self.speeds, float), self.speed_unit, "mean speed"),
                "rva": (np.asarray(self.rva, float), "1", "relative variation amplitude RVA"),
                "rvf": (np.asarray(self.rvf, float), "1", "relative variation frequency RVF"),
            },
            {
                self.limit_name: (self.b_lim, "m", "stability limit under SSV"),
                "chatter_frequency": (self.chatter_frequency, "Hz", "chatter frequency at the limit"),
                "kind": (self.kind, "1", "critical multiplier: 1 hopf, 2 flip, 3 fold, 0 none"),
            },
            {
                "title": "chatterlab SSV stability limits",
                "shape": self.shape,
                "method": self.method,
                "basis": self.basis,
                "width_max_m": float(self.width_max),
                "scan": int(self.scan),
            },
        )
        if "split_hz" in self.meta:
            data["split_error"] = (
                np.asarray(self.meta["split_error"], dtype=float),
                "1",
                "quasi-static split: relative error of the delayed loop's transfer in the chatter band at the limit",
            )
            attrs["split_hz"] = float(self.meta["split_hz"])
        return coords, data, attrs

    def plot(self, ax: Any = None, **style: Any) -> Any:
        """The limit against the mean speed, one curve per (RVA, RVF)
        (:func:`chatterlab.plot.plot_ssv`); returns the Axes."""
        from ..plot import plot_ssv

        return plot_ssv(self, ax=ax, **style)


def ssv_limits(
    source: Any,
    speeds: Any,
    rva: Any,
    rvf: Any,
    *,
    shape: str = "sine",
    width_max: float,
    scan: int = SCAN,
    rtol: float = 1e-6,
    method: str = "spectral",
    degree: int | None = None,
    steps: int | None = None,
    span: float | None = None,
    split: float | None = None,
    jobs: int = 1,
    backend: str = "serial",
    progress: bool = False,
    speed_unit: str | None = None,
    limit_name: str | None = None,
) -> SsvLimits:
    """Limits over the grid speeds x rva x rvf, in parallel through the sweep engine.

    Parameters
    ----------
    source : ClosedLoop or FrozenSystem
        A milling loop (speeds in rpm) or a turning/shaping model's configuration.
    speeds, rva, rvf : array_like
        The mean speeds, relative amplitudes (0: the constant speed), relative frequencies.
    shape : {"sine", "triangle"}
        The wave.
    width_max, scan, rtol, method, degree, steps, span, split
        As :func:`ssv_limit`.
    jobs, backend, progress
        As :func:`chatterlab.sweep.sweep`.
    speed_unit, limit_name : str, optional
        Names for the files (default: from the source's process).

    Returns
    -------
    SsvLimits
    """
    from ..sweep import Grid, sweep

    sp = np.atleast_1d(np.asarray(speeds, dtype=float))
    ra = np.atleast_1d(np.asarray(rva, dtype=float))
    rf = np.atleast_1d(np.asarray(rvf, dtype=float))
    task, outputs = _task_of(
        source, sp, ra, rf, shape=shape, width_max=float(width_max), scan=int(scan), rtol=float(rtol),
        method=method, degree=degree, steps=steps, span=span, split=split,
    )  # fmt: skip
    res = sweep(
        task, Grid({"speed": sp, "rva": ra, "rvf": rf}), outputs=outputs, jobs=jobs,
        backend=backend, progress=progress, on_error="raise",  # type: ignore[arg-type]
    )  # fmt: skip
    ds = res.to_xarray()
    if speed_unit is None or limit_name is None:
        proc = getattr(source, "process", None)
        if proc is None:
            model = getattr(source, "model", None)
            proc = getattr(model, "process", None)
        speed_unit = speed_unit or str(getattr(proc, "speed_unit", "rpm"))
        limit_name = limit_name or str(getattr(proc, "limit_name", "b_lim"))
    get = lambda k: np.asarray(ds[k].transpose("speed", "rva", "rvf").values, dtype=float)  # noqa: E731
    meta: dict[str, Any] = {}
    if split is not None:
        meta = {"split_hz": float(split), "split_error": get("split_error")}
    return SsvLimits(
        sp, ra, rf, get("b_lim"), get("chatter_frequency"), get("kind"), shape, method, float(width_max),
        int(scan), speed_unit, limit_name, meta=meta,
    )  # fmt: skip


def _task_of(
    source: Any, sp: np.ndarray, ra: np.ndarray, rf: np.ndarray, **options: Any
) -> tuple[SsvLimitTask, dict[str, str]]:
    """The task for ``source`` and the sweep's outputs, once the speeds, RVA
    and RVF it is asked at are valid (an InputError naming the first bad one
    before any work)."""
    for name, arr in (("speeds", sp), ("rva", ra), ("rvf", rf)):
        if arr.size == 0 or not np.all(np.isfinite(arr)):
            raise InputError(f"ssv limits: {name} must be finite numbers (got {arr.tolist()})")
    for s in sp:
        check_positive(s, "speed")
    for a in ra:
        for f in rf:
            SpeedVariation(
                float(a), float(f), str(options.get("shape", "sine"))
            )  # refused here, before any work
    outputs = dict(SsvLimitTask.OUTPUTS)
    if options.get("split") is not None:
        outputs["split_error"] = "1"
    return SsvLimitTask.of(source, **options), outputs


@dataclass(frozen=True)
class _AtPoints:
    """An SSV task at listed points (speed, rva, rvf), called by the point's
    index: the sweep engine's one axis (picklable, as the task is)."""

    task: SsvLimitTask
    points: tuple[tuple[float, float, float], ...]

    def __call__(self, point: float) -> dict[str, float]:
        return self.task(*self.points[int(point)])


def ssv_limits_at(
    source: Any,
    points: Any,
    *,
    jobs: int = 1,
    backend: str = "serial",
    shape: str = "sine",
    width_max: float,
    scan: int = SCAN,
    rtol: float = 1e-6,
    method: str = "spectral",
    degree: int | None = None,
    steps: int | None = None,
    span: float | None = None,
    split: float | None = None,
) -> np.ndarray:
    """The limits b_lim (m; inf: none up to ``width_max``) at listed points,
    not a grid: ``points`` is a sequence of (speed, rva, rvf), searched as
    :func:`ssv_limits` searches a grid point, in parallel through the sweep
    engine (``jobs``, ``backend`` as there).  The mesh check of ``ssv``
    searches its picked points of a grid again on a finer mesh with it."""
    from ..sweep import Grid, sweep

    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    if pts.shape[0] == 0:
        return np.zeros(0)
    task, outputs = _task_of(
        source, pts[:, 0], pts[:, 1], pts[:, 2], shape=shape, width_max=float(width_max), scan=int(scan),
        rtol=float(rtol), method=method, degree=degree, steps=steps, span=span, split=split,
    )  # fmt: skip
    at = _AtPoints(task, tuple((float(s), float(a), float(f)) for s, a, f in pts))
    res = sweep(
        at, Grid({"point": np.arange(pts.shape[0], dtype=float)}), outputs=outputs, jobs=min(jobs, pts.shape[0]),
        backend=backend, progress=False, on_error="raise",  # type: ignore[arg-type]
    )  # fmt: skip
    return np.asarray(res["b_lim"], dtype=float).reshape(-1)
