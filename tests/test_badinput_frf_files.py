"""Classes 3, 4, 5 and 7 of issue 21 on measured-FRF files (CSV, CutPro-style
``.frf``, UFF 58/58b), and the FRF headers of issue 20 item 4.

One reader contract: a reader reads the whole file as documented or refuses
it with the file, the line and the reason (status 2 and one line on the
command line); it never blocks on a FIFO or a device, never reads a file
above its cap, and the file it reads is never an output of the command,
however the output is spelt."""

from __future__ import annotations

import hashlib
import json
import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_clean_error
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from chatterlab.cli._main import main
from chatterlab.errors import ChatterlabError, InputError
from chatterlab.io import read_frf, write_frf_uff
from chatterlab.io._frf_table import FRFRecord

ROOT = Path(__file__).resolve().parents[1]
SCALE = {"m/N": 1.0, "mm/N": 1e-3, "um/N": 1e-6, "µm/N": 1e-6}
LOBES = ["--kf", "2e9", "--speed", "2000", "6000", "--points", "3", "--width-max", "5", "--verify", "0"]
#: the longest a refusal or a small read may take here, s (a blocked FIFO or /dev/zero never ends)
BOUND = 20.0

MODEL = """[frf]
file = "{file}"

[[point]]
id = "tool"
coords = {{ x = "{coord}" }}

[[coupling]]
id = "cut"
a = "tool"
b = "ground"
model = "regenerative"
width_ref = 0.001
Kf = 2e9

[process]
kind = "turning"
rpm = 3000
"""


def sdof(f_hz):
    w = 2 * np.pi * np.asarray(f_hz, float)
    return 1.0 / (1.0e7 - w**2 + 2j * 0.03 * np.sqrt(1.0e7) * w)


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def run(capsys, *argv):
    t0 = time.monotonic()
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err, time.monotonic() - t0


def assert_one_line_outcome(code, err, elapsed):
    """Status 0, 1 or 2 (never 3), no traceback, at most one error line, in bounded time."""
    assert code in (0, 1, 2), err
    assert "Traceback" not in err and "internal error" not in err, err
    if code == 2:
        assert_clean_error(code, err)
    assert elapsed < BOUND, elapsed


def csv_text(f, H, units="m/N"):
    rows = "".join(
        f"{a!r},{z.real / SCALE[units]!r},{z.imag / SCALE[units]!r}\n"
        for a, z in zip(f.tolist(), H.tolist(), strict=True)
    )
    return f"# units: {units}\nf,re,im\n{rows}"


@pytest.fixture
def tap(tmp_path):
    f = np.arange(100.0, 1500.0, 4.0)
    p = tmp_path / "tap.csv"
    p.write_text(csv_text(f, sdof(f)))
    return p


# ============================================================================ fuzz: valid files read whole

freqs = st.lists(st.floats(0.5, 40.0), min_size=4, max_size=40).map(lambda d: 100.0 + np.cumsum(d))


@st.composite
def csv_files(draw):
    """A valid CSV in one of the documented spellings, and what it holds (f, H in m/N)."""
    f = draw(freqs)
    H = sdof(f) * draw(st.sampled_from([1.0, -1.0, 1e3]))
    units = draw(st.sampled_from(sorted(SCALE)))
    delim = draw(st.sampled_from([",", "\t", ";", " "]))
    fname = draw(st.sampled_from(["f", "freq", "frequency", "Frequency [Hz]", "f (Hz)", "freq_hz", "FREQ"]))
    prefix = draw(st.sampled_from(["", "xx ", "tool.x/tool.x ", "xx_", "xx:"]))
    in_column = draw(st.booleans())
    cu = f" [{units}]" if in_column else ""
    z = H / SCALE[units]
    if draw(st.booleans()):
        a = draw(st.sampled_from(["re", "real", "Re", "Real", "real part", "REAL"]))
        b = draw(st.sampled_from(["im", "imag", "imaginary", "Imaginary", "imag part", "IMAG"]))
        names = [f"{prefix}{a}{cu}", f"{prefix}{b}{cu}"]
        cols = [z.real, z.imag]
    else:
        a = draw(st.sampled_from(["mag", "magnitude", "abs", "amp", "amplitude", "Magnitude"]))
        ph = draw(
            st.sampled_from(
                ["phase [deg]", "phase (deg)", "phase_deg", "phase [rad]", "Phase (rad)", "phase_rad"]
            )
        )
        rad = "rad" in ph.lower()
        names = [f"{prefix}{a}{cu}", f"{prefix}{ph}"]
        cols = [np.abs(z), np.angle(z) if rad else np.degrees(np.angle(z))]
    if delim == " ":
        names = [n.replace(" [", "[").replace(" (", "(").replace(" ", "_") for n in names]
        fname = fname.replace(" [", "[").replace(" (", "(").replace(" ", "_")
    head = []
    if not in_column:
        head.append(draw(st.sampled_from([f"# units: {units}", f"# Units = {units}", f"#units:{units}"])))
    head.append(draw(st.sampled_from(["", "# quantity: receptance", "# exported by a tap-test system"])))
    lines = [*head, delim.join([fname, *names])]
    for k in range(f.size):
        lines.append(delim.join(repr(float(v)) for v in (f[k], cols[0][k], cols[1][k])))
        if draw(st.integers(0, 9)) == 0:
            lines.append(draw(st.sampled_from(["", "# a comment between rows", "   "])))
    return lines, f, H


@st.composite
def frf_files(draw):
    """A valid CutPro-style file (units from a Units line, a caption, or none: m/N)."""
    f = draw(freqs)
    H = sdof(f)
    units = draw(st.sampled_from(sorted(SCALE)))
    how = draw(st.sampled_from(["line", "caption", "both", "none"]))
    if how == "none":
        units = "m/N"
    sep = draw(st.sampled_from(["\t", " ", "   "]))
    lines = [draw(st.sampled_from(["Tap test, spindle 2", "Point: tool", "% measured FRF"]))]
    if how in ("line", "both"):
        lines.append(draw(st.sampled_from([f"Units: {units}", f"units = {units}", f"# Unit: {units}"])))
    if how in ("caption", "both"):
        lines.append(f"Frequency(Hz)\tReal({units})\tImag({units})")
    z = H / SCALE[units]
    lines += [sep.join(repr(float(v)) for v in (a, b.real, b.imag)) for a, b in zip(f, z, strict=True)]
    return lines, f, H


ENCODINGS = ["utf-8", "utf-8-sig", "utf-16"]
EOLS = ["\n", "\r\n", "\r"]


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    case=st.one_of(csv_files().map(lambda c: ("csv", c)), frf_files().map(lambda c: ("frf", c))),
    encoding=st.sampled_from(ENCODINGS),
    eol=st.sampled_from(EOLS),
    final_eol=st.booleans(),
)
def test_fuzz_valid_files_are_read_whole(capsys, tmp_path, case, encoding, eol, final_eol):
    """Every documented spelling, encoding and line end: the whole file, exactly."""
    fmt, (lines, f, H) = case
    p = tmp_path / f"tap.{fmt}"
    p.write_bytes((eol.join(lines) + (eol if final_eol else "")).encode(encoding))
    before = digest(p)
    t = read_frf(p)
    np.testing.assert_array_equal(t.frequency_hz, f)
    np.testing.assert_allclose(t.data[0, 0], H, rtol=1e-9)
    model = tmp_path / "m.toml"
    model.write_text(MODEL.format(file=p.name, coord=t.outputs[0]))
    code, out, err, elapsed = run(capsys, "check", model)
    assert code == 0, err
    assert f"{f.size}, " in out and "measured FRF" in out
    assert elapsed < BOUND
    assert digest(p) == before


# ============================================================================ fuzz: damaged files


def _uff_file(path: Path, n: int, binary: bool) -> FRFRecord:
    f = 100.0 + 7.0 * np.arange(n)
    H = np.zeros((2, 2, n), complex)
    H[0, 0] = H[1, 1] = sdof(f)
    H[0, 1] = H[1, 0] = 0.1 * sdof(f)
    coh = np.full((2, 2, n), 0.9)
    t = FRFRecord(f, H, ("1.x", "1.y"), ("1.x", "1.y"), "receptance", coh)
    write_frf_uff(path, t, binary=binary)
    return t


DAMAGE = st.sampled_from(["truncate", "nan", "dup", "swap", "junk line", "bad byte", "control"])


def _damage(data: bytes, fmt: str, how: str, draw) -> bytes:
    if how == "truncate" or fmt == "uff":
        return data[: draw(st.integers(0, len(data) - 1))]
    lines = data.decode().split("\n")
    rows = [k for k, ln in enumerate(lines) if ln and ln[0].isdigit()]
    k = draw(st.sampled_from(rows))
    if how == "nan":
        cells = re.split(r"([,\t])", lines[k])
        j = draw(st.sampled_from(range(0, len(cells), 2)))
        cells[j] = draw(st.sampled_from(["nan", "inf", "-inf", "NaN", "Infinity"]))
        lines[k] = "".join(cells)
    elif how == "dup":
        lines.insert(k, lines[k])
    elif how == "swap":
        j = rows[rows.index(k) - 1] if rows.index(k) else rows[1]
        lines[j], lines[k] = lines[k], lines[j]
    elif how == "junk line":  # after the first row: never a title
        j = draw(st.integers(rows[0] + 1, len(lines)))
        lines.insert(j, draw(st.text(alphabet="abcdefghij XYZ!?", min_size=1, max_size=12).filter(str.strip)))
    elif how == "control":
        lines[k] = lines[k] + draw(st.sampled_from(["\x0c", "\x0b", "\x1a", "\x00", "\u2028"]))
    out = "\n".join(lines).encode()
    if how == "bad byte":
        j = draw(st.integers(0, len(out) - 1))
        out = out[:j] + draw(st.sampled_from([b"\xff", b"\xb5", b"\xc3"])) + out[j:]
    return out


def _complete_rows(text: str, cells: int, delim: str | None) -> int:
    """Data rows of a (truncated) CSV/.frf text with all their values."""
    n = 0
    for ln in re.split(r"\r\n|\r|\n", text):
        s = ln.strip()
        if s and (s[0].isdigit() or s[0] in "+-.") and len(s.split(delim) if delim else s.split()) == cells:
            n += 1
    return n


@settings(max_examples=45, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(fmt=st.sampled_from(["csv", "frf", "uff", "uff58b"]), how=DAMAGE, data=st.data())
def test_fuzz_damaged_files_are_refused_or_read_whole(capsys, tmp_path, fmt, how, data):
    """Truncation, NaN/inf, a repeated or swapped frequency, a junk line, a
    byte that is not UTF-8, a control character: status 2 and one line
    naming the file -- or, when what is left is still a valid file (a
    truncation at a line end), exactly that file, never part of it."""
    n = 12
    if fmt.startswith("uff"):
        p = tmp_path / "tap.uff"
        full = _uff_file(p, n, binary=fmt == "uff58b")
        fmt = "uff"
    else:
        p = tmp_path / f"tap.{fmt}"
        f = 100.0 + 9.0 * np.arange(n)
        if fmt == "csv":
            p.write_text(csv_text(f, sdof(f)))
        else:
            p.write_text(
                "Units: m/N\n"
                + "".join(
                    f"{a!r}\t{z.real!r}\t{z.imag!r}\n"
                    for a, z in zip(f.tolist(), sdof(f).tolist(), strict=True)
                )
            )
    p.write_bytes(_damage(p.read_bytes(), fmt, how, data.draw))
    before = digest(p)
    try:
        t = read_frf(p)
    except ChatterlabError as exc:
        assert str(exc).startswith(str(p)) and "\n" not in str(exc), exc
        t = None
    if t is not None:  # accepted: then it is the whole of what is there
        if fmt == "uff":
            np.testing.assert_array_equal(t.frequency_hz, full.frequency_hz)
            # a cut right after a dataset's closing '    -1' leaves a valid file of the datasets before
            # it (UFF has no count of datasets): read whole, they are the full file's entries exactly
            rows = [full.outputs.index(o) for o in t.outputs]
            cols = [full.inputs.index(i) for i in t.inputs]
            np.testing.assert_allclose(t.data, full.data[np.ix_(rows, cols)], rtol=1e-9)
            if t.coherence is not None:
                np.testing.assert_allclose(t.coherence, full.coherence[np.ix_(rows, cols)], rtol=1e-9)
            if t.data.shape != full.data.shape or t.coherence is None:
                # (blanks after it, the start of the next dataset's delimiter line, are still a whole file)
                assert how == "truncate" and p.read_bytes().rstrip().endswith(b"    -1"), how
        else:
            assert how == "truncate", how
            text = p.read_bytes().decode()
            rows = _complete_rows(text, 3, "," if fmt == "csv" else None)
            assert t.frequency_hz.size == rows
    code, _, err, elapsed = run(capsys, "lobes", "--frf", p, *LOBES, "--quiet")
    assert_one_line_outcome(code, err, elapsed)
    assert (code == 2) == (t is None), err
    assert digest(p) == before


# ============================================================================ class 5: the cases found, one by one


def write(tmp_path, name, text, encoding="utf-8"):
    p = tmp_path / name
    p.write_bytes(text.encode(encoding) if isinstance(text, str) else text)
    return p


F = np.array([100.0, 110.0, 120.0, 130.0])
ROWS = "".join(f"{a!r},{z.real!r},{z.imag!r}\n" for a, z in zip(F.tolist(), sdof(F).tolist(), strict=True))
TABS = ROWS.replace(",", "\t")


@pytest.mark.parametrize(
    "header",
    [
        "f, real, imaginary",
        "frequency [Hz], Real, Imaginary",
        "Freq (Hz), Real part, Imag part",
    ],
)
def test_the_headers_people_write_are_read(tmp_path, header):
    p = write(tmp_path, "t.csv", f"# units: m/N\n{header}\n{ROWS}")
    np.testing.assert_allclose(read_frf(p).data[0, 0], sdof(F), rtol=1e-15)


@pytest.mark.parametrize(
    "phase, to", [("phase [deg]", np.degrees), ("phase (rad)", lambda x: x), ("phase_rad", lambda x: x)]
)
def test_magnitude_and_phase_with_the_unit_in_the_header(tmp_path, phase, to):
    z = sdof(F)
    rows = "".join(
        f"{a!r},{abs(b)!r},{float(to(np.angle(b)))!r}\n" for a, b in zip(F.tolist(), z.tolist(), strict=True)
    )
    p = write(tmp_path, "t.csv", f"# units: m/N\nf, magnitude, {phase}\n{rows}")
    np.testing.assert_allclose(read_frf(p).data[0, 0], z, rtol=1e-12)


def test_a_phase_without_its_unit_is_refused_not_guessed(tmp_path):
    p = write(tmp_path, "t.csv", "# units: m/N\nf, mag, phase\n100, 1e-7, 0.5\n110, 1e-7, 0.6\n")
    with pytest.raises(InputError, match=r"line 2.*phase \[deg\]' or 'phase \[rad\]"):
        read_frf(p)


def test_an_unknown_header_names_the_simplest_form(tmp_path, capsys):
    p = write(tmp_path, "t.csv", f"# units: m/N\nf, real, imaginairy\n{ROWS}")
    code, _, err, _ = run(capsys, "lobes", "--frf", p, *LOBES)
    assert_clean_error(code, err, str(p), "line 2", "'imaginairy'", "'f, re, im'")


def test_what_chatterlab_frf_writes_is_read_back(tmp_path, capsys):
    """``chatterlab frf`` writes |H|, phase and re/im of each pair, part first."""
    model = ROOT / "studies" / "traverse_shaper" / "model.toml"
    out = tmp_path / "frf.csv"
    code, _, err, _ = run(capsys, "frf", model, "--input", "rfe5.x", "--output", "rfe5.x", "--fmin", "5",
                          "--fmax", "200", "--points", "50", "--out", out)  # fmt: skip
    assert code == 0, err
    t = read_frf(out)
    assert t.frequency_hz.size == 50 and t.outputs == ("rfe5.x",)


def test_a_units_line_below_the_header_is_refused_not_ignored(tmp_path):
    p = write(tmp_path, "t.csv", f"f,re,im\n# units: mm/N\n{ROWS}")
    with pytest.raises(InputError, match="line 2: '# units' below the header row"):
        read_frf(p, units="m/N")


@pytest.mark.parametrize("encoding", ["utf-16", "utf-16-be-bom"])
def test_utf16_with_its_byte_order_mark_is_read(tmp_path, encoding):
    text = f"# units: µm/N\nf,re,im\n{ROWS}"
    data = b"\xfe\xff" + text.encode("utf-16-be") if encoding == "utf-16-be-bom" else text.encode("utf-16")
    p = write(tmp_path, "t.csv", data)
    np.testing.assert_allclose(read_frf(p).data[0, 0], sdof(F) * 1e-6, rtol=1e-15)


@pytest.mark.parametrize(
    "data, words",
    [
        (f"# units: m/N\nf,re,im\n{ROWS}".encode("utf-16-le"), ["line 1", "NUL", "UTF-16"]),
        (f"# units: µm/N\nf,re,im\n{ROWS}".encode("latin-1"), ["line 1", "0xb5", "UTF-8"]),
        (f"# units: m/N\r\nf,re,im\r\n{ROWS}\r\n100\xe9".encode("latin-1"), ["line 8", "UTF-8"]),
        (f"# units: m/N\nf,re,im\n{ROWS}\x0c\n".encode(), ["line 7", "U+000C"]),
    ],
)
def test_other_encodings_and_control_characters_are_refused_with_the_line(tmp_path, capsys, data, words):
    p = write(tmp_path, "t.csv", data)
    code, _, err, _ = run(capsys, "lobes", "--frf", p, *LOBES)
    assert_clean_error(code, err, str(p), *words)


@pytest.mark.parametrize("eol", ["\r\n", "\r"])
def test_windows_exports_utf16_crlf_and_cr_are_read_and_counted(tmp_path, eol):
    """A Windows export: UTF-16 with its byte-order mark and CRLF (or CR) line ends; the line numbers hold."""
    p = write(tmp_path, "t.csv", f"# units: m/N\nf,re,im\n{ROWS}100,x,1\n".replace("\n", eol), "utf-16")
    with pytest.raises(InputError, match="line 7, column 're': 'x' is not a number"):
        read_frf(p)
    p = write(tmp_path, "t.frf", ("Units: m/N\n" + TABS).replace("\n", eol), "utf-16")
    assert read_frf(p).frequency_hz.size == 4


def test_cutpro_caption_units_are_the_units(tmp_path):
    """'Real(mm/N)' in the captions and no Units line: mm/N, not CutPro's m/N default."""
    p = write(tmp_path, "t.frf", f"Frequency(Hz)\tReal(mm/N)\tImag(mm/N)\n{TABS}")
    t = read_frf(p)
    np.testing.assert_allclose(t.data[0, 0], sdof(F) * 1e-3, rtol=1e-15)
    assert t.meta["units"] == "mm/N"


@pytest.mark.parametrize(
    "head, words",
    [
        ("Units: m/N\nFrequency(Hz)\tReal(mm/N)\tImag(mm/N)\n", ["line 2", "'mm/N'", "Units: m/N"]),
        ("Frequency(kHz)\tReal(m/N)\tImag(m/N)\n", ["line 1", "Hz", "'kHz'"]),
        ("Unitz: mm/N\n", ["line 1", "'Unitz'", "'units'"]),
        ("Units: m/N\n1,5\t1e-7\t1e-8\n", ["line 2", "'1,5'", "decimal comma"]),
        ("\x01\x02garbage\n", ["line 1", "control character"]),
        ("PK\x03\x04\x00\x00junk\n", ["line 1", "NUL"]),
        ("Units: m/N\nUnits: mm/N\n", ["line 2", "twice"]),
    ],
)
def test_cutpro_junk_headers_are_refused(tmp_path, capsys, head, words):
    p = write(tmp_path, "t.frf", head + TABS)
    code, _, err, _ = run(capsys, "lobes", "--frf", p, *LOBES)
    assert_clean_error(code, err, str(p), *words)


def test_a_decimal_comma_is_named(tmp_path):
    p = write(tmp_path, "t.csv", "# units: m/N\nf;re;im\n100;1,5e-7;-2,1e-9\n110;1,6e-7;-2,2e-9\n")
    with pytest.raises(InputError, match="line 3, column 're': '1,5e-7' is not a number; a decimal comma"):
        read_frf(p)


def test_a_cutpro_file_of_comma_rows_is_refused_with_the_line(tmp_path):
    p = write(tmp_path, "t.frf", "Units: m/N\n" + ROWS)
    with pytest.raises(InputError, match="line 2: .* is not a number .*separated by tabs"):
        read_frf(p)


@pytest.mark.parametrize("binary", [False, True])
def test_a_truncated_uff_is_refused_not_read_in_part(tmp_path, capsys, binary):
    p = tmp_path / "t.uff"
    _uff_file(p, 40, binary)
    data = p.read_bytes()
    # the last dataset (a coherence) loses its end: pyuff alone drops it and the FRF reads "whole"
    p.write_bytes(data[: len(data) - len(data) // 16])
    code, _, err, _ = run(capsys, "lobes", "--frf", p, *LOBES)
    assert_clean_error(code, err, str(p), "no closing '    -1' line", "truncated")
    # cut inside the first dataset's values and closed again: fewer values than its header declares
    from chatterlab.io._frf_uff import _uff_tags

    cut = data.rindex(b"\n", 0, _uff_tags(data)[1] - 100) + 1  # at a line end (binary: anywhere)
    p.write_bytes(data[:cut] + b"    -1\n")
    code, _, err, _ = run(capsys, "lobes", "--frf", p, *LOBES)
    assert_clean_error(code, err, str(p), "dataset 1", "declares 40 points")


def test_text_around_uff_datasets_is_refused(tmp_path):
    p = tmp_path / "t.uff"
    _uff_file(p, 10, False)
    p.write_bytes(p.read_bytes() + b"some trailing junk\n")
    with pytest.raises(InputError, match="outside any dataset"):
        read_frf(p)


def test_an_empty_or_foreign_uff_says_what_it_is(tmp_path):
    p = write(tmp_path, "t.uff", b"")
    with pytest.raises(InputError, match="the file is empty"):
        read_frf(p)
    p = write(tmp_path, "t.uff", f"# units: m/N\nf,re,im\n{ROWS}")
    with pytest.raises(InputError, match="not a UFF file"):
        read_frf(p)


# ============================================================================ class 4: bounded work


def _in_subprocess(argv, timeout=BOUND):
    """The CLI in a child process (a blocked read must not block the tests),
    its memory capped (an unbounded read of /dev/zero fails instead of
    eating the machine)."""

    def cap():
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (2 * 2**30, 2 * 2**30))

    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    r = subprocess.run(
        [sys.executable, "-m", "chatterlab.cli", *map(str, argv)],
        capture_output=True, text=True, timeout=timeout, preexec_fn=cap, env=env, cwd=ROOT,
    )  # fmt: skip
    return r.returncode, r.stderr


@pytest.mark.parametrize("kind", ["fifo.csv", "fifo.uff", "dir.uff", "/dev/zero"])
def test_an_frf_path_that_is_not_a_regular_file_is_refused_at_once(tmp_path, kind):
    if kind.startswith("fifo"):
        p = tmp_path / kind
        os.mkfifo(p)
    elif kind.startswith("dir"):
        p = tmp_path / kind
        p.mkdir()
    else:
        p = Path(kind)
        if not p.exists():
            pytest.skip("no /dev/zero")
    model = tmp_path / "m.toml"
    model.write_text(MODEL.format(file=p, coord="response"))
    for argv in (["lobes", "--frf", p, *LOBES], ["lobes", model, *LOBES[2:], "--allow-outside-files"]):
        code, err = _in_subprocess(argv)
        what = "directory" if kind.startswith("dir") else "not a regular file"
        assert_clean_error(code, err, str(p), what)


def test_a_60_mb_frf_file_is_refused_before_it_is_read(tmp_path, capsys, monkeypatch):
    p = tmp_path / "huge.csv"
    with open(p, "wb") as fh:  # sparse: no disk, and nothing is parsed
        fh.truncate(60 * 2**20)
    from chatterlab.io import _frf_table

    monkeypatch.setattr(_frf_table, "decode_text", lambda *a: pytest.fail("parsed"))
    code, _, err, elapsed = run(capsys, "lobes", "--frf", p, *LOBES)
    assert_clean_error(code, err, str(p), "60.0 MiB", "at most 16 MiB")
    assert elapsed < 5


def test_more_frequencies_than_the_cap_are_refused_with_the_line(tmp_path):
    from chatterlab.io._frf_table import MAX_FRF_POINTS

    f = 1.0 + 0.01 * np.arange(MAX_FRF_POINTS + 1)
    p = tmp_path / "dense.csv"
    with open(p, "w") as fh:
        fh.write("# units: m/N\nf,re,im\n")
        np.savetxt(fh, np.column_stack([f, np.full(f.size, 1e-7), np.full(f.size, -1e-8)]), fmt="%.6f,%g,%g")
    with pytest.raises(
        InputError, match=f"line {MAX_FRF_POINTS + 3}: more than {MAX_FRF_POINTS} frequencies"
    ):
        read_frf(p)


# ============================================================================ class 3: an output is never an input


@pytest.fixture
def layout(tmp_path):
    """real/tap.csv, real/m.toml naming it, a folder link, a file link and a hard link."""
    real = tmp_path / "real"
    real.mkdir()
    f = np.arange(100.0, 1500.0, 4.0)
    (real / "tap.csv").write_text(csv_text(f, sdof(f)))
    (real / "m.toml").write_text(MODEL.format(file="tap.csv", coord="response"))
    (tmp_path / "link").symlink_to(real, target_is_directory=True)
    (tmp_path / "tap-link.csv").symlink_to(real / "tap.csv")
    os.link(real / "tap.csv", tmp_path / "hard.csv")
    return tmp_path


SPELLINGS = {
    "relative": "real/tap.csv",
    "absolute": "{root}/real/tap.csv",
    "dot-dot": "real/../real/./tap.csv",
    "folder link": "link/tap.csv",
    "file link": "tap-link.csv",
    "link and dot-dot": "link/../link/tap.csv",
    "hard link": "hard.csv",
}
ROUTES = {
    "lobes --frf": ["lobes", "--frf", "real/tap.csv", *LOBES],
    "[frf] model": ["lobes", "real/m.toml", *LOBES[2:]],
    "model and --frf": ["lobes", "link/m.toml", "--frf", "link/tap.csv", *LOBES[2:]],
}


@pytest.mark.parametrize("route", sorted(ROUTES))
@pytest.mark.parametrize("spelling", sorted(SPELLINGS))
def test_out_naming_the_frf_file_is_refused(capsys, layout, monkeypatch, route, spelling):
    monkeypatch.chdir(layout)
    out = SPELLINGS[spelling].format(root=layout)
    before = digest(layout / "real" / "tap.csv")
    code, _, err, _ = run(capsys, *ROUTES[route], "--out", out)
    assert_clean_error(code, err, repr(out), "is an input of this command", "never overwritten")
    assert digest(layout / "real" / "tap.csv") == before
    assert sorted(p.name for p in (layout / "real").iterdir()) == [
        "m.toml",
        "tap.csv",
    ]  # no temporary file left


def test_the_output_rule_as_a_function(layout, monkeypatch):
    from chatterlab.io._files import check_not_input

    monkeypatch.chdir(layout)
    for out in SPELLINGS.values():
        with pytest.raises(InputError, match="is an input"):
            check_not_input(out.format(root=layout), [layout / "real" / "tap.csv"], "--out")
    check_not_input("real/other.csv", ["real/tap.csv"])  # another file: fine
    check_not_input("link/new.csv", ["link/tap.csv"])  # not there yet: fine


def test_an_frf_read_after_the_outputs_were_checked_is_still_protected(layout, monkeypatch):
    """The Python side of the rule: a reader notes its file with the running
    command's outputs (an [frf] table is only known once the model is read)."""
    from chatterlab.io._files import CSV_SUFFIXES, Outputs

    monkeypatch.chdir(layout)
    outs = Outputs(inputs=["real/m.toml"])
    outs.add("link/tap.csv", "--out", CSV_SUFFIXES)
    with pytest.raises(InputError, match="--out 'link/tap.csv' is an input"):
        read_frf("real/tap.csv")
    outs.discard()
    read_frf("real/tap.csv")  # no command running: the reader is a reader


def test_a_symlinked_frf_without_a_model_is_read_not_refused_for_a_models_folder(capsys, layout, monkeypatch):
    monkeypatch.chdir(layout)
    (layout / "elsewhere").mkdir()
    (layout / "elsewhere" / "tap.csv").symlink_to(layout / "real" / "tap.csv")
    code, out, err, _ = run(
        capsys, "lobes", "--frf", "elsewhere/tap.csv", *LOBES, "--out", "elsewhere/lobes.csv"
    )
    assert code == 0, err
    assert "model's folder" not in err and (layout / "elsewhere" / "lobes.csv").is_file()


# ============================================================================ class 7: check on an [frf] model


def test_check_summarises_a_valid_frf_model(capsys, layout):
    model = layout / "real" / "m.toml"
    code, out, err, _ = run(capsys, "check", model)
    assert code == 0, err
    assert "measured FRF tap.csv (csv, m/N, receptance)" in out and "350, 100 .. 1496 Hz" in out
    assert "cut on response" in out
    code, out, err, _ = run(capsys, "check", model, "--format", "json")
    assert code == 0, err
    d = json.loads(out)
    assert (
        d["structure"] == "measured FRF"
        and d["frequencies"] == 350
        and d["couplings"] == {"cut": ["response"]}
    )


def test_check_refuses_an_frf_model_lobes_would_refuse(capsys, layout):
    model = layout / "real" / "m.toml"
    model.write_text(model.read_text().replace("Kf = 2e9", "Kf = 2e9\nangle_deg = 30.0"))
    code, _, err, _ = run(capsys, "lobes", model, *LOBES[2:])
    assert_clean_error(code, err, "angle_deg = 30")
    code, _, err, _ = run(capsys, "check", model)
    assert_clean_error(code, err, "angle_deg = 30")


def test_reading_stops_on_a_blocked_path_within_the_bound(tmp_path):
    """The FIFO of the hostile corpus in-process: the read returns (refused) instead of blocking."""
    p = tmp_path / "pipe.csv"
    os.mkfifo(p)
    result = []
    th = threading.Thread(target=lambda: result.append(pytest.raises(InputError, read_frf, p)), daemon=True)
    th.start()
    th.join(BOUND)
    if th.is_alive():  # unblock the reader so the test process can end
        with open(p, "w"):
            pass
        pytest.fail("reading a FIFO blocked")
    assert "FIFO" in str(result[0].value)


def test_a_sweep_over_an_frf_model_is_refused_once_before_the_work(capsys, layout):
    model = layout / "real" / "m.toml"
    code, out, err, _ = run(capsys, "sweep", model, "--quantity", "b-lim", "--grid", "speed=3000:4000:2",
                            "--backend", "serial", "--quiet")  # fmt: skip
    assert_clean_error(code, err, str(model), "measured FRF", "chatterlab lobes")
    assert "task" not in err and "sweep of" not in out


@pytest.mark.parametrize("binary", [False, True])
def test_a_uff_cut_right_after_a_dataset_is_those_datasets(tmp_path, binary):
    """UFF has no count of its datasets: a file that ends right after a
    dataset's closing '    -1' is a valid file of the datasets before it
    (found by the fuzz test above on a 58b file cut at byte 1209).  It is
    read as exactly those, never a part of one."""
    from chatterlab.io._frf_uff import _uff_tags

    p = tmp_path / "tap.uff"
    full = _uff_file(p, 12, binary=binary)
    data = p.read_bytes()
    close = _uff_tags(data)[1]  # the first dataset's closing tag
    p.write_bytes(data[: close + 6])
    t = read_frf(p)
    assert t.data.shape == (1, 1, 12) and t.coherence is None
    np.testing.assert_allclose(
        t.data[0, 0], full.data[full.outputs.index(t.outputs[0]), full.inputs.index(t.inputs[0])], rtol=1e-9
    )


def test_a_cross_frf_is_not_taken_for_the_driving_point(capsys, tmp_path):
    """Review: a file holding only tool.x/tool.y (the response at x to a
    force along y) gave lobes with exit 0, as if it were tool.x/tool.x.  The
    cut feeds back at one point: one line, status 2, naming both the file's
    pair and the measurement to give.  An unnamed FRF (re, im columns) is
    still read as the driving point."""
    f = np.arange(100.0, 1500.0, 4.0)
    rows = "".join(
        f"{a!r},{z.real!r},{z.imag!r}\n" for a, z in zip(f.tolist(), sdof(f).tolist(), strict=True)
    )
    p = tmp_path / "cross.csv"
    p.write_text(f"# units: m/N\nf,tool.x/tool.y re,tool.x/tool.y im\n{rows}")
    code, _, err, _ = run(capsys, "lobes", "--frf", p, *LOBES)
    assert_clean_error(code, err, "cross.csv", "this one is tool.x/tool.y, a cross FRF", "tool.x/tool.x")
    q = tmp_path / "plain.csv"
    q.write_text(csv_text(f, sdof(f)))
    assert run(capsys, "lobes", "--frf", q, *LOBES)[0] == 0
