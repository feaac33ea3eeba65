"""chatterlab: machining chatter from structural models.

The flow runs one way::

    model file -> Model -> System -> FrozenSystem -> modes / FRF / roots / lobes
                                \\-> time response (Newmark)      -> plot or file

``import chatterlab`` stays light: matplotlib, joblib and python-control are
imported only inside the functions that need them.
"""

from __future__ import annotations

__version__ = "0.1.0"

from .assembly import CouplingMatrices, FrozenSystem, System, assemble
from .cutting import Feedback, feedback
from .errors import ChatterlabError, InputError, ModelError, SweepError
from .frf import FRF, frequencies, frf, loop_determinant
from .lobes import LobeDiagram, lobes
from .modal import Modes, modes
from .model import Model
from .modelfile import load_model, loads_model
from .simulate import Simulation, simulate
from .stability import Stability, stability
from .sweep import Grid, SweepResult, sweep

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
    "lobes",
    "Simulation",
    "simulate",
    # sweeps
    "Grid",
    "SweepResult",
    "sweep",
    # errors
    "ChatterlabError",
    "InputError",
    "ModelError",
    "SweepError",
]
