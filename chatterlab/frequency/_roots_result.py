"""The outcome of a characteristic-root search: :class:`RootsResult`.

A numerical failure is a status in the result (``status="not_converged"``
with a ``message``), never an exception; :class:`TooLarge` carries a search
that would exceed its memory or time limit up to the entry point, which turns
it into such a status.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..io import Result

__all__ = ["RootsResult", "make_result", "TooLarge"]

ComplexArray = NDArray[np.complex128]
FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class RootsResult(Result):
    """Rightmost characteristic roots of a delay system.

    Attributes
    ----------
    roots : ndarray of complex, shape (k,)
        Roots in rad/s, upper half plane and real axis only (conjugates
        omitted), sorted by decreasing real part; ``k <= count``.
    frequency_hz : ndarray of float, shape (k,)
        ``roots.imag / (2 pi)`` in Hz.
    damping_ratio : ndarray of float, shape (k,)
        ``-Re(lambda) / |lambda|`` (dimensionless; NaN for a root at 0).
    abscissa : float
        Largest real part (1/s): the spectral abscissa; negative means
        asymptotically stable.  NaN when no root was found.
    method : str
        ``"spectral"``, ``"spectral-windowed"``, ``"branch"`` or ``"eig"``.
    n_nodes : tuple of int
        ``(N, N2)``: Chebyshev nodes of the two discretisations (largest over
        the frequency windows); ``(0, 0)`` for methods without them.
    rejected : int
        Candidates dropped by the convergence check (Newton failed, or the
        root was not reproduced by the second discretisation / start).
    status : str
        ``"converged"`` or ``"not_converged"``.
    message : str
        Human-readable diagnostic.
    n_windows : int
        Number of frequency windows (spectral route); 0 otherwise.
    elapsed : float
        Wall-clock time in s.
    band_top : float
        Upper end (rad/s) of the frequency band searched (NaN when the
        caller fixed the band or the nodes).
    complete_above : float
        Every root with real part >= this (1/s) lies in the band searched:
        the gain bound of the loop transfer excludes the frequencies above it
        (NaN when not certified).  A verdict "stable" needs it < 0.
    """

    roots: ComplexArray
    frequency_hz: FloatArray
    damping_ratio: FloatArray
    abscissa: float
    method: str
    n_nodes: tuple[int, int]
    rejected: int
    status: str
    message: str
    n_windows: int = 0
    elapsed: float = 0.0
    band_top: float = math.nan
    complete_above: float = math.nan

    @property
    def converged(self) -> bool:
        """``True`` when ``status == "converged"``."""
        return self.status == "converged"

    @property
    def stable(self) -> bool:
        """``True`` when the rightmost root found has a negative real part."""
        return bool(self.abscissa < 0.0)

    def table(self) -> str:
        """Readable table of the roots (frequency in Hz, real part in 1/s)."""
        lines = [
            f"characteristic roots ({self.method}, N={self.n_nodes[0]}/{self.n_nodes[1]}, "
            f"status={self.status}, rejected={self.rejected})",
            f"{'#':>3} {'Re (1/s)':>14} {'Im (rad/s)':>14} {'f (Hz)':>12} {'zeta':>10}",
        ]
        for i, (lam, f, z) in enumerate(zip(self.roots, self.frequency_hz, self.damping_ratio, strict=True)):
            lines.append(f"{i:>3} {lam.real:>14.6g} {lam.imag:>14.6g} {f:>12.6g} {z:>10.4g}")
        lines.append(f"abscissa = {self.abscissa:.6g} 1/s; {self.message}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.table()

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """The roots (index ``root``, 0 the rightmost) with their real part,
        angular frequency, frequency and damping ratio; the search as attributes."""
        lam = np.asarray(self.roots, dtype=complex)
        return (
            {"root": (np.arange(lam.size), "1", "root, rightmost first")},
            {
                "real_part": (lam.real, "1/s", "Re lambda (growth rate)"),
                "imag_part": (lam.imag, "rad/s", "Im lambda"),
                "frequency": (np.asarray(self.frequency_hz, float), "Hz", "Im lambda / 2 pi"),
                "damping_ratio": (np.asarray(self.damping_ratio, float), "1", "-Re lambda / |lambda|"),
            },
            {
                "title": "chatterlab characteristic roots",
                "abscissa_per_s": float(self.abscissa),
                "method": self.method,
                "status": self.status,
                "message": self.message,
                "band_top_rad_s": float(self.band_top),
                "complete_above_per_s": float(self.complete_above),
            },
        )

    def plot(self, ax: Any = None, *, title: str | None = None, **style: Any) -> Any:
        """The roots in the complex plane (:func:`chatterlab.plot.plot_roots`); returns the Axes."""
        from ..plot import plot_roots

        return plot_roots(self, ax=ax, title=title, **style)


def make_result(
    roots: ArrayLike,
    *,
    method: str,
    n_nodes: tuple[int, int],
    rejected: int,
    status: str,
    message: str,
    n_windows: int = 0,
    t0: float | None = None,
) -> RootsResult:
    lam = np.asarray(roots, dtype=complex).ravel()
    order = np.lexsort((lam.imag, -lam.real))
    lam = lam[order]
    mod = np.abs(lam)
    zeta = np.full(lam.shape, np.nan)
    nz = mod > 0
    zeta[nz] = -lam.real[nz] / mod[nz]
    lam.setflags(write=False)
    fhz = lam.imag / (2.0 * np.pi)
    fhz.setflags(write=False)
    zeta.setflags(write=False)
    return RootsResult(
        roots=lam,
        frequency_hz=fhz,
        damping_ratio=zeta,
        abscissa=float(lam[0].real) if lam.size else float("nan"),
        method=method,
        n_nodes=(int(n_nodes[0]), int(n_nodes[1])),
        rejected=int(rejected),
        status=status,
        message=message,
        n_windows=int(n_windows),
        elapsed=0.0 if t0 is None else time.perf_counter() - t0,
    )


class TooLarge(Exception):
    """A search that cannot complete within its memory limit (reported as a status)."""
