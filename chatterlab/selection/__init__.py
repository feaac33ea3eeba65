"""The speeds to choose (issue 22, item 4): from the lobes and the limits of
the machine and its tool, the spindle speeds and widths of cut that remove
the most material while stable with a margin (:func:`recommend`), and the
shop floor's chatter-frequency rule (:func:`chatter_frequency` from a number
or a recording, :func:`chatter_rule` for the speeds it gives, checked
against the lobes where a model exists).

``_limits``: what a width removes and costs (:class:`Removal`), the
machine's curves, plug-in limits (:class:`WidthLimit`, :func:`width_limit`,
where a surface-location-error limit plugs in); ``_recommend``: the search;
``_reasons``: why each cut is chosen; ``_result``: :class:`Recommendation`;
``_recording``: WAV and CSV recordings; ``_spectrum``: the chatter frequency
of a recording; ``_rule``: the chatter-frequency rule and
:class:`SpeedRule`.  The limits of a model file are its ``[machine]`` table
(:class:`Machine`, docs/model-format.md).
"""

from __future__ import annotations

from ..model import Machine
from ._limits import Removal, WidthLimit, width_limit
from ._recommend import recommend
from ._recording import read_recording
from ._result import Recommendation
from ._rule import SpeedRule, chatter_rule
from ._spectrum import ChatterFrequency, chatter_frequency

__all__ = [
    "Machine",
    "Removal",
    "WidthLimit",
    "width_limit",
    "recommend",
    "Recommendation",
    "read_recording",
    "chatter_frequency",
    "ChatterFrequency",
    "chatter_rule",
    "SpeedRule",
]
