"""The discretisation error of ``simulate``, ``frf``, ``sweep``, ``sle`` and ``ssv``
on a model with beams (docs/lobes.md, "The discretisation error of a result", Eqs.
M1-M5; the machinery is :mod:`chatterlab.model._mesh`, never repeated here).

* ``simulate`` of a continuous cut: the rightmost characteristic root of the
  very frozen system the run integrates, on the model's mesh and on
  :meth:`Model.with_finer_mesh`, judged by :func:`mesh_verdict`: the run's
  "no chatter" / "chatter" stands only when both meshes agree and the
  margin is larger than its error bound 2 |a_{h/2} - a_h| (Eq. M3); else it
  is ``undetermined``.  A moving slide has no frozen system: no verdict is
  claimed and the line says that nothing was checked.
* ``frf``: each resonance peak of |H| (frequency and magnitude, refined
  between grid points) on both meshes, its change and bound (Eq. M3).
* ``sweep``: the quantity recomputed on the finer mesh at the grid's most
  critical point(s) only (:func:`sweep_check`), and the line names them.
* ``sle`` of a milling model: its critical speeds (:func:`sle_picks`,
  :func:`sle_check`); ``simulate`` of a milling model: the linearised cut's
  Floquet verdict at the run's (a_p, rpm) (:func:`milling_run_check`).  A
  milling verdict's margin is the Floquet exponent ln|mu| / T (1/s).
* ``ssv``: the limit searched again at the grid's smallest limit and at up
  to :data:`SSV_FREE_CAP` points with none below the ceiling
  (:func:`ssv_picks`, :func:`ssv_check`); a contradicted claim of no
  chatter becomes NaN (``undetermined``).
* ``sle`` of a turning model: the whole runout response again on h/2, each
  verdict by the roots on both meshes and by :func:`width_verdict` on the
  limits of both (:func:`runout_check`).

The results keep their own class's files and gain the mesh facts through
:func:`meshed` (one subclass per result class, attributes ``mesh_*`` and
per-point data variables).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from ..model._mesh import (
    MeshEstimate,
    converged_tail,
    limit_line,
    mesh_record,
    mesh_verdict,
    mesh_words,
    pct,
    width_verdict,
)

__all__ = [
    "simulate_check",
    "simulate_lines",
    "frf_peaks",
    "follow_peak",
    "refine_peak",
    "frf_check",
    "frf_lines",
    "sweep_check",
    "sle_picks",
    "sle_check",
    "milling_run_check",
    "meshed",
    "ssv_picks",
    "ssv_check",
    "runout_check",
]

#: simulate's words for a verdict of the frozen system
CHATTER_WORDS = {
    "stable": "no chatter",
    "unstable": "chatter",
    "undetermined": "undetermined",
    "marginal": "marginal",
}


def simulate_check(model: Any, st: Any) -> dict[str, Any]:
    """The mesh facts of one ``simulate`` run of a model with beams (``st``:
    the :class:`~chatterlab.frequency.Stability` of its frozen system judged
    on both meshes by :func:`~chatterlab.frequency.mesh_checked`, None for a
    moving slide), as the netCDF attributes ``mesh_*`` (docs/cli.md, "Time
    histories") and ``mesh`` (the printed line)."""
    base: dict[str, Any] = mesh_record(model)
    if st is None:
        return {
            **base,
            "mesh_verdict": "none",
            "mesh": f"mesh: {mesh_words(model)}; the slide moves: no verdict is claimed, and the"
            " histories' discretisation error is not estimated (nothing was computed on a finer mesh;"
            " a frozen configuration: chatterlab roots --position S)",
        }
    m = st.mesh
    return {
        **base,
        "mesh_coarse_verdict": m["coarse_verdict"],
        "mesh_fine_verdict": m["fine_verdict"],
        "mesh_abscissa_per_s": float(st.abscissa),
        "mesh_fine_abscissa_per_s": m["fine_abscissa_per_s"],
        "mesh_abscissa_error_bound_per_s": m["abscissa_error_bound_per_s"],
        "mesh_verdict": st.verdict,
        "mesh": m["line"],
    }


def simulate_lines(facts: dict[str, Any]) -> list[str]:
    """The summary's lines of :func:`simulate_check`: the verdict (for a
    frozen system) and the mesh's line."""
    if facts["mesh_verdict"] == "none":
        return [f"  {facts['mesh']}"]
    v, c = facts["mesh_verdict"], facts["mesh_coarse_verdict"]
    head = f"  verdict: {CHATTER_WORDS[v]} (the frozen system's rightmost root {facts['mesh_abscissa_per_s']:+.4g} 1/s"
    if v == "undetermined" and c != "undetermined":
        head += f"; {CHATTER_WORDS[c]} on this mesh alone: the envelopes above are this mesh's)"
    elif v == "undetermined":
        head += ": not certified on this mesh)"
    else:
        head += ", on this mesh and on one twice as fine)"
    return [head, f"  {facts['mesh']}"]


# ---------------------------------------------------------------------------- frf

#: a peak is a local maximum of |H| at least this fraction of the pair's largest
PEAK_FLOOR = 1e-2
#: the most peaks reported per (output, input) pair (the largest)
MAX_PEAKS = 3


def frf_peaks(mag: Any) -> list[int]:
    """The grid indices of the resonance peaks of one |H| curve: interior
    local maxima of at least PEAK_FLOOR of the largest, the MAX_PEAKS
    largest, by increasing frequency."""
    mag = np.asarray(mag, float)
    if mag.size < 3 or not np.all(np.isfinite(mag)):
        return []
    i = np.nonzero((mag[1:-1] > mag[:-2]) & (mag[1:-1] >= mag[2:]))[0] + 1
    i = i[mag[i] >= PEAK_FLOOR * mag.max()]
    return sorted(int(k) for k in i[np.argsort(-mag[i])][:MAX_PEAKS])


def follow_peak(mag: Any, k: int) -> int | None:
    """The same resonance on another curve on the same grid: the local
    maximum reached by climbing ``mag`` from index ``k``; None when the
    climb ends at the end of the grid (the peak has left the range)."""
    mag = np.asarray(mag, float)
    while 0 < k < mag.size - 1:
        if mag[k - 1] > mag[k] and mag[k - 1] >= mag[k + 1]:
            k -= 1
        elif mag[k + 1] > mag[k]:
            k += 1
        else:
            return k
    return None


def refine_peak(response: Any, f: Any, k: int) -> tuple[float, float]:
    """The peak of ``response(f_hz) -> |H|`` between the grid neighbours of
    index ``k`` (golden-section search): ``(f_peak, |H|_peak)``."""
    return _golden(response, float(f[k - 1]), float(f[k + 1]))


def _golden(g: Any, a: float, b: float, tol: float = 1e-9) -> tuple[float, float]:
    """The maximum of g on [a, b] (unimodal there), to ``tol`` relative in f."""
    r = (math.sqrt(5) - 1) / 2
    c, d = b - r * (b - a), a + r * (b - a)
    gc, gd = g(c), g(d)
    while b - a > tol * abs(b):
        if gc > gd:
            b, d, gd = d, c, gc
            c = b - r * (b - a)
            gc = g(c)
        else:
            a, c, gc = c, d, gd
            d = a + r * (b - a)
            gd = g(d)
    x = 0.5 * (a + b)
    return x, float(g(x))


def frf_check(model: Any, coarse: list[list[Any]], fine: list[list[Any]], names: list[str]) -> dict[str, Any]:
    """The ``mesh`` member of ``frf --format json`` (and the printed lines):
    per (output, input) pair ``names[k]``, each peak on h (``coarse[k]``: a
    list of ``(f, |H|)``) and the same resonance on h/2 (``fine[k]``: ``(f,
    |H|)`` or None where it left the range); the change and the bound (Eq.
    M3) of the frequency and of the magnitude."""
    pairs = []
    for name, pc, pf in zip(names, coarse, fine, strict=True):
        peaks = []
        for (f1, m1), other in zip(pc, pf, strict=True):
            f2, m2 = other if other is not None else (math.nan, math.nan)
            ef, em = MeshEstimate(f1, f2), MeshEstimate(m1, m2)
            peaks.append(
                {
                    "frequency_hz": f1,
                    "fine_frequency_hz": f2,
                    "frequency_error_bound_hz": float(ef.bound),
                    "magnitude": m1,
                    "fine_magnitude": m2,
                    "magnitude_error_bound": float(em.bound),
                }
            )
        pairs.append({"pair": name, "peaks": peaks})
    return {
        **mesh_record(model, prefix=""),
        "pairs": pairs,
    }


def frf_lines(model: Any, doc: dict[str, Any]) -> list[str]:
    """One head line, then one line per pair: each peak's frequency and
    magnitude change on the mesh twice as fine and their bounds (Eq. M3)."""

    out = [
        f"mesh: {mesh_words(model)}; resonance peaks on a mesh twice as fine: the change of the peak's"
        f" frequency and magnitude, and the discretisation error of this mesh's, <= 2 |change|"
        f" (docs/lobes.md, Eq. M3){converged_tail(model)}"
    ]
    for p in doc["pairs"]:
        if not p["peaks"]:
            out.append(f"  {p['pair']}: no resonance peak inside the frequency range")
            continue
        parts = []
        for k in p["peaks"]:
            if not math.isfinite(k["fine_frequency_hz"]):
                parts.append(
                    f"{k['frequency_hz']:.2f} Hz: not found again on the finer mesh (it left the range or merged"
                    " with another peak): no estimate"
                )
                continue
            df = k["fine_frequency_hz"] - k["frequency_hz"]
            dm = (k["fine_magnitude"] - k["magnitude"]) / k["magnitude"]
            parts.append(
                f"{k['frequency_hz']:.2f} Hz {df:+.3g} Hz (err <= {k['frequency_error_bound_hz']:.2g} Hz),"
                f" |H| {pct(dm, '+')} (err <= {pct(k['magnitude_error_bound'] / k['magnitude'])})"
            )
        out.append(f"  {p['pair']}: " + "; ".join(parts))
    return out


# ---------------------------------------------------------------------------- sweep


def sweep_check(task: Any, grid: Any, res: Any) -> dict[str, Any] | None:
    """The sweep's quantity recomputed on the mesh twice as fine at its most
    critical point(s), or None (no beams, or nothing to check).

    * ``stable``, ``rightmost-root``: the stable point nearest the boundary
      (the largest negative abscissa) and the unstable one nearest it (the
      smallest positive), each judged by :func:`mesh_verdict`; a checked
      ``stable`` point that becomes undetermined is set to NaN;
    * ``b-lim``, ``min-b-lim``, ``a-lim``: the point of the smallest
      (finite) limit, by :func:`limit_line`;
    * ``natural-frequencies``: the point of the lowest f1, f1 to f3 there.

    Returns the attributes (``mesh_*``, ``mesh``: the line) and, under the
    key ``_set_nan``, the flat indices whose ``stable`` became NaN."""
    import dataclasses

    model = task.model
    if not model.beams:
        return None
    fine_task = dataclasses.replace(task, model=model.with_finer_mesh())
    q = task.quantity
    names = list(grid.names)
    shape = grid.shape

    def point(flat: int) -> dict[str, float]:
        idx = np.unravel_index(flat, shape)
        return {n: float(np.asarray(ax.values)[i]) for n, ax, i in zip(names, grid.axes, idx, strict=True)}

    def where(p: dict[str, float]) -> str:
        return ", ".join(
            f"{n} {v * 1e3:.4g} mm" if n == "width" else f"{task.aliases.get(n, n)} {v:.6g}"
            for n, v in p.items()
        )

    ok = np.asarray(res.task_status).reshape(-1) == 0 if res.task_status is not None else True
    base = {
        **mesh_record(model),
        "mesh_points_checked": 0,
        "mesh_points": int(grid.size),
    }
    if q in ("stable", "rightmost-root", "spectral-radius"):
        if q == "spectral-radius":  # ln|mu|: its sign is the verdict's; per period, the margin below
            with np.errstate(divide="ignore", invalid="ignore"):
                a = np.log(np.asarray(res.data["spectral_radius"], float).reshape(-1))
        else:
            a = np.asarray(res.data["abscissa"], float).reshape(-1)
        good = np.isfinite(a) & ok
        picks = []
        neg = np.nonzero(good & (a < 0))[0]
        if neg.size:
            picks.append(int(neg[np.argmax(a[neg])]))
        pos = np.nonzero(good & (a > 0))[0]
        if pos.size:
            picks.append(int(pos[np.argmin(a[pos])]))
        if not picks:
            return {
                **base,
                "mesh": f"mesh: {mesh_words(model)}; no point with a margin to check on a finer mesh",
            }
        checks, set_nan, texts = [], [], []
        for flat in picks:
            p = point(flat)
            if q != "rightmost-root":
                code = float(np.asarray(res.data["stable"], float).reshape(-1)[flat])
                coarse = {1.0: "stable", 0.0: "unstable"}.get(code, "undetermined")
            else:
                coarse = "stable" if a[flat] < 0 else "unstable"
            fv = fine_task(**p)
            if q == "spectral-radius":
                # the Floquet exponent's real part, ln|mu| / T (T: the tooth period), 1/s as a root's
                T = float(model.process.delay(p.get("speed", task.fixed.get("speed", model.process.speed))))
                a_flat, fa = float(a[flat]) / T, math.log(float(fv["spectral_radius"])) / T
            else:
                a_flat, fa = float(a[flat]), float(fv["abscissa"])
            if q != "rightmost-root":
                fine = {1.0: "stable", 0.0: "unstable"}.get(float(fv["stable"]), "undetermined")
            else:
                fine = "stable" if fa < 0 else ("unstable" if fa > 0 else "undetermined")
            verdict, why = mesh_verdict(model, coarse, a_flat, fine, fa)
            if q != "rightmost-root" and verdict == "undetermined" and coarse != "undetermined":
                set_nan.append(flat)
            checks.append(
                {"point": p, "coarse_verdict": coarse, "fine_verdict": fine, "verdict": verdict,
                 "abscissa_per_s": a_flat, "fine_abscissa_per_s": fa,
                 "abscissa_error_bound_per_s": float(MeshEstimate(a_flat, fa).bound)}
            )  # fmt: skip
            texts.append(f"at {where(p)}: {verdict} ({why.removeprefix('mesh: ')})")
        n = len(picks)
        nan_note = f"; {len(set_nan)} of them set to NaN (undetermined) in the results" if set_nan else ""
        line = (
            f"mesh: {mesh_words(model)}; checked on a mesh twice as fine at {n} of {grid.size} points, the"
            f" {'stable and the unstable point' if n == 2 else 'point'} nearest the boundary (smallest"
            f" {'|ln spectral_radius|' if q == 'spectral-radius' else '|abscissa|'})"
            f"{nan_note}; the others are this mesh's: " + " | ".join(texts)
        )
        import json

        return {
            **base,
            "mesh_points_checked": n,
            "mesh_checks": json.dumps(checks),
            "mesh_undetermined_points": len(set_nan),
            "mesh": line,
            "_set_nan": set_nan,
        }
    key = {"b-lim": "b_lim", "min-b-lim": "b_lim_min", "a-lim": "a_lim", "natural-frequencies": "f1"}.get(q)
    if key is None:
        return None
    v = np.asarray(res.data[key], float).reshape(-1)
    good = np.nonzero(np.isfinite(v) & ok)[0]
    what = f"the point of the smallest {key}"
    if not good.size:  # every limit at the ceiling (inf): is it there on the finer mesh too?
        good = np.nonzero(~np.isnan(v) & ok)[0]
        what = f"the first point (every {key} is at the ceiling here)"
        if not good.size:
            return {**base, "mesh": f"mesh: {mesh_words(model)}; no {key} to check on a finer mesh"}
    flat = int(good[np.argmin(v[good])])
    p = point(flat)
    fv = fine_task(**p)
    where_p = f"; checked at {where(p)} only, {what} (the other {grid.size - 1} points are this mesh's)"
    if q == "natural-frequencies":
        fs = [float(np.asarray(res.data[k], float).reshape(-1)[flat]) for k in ("f1", "f2", "f3")]
        f2s = [float(fv[k]) for k in ("f1", "f2", "f3")]
        e = MeshEstimate(np.array(fs), np.array(f2s))
        text = ", ".join(
            f"{k} {pct(float(c), '+')} (err <= {pct(float(b))})"
            for k, c, b in zip(("f1", "f2", "f3"), e.relative_change, e.relative_bound, strict=True)
        )
        return {
            **base,
            "mesh_points_checked": 1,
            "mesh_point": json_point(p),
            "mesh_fine_values_hz": f2s,
            "mesh_error_bounds_hz": [float(x) for x in e.bound],
            "mesh": f"mesh: {mesh_words(model)}; twice as fine: {text}{where_p}",
        }
    fine_v = float(fv[key])
    e = MeshEstimate(v[flat], fine_v)
    line = limit_line(model, key, float(v[flat]), fine_v, tail=False) + where_p + converged_tail(model)
    return {
        **base,
        "mesh_points_checked": 1,
        "mesh_point": json_point(p),
        "mesh_fine_value_m": fine_v,
        "mesh_change": float(e.relative_change),
        "mesh_error_bound": float(e.relative_bound),
        "mesh": line,
    }


def json_point(p: dict[str, float]) -> str:
    import json

    return json.dumps(p)


# ---------------------------------------------------------------------------- sle (milling)


def sle_check(model: Any, res: Any, fine: Any, picks: list[int]) -> tuple[Any, dict[str, Any], list[str]]:
    """The SLE of a milling model with beams judged on the mesh twice as
    fine at the speeds ``picks`` (indices into ``res.speeds``; ``fine``: the
    :class:`SurfaceLocation` of those speeds on the finer mesh).  Each
    checked verdict by :func:`mesh_verdict` with the margin ln|mu| / T (1/s,
    T the tooth period); a checked ``stable`` speed that does not survive
    becomes ``undetermined`` (no SLE).  The largest |SLE| among the checked
    stable speeds gets its change and bound (Eq. M3, absolute, m).
    ``(result with a mesh record, the record, the printed lines)``."""
    import json

    verdict = list(res.verdict)
    sle, p2v = np.array(res.sle, float), np.array(res.peak_to_valley, float)
    checks, texts = [], []
    for j, i in enumerate(picks):
        rpm = float(res.speeds[i])
        T = float(model.process.delay(rpm))
        a_h = math.log(float(res.spectral_radius[i])) / T
        a_h2 = math.log(float(fine.spectral_radius[j])) / T
        v, why = mesh_verdict(model, res.verdict[i], a_h, fine.verdict[j], a_h2)
        if v == "undetermined" and verdict[i] == "stable":
            verdict[i], sle[i], p2v[i] = "undetermined", math.nan, math.nan
        e = MeshEstimate(res.sle[i], fine.sle[j])
        checks.append(
            {"speed_rpm": rpm, "coarse_verdict": res.verdict[i], "fine_verdict": fine.verdict[j], "verdict": v,
             "margin_per_s": a_h, "fine_margin_per_s": a_h2,
             "margin_error_bound_per_s": float(MeshEstimate(a_h, a_h2).bound),
             "sle_m": float(res.sle[i]), "fine_sle_m": float(fine.sle[j]), "sle_error_bound_m": float(e.bound)}
        )  # fmt: skip
        sle_text = (
            f"; SLE {res.sle[i] * 1e6:.4g} um, {fine.sle[j] * 1e6:.4g} um twice as fine (err <= {float(e.bound) * 1e6:.2g} um)"
            if np.isfinite(e.bound)
            else ""
        )
        texts.append(f"  at {rpm:g} rpm: {v} ({why.removeprefix('mesh: ')}){sle_text}")
    n_nan = sum(1 for a, b in zip(verdict, res.verdict, strict=True) if a != b)
    head = (
        f"mesh: {mesh_words(model)}; checked on a mesh twice as fine at {len(picks)} of {len(res.speeds)} speeds"
        " (the stable and the unstable speed nearest |mu| = 1, and the largest |SLE|); the others are this"
        " mesh's" + (f"; {n_nan} stable speed(s) now undetermined (no SLE)" if n_nan else "")
    )
    record = {
        **mesh_record(model),
        "mesh_speeds_checked": len(picks),
        "mesh_checks": json.dumps(checks),
        "mesh": head,
    }
    out = meshed(res, record, verdict=verdict, sle=sle, peak_to_valley=p2v)
    return out, record, [head, *texts]


def sle_picks(res: Any) -> list[int]:
    """The speeds an SLE is checked at: the stable one with the largest
    spectral radius, the unstable one with the smallest, and the stable one
    with the largest |SLE| (distinct, in order)."""
    rho = np.asarray(res.spectral_radius, float)
    st = [i for i, v in enumerate(res.verdict) if v == "stable" and np.isfinite(rho[i])]
    un = [i for i, v in enumerate(res.verdict) if v == "unstable" and np.isfinite(rho[i])]
    picks = []
    if st:
        picks.append(max(st, key=lambda i: rho[i]))
    if un:
        picks.append(min(un, key=lambda i: rho[i]))
    ok = [i for i in st if np.isfinite(res.sle[i])]
    if ok:
        k = max(ok, key=lambda i: abs(float(res.sle[i])))
        if k not in picks:
            picks.append(k)
    return picks


@functools.cache
def _meshed_class(cls: Any) -> Any:
    """``cls`` (a frozen :class:`~chatterlab.io.Result` dataclass) with its
    mesh check: ``mesh``, the ``mesh_*`` attributes of its files (netCDF,
    JSON), and ``mesh_data``, data variables of its files (``name: (values,
    unit, long name)``, per point of the result); built once per class."""
    from dataclasses import dataclass, field

    @dataclass(frozen=True, eq=False)
    class Meshed(cls):
        mesh: dict[str, Any] = field(default_factory=dict)
        mesh_data: dict[str, Any] = field(default_factory=dict)

        def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
            coords, data, attrs = super().dataset_parts()
            return coords, {**data, **self.mesh_data}, {**attrs, **self.mesh}

    Meshed.__name__ = Meshed.__qualname__ = f"Meshed{cls.__name__}"
    return Meshed


def meshed(
    res: Any, record: dict[str, Any], data: dict[str, Any] | None = None, cls: Any = None, **changes: Any
) -> Any:
    """``res`` with its mesh check (``cls``, default :func:`_meshed_class` of
    its type): the attributes ``record``, the data variables ``data``, and
    the fields ``changes`` (the verdicts and values the finer mesh did not
    confirm)."""
    import dataclasses

    fields = {f.name: getattr(res, f.name) for f in dataclasses.fields(res)}
    cls = cls if cls is not None else _meshed_class(type(res))  # type: ignore[arg-type]
    return cls(**{**fields, **changes}, mesh=record, mesh_data=data or {})


# ---------------------------------------------------------------------------- ssv

#: the most no-chatter points (no limit below the width ceiling) of an ``ssv``
#: grid that are checked on the finer mesh: each is a whole limit search there
#: (on the shaper's example in docs/ssv.md about a minute of CPU), so a grid
#: with more is checked at this many, spread over them, and the line says how
#: many were not
SSV_FREE_CAP = 3


def ssv_picks(res: Any, cap: int = SSV_FREE_CAP) -> tuple[int | None, list[int], int]:
    """The flat grid indices (speeds x RVA x RVF) an ``ssv`` result is checked
    at on the finer mesh: the point of the smallest finite limit (None when
    there is none), the points with no limit below the ceiling (all of them
    when at most ``cap``, else ``cap`` spread evenly over them in grid
    order), and how many of those were left unchecked."""
    b = np.asarray(res.b_lim, float).reshape(-1)
    finite = np.nonzero(np.isfinite(b))[0]
    crit = int(finite[np.argmin(b[finite])]) if finite.size else None
    free = np.nonzero(np.isposinf(b))[0]
    chosen = (
        free
        if free.size <= cap
        else free[np.unique(np.round(np.linspace(0, free.size - 1, cap)).astype(int))]
    )
    return crit, [int(i) for i in chosen], int(free.size - chosen.size)


def ssv_check(
    model: Any,
    res: Any,
    fine_limits: Callable[[list[tuple[float, float, float]]], Any],
    cap: int = SSV_FREE_CAP,
) -> tuple[Any, dict[str, Any]]:
    """The SSV limits of a model with beams checked on the mesh twice as fine
    at the points :func:`ssv_picks` chooses (``fine_limits(points)``: the
    limits at those (speed, rva, rvf) on :meth:`Model.with_finer_mesh`, SI,
    inf at the ceiling; one call, so that it can search them in parallel), as ``sweep`` checks a ``b-lim`` grid: the smallest limit's value
    twice as fine, its change and bound (:func:`limit_line`, Eq. M3); a point
    with no limit below the ceiling (a claim of no chatter) where the finer
    mesh finds one is not established: its limit becomes NaN
    (``undetermined`` in the table).  ``(result with the mesh record, the
    record)``; the record's ``mesh`` is the printed line."""
    import json
    import time

    t0 = time.perf_counter()
    crit, free, left = ssv_picks(res, cap)
    b = np.asarray(res.b_lim, float).reshape(-1)
    name, unit = res.limit_name, res.speed_unit

    def point(flat: int) -> tuple[float, float, float]:
        i, j, k = np.unravel_index(flat, np.shape(res.b_lim))
        return float(res.speeds[i]), float(res.rva[j]), float(res.rvf[k])

    def where(flat: int) -> str:
        s, a, f = point(flat)
        return f"speed {s:g} {unit}, RVA {a:g}, RVF {f:g}"

    picks = ([crit] if crit is not None else []) + free
    found = np.asarray(fine_limits([point(flat) for flat in picks]), dtype=float).reshape(-1)
    fine = {flat: float(x) for flat, x in zip(picks, found, strict=True)}
    if crit is not None:
        line = (
            limit_line(model, name, b[crit], fine[crit], tail=False)
            + f" at {where(crit)}, the grid's smallest {name}"
        )
    else:
        line = f"mesh: {mesh_words(model)}"
    n_free = int(np.count_nonzero(np.isposinf(b)))
    # only none below the ceiling on h/2 too (inf) confirms; a limit, or nothing established (NaN), does not
    held = [f for f in free if np.isposinf(fine[f])]
    lost = [f for f in free if f not in held]
    if n_free:
        every = " (every point)" if n_free == b.size else ""
        line += (
            f"; of the {n_free} point{'s' * (n_free != 1)} with no {name} below the ceiling{every},"
            f" {len(free)} checked on a mesh twice as fine"
        )
        if held:
            line += ": none below it twice as fine either at " + " and ".join(where(f) for f in held)
        if lost:
            line += ("; " if held else ": ") + " and ".join(
                (
                    f"twice as fine {name} {fine[f] * 1e3:.4g} mm"
                    if np.isfinite(fine[f])
                    else "twice as fine nothing established"
                )
                + f" at {where(f)}"
                for f in lost
            )
            line += ", so no chatter there is not established: undetermined (NaN in the files)"
        if left:
            line += (
                f"; {left} not checked (at most {cap} are, a limit search each): their claim of no chatter is"
                " this mesh's"
            )
    rest = b.size - len(picks)
    line += (
        f"; the other {rest} point{' is' if rest == 1 else 's are'} this mesh's" if rest else ""
    ) + converged_tail(model)

    def num(x: float) -> float | None:
        return float(x) if math.isfinite(x) else None

    checks = [
        {"point": dict(zip(("speed", "rva", "rvf"), point(f), strict=True)), "limit_m": num(b[f]),
         "fine_limit_m": num(fine[f]),
         "verdict": "limit" if f == crit else ("undetermined" if f in lost else "no chatter")}
        for f in picks
    ]  # fmt: skip
    record: dict[str, Any] = {
        **mesh_record(model),
        "mesh_points": int(b.size),
        "mesh_points_checked": len(picks),
    }
    if crit is not None:
        e = MeshEstimate(b[crit], fine[crit])
        record.update(
            mesh_point=json.dumps(checks[0]["point"]),
            mesh_fine_value_m=fine[crit],
            mesh_change=float(e.relative_change),
            mesh_error_bound=float(e.relative_bound),
        )
    record.update(
        mesh_free_points=n_free,
        mesh_free_points_checked=len(free),
        mesh_free_points_fine_limited=len(lost),
        mesh_undetermined_points=len(lost),
        mesh_checks=json.dumps(checks),
        mesh_seconds=time.perf_counter() - t0,
        mesh=line,
    )
    out = b.copy()
    out[lost] = math.nan
    return meshed(res, record, cls=_meshed_ssv_class(), b_lim=out.reshape(np.shape(res.b_lim))), record


@functools.cache
def _meshed_ssv_class() -> Any:
    """The :class:`SsvLimits` with its mesh check; its table says
    ``undetermined`` where the check made a limit NaN (the plain table would
    print a NaN as no limit below the ceiling)."""
    from dataclasses import dataclass

    from ..frequency._floquet_ssv_limit import SsvLimits

    @dataclass(frozen=True, eq=False)
    class MeshedSsvLimits(_meshed_class(SsvLimits)):  # type: ignore[misc]
        def table(self) -> str:
            lines = super().table().splitlines()
            b = np.asarray(self.b_lim, float).reshape(-1)
            first = len(lines) - b.size
            for flat in np.nonzero(np.isnan(b))[0]:
                row = lines[first + flat]
                w = max(12, len(row) - row.rindex("> "))
                lines[first + flat] = row[: len(row) - w] + "undetermined".rjust(w)
            return "\n".join(lines)

    return MeshedSsvLimits


# ---------------------------------------------------------------------------- sle (turning)


def established_limits(
    model: Any, speeds: Any, width_max: float, position: Any = None, **options: Any
) -> Any:
    """The limit (m) at each of ``speeds`` (any order) from the lobes of
    ``model`` at ``position`` on the diagram's own claim
    (:func:`chatterlab.selection._recommend.stable_width`): inf where no
    boundary lies below ``width_max`` on a proven basis, NaN where the
    diagram establishes nothing there (no boundary found in a band not
    proven complete, or contradicted by a check) -- what
    :func:`width_verdict` judges.  The D-subdivision routes run without
    the argument principle (``verify=0``): a limit's value; the principle
    confirms a boundary, it does not move it."""
    from ..lobes import lobes
    from ..selection._recommend import stable_width

    opts = dict(options)
    if model.process.kind != "milling" or opts.get("method") == "zoa":
        opts["verify"] = 0
    v = np.asarray(speeds, float)
    o = np.argsort(v, kind="stable")
    b, ceiling = stable_width(lobes(model, v[o], width_max=width_max, position=position, **opts))
    out = np.empty(v.size)
    out[o] = np.where(ceiling, np.inf, b)
    return out


#: at most this many speeds whose verdict the finer mesh did not confirm get a line of their own
RUNOUT_LINES = 5


def runout_check(
    model: Any, res: Any, fine: Any, limit: Any, fine_limit: Any
) -> tuple[Any, dict[str, Any], list[str]]:
    """The runout response of a turning model with beams (``res``, a
    :class:`RunoutResponse`) against the whole of it on the mesh twice as
    fine (``fine``: the same speeds on :meth:`Model.with_finer_mesh`);
    ``limit``, ``fine_limit``: the limit width b_lim at each speed on the two
    meshes (SI, :func:`established_limits`: inf none below the lobes'
    ceiling, NaN nothing established).  A verdict stands only
    when the roots on both meshes give it and :func:`width_verdict` on the
    two limits confirms it (the margin b_lim - b outside the limit's bound
    2 |change|, Eq. M3); else it is ``undetermined`` and a stable speed loses
    its amplitude (NaN).  Per speed the amplitude twice as fine and the bound
    of this mesh's, 2 |change|.  ``(result with the record and the per-speed
    data, the record, the printed lines)``."""
    from ..frequency._forced import VERDICTS

    n = len(res.speeds)
    b = float(res.width)
    verdict, whys = [], []
    for i in range(n):
        c, f = str(res.verdict[i]), str(fine.verdict[i])
        wv, why = width_verdict(model, b, float(limit[i]), float(fine_limit[i]))
        why = why.removeprefix("mesh: ")
        if c == "undetermined":
            v, why = c, "undetermined already on this mesh"
        elif f != c:
            v, why = "undetermined", f"{c} on this mesh, {f} on a mesh twice as fine"
        elif wv != c:
            v = "undetermined"
            if wv != "undetermined":
                why = f"{c} by the roots, but {wv} against the limit b_lim {float(limit[i]) * 1e3:.4g} mm"
        else:
            v = c
        verdict.append(v)
        whys.append(why)
    ok = np.array([v == "stable" for v in verdict])
    e = MeshEstimate(res.amplitude, fine.amplitude)
    amp = np.where(ok, np.asarray(res.amplitude, float), np.nan)
    phase = np.where(ok, np.asarray(res.phase, float), np.nan)
    changed = [i for i in range(n) if verdict[i] != res.verdict[i]]
    count = {w: verdict.count(w) for w in VERDICTS}
    line = (
        f"mesh: {mesh_words(model)}; the whole response again on a mesh twice as fine (all {n} speeds), each"
        f" verdict also against the limit b_lim on both meshes (Eq. M3): {count['stable']} stable and"
        f" {count['unstable']} unstable confirmed, {count['undetermined']} undetermined"
    )
    if changed:
        line += f" ({len(changed)} of them not confirmed on both meshes: no amplitude)"
    rel = np.where(ok, np.abs(np.asarray(e.relative_change, float)), np.nan)
    rb = np.where(ok, np.asarray(e.relative_bound, float), np.nan)
    if np.any(np.isfinite(rb)):
        k = int(np.nanargmax(rb))
        line += (
            f"; the amplitude moves by up to {pct(float(np.nanmax(rel)))}, its discretisation error <="
            f" {pct(float(rb[k]))} (largest, at {float(res.speeds[k]):g} rpm; median {pct(float(np.nanmedian(rb)))})"
        )
    line += converged_tail(model)
    lines = [line] + [
        f"  at {float(res.speeds[i]):g} rpm: {verdict[i]} ({whys[i]})" for i in changed[:RUNOUT_LINES]
    ]
    if len(changed) > RUNOUT_LINES:
        lines.append(
            f"  and {len(changed) - RUNOUT_LINES} more speeds undetermined (the files' coarse_verdict,"
            " fine_verdict, b_lim and fine_b_lim)"
        )

    def codes(vs: Any) -> Any:
        return np.array([VERDICTS.index(v) if v in VERDICTS else 2 for v in vs], dtype=int)

    record: dict[str, Any] = {
        **mesh_record(model),
        "mesh_speeds_checked": n,
        "mesh_undetermined_speeds": len(changed),
        "mesh_amplitude_change_max": float(np.nanmax(rel)) if np.any(np.isfinite(rel)) else math.nan,
        "mesh_amplitude_error_bound_max": float(np.nanmax(rb)) if np.any(np.isfinite(rb)) else math.nan,
        "mesh": line,
    }
    data = {
        "fine_amplitude": (np.asarray(fine.amplitude, float), "m", "vibration amplitude at the spindle frequency, mesh twice as fine"),
        "amplitude_error_bound": (np.where(ok, np.asarray(e.bound, float), np.nan), "m", "bound of the amplitude's discretisation error, 2 |change| (Eq. M3)"),
        "coarse_verdict": (codes(res.verdict), "1", "the verdict on this mesh alone: 0 stable, 1 unstable, 2 undetermined"),
        "fine_verdict": (codes(fine.verdict), "1", "the verdict on the mesh twice as fine: 0 stable, 1 unstable, 2 undetermined"),
        "b_lim": (np.asarray(limit, float), "m", "limit width at the speed (inf: none below the ceiling)"),
        "fine_b_lim": (np.asarray(fine_limit, float), "m", "limit width at the speed, mesh twice as fine"),
    }  # fmt: skip
    return meshed(res, record, data, verdict=verdict, amplitude=amp, phase=phase), record, lines


# ---------------------------------------------------------------------------- simulate (milling)


def milling_run_check(model: Any, run: Any, position: Any) -> tuple[dict[str, Any], list[str]]:
    """The verdict of a milling run of a model with beams on the mesh twice as
    fine: the linearised cut's Floquet multipliers at the run's (a_p, rpm)
    (the sweep's ``spectral-radius`` task, |mu| against its convergence
    error) on both meshes, judged by :func:`mesh_verdict` on the margin
    ln|mu| / T (1/s, T the tooth period).  The run's own ``stable`` stands
    only when that verdict does; a chatter verdict of the run is reported
    beside it (the nonlinear run can chatter where the linearisation does
    not: a finite-amplitude effect, not the mesh's).  ``(attributes, lines)``."""
    import dataclasses

    from ..quantities import QuantityTask

    fixed = {"width": float(run.depth), "speed": float(run.rpm)}
    if position is not None:
        fixed["position"] = float(position)
    task = QuantityTask(model, "spectral-radius", fixed)
    coarse_v, fine_v = task(), dataclasses.replace(task, model=model.with_finer_mesh())()
    T = float(model.process.delay(float(run.rpm)))
    words = {1.0: "stable", 0.0: "unstable"}
    c = words.get(float(coarse_v["stable"]), "undetermined")
    f = words.get(float(fine_v["stable"]), "undetermined")
    a_h = math.log(float(coarse_v["spectral_radius"])) / T
    a_h2 = math.log(float(fine_v["spectral_radius"])) / T
    verdict, why = mesh_verdict(model, c, a_h, f, a_h2)
    facts: dict[str, Any] = {
        **mesh_record(model),
        "mesh_coarse_verdict": c,
        "mesh_fine_verdict": f,
        "mesh_margin_per_s": a_h,
        "mesh_fine_margin_per_s": a_h2,
        "mesh_margin_error_bound_per_s": float(MeshEstimate(a_h, a_h2).bound),
        "mesh_verdict": verdict,
        "mesh": why,
    }
    run_stable = str(run.verdict) == "stable"
    head = (
        f"  linearised verdict (Floquet, |mu| = {float(coarse_v['spectral_radius']):.5g}): {verdict}"
        f" (on this mesh: {c}; margin ln|mu|/T = {a_h:+.4g} 1/s)"
    )
    lines = [head, f"  {why}"]
    if run_stable and verdict != "stable":
        lines.append(
            "  verdict: undetermined (this run is stable on this mesh alone; the mesh twice as fine does"
            " not confirm it)"
        )
        facts["mesh_run_verdict"] = "undetermined"
    else:
        facts["mesh_run_verdict"] = str(run.verdict)
    return facts, lines
