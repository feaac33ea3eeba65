"""The ``chatterlab`` command (``chatterlab --help``)."""

from __future__ import annotations

from ._main import build_parser, main

__all__ = ["main", "build_parser"]
