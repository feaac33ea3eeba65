"""Reading and validating TOML model files (format: ``docs/model-format.md``).

Every problem is a :class:`~chatterlab.errors.ModelError` naming the file,
the item (``[[beam]] "table"``), the field and the fix.  Unknown fields are
refused with the closest known name, so a misspelt key never passes silently.
"""

from __future__ import annotations

import copy
import difflib
import json
import os
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ChatterlabError, ModelError
from ._absorber import read_absorbers
from ._actuator import read_actuators
from ._damping import read_process_damping
from ._fields import LIST_TABLES, PARAMETER_TABLES, TABLES, _Ids, _Item
from ._frf import read_frf_table
from ._items import (
    SSV_AMPLITUDE_MAX,
    SSV_FREQUENCY_RANGE,
    SSV_SHAPES,
    Machine,
    Mode,
    Model,
    Process,
    SpindleSpeedVariation,
    machine_problem,
)
from ._matrices import _read_matrix_model
from ._modes import read_modal_model, shape_coordinates
from ._points import (
    _check_stroke,
    _read_couplings,
    _read_points,
    _read_process,
    _read_springs,
    _RefContext,
    milling_couplings,
)
from ._tables import (
    _check_massless,
    _check_movable,
    _coordinate_names,
    _read_attachments,
    _read_beams,
    _read_bodies,
    _read_constraints,
    _read_contacts,
    _read_movable,
    _read_nodes,
    _read_supports,
)
from ._uncertainty import read_uncertainty

__all__ = ["load_model", "loads_model", "build_model"]


#: Limits checked before anything is parsed or allocated (docs/model-format.md, "Limits").
MAX_MODEL_BYTES = 8 * 2**20  #: a model file larger than this is refused unread
MAX_NESTING = 32  #: tables and arrays nested deeper than this are refused
MAX_INTEGER = 2**63  #: integers must have |n| < 2**63 (write larger numbers as floats, 1e20)


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
    if head in LIST_TABLES and len(path) >= 2 and isinstance(path[1], int):
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


def _apply_overrides(src: str, raw: dict[str, Any], overrides: Mapping[str, Any], what: str) -> None:
    for path, value in overrides.items():
        # values from a numpy grid (np.int64 elements, np.float32 ...) are
        # the Python numbers a TOML file would hold
        if isinstance(value, np.generic):
            value = value.item()
        elif isinstance(value, np.ndarray):
            value = value.tolist()
        parts = str(path).split(".")
        if len(parts) == 3 and parts[0] in LIST_TABLES:
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
        elif len(parts) == 2 and parts[0] in PARAMETER_TABLES:
            tbl, fld = parts
            table = raw.setdefault(tbl, {})
            if not isinstance(table, dict):
                raise ModelError(f"{what} '{path}': [{tbl}] is not a table in the file", source=src)
            table[fld] = value
        else:
            raise ModelError(
                f"{what} '{path}' does not address a field: write KIND.ID.FIELD for list items"
                f" (KIND one of {', '.join(LIST_TABLES)}) or movable.FIELD / process.FIELD / frf.FIELD",
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
    """The model of a parsed file: the variant and overrides applied, then one
    reader per table, in the order in which the tables refer to each other."""
    src = source
    raw = copy.deepcopy(raw)
    frozen_raw = json.dumps(raw)
    base_dir = Path(raw.pop("__base_dir__", "."))
    files_outside = bool(raw.pop("__files_outside__", False))
    read_uncertainty(src, raw, variant, overrides)  # [uncertainty]: checked, set aside (_uncertainty)
    _check_tables(src, raw)
    _apply_variant(src, raw, variant, overrides)
    meta = _Item(src, "[model]", raw.get("model", {}), ("name", "description", "reference"))
    name = meta.str("name", Path(src).stem)

    ids = _Ids(src)
    movable = _read_movable(src, raw)
    mov_bodies = set(movable.bodies) if movable is not None else set()
    bodies = _read_bodies(src, raw, ids, movable)
    body_ids = {b.id for b in bodies}
    nodes = _read_nodes(src, raw, ids)
    node_xy = {n.id: np.array(n.xy) for n in nodes}
    beams, beam_len = _read_beams(src, raw, ids, node_xy)
    contacts = _read_contacts(src, raw, ids, beams, node_xy, body_ids, mov_bodies)
    matrices = _read_matrix_model(src, raw, base_dir, files_outside)
    modal = read_modal_model(src, raw)
    modes: tuple[Mode, ...] = ()
    shapes: dict[str, tuple[tuple[str, float], ...]] = {}
    if modal is not None:
        modes, matrices = modal
        shapes = shape_coordinates(modes)
    frf = read_frf_table(src, raw, base_dir, files_outside)
    coord_names = set(matrices.coordinates) if matrices and not modes else set(shapes)
    if frf is not None:
        coord_names = set(frf.coordinates)
    ctx = _RefContext(src, body_ids, node_xy, beam_len, {c.id for c in contacts}, coord_names, {}, shapes)
    points = _read_points(src, raw, ids, ctx)
    springs = _read_springs(src, raw, ids, ctx)
    attachments = _read_attachments(src, raw, ids, node_xy, body_ids, mov_bodies)
    supports = _read_supports(src, raw, node_xy, body_ids, set() if modes else coord_names)
    constraints = _read_constraints(src, raw, _coordinate_names(bodies, nodes, beams, contacts, matrices))
    _check_massless(src, bodies, constraints)
    couplings = _read_couplings(src, raw, ids, ctx)
    process = _read_process(src, raw["process"]) if "process" in raw else None
    couplings = milling_couplings(src, couplings, process)
    _check_stroke(src, process, movable)
    absorbers = read_absorbers(src, raw, ids, ctx)
    actuators = read_actuators(src, raw, ids, ctx)
    machine = _read_machine(src, raw, process)
    process_damping = read_process_damping(src, raw, process, couplings, machine)
    ssv = _read_ssv(src, raw, process)

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
        absorbers=tuple(absorbers),
        actuators=tuple(actuators),
        process=process,
        movable=movable,
        matrices=matrices,
        modes=modes,
        frf=frf,
        machine=machine,
        process_damping=process_damping,
        ssv=ssv,
        variant=variant,
        overrides=tuple((overrides or {}).items()),
        text=text,
        raw=frozen_raw,
        rebuild=build_model,
    )
    if not matrices and not bodies and not beams and frf is None:
        raise ModelError(
            "the model has no [[body]], no [[beam]], no [matrices] and no [[mode]]; nothing to analyse",
            source=src,
        )
    if movable is not None or contacts:
        _check_movable(model)
    from ._geometry import check_geometry

    check_geometry(model)
    return model


def _check_tables(src: str, raw: dict[str, Any]) -> None:
    """Only known tables, and the list tables written as arrays of tables."""
    for key in raw:
        if key not in LIST_TABLES and key not in TABLES:
            close = difflib.get_close_matches(key, list(LIST_TABLES + TABLES), n=1)
            hint = f" Did you mean '{close[0]}'?" if close else ""
            raise ModelError(
                f"unknown table '{key}'.{hint} Known: "
                + ", ".join([f"[[{k}]]" for k in LIST_TABLES] + [f"[{k}]" for k in TABLES]),
                source=src,
            )
    for kind in LIST_TABLES:
        if kind in raw and not isinstance(raw[kind], list):
            raise ModelError(f"'{kind}' must be an array of tables, written [[{kind}]]", source=src)


def _apply_variant(
    src: str, raw: dict[str, Any], variant: str | None, overrides: Mapping[str, Any] | None
) -> None:
    """Apply the selected [variant.NAME] and then the overrides to ``raw`` (every
    variant is checked to address existing fields, even when not selected)."""
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


#: the most points of a [machine] power or torque curve
MAX_CURVE_POINTS = 10_000


def _read_machine(src: str, raw: dict[str, Any], process: Process | None) -> Machine | None:
    """The ``[machine]`` table (docs/model-format.md, "[machine]"): the limits of
    the machine and its tool that a recommended cut respects, and its feed; the
    rules are :func:`chatterlab.model._items.machine_problem`'s."""
    if "machine" not in raw:
        return None
    if process is None or process.kind == "delay":
        raise ModelError(
            "needs a [process] of kind turning, milling or shaping: its speeds are in the process's unit",
            source=src,
            item="[machine]",
        )
    kind = process.kind
    spindle = kind in ("turning", "milling")
    vmax, vmin = ("max_rpm", "min_rpm") if spindle else ("max_speed", "min_speed")
    t = raw["machine"]
    others = ("max_speed", "min_speed") if spindle else ("max_rpm", "min_rpm")
    for key, use in zip(others, (vmax, vmin), strict=True):
        if isinstance(t, dict) and key in t:
            raise ModelError(
                f"{key}: a {kind} process's speed is in {process.speed_unit}: write {use}",
                source=src,
                item="[machine]",
                field=key,
            )
    fields = (vmax, vmin, "power", "torque", "max_depth", "max_width", "feed", "workpiece_diameter",
              "specific_energy", "description")  # fmt: skip
    it = _Item(src, "[machine]", t, fields)
    unit = process.speed_unit
    inf, nan = float("inf"), float("nan")
    machine = Machine(
        max_speed=it.num(vmax, inf, unit=unit, positive=True),
        min_speed=it.num(vmin, 0.0, unit=unit, nonneg=True),
        power=_curve(it, "power", "W", unit),
        torque=_curve(it, "torque", "N m", unit),
        max_depth=it.num("max_depth", inf, unit="m", positive=True),
        max_width=it.num("max_width", inf, unit="m", positive=True),
        feed=it.num("feed", nan, unit="m", positive=True),
        workpiece_diameter=it.num("workpiece_diameter", nan, unit="m", positive=True),
        specific_energy=it.num("specific_energy", nan, unit="N/m^2", positive=True),
    )
    bad = machine_problem(machine, kind)
    if bad is not None:
        raise it.err(*bad)
    return machine


def _curve(it: _Item, key: str, what: str, unit: str) -> tuple[tuple[float, float], ...]:
    """A number (the same at every speed) or a list of [speed, value] points."""
    v = it.raw(key, None)
    if v is None:
        return ()
    if isinstance(v, int | float) and not isinstance(v, bool):
        return ((0.0, it.num(key, unit=what, positive=True)),)
    form = f"a number in {what} or a list of [speed {unit}, {key} {what}] points"
    if not isinstance(v, list) or not v:
        raise it.err(key, f"must be {form}, got {v!r}")
    if len(v) > MAX_CURVE_POINTS:
        raise it.err(key, f"has {len(v)} points; at most {MAX_CURVE_POINTS} are read")
    out = []
    for i, p in enumerate(v):
        ok = (
            isinstance(p, list)
            and len(p) == 2
            and all(isinstance(x, int | float) and not isinstance(x, bool) for x in p)
        )
        if not ok:
            raise it.err(key, f"point {i + 1} must be [speed {unit}, {key} {what}], got {p!r}")
        out.append((float(p[0]), float(p[1])))
    return tuple(out)


def _read_ssv(src: str, raw: dict[str, Any], process: Process | None) -> SpindleSpeedVariation | None:
    """The ``[ssv]`` table (docs/ssv.md): shape, rva, rvf, or None when the file has none."""
    if "ssv" not in raw:
        return None
    it = _Item(src, "[ssv]", raw["ssv"], ("shape", "rva", "rvf", "description"))
    if process is None or process.kind == "delay":
        raise it.err(
            None,
            "needs a [process] of kind turning, shaping or milling: the variation is of its speed, which a"
            " delay process does not have",
        )
    shape = it.str("shape", "sine")
    if shape not in SSV_SHAPES:
        raise it.err("shape", f"must be one of {', '.join(SSV_SHAPES)} (got {shape!r})")
    rva = it.num("rva", nonneg=True)
    if rva > SSV_AMPLITUDE_MAX:
        raise it.err(
            "rva",
            f"{rva:g} is above {SSV_AMPLITUDE_MAX:g}: rva is the speed's amplitude over its mean (a ratio, 1),"
            " e.g. 0.1 for +-10 %",
        )
    rvf = it.num("rvf", positive=True)
    lo, hi = SSV_FREQUENCY_RANGE
    if not lo <= rvf <= hi:
        raise it.err(
            "rvf",
            f"{rvf:g} is outside {lo:g}..{hi:g}: rvf is the variation's frequency over the mean rotation"
            " frequency (a ratio, 1), e.g. 0.5 for one cycle in two revolutions",
        )
    return SpindleSpeedVariation(rva, rvf, shape)
