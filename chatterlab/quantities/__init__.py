"""Chatter quantities for the sweep engine: b_lim, roots, spectral abscissa,
and the stability atlas along the slide's stroke."""

from __future__ import annotations

from ._tasks import QUANTITIES, AtlasTask, QuantityTask, axis_name, model_fingerprint

__all__ = ["AtlasTask", "QuantityTask", "QUANTITIES", "model_fingerprint", "axis_name"]
