"""chatterlab: machining chatter from structural models.

The flow runs one way, and each step has its room::

    model file -> model.Model -> structure.System -> FrozenSystem
        -> frequency (FRF, roots, verdict) / time (Newmark) -> lobes -> sweep
        -> io (netCDF, CSV) / plot / cli

``import chatterlab`` stays light: matplotlib, joblib and python-control are
imported only inside the functions that need them.  The lobe diagram and the
sweep engine are subpackages: ``from chatterlab.lobes import lobes``,
``from chatterlab.sweep import sweep, Grid``.
"""

from __future__ import annotations

from . import lobes, sweep
from ._version import __version__
from .errors import ChatterlabError, InputError, ModelError, SweepError
from .frequency import FRF, Stability, frequencies, frf, loop_determinant, stability
from .lobes import LobeDiagram
from .model import Model, load_model, loads_model
from .process import Feedback, feedback
from .structure import CouplingMatrices, FrozenSystem, Modes, System, assemble, modes
from .sweep import Grid, SweepResult
from .time import Simulation, simulate

__all__ = [
    "__version__",
    # model and assembly
    "Model",
    "load_model",
    "loads_model",
    "System",
    "FrozenSystem",
    "CouplingMatrices",
    "assemble",
    # analyses and their results
    "Modes",
    "modes",
    "FRF",
    "frf",
    "frequencies",
    "loop_determinant",
    "Feedback",
    "feedback",
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
