"""``chatterlab --help`` in a blink (issue 20, item 8).

The command line is parsed before anything heavy is imported, and only the
chosen command's module is imported: ``--help`` and ``-h``, of the top level
and of every command, load no numpy (let alone scipy, matplotlib, xarray).
Each case runs in a fresh interpreter, which names at exit every module the
run loaded (``sys.modules``).  The timing itself is benchmarks/bench_help.py.
"""

from __future__ import annotations

import argparse
import subprocess
import sys

import pytest

from chatterlab.cli._main import _COMMAND_TABLE, build_parser, main

HEAVY = ("numpy", "scipy", "matplotlib", "xarray", "joblib", "control", "h5py", "tqdm", "pint")

CASES = [[flag] for flag in ("--help", "-h")] + [
    [cmd, flag] for cmd in _COMMAND_TABLE for flag in ("--help", "-h")
]


#: the real entry point (``python -m chatterlab.cli``), and at exit the names of every loaded module
_PROBE = (
    "import atexit, runpy, sys\n"
    "atexit.register(lambda: sys.stderr.write('\\nMODULES ' + ' '.join(sorted(sys.modules)) + '\\n'))\n"
    "sys.argv = ['chatterlab', *sys.argv[1:]]\n"
    "runpy.run_module('chatterlab.cli', run_name='__main__', alter_sys=True)\n"
)


def _imported(args: list[str]) -> tuple[set[str], subprocess.CompletedProcess]:
    r = subprocess.run([sys.executable, "-c", _PROBE, *args], capture_output=True, text=True, timeout=120)
    line = next(ln for ln in r.stderr.splitlines() if ln.startswith("MODULES "))
    return set(line.split()[1:]), r


@pytest.mark.parametrize("args", CASES, ids=[" ".join(a) for a in CASES])
def test_help_imports_nothing_heavy(args):
    mods, r = _imported(args)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "usage: chatterlab" in r.stdout
    assert "chatterlab.cli._main" in mods  # the record is complete
    heavy = sorted(m for m in mods if m.split(".")[0] in HEAVY)
    assert not heavy, f"chatterlab {' '.join(args)} imported {heavy[:8]}"
    # only the chosen command's module
    others = {f"chatterlab.cli._{c}" for c in _COMMAND_TABLE if c not in args}
    assert not (mods & others), sorted(mods & others)


def test_the_listed_help_lines_are_the_commands_own():
    """``chatterlab --help`` lists each command with the help line its module gives."""
    for name, (_, line) in _COMMAND_TABLE.items():
        p = build_parser(name)
        (sub,) = (a for a in p._actions if isinstance(a, argparse._SubParsersAction))
        own = {a.dest: a.help for a in sub._choices_actions}
        assert own[name] == line, name
    full = build_parser()
    (sub,) = (a for a in full._actions if isinstance(a, argparse._SubParsersAction))
    assert list(sub.choices) == list(_COMMAND_TABLE)


def test_a_misspelt_command_still_lists_them(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["lobe", "model.toml"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "invalid choice: 'lobe'" in err and "lobes" in err and len(err.strip().splitlines()) == 1


def test_a_command_runs_after_the_lazy_parse(capsys):
    """A chosen command's options are all there (its module's parser, not a stub)."""
    with pytest.raises(SystemExit) as exc:
        main(["check", "model.toml", "--formt", "json"])
    assert exc.value.code == 2
    assert "--formt: did you mean --format?" in capsys.readouterr().err
