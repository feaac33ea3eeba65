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
from .errors import ChatterlabError, InputError, ModelError, SweepError
from .modal import Modes, modes
from .model import Model
from .modelfile import load_model, loads_model

__all__ = [
    "__version__",
    "ChatterlabError",
    "CouplingMatrices",
    "FrozenSystem",
    "InputError",
    "Model",
    "ModelError",
    "Modes",
    "SweepError",
    "System",
    "assemble",
    "load_model",
    "loads_model",
    "modes",
]
