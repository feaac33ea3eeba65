"""Reading and validating TOML model files (format: ``docs/model-format.md``).

Every problem is a :class:`~chatterlab.errors.ModelError` naming the file,
the item (``[[beam]] "table"``), the field and the fix.  Unknown fields are
refused with the closest known name, so a misspelt key never passes silently.
"""

from __future__ import annotations

import builtins
import copy
import difflib
import json
import math
import os
import tomllib
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ChatterlabError, ModelError
from ._items import (
    DIRECTIONS,
    GROUND,
    Attachment,
    Beam,
    Body,
    Constraint,
    Contact,
    Coupling,
    MatrixBlock,
    Model,
    Movable,
    Node,
    Point,
    PointRef,
    Process,
    Section,
    Spring,
    Support,
)

__all__ = ["load_model", "loads_model", "build_model"]

# list tables of the file -> item kind used in messages and parameter paths
_LISTS = (
    "body",
    "node",
    "beam",
    "point",
    "spring",
    "attachment",
    "support",
    "contact",
    "constraint",
    "coupling",
)
_TABLES = ("model", "movable", "process", "matrices", "variant")

#: Limits checked before anything is parsed or allocated (docs/model-format.md, "Limits").
MAX_MODEL_BYTES = 8 * 2**20  #: a model file larger than this is refused unread
MAX_NESTING = 32  #: tables and arrays nested deeper than this are refused
MAX_INTEGER = 2**63  #: integers must have |n| < 2**63 (write larger numbers as floats, 1e20)
MAX_COORDINATES = 4000  #: rows (and columns) of a [matrices] matrix
MAX_MATRIX_FILE_BYTES = 512 * 2**20  #: size of one .mtx/.npy/.npz file named by [matrices]


def load_model(
    path: str | os.PathLike[str],
    *,
    variant: str | None = None,
    overrides: Mapping[str, Any] | None = None,
    files_outside: bool = False,
) -> Model:
    """Read a model file.

    Parameters
    ----------
    path : path-like
        A TOML model file (``docs/model-format.md``).
    variant : str, optional
        Name of a ``[variant.NAME]`` table of the file whose parameter values
        replace the defaults (e.g. ``"printed"`` for the traverse shaper's
        Table 2 exactly as printed).
    overrides : mapping, optional
        Parameter paths (``"spring.leg3-foundation.c2"``) and values applied
        after the variant.
    files_outside : bool, default False
        Allow ``[matrices]`` file names that lead outside the model file's
        folder (``../K.npy``, an absolute path, a symbolic link pointing
        out).  Off by default, so a model file from elsewhere reads no other
        file on the machine (CLI: ``--allow-outside-files``).

    Raises
    ------
    ModelError
        For anything wrong in the file, naming the file, item and field:
        also an unreadable file, a file over :data:`MAX_MODEL_BYTES`, nesting
        deeper than :data:`MAX_NESTING`, dates, and integers of 2**63 or more.
    """
    p = Path(path)
    name = str(path)
    try:
        with open(p, "rb") as fh:
            size = os.fstat(fh.fileno()).st_size
            if size > MAX_MODEL_BYTES:
                raise _too_big(name, size)
            data = fh.read(MAX_MODEL_BYTES + 1)  # a pipe or device has no size: read no more than the cap
        if len(data) > MAX_MODEL_BYTES:
            raise _too_big(name, len(data))
        text = data.decode("utf-8")
    except FileNotFoundError:
        raise ModelError("file not found; check the path", source=name) from None
    except IsADirectoryError:
        raise ModelError("is a directory, not a model file", source=name) from None
    except PermissionError:
        raise ModelError(
            "cannot be read (permission denied); check the file's permissions", source=name
        ) from None
    except OSError as exc:
        raise ModelError(f"cannot be read ({exc.strerror or exc}); check the path", source=name) from None
    except UnicodeDecodeError:
        raise ModelError("is not a UTF-8 text file; a model file is TOML text", source=name) from None
    return loads_model(
        text,
        source=name,
        base_dir=p.parent,
        variant=variant,
        overrides=overrides,
        files_outside=files_outside,
    )


def _too_big(name: str, size: int) -> ModelError:
    return ModelError(
        f"is {size / 2**20:.1f} MiB; a model file may hold at most {MAX_MODEL_BYTES // 2**20} MiB"
        " (put large matrices in .npy or .mtx files named in [matrices])",
        source=name,
    )


def loads_model(
    text: str,
    *,
    source: str = "<string>",
    base_dir: str | os.PathLike[str] | None = None,
    variant: str | None = None,
    overrides: Mapping[str, Any] | None = None,
    files_outside: bool = False,
) -> Model:
    """Like :func:`load_model` for the text of a model file (``[matrices]``
    files are looked up in ``base_dir``, default: the working directory)."""
    if not isinstance(text, str):
        raise ModelError(f"the model text must be a string, got {type(text).__name__}", source=source)
    if len(text) > MAX_MODEL_BYTES:
        raise _too_big(source, len(text.encode("utf-8", "replace")))
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ModelError(
            f"is not valid TOML ({exc}); see docs/model-format.md for the syntax", source=source
        ) from None
    except RecursionError:
        raise ModelError(
            f"is nested too deeply (tables or arrays more than {MAX_NESTING} levels deep)", source=source
        ) from None
    for key in raw:
        if key.startswith("__"):
            raise ModelError(f"unknown table '{key}': names starting with '__' are reserved", source=source)
    raw["__base_dir__"] = str(base_dir if base_dir is not None else ".")
    if files_outside:
        raw["__files_outside__"] = True
    return build_model(raw, source=source, text=text, variant=variant, overrides=overrides)


def _where(path: tuple[Any, ...]) -> tuple[str, str]:
    """(item, field) of a place in the parsed file, for messages."""
    if not path:
        return "", ""
    head = path[0]
    if head in _LISTS and len(path) >= 2 and isinstance(path[1], int):
        return f"[[{head}]] #{path[1] + 1}", ".".join(str(p) for p in path[2:])
    return f"[{head}]", ".".join(str(p) for p in path[1:])


def _check_tree(raw: Any, src: str) -> None:
    """Refuse, naming the place, what no model field can hold: nesting deeper
    than MAX_NESTING, dates and times, integers of 2**63 or more, values of
    other types (a dict handed to build_model may hold anything).  Iterative,
    so a deep structure cannot exhaust the stack."""
    import datetime

    stack: list[tuple[Any, tuple[Any, ...]]] = [(raw, ())]
    while stack:
        obj, path = stack.pop()
        if len(path) > MAX_NESTING:
            item, fld = _where(path[:2])
            raise ModelError(
                f"{fld + ': ' if fld else ''}nested too deeply (more than {MAX_NESTING} levels of tables or"
                " arrays)",
                source=src,
                item=item or None,
            )
        if isinstance(obj, dict):
            for k, v in obj.items():
                if not isinstance(k, str):
                    raise ModelError(f"keys must be strings, got {k!r}", source=src)
                stack.append((v, (*path, k)))
        elif isinstance(obj, list | tuple):
            for i, v in enumerate(obj):
                stack.append((v, (*path, i)))
        elif isinstance(obj, bool | str | float) or obj is None:
            continue
        elif isinstance(obj, int):
            if not -MAX_INTEGER < obj < MAX_INTEGER:
                item, fld = _where(path)
                raise ModelError(
                    f"{fld or 'value'}: integer of {len(str(abs(obj)))} digits is too large; write it as a"
                    " float (e.g. 1e20)",
                    source=src,
                    item=item or None,
                    field=fld or None,
                )
        else:
            item, fld = _where(path)
            what = (
                "a date or time"
                if isinstance(obj, datetime.date | datetime.time)
                else f"a {type(obj).__name__}"
            )
            raise ModelError(
                f"{fld or 'value'}: {what} is not a model value; write a number, a string, a list or a table",
                source=src,
                item=item or None,
                field=fld or None,
            )


# ---------------------------------------------------------------------------
# helpers


class _Item:
    """Typed access to one table of the file, with messages that name it."""

    def __init__(self, src: str, label: str, table: Any, allowed: Iterable[str]):
        self.src = src
        self.label = label
        if not isinstance(table, dict):
            raise ModelError(f"must be a table, got {type(table).__name__}", source=src, item=label)
        self.t = table
        allowed = set(allowed)
        for key in table:
            if key not in allowed:
                close = difflib.get_close_matches(key, sorted(allowed), n=1)
                hint = f" Did you mean '{close[0]}'?" if close else ""
                raise ModelError(
                    f"unknown field '{key}'.{hint} Allowed: {', '.join(sorted(allowed))}",
                    source=src,
                    item=label,
                    field=key,
                )

    def err(self, field: str | None, msg: str) -> ModelError:
        return ModelError(f"{field}: {msg}" if field else msg, source=self.src, item=self.label, field=field)

    def has(self, key: str) -> bool:
        return key in self.t

    def raw(self, key: str, default: Any = ...) -> Any:
        if key not in self.t:
            if default is ...:
                raise self.err(key, "missing field; it is required (see docs/model-format.md)")
            return default
        return self.t[key]

    def str(self, key: str, default: Any = ...) -> str:
        v = self.raw(key, default)
        if v is default and default is not ...:
            return v
        if not isinstance(v, str) or not v:
            raise self.err(key, f"must be a non-empty string, got {v!r}")
        return v

    def num(
        self,
        key: builtins.str,
        default: Any = ...,
        *,
        unit: builtins.str = "",
        positive: bool = False,
        nonneg: bool = False,
    ) -> float:
        v = self.raw(key, default)
        if v is default and default is not ...:
            return v
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise self.err(key, f"must be a number{f' in {unit}' if unit else ''}, got {v!r}")
        v = float(v)
        if not math.isfinite(v):
            raise self.err(key, f"must be finite, got {v}")
        u = f" {unit}" if unit else ""
        if positive and v <= 0:
            raise self.err(key, f"must be > 0 (got {v:g}{u})")
        if nonneg and v < 0:
            raise self.err(key, f"must be >= 0 (got {v:g}{u})")
        return v

    def vec(
        self, key: builtins.str, n: int, default: Any = ..., *, unit: builtins.str = ""
    ) -> tuple[float, ...]:
        v = self.raw(key, default)
        if v is default and default is not ...:
            return v
        if not isinstance(v, list) or len(v) != n:
            raise self.err(key, f"must be a list of {n} numbers{f' in {unit}' if unit else ''}, got {v!r}")
        out = []
        for x in v:
            if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x):
                raise self.err(key, f"must hold finite numbers, got {v!r}")
            out.append(float(x))
        return tuple(out)

    def matrix3(self, key: builtins.str) -> tuple[tuple[float, ...], ...]:
        v = self.raw(key, [[0.0] * 3] * 3)
        ok = (
            isinstance(v, list)
            and len(v) == 3
            and all(isinstance(r, list) and len(r) == 3 for r in v)
            and all(
                isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)
                for r in v
                for x in r
            )
        )
        if not ok:
            raise self.err(key, f"must be a 3x3 matrix (a list of 3 rows of 3 numbers), got {v!r}")
        return tuple(tuple(float(x) for x in r) for r in v)


def _id_of(src: str, kind: str, k: int, table: Any, required: bool = True) -> str:
    if isinstance(table, dict) and "id" in table:
        v = table["id"]
        if not isinstance(v, str) or not v.strip():
            raise ModelError(
                f"id must be a non-empty string, got {v!r}", source=src, item=f"[[{kind}]] #{k + 1}"
            )
        return v
    if required:
        raise ModelError(
            "missing field 'id': every item needs a unique string id",
            source=src,
            item=f"[[{kind}]] #{k + 1}",
            field="id",
        )
    return f"{kind}-{k + 1}"


def _apply_overrides(src: str, raw: dict[str, Any], overrides: Mapping[str, Any], what: str) -> None:
    for path, value in overrides.items():
        # values from a numpy grid (np.int64 elements, np.float32 ...) are
        # the Python numbers a TOML file would hold
        if isinstance(value, np.generic):
            value = value.item()
        elif isinstance(value, np.ndarray):
            value = value.tolist()
        parts = str(path).split(".")
        if len(parts) == 3 and parts[0] in _LISTS:
            kind, iid, fld = parts
            items = raw.get(kind, [])
            for it in items if isinstance(items, list) else []:
                if isinstance(it, dict) and it.get("id") == iid:
                    it[fld] = value
                    break
            else:
                known = (
                    [it.get("id") for it in items if isinstance(it, dict)] if isinstance(items, list) else []
                )
                raise ModelError(
                    f"{what} '{path}': there is no [[{kind}]] with id '{iid}'"
                    f" (known: {', '.join(map(str, known)) or 'none'})",
                    source=src,
                )
        elif len(parts) == 2 and parts[0] in ("movable", "process", "model"):
            tbl, fld = parts
            table = raw.setdefault(tbl, {})
            if not isinstance(table, dict):
                raise ModelError(f"{what} '{path}': [{tbl}] is not a table in the file", source=src)
            table[fld] = value
        else:
            raise ModelError(
                f"{what} '{path}' does not address a field: write KIND.ID.FIELD for list items"
                f" (KIND one of {', '.join(_LISTS)}) or movable.FIELD / process.FIELD",
                source=src,
            )


# ---------------------------------------------------------------------------


def build_model(
    raw: dict[str, Any],
    *,
    source: str = "<dict>",
    text: str = "",
    variant: str | None = None,
    overrides: Mapping[str, Any] | None = None,
) -> Model:
    """Validate a parsed model-file dictionary and build the :class:`Model`.

    Every problem is a :class:`ModelError`: a value of the wrong type where
    the reader does not name it more precisely ends in a one-line message
    naming the file and the exception, never in a traceback."""
    if not isinstance(raw, dict):
        raise ModelError(f"a model is a table of tables, got {type(raw).__name__}", source=source)
    _check_tree(raw, source)  # before deepcopy and json: they recurse
    try:
        return _build_model(raw, source=source, text=text, variant=variant, overrides=overrides)
    except ChatterlabError:
        raise
    except RecursionError:
        raise ModelError(f"is nested too deeply (more than {MAX_NESTING} levels)", source=source) from None
    except MemoryError:
        raise ModelError("is too large to build in memory; make the model smaller", source=source) from None
    except (
        TypeError,
        ValueError,
        KeyError,
        IndexError,
        AttributeError,
        OverflowError,
        ZeroDivisionError,
    ) as exc:
        detail = str(exc).splitlines()[0][:200] if str(exc) else type(exc).__name__
        raise ModelError(
            f"a value has the wrong type or form ({type(exc).__name__}: {detail}); check the fields against"
            " docs/model-format.md",
            source=source,
        ) from None


def _build_model(
    raw: dict[str, Any],
    *,
    source: str,
    text: str,
    variant: str | None,
    overrides: Mapping[str, Any] | None,
) -> Model:
    src = source
    raw = copy.deepcopy(raw)
    frozen_raw = json.dumps(raw)
    base_dir = Path(raw.pop("__base_dir__", "."))
    files_outside = bool(raw.pop("__files_outside__", False))

    for key in raw:
        if key not in _LISTS and key not in _TABLES:
            close = difflib.get_close_matches(key, list(_LISTS + _TABLES), n=1)
            hint = f" Did you mean '{close[0]}'?" if close else ""
            raise ModelError(
                f"unknown table '{key}'.{hint} Known: "
                + ", ".join([f"[[{k}]]" for k in _LISTS] + [f"[{k}]" for k in _TABLES]),
                source=src,
            )
    for kind in _LISTS:
        if kind in raw and not isinstance(raw[kind], list):
            raise ModelError(f"'{kind}' must be an array of tables, written [[{kind}]]", source=src)

    variants = raw.get("variant", {})
    if not isinstance(variants, dict):
        raise ModelError("[variant] must be a table of tables [variant.NAME]", source=src)
    for vname, vtab in variants.items():
        if not isinstance(vtab, dict):
            raise ModelError(f'[variant.{vname}] must be a table of "PATH" = value', source=src)
        # every variant must address existing fields, even when not selected
        _apply_overrides(src, copy.deepcopy(raw), vtab, f"[variant.{vname}] parameter")
    if variant is not None:
        if variant not in variants:
            raise ModelError(
                f"variant '{variant}' is not defined (known: {', '.join(variants) or 'none'});"
                " add a [variant.NAME] table or drop the option",
                source=src,
            )
        _apply_overrides(src, raw, variants[variant], f"[variant.{variant}] parameter")
    if overrides:
        _apply_overrides(src, raw, overrides, "parameter")
        _check_tree(raw, src)  # --set values come from JSON: same limits as the file

    meta = _Item(src, "[model]", raw.get("model", {}), ("name", "description", "reference"))
    name = meta.str("name", Path(src).stem)

    seen: dict[str, str] = {}

    def register(kind: str, iid: str) -> None:
        if iid == GROUND:
            raise ModelError(
                f"'{GROUND}' is reserved for the foundation; choose another id",
                source=src,
                item=f'[[{kind}]] "{iid}"',
            )
        if iid in seen:
            raise ModelError(
                f"duplicate id '{iid}' (already used by a [[{seen[iid]}]]); ids must be unique",
                source=src,
                item=f'[[{kind}]] "{iid}"',
                field="id",
            )
        seen[iid] = kind

    # ---- movable subsystem (read first: bodies need to know) -------------------
    movable: Movable | None = None
    mov_bodies: set[str] = set()
    if "movable" in raw:
        it = _Item(src, "[movable]", raw["movable"], ("bodies", "direction", "position", "range"))
        bl = it.raw("bodies")
        if not isinstance(bl, list) or not bl or not all(isinstance(b, str) for b in bl):
            raise it.err("bodies", f"must be a non-empty list of body ids, got {bl!r}")
        d = it.vec("direction", 2, (1.0, 0.0))
        nd = math.hypot(*d)
        if nd == 0:
            raise it.err("direction", "must be a non-zero vector")
        pos = it.num("position", unit="m")
        rng = it.vec("range", 2, (pos, pos), unit="m")
        if not (rng[0] <= pos <= rng[1]):
            raise it.err("range", f"must contain position {pos:g} m (got {list(rng)})")
        movable = Movable(tuple(bl), (d[0] / nd, d[1] / nd), pos, (rng[0], rng[1]))
        mov_bodies = set(bl)

    # ---- bodies -----------------------------------------------------------------
    bodies: list[Body] = []
    for k, t in enumerate(raw.get("body", [])):
        iid = _id_of(src, "body", k, t)
        it = _Item(
            src, f'[[body]] "{iid}"', t, ("id", "mass", "inertia", "centre", "angle_deg", "description")
        )
        register("body", iid)
        m = it.num("mass", unit="kg", nonneg=True)
        J = it.num("inertia", unit="kg m^2", nonneg=True)
        if (m == 0) != (J == 0):
            raise it.err(
                "inertia" if m > 0 else "mass",
                f"mass and inertia must both be > 0, or both 0 for a massless body (got {m:g} kg, {J:g} kg m^2)",
            )
        c = it.vec("centre", 2, unit="m")
        ang = math.radians(it.num("angle_deg", 0.0))
        bodies.append(Body(iid, m, J, (c[0], c[1]), ang, iid in mov_bodies))
    body_ids = {b.id for b in bodies}
    if movable is not None:
        for b in movable.bodies:
            if b not in body_ids:
                raise ModelError(
                    f"bodies: '{b}' is not a [[body]] (known: {', '.join(sorted(body_ids)) or 'none'})",
                    source=src,
                    item="[movable]",
                    field="bodies",
                )

    # ---- nodes --------------------------------------------------------------------
    nodes: list[Node] = []
    for k, t in enumerate(raw.get("node", [])):
        iid = _id_of(src, "node", k, t)
        it = _Item(src, f'[[node]] "{iid}"', t, ("id", "at", "description"))
        register("node", iid)
        xy = it.vec("at", 2, unit="m")
        nodes.append(Node(iid, (xy[0], xy[1])))
    node_xy = {n.id: np.array(n.xy) for n in nodes}

    # ---- beams --------------------------------------------------------------------
    beams: list[Beam] = []
    beam_len: dict[str, float] = {}
    for k, t in enumerate(raw.get("beam", [])):
        iid = _id_of(src, "beam", k, t)
        it = _Item(
            src,
            f'[[beam]] "{iid}"',
            t,
            ("id", "nodes", "E", "nu", "G", "rho", "A", "I", "kappa", "eta", "elements", "description"),
        )
        register("beam", iid)
        nl = it.raw("nodes")
        if not (isinstance(nl, list) and len(nl) == 2 and all(isinstance(x, str) for x in nl)):
            raise it.err("nodes", f"must be a list of two node ids, got {nl!r}")
        for n in nl:
            if n not in node_xy:
                raise it.err(
                    "nodes", f"node '{n}' is not defined (known: {', '.join(sorted(node_xy)) or 'none'})"
                )
        if nl[0] == nl[1]:
            raise it.err("nodes", "the two nodes must differ")
        L = float(np.hypot(*(node_xy[nl[1]] - node_xy[nl[0]])))
        if L <= 1e-12:
            raise it.err(
                "nodes",
                f"beam has zero length: nodes '{nl[0]}' and '{nl[1]}' are at the same place; move one",
            )
        E = it.num("E", unit="Pa", positive=True)
        if it.has("G") and it.has("nu"):
            raise it.err("G", "give either G or nu, not both")
        if it.has("G"):
            G = it.num("G", unit="Pa", positive=True)
        else:
            nu = it.num("nu", 0.3)
            if not -1.0 < nu < 0.5:
                raise it.err("nu", f"Poisson's ratio must be in (-1, 0.5) (got {nu:g})")
            G = E / (2.0 * (1.0 + nu))
        sec = Section(
            E=E,
            G=G,
            rho=it.num("rho", unit="kg/m^3", positive=True),
            A=it.num("A", unit="m^2", positive=True),
            I=it.num("I", unit="m^4", positive=True),
            kappa=it.num("kappa", 5.0 / 6.0, positive=True),
            eta=it.num("eta", 0.0, unit="N s/m^2", nonneg=True),
        )
        ne = it.raw("elements", 1)
        if isinstance(ne, bool) or not isinstance(ne, int) or ne < 1:
            raise it.err("elements", f"must be an integer >= 1, got {ne!r}")
        beams.append(Beam(iid, (nl[0], nl[1]), sec, ne))
        beam_len[iid] = L
    beam_by_id = {b.id: b for b in beams}

    # ---- contacts (massless moving points) -------------------------------------------
    contacts: list[Contact] = []
    for k, t in enumerate(raw.get("contact", [])):
        iid = _id_of(src, "contact", k, t)
        it = _Item(
            src,
            f'[[contact]] "{iid}"',
            t,
            ("id", "beams", "follows", "offset", "shift", "outside", "description"),
        )
        register("contact", iid)
        bl = it.raw("beams")
        if isinstance(bl, str):
            bl = [bl]
        if not isinstance(bl, list) or not bl or not all(isinstance(b, str) for b in bl):
            raise it.err("beams", f"must be a beam id or a list of collinear beam ids, got {bl!r}")
        for b in bl:
            if b not in beam_by_id:
                raise it.err(
                    "beams", f"beam '{b}' is not defined (known: {', '.join(sorted(beam_by_id)) or 'none'})"
                )
        _check_track(it, [beam_by_id[b] for b in bl], node_xy)
        fol = it.str("follows")
        if fol not in body_ids:
            raise it.err("follows", f"body '{fol}' is not defined (known: {', '.join(sorted(body_ids))})")
        if fol not in mov_bodies:
            raise it.err(
                "follows", f"body '{fol}' is not in [movable] bodies; a contact follows a moving body"
            )
        outside = it.raw("outside", "error")
        if outside not in ("error", "clamp"):
            raise it.err(
                "outside",
                f"must be 'error' (the contact may not leave its track) or 'clamp' (it waits at the track end), got {outside!r}",
            )
        contacts.append(
            Contact(
                iid, tuple(bl), fol, it.num("offset", 0.0, unit="m"), it.num("shift", 0.0, unit="m"), outside
            )
        )
    contact_ids = {c.id for c in contacts}

    # ---- matrix-level model --------------------------------------------------------------
    matrices: MatrixBlock | None = None
    if "matrices" in raw:
        matrices = _read_matrices(src, raw["matrices"], base_dir, files_outside)
        structural = [
            k for k in ("body", "node", "beam", "attachment", "contact", "constraint", "movable") if k in raw
        ]
        if structural:
            raise ModelError(
                "a model is either structural ([[body]], [[beam]], ...) or matrix-level ([matrices]), not both:"
                f" remove {', '.join(structural)} or the [matrices] table (a matrix-level model takes"
                " [[point]] with coords, [[spring]], [[support]] with coordinate, [[coupling]] and [process])",
                source=src,
                item="[matrices]",
            )
    coord_names = set(matrices.coordinates) if matrices else set()

    # ---- points ---------------------------------------------------------------------------
    ctx = _RefContext(src, body_ids, node_xy, beam_len, contact_ids, coord_names, {})
    points: list[Point] = []
    for k, t in enumerate(raw.get("point", [])):
        iid = _id_of(src, "point", k, t)
        it = _Item(
            src,
            f'[[point]] "{iid}"',
            t,
            ("id", "body", "node", "beam", "distance", "offset", "coords", "description"),
        )
        register("point", iid)
        ref = ctx.ref_from_table(it, None, dict(t))
        points.append(Point(iid, ref))
        ctx.points[iid] = ref

    # ---- springs ----------------------------------------------------------------------------
    springs: list[Spring] = []
    for k, t in enumerate(raw.get("spring", [])):
        iid = _id_of(src, "spring", k, t)
        it = _Item(
            src,
            f'[[spring]] "{iid}"',
            t,
            ("id", "a", "b", "c1", "c2", "c6", "d1", "d2", "d6", "angle_deg", "description"),
        )
        register("spring", iid)
        pa = ctx.ref(it, "a")
        pb = ctx.ref(it, "b")
        c = tuple(
            it.num(f, 0.0, unit=u, nonneg=True) for f, u in (("c1", "N/m"), ("c2", "N/m"), ("c6", "N m/rad"))
        )
        d = tuple(
            it.num(f, 0.0, unit=u, nonneg=True)
            for f, u in (("d1", "N s/m"), ("d2", "N s/m"), ("d6", "N m s/rad"))
        )
        if not any(c) and not any(d):
            raise it.err(
                "c1",
                "a spring needs a stiffness (c1, c2 or c6 > 0) or a damping (d1, d2, d6 > 0); all are zero",
            )
        if pa.kind == "ground" and pb.kind == "ground":
            raise it.err("b", "both ends are on the ground; connect at least one end to the structure")
        springs.append(
            Spring(
                iid, pa, pb, (c[0], c[1], c[2]), (d[0], d[1], d[2]), math.radians(it.num("angle_deg", 0.0))
            )
        )

    # ---- attachments, supports, constraints -------------------------------------------------
    attachments: list[Attachment] = []
    for k, t in enumerate(raw.get("attachment", [])):
        iid = _id_of(src, "attachment", k, t, required=False)
        it = _Item(src, f'[[attachment]] "{iid}"', t, ("id", "node", "body", "description"))
        if "id" in t:
            register("attachment", iid)
        n = it.str("node")
        if n not in node_xy:
            raise it.err("node", f"node '{n}' is not defined (known: {', '.join(sorted(node_xy)) or 'none'})")
        b = it.str("body")
        if b != GROUND and b not in body_ids:
            raise it.err(
                "body", f"body '{b}' is not defined (known: {', '.join(sorted(body_ids | {GROUND}))})"
            )
        if b in mov_bodies:
            raise it.err(
                "body",
                f"body '{b}' is movable and node '{n}' is not; attach moving parts through a [[contact]]",
            )
        attachments.append(Attachment(iid, n, b))
    att_nodes = [a.node for a in attachments]
    for n in set(att_nodes):
        if att_nodes.count(n) > 1:
            raise ModelError(
                f"node '{n}' is attached twice; a node can be clamped to one body only",
                source=src,
                item="[[attachment]]",
                field="node",
            )

    supports: list[Support] = []
    for k, t in enumerate(raw.get("support", [])):
        iid = _id_of(src, "support", k, t, required=False)
        it = _Item(src, f'[[support]] "{iid}"', t, ("id", "node", "body", "coordinate", "fix", "description"))
        targets = [f for f in ("node", "body", "coordinate") if f in t]
        if len(targets) != 1:
            raise it.err(None, "give exactly one of node, body or coordinate")
        tgt = it.str(targets[0])
        if targets[0] == "node" and tgt not in node_xy:
            raise it.err("node", f"node '{tgt}' is not defined (known: {', '.join(sorted(node_xy))})")
        if targets[0] == "body" and tgt not in body_ids:
            raise it.err("body", f"body '{tgt}' is not defined (known: {', '.join(sorted(body_ids))})")
        if targets[0] == "coordinate":
            if tgt not in coord_names:
                raise it.err("coordinate", f"coordinate '{tgt}' is not in [matrices] coordinates")
            supports.append(Support(iid, tgt, ("",)))
            continue
        fix = it.raw("fix", list(DIRECTIONS))
        if not isinstance(fix, list) or not fix or any(f not in DIRECTIONS for f in fix):
            raise it.err("fix", f"must be a list drawn from {list(DIRECTIONS)}, got {fix!r}")
        supports.append(Support(iid, tgt, tuple(fix)))

    all_coords = _coordinate_names(bodies, nodes, beams, contacts, matrices)
    constraints: list[Constraint] = []
    for k, t in enumerate(raw.get("constraint", [])):
        iid = _id_of(src, "constraint", k, t, required=False)
        it = _Item(src, f'[[constraint]] "{iid}"', t, ("id", "dependent", "equations", "description"))
        dep = it.raw("dependent")
        if not isinstance(dep, list) or not dep or not all(isinstance(x, str) for x in dep):
            raise it.err("dependent", f"must be a non-empty list of coordinate names, got {dep!r}")
        for x in dep:
            if x not in all_coords:
                raise it.err(
                    "dependent",
                    f"'{x}' is not a coordinate of the model (e.g. {', '.join(list(all_coords)[:6])}, ...)",
                )
        eqs = it.raw("equations")
        if not isinstance(eqs, list) or not eqs or not all(isinstance(e, dict) and e for e in eqs):
            raise it.err("equations", 'must be a list of tables {"coordinate" = coefficient, ...}')
        rows = []
        for e in eqs:
            row = []
            for cname, coef in e.items():
                if cname not in all_coords:
                    raise it.err("equations", f"'{cname}' is not a coordinate of the model")
                if isinstance(coef, bool) or not isinstance(coef, int | float) or not math.isfinite(coef):
                    raise it.err(
                        "equations", f"coefficient of '{cname}' must be a finite number, got {coef!r}"
                    )
                row.append((cname, float(coef)))
            rows.append(tuple(row))
        constraints.append(Constraint(iid, tuple(dep), tuple(rows)))

    # massless bodies must be fully dependent
    constrained = {x for c in constraints for x in c.dependent}
    for body in bodies:
        if body.mass == 0.0:
            missing = [d for d in DIRECTIONS if f"{body.id}.{d}" not in constrained]
            if missing:
                raise ModelError(
                    "mass must be > 0 (got 0 kg): a massless body is allowed only where all its coordinates"
                    f" are dependent, and {', '.join(body.id + '.' + m for m in missing)} are not; give it a mass,"
                    " make it a [[contact]], or declare it in a [[constraint]]",
                    source=src,
                    item=f'[[body]] "{body.id}"',
                    field="mass",
                )

    # ---- couplings ------------------------------------------------------------------------------
    couplings: list[Coupling] = []
    for k, t in enumerate(raw.get("coupling", [])):
        iid = _id_of(src, "coupling", k, t)
        couplings.append(_read_coupling(src, iid, t, ctx))
        register("coupling", iid)

    process = _read_process(src, raw["process"]) if "process" in raw else None
    if process is not None and process.kind == "shaping" and movable is not None:
        x0 = process.start
        x1 = process.start + process.direction * (process.run_in + process.cut + process.coast)
        lo, hi = min(x0, x1), max(x0, x1)
        if lo < movable.range[0] - 1e-9 or hi > movable.range[1] + 1e-9:
            raise ModelError(
                f"the stroke from start = {x0:g} m over {process.run_in + process.cut + process.coast:g} m"
                f" in direction {process.direction:+g} spans [{lo:g}, {hi:g}] m, outside [movable] range"
                f" [{movable.range[0]:g}, {movable.range[1]:g}] m; move start, flip direction or widen the range",
                source=src,
                item="[process]",
                field="start",
            )

    model = Model(
        name=name,
        source=src,
        bodies=tuple(bodies),
        nodes=tuple(nodes),
        beams=tuple(beams),
        springs=tuple(springs),
        attachments=tuple(attachments),
        supports=tuple(supports),
        contacts=tuple(contacts),
        constraints=tuple(constraints),
        points=tuple(points),
        couplings=tuple(couplings),
        process=process,
        movable=movable,
        matrices=matrices,
        variant=variant,
        overrides=tuple((overrides or {}).items()),
        text=text,
        raw=frozen_raw,
        rebuild=build_model,
    )
    if not matrices and not bodies and not beams:
        raise ModelError(
            "the model has no [[body]], no [[beam]] and no [matrices]; nothing to analyse", source=src
        )
    if movable is not None or contacts:
        _check_movable(model)
    from ._geometry import check_geometry

    check_geometry(model)
    return model


def _coordinate_names(bodies, nodes, beams, contacts, matrices) -> list[str]:
    if matrices is not None:
        return list(matrices.coordinates)
    names = []
    for b in bodies:
        names += [f"{b.id}.{d}" for d in DIRECTIONS]
    for c in contacts:
        names += [f"{c.id}.{d}" for d in DIRECTIONS]
    for n in nodes:
        names += [f"{n.id}.{d}" for d in DIRECTIONS]
    for bm in beams:
        for j in range(1, bm.elements):
            names += [f"{bm.id}#{j}.{d}" for d in DIRECTIONS]
    return names


def _check_track(it: _Item, beams: list[Beam], node_xy: dict[str, np.ndarray]) -> None:
    """A contact's beams must form one straight, contiguous track."""
    if len(beams) == 1:
        return
    p0 = node_xy[beams[0].nodes[0]]
    e = node_xy[beams[0].nodes[1]] - p0
    e = e / np.linalg.norm(e)
    prev_end = node_xy[beams[0].nodes[1]]
    for b in beams[1:]:
        a, c = node_xy[b.nodes[0]], node_xy[b.nodes[1]]
        d = (c - a) / np.linalg.norm(c - a)
        if abs(d @ e - 1.0) > 1e-9 or np.linalg.norm(a - prev_end) > 1e-9:
            raise it.err(
                "beams",
                f"beam '{b.id}' does not continue the track straight from the previous beam's end;"
                " list collinear beams in order, each starting where the previous one ends",
            )
        prev_end = c


class _RefContext:
    """Resolves how the file names a point into a :class:`PointRef`."""

    def __init__(self, src, body_ids, node_xy, beam_len, contact_ids, coord_names, points):
        self.src = src
        self.body_ids = body_ids
        self.node_xy = node_xy
        self.beam_len = beam_len
        self.contact_ids = contact_ids
        self.coord_names = coord_names
        self.points: dict[str, PointRef] = points

    def known(self) -> str:
        names = sorted(set(self.points) | self.body_ids | set(self.node_xy) | self.contact_ids | {GROUND})
        return ", ".join(names)

    def ref(self, it: _Item, key: str) -> PointRef:
        v = it.raw(key)
        if isinstance(v, str):
            if v in self.points:
                return self.points[v]
            if v == GROUND:
                return PointRef("ground", GROUND, label=v)
            if v in self.body_ids or v in self.contact_ids:
                return PointRef("body", v, label=v)
            if v in self.node_xy:
                return PointRef("node", v, label=v)
            raise it.err(
                key, f"'{v}' is not a point, body, contact, node or '{GROUND}' (known: {self.known()})"
            )
        if isinstance(v, dict):
            sub = _Item(self.src, it.label, v, ("body", "node", "beam", "distance", "offset", "coords"))
            return self.ref_from_table(sub, key, v)
        raise it.err(
            key,
            f'must be a point name or an inline table like {{ body = "frame", offset = [0.0, -0.5] }}, got {v!r}',
        )

    def ref_from_table(self, it: _Item, key: str | None, t: dict[str, Any]) -> PointRef:
        f = (lambda s: f"{key}.{s}") if key else (lambda s: s)
        kinds = [k for k in ("body", "node", "beam", "coords") if k in t]
        if len(kinds) != 1:
            raise it.err(key, "give exactly one of body, node, beam or coords")
        kind = kinds[0]
        label = json.dumps(t)
        if kind == "coords":
            cs = t["coords"]
            if not isinstance(cs, dict) or not cs or any(d not in DIRECTIONS for d in cs):
                raise it.err(
                    f("coords"),
                    f'must be a table like {{ x = "q1", y = "q2" }} with keys from {list(DIRECTIONS)}',
                )
            for c in cs.values():
                if c not in self.coord_names:
                    raise it.err(
                        f("coords"),
                        f"'{c}' is not in [matrices] coordinates (known: {', '.join(sorted(self.coord_names))})",
                    )
            return PointRef("coords", "", coords=tuple(cs.get(d, "") for d in DIRECTIONS), label=label)
        target = t[kind]
        if not isinstance(target, str):
            raise it.err(f(kind), f"must be an id string, got {target!r}")
        if kind == "beam":
            if target not in self.beam_len:
                raise it.err(
                    f("beam"),
                    f"beam '{target}' is not defined (known: {', '.join(sorted(self.beam_len)) or 'none'})",
                )
            dist = it.num("distance", unit="m")
            L = self.beam_len[target]
            if not (-1e-12 <= dist <= L + 1e-12):
                raise it.err(
                    f("distance"),
                    f"point is outside its beam: distance must be in [0, {L:g}] m (the beam's length), got {dist:g} m",
                )
            off = it.num("offset", 0.0, unit="m")
            return PointRef("beam", target, (0.0, off), min(max(dist, 0.0), L), label=label)
        ox, oy = it.vec("offset", 2, (0.0, 0.0), unit="m")
        off2 = (ox, oy)
        if it.has("distance"):
            raise it.err(f("distance"), "only a point on a beam has a distance")
        if kind == "body":
            if target == GROUND:
                return PointRef("ground", GROUND, off2, label=label)
            if target not in self.body_ids and target not in self.contact_ids:
                raise it.err(
                    f("body"),
                    f"body '{target}' is not defined (known: {', '.join(sorted(self.body_ids | self.contact_ids | {GROUND}))})",
                )
            return PointRef("body", target, off2, label=label)
        if target not in self.node_xy:
            raise it.err(
                f("node"),
                f"node '{target}' is not defined (known: {', '.join(sorted(self.node_xy)) or 'none'})",
            )
        return PointRef("node", target, off2, label=label)


def _read_coupling(src: str, iid: str, t: Any, ctx: _RefContext) -> Coupling:
    label = f'[[coupling]] "{iid}"'
    base = ("id", "a", "b", "angle_deg", "width_ref", "forces", "model", "description")
    model_kind = t.get("model", "matrices") if isinstance(t, dict) else "matrices"
    extra = {
        "matrices": ("DP", "DV", "DO"),
        "grasso": tuple(f"K{i}" for i in range(1, 9)),
        "regenerative": ("Kf", "force_angle_deg", "normal_angle_deg", "Kv"),
    }
    if not isinstance(model_kind, str) or model_kind not in extra:
        raise ModelError(
            f"model: must be one of {', '.join(extra)} (got {model_kind!r})",
            source=src,
            item=label,
            field="model",
        )
    it = _Item(src, label, t, base + extra[model_kind])
    a = ctx.ref(it, "a")
    b = ctx.ref(it, "b")
    width_ref = it.num("width_ref", unit="m", positive=True)
    f1, f2, f3 = it.vec("forces", 3, (0.0, 0.0, 0.0), unit="N")
    forces = (f1, f2, f3)
    angle = math.radians(it.num("angle_deg", 0.0))
    params: tuple[tuple[str, float], ...] = ()
    if model_kind == "matrices":
        DP, DV, DO = it.matrix3("DP"), it.matrix3("DV"), it.matrix3("DO")
        if not any(any(r) for r in DP + DV + DO):
            raise it.err("DP", "all of DP, DV, DO are zero; give at least one feedback matrix")
    elif model_kind == "grasso":
        K = [it.num(f"K{i}") for i in range(1, 9)]
        params = tuple((f"K{i}", K[i - 1]) for i in range(1, 9))
        K1, K2, K3, K4, K5, K6, K7, K8 = K
        # Eqs. (3.7)-(3.9) of the seed paper, dw = (q_z, dh, 0)
        DV = ((K1, K4, 0.0), (K2, K6, 0.0), (0.0, 0.0, 0.0))
        DP = ((0.0, K3, 0.0), (0.0, K5, 0.0), (0.0, 0.0, 0.0))
        DO = ((0.0, -K7, 0.0), (0.0, -K8, 0.0), (0.0, 0.0, 0.0))
    else:
        Kf = it.num("Kf", unit="N/m^2", positive=True)
        Kv = it.num("Kv", 0.0, unit="N s/m^2", nonneg=True)
        fa = math.radians(it.num("force_angle_deg", 0.0))
        na = math.radians(it.num("normal_angle_deg", 0.0))
        params = (
            ("Kf", Kf),
            ("Kv", Kv),
            ("force_angle_deg", math.degrees(fa)),
            ("normal_angle_deg", math.degrees(na)),
        )
        f = np.array([math.cos(fa), math.sin(fa), 0.0])
        n = np.array([math.cos(na), math.sin(na), 0.0])
        G = np.outer(f, n)
        # F_a = K_f b (h - h0) f with h = h0 - n.dw(t) + n.dw(t-T): D_P = Kf b f n^T, D_O = -Kf b f n^T
        DP = tuple(tuple(float(x) for x in r) for r in Kf * width_ref * G)
        DO = tuple(tuple(float(x) for x in r) for r in -Kf * width_ref * G)
        DV = tuple(tuple(float(x) for x in r) for r in Kv * width_ref * G)
    return Coupling(iid, a, b, DP, DV, DO, width_ref, forces, angle, model_kind, params)


def _read_process(src: str, t: Any) -> Process:
    kind = t.get("kind") if isinstance(t, dict) else None
    allowed = {
        "shaping": (
            "kind",
            "speed",
            "return_speed",
            "run_in",
            "cut",
            "coast",
            "start",
            "direction",
            "description",
        ),
        "turning": ("kind", "rpm", "description"),
        "delay": ("kind", "delay", "description"),
    }
    if not isinstance(kind, str) or kind not in allowed:
        raise ModelError(
            f"kind: must be one of {', '.join(allowed)} (got {kind!r})",
            source=src,
            item="[process]",
            field="kind",
        )
    it = _Item(src, "[process]", t, allowed[kind])
    if kind == "shaping":
        direction = it.num("direction", -1.0)
        if direction not in (-1.0, 1.0):
            raise it.err(
                "direction", f"must be +1 or -1 (the sign of ds/dt in the work stroke), got {direction:g}"
            )
        return Process(
            "shaping",
            speed=it.num("speed", unit="m/s", positive=True),
            return_speed=it.num("return_speed", unit="m/s", positive=True),
            run_in=it.num("run_in", unit="m", nonneg=True),
            cut=it.num("cut", unit="m", positive=True),
            coast=it.num("coast", unit="m", nonneg=True),
            start=it.num("start", 0.0, unit="m"),
            direction=direction,
        )
    if kind == "turning":
        return Process("turning", speed=it.num("rpm", unit="rpm", positive=True))
    return Process(
        "delay",
        speed=it.num("delay", unit="s", positive=True),
        delay_value=it.num("delay", unit="s", positive=True),
    )


def _check_movable(model: Model) -> None:
    from ._geometry import contact_track_position

    mv = model.movable
    src = model.source
    if model.contacts and mv is None:
        raise ModelError(
            "a [[contact]] needs a [movable] table naming the moving bodies",
            source=src,
            item=f'[[contact]] "{model.contacts[0].id}"',
        )
    assert mv is not None
    for c in model.contacts:
        for s in (mv.range[0], mv.position, mv.range[1]):
            try:
                contact_track_position(model, c, s)
            except ValueError as exc:
                raise ModelError(
                    f"{exc}; narrow [movable] range or extend the track",
                    source=src,
                    item=f'[[contact]] "{c.id}"',
                    field="beams",
                ) from None


def _read_matrices(src: str, t: Any, base_dir: Path, files_outside: bool = False) -> MatrixBlock:
    it = _Item(src, "[matrices]", t, ("coordinates", "M", "L", "K", "file", "given", "description"))
    arrays: dict[str, np.ndarray] = {}
    coords = it.raw("coordinates", None)
    if isinstance(coords, list) and len(coords) > MAX_COORDINATES:
        raise it.err(
            "coordinates",
            f"{len(coords)} coordinates; a matrix-level model may have at most {MAX_COORDINATES}",
        )
    if it.has("file"):
        fn = _matrix_path(it, "file", it.str("file"), base_dir, files_outside)
        arrays_z, coords_z = _read_npz(it, fn)
        arrays.update(arrays_z)
        if coords is None and coords_z is not None:
            coords = coords_z
    for key in ("M", "L", "K"):
        if it.has(key):
            v = it.raw(key)
            if isinstance(v, str):
                arrays[key] = _read_matrix_file(it, key, _matrix_path(it, key, v, base_dir, files_outside))
            else:
                try:
                    arr = np.array(v, dtype=float)
                except (TypeError, ValueError, OverflowError):
                    raise it.err(key, "must be a list of rows of numbers, or a .mtx/.npy file name") from None
                arrays[key] = arr
    if "M" not in arrays or "K" not in arrays:
        raise it.err(
            "M" if "M" not in arrays else "K", "missing: a matrix-level model needs M and K (L optional)"
        )
    n = arrays["M"].shape[0] if arrays["M"].ndim == 2 else -1
    if not isinstance(coords, list) or not all(isinstance(c, str) for c in coords):
        raise it.err("coordinates", "must be a list of coordinate names, one per row of M")
    if len(set(coords)) != len(coords):
        dup = sorted({c for c in coords if coords.count(c) > 1})
        raise it.err("coordinates", f"duplicate coordinate names: {', '.join(dup)}")
    arrays.setdefault("L", np.zeros_like(arrays["M"]))
    for key, arr in arrays.items():
        if arr.ndim != 2 or arr.shape != (len(coords), len(coords)):
            raise it.err(
                key, f"must be {len(coords)}x{len(coords)} (one row per coordinate), got shape {arr.shape}"
            )
        if not np.all(np.isfinite(arr)):
            raise it.err(key, "holds non-finite entries")
        if not np.allclose(arr, arr.T, rtol=1e-10, atol=1e-12 * max(1.0, np.abs(arr).max())):
            raise it.err(key, "must be symmetric")
        arr.setflags(write=False)
    try:
        np.linalg.cholesky(arrays["M"])
    except np.linalg.LinAlgError:
        raise it.err("M", "must be positive definite (every coordinate needs mass)") from None
    given = it.raw("given", [])
    if not isinstance(given, list) or any(g not in coords for g in given):
        raise it.err("given", "must be a list of names from coordinates")
    del n
    return MatrixBlock(tuple(coords), arrays["M"], arrays["L"], arrays["K"], tuple(given))


def _matrix_path(it: _Item, key: str, name: str, base_dir: Path, files_outside: bool) -> Path:
    """A [matrices] file name resolved against the model's folder; a name that
    leads outside it (``..``, an absolute path, a link pointing out) is refused
    unless ``files_outside``."""
    if "\x00" in name:
        raise it.err(key, "file name holds a NUL character")
    full = base_dir / name  # an absolute name replaces base_dir
    if not files_outside:
        root = base_dir.resolve()
        real = full.resolve()
        if not real.is_relative_to(root):
            raise it.err(
                key,
                f"'{name}' leads outside the model's folder {str(root)!r}; put the file in that folder, or"
                " allow it with --allow-outside-files (Python: load_model(..., files_outside=True))",
            )
    try:
        size = full.stat().st_size
    except FileNotFoundError:
        raise it.err(key, f"'{full}' not found (paths are relative to the model file)") from None
    except OSError as exc:
        raise it.err(key, f"'{full}' cannot be read ({exc.strerror or exc})") from None
    if size > MAX_MATRIX_FILE_BYTES:
        raise it.err(
            key,
            f"'{full}' is {size / 2**20:.0f} MiB; a matrix file may hold at most {MAX_MATRIX_FILE_BYTES // 2**20} MiB",
        )
    return full


def _check_shape(it: _Item, key: str, fn: Path, shape: tuple[int, ...]) -> None:
    if len(shape) != 2 or shape[0] != shape[1]:
        raise it.err(key, f"'{fn}' holds an array of shape {shape}; a matrix must be square")
    if shape[0] > MAX_COORDINATES:
        raise it.err(
            key,
            f"'{fn}' declares a {shape[0]}x{shape[1]} matrix; at most {MAX_COORDINATES} coordinates are allowed",
        )


_NOT_NUMBERS = "holds no plain array of numbers (object or pickled data is never loaded)"


def _npy_header(fh: Any) -> tuple[tuple[int, ...], np.dtype]:
    fmt = np.lib.format
    version = fmt.read_magic(fh)
    if version == (1, 0):
        shape, _, dtype = fmt.read_array_header_1_0(fh)
    else:
        shape, _, dtype = fmt.read_array_header_2_0(fh)
    return tuple(shape), dtype


def _read_npz(it: _Item, fn: Path) -> tuple[dict[str, np.ndarray], list[str] | None]:
    import zipfile

    arrays: dict[str, np.ndarray] = {}
    coords: list[str] | None = None
    try:
        with zipfile.ZipFile(fn) as zf:
            names = set(zf.namelist())
            for key in ("M", "L", "K", "coordinates"):
                member = f"{key}.npy"
                if member not in names:
                    continue
                if zf.getinfo(member).file_size > MAX_MATRIX_FILE_BYTES:
                    raise it.err(
                        "file", f"'{fn}': {member} unpacks to more than {MAX_MATRIX_FILE_BYTES // 2**20} MiB"
                    )
                with zf.open(member) as fh:
                    shape, dtype = _npy_header(fh)
                if dtype.hasobject:
                    raise it.err("file", f"'{fn}': {member} {_NOT_NUMBERS}")
                if key == "coordinates":
                    if len(shape) != 1 or shape[0] > MAX_COORDINATES or dtype.kind not in "US":
                        raise it.err(
                            "file",
                            f"'{fn}': coordinates must be a 1-D array of at most {MAX_COORDINATES} names",
                        )
                else:
                    _check_shape(it, "file", fn, shape)
        with np.load(fn, allow_pickle=False) as z:
            for key in ("M", "L", "K"):
                if key in z:
                    arrays[key] = np.asarray(z[key], float)
            if "coordinates" in z:
                coords = [str(x) for x in z["coordinates"]]
    except ModelError:
        raise
    except (ValueError, TypeError, OSError, EOFError, zipfile.BadZipFile) as exc:
        detail = f" ({exc})" if "pickle" not in str(exc).lower() else ""
        raise it.err("file", f"'{fn}' is not a readable .npz file of numbers{detail}") from None
    return arrays, coords


def _read_matrix_file(it: _Item, key: str, fn: Path) -> np.ndarray:
    try:
        if fn.suffix == ".mtx":
            from scipy.io import mminfo, mmread

            rows, cols, entries, _, field, _ = mminfo(str(fn))
            _check_shape(it, key, fn, (int(rows), int(cols)))
            if field == "complex":
                raise it.err(key, f"'{fn}' holds complex entries; a matrix holds real numbers")
            if int(entries) > int(rows) * int(cols):
                raise it.err(key, f"'{fn}' declares {entries} entries for a {rows}x{cols} matrix")
            m = mmread(str(fn))
            return np.asarray(m.toarray() if hasattr(m, "toarray") else m, float)
        if fn.suffix == ".npy":
            with open(fn, "rb") as fh:
                shape, dtype = _npy_header(fh)
            if dtype.hasobject:
                raise it.err(key, f"'{fn}' {_NOT_NUMBERS}")
            _check_shape(it, key, fn, shape)
            return np.asarray(np.load(fn, allow_pickle=False), float)
    except ModelError:
        raise
    except FileNotFoundError:
        raise it.err(key, f"'{fn}' not found (paths are relative to the model file)") from None
    except (ValueError, TypeError, OSError, EOFError, IndexError) as exc:
        detail = f" ({exc})" if "pickle" not in str(exc).lower() else f": it {_NOT_NUMBERS}"
        raise it.err(key, f"'{fn}' could not be read{detail}") from None
    raise it.err(key, f"'{fn}': use a Matrix Market (.mtx) or NumPy (.npy) file, or an inline list")
