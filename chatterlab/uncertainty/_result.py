"""The result of :func:`chatterlab.uncertainty.risk`: :class:`ProbabilisticLobes`.

What it holds, for a limit b_lim(v) that is a random function of the
uncertain fields:

* ``p_stable`` -- P(b < b_lim(v)) on the (speed, width) grid: the
  probability that every width up to b is free of chatter at speed v (the
  probability of chatter at (v, b) is 1 - p_stable);
* ``quantiles`` -- quantile lobes b_q(v), P(b_lim(v) <= b_q(v)) = q: at the
  5 % lobe, 95 % of the machines (of the distribution) are still stable;
* ``p_chatter`` -- P(b_lim(v) <= b) at operating points;
* ``b_min`` -- the smallest limit over the speed range: its mean and
  quantiles;
* ``sobol`` -- first-order and total Sobol' indices of the smallest limit
  and of chatter at each point, per factor (with ``sensitivity=True``);

each an :class:`~chatterlab.uncertainty.Estimate` with its standard error
and confidence interval from the replicates.  The samples' limits are kept
(:attr:`ProbabilisticLobes.samples`), so any other point, width or risk
level is a query, not a new run (:meth:`p_chatter_at`,
:meth:`safe_width`, :meth:`recommend`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..io import Result
from ._estimate import Estimate, p_stable_replicates, quantile_estimate, replicate_estimate, sobol_indices

__all__ = ["ProbabilisticLobes", "RiskLimit"]


@dataclass(frozen=True, eq=False)
class RiskLimit:
    """A width limit at a risk of chatter: ``name`` and
    ``max_width(speeds, upper)`` -- the largest width (m) at each speed whose
    probability of chatter is at most the risk (on the safe side of its
    sampling error), capped at ``upper`` -- the form of a plug-in width
    limit of a speed recommendation (``limits=``).

    The limit is known at the speeds the diagram computed; at a speed
    between two of them it is the smaller of the two (a dip narrower than
    the speed step is not seen, as in any sampled lobe diagram: compute the
    speeds the recommendation will ask for), and 0 -- no cut -- outside
    their range."""

    name: str
    speeds: np.ndarray
    widths: np.ndarray

    def max_width(self, speeds: Any, upper: Any) -> np.ndarray:
        v = np.atleast_1d(np.asarray(speeds, float))
        j = np.clip(np.searchsorted(self.speeds, v), 0, self.speeds.size - 1)
        exact = self.speeds[j] == v
        below = self.widths[np.maximum(j - 1, 0)]
        w = np.where(exact, self.widths[j], np.minimum(below, self.widths[j]))
        w = np.where((v < self.speeds[0]) | (v > self.speeds[-1]), 0.0, w)
        return np.minimum(np.asarray(upper, float), w)


@dataclass(frozen=True, eq=False)
class ProbabilisticLobes(Result):
    """A probabilistic stability lobe diagram (see the module docstring).

    Attributes
    ----------
    speed : ndarray (n_v,)
        The speeds of the diagram, in the process's unit.
    width : ndarray (n_b,)
        The widths of the probability map, m.
    p_stable : Estimate
        P(b < b_lim(v)), arrays (n_v, n_b).
    quantile_levels : ndarray (n_q,)
    quantiles : Estimate
        Quantile lobes, arrays (n_q, n_v), m (``inf``: no boundary up to
        ``width_max`` at that level).
    nominal : LobeDiagram
        The diagram of the model as written (at every speed computed).
    points : ndarray (n_p, 2)
        Operating points (speed, width m).
    p_chatter : Estimate
        P(b_lim(v) <= b) at the points, arrays (n_p,).
    b_min : Estimate
        Mean of the smallest limit over the speed range, m.
    b_min_quantiles : Estimate
        Its quantiles at ``quantile_levels``, m.
    sobol : dict
        ``output -> (first, total)`` Estimates over the factors (outputs
        ``"b_min"`` and ``"chatter@k"`` for point k); empty without
        sensitivity.
    factor_names : tuple of str
    samples : ndarray (R, n, n_all)
        Every sample's limit at every speed computed (:attr:`all_speeds`),
        by replicate: the data of every estimate.
    inputs : ndarray (R, n, p)
        Every sample's values of the uncertain fields (:attr:`paths`).
    sample_min, sample_abs_min : ndarray (R, n)
        Every sample's smallest limit over the speed range, and over all
        speeds (the asymptote of its lobes; nan where the route has none).
    """

    speed: np.ndarray
    width: np.ndarray
    p_stable: Estimate
    quantile_levels: np.ndarray
    quantiles: Estimate
    nominal: Any
    points: np.ndarray
    p_chatter: Estimate
    b_min: Estimate
    b_min_quantiles: Estimate
    sobol: dict[str, tuple[Estimate, Estimate]]
    factor_names: tuple[str, ...]
    samples: np.ndarray
    inputs: np.ndarray
    paths: tuple[str, ...]
    sample_min: np.ndarray
    sample_abs_min: np.ndarray
    all_speeds: np.ndarray
    level: float
    method: str
    replicates: int
    rows: int
    seed: int
    distributions: tuple[str, ...]
    tol: float | None = None
    stop: str = ""
    error: float = float("nan")
    stages: tuple[int, ...] = ()  #: samples after each stage of the run
    errors: tuple[float, ...] = ()  #: the stopping rule's error after each stage
    n_failed: int = 0
    n_contradicted: int = 0
    #: sample diagrams that establish nothing at some speed (NaN there: undetermined, never stable)
    n_undetermined: int = 0
    n_unverified: int = 0
    n_checked: int = 0
    elapsed: float = 0.0
    checkpoint: str | None = None
    shared: bool = False
    evaluations: int = 0
    meta: dict[str, Any] = field(default_factory=dict)

    # ------------------------------------------------------------------ construction
    @classmethod
    def build(
        cls,
        *,
        nominal: Any,
        space: Any,
        design: Any,
        rows: int,
        data: dict[str, np.ndarray],
        all_speeds: np.ndarray,
        speeds: np.ndarray,
        widths: np.ndarray,
        quantile_levels: np.ndarray,
        points: np.ndarray,
        level: float,
        inputs: np.ndarray,
        **info: Any,
    ) -> ProbabilisticLobes:
        """The estimates from the samples' outputs ``data`` (name -> (R,
        matrices, rows, speeds)) of :func:`chatterlab.uncertainty.risk`."""
        R = design.replicates
        grid = np.searchsorted(all_speeds, speeds)
        b = data["b_lim"][:, 0]  # (R, n, n_all): the matrix A
        p_st = replicate_estimate(p_stable_replicates(b[:, :, grid], widths), level)
        qs = quantile_estimate(b[:, :, grid], quantile_levels, level)
        pj = np.searchsorted(all_speeds, points[:, 0]) if points.size else np.zeros(0, int)
        chatter = b[:, :, pj] <= points[None, None, :, 1]
        # a sample whose limit is NaN there (nothing established, or failed) makes the point undetermined
        p_pt = np.where(np.isnan(b[:, :, pj]).any(axis=1), np.nan, chatter.mean(axis=1))
        p_ch = replicate_estimate(p_pt.reshape(R, -1), level)
        bmin = data["b_min"][:, 0, :, 0]  # (R, n)
        with np.errstate(invalid="ignore"):
            b_mean = replicate_estimate(bmin.mean(axis=1), level)
        b_q = quantile_estimate(bmin, quantile_levels, level)
        sob: dict[str, tuple[Estimate, Estimate]] = {}
        if design.sensitivity:
            allb = data["b_min"][:, :, :, 0]  # (R, M, n)
            sob["b_min"] = sobol_indices(allb[:, 0], allb[:, 1], np.moveaxis(allb[:, 2:], 1, 0), level)
            for k, j in enumerate(pj):
                ind = (data["b_lim"][:, :, :, j] <= points[k, 1]).astype(float)  # (R, M, n)
                sob[f"chatter@{k}"] = sobol_indices(
                    ind[:, 0], ind[:, 1], np.moveaxis(ind[:, 2:], 1, 0), level
                )
        from ..selection._recommend import UNTRUSTED_CLAIMS  # the claims that establish nothing (one place)

        ver = data["verified"][..., 0]
        claim = data["claim"]
        return cls(
            speed=np.asarray(speeds, float),
            width=np.asarray(widths, float),
            p_stable=p_st,
            quantile_levels=np.asarray(quantile_levels, float),
            quantiles=qs,
            nominal=nominal,
            points=np.asarray(points, float).reshape(-1, 2),
            p_chatter=p_ch,
            b_min=b_mean,
            b_min_quantiles=b_q,
            sobol=sob,
            samples=b,
            inputs=np.asarray(inputs, float),
            paths=space.paths,
            sample_min=bmin,
            sample_abs_min=data["b_abs_min"][:, 0, :, 0],
            all_speeds=np.asarray(all_speeds, float),
            level=level,
            method=design.method,
            replicates=R,
            rows=rows,
            seed=design.seed,
            distributions=tuple(space.describe()),
            n_contradicted=int(np.sum(np.any(claim == 3, axis=-1))),
            n_undetermined=int(np.sum(np.any(np.isin(claim, UNTRUSTED_CLAIMS), axis=-1))),
            n_unverified=int(np.sum(ver == 0)),
            n_checked=int(np.sum(np.isfinite(ver))),
            evaluations=int(np.prod(ver.shape)),
            **info,
        )

    # ------------------------------------------------------------------ names
    @property
    def process(self) -> Any:
        return self.nominal.process

    @property
    def speed_unit(self) -> str:
        return self.nominal.speed_unit

    @property
    def limit_name(self) -> str:
        return self.nominal.limit_name

    @property
    def n_samples(self) -> int:
        """Samples of the input distribution (R n)."""
        return self.replicates * self.rows

    @property
    def p_chatter_map(self) -> np.ndarray:
        """1 - P(stable) on the (speed, width) grid."""
        return 1.0 - np.asarray(self.p_stable.value)

    # ------------------------------------------------------------------ queries
    def _speed_index(self, speed: float) -> int:
        j = int(np.argmin(np.abs(self.all_speeds - speed)))
        if not np.isclose(self.all_speeds[j], speed, rtol=1e-12, atol=0):
            raise InputError(
                f"speed {speed:g} {self.speed_unit} was not computed: give it to risk() (speeds or points);"
                f" computed: {self.all_speeds.min():g} .. {self.all_speeds.max():g} {self.speed_unit}"
            )
        return j

    def p_chatter_at(self, speed: float, width: float) -> Estimate:
        """P(b_lim(speed) <= width) from the samples, at a computed speed
        (process unit) and any width (m)."""
        j = self._speed_index(speed)
        ind = self.samples[:, :, j] <= width
        return replicate_estimate(ind.mean(axis=1), self.level)

    def safe_width(self, risk: float, *, conservative: bool = True) -> np.ndarray:
        """The largest width (m) at each speed of :attr:`speed` whose
        probability of chatter is at most ``risk``.

        P(chatter) at b is P(b_lim <= b), a step function of b that rises
        at each sample's limit; the width returned is the largest float
        below the first sample limit s_k at which the estimate (with
        ``conservative``: the upper end of its confidence interval, at
        least -ln(1 - level)/N -- the rule of three) would exceed ``risk``.
        So every width up to it has an estimated probability of chatter at
        most ``risk`` -- on the safe side of the sampling error with
        ``conservative``.  0 where no width is safe enough (too few samples
        to claim the risk, or a sample establishes nothing at that speed), inf
        where every width up to the ceiling is."""
        from ._estimate import t_factor

        if not 0 < risk < 1:
            raise InputError(f"risk must lie between 0 and 1 (got {risk:g})")
        grid = np.searchsorted(self.all_speeds, self.speed)
        R, n = self.replicates, self.rows
        t = t_factor(R, self.level)
        floor = -np.log(1.0 - self.level) / (R * n)
        out = np.zeros(grid.size)
        for i, j in enumerate(grid):
            b = self.samples[:, :, j]
            if np.isnan(b).any():  # a sample establishes nothing here: no width is claimed safe
                continue
            # the estimate is a step function: on [s_(k-1), s_k) it is P(b_lim < s_k) (s_-1 = 0, s_K = inf)
            edges = np.append(np.unique(b[np.isfinite(b)]), np.inf)
            reps = np.sort(b, axis=1)
            p = np.stack([np.searchsorted(reps[r], edges, side="left") for r in range(R)]) / n
            est = p.mean(axis=0)
            if conservative:
                est = np.maximum(est + t * p.std(axis=0, ddof=1) / np.sqrt(R), floor)
            bad = np.nonzero(est > risk)[0]
            if bad.size == 0:
                out[i] = np.inf  # safe up to the ceiling
            else:
                out[i] = np.nextafter(edges[bad[0] - 1], 0.0) if bad[0] > 0 else 0.0
        return out

    def risk_limit(self, risk: float, *, conservative: bool = True) -> RiskLimit:
        """:meth:`safe_width` as a :class:`RiskLimit`: a plug-in width limit
        for a speed recommendation (``recommend(model, limits=[res.risk_limit(0.01)],
        margin=0)``: the stability limit becomes the 1 % risk lobe)."""
        w = self.safe_width(risk, conservative=conservative)
        return RiskLimit(
            f"P(chatter) <= {100 * risk:g} % ({self.n_samples} samples)", np.asarray(self.speed, float), w
        )

    def recommend(self, risk: float, *, count: int = 3, conservative: bool = True) -> list[dict[str, float]]:
        """The best operating points at a risk: the tops of the ``risk``
        lobe (:meth:`safe_width`) -- its local maxima over speed, highest
        first -- each with its width (m), speed and estimated probability
        of chatter (and the interval's upper end) there (a width at the
        ceiling: safe as far as the diagram searched)."""
        w = np.minimum(self.safe_width(risk, conservative=conservative), float(self.nominal.width_max))
        fin = w
        peaks = [
            j
            for j in range(fin.size)
            if (j == 0 or fin[j] >= fin[j - 1]) and (j == fin.size - 1 or fin[j] > fin[j + 1])
        ]
        peaks.sort(key=lambda j: -fin[j])
        out = []
        for j in [j for j in peaks if w[j] > 0][:count]:  # a top at 0: nothing is safe there
            e = self.p_chatter_at(float(self.speed[j]), float(w[j]))
            out.append(
                {
                    "speed": float(self.speed[j]),
                    "width": float(w[j]),
                    "p_chatter": float(e.value),
                    # the interval's upper end, never below the rule of three (none of N samples chattered)
                    "p_chatter_high": max(float(e.high), -np.log(1.0 - self.level) / self.n_samples),
                }
            )
        return out

    # ------------------------------------------------------------------ words
    def _nominal_minimum(self) -> float:
        """The nominal diagram's smallest limit, NaN (undetermined) where it
        establishes nothing at some speed (selection's ``stable_width``)."""
        from ..selection._recommend import stable_width

        known = np.isfinite(stable_width(self.nominal)[0]).all()
        return float(self.nominal.minimum["width"]) if known else float("nan")

    def summary(self) -> str:
        """What the run says, in words (mm and the process's speed unit)."""
        u = self.speed_unit
        lines = [
            f"probabilistic lobes of {self.nominal.model}: {self.n_samples} samples ({self.replicates}"
            f" replicates x {self.rows}, {'scrambled Sobol' + chr(39) + ' points' if self.method == 'qmc' else 'Monte Carlo'},"
            f" seed {self.seed}), {self.speed.size} speeds {_v(self.speed.min(), u)} .. {_v(self.speed.max(), u)},"
            f" {self.elapsed:.1f} s",
        ]
        lines += [f"  {d}" for d in self.distributions]
        lim = self.limit_name
        half = self.b_min.half_width
        lines.append(
            f"  smallest {lim} over the speeds: mean {_mm(self.b_min.value)} +- {_mm(half)},"
            + " ".join(
                f" {100 * q:g} %: {_mm(x)}"
                for q, x in zip(self.quantile_levels, np.asarray(self.b_min_quantiles.value), strict=True)
            )
            + f" (nominal {_mm(self._nominal_minimum())})"
        )
        qv = np.asarray(self.quantiles.value)
        for q, row in zip(self.quantile_levels, qv, strict=True):
            fin = np.isfinite(row)
            if fin.any():
                j = int(np.argmax(np.where(fin, row, -np.inf)))
                lines.append(
                    f"  {100 * q:g} % lobe: lowest {_mm(np.nanmin(np.where(fin, row, np.nan)))}, highest"
                    f" {_mm(row[j])} at {_v(self.speed[j], u)}"
                )
        for k, (v, b) in enumerate(self.points):
            e = self.p_chatter
            lines.append(
                f"  P(chatter) at {_v(v, u)}, {_mm(b)}: {float(e.value[k]):.4f} (interval"
                f" {max(float(e.low[k]), 0.0):.4f} .. {min(float(e.high[k]), 1.0):.4f} at {100 * self.level:g} %)"
                if np.isfinite(e.value[k])
                else f"  P(chatter) at {_v(v, u)}, {_mm(b)}: undetermined (a sample's diagram establishes nothing"
                " at this speed)"
            )
        for out, (s1, st) in self.sobol.items():
            what = f"smallest {lim}" if out == "b_min" else f"chatter at point {int(out.split('@')[1]) + 1}"
            order = np.argsort(-np.nan_to_num(np.asarray(st.value), nan=-1.0))
            lines.append(f"  Sobol' indices of the {what} (first order, total, +- their interval):")
            for i in order:
                lines.append(
                    f"    {self.factor_names[i]}: S1 {float(s1.value[i]):.3f} +- {float(s1.half_width[i]):.3f},"
                    f" ST {float(st.value[i]):.3f} +- {float(st.half_width[i]):.3f}"
                )
        ver = (
            f"{self.n_checked - self.n_unverified}/{self.n_checked} sample diagrams verified by the argument"
            " principle"
            if self.n_checked
            else "the samples' diagrams carry no argument-principle checks on this route"
        )
        lines.append(
            f"  {ver}"
            + (
                f"; {self.n_contradicted} contradicted by a check (CHECK FAILED)"
                if self.n_contradicted
                else ""
            )
            + (f"; {self.n_failed} failed tasks (NaN)" if self.n_failed else "")
            + (
                f"; {self.n_undetermined} establish nothing at some speeds (no boundary in a band not proven,"
                " contradicted, or zeroth-order): the estimates there are undetermined (NaN), never stable"
                if self.n_undetermined
                else ""
            )
        )
        lines.append(f"  stop: {self.stop}")
        return "\n".join(lines)

    # ------------------------------------------------------------------ files
    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """``(coords, data, attrs)``: the probability map on (speed, width),
        the quantile lobes on (quantile, speed), the points, the Sobol'
        indices on (factor,), every sample's limit on (sample, speed); the
        sample count, the errors and the run as attributes."""
        lim = self.limit_name
        u = self.speed_unit
        grid = np.searchsorted(self.all_speeds, self.speed)
        R, n = self.replicates, self.rows
        coords: dict[str, Any] = {
            "speed": (self.speed, u, str(self.process.speed_name)),
            "width": (self.width, "m", "width of cut b (milling: axial depth)"),
            "quantile": (self.quantile_levels, "1", "probability level of the quantile lobe"),
            "sample": (np.arange(R * n), "1", "sample index (replicate-major)"),
            "field": (np.arange(len(self.paths)), "1", "uncertain field (attribute fields)"),
        }
        ps = self.p_stable
        data: dict[str, Any] = {
            "p_stable": (ps.value, "1", "P(b < limit): probability that every width up to b is chatter-free", ("speed", "width")),
            "p_stable_se": (ps.se, "1", "standard error of p_stable (from the replicates)", ("speed", "width")),
            "p_stable_low": (ps.low, "1", f"lower end of the {100 * self.level:g} % interval of p_stable", ("speed", "width")),
            "p_stable_high": (ps.high, "1", f"upper end of the {100 * self.level:g} % interval of p_stable", ("speed", "width")),
            f"{lim}_quantile": (self.quantiles.value, "m", f"quantile lobe of {lim}", ("quantile", "speed")),
            f"{lim}_quantile_se": (self.quantiles.se, "m", "standard error of the quantile lobe", ("quantile", "speed")),
            f"{lim}_nominal": (np.asarray(self.nominal.b_lim)[grid], "m", f"{lim} of the model as written", ("speed",)),
            f"{lim}_sample": (self.samples[:, :, grid].reshape(R * n, -1), "m", f"{lim} of each sample", ("sample", "speed")),
            "replicate": (np.repeat(np.arange(R), n), "1", "replicate of each sample", ("sample",)),
            "inputs": (self.inputs.reshape(R * n, -1), "", "the uncertain fields' values of each sample"
                       " (attribute fields; SI)", ("sample", "field")),
            f"{lim}_sample_min": (self.sample_min.reshape(-1), "m", f"smallest {lim} of each sample over the"
                                  " speed range", ("sample",)),
        }  # fmt: skip
        if self.points.size:
            coords["point"] = (np.arange(self.points.shape[0]), "1", "operating point")
            e = self.p_chatter
            data.update(
                {
                    "point_speed": (self.points[:, 0], u, "speed of the operating point", ("point",)),
                    "point_width": (self.points[:, 1], "m", "width of the operating point", ("point",)),
                    "p_chatter": (e.value, "1", "P(limit <= width) at the point", ("point",)),
                    "p_chatter_se": (e.se, "1", "standard error of p_chatter", ("point",)),
                    "p_chatter_low": (e.low, "1", "lower end of the interval of p_chatter", ("point",)),
                    "p_chatter_high": (e.high, "1", "upper end of the interval of p_chatter", ("point",)),
                }
            )
        if self.sobol:
            coords["factor"] = (
                np.arange(len(self.factor_names)),
                "1",
                "independent factor (attribute factors)",
            )
            for out, (s1, st) in self.sobol.items():
                tag = out.replace("@", "_")
                for nm, e in (("first", s1), ("total", st)):
                    data[f"sobol_{nm}_{tag}"] = (
                        e.value,
                        "1",
                        f"{nm}-order Sobol' index of {out}",
                        ("factor",),
                    )
                    data[f"sobol_{nm}_{tag}_se"] = (e.se, "1", "its standard error", ("factor",))
        attrs = {
            "title": "chatterlab probabilistic stability lobe diagram",
            "model": str(self.nominal.model),
            "process": str(self.process.kind),
            "limit": lim,
            "n_samples": self.n_samples,
            "replicates": R,
            "rows_per_replicate": n,
            "method": "randomised QMC (scrambled Sobol')" if self.method == "qmc" else "Monte Carlo",
            "seed": self.seed,
            "confidence_level": self.level,
            "error": self.error,
            "error_meaning": "half-width of the confidence interval of P(chatter) at the points (without points:"
            " the largest over the probability map), at least -ln(1 - level)/N",
            "tol": float("nan") if self.tol is None else self.tol,
            "stop": self.stop,
            "stages": list(self.stages),
            "stage_errors": list(self.errors),
            "max_p_stable_se": float(np.nanmax(ps.se)) if np.size(ps.se) else float("nan"),
            f"min_{lim}_mean_m": float(self.b_min.value),
            f"min_{lim}_se_m": float(self.b_min.se),
            "width_max_m": float(self.nominal.width_max),
            "distributions": json.dumps(list(self.distributions)),
            "factors": json.dumps(list(self.factor_names)),
            "fields": json.dumps(list(self.paths)),
            "n_failed": self.n_failed,
            "n_contradicted": self.n_contradicted,
            "n_undetermined": self.n_undetermined,
            "n_verified": self.n_checked - self.n_unverified,
            "n_checked": self.n_checked,
            "evaluations": self.evaluations,
            "shared_structure": str(self.shared),
        }
        return coords, data, attrs

    def to_csv(self, path: Any) -> Path | None:
        """One row per (speed, width): ``speed``, ``width [m]``, ``p_stable``
        with its standard error and interval, then on every row of a speed
        that speed's quantile lobes (``b_lim_quantile_0.05 [m]`` ...: the
        netCDF variable and the level) with their standard errors and the nominal limit; exact floats, written
        atomically.  (The samples, points and Sobol' indices are in the
        netCDF file.)"""
        from ..io import write_csv

        coords, data, _ = self.dataset_parts()
        nb = self.width.size
        lim = self.limit_name
        out: dict[str, Any] = {
            k: data[k][:3] for k in ("p_stable", "p_stable_se", "p_stable_low", "p_stable_high")
        }
        for i, q in enumerate(self.quantile_levels):
            # a variable over quantiles: one column per level, the netCDF name and the level
            for key in (f"{lim}_quantile", f"{lim}_quantile_se"):
                vals = np.asarray(data[key][0])[i]
                out[f"{key}_{q:g}"] = (np.repeat(vals[:, None], nb, axis=1), "m", f"{q:g} quantile")
        out[f"{lim}_nominal"] = (
            np.repeat(np.asarray(data[f"{lim}_nominal"][0])[:, None], nb, axis=1),
            "m",
            "nominal",
        )
        return write_csv(path, {"speed": coords["speed"], "width": coords["width"]}, out)

    def plot(
        self, ax: Any = None, *, risk: float | None = None, title: str | None = None, **style: Any
    ) -> Any:
        """The probability of chatter over (speed, width) with the quantile
        lobes, the nominal lobe, the operating points and, with ``risk``,
        the risk contour (:func:`chatterlab.plot.plot_risk`); returns the Axes."""
        from ..plot import plot_risk

        return plot_risk(self, ax=ax, risk=risk, title=title, **style)

    def plot_sensitivity(self, ax: Any = None, *, output: str = "b_min", **style: Any) -> Any:
        """The Sobol' indices of ``output`` as bars (:func:`chatterlab.plot.plot_sobol`)."""
        from ..plot import plot_sobol

        return plot_sobol(self, ax=ax, output=output, **style)


def _mm(x: Any) -> str:
    x = float(x)
    return (
        f"{x * 1e3:.4g} mm"
        if np.isfinite(x)
        else ("inf" if x > 0 else "undetermined" if np.isnan(x) else "nan")
    )


def _v(v: float, unit: str) -> str:
    return f"{v:.0f} {unit}" if unit == "rpm" else f"{v:.5g} {unit}"
