"""The ``chatterlab`` command (``chatterlab --help``).

``_main`` parses the command line, then imports the chosen command's module
and dispatches (``--help`` loads no numpy); each command is one module
(``_check``, ``_modes``, ``_frf``, ``_roots``, ``_lobes``, ``_simulate``,
``_sweep``, ``_example``) with ``add_parser(sub)`` and ``run(args) -> int``; ``_common``
holds the shared options, the mm/Hz/speed-unit conversions of this edge,
warnings and output files; ``_parallel`` the sweep engine's options
(workers, checkpoint, resume); ``_claims`` what an ``inf`` b_lim means in a
sweep's summary.
"""

from __future__ import annotations

from ._main import build_parser, main

__all__ = ["main", "build_parser"]
