"""The 0.2 names of the closed loop (``Feedback``, ``feedback``) and
:func:`ce_maps`, kept for the callers not yet moved: everything lives in
:mod:`chatterlab.process._loop`."""

from __future__ import annotations

from ._loop import TERMS, ce_maps, delay_for
from ._loop import ClosedLoop as Feedback
from ._loop import closed_loop as feedback
from ._loop import closed_loop_unwarned as feedback_unwarned

__all__ = ["Feedback", "feedback", "feedback_unwarned", "delay_for", "ce_maps", "TERMS"]
