"""The worked examples that come with chatterlab, reachable from any folder.

One copy of each file: in the repository they are the studies' own files
(``studies/traverse_shaper/model.toml``, ``studies/milling/*.toml``,
``studies/tap_test/*.csv``); a wheel carries the same files as
``chatterlab/examples/`` (the build copies them there: ``setup.py``).  This
module finds them in either place, so that

* ``chatterlab example NAME [DEST]`` copies one into the working folder, and
* ``example:NAME`` stands for one wherever a model or FRF file is asked for
  (``chatterlab lobes example:traverse_shaper --speed 0.1 1 ...``): the
  command line resolves it before any reader opens a file
  (:func:`resolve_args`); :func:`resolve` does it for any other caller.

Layer 1: the standard library and, for its refusals, ``errors`` (imported only
then), so that ``setup.py`` can read the table below without importing the
package.
"""

from __future__ import annotations

import importlib.resources
import os
from pathlib import Path
from typing import Any

__all__ = ["EXAMPLES", "GROUPS", "PREFIX", "canonical", "example_path", "names", "resolve", "resolve_args"]

#: what marks a bundled example in place of a file path
PREFIX = "example:"

#: name -> (file, relative to the examples folder; what it is).  The name is
#: what ``chatterlab example`` and ``example:NAME`` take; the copy is named
#: NAME plus the file's suffix (``traverse_shaper.toml``, ``tool_point.csv``).
EXAMPLES: dict[str, tuple[str, str]] = {
    "traverse_shaper": (
        "traverse_shaper/model.toml",
        "the traverse shaper of Wittbrodt & Kalinski (RDFEM, shaping; the README's main job)",
    ),
    "benchmark_1dof": (
        "milling/benchmark_1dof.toml",
        "1-DOF milling benchmark of Insperger & Stepan (2 teeth, a_e/D = 0.05, down-milling)",
    ),
    "benchmark_2dof": (
        "milling/benchmark_2dof.toml",
        "2-DOF milling benchmark (the tool flexible alike in x and y)",
    ),
    "tool_cantilever": (
        "milling/tool_cantilever.toml",
        "a modelled end mill: carbide Timoshenko cantilever in a holder on a spindle spring",
    ),
    "tool_point": ("tap_test/tool_point.csv", "tap-test FRF at the tool point (x and y, receptance, m/N)"),
    "holder_x": ("tap_test/holder_x.csv", "tap-test FRF of the holder, x"),
    "holder_y": ("tap_test/holder_y.csv", "tap-test FRF of the holder, y"),
    "damped_turning": (
        "process_damping/turning.toml",
        "1-DOF turning tool with process damping (C_pd; docs/process-damping.md)",
    ),
    "damping_cuts": ("process_damping/cuts.csv", "stable/unstable test cuts to fit C_pd from (fit-damping)"),
    "chatter": ("speed_selection/chatter.wav", "a chatter recording (WAV) for the chatter-frequency rule"),
}

#: group -> its examples (``chatterlab example tap_test`` copies all three)
GROUPS: dict[str, tuple[str, ...]] = {
    "milling": ("benchmark_1dof", "benchmark_2dof", "tool_cantilever"),
    "tap_test": ("tool_point", "holder_x", "holder_y"),
    "process_damping": ("damped_turning", "damping_cuts"),
}

#: the folder of the examples in a source tree (an editable install, a checkout)
_SOURCE_TREE = Path(__file__).resolve().parent.parent / "studies"


def names() -> list[str]:
    """The examples' names, in the order ``chatterlab example`` lists them."""
    return list(EXAMPLES)


def canonical(name: str) -> str:
    """``name`` as a key of :data:`EXAMPLES` (its file's suffix may be given:
    ``tool_point.csv``), or an error that lists the names."""
    key = name.strip()
    if key not in EXAMPLES:
        stem, dot, suffix = key.rpartition(".")
        if dot and stem in EXAMPLES and EXAMPLES[stem][0].endswith("." + suffix):
            key = stem
    if key not in EXAMPLES:
        import difflib

        from .errors import InputError

        near = difflib.get_close_matches(key, [*EXAMPLES, *GROUPS], n=1)
        hint = f"did you mean {near[0]}? " if near else ""
        raise InputError(
            f"no example {name!r}: {hint}the examples are {', '.join(EXAMPLES)} (list them: chatterlab example)"
        )
    return key


def example_path(name: str) -> Path:
    """The file of the example ``name`` on disk: the installed package's
    ``chatterlab/examples/...``, else the source tree's ``studies/...``."""
    rel = EXAMPLES[canonical(name)][0]
    packaged = importlib.resources.files("chatterlab").joinpath("examples", *rel.split("/"))
    if packaged.is_file():
        if isinstance(packaged, os.PathLike):
            return Path(os.fspath(packaged))
        return _extracted(rel, packaged.read_bytes())  # a zipped install: a real file for the readers
    source = _SOURCE_TREE.joinpath(*rel.split("/"))
    if source.is_file():
        return source
    from .errors import InputError

    raise InputError(
        f"the example {name!r} is missing from this installation ({rel} is neither in chatterlab/examples/"
        " nor in the source tree's studies/): reinstall chatterlab"
    )


def _extracted(rel: str, data: bytes) -> Path:
    import tempfile

    path = Path(tempfile.gettempdir(), "chatterlab-examples", *rel.split("/"))
    if not path.is_file() or path.read_bytes() != data:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    return path


def resolve(path: Any) -> Any:
    """``example:NAME`` as the path of that example's file; any other value as it is."""
    if isinstance(path, str) and path.startswith(PREFIX):
        return str(example_path(path[len(PREFIX) :]))
    return path


#: the command-line options that name an input file (``args.model``, ``args.frf``)
_FILE_OPTIONS = ("model", "frf")


def resolve_args(args: Any) -> None:
    """Resolve ``example:NAME`` in the file options of a parsed command line, in place."""
    for option in _FILE_OPTIONS:
        value = getattr(args, option, None)
        if isinstance(value, list):
            setattr(args, option, [resolve(v) for v in value])
        elif value is not None:
            setattr(args, option, resolve(value))
