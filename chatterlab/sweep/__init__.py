"""The sweep engine: a pure function mapped over a named grid, in parallel,
checkpointed and resumable.  It knows nothing of chatter (the chatter
quantities are :mod:`chatterlab.quantities`).

Run one with :func:`sweep` (``from chatterlab.sweep import sweep, Grid``).
Inside: ``_engine`` (:func:`sweep`), ``_grid`` (:class:`Axis`, :class:`Grid`),
``_result`` (:class:`SweepResult` and its files), ``_backends`` (the worker
side and the serial, loky and dask runners), ``_checkpoint``, ``_store``
(where results go while running) and ``_progress``.
"""

from __future__ import annotations

from ._engine import Axis, Grid, SweepInterrupted, SweepResult, TaskFailure, sweep

__all__ = ["Axis", "Grid", "SweepInterrupted", "SweepResult", "TaskFailure", "sweep"]
