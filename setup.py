"""The build's one addition to pyproject.toml: the worked examples go into the
wheel as ``chatterlab/examples/``.

The repository keeps one copy of each example file, where the studies use
it (``studies/traverse_shaper/model.toml``, ``studies/milling/*.toml``,
``studies/tap_test/*.csv``); the table of them is ``EXAMPLES`` in
``chatterlab/_examples.py``, read here without importing the package.  An
editable install needs no copy: ``chatterlab._examples`` finds the files in
the source tree.  The sdist carries them through MANIFEST.in.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent


def _example_files() -> list[str]:
    spec = importlib.util.spec_from_file_location(
        "_chatterlab_examples", HERE / "chatterlab" / "_examples.py"
    )
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return [rel for rel, _ in mod.EXAMPLES.values()]


class BuildWithExamples(build_py):
    """build_py, then studies/<file> -> <build>/chatterlab/examples/<file>."""

    def run(self) -> None:
        super().run()
        if getattr(self, "editable_mode", False):
            return
        for rel in _example_files():
            src = HERE / "studies" / rel
            if not src.is_file():
                raise SystemExit(f"setup.py: the example {src} is missing")
            dst = Path(self.build_lib) / "chatterlab" / "examples" / rel
            self.mkpath(str(dst.parent))
            self.copy_file(str(src), str(dst))


setup(cmdclass={"build_py": BuildWithExamples})
