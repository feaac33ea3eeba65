"""The probabilistic lobe diagram: :func:`risk`.

Each sample of the uncertain fields (:class:`~._space.InputSpace`, points of
:class:`~._design.Design`) is one model and one complete lobe diagram with
its argument-principle checks (:func:`chatterlab.lobes.lobes`), computed by
the sweep engine (:func:`chatterlab.sweep.sweep`, grid ``sample x speed``,
a chunk holds whole samples) in parallel, checkpointed and resumable; the
samples' limits give the probability of stability on a (speed, width)
grid, quantile lobes, the probability of chatter at operating points, the
distribution of the smallest limit and, with ``sensitivity=True``, Sobol'
indices -- each with its error from the replicates (:mod:`._estimate`).

**The stopping rule.**  With ``tol``, the run proceeds in stages of
n = 16, 32, 64, ... rows per replicate (the Sobol' sequences extended, the
rows already computed kept) and stops at the first stage where the error
of the target is at most ``tol``: the half-width of the confidence
interval of P(chatter) at every operating point (without points: at every
cell of the probability map), and never less than -ln(1 - level)/N -- the
bound of a probability of which none of N samples has shown an event
(3/N at 95 %, the "rule of three"), so that a run cannot stop because an
event too rare to have been seen has no spread -- or when ``samples`` is
reached.
"""

from __future__ import annotations

import math
import os
import shutil
import uuid
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError, ModelError, check_positive, check_speed, check_width
from ..model._items import Model
from ._design import Design, check_samples, rows_per_replicate
from ._result import ProbabilisticLobes
from ._space import InputSpace
from ._task import OUTPUTS, LobeSampleTask, pack

__all__ = ["risk", "speed_unit"]

#: rows per replicate of the first stage of a run with a stopping rule
FIRST_STAGE = 16
#: the probability-map widths when none are given
N_WIDTHS = 200


def speed_unit(process: Any) -> str:
    """The unit of the speeds of a lobe diagram of this process (the one place
    this package reads it: speeds are handed to the lobe engine as given)."""
    return str(process.speed_unit) if process is not None else ""


def risk(
    model: Model,
    speeds: Any,
    *,
    width_max: float | None = None,
    samples: int = 1024,
    replicates: int = 8,
    seed: int = 0,
    method: str = "qmc",
    quantiles: Sequence[float] = (0.05, 0.5, 0.95),
    widths: Any = None,
    points: Sequence[tuple[float, float]] = (),
    sensitivity: bool = False,
    factors: dict[str, Any] | None = None,
    tol: float | None = None,
    level: float = 0.95,
    position: float | None = None,
    verify: int = 1,
    share: bool = True,
    jobs: int = 2,
    backend: str = "loky",
    scheduler: Any = None,
    security: Any = None,
    checkpoint: str | os.PathLike[str] | None = None,
    resume: bool = False,
    keep_checkpoint: bool = True,
    progress: bool = False,
    **options: Any,
) -> ProbabilisticLobes:
    """The probabilistic lobe diagram of a model with an ``[uncertainty]`` table.

    Parameters
    ----------
    model : Model
        A model file with an ``[uncertainty]`` table (docs/model-format.md);
        turning, shaping, milling or a measured FRF (``[frf]``), as
        :func:`chatterlab.lobes.lobes` takes it.
    speeds : array
        Speeds in the process's unit (as :func:`chatterlab.lobes.lobes`).
    width_max : float, optional
        Largest width of cut searched, m (the lobe engine's default when None).
    samples : int
        The sample budget: ``replicates`` x the power of two of rows nearest
        samples / replicates (with ``tol``: the most it may take).
    replicates : int
        Independent randomisations (>= 2; their spread is the error bar).
    seed : int
        The run's seed: the same seed gives the same samples and results.
    method : {"qmc", "mc"}
        Scrambled Sobol' points (default) or pseudo-random ones.
    quantiles : sequence of float
        Levels of the quantile lobes, in (0, 1).
    widths : array, optional
        Widths of the probability map, m (default: 200 up to ``width_max``).
    points : sequence of (speed, width)
        Operating points (process unit, m) whose probability of chatter is
        estimated; their speeds are computed with the others.
    sensitivity : bool
        Sobol' indices of the smallest limit and of chatter at each point
        (k + 2 lobe diagrams per sample for k factors).
    factors : dict, optional
        The factors of the Sobol' indices as named groups of fields, ``{name:
        [pattern, ...]}`` with shell patterns of parameter paths (``{"tap
        test": ["mode.*"], "cutting test": ["coupling.*"]}``); the fields
        no pattern names are factors of their own (default: every
        independent field or correlated group).
    tol : float, optional
        Stop when the error of P(chatter) at the points (without points: of
        the map) is at most ``tol`` (the module docstring).
    level : float
        Confidence level of every interval (0.95).
    position : float, optional
        A model's slide position, m.
    verify : int
        Argument-principle checks per diagram (``lobes(verify=)``; 1: the
        minimum from below and above and every inf at the ceiling).
    share : bool
        Reuse the structure (assembly, complex modes) when only the cut is
        uncertain.
    jobs, backend, scheduler, security, checkpoint, resume, keep_checkpoint, progress
        The sweep engine's (:func:`chatterlab.sweep.sweep`); the checkpoint
        is a directory of one sweep checkpoint per stage.
    **options
        The lobe route's options (``terms``, ``fmin``, ``fmax``,
        ``n_frequencies``, ``method`` for milling, ...).

    Returns
    -------
    ProbabilisticLobes
    """
    import time

    t0 = time.perf_counter()
    from ..lobes import lobes

    if not isinstance(model, Model):
        raise InputError(
            f"risk takes a Model with an [uncertainty] table (load_model(...)), not {type(model).__name__}"
        )
    space = InputSpace.of(model)
    level = _fraction(level, "level")
    if tol is not None:
        tol = check_positive(tol, "tol")
        if not tol < 1:
            raise InputError(f"tol is an error of a probability: it must be below 1 (got {tol:g})")
    q = np.array([_fraction(x, "quantile") for x in quantiles], float)
    fdims, fnames = space.sensitivity_factors(factors)
    design = Design(space.dims, fdims, replicates, seed, method, sensitivity)  # type: ignore[arg-type]
    samples = check_samples(samples, replicates)
    n_max = rows_per_replicate(samples, replicates)
    grid_v = np.asarray(speeds, float)
    if grid_v.ndim != 1 or grid_v.size == 0:
        raise InputError("speeds must be a non-empty 1-D array")
    pts = _points(points, speed_unit(model.process))
    all_v = np.unique(np.concatenate([grid_v, pts[:, 0]]))
    opts = _lobe_options(model, verify, options)
    # the nominal diagram: checks the speeds, width and options before any sample, and is drawn with them
    nominal = lobes(model, all_v, width_max=width_max, position=position, **opts)
    wmax = float(nominal.width_max)
    b_grid = _widths(widths, wmax)
    for p in pts:
        if not p[1] <= wmax:
            raise InputError(
                f"operating point width {p[1] * 1e3:g} mm is above width_max {wmax * 1e3:g} mm: nothing is"
                " known there; raise width_max"
            )
    _check_extremes(model, space)
    fp = _fingerprint(model, space, design, n_max, all_v, wmax, position, opts)
    task = LobeSampleTask(
        model, space, design, n_max, tuple(all_v.tolist()), wmax, position, tuple(sorted(opts.items())),
        share, fp, uuid.uuid4().hex,
    )  # fmt: skip
    stages = [n_max] if tol is None else _schedule(n_max)
    arrays = {k: np.full((replicates, design.matrices, n_max, all_v.size), np.nan) for k in OUTPUTS}
    ckpt = Path(checkpoint) if checkpoint is not None else None
    if ckpt is not None and not resume and ckpt.exists() and any(ckpt.iterdir()):
        raise InputError(
            f"checkpoint directory {str(ckpt)!r} is not empty: pass resume=True (CLI: --resume) to continue"
            " the run saved there, or give another directory"
        )
    done, n, n_failed, stop, errors = 0, 0, 0, "", []
    for s, n in enumerate(stages):
        n_failed += _stage(task, arrays, done, n, all_v, s, ckpt, resume, progress, jobs, backend, scheduler,
                           security)  # fmt: skip
        done = n
        err = _target_error(arrays, n, all_v, grid_v, b_grid, pts, level, replicates)
        errors.append(err)
        if tol is not None and err <= tol:
            stop = f"tol reached: error {err:.3g} <= {tol:g} at {replicates * n} samples"
            break
    else:
        stop = f"sample budget reached ({replicates * n} samples)" + (
            f"; error {err:.3g} > tol {tol:g}" if tol is not None else ""
        )
    if ckpt is not None and not keep_checkpoint and n_failed == 0:
        shutil.rmtree(ckpt, ignore_errors=True)
    data = {k: v[:, :, :n] for k, v in arrays.items()}
    inputs = np.stack([space.transform(design.points(r, 0, np.arange(n))) for r in range(replicates)])
    return ProbabilisticLobes.build(
        nominal=nominal,
        space=space,
        design=design,
        rows=n,
        data=data,
        all_speeds=all_v,
        speeds=grid_v,
        widths=b_grid,
        quantile_levels=q,
        points=pts,
        level=level,
        inputs=inputs,
        tol=tol,
        stop=stop,
        error=err,
        stages=tuple(replicates * x for x in stages[: stages.index(n) + 1]),
        errors=tuple(errors),
        n_failed=n_failed,
        elapsed=time.perf_counter() - t0,
        checkpoint=None if ckpt is None or not ckpt.exists() else str(ckpt),
        shared=task._shared_route(),
        factor_names=fnames,
    )


# ---------------------------------------------------------------------------- the stages


def _schedule(n_max: int) -> list[int]:
    out, n = [], min(FIRST_STAGE, n_max)
    while n < n_max:
        out.append(n)
        n *= 2
    return [*out, n_max]


def _stage(
    task: LobeSampleTask,
    arrays: dict[str, np.ndarray],
    start: int,
    stop: int,
    all_v: np.ndarray,
    s: int,
    ckpt: Path | None,
    resume: bool,
    progress: bool,
    jobs: int,
    backend: str,
    scheduler: Any,
    security: Any,
) -> int:
    """Rows [start, stop) of every replicate and matrix through the sweep
    engine; their outputs into ``arrays``; returns the failed tasks."""
    from ..sweep import Grid, sweep

    R, M = task.design.replicates, task.design.matrices
    rows = range(start, stop)
    ids = [pack(r, m, j, M, task.rows) for r in range(R) for m in range(M) for j in rows]
    grid = Grid({"sample": (np.asarray(ids, float), ""), "speed": (all_v, speed_unit(task.model.process))})
    per = max(1, min(16, len(ids) // (8 * max(jobs, 1))))  # whole samples per chunk
    stage_dir = None if ckpt is None else ckpt / f"stage_{s:02d}_rows_{start}_{stop}"
    res = sweep(
        task,
        grid,
        outputs={k: (u, w) for k, (u, w) in OUTPUTS.items()},
        jobs=jobs,
        backend=backend,  # type: ignore[arg-type]
        scheduler=scheduler,
        security=security,
        chunk_size=per * all_v.size,
        checkpoint=stage_dir,
        resume=bool(resume and stage_dir is not None and stage_dir.exists()),
        fingerprint={"run": task.key, "stage": f"{start}:{stop}"},
        progress=progress,
        keep_checkpoint=True,
    )
    shape = (R, M, stop - start, all_v.size)
    for k in OUTPUTS:
        arrays[k][:, :, start:stop, :] = np.asarray(res[k]).reshape(shape)
    return int(res.n_failed)


def _target_error(
    arrays: dict[str, np.ndarray],
    n: int,
    all_v: np.ndarray,
    grid_v: np.ndarray,
    b_grid: np.ndarray,
    pts: np.ndarray,
    level: float,
    R: int,
) -> float:
    """The error the stopping rule holds to ``tol`` (module docstring)."""
    from ._estimate import p_stable_replicates, t_factor

    b = arrays["b_lim"][:, 0, :n, :]  # (R, n, speeds): the matrix A
    if pts.size:
        j = np.searchsorted(all_v, pts[:, 0])
        chatter = b[:, :, j] <= pts[None, None, :, 1]
        reps = np.where(np.isnan(b[:, :, j]).any(axis=1), np.nan, chatter.mean(axis=1))  # (R, points)
    else:
        j = np.searchsorted(all_v, grid_v)
        reps = p_stable_replicates(b[:, :, j], b_grid).reshape(R, -1)
    se = reps.std(axis=0, ddof=1) / math.sqrt(R)
    floor = -math.log(1.0 - level) / (R * n)
    # undetermined estimates (NaN: a sample establishes nothing there) are not made precise by more samples
    err = t_factor(R, level) * se
    return float(max(np.max(err[np.isfinite(err)], initial=0.0), floor))


# ---------------------------------------------------------------------------- checks


def _lobe_options(model: Model, verify: int, options: dict[str, Any]) -> dict[str, Any]:
    """The lobe route's options, with ``verify`` where the route checks its
    diagram by the argument principle (the D-subdivision of a model's
    matrices; the Floquet and measured-FRF routes have their own checks)."""
    opts = dict(options)
    milling = model.process is not None and model.process.kind == "milling" and opts.get("method") != "zoa"
    if model.frf is None and not milling:
        opts.setdefault("verify", verify)
    return opts


def _fraction(x: Any, name: str) -> float:
    v = check_positive(x, name)
    if not v < 1:
        raise InputError(f"{name} must lie between 0 and 1 (got {v:g})")
    return v


def _points(points: Sequence[tuple[float, float]], unit: str) -> np.ndarray:
    out = []
    for k, p in enumerate(points):
        try:
            v, b = p
        except (TypeError, ValueError):
            raise InputError(f"operating point #{k + 1}: give (speed, width) (got {p!r})") from None
        out.append(
            (
                check_speed(v, f"operating point #{k + 1} speed", unit),
                check_width(b, f"operating point #{k + 1} width"),
            )
        )
    return np.array(out, float).reshape(-1, 2)


def _widths(widths: Any, wmax: float) -> np.ndarray:
    if widths is None:
        return np.linspace(wmax / N_WIDTHS, wmax, N_WIDTHS)
    b = np.asarray(widths, float)
    if b.ndim != 1 or b.size == 0 or not np.all(np.isfinite(b)) or not np.all(b > 0):
        raise InputError("widths must be a non-empty 1-D array of widths > 0, m")
    if np.any(np.diff(b) <= 0):
        raise InputError("widths must increase")
    if b[-1] > wmax:
        raise InputError(
            f"widths reach {b[-1] * 1e3:g} mm, above width_max {wmax * 1e3:g} mm: nothing is known there"
        )
    return b


def _check_extremes(model: Model, space: InputSpace) -> None:
    """Every field's distribution stays within what the model accepts: the
    model is built at the 1e-6 and 1 - 1e-6 quantiles of each factor (the
    others at their medians), before any sample is computed."""
    from ..model import parameter_overrides

    for f, cols in zip(space.factors, space.factor_dims(), strict=True):
        if all(space.marginals[i].zero_width for i in f):
            continue
        for edge in (1e-6, 1 - 1e-6):
            u = np.full((1, space.dims), 0.5)
            u[0, list(cols)] = edge
            x = space.transform(u)[0]
            values = dict(zip(space.paths, x.tolist(), strict=True))
            try:
                model.with_parameters(parameter_overrides(model, values))
            except ModelError as exc:
                what = ", ".join(f"{space.paths[i]} = {x[i]:.6g}" for i in f)
                raise InputError(
                    f"[uncertainty]: at its {edge:g} quantile the distribution gives {what}, which the model"
                    f" refuses ({exc.detail}): truncate it (lower/upper) or narrow it"
                ) from None


def _fingerprint(
    model: Model,
    space: InputSpace,
    design: Design,
    n_max: int,
    v: np.ndarray,
    wmax: float,
    position: float | None,
    opts: dict[str, Any],
) -> str:
    """What the samples depend on, as one text: the model (file, variant,
    overrides, matrix files), the distributions, the design and the lobe
    options; a checkpoint written for another run is refused by it."""
    import hashlib

    from ..quantities import model_fingerprint

    text = "|".join(
        [
            model_fingerprint(model),
            space.fingerprint(),
            repr((design.dims, design.factor_dims, design.replicates, design.seed, design.method,
                  design.sensitivity, n_max)),
            hashlib.sha1(np.ascontiguousarray(v).tobytes()).hexdigest(),
            repr((wmax, position, sorted((k, repr(x)) for k, x in opts.items()))),
        ]
    )  # fmt: skip
    return hashlib.sha1(text.encode()).hexdigest()[:20]
