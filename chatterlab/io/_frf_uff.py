"""Measured FRFs in Universal File Format dataset 58 / 58b through pyuff:
the reader and the (atomic) writer (format in docs/measured-frf.md)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ._frf_table import (
    _QNAME,
    FRFRecord,
    _check_increasing,
    _line_of,
    _resolve_units,
    check_points,
    read_input,
    to_si,
)

__all__ = ["read_frf_uff", "write_frf_uff"]


# ============================================================================ UFF 58 / 58b

_UFF_DIRS = {1: "x", 2: "y", 3: "z", 4: "rx", 5: "ry", 6: "rz"}
_UFF_DIR_CODES = {v: k for k, v in _UFF_DIRS.items()}
#: ordinate specific data types of dataset 58 (record 8) -> power of j w
_UFF_ORDINATE = {8: 0, 11: 1, 12: 2}


def _pyuff() -> Any:
    try:
        import pyuff
    except ImportError:
        raise InputError(
            "reading or writing UFF files needs pyuff: pip install chatterlab[uff] (or pip install pyuff)"
        ) from None
    return pyuff


def read_frf_uff(
    path: str | os.PathLike[str],
    *,
    units: str | None = None,
    quantity: str | None = None,
    point: str | None = None,
) -> FRFRecord:
    """Read the FRFs (function type 4) of a UFF file, datasets 58 and 58b.

    Each dataset is one (response node+direction, reference node+direction)
    pair; together they form the matrix, coordinates named ``NODE.DIR``
    (``x, y, z, rx, ry, rz``; a negative direction flips the sign of the
    data so the name is the positive axis) -- or ``ENTITY.DIR`` when every
    node carries one entity name (as chatterlab writes).  Coherences
    (function type 6) of the same pairs are read too.  The ordinate type
    (record 8: 8 displacement, 11 velocity, 12 acceleration) gives the
    quantity; the values are taken as SI unless ``units`` says otherwise
    (dataset 164 is not read)."""
    pyuff = _pyuff()
    p = Path(os.fspath(path))
    where = str(p)
    _uff_blocks(read_input(p), where)  # a regular file, within the cap, every dataset closed
    frfs, cohs = _uff_datasets(pyuff, p, where)
    x0, power0, entries, coh_entries = _uff_entries(frfs, cohs, quantity, where)
    A, coh, outs, ins = _uff_matrix(entries, coh_entries, x0.size, where)
    qname = None if power0 is None else _QNAME[power0]
    scale, power, used = _resolve_units(units, quantity, None, qname, where, "m/N" if qname is None else None)
    meta = {"units": used, "quantity": _QNAME[power], "format": "uff58", "datasets": len(frfs)}
    return FRFRecord(x0, to_si(x0, A, scale, power, where, None), outs, ins, _QNAME[power], coh, where, meta)


def _uff_tags(data: bytes) -> list[int]:
    """Offsets of the ``    -1`` lines that open and close the datasets,
    found as pyuff finds them (so both see the same blocks)."""
    tags: list[int] = []
    ind = -1
    n = len(data)
    while True:
        ind = data.find(b"    -1", ind + 1)
        if ind == -1:
            return tags
        end = ind + 6
        if (
            end == n
            or (end < n and data[end] in (10, 13))
            or (ind + 80 < n and data[end : ind + 80] == b" " * 74)
        ):
            tags.append(ind)


def _uff_blocks(data: bytes, where: str) -> None:
    """The file is datasets and nothing else: every ``    -1`` that opens a
    dataset has its closing ``    -1`` (pyuff silently drops a last dataset
    that has none: a truncated file would be read in part), and no text
    lies between or around them."""
    tags = _uff_tags(data)
    if not tags:
        if data.strip():
            raise InputError(
                f"{where}: not a UFF file (no '    -1' line opening a dataset); export the FRFs as UFF 58"
            )
        raise InputError(f"{where}: the file is empty; export the FRFs as UFF 58")
    if len(tags) % 2:
        raise InputError(
            f"{where}, line {_line_of(data, tags[-1])}: the dataset opened here has no closing '    -1' line:"
            " the file is truncated (or a dataset is damaged); export it again"
        )
    edges = [0, *tags, len(data)]
    for k in range(0, len(edges), 2):  # outside the blocks: [start, first tag), [close + its line, next open)
        lo, hi = edges[k], edges[k + 1]
        if k:
            nl = data.find(b"\n", lo)
            lo = hi if nl == -1 or nl > hi else nl + 1
        junk = data[lo:hi]
        if junk.strip():
            off = lo + len(junk) - len(junk.lstrip())
            raise InputError(
                f"{where}, line {_line_of(data, off)}: text outside any dataset (a dataset is the lines between two"
                " '    -1' lines); the file is damaged or not UFF"
            )


#: datasets as (index in the file, pyuff's fields); FRFs or coherences per (output, input) pair
_Sets = list[tuple[int, dict[str, Any]]]
_Pairs = dict[tuple[str, str], np.ndarray]


def _uff_datasets(pyuff: Any, p: Path, where: str) -> tuple[_Sets, _Sets]:
    """The datasets 58 of the file as (index, fields): the FRFs (function
    type 4) and the coherences (6); InputError when there is no FRF."""
    try:
        uf = pyuff.UFF(str(p))
        types = [int(t) for t in uf.get_set_types()]
    except Exception as exc:  # pyuff raises bare Exceptions on malformed files
        raise InputError(f"{where}: not a readable UFF file ({exc})") from None
    idx = [k for k, t in enumerate(types) if t == 58]
    if not idx:
        found = ", ".join(str(t) for t in dict.fromkeys(types)) or "none"
        raise InputError(
            f"{where}: no dataset 58 (FRF) in the file (datasets found: {found}); export the FRFs as UFF 58"
        )
    sets = []
    for k in idx:
        try:
            sets.append((k, uf.read_sets(k)))
        except Exception as exc:
            raise InputError(f"{where}, dataset {k + 1} (58): cannot be read ({exc})") from None
    frfs = [(k, s) for k, s in sets if int(s.get("func_type", 0)) == 4]
    cohs = [(k, s) for k, s in sets if int(s.get("func_type", 0)) == 6]
    if not frfs:
        kinds = sorted({int(s.get("func_type", 0)) for _, s in sets})
        raise InputError(f"{where}: the datasets 58 hold no FRF (function type 4; found types {kinds})")
    return frfs, cohs


def _uff_entries(
    frfs: _Sets, cohs: _Sets, quantity: str | None, where: str
) -> tuple[np.ndarray, int | None, _Pairs, _Pairs]:
    """(frequencies, power of j w of the FRFs' quantity, FRF per (output,
    input), coherence per pair), every dataset checked: one frequency grid,
    one quantity, complex finite FRFs, each pair once."""
    ent = _entity_names(frfs)
    x0: np.ndarray | None = None
    power0: int | None = None
    entries: _Pairs = {}
    coh_entries: _Pairs = {}
    for group, target in ((frfs, entries), (cohs, coh_entries)):
        for k, s in group:
            ds = f"{where}, dataset {k + 1} (58)"
            x = np.asarray(s["x"], dtype=float)
            y = np.asarray(s["data"])
            declared = int(s.get("num_pts", x.size))
            if not x.size == y.size == declared:
                raise InputError(
                    f"{ds}: declares {declared} points but holds {y.size} values"
                    f"{'' if x.size == y.size else f' and {x.size} frequencies'}: the file is truncated or"
                    " damaged; export it again"
                )
            check_points(x.size, ds)
            if target is entries and not np.iscomplexobj(y):
                raise InputError(
                    f"{ds}: ordinate data type {s.get('ord_data_type')} is real; an FRF is complex (5 or 6)"
                )
            if x0 is None:
                x0 = x
                _check_increasing(x, list(range(1, x.size + 1)), f"{ds}, abscissa point")
            elif x.shape != x0.shape or not np.allclose(x, x0, rtol=1e-9, atol=0):
                raise InputError(
                    f"{ds}: its frequencies differ from the first FRF's; resample all FRFs on one grid"
                )
            o, sgn_o = _uff_coord(s, "rsp", ent, ds)
            i, sgn_i = _uff_coord(s, "ref", ent, ds)
            if target is entries:
                pw = _UFF_ORDINATE.get(int(s.get("ordinate_spec_data_type", 0)))
                if pw is None and quantity is None:
                    raise InputError(
                        f"{ds}: ordinate type {s.get('ordinate_spec_data_type')} is not displacement (8), velocity (11)"
                        " or acceleration (12); give the quantity (quantity=..., --frf-quantity)"
                    )
                if power0 is not None and pw != power0:
                    raise InputError(
                        f"{ds}: a different quantity than the first FRF's; give all FRFs as one quantity"
                    )
                power0 = pw
                val = y.astype(complex) * sgn_o * sgn_i
            else:
                val = np.abs(np.asarray(y, dtype=complex))
            if (o, i) in target:
                raise InputError(f"{ds}: the pair {o}/{i} appears twice; keep one dataset per pair")
            if not np.all(np.isfinite(val)):
                j = int(np.nonzero(~np.isfinite(val))[0][0])
                raise InputError(f"{ds}, point {j + 1} ({x[j]:g} Hz): not a finite value; repair or drop it")
            target[(o, i)] = val
    assert x0 is not None
    return x0, power0, entries, coh_entries


def _uff_matrix(
    entries: _Pairs, coh_entries: _Pairs, n: int, where: str
) -> tuple[np.ndarray, np.ndarray | None, tuple[str, ...], tuple[str, ...]]:
    """(A (n_out, n_in, n), coherence like A or None, outputs, inputs) from
    the pairs; InputError when a pair of the matrix is missing.  A coherence
    of a pair that is not an FRF's is ignored; one not given is 1."""
    outs = tuple(dict.fromkeys(o for o, _ in entries))
    ins = tuple(dict.fromkeys(i for _, i in entries))
    missing = [f"{o}/{i}" for o in outs for i in ins if (o, i) not in entries]
    if missing:
        raise InputError(
            f"{where}: the FRFs form a {len(outs)}x{len(ins)} matrix but {', '.join(missing)} is not in the file;"
            " add its dataset 58"
        )
    A = np.empty((len(outs), len(ins), n), dtype=complex)
    for (o, i), v in entries.items():
        A[outs.index(o), ins.index(i)] = v
    coh = None
    if coh_entries:
        coh = np.ones(A.shape)
        for (o, i), v in coh_entries.items():
            if o in outs and i in ins:
                coh[outs.index(o), ins.index(i)] = v
    return A, coh, outs, ins


def _entity_names(frfs: list[tuple[int, dict[str, Any]]]) -> dict[int, str] | None:
    """Node -> entity name when every node carries exactly one real name."""
    names: dict[int, set[str]] = {}
    for _, s in frfs:
        for side in ("rsp", "ref"):
            nm = str(s.get(f"{side}_ent_name", "")).strip()
            names.setdefault(int(s[f"{side}_node"]), set()).add(nm)
    out = {}
    for node, ns in names.items():
        if len(ns) != 1:
            return None
        nm = next(iter(ns))
        if not nm or nm.upper() == "NONE":
            return None
        out[node] = nm
    if len(set(out.values())) != len(out):
        return None
    return out


def _uff_coord(s: dict[str, Any], side: str, ent: dict[int, str] | None, ds: str) -> tuple[str, float]:
    node = int(s[f"{side}_node"])
    d = int(s[f"{side}_dir"])
    if abs(d) not in _UFF_DIRS:
        what = "response" if side == "rsp" else "reference"
        raise InputError(f"{ds}: {what} direction {d} is not one of +-1..6 (x, y, z, rx, ry, rz)")
    name = ent[node] if ent else str(node)
    return f"{name}.{_UFF_DIRS[abs(d)]}", (1.0 if d > 0 else -1.0)


def write_frf_uff(path: str | os.PathLike[str], record: FRFRecord, *, binary: bool = False) -> Path:
    """Write one UFF dataset 58 (58b with ``binary``) per (output, input)
    pair: function type 4 (FRF), the record's quantity over force (ordinate
    types 8 displacement, 11 velocity or 12 acceleration / 13 force), SI, frequencies as explicit abscissa values (uneven spacing, so an
    uneven grid is kept), complex double ordinates.  A coordinate named
    ``NODE.DIR`` with an integer node keeps its node; other point names get
    nodes 1, 2, ... in order and are written as the entity name (at most 10
    characters), which :func:`read_frf_uff` reads back.  Coherences as
    function type 6.  Written to a temporary name and moved into place.

    Precision: 58b (binary) is exact; ASCII 58 writes ordinates with 12
    significant digits (E20.11) and the abscissa with 6 (E13.5), so two
    frequencies closer than ~1e-5 relative collapse in ASCII."""
    from ._files import _tmp_name

    pyuff = _pyuff()
    coords = list(dict.fromkeys(record.outputs + record.inputs))
    points = list(dict.fromkeys(c.rpartition(".")[0] for c in coords))
    node_of: dict[str, int] = {}
    numeric = all(pt.isdigit() for pt in points)
    for k, pt in enumerate(points, 1):
        if not pt:
            raise InputError("UFF coordinates must be named POINT.DIR (e.g. tool.x or 12.x); rename them")
        node_of[pt] = int(pt) if numeric else k
        if not numeric and len(pt) > 10:
            raise InputError(f"UFF entity names hold at most 10 characters: rename point {pt!r}")

    def split(c: str) -> tuple[int, int, str]:
        pt, _, d = c.rpartition(".")
        if d not in _UFF_DIR_CODES:
            raise InputError(
                f"UFF coordinate {c!r}: the direction must be one of {', '.join(_UFF_DIR_CODES)}"
            )
        return node_of[pt], _UFF_DIR_CODES[d], ("NONE" if numeric else pt)

    x = np.asarray(record.frequency_hz, dtype=float)
    ordinate = {p: code for code, p in _UFF_ORDINATE.items()}[_QNAME.index(record.quantity)]
    sets = []
    for func, arr in ((4, record.data), (6, record.coherence)):
        if arr is None:
            continue
        for o, on in enumerate(record.outputs):
            for i, inn in enumerate(record.inputs):
                rn, rd, re_ = split(on)
                fn, fd, fe = split(inn)
                sets.append(
                    pyuff.prepare_58(
                        binary=int(binary),
                        id1=("FRF" if func == 4 else "Coherence") + f" {on}/{inn}"[:70],
                        id2="chatterlab measured FRF",
                        func_type=func,
                        rsp_ent_name=re_,
                        rsp_node=rn,
                        rsp_dir=rd,
                        ref_ent_name=fe,
                        ref_node=fn,
                        ref_dir=fd,
                        ord_data_type=6,
                        abscissa_spacing=0,
                        abscissa_spec_data_type=18,
                        ordinate_spec_data_type=ordinate if func == 4 else 0,
                        orddenom_spec_data_type=13 if func == 4 else 0,
                        data=np.asarray(arr[o, i], dtype=complex),
                        x=x,
                    )
                )
    final = Path(os.fspath(path))
    tmp = _tmp_name(final)
    try:
        tmp.touch()
        # mode "add": pyuff's binary writer reopens the file by name and would truncate it in "overwrite"
        pyuff.UFF(str(tmp)).write_sets(sets, mode="add")
        os.replace(tmp, final)
        return final
    except BaseException:
        import contextlib

        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise
