"""Chatter quantities as pure functions of a grid point, for sweeps.

:mod:`chatterlab.sweep._engine` knows nothing about chatter; this module supplies the
picklable callables it maps over a grid:

* :class:`AtlasTask` -- b_lim at (position, speed): the stability atlas along
  the stroke (the boundary of each position is computed once per worker and
  cached);
* :class:`QuantityTask` -- one quantity (rightmost root, b_lim at a speed,
  minimum b_lim over all speeds, natural frequencies) at a grid point whose
  axes are width, speed, delay, position or any model parameter addressed by
  its path (``spring.leg3-foundation.c2``).

Grid axes use SI units: width in m, delay in s, position in m, speed in the
model's process unit.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Any, Literal, cast

import numpy as np

from ..errors import InputError, check_delay, check_position, check_speed, check_width
from ..model._items import Model
from ..model._uncertainty import parameter_value

__all__ = ["AtlasTask", "QuantityTask", "QUANTITIES", "KIND_CODES", "model_fingerprint", "axis_name"]

# The tasks keep ``terms: str`` (it comes from the command line); Boundary and stability
# refuse any other value with an InputError, so the casts below only inform the type checker.
_LobeTerms = Literal["pdo", "o"]
_Terms = Literal["pdo", "pd", "o", "none"]


def axis_name(path: str) -> str:
    """A grid-axis (netCDF variable) name for a model parameter path:
    ``spring.leg3-foundation.c2`` -> ``spring_leg3_foundation_c2``."""
    import re

    name = re.sub(r"[^0-9A-Za-z_]", "_", path)
    return name if not name[:1].isdigit() else f"p_{name}"


#: quantity name -> {output name: unit}
QUANTITIES: dict[str, dict[str, str]] = {
    "rightmost-root": {"abscissa": "1/s", "frequency": "Hz"},
    "stable": {"stable": "1", "abscissa": "1/s"},
    "b-lim": {"b_lim": "m", "chatter_frequency": "Hz"},
    "min-b-lim": {"b_lim_min": "m", "chatter_frequency": "Hz"},
    "natural-frequencies": {"f1": "Hz", "f2": "Hz", "f3": "Hz"},
    # milling models (Floquet, spectral elements): at (width = a_p, speed = rpm)
    "spectral-radius": {"spectral_radius": "1", "stable": "1", "kind": "1", "error": "1"},
    # milling models: the limit depth at a speed, searched up to width_max
    "a-lim": {"a_lim": "m", "chatter_frequency": "Hz", "kind": "1"},
}
#: the ``kind`` output of the milling quantities: the type of the critical multiplier
KIND_CODES = {"": 0.0, "hopf": 1.0, "flip": 2.0, "fold": 3.0}
_BUILTIN_AXES = {"width", "speed", "delay", "position"}

_CACHE: OrderedDict[tuple[Any, ...], Any] = OrderedDict()


def _cached(key: tuple[Any, ...], make: Any) -> Any:
    hit = _CACHE.get(key)
    if hit is None:
        hit = make()
        _CACHE[key] = hit
        if len(_CACHE) > 16:
            _CACHE.popitem(last=False)
    else:
        _CACHE.move_to_end(key)
    return hit


def model_fingerprint(model: Model) -> str:
    """A short :func:`joblib.hash` of everything that defines the model (for
    checkpoints): the parsed file, the variant and overrides, and the
    matrices a ``[matrices]`` table reads from other files -- by content, so
    an edited ``K.npy`` is another model although the model file is the same."""
    import joblib

    m = model.matrices
    matrices = None if m is None else (m.coordinates, m.M, m.L, m.K, m.given)
    return str(joblib.hash((model.raw, model.variant, model.overrides, matrices), hash_name="sha1"))[:16]


@dataclass(frozen=True, eq=False)
class AtlasTask:
    """b_lim (m) and chatter frequency (Hz) at a (position, speed) point.

    The first call at a position computes the boundary and the envelope at
    all ``speeds`` at once (vectorised) and caches them in the worker; the
    atlas sweep uses chunks of one position so each is computed once.
    """

    model: Model
    width_max: float
    speeds: tuple[float, ...]
    terms: str = "pdo"
    fmin: float | None = None
    fmax: float | None = None
    key: str = field(default="", repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "width_max", check_width(self.width_max, "width_max"))
        unit = self.model.process.speed_unit if self.model.process is not None else ""
        for v in self.speeds:
            check_speed(v, "speed", unit)
        if self.model.process is not None and self.speeds:
            self.model.process.delay(np.asarray(self.speeds, dtype=float))  # and their delays
        object.__setattr__(self, "key", model_fingerprint(self.model))

    def boundary(self, position: float) -> Any:
        from ..lobes._diagram import Boundary
        from ..structure._assembly import assemble

        def make() -> Any:
            sy = _cached(("system", self.key), lambda: assemble(self.model))
            return Boundary(
                sy.at(position),
                width_max=self.width_max,
                terms=cast(_LobeTerms, self.terms),
                fmin=self.fmin,
                fmax=self.fmax,
            )

        return _cached(
            ("boundary", self.key, float(position), self.width_max, self.terms, self.fmin, self.fmax), make
        )

    def row(self, position: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(speeds, b_lim, chatter Hz) along all speeds at one position."""
        proc = self.model.process
        assert proc is not None
        v = np.asarray(self.speeds, dtype=float)
        T = np.asarray(proc.delay(v)) if proc.kind != "delay" else v

        def make() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            b, f, _ = self.boundary(position).envelope(np.atleast_1d(T))
            return v, b, f

        return _cached(
            ("row", self.key, float(position), self.width_max, self.terms, self.fmin, self.fmax), make
        )

    def __call__(self, position: float, speed: float) -> dict[str, float]:
        v, b, f = self.row(position)
        j = int(np.argmin(np.abs(v - speed)))
        if v[j] != speed:
            # a speed off the declared axis: compute it alone
            proc = self.model.process
            assert proc is not None
            T = proc.delay(speed) if proc.kind != "delay" else speed
            bb, ff, _ = self.boundary(position).envelope(np.array([T]))
            return {"b_lim": float(bb[0]), "chatter_frequency": float(ff[0])}
        return {"b_lim": float(b[j]), "chatter_frequency": float(f[j])}


@dataclass(frozen=True, eq=False)
class QuantityTask:
    """One chatter quantity at a grid point (see :data:`QUANTITIES`).

    ``fixed`` holds values for the built-in axes that are not on the grid
    (``width`` m, ``speed``, ``delay`` s, ``position`` m); grid axes whose
    names contain a dot are model parameter paths.
    """

    model: Model
    quantity: str
    fixed: dict[str, float] = field(default_factory=dict)
    terms: str = "pdo"
    width_max: float = 0.05
    aliases: dict[str, str] = field(default_factory=dict)  #: grid axis name -> parameter path
    key: str = field(default="", repr=False)

    def __post_init__(self) -> None:
        if self.quantity not in QUANTITIES:
            raise InputError(f"unknown quantity '{self.quantity}' (known: {', '.join(QUANTITIES)})")
        if getattr(self.model, "frf", None) is not None:  # refused once, before the work, not in every task
            raise InputError(
                f"{self.model.source}: its structure is a measured FRF ([frf]), which has no matrices for the sweep's"
                " quantities; draw its lobes (chatterlab lobes), or fit modes to it"
                " (chatterlab.structure.fit_modes(...).to_model(), docs/tap-test.md) and sweep that model"
            )
        object.__setattr__(self, "width_max", check_width(self.width_max, "width_max"))
        if self.quantity in ("stable", "rightmost-root", "b-lim", "min-b-lim"):
            from ..lobes._milling_model import is_milling

            if is_milling(self.model):  # these are the time-averaged loop's: flip lobes are not in it
                raise InputError(
                    f"{self.model.source}: quantity '{self.quantity}' of a milling model would be its"
                    " time-averaged (zeroth-order) loop's, which misses the flip lobes; use --quantity"
                    " spectral-radius (stable where < 1) or a-lim (the Floquet limit depth)"
                )
        unknown = set(self.fixed) - _BUILTIN_AXES
        if unknown:
            raise InputError(
                f"fixed values are for {', '.join(sorted(_BUILTIN_AXES))}, not {', '.join(sorted(unknown))}"
            )
        object.__setattr__(self, "fixed", self._checked(self.fixed, "{}"))
        object.__setattr__(self, "key", model_fingerprint(self.model))

    def _checked(self, values: dict[str, float], label: str) -> dict[str, float]:
        """The built-in axis values checked by the one validator set (width,
        speed and delay > 0, position finite); ``label`` formats the name."""
        proc = self.model.process
        unit = {"width": "m", "speed": proc.speed_unit if proc else "", "delay": "s", "position": "m"}
        check = {"width": check_width, "speed": check_speed, "delay": check_delay, "position": check_position}
        out = {}
        for k, v in values.items():
            out[k] = check[k](v, label.format(k), unit[k]) if k in check else v
        if "position" in out and self.model.movable is not None:
            check_position(out["position"], label.format("position"), within=self.model.movable.range)
        if "speed" in out and proc is None:
            raise InputError(
                f"{self.model.source} has no [process] table, so a speed cannot be turned into a delay;"
                " give the delay instead"
            )
        if "speed" in out and proc is not None:
            proc.delay(out["speed"])  # the delay it gives is checked too (errors.check_delay)
        return out

    def check_grid(self, grid: Any) -> None:
        """Refuse a grid whose axes are unknown (see :meth:`check_axes`) or
        whose built-in axes hold invalid values (a width, speed or delay
        <= 0, a non-finite position), before anything is computed."""
        self.check_axes(list(grid.names), {ax.name: np.asarray(ax.values).tolist() for ax in grid.axes})
        for ax in grid.axes:
            name = self.aliases.get(ax.name, ax.name)
            if name in _BUILTIN_AXES:
                for v in np.asarray(ax.values, dtype=float).tolist():
                    self._checked({name: v}, "grid axis {}")

    @property
    def outputs(self) -> dict[str, str]:
        return QUANTITIES[self.quantity]

    def check_axes(
        self, names: list[str] | tuple[str, ...], values: dict[str, list[Any]] | None = None
    ) -> None:
        """Refuse grid axes that are neither built in nor model parameters.

        A parameter path is checked by building the model at the ends of its
        axis (``values``), so every documented field can be swept, also one the
        file leaves at its default; without values, at the file's own value."""
        params = {}
        for axis in names:
            nm = self.aliases.get(axis, axis)
            if nm in _BUILTIN_AXES:
                continue
            if "." not in nm:
                raise InputError(
                    f"grid axis '{nm}' is not one of {', '.join(sorted(_BUILTIN_AXES))} and not a model"
                    " parameter path KIND.ID.FIELD (e.g. spring.leg3-foundation.c2)"
                )
            given = (values or {}).get(axis) or (values or {}).get(nm)
            if given:
                for v in (given[0], given[-1]):
                    self.model.with_parameters({nm: v})
            else:
                params[nm] = parameter_value(self.model, nm)
        if params:
            self.model.with_parameters(params)
        if (
            self.quantity in ("rightmost-root", "stable", "spectral-radius")
            and "width" not in names
            and "width" not in self.fixed
        ):
            raise InputError(
                f"quantity '{self.quantity}' needs a width of cut: put width on the grid (--grid width=MIN:MAX:N,"
                " mm) or give --width"
            )

    def __call__(self, **point: float) -> dict[str, float]:
        from ..structure._assembly import assemble

        params = {self.aliases.get(k, k): float(v) for k, v in point.items() if k not in _BUILTIN_AXES}
        vals = {**self.fixed, **self._checked({k: v for k, v in point.items() if k in _BUILTIN_AXES}, "{}")}
        pkey = tuple(sorted(params.items()))

        def make_system() -> Any:
            mdl = self.model.with_parameters(params) if params else self.model
            return assemble(mdl)

        sy = _cached(("system", self.key, pkey), make_system)
        pos = vals.get("position")
        q = self.quantity
        if q == "natural-frequencies":
            from ..structure._modal import modes

            f = modes(sy, count=3, position=pos).frequency_hz
            f = np.concatenate([f, np.full(3, np.nan)])[:3]
            return {"f1": float(f[0]), "f2": float(f[1]), "f3": float(f[2])}
        fz = _cached(("frozen", self.key, pkey, pos), lambda: sy.at(pos))
        if q in ("spectral-radius", "a-lim"):
            return self._milling(sy, fz, vals, pkey, pos)
        if q in ("rightmost-root", "stable"):
            from ..frequency._stability import stability

            if "width" not in vals:
                raise InputError(f"quantity '{q}' needs a width: put 'width' on the grid or give it")
            st = stability(
                fz,
                width=vals["width"],
                speed=vals.get("speed"),
                delay=vals.get("delay"),
                terms=cast(_Terms, self.terms),
                winding=False,
            )
            if q == "stable":
                # 1 stable, 0 unstable, NaN undetermined or marginal: as spectral-radius's
                code = {"stable": 1.0, "unstable": 0.0}.get(st.verdict, float("nan"))
                return {"stable": code, "abscissa": st.abscissa}
            return {"abscissa": st.abscissa, "frequency": st.chatter_hz}
        from ..lobes._diagram import Boundary

        bd = _cached(
            ("boundary", self.key, pkey, pos, self.width_max, self.terms),
            lambda: Boundary(fz, width_max=self.width_max, terms=cast(_LobeTerms, self.terms)),
        )
        if q == "min-b-lim":
            m = bd.absolute_minimum()
            return {"b_lim_min": float(m["width"]), "chatter_frequency": float(m["chatter_hz"])}
        proc = sy.model.process
        if "delay" in vals:
            T = vals["delay"]
        elif "speed" in vals and proc is not None:
            T = float(proc.delay(vals["speed"]))
        elif proc is not None:
            T = float(proc.delay())
        else:
            raise InputError("quantity 'b-lim' needs a speed or a delay")
        b, f, _ = bd.envelope(np.array([T]))
        return {"b_lim": float(b[0]), "chatter_frequency": float(f[0])}

    def _milling(self, sy: Any, fz: Any, vals: dict[str, float], pkey: Any, pos: Any) -> dict[str, float]:
        """The Floquet quantities of a milling model (docs/milling.md): the
        spectral radius at (a_p, rpm) with its convergence check, or the
        limit depth a_lim at a speed (inf: stable at every scanned depth
        up to ``width_max``)."""
        from ..frequency._floquet import multipliers
        from ..lobes._milling import milling_lobes
        from ..lobes._milling_model import is_milling, model_milling_loop

        mdl = sy.model
        if not is_milling(mdl):
            raise InputError(
                f"quantity '{self.quantity}' is for milling models ([process] kind = \"milling\");"
                f" {mdl.source} is {mdl.process.kind if mdl.process else 'without a process'}"
            )

        def structure() -> Any:
            return model_milling_loop(fz)[0]

        S = _cached(("tool", self.key, pkey, pos), structure)
        rpm = float(vals.get("speed", mdl.process.speed))
        if "delay" in vals:
            raise InputError("milling quantities take the spindle speed (speed, rpm), not a delay")
        if self.quantity == "spectral-radius":
            r = multipliers(S, rpm, vals["width"])
            rho, err = float(r.spectral_radius), float(r.error)
            verdict = 1.0 if rho + err < 1.0 else 0.0 if rho - err > 1.0 else float("nan")
            return {
                "spectral_radius": rho,
                "stable": verdict,
                "kind": KIND_CODES.get(r.kind, -1.0),
                "error": err,
            }
        ml = milling_lobes(S, np.array([rpm]), depth_max=self.width_max)
        return {
            "a_lim": float(ml.a_lim[0]),
            "chatter_frequency": float(ml.chatter_hz[0]),
            "kind": KIND_CODES.get(str(ml.kind[0]), -1.0),
        }
