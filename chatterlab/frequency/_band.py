"""The frequency band that holds every characteristic root right of a line.

A root of :math:`\\det(P(\\lambda) - e^{-\\lambda\\tau} U V^T)` needs
:math:`\\|e^{-\\lambda\\tau} V^T P(\\lambda)^{-1} U\\| \\ge 1`; the gain
bound of :func:`chatterlab.frequency._bounds.certified_band` on the loop
transfer in pole-residue form excludes every frequency above
:func:`certified_top` for roots with :math:`\\Re\\lambda \\ge \\sigma`.
"""

from __future__ import annotations

import numpy as np

from ._bounds import PoleResidue, certified_band
from ._delay_system import DelaySystem

__all__ = ["certified_top", "band_top", "SIGMA_TAU"]


#: roots outside the certified band have Re < -SIGMA_TAU / tau
SIGMA_TAU = 2.0


def band_top(sys: DelaySystem, count: int, omega_max: float | None, sigma: float | None = None) -> float:
    """Upper end (rad/s) of the band in which root locations are predicted.

    A root lambda of det(P(lambda) - e^{-lambda tau} U V^T) needs
    ||e^{-lambda tau} V^T P(lambda)^{-1} U|| >= 1.  With the loop transfer in
    pole-residue form (:meth:`DelaySystem.transfer_fast`) the gain bound of
    :func:`chatterlab.frequency._bounds.certified_band` excludes every frequency above the
    returned value for roots with Re lambda >= -SIGMA_TAU / tau: the band
    follows from the loop, not from the highest structural pole.
    """
    if omega_max is not None:
        return omega_max
    floor_ = max(2.0 * np.pi * (2 * count + 4) / (sys.tau * sys.r), 20.0 / sys.tau)
    cert = certified_top(sys, -SIGMA_TAU / sys.tau if sigma is None else sigma)
    if cert is not None:
        return max(cert, floor_)
    p = sys.delay_free_poles()
    pmax = float(np.max(np.abs(p))) if p.size else 0.0
    return max(2.0 * pmax, floor_)


def certified_top(sys: DelaySystem, sigma: float) -> float | None:
    """Frequency (rad/s) above which no root with Re >= ``sigma`` exists (gain
    bound on the loop transfer), or None if it cannot be bounded (no
    well-conditioned pole-residue form of the loop transfer)."""

    def compute() -> float | None:
        pf = sys.partial_fractions()
        if pf is None or not sys.r:
            return None
        p, L, R = pf
        pos = np.abs(p)[np.abs(p) > 0]
        w_low = 1e-3 * float(pos.min()) if pos.size else 1e-3
        r = sys.r
        Z = np.zeros((r, r))
        # ||e^{-lam tau} H(lam)|| <= e^{-sigma tau} ||H(lam)|| for Re lam >= sigma
        bd = certified_band(
            PoleResidue(p, L, R, Z), np.eye(r), Z, Z, float(np.exp(-sigma * sys.tau)), w_low, shift=sigma
        )
        return float(bd.hi) if bd.certified else None

    return sys.cached(f"band_top:{float(sigma)!r}", compute)
