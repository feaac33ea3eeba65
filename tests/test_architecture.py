"""The layers of the package, enforced on its import graph (docs/architecture.md).

Every ``import`` and ``from ... import`` in chatterlab/ is read with ``ast``,
including imports inside functions (a lazy import is still a dependency).
The contract:

* a subpackage imports only from lower layers (or itself);
* the graph of modules has no cycle;
* ``sweep`` knows nothing of chatter, ``io`` and ``plot`` know nothing of the
  analyses (they work on what they are handed);
* a name imported from another subpackage is public (no leading underscore);
* ``import chatterlab`` does not import matplotlib, joblib or python-control.

The test fails on the first upward import, cycle or private name the day it
is written, and names it.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "chatterlab"

#: layer of each top-level unit (higher may import lower; equal ranks must not
#: import each other unless they are the same unit)
LAYERS = {
    "_version": 0,
    "_threads": 0,
    "_lazy": 0,  # the subpackages' names loaded on first use (imports nothing of chatterlab)
    "_progress": 0,  # the one progress bar (sweeps, diagrams, simulations)
    "_minimize": 0,  # Brent's bounded minimum (imports nothing of chatterlab)
    "_examples": 1,  # the bundled examples (imports errors only)
    "errors": 0,
    "io": 1,
    "plot": 1,
    "sweep": 2,
    "model": 2,
    "structure": 3,
    "process": 4,
    "frequency": 5,
    "time": 5,
    "lobes": 6,
    "quantities": 7,
    "design": 7,  # sensitivities of the limit, absorbers (issue 23): above lobes
    "uncertainty": 7.5,  # probabilistic lobes (issue 24): on lobes, sweep and quantities, below cli
    "selection": 7,  # the speeds to choose (issue 22 item 4): on lobes, frequency and time, below cli
    "cli": 8,
    "__init__": 9,
}


def _modules() -> dict[str, Path]:
    out = {}
    for p in PKG.rglob("*.py"):
        rel = p.relative_to(PKG).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(["chatterlab", *parts])] = p
    return out


def _unit(mod: str) -> str:
    parts = mod.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def _imports(mod: str, path: Path) -> list[tuple[str, list[str], int]]:
    """(imported module, names, line) for every import in the file."""
    tree = ast.parse(path.read_text())
    is_pkg = path.name == "__init__.py"
    base = mod.split(".") if is_pkg else mod.split(".")[:-1]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                anchor = base[: len(base) - (node.level - 1)]
                target = ".".join(anchor + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            names = [a.name for a in node.names]
            if target.startswith("chatterlab"):
                # "from . import x" / "from .pkg import mod": a submodule import
                out.append((target, names, node.lineno))
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("chatterlab"):
                    out.append((a.name, [], node.lineno))
    return out


def _resolve(target: str, names: list[str], mods: dict[str, Path]) -> list[str]:
    """The modules an import statement loads."""
    got = []
    for n in names:
        if f"{target}.{n}" in mods:
            got.append(f"{target}.{n}")
    if target in mods:
        got.append(target)
    return got


def _graph() -> tuple[dict[str, set[str]], list[str]]:
    mods = _modules()
    graph: dict[str, set[str]] = {m: set() for m in mods}
    problems = []
    for mod, path in mods.items():
        for target, names, line in _imports(mod, path):
            for dep in _resolve(target, names, mods):
                if dep == mod:
                    continue
                graph[mod].add(dep)
                a, b = _unit(mod), _unit(dep)
                if a == b:
                    continue
                if LAYERS[b] >= LAYERS[a]:
                    problems.append(
                        f"{path.relative_to(PKG.parent)}:{line}: {a} (layer {LAYERS[a]}) imports {dep} "
                        f"(layer {LAYERS[b]})"
                    )
                private = [
                    n
                    for n in names
                    if n.startswith("_") and not n.startswith("__") and f"{target}.{n}" not in mods
                ]
                if private:
                    problems.append(
                        f"{path.relative_to(PKG.parent)}:{line}: private name(s) {private} from {dep}"
                    )
    return graph, problems


def test_every_unit_has_a_layer():
    units = {_unit(m) for m in _modules()}
    assert units <= set(LAYERS), units - set(LAYERS)


def test_imports_go_down_the_layers_and_use_public_names():
    _, problems = _graph()
    assert not problems, "\n".join(problems)


def test_no_import_cycle():
    graph, _ = _graph()
    # iterative DFS for a back edge
    state: dict[str, int] = {}
    for start in graph:
        if state.get(start):
            continue
        stack = [(start, iter(sorted(graph[start])))]
        path = [start]
        state[start] = 1
        while stack:
            node, it = stack[-1]
            nxt = next(it, None)
            if nxt is None:
                state[node] = 2
                stack.pop()
                path.pop()
                continue
            if state.get(nxt) == 1:
                cyc = path[path.index(nxt) :] + [nxt]
                pytest.fail("import cycle: " + " -> ".join(cyc))
            if not state.get(nxt):
                state[nxt] = 1
                stack.append((nxt, iter(sorted(graph[nxt]))))
                path.append(nxt)


@pytest.mark.parametrize(("unit", "allowed"), [("sweep", ("io", "plot")), ("io", ()), ("plot", ())])
def test_engines_know_nothing_of_chatter(unit, allowed):
    """The sweep engine may write files (io) and draw its result (plot); io and plot use nothing else
    (besides the layer-0 utilities: errors, _version, _threads, _progress, _lazy)."""
    graph, _ = _graph()
    for mod, deps in graph.items():
        if _unit(mod) != unit:
            continue
        foreign = {
            d
            for d in deps
            if _unit(d) not in (unit, "errors", "_version", "_threads", "_progress", "_lazy", *allowed)
        }
        assert not foreign, f"{mod} imports {sorted(foreign)}"


def test_the_contract_catches_an_upward_import(tmp_path, monkeypatch):
    """The checker itself: an upward import planted in a copy is reported."""
    import shutil

    copy = tmp_path / "chatterlab"
    shutil.copytree(PKG, copy)
    bad = copy / "structure" / "_complex.py"
    bad.write_text(bad.read_text() + "\n\ndef _f():\n    from ..lobes import lobes\n")
    monkeypatch.setattr(sys.modules[__name__], "PKG", copy)
    _, problems = _graph()
    assert any("structure (layer 3) imports chatterlab.lobes" in p for p in problems)


def test_import_chatterlab_is_light():
    """``import chatterlab`` loads no scipy (let alone matplotlib, xarray...):
    the public names come from their subpackages on first use."""
    code = (
        "import sys, chatterlab\n"
        "heavy = [m for m in ('scipy', 'matplotlib', 'joblib', 'control', 'xarray', 'dask', 'h5py', 'pint')"
        " if m in sys.modules]\n"
        "print(','.join(heavy))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.strip()
    assert out == ""


def test_every_public_name_resolves_to_its_subpackage_object():
    """The lazy top level gives, for each name of ``chatterlab.__all__``, the
    very object its subpackage exports (and subpackages as modules); an
    unknown name is an AttributeError, as for any module."""
    import importlib

    import chatterlab

    for name in chatterlab.__all__:
        obj = getattr(chatterlab, name)
        home = chatterlab._HOME.get(name)
        if home is None:
            continue  # defined in chatterlab/__init__.py itself (version, errors)
        if home == "":
            assert obj is importlib.import_module(f"chatterlab.{name}")
        else:
            assert obj is getattr(importlib.import_module(f"chatterlab.{home}"), name), name
    assert set(chatterlab.__all__) <= set(dir(chatterlab))
    # every subpackage is an attribute, as when the top level imported them all
    # (fresh interpreter: nothing imported by this session may bind them first)
    code = (
        "import chatterlab as cl\n"
        "print(cl.frequency.frf.__name__, cl.time.simulate.__name__, cl.model.load_model.__name__,"
        " cl.structure.assemble.__name__, cl.process.closed_loop.__name__, cl.io.read_netcdf.__name__,"
        " cl.quantities.__name__, cl.plot.__name__)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["frf", "simulate", "load_model", "assemble", "closed_loop", "read_netcdf",
                           "chatterlab.quantities", "chatterlab.plot"]  # fmt: skip
    assert chatterlab._SUBPACKAGES <= set(dir(chatterlab))
    assert set(chatterlab._HOME) <= set(chatterlab.__all__)
    with pytest.raises(AttributeError, match="no attribute 'lobe_diagram'"):
        chatterlab.lobe_diagram  # noqa: B018
