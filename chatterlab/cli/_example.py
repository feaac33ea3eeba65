"""``chatterlab example [NAME [DEST]]``: the bundled worked examples.

Alone it lists them (name, file, what it is); with a NAME it copies that
example into the working folder (or DEST) as NAME plus its suffix
(``traverse_shaper.toml``, ``tool_point.csv``), as ``mkdocs new`` or
``cookiecutter`` do; a group name (``milling``, ``tap_test``) copies each of
its files.  An existing file is never overwritten: the command refuses in
one line (status 2) and copies nothing.  Any command also takes
``example:NAME`` in place of a model or FRF file (chatterlab/_examples.py).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from .._examples import EXAMPLES, GROUPS, PREFIX, canonical, example_path
from ..errors import InputError

__all__ = ["add_parser", "run"]


def add_parser(sub: Any) -> None:
    e = sub.add_parser(
        "example",
        help="copy a bundled example (model, FRF) into this folder; alone: list them",
        description="The worked examples that come with chatterlab. Alone: list them. With NAME: copy it into"
        f" the working folder (never over an existing file). Any command takes {PREFIX}NAME in place of a"
        f" model or FRF file, e.g. chatterlab lobes {PREFIX}traverse_shaper --speed 0.1 1 --width-max 1.",
    )
    e.add_argument("name", nargs="?", metavar="NAME", help="an example (or a group: milling, tap_test)")
    e.add_argument(
        "dest",
        nargs="?",
        metavar="DEST",
        help="where to copy: a file name, or a folder (an existing one, one ending in '/', or for a group);"
        " default: the working folder",
    )


def _listing() -> str:
    copies = {name: f"{name}{Path(rel).suffix}" for name, (rel, _) in EXAMPLES.items()}
    w = max(len(c) for c in copies.values())
    lines = [
        f"bundled examples (chatterlab example NAME copies one here as FILE; {PREFIX}NAME works as a file path):"
    ]
    lines += [f"  {copies[name]:<{w}}  {what}" for name, (_, what) in EXAMPLES.items()]
    lines.append("groups: " + "; ".join(f"{g} ({', '.join(m)})" for g, m in GROUPS.items()))
    return "\n".join(lines)


def _targets(names: list[str], dest: str | None, group: bool) -> list[tuple[str, Path, Path]]:
    """(name, source, target) of each example to copy."""
    rows = [(n, example_path(n)) for n in names]
    copies = [Path(f"{n}{src.suffix}") for n, src in rows]
    if dest is not None:
        d = Path(dest)
        if group or d.is_dir() or dest.endswith(("/", "\\")):
            if d.exists() and not d.is_dir():
                raise InputError(f"{dest}: is a file, not a folder to copy into")
            copies = [d / c for c in copies]
        else:
            copies = [d]
    return [(n, src, c) for (n, src), c in zip(rows, copies, strict=True)]


def run(args: argparse.Namespace) -> int:
    if args.name is None:
        print(_listing())
        return 0
    name = args.name.removeprefix(PREFIX)
    group = name in GROUPS
    members = list(GROUPS[name]) if group else [canonical(name)]
    rows = _targets(members, args.dest, group)
    there = [str(t) for _, _, t in rows if t.exists() or t.is_symlink()]
    if there:
        raise InputError(
            f"{', '.join(there)}: exists; chatterlab example never overwrites a file (remove it, or give DEST)"
        )
    for _, _, target in rows:
        if not target.parent.is_dir():
            if target.parent.exists():
                raise InputError(f"{target.parent}: is not a folder")
            target.parent.mkdir(parents=True)
    for n, src, target in rows:
        # exclusive creation: a file that appeared meanwhile is not overwritten either
        try:
            with target.open("xb") as f:
                f.write(src.read_bytes())
        except FileExistsError:
            raise InputError(f"{target}: exists; chatterlab example never overwrites a file") from None
        print(f"wrote {target}: {EXAMPLES[n][1]}", file=sys.stderr)  # as every command says it
    return 0
