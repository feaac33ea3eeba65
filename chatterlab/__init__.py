"""chatterlab: machining chatter from structural models.

The flow runs one way, and each step has its room::

    model file -> model.Model -> structure.System -> FrozenSystem
        -> frequency (FRF, roots, verdict) / time (Newmark) -> lobes -> sweep
        -> io (netCDF, CSV) / plot / cli

``import chatterlab`` stays light: the names below are imported from their
subpackage on first use, and matplotlib, joblib, xarray and python-control
only inside the functions that need them.  The lobe diagram and the
sweep engine are subpackages: ``from chatterlab.lobes import lobes``,
``from chatterlab.sweep import sweep, Grid``.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from ._version import __version__
from .errors import ChatterlabError, InputError, ModelError, SweepError

if TYPE_CHECKING:  # what type checkers and the API reference see; at run time, below
    from . import lobes, sweep
    from .frequency import Stability, frequencies, frf, loop_determinant, stability
    from .lobes import LobeDiagram
    from .model import Model, load_model, loads_model
    from .process import ClosedLoop, closed_loop, milling_loop
    from .structure import FRF, FrozenSystem, Modes, Structure, System, assemble, modes
    from .sweep import Grid, SweepResult
    from .time import Simulation, simulate

#: public name -> the subpackage that holds it, imported on first use (PEP 562):
#: ``import chatterlab`` loads numpy and nothing heavier, scipy included
_HOME = {
    **dict.fromkeys(("lobes", "sweep"), ""),
    **dict.fromkeys(("Stability", "frequencies", "frf", "loop_determinant", "stability"), "frequency"),
    "LobeDiagram": "lobes",
    **dict.fromkeys(("Model", "load_model", "loads_model"), "model"),
    **dict.fromkeys(("ClosedLoop", "closed_loop", "milling_loop"), "process"),
    **dict.fromkeys(
        ("FRF", "FrozenSystem", "Modes", "Structure", "System", "assemble", "modes"), "structure"
    ),
    **dict.fromkeys(("Grid", "SweepResult"), "sweep"),
    **dict.fromkeys(("Simulation", "simulate"), "time"),
}


#: the subpackages, reachable as attributes (``chatterlab.frequency.frf``) as
#: when the top level imported them all
_SUBPACKAGES = frozenset(
    (
        "model",
        "structure",
        "process",
        "frequency",
        "time",
        "lobes",
        "sweep",
        "quantities",
        "design",
        "uncertainty",
        "selection",
        "io",
        "plot",
        "cli",
    )
)


def __getattr__(name: str) -> Any:
    if name in _SUBPACKAGES:
        return importlib.import_module(f".{name}", __name__)
    home = _HOME.get(name)
    if home is None:
        raise AttributeError(f"module 'chatterlab' has no attribute {name!r}")
    if home == "":  # a subpackage itself
        return importlib.import_module(f".{name}", __name__)
    value = getattr(importlib.import_module(f".{home}", __name__), name)
    globals()[name] = value  # later lookups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__) | _SUBPACKAGES)


__all__ = [
    "__version__",
    # model and assembly
    "Model",
    "load_model",
    "loads_model",
    "System",
    "FrozenSystem",
    "Structure",
    "assemble",
    # analyses and their results
    "Modes",
    "modes",
    "FRF",
    "frf",
    "frequencies",
    "loop_determinant",
    "ClosedLoop",
    "closed_loop",
    "milling_loop",
    "Stability",
    "stability",
    "LobeDiagram",
    "Simulation",
    "simulate",
    # subpackages: the lobe engine and the sweep engine
    "lobes",
    "sweep",
    "Grid",
    "SweepResult",
    # errors
    "ChatterlabError",
    "InputError",
    "ModelError",
    "SweepError",
]
