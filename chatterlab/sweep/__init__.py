"""The sweep engine: a pure function mapped over a named grid, in parallel,
checkpointed and resumable.  It knows nothing of chatter (the chatter
quantities are :mod:`chatterlab.quantities`).

Run one with :func:`sweep` (``from chatterlab.sweep import sweep, Grid``).
"""

from __future__ import annotations

from ._engine import Axis, Grid, SweepInterrupted, SweepResult, TaskFailure, sweep

__all__ = ["Axis", "Grid", "SweepInterrupted", "SweepResult", "TaskFailure", "sweep"]
