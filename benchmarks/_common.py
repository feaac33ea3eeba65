"""What every benchmark records beside its timings, written once.

The load of the machine (``/proc/loadavg``; a run whose 1-minute load
exceeds 1 on this 2-core machine is marked LOADED), the commit of the
chatterlab that was timed (``+dirty`` when its tracked files differ), the
peak resident memory, and the min/median summary of repeated runs.  A
benchmark script imports these by ``from _common import ...`` (the script's
own folder is on ``sys.path`` when it runs as ``python benchmarks/x.py``).
"""

from __future__ import annotations

import os
import resource
import statistics
import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

#: the repository
ROOT = Path(__file__).resolve().parents[1]
#: a 1-minute load above this on 2 cores: the timings are marked LOADED
LOADED = 1.0


def loadavg() -> tuple[float, float, float]:
    """The 1-, 5- and 15-minute load averages (nan where the OS has none)."""
    try:
        return tuple(float(x) for x in Path("/proc/loadavg").read_text().split()[:3])  # type: ignore[return-value]
    except OSError:
        return os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3


def load1() -> float:
    """The 1-minute load average."""
    return loadavg()[0]


def loadavg_text() -> str:
    """``/proc/loadavg`` as the kernel writes it (with the run queue), else the three averages."""
    try:
        return Path("/proc/loadavg").read_text().strip()
    except OSError:
        return " ".join(f"{x:.2f}" for x in loadavg())


def source_commit(package: Any = None) -> str:
    """The short commit of the chatterlab checkout that is imported (PYTHONPATH
    may point at another checkout than this one), ``+dirty`` when its tracked
    files under ``chatterlab/`` differ; ``"unknown"`` outside git."""
    if package is None:
        import chatterlab as package
    src = Path(package.__file__).resolve().parents[1]
    try:
        head = subprocess.run(
            ["git", "-C", str(src), "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(src), "status", "--porcelain", "--untracked-files=no", "chatterlab"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("+dirty" if dirty else "")


def peak_rss_mb() -> float:
    """This process's peak resident set, MB (Linux reports ``ru_maxrss`` in kB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def timed(fn: Callable[[], Any]) -> tuple[Any, float, float]:
    """``(fn(), wall seconds, CPU seconds of this process)``."""
    c, t = time.process_time(), time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t, time.process_time() - c


def stats(wall: list[float], cpu: list[float] | None = None, *, wall_key: str = "times_s") -> dict[str, Any]:
    """Min and median of repeated wall times (and CPU times when given), with every sample."""
    out: dict[str, Any] = {
        "min_s": min(wall),
        "median_s": float(statistics.median(wall)),
        wall_key: list(wall),
    }
    if cpu is not None:
        out.update(cpu_min_s=min(cpu), cpu_median_s=float(statistics.median(cpu)), cpu_s=list(cpu))
    return out
