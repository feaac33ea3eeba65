"""Exact sensitivities of the stability limit to the fields of a model.

:func:`sensitivity` draws the lobe diagram (:func:`chatterlab.lobes.lobes`),
polishes its critical points (:mod:`chatterlab.design._limits`) and, for
every field, differentiates the loop's matrices
(:mod:`chatterlab.design._matrices`) and the boundary equation at each
critical point (:mod:`chatterlab.design._critical`): the derivative of
b_lim at every speed, of the minimum over the speed range and of the
absolute minimum over all speeds.  The result, :class:`Sensitivity`, ranks
the fields by how much they raise the minimum limit per unit change and
per relative change, and writes CSV and netCDF.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from ..errors import InputError, check_width
from ..io import Result
from ..model import Model
from ..structure import assemble
from ._controlled import design_lobes
from ._fields import design_fields, field_value
from ._limits import limits_of
from ._matrices import FieldDerivative, field_derivative, loop_matrices

__all__ = ["Sensitivity", "sensitivity"]

#: the limits a table ranks by: the minimum over the speed range, the absolute minimum over all speeds
LIMITS = ("minimum", "absolute")


@dataclass(frozen=True, eq=False)
class Sensitivity(Result):
    """Derivatives of the stability limit with respect to model fields.

    Attributes
    ----------
    fields, units, values, methods
        The parameter paths, their units, their values in the model and how
        the loop's matrices were differentiated (``"affine"``: one exact
        difference; ``"central"``: the central difference with the derived step).
    speed : ndarray (n,)
        The speeds of the study (process unit); ``b_lim`` (m) at them.
    d_b_lim : ndarray (n_fields, n)
        db_lim/dp at every speed, m per field unit (nan where b_lim is inf).
    minimum, absolute_minimum : dict
        The minimum over the speed range (``width`` m, ``speed``,
        ``chatter_hz``, ``at``: "bottom", "end" or "static") and over all
        speeds (``width``, ``chatter_hz``), polished to round-off.
    d_minimum, d_absolute : ndarray (n_fields,)
        Their derivatives, m per field unit.
    err_minimum, err_absolute : ndarray (n_fields,)
        Error estimates of those, propagated from the matrices' derivatives:
        their truncation error (none for an affine field; for a non-affine
        one its leading term, from a third difference) plus a bound of their
        round-off.
    degenerate : bool
        Two boundaries meet at the minimum (a symmetric structure): the
        minimum has no derivative there (d_* are nan).
    diagram : LobeDiagram
        The lobe diagram the critical points come from.

    Files through the result protocol (:class:`chatterlab.io.Result`):
    :meth:`to_csv` (the ranked table), ``to_netcdf``, ``to_xarray`` and
    ``to_json`` from :meth:`dataset_parts`.
    """

    model: str
    fields: tuple[str, ...]
    units: tuple[str, ...]
    values: np.ndarray
    methods: tuple[str, ...]
    speed: np.ndarray
    speed_unit: str
    b_lim: np.ndarray
    d_b_lim: np.ndarray
    minimum: dict[str, Any]
    absolute_minimum: dict[str, Any]
    d_minimum: np.ndarray
    d_absolute: np.ndarray
    err_minimum: np.ndarray
    err_absolute: np.ndarray
    degenerate: bool
    position: float | None
    diagram: Any = field(repr=False)
    elapsed: float = 0.0
    evaluations: int = 0

    # ------------------------------------------------------------------ views
    def derivative(self, limit: str = "minimum") -> np.ndarray:
        """d limit / dp (m per field unit) for ``limit`` in :data:`LIMITS`."""
        _check_limit(limit)
        return self.d_minimum if limit == "minimum" else self.d_absolute

    def width(self, limit: str = "minimum") -> float:
        _check_limit(limit)
        return float((self.minimum if limit == "minimum" else self.absolute_minimum)["width"])

    def relative(self, limit: str = "minimum") -> np.ndarray:
        """p d limit / dp, m: the change of the limit per 100 % change of the
        field (to first order); divided by the limit, the elasticity."""
        return self.values * self.derivative(limit)

    def ranked(self, by: str = "relative", limit: str = "minimum") -> np.ndarray:
        """Field indices, the one that raises ``limit`` most first: by
        ``p d/dp`` (``by="relative"``) or by ``d/dp`` (``"unit"``: per unit
        of each field's own unit; compare fields of the same unit)."""
        if by not in ("relative", "unit"):
            raise InputError(f"by must be 'relative' or 'unit' (got {by!r})")
        key = self.relative(limit) if by == "relative" else self.derivative(limit)
        return np.argsort(-np.nan_to_num(key, nan=-np.inf), kind="stable")

    def table(self, by: str = "relative", limit: str = "minimum", count: int | None = None) -> str:
        """The ranked table: which field raises the limit most (text)."""
        b = self.width(limit)
        d = self.derivative(limit)
        err = self.err_minimum if limit == "minimum" else self.err_absolute
        what = "minimum over the speed range" if limit == "minimum" else "absolute minimum (all speeds)"
        lines = [
            f"sensitivity of the {what} of {self.model}: {b * 1e3:.6g} mm"
            + (f" at {self.minimum['speed']:.6g} {self.speed_unit}" if limit == "minimum" else "")
            + f", chatter {(self.minimum if limit == 'minimum' else self.absolute_minimum)['chatter_hz']:.2f} Hz",
            f"  ranked by {'p db/dp (per relative change)' if by == 'relative' else 'db/dp (per unit change)'};"
            " elasticity = (p/b) db/dp",
            f"  {'rank':>4}  {'field':<34} {'value':>12} {'unit':<9} {'db/dp [m/unit]':>15}"
            f" {'p db/dp [mm]':>13} {'elasticity':>11} {'rel. error':>10}",
        ]
        order = self.ranked(by, limit)
        for r, i in enumerate(order[: count or len(order)], start=1):
            rel = err[i] / abs(d[i]) if d[i] != 0 and np.isfinite(d[i]) else np.nan
            lines.append(
                f"  {r:>4}  {self.fields[i]:<34} {self.values[i]:>12.5g} {self.units[i] or '-':<9}"
                f" {d[i]:>15.6g} {self.values[i] * d[i] * 1e3:>13.5g} {self.values[i] * d[i] / b:>11.4g}"
                f" {rel:>10.1e}"
            )
        if self.degenerate:
            lines.append("  two boundaries meet at the minimum: it has no derivative (nan)")
        return "\n".join(lines)

    # ------------------------------------------------------------------ files
    def columns(self) -> list[tuple[str, str, np.ndarray, str]]:
        """Per-field data ``(name, unit, values, what)`` of the CSV and netCDF."""
        bm, ba = self.width("minimum"), self.width("absolute")
        return [
            ("value", "", self.values, "the field's value in the model (its own unit: see field_units)"),
            ("d_minimum", "m/unit", self.d_minimum, "d(minimum b_lim over the speed range)/dp"),
            ("p_d_minimum", "m", self.values * self.d_minimum, "p d(minimum)/dp: change per 100 % of p"),
            ("elasticity_minimum", "1", self.values * self.d_minimum / bm, "(p/b_min) db_min/dp"),
            ("error_minimum", "m/unit", self.err_minimum, "error estimate of d_minimum (upper bound)"),
            ("d_absolute", "m/unit", self.d_absolute, "d(absolute minimum over all speeds)/dp"),
            ("p_d_absolute", "m", self.values * self.d_absolute, "p d(absolute minimum)/dp"),
            ("elasticity_absolute", "1", self.values * self.d_absolute / ba, "(p/b_abs) db_abs/dp"),
            ("error_absolute", "m/unit", self.err_absolute, "error estimate of d_absolute (upper bound)"),
        ]

    def to_csv(self, path: Any) -> Any:
        """One row per field, ranked by p d(minimum)/dp: ``rank``, ``field``,
        ``field_unit``, then :meth:`columns`; every number as the shortest decimal
        that reads back to the same double; written atomically.  Returns the
        path."""
        import csv
        from pathlib import Path

        from ..io import text_out

        cols = self.columns()
        with text_out(path) as fh:
            w = csv.writer(fh, lineterminator="\n")
            w.writerow(
                ["rank", "field", "field_unit"]
                + [f"{n} [{'-' if u in ('1', '') else u}]" for n, u, _, _ in cols]
            )
            for r, i in enumerate(self.ranked(), start=1):
                w.writerow(
                    [r, self.fields[i], self.units[i] or "-"] + [repr(float(v[i])) for _, _, v, _ in cols]
                )
        return Path(path) if not hasattr(path, "write") else path

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """``(coords, data, attrs)`` of :meth:`to_xarray` / :meth:`to_netcdf`:
        coordinates ``field`` (index into the ``fields`` attribute) and
        ``speed``; per-field columns, ``b_lim(speed)`` and
        ``d_b_lim(field, speed)``."""
        import json

        coords = {
            "field": (np.arange(len(self.fields)), "1", "index into the 'fields' attribute"),
            "speed": (self.speed, self.speed_unit, str(self.diagram.speed_name)),
        }
        data: dict[str, Any] = {n: (v, u, what, ("field",)) for n, u, v, what in self.columns()}
        rank = np.empty(len(self.fields), dtype=float)
        rank[self.ranked()] = np.arange(1, len(self.fields) + 1)
        data["rank"] = (rank, "1", "rank by p d(minimum)/dp (1: raises the minimum most)", ("field",))
        data["b_lim"] = (self.b_lim, "m", "limit width at each speed", ("speed",))
        data["d_b_lim"] = (self.d_b_lim, "m/unit", "db_lim/dp at each speed", ("field", "speed"))
        attrs = {
            "title": "chatterlab sensitivities of the stability limit",
            "model": self.model,
            "fields": json.dumps(list(self.fields)),
            "field_units": json.dumps(list(self.units)),
            "methods": json.dumps(list(self.methods)),
            "position_m": float("nan") if self.position is None else self.position,
            "min_b_lim_m": self.width("minimum"),
            "min_b_lim_speed": float(self.minimum["speed"]),
            "min_b_lim_chatter_hz": float(self.minimum["chatter_hz"]),
            "min_b_lim_at": str(self.minimum["at"]),
            "absolute_min_b_lim_m": self.width("absolute"),
            "absolute_min_chatter_hz": float(self.absolute_minimum["chatter_hz"]),
            "degenerate": str(self.degenerate),
        }
        return coords, data, attrs

    def plot(self, ax: Any = None, *, by: str = "relative", limit: str = "minimum", count: int = 15) -> Any:
        """The ranked bar chart (:func:`chatterlab.plot.plot_sensitivity`); returns the Axes."""
        from ..plot import plot_sensitivity

        d = self.derivative(limit)
        vals = self.values * d if by == "relative" else d
        big = np.argsort(-np.abs(np.nan_to_num(vals)), kind="stable")[:count]  # the largest effects,
        order = [i for i in self.ranked(by, limit) if i in set(big.tolist())]  # raising first
        b = self.width(limit)
        return plot_sensitivity(
            [self.fields[i] for i in order],
            vals[order] / b if by == "relative" else vals[order],
            ax=ax,
            xlabel=(
                f"elasticity (p / b) db/dp of the {'minimum' if limit == 'minimum' else 'absolute minimum'}"
                " (% per %)"
                if by == "relative"
                else "db/dp, m per unit of the field"
            ),
            units=[self.units[i] for i in order] if by == "unit" else None,
            title=f"{self.model}: {'b_min' if limit == 'minimum' else 'absolute b_min'} = {b * 1e3:.4g} mm",
        )


def _check_limit(limit: str) -> None:
    if limit not in LIMITS:
        raise InputError(f"limit must be one of {', '.join(LIMITS)} (got {limit!r})")


def sensitivity(
    model: Model,
    speeds: Any,
    *,
    fields: list[str] | None = None,
    position: float | None = None,
    width_max: float = 0.02,
    terms: Literal["pdo", "o"] = "pdo",
    couplings: list[str] | None = None,
    n_frequencies: int | None = None,
    verify: int = 0,
    per_speed: bool = True,
) -> Sensitivity:
    """Exact derivatives of the stability limit with respect to model fields.

    Parameters
    ----------
    model : Model
        From :func:`chatterlab.load_model` (its fields are changed by
        :meth:`Model.with_parameter`).
    speeds : array
        Cutting speeds (process unit) of the lobe diagram; the minimum is
        taken over their range.
    fields : list of str, optional
        Parameter paths (``spring.holder.c1``); default
        :func:`~chatterlab.design.design_fields` (every number of the file
        for bodies, beams, springs, couplings, absorbers and modes, and the
        damping of every joint direction with a stiffness).
    position, width_max, terms, couplings, n_frequencies, verify
        As for :func:`chatterlab.lobes.lobes` (verify 0: no argument-principle
        checks, the derivatives do not need them).
    per_speed : bool
        Also differentiate b_lim at every speed (``d_b_lim``).

    Returns
    -------
    Sensitivity
    """
    t0 = time.perf_counter()
    width_max = check_width(width_max, "width_max")
    paths = list(design_fields(model) if fields is None else fields)
    if not paths:
        raise InputError(f"{model.source}: no fields to differentiate; name them (fields=[...], --fields)")
    for p in paths:
        field_value(model, p)  # every path checked before the work
    frozen = assemble(model).at(position)
    diagram = design_lobes(
        frozen, np.asarray(speeds, dtype=float), width_max=width_max, terms=terms,
        n_frequencies=n_frequencies, verify=verify, couplings=couplings,
    )  # fmt: skip
    if diagram.method != "d-subdivision":
        raise InputError(
            f"{model.source}: sensitivities are for turning and shaping (D-subdivision lobes); this model's"
            f" lobes are {diagram.method}: the milling limit's derivative is not implemented"
        )
    speeds = np.asarray(diagram.speed, dtype=float)
    kw: dict[str, Any] = {
        "position": frozen.position,
        "speeds": speeds,
        "terms": terms,
        "couplings": couplings,
    }
    L = loop_matrices(model, **kw)
    lim = limits_of(diagram, L, speeds=per_speed)
    if lim.minimum is None and lim.absolute is None:
        raise InputError(
            f"{model.source}: no limit below the width ceiling {width_max * 1e3:.4g} mm, at these speeds or"
            " any other: there is no limit to differentiate; raise the ceiling (width_max=, --width-max)"
        )
    nf = len(paths)
    d_lim = np.full((nf, speeds.size), np.nan)
    d_min, d_abs, e_min, e_abs = (np.full(nf, np.nan) for _ in range(4))
    ders: list[FieldDerivative] = []
    evals = 0
    for i, p in enumerate(paths):
        fd = field_derivative(model, p, base=L, **kw)
        ders.append(fd)
        evals += fd.evaluations
        for j, cp in enumerate(lim.speeds):
            if cp is not None:
                d_lim[i, j] = cp.derivative(fd.d)
        for cp, dd, ee in ((lim.minimum, d_min, e_min), (lim.absolute, d_abs, e_abs)):
            if cp is not None:
                dd[i] = cp.derivative(fd.d)
                ee[i] = abs(dd[i] - cp.derivative(fd.alt))
                if fd.roundoff is not None:
                    ee[i] += cp.error_bound(fd.roundoff)
    mn = lim.minimum
    minimum = {
        "width": float(mn.b) if mn is not None else float("inf"),
        "speed": lim.minimum_speed,
        "chatter_hz": float(mn.frequency_hz) if mn is not None else float("nan"),
        "at": lim.minimum_at,
    }
    ab = lim.absolute
    absolute = {
        "width": float(ab.b) if ab is not None else float("inf"),
        "chatter_hz": float(ab.frequency_hz) if ab is not None else float("nan"),
    }
    degenerate = bool((mn is not None and mn.degenerate) or (ab is not None and ab.degenerate))
    return Sensitivity(
        model=str(model.name),
        fields=tuple(paths),
        units=tuple(fd.unit for fd in ders),
        values=np.array([fd.value for fd in ders]),
        methods=tuple(fd.method for fd in ders),
        speed=speeds,
        speed_unit=str(diagram.speed_unit),
        b_lim=np.array(
            [cp.b if cp is not None else b for cp, b in zip(lim.speeds, diagram.b_lim, strict=True)]
        )
        if per_speed
        else np.asarray(diagram.b_lim, dtype=float),
        d_b_lim=d_lim,
        minimum=minimum,
        absolute_minimum=absolute,
        d_minimum=d_min,
        d_absolute=d_abs,
        err_minimum=e_min,
        err_absolute=e_abs,
        degenerate=degenerate,
        position=frozen.position,
        diagram=diagram,
        elapsed=time.perf_counter() - t0,
        evaluations=evals,
    )
