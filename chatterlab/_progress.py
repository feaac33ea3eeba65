"""Progress of long work on stderr, the one implementation (a sweep, a lobe
diagram's speeds, a simulation): a tqdm bar on a terminal, one line at the
end elsewhere (a log file gets no carriage returns), nothing when disabled.
The engines know nothing of it: they call a ``progress(fraction)`` callback,
and the command line passes :func:`fraction_bar`'s."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import Any


class Progress:
    """The progress of ``total`` points of which ``initial`` are already done
    (resumed).  ``note`` prints a line above the bar; ``close`` (idempotent:
    called on success and on an interrupt) ends the bar, or prints the one
    line ``DESC: PCT% (N/TOTAL points, T s)`` when stderr is not a terminal."""

    def __init__(self, total: int, initial: int, enabled: bool, desc: str) -> None:
        self.total, self.n, self.desc = total, initial, desc
        self.enabled = enabled and total > 0
        self._bar: Any = None
        self._t0 = time.monotonic()
        if self.enabled and bool(getattr(sys.stderr, "isatty", lambda: False)()):
            from tqdm import tqdm

            self._bar = tqdm(
                total=total,
                initial=initial,
                unit="pt",
                desc=desc,
                file=sys.stderr,
                dynamic_ncols=True,
                mininterval=0.2,
            )

    def note(self, text: str) -> None:
        if self._bar is not None:
            self._bar.write(f"{self.desc}: {text}", file=sys.stderr)
        elif self.enabled:
            print(f"{self.desc}: {text}", file=sys.stderr, flush=True)

    def update(self, k: int) -> None:
        self.n += k
        if self._bar is not None:
            self._bar.update(k)

    def close(self) -> None:
        if not self.enabled:
            return
        self.enabled = False
        if self._bar is not None:
            self._bar.close()
            return
        pct = 100 * self.n // self.total
        el = time.monotonic() - self._t0
        print(
            f"{self.desc}: {pct:3d}% ({self.n}/{self.total} points, {el:.1f} s)", file=sys.stderr, flush=True
        )


def fraction_bar(desc: str, enabled: bool = True) -> Callable[[float], None]:
    """A ``progress(fraction)`` callback drawing a :class:`Progress` of
    1000 steps (``fraction`` in [0, 1]; the bar closes at 1)."""
    bar = Progress(1000, 0, enabled, desc)

    def show(frac: float) -> None:
        k = int(round(1000 * min(max(float(frac), 0.0), 1.0)))
        if k > bar.n:
            bar.update(k - bar.n)
        if k >= 1000:
            bar.close()

    return show
