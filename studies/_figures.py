"""Where a study writes its figures: nowhere unless asked.

``python studies/<study>.py`` prints the study's numbers; with
``--figures DIR`` it also draws its figures into DIR
(``--figures docs/figures`` refreshes the documentation's, which are
committed: nothing rewrites them unless asked to).
"""

from __future__ import annotations

import argparse
from pathlib import Path


def figures_dir(description: str) -> Path | None:
    """The ``--figures DIR`` of the command line (created), or None."""
    p = argparse.ArgumentParser(description=description)
    p.add_argument(
        "--figures",
        metavar="DIR",
        type=Path,
        help="also draw the figures into DIR (docs/figures refreshes the documentation's)",
    )
    args = p.parse_args()
    if args.figures is None:
        print("(figures not drawn: pass --figures DIR; --figures docs/figures refreshes the documentation's)")
        return None
    args.figures.mkdir(parents=True, exist_ok=True)
    return args.figures
