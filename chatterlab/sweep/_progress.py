"""Progress of a sweep on stderr."""

from __future__ import annotations

import sys
import time
from typing import Any

# =========================================================================== progress


class _Progress:
    """tqdm on a terminal (a plain bar without tqdm), a line per ~10 % otherwise."""

    def __init__(self, total: int, initial: int, enabled: bool, desc: str) -> None:
        self.total, self.n, self.desc = total, initial, desc
        self.mode = "off"
        self._bar: Any = None
        self._t0 = time.monotonic()
        self._last = 0.0
        self._next_decile = 1 + (10 * initial) // max(total, 1)
        if not enabled or total <= 0:
            return
        stream = sys.stderr
        tty = bool(getattr(stream, "isatty", lambda: False)())
        if tty:
            try:
                from tqdm import tqdm

                self._bar = tqdm(
                    total=total,
                    initial=initial,
                    unit="pt",
                    desc=desc,
                    file=stream,
                    dynamic_ncols=True,
                    mininterval=0.2,
                )
                self.mode = "tqdm"
            except ImportError:
                self.mode = "bar"
        else:
            self.mode = "lines"

    def note(self, text: str) -> None:
        if self.mode == "lines":
            print(f"{self.desc}: {text}", file=sys.stderr, flush=True)
        elif self.mode == "tqdm":
            self._bar.write(f"{self.desc}: {text}", file=sys.stderr)
        elif self.mode == "bar":
            print(f"\r{self.desc}: {text}", file=sys.stderr, flush=True)

    def update(self, k: int) -> None:
        self.n += k
        if self.mode == "tqdm":
            self._bar.update(k)
        elif self.mode == "bar":
            now = time.monotonic()
            if now - self._last >= 0.2 or self.n >= self.total:
                self._last = now
                frac = self.n / self.total
                bar = "#" * int(30 * frac) + "-" * (30 - int(30 * frac))
                print(
                    f"\r{self.desc}: [{bar}] {100 * frac:5.1f}% {self.n}/{self.total} {now - self._t0:.1f} s",
                    end="",
                    file=sys.stderr,
                    flush=True,
                )
        elif self.mode == "lines":
            decile = (10 * self.n) // self.total
            if decile >= self._next_decile:
                self._next_decile = decile + 1
                el = time.monotonic() - self._t0
                print(
                    f"{self.desc}: {10 * decile:3d}% ({self.n}/{self.total} points, {el:.1f} s)",
                    file=sys.stderr,
                    flush=True,
                )

    def close(self) -> None:
        if self.mode == "tqdm":
            self._bar.close()
        elif self.mode == "bar":
            print(file=sys.stderr, flush=True)
        self.mode = "off"
