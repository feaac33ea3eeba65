"""The discretisation error of ``simulate``, ``frf``, ``sweep`` and ``sle`` on a
model with beams (docs/lobes.md, "The discretisation error of a result", Eqs.
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
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np

from ..model._mesh import MeshEstimate, converged_tail, limit_line, mesh_record, mesh_verdict, mesh_words, pct

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
    import dataclasses
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
    out = _meshed_surface_location()(
        **{f.name: getattr(res, f.name) for f in dataclasses.fields(res)},
        mesh=record,
    )
    out = dataclasses.replace(out, verdict=verdict, sle=sle, peak_to_valley=p2v)
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
def _meshed_surface_location() -> Any:
    """The class, built on first use (importing chatterlab.frequency._forced costs)."""
    from dataclasses import dataclass, field

    from ..frequency._forced import SurfaceLocation

    @dataclass(frozen=True, eq=False)
    class MeshedSurfaceLocation(SurfaceLocation):
        """A :class:`SurfaceLocation` with its mesh check: the ``mesh_*``
        attributes of its files (netCDF, JSON)."""

        mesh: dict[str, Any] = field(default_factory=dict)

        def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
            coords, data, attrs = super().dataset_parts()
            return coords, data, {**attrs, **self.mesh}

    return MeshedSurfaceLocation


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
