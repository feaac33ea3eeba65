"""``chatterlab example`` and ``example:NAME`` (issue 20, item 1), in process.

The wheel itself is tests/test_wheel.py; here the source tree's copy of the
examples (studies/) is the one found.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from chatterlab._examples import EXAMPLES, GROUPS, example_path, resolve
from chatterlab.cli._main import main

ROOT = Path(__file__).resolve().parents[1]


def test_every_example_is_found_in_the_source_tree():
    for name, (rel, _) in EXAMPLES.items():
        assert example_path(name) == ROOT / "studies" / rel
    assert resolve("example:tool_point.csv") == str(ROOT / "studies" / "tap_test" / "tool_point.csv")
    assert resolve("studies/x.toml") == "studies/x.toml"


def test_listing(capsys):
    assert main(["example"]) == 0
    out = capsys.readouterr().out
    assert all(f"{n}{Path(rel).suffix}" in out for n, (rel, _) in EXAMPLES.items())
    assert all(g in out for g in GROUPS)


def test_copy_and_never_overwrite(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["example", "traverse_shaper"]) == 0
    copy = tmp_path / "traverse_shaper.toml"
    assert copy.read_bytes() == (ROOT / "studies/traverse_shaper/model.toml").read_bytes()
    assert "wrote traverse_shaper.toml" in capsys.readouterr().err
    copy.write_text("# my own edits\n")
    assert main(["example", "traverse_shaper"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "never overwrites" in err
    assert copy.read_text() == "# my own edits\n"
    # a group is refused whole when one of its files is there: nothing copied
    (tmp_path / "g").mkdir()
    (tmp_path / "g" / "holder_x.csv").write_text("mine")
    assert main(["example", "tap_test", "g"]) == 2
    assert sorted(p.name for p in (tmp_path / "g").iterdir()) == ["holder_x.csv"]
    capsys.readouterr()


def test_dest_file_folder_and_group(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["example", "tool_point.csv", "mine.csv"]) == 0
    assert (tmp_path / "mine.csv").stat().st_size > 0
    assert main(["example", "benchmark_1dof", "models/"]) == 0
    assert (tmp_path / "models" / "benchmark_1dof.toml").is_file()
    assert main(["example", "milling", "m"]) == 0
    assert sorted(p.name for p in (tmp_path / "m").iterdir()) == [
        "benchmark_1dof.toml",
        "benchmark_2dof.toml",
        "tool_cantilever.toml",
    ]


def test_unknown_example_is_one_line(capsys):
    assert main(["example", "traverse_shapper"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "did you mean traverse_shaper?" in err
    assert main(["check", "example:nope"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("chatterlab: error: no example 'nope'") and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("name", ["traverse_shaper", "benchmark_1dof", "benchmark_2dof", "tool_cantilever"])
def test_example_path_in_place_of_a_model(name, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no studies/ here: the example is found all the same
    assert main(["check", f"example:{name}"]) == 0
    assert ": OK" in capsys.readouterr().out
