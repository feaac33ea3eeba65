"""The joint distribution of a model's uncertain fields, as a map from the
unit cube: :class:`InputSpace`.

A point ``u`` of the unit cube (one coordinate per *dimension*) becomes one
value per uncertain field by the inverse distribution function of its
marginal; a correlated group takes as many dimensions as it has members,
turned into standard normals ``z = Phi^-1(u)``, correlated by ``y = L z``
with ``L L^T = R`` (the group's correlation) and handed to each member's
marginal through ``Phi(y)`` -- a Gaussian copula, which for normal marginals
(a covariance group) is exactly the multivariate normal: there ``x = mean +
std * y`` directly.  The *factors* of a variance-based sensitivity analysis
are the independent units: a field of its own, or a whole group.

A zero-width marginal (``std = 0``, or a uniform with ``low = high``) gives
its mean exactly, whatever ``u``: with every width zero the samples are the
model itself.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError
from ..model import CorrelatedGroup, Marginal, UncertaintyTable, uncertainty_of

__all__ = ["InputSpace"]

#: a point of the unit cube is kept this far from 0 and 1, so that Phi^-1 stays finite
#: (scrambled Sobol' and PCG64 points lie on a 2^-53 grid: 0 can occur)
_EDGE = 2.0**-54


@dataclass(frozen=True, eq=False)
class InputSpace:
    """The uncertain fields of a model and their joint distribution.

    Attributes
    ----------
    marginals : tuple of Marginal
        One per uncertain field, in the order of :attr:`paths`.
    groups : tuple of CorrelatedGroup
        Correlated fields (a Gaussian copula).
    factors : tuple of tuple of int
        The independent units, as indices into :attr:`marginals`: a field
        of its own, or a group's members.
    source : str
        Where the table was read.
    """

    marginals: tuple[Marginal, ...]
    groups: tuple[CorrelatedGroup, ...] = ()
    source: str = ""

    # ------------------------------------------------------------------ construction
    @classmethod
    def of(cls, model: Any) -> InputSpace:
        """The ``[uncertainty]`` table of a model (docs/model-format.md);
        an :class:`InputError` when it has none."""
        table = uncertainty_of(model)
        if table is None:
            raise InputError(
                f"{model.source} has no [uncertainty] table: name the uncertain fields and their distributions"
                ' there, e.g. "coupling.cut.Kf" = { distribution = "lognormal", cv = 0.1 } (docs/uncertainty.md)'
            )
        return cls.from_table(table)

    @classmethod
    def from_table(cls, table: UncertaintyTable) -> InputSpace:
        return cls(table.marginals, table.groups, table.source)

    @classmethod
    def from_dict(cls, spec: Mapping[str, Any], nominal: Mapping[str, float] | None = None) -> InputSpace:
        """A space from a mapping written like the model file's table
        (``{"x": {"distribution": "normal", "mean": 0, "std": 1}, "group":
        [...]}``); ``nominal`` gives the values of fields whose entries
        leave out their mean.  For functions that are not a model (tests,
        studies of a closed form)."""
        import json

        names = [p for p in spec if p != "group"] + [
            p for g in spec.get("group", []) for p in g.get("parameters", [])
        ]
        # each name a field of a [model] table, path model.NAME, holding its nominal value if given
        raw: dict[str, Any] = {"model": {n: float(v) for n, v in (nominal or {}).items() if n in names}}
        table = {f"model.{k}" if k != "group" else k: v for k, v in spec.items()}
        if "group" in table:
            table["group"] = [
                {**g, "parameters": [f"model.{p}" for p in g.get("parameters", [])]} for g in table["group"]
            ]

        text = json.dumps({**raw, "uncertainty": table})

        class _M:  # the little a table needs of a model
            source = "<dict>"
            variant = None
            overrides: tuple[tuple[str, Any], ...] = ()
            raw = text

        m = _M()
        t = uncertainty_of(m)
        assert t is not None
        strip = [Marginal(**{**mg.__dict__, "path": mg.path.removeprefix("model.")}) for mg in t.marginals]
        groups = [
            CorrelatedGroup(tuple(p.removeprefix("model.") for p in g.paths), g.correlation, g.given)
            for g in t.groups
        ]
        return cls(tuple(strip), tuple(groups), "<dict>")

    # ------------------------------------------------------------------ structure
    @property
    def paths(self) -> tuple[str, ...]:
        """The uncertain fields' parameter paths."""
        return tuple(m.path for m in self.marginals)

    @property
    def factors(self) -> tuple[tuple[int, ...], ...]:
        """Independent units (indices into :attr:`marginals`), ungrouped fields
        first in file order, then the groups."""
        grouped = {p for g in self.groups for p in g.paths}
        idx = {p: i for i, p in enumerate(self.paths)}
        single = tuple((i,) for i, p in enumerate(self.paths) if p not in grouped)
        return single + tuple(tuple(idx[p] for p in g.paths) for g in self.groups)

    @property
    def factor_names(self) -> tuple[str, ...]:
        """A name per factor: the field's path, or the group's paths joined by ``+``."""
        return tuple("+".join(self.paths[i] for i in f) for f in self.factors)

    def sensitivity_factors(
        self, factors: Mapping[str, Any] | None = None
    ) -> tuple[tuple[tuple[int, ...], ...], tuple[str, ...]]:
        """The factors of a Sobol' analysis: the independent units
        (:attr:`factors`), or, with ``factors`` (``{name: [pattern, ...]}``,
        shell patterns of parameter paths such as ``"mode.*"``), named
        unions of them -- one index per question a user asks ("the tap test
        or the cutting test?") -- and the units no pattern names, each on
        its own.  Returns (the unit-cube dimensions of each factor, names);
        a pattern that names nothing, a field named twice or a correlated
        group split between names is an :class:`InputError`."""
        import fnmatch

        base, dims, names = self.factors, self.factor_dims(), self.factor_names
        if not factors:
            return dims, names
        taken: dict[int, str] = {}
        out_dims: list[tuple[int, ...]] = []
        out_names: list[str] = []
        for name, pats in factors.items():
            pats = [pats] if isinstance(pats, str) else list(pats)
            hit = [i for i, p in enumerate(self.paths) if any(fnmatch.fnmatchcase(p, pat) for pat in pats)]
            if not hit:
                raise InputError(
                    f"factor {name!r}: {', '.join(map(repr, pats))} names no uncertain field"
                    f" (the fields: {', '.join(self.paths)})"
                )
            units = [k for k, f in enumerate(base) if set(f) & set(hit)]
            for k in units:
                if not set(base[k]) <= set(hit):
                    raise InputError(
                        f"factor {name!r} takes part of a correlated group ({names[k]}): a group is one factor,"
                        " name all of its fields"
                    )
                if k in taken:
                    raise InputError(f"{names[k]} is in factor {taken[k]!r} and in factor {name!r}")
                taken[k] = name
            out_dims.append(tuple(d for k in units for d in dims[k]))
            out_names.append(str(name))
        for k in range(len(base)):
            if k not in taken:
                out_dims.append(dims[k])
                out_names.append(names[k])
        return tuple(out_dims), tuple(out_names)

    @property
    def dims(self) -> int:
        """Dimensions of the unit cube (one per field)."""
        return len(self.marginals)

    def factor_dims(self) -> tuple[tuple[int, ...], ...]:
        """The unit-cube dimensions of each factor (the cube's coordinates are
        ordered factor by factor)."""
        out, k = [], 0
        for f in self.factors:
            out.append(tuple(range(k, k + len(f))))
            k += len(f)
        return tuple(out)

    @property
    def zero_width(self) -> bool:
        """Every distribution has zero width: the samples are the model."""
        return all(m.zero_width for m in self.marginals)

    def fingerprint(self) -> str:
        """A text that identifies the distributions (for checkpoints)."""
        import hashlib

        parts = [repr((m.path, m.kind, m.mean, m.std, m.lower, m.upper)) for m in self.marginals]
        parts += [repr((g.paths, g.correlation.tobytes().hex(), g.given)) for g in self.groups]
        return hashlib.sha1("\n".join(parts).encode()).hexdigest()[:16]

    # ------------------------------------------------------------------ the map
    def transform(self, u: Any) -> np.ndarray:
        """Values of the fields (n, len(paths)) at points ``u`` (n, dims) of
        the unit cube, ordered as :meth:`factor_dims`."""
        from scipy.special import ndtr, ndtri

        u = np.clip(np.atleast_2d(np.asarray(u, float)), _EDGE, 1.0 - _EDGE)
        if u.shape[1] != self.dims:
            raise InputError(f"points of the unit cube need {self.dims} coordinates (got {u.shape[1]})")
        x = np.empty((u.shape[0], self.dims))
        group_of = {p: g for g in self.groups for p in g.paths}
        for f, cols in zip(self.factors, self.factor_dims(), strict=True):
            first = self.marginals[f[0]]
            g = group_of.get(first.path)
            if g is None:
                x[:, f[0]] = _ppf(first, u[:, cols[0]])
                continue
            y = ndtri(u[:, list(cols)]) @ _root(g.correlation).T
            for k, i in enumerate(f):
                m = self.marginals[i]
                if m.kind == "normal" and not _truncated(m):
                    x[:, i] = m.mean if m.zero_width else m.mean + m.std * y[:, k]
                else:
                    x[:, i] = _ppf(m, ndtr(y[:, k]))
        return x

    def values(self, u: Any) -> list[dict[str, float]]:
        """:meth:`transform` as one ``{path: value}`` per point."""
        x = self.transform(u)
        return [dict(zip(self.paths, row.tolist(), strict=True)) for row in x]

    def describe(self) -> list[str]:
        """One line per field: its path and distribution (and its group)."""
        out = [f"{m.path}: {m.describe()}" for m in self.marginals]
        for g in self.groups:
            out.append(f"correlated ({g.given}): {', '.join(g.paths)}")
        return out


def _truncated(m: Marginal) -> bool:
    return m.kind != "uniform" and (math.isfinite(m.lower) or math.isfinite(m.upper))


def _root(R: np.ndarray) -> np.ndarray:
    """L with L L^T = R for a positive semi-definite R (by its eigenvalues, so
    a singular R -- perfectly correlated fields -- is taken)."""
    lam, V = np.linalg.eigh(R)
    return V * np.sqrt(np.maximum(lam, 0.0))


def _ppf(m: Marginal, u: np.ndarray) -> np.ndarray:
    """The inverse distribution function of a marginal at ``u`` in (0, 1)."""
    from scipy import stats
    from scipy.special import ndtri

    if m.zero_width:
        return np.full(u.shape, m.mean)
    if m.kind == "uniform":
        return m.lower + (m.upper - m.lower) * u
    if m.kind == "normal":
        if not _truncated(m):
            return m.mean + m.std * ndtri(u)
        a, b = (m.lower - m.mean) / m.std, (m.upper - m.mean) / m.std
        return np.asarray(stats.truncnorm.ppf(u, a, b, loc=m.mean, scale=m.std))
    # lognormal with the field's mean and std: log x ~ N(mu, s^2), s^2 = ln(1 + cv^2), mu = ln mean - s^2/2
    s2 = math.log1p((m.std / m.mean) ** 2)
    s, mu = math.sqrt(s2), math.log(m.mean) - 0.5 * s2
    if not _truncated(m):
        return np.exp(mu + s * ndtri(u))
    lo = (math.log(m.lower) - mu) / s if m.lower > 0 else -math.inf
    hi = (math.log(m.upper) - mu) / s if math.isfinite(m.upper) else math.inf
    return np.exp(np.asarray(stats.truncnorm.ppf(u, lo, hi, loc=mu, scale=s)))
