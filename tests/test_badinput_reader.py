"""Classes 2 and 5 of issue 10: whatever a model file (or --set) holds, the
reader ends in a ModelError -- one line naming the file, the item and the
field -- never a traceback; sizes are checked before anything is allocated;
[matrices] files stay inside the model's folder unless the user opts in."""

from __future__ import annotations

import datetime
import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_clean_error
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import chatterlab as cl
from chatterlab.cli._main import main
from chatterlab.errors import ModelError
from chatterlab.model import _reader as modelfile

ROOT = Path(__file__).resolve().parents[1]
SHAPER = ROOT / "studies" / "traverse_shaper" / "model.toml"
SHAPER_TEXT = SHAPER.read_text()

MATRIX = """
[matrices]
coordinates = ["q1", "q2"]
M = {M}
K = [[2.0e6, -1.0e6], [-1.0e6, 1.0e6]]
[process]
kind = "turning"
rpm = 1500
"""


def check(capsys, path, *more):
    code = main(["check", str(path), *more])
    return code, capsys.readouterr().err


# ----------------------------------------------------------------------------- the examples


@pytest.mark.parametrize(
    "text, words",
    [
        ('[model]\nname = "a"\ncreated = 1979-05-27\n', ["date or time", "created"]),
        ('[[body]]\nid = "b"\nmass = 07:32:00\n', ["[[body]] #1", "mass", "date or time"]),
        ('[[body]]\nid = "b"\nmass = 1' + "0" * 400 + "\n", ["[[body]] #1", "mass", "401 digits", "1e20"]),
        ("a = " + "[" * 40 + "]" * 40 + "\n", ["nested too deeply"]),
        ("a = " + "[" * 5000 + "]" * 5000 + "\n", ["nested too deeply"]),
        ("a = " + "{b = " * 40 + "1" + "}" * 40 + "\n", ["nested too deeply"]),
        ('__base_dir__ = "/"\n', ["reserved"]),
        ("__files_outside__ = true\n", ["reserved"]),
    ],
)
def test_hostile_model_text_is_one_line(capsys, tmp_path, text, words):
    p = tmp_path / "m.toml"
    p.write_text(text)
    code, err = check(capsys, p)
    assert_clean_error(code, err, str(p), *words)


@pytest.mark.parametrize(
    "setting, words",
    [
        ('process.kind=["shaping"]', ["[process]", "kind", "must be one of"]),
        ("process.speed=" + "1" * 5000, ["--set process.speed"]),
        ("process.speed=" + "[" * 3000 + "]" * 3000, ["--set process.speed"]),
        ("process.speed=" + "[" * 40 + "]" * 40, ["nested too deeply"]),
        ("process.speed=" + str(10**30), ["[process]", "speed", "too large"]),
        ('model.name={"a": 1}', ["[model]", "name"]),
        ('body.frame.centre=[[0.0], {"x": 1}]', ['[[body]] "frame"', "centre"]),
        ('movable.bodies=[["slide"]]', ["[movable]", "bodies"]),
        ("=3", ["PATH"]),
    ],
)
def test_hostile_set_values_are_one_line(capsys, setting, words):
    code, err = check(capsys, SHAPER, "--set", setting)
    assert_clean_error(code, err, *words)


def test_huge_model_file_is_refused_before_it_is_read(capsys, tmp_path, monkeypatch):
    p = tmp_path / "huge.toml"
    with open(p, "wb") as fh:  # a sparse 50 MB file: no disk, and nothing is parsed
        fh.truncate(50 * 2**20)
    parsed = []
    monkeypatch.setattr(modelfile.tomllib, "loads", lambda *a, **k: parsed.append(1))
    code, err = check(capsys, p)
    assert_clean_error(code, err, "50.0 MiB", "at most 8 MiB")
    assert parsed == []


def test_unreadable_model_file_is_one_line(capsys, tmp_path, monkeypatch):
    p = tmp_path / "secret.toml"
    p.write_text('[model]\nname = "x"\n')
    real_open = open

    def refusing_open(file, *a, **k):
        if Path(file) == p:
            raise PermissionError(13, "Permission denied", str(file))
        return real_open(file, *a, **k)

    # root reads any file, so the refusal is simulated where the reader opens it
    monkeypatch.setattr(modelfile, "open", refusing_open, raising=False)
    code, err = check(capsys, p)
    assert_clean_error(code, err, str(p), "permission denied")


def test_model_path_that_is_a_directory_or_device(capsys, tmp_path):
    code, err = check(capsys, tmp_path)
    assert_clean_error(code, err, "directory")
    if os.path.exists("/dev/zero"):  # no size to stat: the read stops at the cap
        code, err = check(capsys, "/dev/zero")
        assert_clean_error(code, err, "/dev/zero")


# ----------------------------------------------------------------------------- [matrices] files


@pytest.fixture
def folder(tmp_path):
    d = tmp_path / "model"
    d.mkdir()
    return d


def write_model(folder, M):
    p = folder / "m.toml"
    p.write_text(MATRIX.replace("{M}", M))
    return p


def test_mtx_declaring_a_huge_matrix_is_refused_before_allocation(capsys, folder):
    (folder / "M.mtx").write_text(
        "%%MatrixMarket matrix coordinate real general\n1000000 1000000 1\n1 1 1.0\n"
    )
    code, err = check(capsys, write_model(folder, '"M.mtx"'))
    assert_clean_error(code, err, "[matrices]", "M:", "1000000x1000000", "at most 4000")
    (folder / "M.mtx").write_text("%%MatrixMarket matrix array real general\n1000000 1000000\n1.0\n")
    code, err = check(capsys, write_model(folder, '"M.mtx"'))
    assert_clean_error(code, err, "1000000x1000000")


def test_npy_declaring_a_huge_matrix_is_refused_before_allocation(capsys, folder):
    fmt = np.lib.format
    with open(folder / "M.npy", "wb") as fh:  # header only: the data would be 8 TB
        fmt.write_array_header_1_0(fh, {"descr": "<f8", "fortran_order": False, "shape": (10**6, 10**6)})
    code, err = check(capsys, write_model(folder, '"M.npy"'))
    assert_clean_error(code, err, "1000000x1000000")


def test_pickled_npy_is_refused_without_numpys_advice(capsys, folder):
    np.save(folder / "M.npy", np.array([[{"a": 1}, None], [None, 1]], dtype=object), allow_pickle=True)
    code, err = check(capsys, write_model(folder, '"M.npy"'))
    assert_clean_error(code, err, "never loaded")
    assert "unsafe" not in err and "allow_pickle" not in err
    import pickle

    (folder / "M.npy").write_bytes(pickle.dumps([[1.0, 0.0], [0.0, 1.0]]))
    code, err = check(capsys, write_model(folder, '"M.npy"'))
    assert_clean_error(code, err, "M.npy")
    assert "unsafe" not in err and "allow_pickle" not in err


def test_npz_members_are_checked_before_they_are_read(capsys, folder):
    np.savez(folder / "sys.npz", M=np.zeros((3, 4)), K=np.eye(3))
    p = folder / "m.toml"
    p.write_text('[matrices]\nfile = "sys.npz"\ncoordinates = ["a", "b", "c"]\n')
    code, err = check(capsys, p)
    assert_clean_error(code, err, "(3, 4)", "square")
    np.savez(folder / "sys.npz", M=np.array([[None]], dtype=object), K=np.eye(1))
    code, err = check(capsys, p)
    assert_clean_error(code, err, "never loaded")
    (folder / "sys.npz").write_bytes(b"not a zip file")
    code, err = check(capsys, p)
    assert_clean_error(code, err, "sys.npz")


@pytest.mark.parametrize("name", ["../outside/M.npy", "ABSOLUTE", "link/M.npy"])
def test_matrix_files_outside_the_models_folder_need_the_opt_in(capsys, folder, name):
    outside = folder.parent / "outside"
    outside.mkdir()
    np.save(outside / "M.npy", np.eye(2))
    (folder / "link").symlink_to(outside, target_is_directory=True)
    if name == "ABSOLUTE":
        name = str(outside / "M.npy")
    p = write_model(folder, json.dumps(name))
    code, err = check(capsys, p)
    assert_clean_error(code, err, "leads outside the model's folder", "--allow-outside-files")
    with pytest.raises(ModelError, match="outside"):
        cl.load_model(p)
    # the user's opt-in, on the command line or in Python
    assert check(capsys, p, "--allow-outside-files")[0] == 0
    m = cl.load_model(p, files_outside=True)
    np.testing.assert_array_equal(m.matrices.M, np.eye(2))
    # the opt-in travels with the model to its changed copies (sweeps over parameters)
    assert m.with_parameters({"process.rpm": 2000.0}).process.speed == 2000.0


def test_matrix_files_inside_the_folder_are_read(folder):
    (folder / "sub").mkdir()
    np.save(folder / "sub" / "M.npy", np.eye(2))
    m = cl.load_model(write_model(folder, '"sub/M.npy"'))
    np.testing.assert_array_equal(m.matrices.M, np.eye(2))


def test_every_np_load_refuses_pickles():
    """allow_pickle=False wherever chatterlab calls np.load (a source check: a new call
    without it fails here)."""
    import re

    for path in (ROOT / "chatterlab").glob("*.py"):
        for m in re.finditer(r"np\.load\(([^)]*)\)", path.read_text()):
            assert "allow_pickle=False" in m[1], f"{path.name}: np.load({m[1]})"


# ----------------------------------------------------------------------------- fuzz

KEYS = [
    "id", "mass", "inertia", "centre", "at", "nodes", "E", "nu", "G", "rho", "A", "I", "kind", "speed",
    "rpm", "delay", "bodies", "position", "range", "direction", "a", "b", "c1", "c2", "model", "Kf",
    "width_ref", "coordinates", "M", "K", "file", "beams", "follows", "node", "body", "fix", "coords",
    "dependent", "equations", "elements", "name", "x",
]  # fmt: skip
TABLES = list(modelfile.LIST_TABLES) + list(modelfile.TABLES) + ["other"]

scalars = st.one_of(
    st.integers(min_value=-(2**70), max_value=2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8),
    st.sampled_from(
        ["ground", "frame", "slide", "shaping", "turning", "delay", "p", "q", "q1", "M.npy", "../x.npy"]
    ),
    st.booleans(),
    st.dates(),
    st.times(),
    st.datetimes(),
)
values = st.recursive(
    scalars,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4), st.dictionaries(st.sampled_from(KEYS), inner, max_size=4)
    ),
    max_leaves=12,
)
items = st.dictionaries(st.sampled_from(KEYS), values, max_size=6)
raw_models = st.dictionaries(
    st.sampled_from(TABLES), st.one_of(items, st.lists(items, max_size=3), values), max_size=5
)


def toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, datetime.date | datetime.time):
        return v.isoformat()
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return "{" + ", ".join(f"{json.dumps(k)} = {toml_value(x)}" for k, x in v.items()) + "}"


def toml_text(raw):
    lines = []
    for table, content in raw.items():
        if isinstance(content, list) and all(isinstance(x, dict) for x in content) and content:
            for item in content:
                lines.append(f"[[{table}]]")
                lines += [f"{json.dumps(k)} = {toml_value(v)}" for k, v in item.items()]
        else:
            lines.append(f"{json.dumps(table)} = {toml_value(content)}")
    return "\n".join(lines) + "\n"


@settings(max_examples=150, deadline=None)
@given(raw=raw_models)
def test_fuzz_model_text_is_a_model_or_a_model_error(raw):
    try:
        text = toml_text(raw)
    except (ValueError, OverflowError):
        return
    try:
        cl.loads_model(text, source="fuzz.toml")
    except ModelError as exc:
        assert "\n" not in str(exc).strip() or "is not valid TOML" in str(exc)
        assert str(exc).startswith("fuzz.toml")


@settings(max_examples=150, deadline=None)
@given(raw=raw_models)
def test_fuzz_parsed_dicts_are_a_model_or_a_model_error(raw):
    try:
        modelfile.build_model(raw, source="fuzz.toml")
    except ModelError as exc:
        assert str(exc).startswith("fuzz.toml")


SHAPER_LINES = SHAPER_TEXT.splitlines()
VALUE_LINES = [i for i, ln in enumerate(SHAPER_LINES) if " = " in ln and not ln.lstrip().startswith("#")]


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(line=st.sampled_from(VALUE_LINES), value=values)
def test_fuzz_one_spoilt_value_of_the_shaper(line, value):
    """Spoil one value of the shipped model: a Model (the value happened to be
    valid) or a one-line ModelError naming the file."""
    lines = list(SHAPER_LINES)
    key = lines[line].split(" = ", 1)[0]
    try:
        lines[line] = f"{key} = {toml_value(value)}"
    except (ValueError, OverflowError):
        return
    try:
        cl.loads_model("\n".join(lines), source="spoilt.toml")
    except ModelError as exc:
        assert str(exc).startswith("spoilt.toml")


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(path=st.sampled_from(["process.kind", "process.speed", "movable.position", "movable.bodies", "body.frame.mass", "spring.leg3-foundation.c2", "model.name", "beam.table.nodes"]), value=values)  # fmt: skip
def test_fuzz_set_values_never_traceback(capsys, path, value):
    try:
        text = json.dumps(value, default=str)
    except (ValueError, OverflowError):
        return
    code = main(["check", str(SHAPER), "--set", f"{path}={text}"])
    out = capsys.readouterr()
    assert code in (0, 2), out.err
    if code == 2:
        assert_clean_error(code, out.err)
