"""The ``[uncertainty]`` table of a model file: which fields are uncertain
and how (docs/model-format.md, "[uncertainty]"; the analysis is
:mod:`chatterlab.uncertainty`).

Every numeric field a parameter path addresses (``coupling.cut.Kf``,
``mode.y1.damping_ratio``, ``spring.holder.c1``; an entry of a list-valued
field as ``coupling.cut.DO[1][1]``) may carry a distribution::

    [uncertainty]
    "coupling.cut.Kf" = { distribution = "lognormal", cv = 0.08 }
    "mode.y1.frequency_hz" = { distribution = "normal", std = 0.063 }
    "mode.y1.damping_ratio" = { distribution = "normal", std = 8.7e-5, lower = 0.0 }
    "spring.holder.c1" = { distribution = "uniform", low = 0.9e7, high = 1.1e7 }

    [[uncertainty.group]]             # correlated fields
    parameters = ["mode.t1.frequency_hz", "mode.t2.frequency_hz"]
    covariance = [[2.4e-3, 2.4e-3], [2.4e-3, 2.4e-3]]

The reader hands the table to :func:`read_uncertainty` (one call, before it
checks the table names), which checks it against the file and sets it
aside; :func:`uncertainty_of` reads it back from a built model, with each
distribution's location resolved to the field's value in that model (after
``[variant.NAME]`` and the overrides).  Every problem is one
:class:`~chatterlab.errors.ModelError` line naming the file, the entry and
the fix.
"""

from __future__ import annotations

import copy
import difflib
import json
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ModelError
from ._fields import LIST_TABLES, PARAMETER_TABLES

__all__ = [
    "Marginal",
    "CorrelatedGroup",
    "UncertaintyTable",
    "read_uncertainty",
    "uncertainty_of",
    "parameter_value",
    "parameter_overrides",
    "DISTRIBUTIONS",
]

#: the distributions an entry may name
DISTRIBUTIONS = ("normal", "lognormal", "uniform")

_KEYS = {
    "normal": ("distribution", "mean", "std", "cv", "lower", "upper", "description"),
    "lognormal": ("distribution", "mean", "std", "cv", "lower", "upper", "description"),
    "uniform": ("distribution", "mean", "low", "high", "half_width", "description"),
}
_GROUP_KEYS = ("parameters", "covariance", "correlation", "mean", "description")
_INDEX = re.compile(r"\[(\d+)\]")
_PATH = re.compile(r"^([^\[\]]+)((?:\[\d+\])*)$")


@dataclass(frozen=True)
class Marginal:
    """One uncertain field: its distribution, in the field's SI unit.

    ``kind`` is ``"normal"``, ``"lognormal"`` (``mean`` and ``std`` of the
    field itself) or ``"uniform"`` (on ``[lower, upper]``; ``mean`` its
    centre, ``std`` = (upper - lower)/sqrt(12)).  For the first two,
    ``lower``/``upper`` truncate the distribution (``mean`` and ``std``
    are then those of the distribution before truncation).  ``nominal`` is
    the field's value in the model; ``std == 0`` (or ``lower == upper`` for
    a uniform) is a zero-width distribution: every sample is ``mean``
    exactly.
    """

    path: str
    kind: str
    mean: float
    std: float
    lower: float = -math.inf
    upper: float = math.inf
    nominal: float = math.nan

    @property
    def zero_width(self) -> bool:
        return self.std == 0.0 or (self.kind == "uniform" and self.lower == self.upper)

    def describe(self) -> str:
        """The distribution in words (``normal(mean 2e+09, std 1e+08)``)."""
        if self.kind == "uniform":
            return f"uniform({self.lower:.6g} .. {self.upper:.6g})"
        trunc = []
        if math.isfinite(self.lower):
            trunc.append(f">= {self.lower:.6g}")
        if math.isfinite(self.upper):
            trunc.append(f"<= {self.upper:.6g}")
        cut = f", truncated {' and '.join(trunc)}" if trunc else ""
        return f"{self.kind}(mean {self.mean:.6g}, std {self.std:.4g}{cut})"


@dataclass(frozen=True, eq=False)
class CorrelatedGroup:
    """Fields whose variations are correlated: the correlation matrix of the
    standard normals behind their marginals (a Gaussian copula; for normal
    marginals, exactly the multivariate normal of the covariance given).
    ``correlation`` is symmetric positive semi-definite with unit diagonal
    (rows of a zero-width member are those of the identity)."""

    paths: tuple[str, ...]
    correlation: np.ndarray
    given: str  #: ``"covariance"`` or ``"correlation"``: what the file gave


@dataclass(frozen=True, eq=False)
class UncertaintyTable:
    """The ``[uncertainty]`` table of a model: one :class:`Marginal` per
    uncertain field (file order) and the :class:`CorrelatedGroup` s among
    them."""

    marginals: tuple[Marginal, ...]
    groups: tuple[CorrelatedGroup, ...] = ()
    source: str = ""

    @property
    def paths(self) -> tuple[str, ...]:
        return tuple(m.path for m in self.marginals)

    def marginal(self, path: str) -> Marginal:
        for m in self.marginals:
            if m.path == path:
                return m
        raise KeyError(path)


# ---------------------------------------------------------------------------- parameter values


def split_path(path: str) -> tuple[str, tuple[int, ...]]:
    """``"coupling.cut.DO[1][1]"`` -> ``("coupling.cut.DO", (1, 1))``."""
    m = _PATH.match(path)
    if not m:
        raise ValueError(path)
    return m.group(1), tuple(int(i) for i in _INDEX.findall(m.group(2)))


#: what a path that addresses no field is told (the model's one wording, for --set, sweeps and [uncertainty])
NOT_A_PATH = (
    "is not a parameter path: write KIND.ID.FIELD (e.g. coupling.cut.Kf, mode.y1.damping_ratio),"
    " TABLE.FIELD (e.g. process.rpm), or an entry of a list field, coupling.cut.DO[1][1]"
)


def _lookup(raw: Mapping[str, Any], base: str) -> tuple[bool, Any, str]:
    """(found, value, where) of a field path in the parsed file; ``where``
    says what is missing when not found."""
    parts = base.split(".")
    if len(parts) == 3 and parts[0] in LIST_TABLES:
        kind, iid, fld = parts
        items = raw.get(kind, [])
        for it in items if isinstance(items, list) else []:
            if isinstance(it, dict) and it.get("id") == iid:
                return (fld in it), it.get(fld), f'[[{kind}]] "{iid}" has no field {fld!r}'
        known = [str(it.get("id")) for it in items if isinstance(it, dict)] if isinstance(items, list) else []
        return False, None, f"there is no [[{kind}]] with id {iid!r} (known: {', '.join(known) or 'none'})"
    if len(parts) == 2 and parts[0] in PARAMETER_TABLES:
        table = raw.get(parts[0])
        if not isinstance(table, dict):
            return False, None, f"the file has no [{parts[0]}] table"
        return (parts[1] in table), table.get(parts[1]), f"[{parts[0]}] has no field {parts[1]!r}"
    if parts[0] == "matrices":
        return (
            False,
            None,
            "[matrices] entries are not parameters (give the model as [[mode]] tables, or vary a factor)",
        )
    return False, None, NOT_A_PATH


def _resolved(
    raw: Mapping[str, Any], variant: str | None, overrides: Mapping[str, Any] | None, base: str
) -> Any:
    """The value a field path holds after the variant and the overrides, in
    the reader's order (the file, then ``[variant.NAME]``, then overrides)."""
    if overrides and base in overrides:
        return True, overrides[base], ""
    variants = raw.get("variant")
    if variant and isinstance(variants, dict) and isinstance(variants.get(variant), dict):
        if base in variants[variant]:
            return True, variants[variant][base], ""
    return _lookup(raw, base)


def _index(value: Any, idx: tuple[int, ...]) -> tuple[bool, Any]:
    for i in idx:
        if not isinstance(value, list) or i >= len(value):
            return False, None
        value = value[i]
    return True, value


def _or_nan(x: float | None) -> float:
    return math.nan if x is None else x


def _number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(float(v))


def parameter_value(model: Any, path: str) -> float:
    """The number the field ``path`` holds in ``model`` (after its variant and
    overrides); a :class:`ModelError` when the file does not write it or it
    is not a number."""
    raw = json.loads(model.raw)
    base, idx = split_path(path)
    found, value, why = _resolved(raw, model.variant, dict(model.overrides), base)
    if found:
        found, value = _index(value, idx)
        why = f"{base} has no entry {''.join(f'[{i}]' for i in idx)}"
    if not found:
        raise ModelError(f"parameter {path!r}{' ' if why == NOT_A_PATH else ': '}{why}", source=model.source)
    if not _number(value):
        raise ModelError(f"parameter {path!r} is not a number (got {value!r})", source=model.source)
    return float(value)


def parameter_overrides(model: Any, values: Mapping[str, float]) -> dict[str, Any]:
    """``{path: value}`` as the overrides of :meth:`Model.with_parameters`:
    entries of a list-valued field (``coupling.cut.DO[1][1]``) are written
    into a copy of the field's value in ``model``."""
    out: dict[str, Any] = {}
    raw: dict[str, Any] | None = None
    for path, v in values.items():
        base, idx = split_path(path)
        if not idx:
            out[base] = float(v)
            continue
        if base not in out:
            raw = json.loads(model.raw) if raw is None else raw
            out[base] = copy.deepcopy(_resolved(raw, model.variant, dict(model.overrides), base)[1])
        target = out[base]
        for i in idx[:-1]:
            target = target[i]
        target[idx[-1]] = float(v)
    return out


# ---------------------------------------------------------------------------- reading


def read_uncertainty(
    src: str, raw: dict[str, Any], variant: str | None = None, overrides: Mapping[str, Any] | None = None
) -> None:
    """The reader's hook: take the ``[uncertainty]`` table out of ``raw`` and
    check it against the file (a :class:`ModelError` naming the entry);
    the table stays in the model's ``raw`` text, where
    :func:`uncertainty_of` reads it."""
    table = raw.pop("uncertainty", None)
    if table is not None:
        _parse(src, table, raw, variant, overrides)


def uncertainty_of(model: Any) -> UncertaintyTable | None:
    """The ``[uncertainty]`` table of ``model`` (None when the file has
    none), each location resolved to the field's value in ``model``."""
    raw = json.loads(model.raw) if model.raw else {}
    table = raw.pop("uncertainty", None)
    if table is None:
        return None
    return _parse(model.source, table, raw, model.variant, dict(model.overrides))


def _err(src: str, entry: str, msg: str) -> ModelError:
    return ModelError(msg, source=src, item=f"[uncertainty] {entry}" if entry else "[uncertainty]")


def _float(src: str, entry: str, d: Mapping[str, Any], key: str) -> float | None:
    if key not in d:
        return None
    v = d[key]
    if not _number(v):
        raise _err(src, entry, f"{key}: must be a finite number (got {v!r})")
    return float(v)


def _parse(
    src: str, table: Any, raw: dict[str, Any], variant: str | None, overrides: Mapping[str, Any] | None
) -> UncertaintyTable:
    if not isinstance(table, dict):
        raise _err(
            src, "", 'must be a table of "PATH" = { distribution = ... } entries (docs/model-format.md)'
        )
    groups_raw = table.get("group", [])
    if not isinstance(groups_raw, list) or not all(isinstance(g, dict) for g in groups_raw):
        raise _err(src, "group", "write each correlated group as a [[uncertainty.group]] table")
    entries = {k: v for k, v in table.items() if k != "group"}
    nominal: dict[str, float | None] = {}
    for path in list(entries) + [
        p for g in groups_raw for p in g.get("parameters", []) if isinstance(p, str)
    ]:
        if path not in nominal:
            nominal[path] = _nominal(src, raw, variant, overrides, path)
    # the groups first: a covariance group defines its members' marginals
    cov_members: dict[str, Marginal] = {}
    groups: list[CorrelatedGroup] = []
    seen: set[str] = set()
    for k, g in enumerate(groups_raw):
        grp, marg = _group(src, k, g, entries, nominal, seen)
        groups.append(grp)
        cov_members.update(marg)
    marginals: list[Marginal] = []
    order = list(entries) + [p for g in groups if g.given == "covariance" for p in g.paths]
    for path in order:
        marginals.append(
            cov_members[path] if path in cov_members else _marginal(src, path, entries[path], nominal[path])
        )
    if not marginals:
        raise _err(src, "", "is empty: name at least one uncertain field, or remove the table")
    return UncertaintyTable(tuple(marginals), tuple(groups), src)


def _nominal(
    src: str, raw: dict[str, Any], variant: str | None, overrides: Mapping[str, Any] | None, path: str
) -> float | None:
    """The field's value in the model (None when the file leaves it out);
    refuses a path that addresses nothing or a field that is not a number."""
    entry = f'"{path}"'
    try:
        base, idx = split_path(path)
        found, value, why = _resolved(raw, variant, overrides, base)
    except ValueError:
        raise _err(src, entry, NOT_A_PATH) from None
    if why == NOT_A_PATH:
        raise _err(src, entry, NOT_A_PATH)
    if not found:
        if "has no field" in why and not idx:
            return None  # a field the file leaves at its default: the entry must give its location
        raise _err(src, entry, f"addresses nothing: {why}")
    if idx:
        ok, value = _index(value, idx)
        if not ok:
            raise _err(
                src, entry, f"{base} has no entry {''.join(f'[{i}]' for i in idx)} (got {value!r} there)"
            )
    if isinstance(value, list | dict):
        raise _err(
            src,
            entry,
            f"{base} is a list or table, not a number: a distribution is for a numeric field (give an entry,"
            f" e.g. {base}[0])",
        )
    if not _number(value):
        raise _err(src, entry, f"a distribution is for a numeric field; {base} holds {value!r}")
    return float(value)


def _marginal(src: str, path: str, spec: Any, nominal: float | None) -> Marginal:
    entry = f'"{path}"'
    if not isinstance(spec, dict):
        raise _err(
            src,
            entry,
            'write an inline table, e.g. { distribution = "normal", std = 1e5 } (docs/model-format.md)',
        )
    kind = spec.get("distribution")
    if kind not in DISTRIBUTIONS:
        raise _err(
            src,
            entry,
            f"distribution: must be one of {', '.join(DISTRIBUTIONS)} (got {kind!r}); truncate with lower/upper",
        )
    for key in spec:
        if key not in _KEYS[kind]:
            close = difflib.get_close_matches(key, _KEYS[kind], n=1)
            raise _err(
                src,
                entry,
                f"unknown field {key!r} for a {kind} distribution"
                + (f" (did you mean {close[0]!r}?)" if close else "")
                + f"; it takes {', '.join(_KEYS[kind][1:-1])}",
            )
    mean = _float(src, entry, spec, "mean")
    if mean is None:
        mean = nominal
    if kind == "uniform":
        return _uniform(src, entry, path, spec, mean, nominal)
    if mean is None:
        raise _err(src, entry, "the file does not write this field: give the distribution's mean")
    std, cv = _float(src, entry, spec, "std"), _float(src, entry, spec, "cv")
    if (std is None) == (cv is None):
        raise _err(src, entry, "give exactly one of std (in the field's unit) and cv (std / |mean|)")
    if std is not None and not std >= 0:
        raise _err(src, entry, f"std: must be >= 0 (got {std:g}); 0 is a zero-width distribution")
    if cv is not None and not cv >= 0:
        raise _err(src, entry, f"cv: must be >= 0 (got {cv:g}); 0 is a zero-width distribution")
    s = std if std is not None else float(cv) * abs(mean)  # type: ignore[arg-type]
    lo = _float(src, entry, spec, "lower")
    hi = _float(src, entry, spec, "upper")
    lo = -math.inf if lo is None else lo
    hi = math.inf if hi is None else hi
    if kind == "lognormal":
        if not mean > 0:
            raise _err(src, entry, f"a lognormal field is positive: its mean must be > 0 (got {mean:g})")
        if math.isfinite(lo) and lo < 0:
            raise _err(
                src, entry, f"lower: a lognormal field is positive, so lower must be >= 0 (got {lo:g})"
            )
    if not lo < hi:
        raise _err(src, entry, f"lower ({lo:g}) must be below upper ({hi:g})")
    if not lo <= mean <= hi:
        raise _err(src, entry, f"the mean {mean:g} lies outside the truncation [{lo:g}, {hi:g}]")
    return Marginal(path, kind, float(mean), float(s), lo, hi, math.nan if nominal is None else nominal)


def _uniform(
    src: str, entry: str, path: str, spec: dict[str, Any], mean: float | None, nominal: float | None
) -> Marginal:
    low, high = _float(src, entry, spec, "low"), _float(src, entry, spec, "high")
    hw = _float(src, entry, spec, "half_width")
    if hw is not None:
        if low is not None or high is not None:
            raise _err(src, entry, "give either low and high, or half_width (around the mean), not both")
        if not hw >= 0:
            raise _err(src, entry, f"half_width: must be >= 0 (got {hw:g}); 0 is a zero-width distribution")
        if mean is None:
            raise _err(
                src, entry, "the file does not write this field: give the mean the half_width is around"
            )
        low, high = mean - hw, mean + hw
        if hw == 0:
            low = high = mean
    elif low is None or high is None:
        raise _err(src, entry, "a uniform distribution needs low and high (or half_width around the mean)")
    elif "mean" in spec:
        raise _err(src, entry, "a uniform distribution on low..high has its mean at the centre: drop mean")
    if not low <= high:
        raise _err(src, entry, f"low ({low:g}) must not exceed high ({high:g})")
    assert low is not None and high is not None
    centre = low if low == high else 0.5 * (low + high)
    return Marginal(path, "uniform", centre, (high - low) / math.sqrt(12.0), low, high,
                    math.nan if nominal is None else nominal)  # fmt: skip


def _matrix(src: str, entry: str, key: str, value: Any, k: int) -> np.ndarray:
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        a = np.zeros(0)
    if a.shape != (k, k) or not np.all(np.isfinite(a)):
        raise _err(
            src, entry, f"{key}: must be a {k} x {k} list of rows of finite numbers (one per parameter)"
        )
    scale = max(float(np.abs(a).max()), np.finfo(float).tiny)
    if np.abs(a - a.T).max() > 1e-10 * scale:
        raise _err(src, entry, f"{key}: must be symmetric (entry [i][j] equal to [j][i])")
    a = 0.5 * (a + a.T)
    lam = np.linalg.eigvalsh(a)
    # eigenvalues of a symmetric matrix are computed to k eps ||A|| (Golub & Van Loan, 8.1):
    # anything more negative than ten times that is the matrix's own
    if lam.min() < -10 * k * np.finfo(float).eps * max(abs(lam).max(), scale):
        raise _err(
            src,
            entry,
            f"{key}: is not positive semi-definite (smallest eigenvalue {lam.min():.3g}); a {key} matrix has"
            " no negative eigenvalues: correct the off-diagonal entries",
        )
    return a


def _group(
    src: str,
    k: int,
    g: dict[str, Any],
    entries: dict[str, Any],
    nominal: dict[str, float | None],
    seen: set[str],
) -> tuple[CorrelatedGroup, dict[str, Marginal]]:
    entry = f"group #{k + 1}"
    for key in g:
        if key not in _GROUP_KEYS:
            close = difflib.get_close_matches(key, _GROUP_KEYS, n=1)
            raise _err(
                src,
                entry,
                f"unknown field {key!r}"
                + (f" (did you mean {close[0]!r}?)" if close else "")
                + f"; a group takes {', '.join(_GROUP_KEYS[:-1])}",
            )
    paths = g.get("parameters")
    if not isinstance(paths, list) or len(paths) < 2 or not all(isinstance(p, str) for p in paths):
        raise _err(src, entry, "parameters: a list of two or more parameter paths")
    if len(set(paths)) != len(paths):
        raise _err(src, entry, "parameters: a path is named twice")
    for p in paths:
        if p in seen:
            raise _err(src, entry, f"{p!r} is in two groups: merge them into one")
        seen.add(p)
    n = len(paths)
    has_cov, has_cor = "covariance" in g, "correlation" in g
    if has_cov == has_cor:
        raise _err(
            src, entry, "give exactly one of covariance (the members' normal distribution) and correlation"
        )
    if has_cov:
        C = _matrix(src, entry, "covariance", g["covariance"], n)
        for p in paths:
            if p in entries:
                raise _err(
                    src,
                    entry,
                    f"{p!r} has its own distribution and is in a covariance group, which defines it: drop one"
                    " (or give the group a correlation instead)",
                )
        means = g.get("mean")
        if means is None:
            missing = [p for p in paths if nominal[p] is None]
            if missing:
                raise _err(src, entry, f"the file does not write {', '.join(missing)}: give the group's mean")
            mu = [float(nominal[p]) for p in paths]  # type: ignore[arg-type]
        else:
            if not isinstance(means, list) or len(means) != n or not all(_number(x) for x in means):
                raise _err(src, entry, f"mean: a list of {n} finite numbers, one per parameter")
            mu = [float(x) for x in means]
        sd = np.sqrt(np.maximum(np.diag(C), 0.0))
        R = np.eye(n)
        live = sd > 0
        R[np.ix_(live, live)] = C[np.ix_(live, live)] / np.outer(sd[live], sd[live])
        marg = {
            p: Marginal(p, "normal", mu[i], float(sd[i]), nominal=_or_nan(nominal[p]))
            for i, p in enumerate(paths)
        }
        return CorrelatedGroup(tuple(paths), R, "covariance"), marg
    R = _matrix(src, entry, "correlation", g["correlation"], n)
    if np.abs(np.diag(R) - 1).max() > 1e-12 or np.abs(R).max() > 1 + 1e-12:
        raise _err(src, entry, "correlation: the diagonal must be 1 and every entry within [-1, 1]")
    for p in paths:
        if p not in entries:
            raise _err(
                src,
                entry,
                f"{p!r} has no distribution of its own: a correlation group correlates fields that have one"
                " (or give the group a covariance)",
            )
    return CorrelatedGroup(tuple(paths), R, "correlation"), {}
