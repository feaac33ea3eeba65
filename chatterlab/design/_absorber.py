"""Tuned vibration absorbers against chatter: the tuning that maximises the
minimum chatter-free width.

An absorber (``[[absorber]]``, :mod:`chatterlab.model._absorber`) of mass
m_a, natural frequency f_a = sqrt(k_a / m_a) / 2 pi and damping ratio
zeta_a = c_a / (2 sqrt(k_a m_a)) is part of the structure.  The tuning
problem is

    maximise  b_min(x)  over x = (f_a, zeta_a [, m_a]) of every absorber,    (1)

b_min the minimum of b_lim over a speed range, or the absolute minimum over
all speeds.  b_min is the lowest of several smooth functions -- the bottoms
of the boundary's branches (one per mode the absorber splits the host's mode
into, :func:`chatterlab.design.lobe_bottoms`) and, over a range, the limits
at its ends -- so at the optimum two or more of them are equal (the
equal-ripple optimum of a min-max problem) and b_min has a kink there.  (1)
is therefore solved in its epigraph form

    maximise t  subject to  b_i(x) >= t  (the lowest few candidates i),       (2)

by sequential quadratic programming (scipy's SLSQP) with the *exact*
gradients of every b_i from :mod:`chatterlab.design._critical` (the
absorber's stiffness, damping and mass enter the matrices affinely: their
derivatives are exact differences), from several starts: the classical
tuning of Den Hartog [1] (with Brock's damping), the optimum of the chatter
criterion for an undamped one-degree-of-freedom host [2], and Latin-hypercube
points in the bounds.  The host of the two classical tunings is the bare
structure's mode nearest its chatter frequency, reduced to the absorber's
point and direction (modal mass 1 / (e . P phi)^2 for a mass-normalised
shape phi) -- for a one-degree-of-freedom host the tunings themselves.

The chatter criterion of Sims [2]: for a one-degree-of-freedom host under a
regenerative cut, b_min = -1 / (2 K_f min_w Re G(w)) (Tlusty's limit), so
the best absorber maximises the minimum of the real part of the host's
receptance G -- not the peak of |G| that Den Hartog's tuning minimises.
Sims derived an analytical approximation of that optimum for an undamped
host; :func:`real_part_tuning` computes the optimum of the same criterion
exactly (the equal-minima condition, by nested one-dimensional searches on
the closed-form Re G), so no approximation of the published formulas enters
here.

References
----------
.. [1] J. P. Den Hartog, *Mechanical Vibrations*, 4th ed., McGraw-Hill 1956
   (Dover 1985), sec. 3.3; J. E. Brock, "A note on the damped vibration
   absorber", J. Appl. Mech. 13 (1946) A-284.
.. [2] N. D. Sims, "Vibration absorbers for chatter suppression: a new
   analytical tuning methodology", J. Sound Vib. 301 (2007) 592-607.
.. [3] J. Nocedal, S. J. Wright, *Numerical Optimization*, 2nd ed.,
   Springer, 2006, ch. 18 (SQP) and sec. 12.8 (sensitivity of an optimum).
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from ..errors import ChatterlabError, InputError, check_width
from ..io import Result
from ..model import Model
from ..structure import assemble
from ._controlled import design_lobes
from ._epigraph import (
    CANDIDATES,
    best_start,
    candidate_points,
    check_bound,
    check_starts,
    solve_epigraph,
    start_points,
    starts_line,
)
from ._limits import limits_of
from ._matrices import field_derivative, loop_matrices

__all__ = [
    "AbsorberDesign",
    "tune_absorbers",
    "with_absorber",
    "without_absorbers",
    "den_hartog_tuning",
    "real_part_tuning",
]

OBJECTIVES = ("minimum", "absolute")


# ------------------------------------------------------------------ the classical tunings
def den_hartog_tuning(mu: float) -> tuple[float, float]:
    """(f_a / f_host, zeta_a) of Den Hartog's equal-peak tuning with Brock's
    damping for mass ratio mu = m_a / m_host: 1 / (1 + mu) and
    sqrt(3 mu / (8 (1 + mu)^3)) [1]."""
    if not mu > 0:
        raise InputError(f"mass ratio must be > 0 (got {mu!r})")
    return 1.0 / (1.0 + mu), math.sqrt(3 * mu / (8 * (1 + mu) ** 3))


def _re_g(r: Any, f: float, z: float, mu: float) -> Any:
    """k Re G of the undamped host with an absorber, r = w / w_host."""
    q = f * f + 2j * z * f * r
    return np.real((q - r * r) / ((1 - r * r) * (q - r * r) - mu * r * r * q))


def _min_re_g(f: float, z: float, mu: float) -> float:
    """min over r of k Re G: every local minimum on a fine grid, refined by
    Brent's method."""
    from scipy.optimize import minimize_scalar

    r = np.linspace(0.3, 2.5, 2201)
    g = _re_g(r, f, z, mu)
    idx = np.nonzero((g[1:-1] <= g[:-2]) & (g[1:-1] <= g[2:]))[0] + 1
    best = float(g.min())
    for i in idx:
        res = minimize_scalar(
            lambda x: float(_re_g(x, f, z, mu)), bounds=(r[i - 1], r[i + 1]), method="bounded",
            options={"xatol": 1e-13},
        )  # fmt: skip
        best = min(best, float(res.fun))
    return best


def real_part_tuning(mu: float) -> tuple[float, float, float]:
    """(f_a / f_host, zeta_a, min k Re G) maximising the minimum real part of
    the receptance of an undamped one-degree-of-freedom host with an
    absorber of mass ratio mu: Sims' chatter criterion [2], solved exactly by
    nested bounded searches (for each zeta the best frequency ratio, then the
    best zeta)."""
    from scipy.optimize import minimize_scalar

    if not mu > 0:
        raise InputError(f"mass ratio must be > 0 (got {mu!r})")

    def best_f(z: float) -> tuple[float, float]:
        res = minimize_scalar(
            lambda f: -_min_re_g(f, z, mu), bounds=(0.5, 1.5), method="bounded", options={"xatol": 1e-12}
        )
        return float(res.x), -float(res.fun)

    res = minimize_scalar(
        lambda z: -best_f(z)[1], bounds=(1e-3, 1.0), method="bounded", options={"xatol": 1e-12}
    )
    z = float(res.x)
    f, g = best_f(z)
    return f, z, g


# ------------------------------------------------------------------ absorbers in a model
def _rebuild(model: Model, raw: dict[str, Any], drop: set[str] | None = None) -> Model:
    """The model of ``raw`` with the variant and overrides of ``model``
    (overrides of the absorbers in ``drop`` left out: ``raw`` sets them)."""

    def kept(path: str) -> bool:
        parts = str(path).split(".")
        return not (drop and len(parts) == 3 and parts[0] == "absorber" and parts[1] in drop)

    overrides = {k: v for k, v in dict(model.overrides).items() if kept(k)}
    return model.rebuild(
        raw, source=model.source, text=model.text, variant=model.variant, overrides=overrides
    )


def with_absorber(
    model: Model,
    id: str,
    at: str | dict[str, Any],
    *,
    direction: str | None = None,
    angle_deg: float | None = None,
    mass: float,
    frequency_hz: float,
    damping_ratio: float,
) -> Model:
    """A copy of ``model`` with one more ``[[absorber]]`` (its fields as in
    docs/model-format.md), validated like a model file."""
    raw = json.loads(model.raw)
    t: dict[str, Any] = {"id": id, "at": at, "mass": mass, "frequency_hz": frequency_hz}
    t["damping_ratio"] = damping_ratio
    if direction is not None:
        t["direction"] = direction
    if angle_deg is not None:
        t["angle_deg"] = angle_deg
    raw.setdefault("absorber", []).append(t)
    return _rebuild(model, raw)


def without_absorbers(model: Model) -> Model:
    """The bare structure: ``model`` without its ``[[absorber]]`` items."""
    raw = json.loads(model.raw)
    ids = {a.id for a in model.absorbers}
    raw.pop("absorber", None)
    return _rebuild(model, raw, drop=ids)


def _with_values(model: Model, values: dict[str, tuple[float, float, float]]) -> Model:
    """``model`` with absorbers ``id -> (mass, stiffness, damping)``."""
    raw = json.loads(model.raw)
    for t in raw.get("absorber", []):
        if isinstance(t, dict) and t.get("id") in values:
            m, k, c = values[t["id"]]
            for key in ("mass", "stiffness", "frequency_hz", "damping", "damping_ratio"):
                t.pop(key, None)
            t.update({"mass": float(m), "stiffness": float(k), "damping": float(c)})
    return _rebuild(model, raw, drop=set(values))


# ------------------------------------------------------------------ the result
@dataclass(frozen=True, eq=False)
class AbsorberDesign(Result):
    """A tuned absorber design and what it buys.

    Attributes
    ----------
    absorbers : tuple of dict
        Each tuned absorber: ``id``, ``mass`` (kg), ``stiffness`` (N/m),
        ``damping`` (N s/m), ``frequency_hz``, ``damping_ratio``.
    objective : {"minimum", "absolute"}
        What was maximised: the minimum b_lim over the speed range or the
        absolute minimum over all speeds.
    width, bare_width : float
        The objective (m) of the tuned design and of the structure without
        the absorbers (0 when the bare structure has an undamped mode).
    den_hartog, den_hartog_width
        Den Hartog's tuning of the same absorbers (per absorber: ``mass``,
        ``frequency_hz``, ``damping_ratio``, the host mode ``host_hz`` and
        modal mass ``host_mass``) and its objective, m.
    before, after : LobeDiagram
        The lobes without the absorbers and of the tuned design (checked by
        the argument principle: ``after.verified``).
    starts : tuple of dict
        Every start of the optimiser: ``start`` and ``end`` (per absorber
        (f_a Hz, zeta_a[, m_a kg])), ``width`` (m), ``iterations``, ``label``.
    model : Model
        The tuned model.

    Files through the result protocol (:class:`chatterlab.io.Result`):
    ``to_csv`` (the lobes before and after, one row per speed),
    ``to_netcdf``, ``to_xarray``, ``to_json``.
    """

    absorbers: tuple[dict[str, float | str], ...]
    objective: str
    width: float
    bare_width: float
    den_hartog: tuple[dict[str, float | str], ...]
    den_hartog_width: float
    before: Any = field(repr=False)
    after: Any = field(repr=False)
    starts: tuple[dict[str, Any], ...] = ()
    model: Any = field(default=None, repr=False)
    elapsed: float = 0.0
    evaluations: int = 0

    @property
    def gain(self) -> float:
        """width / bare_width (inf when the bare structure chatters at any width)."""
        return self.width / self.bare_width if self.bare_width > 0 else float("inf")

    @property
    def verified(self) -> bool | None:
        """The tuned design's lobes passed every argument-principle check."""
        return self.after.verified

    def toml(self) -> str:
        """The tuned ``[[absorber]]`` tables, to paste into the model file."""
        out = []
        for a in self.absorbers:
            out.append(
                f'[[absorber]]\nid = "{a["id"]}"\n# at, direction / angle_deg: as in the model\n'
                f"mass = {float(a['mass'])!r}\nfrequency_hz = {float(a['frequency_hz'])!r}\n"
                f"damping_ratio = {float(a['damping_ratio'])!r}\n"
            )
        return "\n".join(out)

    def summary(self) -> str:
        what = (
            "minimum b_lim over the speed range" if self.objective == "minimum" else "absolute minimum b_lim"
        )
        lines = [f"absorber tuning of {self.after.model}: maximise the {what}"]
        for a, dh in zip(self.absorbers, self.den_hartog, strict=True):
            lines.append(
                f"  {a['id']}: mass {float(a['mass']):.4g} kg, f_a {float(a['frequency_hz']):.5g} Hz,"
                f" zeta_a {float(a['damping_ratio']):.4g} (k {float(a['stiffness']):.5g} N/m,"
                f" c {float(a['damping']):.5g} N s/m); host mode {float(dh['host_hz']):.5g} Hz,"
                f" modal mass {float(dh['host_mass']):.4g} kg"
            )
        bare = f"{self.bare_width * 1e3:.4g} mm" if self.bare_width > 0 else "0 (an undamped mode)"
        gain = f"x {self.gain:.3g}" if np.isfinite(self.gain) else "from 0"
        lines.append(f"  tuned: {self.width * 1e3:.5g} mm; without the absorbers: {bare} ({gain})")
        lines.append(
            "  Den Hartog's tuning ("
            + ", ".join(
                f"f_a {float(d['frequency_hz']):.5g} Hz, zeta_a {float(d['damping_ratio']):.4g}"
                for d in self.den_hartog
            )
            + f"): {self.den_hartog_width * 1e3:.5g} mm"
        )
        if self.starts:
            lines.append(starts_line(self.starts, self.width, self.evaluations, self.elapsed))
        ok = self.after.verified
        n = len(self.after.checks)
        lines.append(
            f"  tuned design verified by the argument principle: {sum(c['agrees'] for c in self.after.checks)}/{n}"
            " checks agree"
            if n
            else "  tuned design not verified (verify=0)"
        )
        if ok is False:
            lines.append(
                "  CHECK FAILED: the tuned design's lobes are contradicted by the argument principle"
            )
        return "\n".join(lines)

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """``(coords, data, attrs)`` of the files (:class:`chatterlab.io.Result`):
        the lobes before and after on the speeds (``b_lim_before``,
        ``b_lim_after`` and their chatter frequencies), the tuning in the
        attributes."""
        d0, d1 = self.before, self.after
        coords = {"speed": (d1.speed, d1.speed_unit, str(d1.speed_name))}
        data = {
            "b_lim_before": (d0.b_lim, "m", "limit width without the absorbers"),
            "b_lim_after": (d1.b_lim, "m", "limit width with the tuned absorbers"),
            "chatter_hz_before": (d0.chatter_hz, "Hz", "chatter frequency without the absorbers"),
            "chatter_hz_after": (d1.chatter_hz, "Hz", "chatter frequency with the tuned absorbers"),
        }

        def plain(d: dict[str, Any]) -> dict[str, Any]:
            return {k: (float(v) if isinstance(v, float | np.floating) else v) for k, v in d.items()}

        attrs = {
            "title": "chatterlab tuned vibration absorbers",
            "model": str(getattr(self.model, "name", "") or d1.model),
            "objective": self.objective,
            "width_m": self.width,
            "bare_width_m": self.bare_width,
            "den_hartog_width_m": self.den_hartog_width,
            "absorbers": json.dumps([plain(a) for a in self.absorbers]),
            "den_hartog": json.dumps([plain(a) for a in self.den_hartog]),
            "verified": str(self.verified),
        }
        return coords, data, attrs

    def plot(self, ax: Any = None, *, title: str | None = None) -> Any:
        """The lobes before and after on one axis (:func:`chatterlab.plot.plot_lobes_compare`)."""
        from ..plot import plot_lobes_compare

        return plot_lobes_compare(
            [self.before, self.after],
            ["without absorber", "tuned absorber" + ("s" if len(self.absorbers) > 1 else "")],
            ax=ax,
            title=title
            or f"{getattr(self.model, 'name', '') or self.after.model}: tuned absorber, {self.width * 1e3:.4g} mm"
            + (f" (x {self.gain:.3g})" if np.isfinite(self.gain) else ""),
        )


# ------------------------------------------------------------------ the tuning
@dataclass
class _Problem:
    model: Model
    ids: list[str]
    speeds: np.ndarray
    objective: str
    lobe_kw: dict[str, Any]
    mat_kw: dict[str, Any]
    lo: np.ndarray
    hi: np.ndarray
    masses: np.ndarray  #: fixed masses (when the mass is not a variable)
    free_mass: bool
    scale: float = 1.0  #: the objective's scale, m
    evaluations: int = 0
    cache: dict[bytes, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)

    @property
    def nv(self) -> int:
        return 3 if self.free_mass else 2

    def physical(self, u: np.ndarray) -> list[tuple[float, float, float]]:
        """(f_a Hz, zeta_a, m_a kg) per absorber from the unit-box variables u."""
        x = self.lo + np.clip(u, 0.0, 1.0) * (self.hi - self.lo)
        out = []
        for j in range(len(self.ids)):
            v = x[self.nv * j : self.nv * (j + 1)]
            m = float(v[2]) if self.free_mass else float(self.masses[j])
            out.append((float(math.exp(v[0])), float(v[1]), m))
        return out

    def model_at(self, u: np.ndarray) -> Model:
        vals = {}
        for i, (f, z, m) in zip(self.ids, self.physical(u), strict=True):
            k = m * (2 * math.pi * f) ** 2
            vals[i] = (m, k, 2 * z * math.sqrt(k * m))
        return _with_values(self.model, vals)

    def candidates(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The lowest candidate limits (m) of (2) and their gradients in u."""
        key = np.asarray(u, float).tobytes()
        if key in self.cache:
            return self.cache[key]
        self.evaluations += 1
        mdl = self.model_at(u)
        d = design_lobes(assemble(mdl).at(self.mat_kw["position"]), self.speeds, verify=0, **self.lobe_kw)
        L = loop_matrices(mdl, **self.mat_kw)
        cps = candidate_points(d, L, self.objective)
        grads = np.zeros((len(cps), u.size))
        if cps:
            phys = self.physical(u)
            for j, aid in enumerate(self.ids):
                f, z, m = phys[j]
                k = m * (2 * math.pi * f) ** 2
                c = 2 * z * math.sqrt(k * m)
                dk, dc, dm = (
                    field_derivative(mdl, f"absorber.{aid}.{name}", base=L, affine=True, **self.mat_kw).d
                    for name in ("stiffness", "damping", "mass")
                )
                span = self.hi[self.nv * j : self.nv * (j + 1)] - self.lo[self.nv * j : self.nv * (j + 1)]
                for i, cp in enumerate(cps):
                    bk, bc, bm = (cp.derivative(x) for x in (dk, dc, dm))
                    # chain rule: k = m (2 pi f)^2, c = 2 zeta sqrt(k m)
                    g = [2 * k * bk + c * bc, 2 * math.sqrt(k * m) * bc]  # d/d ln f, d/d zeta
                    if self.free_mass:
                        g.append(bm + (k / m) * bk + (c / m) * bc)  # d/d m at fixed f, zeta
                    grads[i, self.nv * j : self.nv * (j + 1)] = np.array(g) * span
        vals = np.array([cp.b for cp in cps]) if cps else np.array([np.inf])
        if not cps:
            grads = np.zeros((1, u.size))
        order = np.argsort(vals)[:CANDIDATES]
        vals, grads = vals[order], grads[order]
        while vals.size < CANDIDATES:  # a fixed number of constraints: repeat the highest
            vals, grads = np.r_[vals, vals[-1]], np.vstack([grads, grads[-1]])
        self.cache[key] = (vals, grads)
        return vals, grads


def _host_modes(
    bare: Model, ids: list[str], model: Model, position: float | None, f_c: float
) -> list[tuple[float, float]]:
    """(host mode frequency Hz, modal mass kg at the absorber's point and
    direction) per absorber (:func:`host_mode`)."""
    fz = assemble(bare).at(position)
    L = loop_matrices(bare, position=position)
    out = []
    for aid in ids:
        ab = next(a for a in model.absorbers if a.id == aid)
        row = np.array(ab.direction) @ fz.expand(fz.system.point_map(ab.at, fz.position))[:2]
        out.append(host_mode(L.M, L.K, row, f_c, f'[[absorber]] "{aid}": its point'))
    return out


def host_mode(M: np.ndarray, K: np.ndarray, row: np.ndarray, f_c: float, what: str) -> tuple[float, float]:
    """(frequency Hz, modal mass kg) of the host mode seen through ``row`` (a
    point's displacement along a direction, from the coordinates): of the
    undamped modes of (M, K) within a factor 2 of the chatter frequency f_c
    that it sees (a mass-normalised amplitude row . phi of at least 1 % of
    the largest there), the one nearest f_c; its modal mass 1 / (row . phi)^2."""
    from scipy.linalg import eigh

    w2, phi = eigh(K, M)
    f = np.sqrt(np.abs(w2)) / (2 * np.pi)
    band = np.nonzero((f >= f_c / 2) & (f <= 2 * f_c))[0]
    if band.size == 0:
        band = np.array([int(np.argmin(np.abs(f - f_c)))])
    amp = row @ phi[:, band]
    seen = np.abs(amp) >= 0.01 * np.abs(amp).max()
    j = int(np.argmin(np.where(seen, np.abs(f[band] - f_c), np.inf)))
    if amp[j] == 0:
        raise InputError(
            f"{what} does not move along its direction in any mode near the chatter frequency {f_c:.4g} Hz,"
            " so it cannot act; put it where the structure vibrates"
        )
    return float(f[band[j]]), float(1.0 / amp[j] ** 2)


def tune_absorbers(
    model: Model,
    speeds: Any,
    *,
    absorbers: list[str] | None = None,
    objective: Literal["minimum", "absolute"] = "minimum",
    mass_max: float | None = None,
    frequency_hz: tuple[float, float] | None = None,
    damping_ratio: tuple[float, float] = (0.005, 0.5),
    starts: int = 4,
    position: float | None = None,
    width_max: float = 0.02,
    terms: Literal["pdo", "o"] = "pdo",
    n_frequencies: int | None = None,
    verify: int = 16,
    seed: int = 0,
) -> AbsorberDesign:
    """Tune the model's absorbers to maximise the minimum chatter-free width.

    Parameters
    ----------
    model : Model
        With one or more ``[[absorber]]`` items (their mass, and their point
        and direction, are kept; :func:`with_absorber` adds one).
    speeds : array
        Speeds (process unit) of the lobe diagrams.
    absorbers : list of str, optional
        Ids of the absorbers tuned (default: all).
    objective : {"minimum", "absolute"}
        Maximise the minimum b_lim over the speed range (default) or the
        absolute minimum over all speeds.
    mass_max : float, optional
        Make each absorber's mass a variable in [mass_max / 20, mass_max]
        kg (default: the masses of the file are kept).
    frequency_hz : (lo, hi), optional
        Bounds of every absorber's natural frequency, Hz (default: 0.6 to
        1.4 times the bare structure's chatter frequency at the objective).
    damping_ratio : (lo, hi)
        Bounds of the damping ratios.
    starts : int
        Optimiser starts: Den Hartog's tuning, the exact optimum of the
        chatter criterion for the equivalent one-degree-of-freedom host
        (:func:`real_part_tuning`), then Latin-hypercube points (``seed``).
    position, width_max, terms, n_frequencies
        As for :func:`chatterlab.lobes.lobes`.
    verify : int
        Argument-principle checks of the tuned design's lobes (and of the
        bare structure's).

    Returns
    -------
    AbsorberDesign
    """
    t0 = time.perf_counter()
    if objective not in OBJECTIVES:
        raise InputError(f"objective must be one of {', '.join(OBJECTIVES)} (got {objective!r})")
    width_max = check_width(width_max, "width_max")
    check_starts(starts)
    known = [a.id for a in model.absorbers]
    if not known:
        raise InputError(
            f"{model.source} has no [[absorber]]: add one (docs/model-format.md) or use with_absorber(...)"
        )
    ids = list(known if absorbers is None else absorbers)
    for aid in ids:
        if aid not in known:
            raise InputError(f"unknown absorber '{aid}' (known: {', '.join(known)})")
    lo_z, hi_z = check_bound("damping_ratio bounds", *damping_ratio, positive=True)
    if mass_max is not None and not (
        isinstance(mass_max, int | float) and math.isfinite(mass_max) and mass_max > 0
    ):
        raise InputError(f"mass_max must be a mass > 0 in kg (got {mass_max!r})")
    speeds = np.asarray(speeds, dtype=float)
    lobe_kw: dict[str, Any] = {"width_max": width_max, "terms": terms, "n_frequencies": n_frequencies}
    fz0 = assemble(model).at(position)
    # the optimiser's candidates are the branch bottoms the lobes show (they depend on the
    # range of delays, not on the number of speeds) and the range's ends: 9 speeds suffice
    inner = np.linspace(float(speeds.min()), float(speeds.max()), 9)
    mat_kw = {"position": fz0.position, "speeds": inner, "terms": terms}
    # the bare structure: its lobes, the chatter frequency, the host modes
    bare = without_absorbers(model)
    try:
        before = design_lobes(assemble(bare).at(position), speeds, verify=verify, **lobe_kw)
        bare_width, f_c = _objective(before, bare, objective, position, speeds, terms)
    except ChatterlabError as exc:
        if "undamped" not in str(exc):
            raise
        before, bare_width, f_c = None, 0.0, float("nan")
    if not np.isfinite(f_c):  # an undamped bare structure: its lowest mode is the host
        d0 = design_lobes(fz0, speeds, verify=0, **lobe_kw)
        f_c = float(d0.absolute_minimum["chatter_hz"])
    lo_f, hi_f = check_bound(
        "frequency_hz bounds",
        *(frequency_hz if frequency_hz is not None else (0.6 * f_c, 1.4 * f_c)),
        positive=True,
    )
    masses = np.array([next(a for a in model.absorbers if a.id == i).mass for i in ids])
    free = mass_max is not None
    m_max = float(mass_max) if mass_max is not None else 0.0
    lo1 = [math.log(lo_f), lo_z] + ([m_max / 20] if free else [])
    hi1 = [math.log(hi_f), hi_z] + ([m_max] if free else [])
    # and a coarser uniform frequency grid than the final diagram's (the resonance clusters of
    # every mode stay): a bottom only has to show on a lobe curve, then it is polished exactly
    inner_kw = {**lobe_kw, "n_frequencies": min(n_frequencies or 2000, 400)}
    prob = _Problem(
        model,
        ids,
        inner,
        objective,
        inner_kw,
        mat_kw,
        np.array(lo1 * len(ids)),
        np.array(hi1 * len(ids)),
        masses,
        free,
    )
    hosts = _host_modes(bare, ids, model, fz0.position, f_c)
    m_dh = [m_max if free else float(masses[j]) for j in range(len(ids))]
    dh = [den_hartog_tuning(m / hm) for m, (_, hm) in zip(m_dh, hosts, strict=True)]
    rp = [real_part_tuning(m / hm)[:2] for m, (_, hm) in zip(m_dh, hosts, strict=True)]

    def unit(tunings: list[tuple[float, float]]) -> np.ndarray:
        x = []
        for (ratio, z), (fh, _), m in zip(tunings, hosts, m_dh, strict=True):
            x += [math.log(ratio * fh), z] + ([m] if free else [])
        return np.clip((np.array(x) - prob.lo) / (prob.hi - prob.lo), 0.0, 1.0)

    u0 = start_points([("Den Hartog", unit(dh)), ("real part", unit(rp))], prob.lo.size, starts, seed)
    # the objective's scale: the design at Den Hartog's tuning
    prob.scale = float(prob.candidates(u0[0][1])[0][0])
    if not np.isfinite(prob.scale) or prob.scale <= 0:
        prob.scale = width_max
    runs, (label, u_start, u_best, w_best, nit) = best_start(u0, lambda u: solve_epigraph(prob, u))
    tuned = prob.model_at(u_best)
    after = design_lobes(assemble(tuned).at(position), speeds, verify=verify, **lobe_kw)
    width, _ = _objective(after, tuned, objective, position, speeds, terms)
    phys = prob.physical(u_best)
    tuned_abs = []
    for aid, (f, z, m) in zip(ids, phys, strict=True):
        k = m * (2 * math.pi * f) ** 2
        tuned_abs.append(
            {"id": aid, "mass": m, "stiffness": k, "damping": 2 * z * math.sqrt(k * m), "frequency_hz": f,
             "damping_ratio": z}
        )  # fmt: skip
    u_dh = unit(dh)
    dh_width = float(prob.candidates(u_dh)[0][0])
    dh_list = []
    for aid, (f, z, m), (fh, hm) in zip(ids, prob.physical(u_dh), hosts, strict=True):
        dh_list.append(
            {"id": aid, "mass": m, "frequency_hz": f, "damping_ratio": z, "host_hz": fh, "host_mass": hm}
        )
    starts_info = tuple(
        {
            "label": lb,
            "start": prob.physical(us),
            "end": prob.physical(ub),
            "width": float(wb),
            "iterations": int(it),
        }
        for lb, us, ub, wb, it in runs
    )
    return AbsorberDesign(
        absorbers=tuple(tuned_abs),
        objective=objective,
        width=width,
        bare_width=bare_width,
        den_hartog=tuple(dh_list),
        den_hartog_width=dh_width,
        before=before if before is not None else after,
        after=after,
        starts=starts_info,
        model=tuned,
        elapsed=time.perf_counter() - t0,
        evaluations=prob.evaluations,
    )


def _objective(
    d: Any, model: Model, objective: str, position: Any, speeds: np.ndarray, terms: Any
) -> tuple[float, float]:
    """The objective of a diagram polished to round-off (m) and its chatter frequency (Hz)."""
    L = loop_matrices(model, position=position, speeds=speeds, terms=terms)
    lim = limits_of(d, L, speeds=False)
    cp = lim.minimum if objective == "minimum" else lim.absolute
    if cp is None:
        return float("inf"), float("nan")
    return float(cp.b), float(cp.frequency_hz)
