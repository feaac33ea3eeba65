"""The chatterlab exception family.

Every error chatterlab raises on purpose derives from :class:`ChatterlabError`
and from the built-in exception a caller would expect (``ValueError`` for bad
input), so ``except ValueError`` keeps working.  Errors are raised at the
boundary where input enters and say what to do about it.

Numerical outcomes (a diverging simulation, a root search that did not
converge) are *not* exceptions: they are reported as a ``status`` and
``message`` on the result object.
"""

from __future__ import annotations

__all__ = ["ChatterlabError", "ModelError", "InputError", "SweepError"]


class ChatterlabError(Exception):
    """Base class of every exception raised on purpose by chatterlab."""


class ModelError(ChatterlabError, ValueError):
    """A model file or model description is invalid.

    The message names the file, the item (``[[beam]] "bed"``), the field and
    the fix, e.g.::

        model.toml, [[beam]] "bed-1": I must be > 0 (got -0.0004 m^4)
    """

    def __init__(
        self,
        message: str,
        *,
        source: str | None = None,
        item: str | None = None,
        field: str | None = None,
    ) -> None:
        self.source = source
        self.item = item
        self.field = field
        self.detail = message
        prefix = ", ".join(p for p in (source, item) if p)
        super().__init__(f"{prefix}: {message}" if prefix else message)


class InputError(ChatterlabError, ValueError):
    """An argument to an analysis is invalid (a non-positive width, an empty
    frequency range, an unknown point name...).  The message names the
    argument and the accepted values."""


class SweepError(ChatterlabError, RuntimeError):
    """A sweep task failed; the message names the grid point.  Results of the
    tasks that finished are kept in the checkpoint."""
