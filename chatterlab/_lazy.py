"""Names that load their module on first use (PEP 562), for the subpackages.

A subpackage lists where each public name lives (``_HOME``: name -> private
module) and binds ``__getattr__, __dir__ = lazy_names(__name__, _HOME)``:
``chatterlab.frequency.frf`` then imports ``frequency/_frf.py`` on the first
lookup only, so a command that needs one module of a subpackage does not
load the others (the README main job loads 73 of chatterlab's modules, not
115).  The name is then bound in the package, and later lookups do not come
here.  Type checkers and the API reference see the names through each
``__init__``'s ``if TYPE_CHECKING:`` imports.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from typing import Any


def lazy_names(package: str, home: Mapping[str, str]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` of the package ``package`` whose names live in
    the modules ``home[name]`` (relative to it)."""

    def __getattr__(name: str) -> Any:
        where = home.get(name)
        if where is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f".{where}", package), name)
        setattr(sys.modules[package], name, value)  # later lookups skip this function
        return value

    def __dir__() -> list[str]:
        mod = sys.modules[package]
        return sorted(set(vars(mod)) | set(getattr(mod, "__all__", ())))

    return __getattr__, __dir__
