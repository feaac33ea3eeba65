"""The frequency side of the boundary search: the chatter-frequency band
searched (proven complete by the gain bound where the structure allows it,
the measured band for a measured FRF, or the caller's) and the frequency grid
that resolves every resonance in it.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..frequency._bounds import Band, certified_band
from ..frequency._frf import resonance_grid
from ._plant import Plant


def _grid(plant: Plant, lo: float, hi: float, n_base: int) -> np.ndarray:
    """Frequency grid on [lo, hi] (rad/s): logarithmic below a quarter of the
    first natural frequency, uniform above, plus clusters that resolve every
    resonance.  A measured plant: its measured frequencies in [lo, hi] and
    ``n_base`` uniform points between them (spline-interpolated FRF)."""
    if plant.grid is not None:
        w = np.unique(np.concatenate([plant.grid, np.linspace(lo, hi, n_base)]))
        return w[(w >= lo) & (w <= hi)]
    w1 = _first_mode(plant)
    parts = [resonance_grid(plant.poles, max(lo, min(0.25 * w1, hi)), hi, n_base)]
    if lo < 0.25 * w1:
        parts.append(np.geomspace(max(lo, 1e-4 * w1), min(0.25 * w1, hi), 80))
    if lo == 0.0:
        parts.append(np.zeros(1))  # w = 0 itself: the grid reaches the static case
    w = np.unique(np.concatenate(parts))
    return w[(w >= lo) & (w <= hi)]


def _first_mode(plant: Plant) -> float:
    wn = np.abs(plant.poles[plant.poles.imag > 0])
    return float(wn.min()) if wn.size else 1.0


def _band(plant: Plant, fmin: float | None, fmax: float | None, width_max: float) -> Band:
    """The chatter-frequency band searched (rad/s) and whether it is proven
    to hold every boundary point below ``width_max``.  A band given by the
    caller (either end) is searched as given and proves nothing outside it.
    A measured plant's band is the measured one (or the part of it between
    fmin and fmax), never certified."""
    if plant.measured_band is not None:
        return _measured_search_band(plant.measured_band, fmin, fmax)
    if fmin is None or fmax is None:
        auto = _auto_band(plant, width_max)
        if fmin is None and fmax is None:
            return auto
    lo = 2 * np.pi * fmin if fmin is not None else auto.lo
    hi = 2 * np.pi * fmax if fmax is not None else auto.hi
    if not hi > lo >= 0:
        raise InputError(
            f"the chatter frequency band is empty: fmin {lo / 2 / np.pi:g} Hz, fmax {hi / 2 / np.pi:g} Hz"
        )
    return Band(lo, hi, False, "band given by the caller (fmin/fmax): outside it nothing is claimed")


def _measured_search_band(mb: Band, fmin: float | None, fmax: float | None) -> Band:
    lo = mb.lo if fmin is None else 2 * np.pi * fmin
    hi = mb.hi if fmax is None else 2 * np.pi * fmax
    tol = 1e-12 * mb.hi
    if lo < mb.lo - tol or hi > mb.hi + tol:
        raise InputError(
            f"the chatter band {lo / 2 / np.pi:g} .. {hi / 2 / np.pi:g} Hz reaches outside the measured band"
            f" {mb.lo / 2 / np.pi:g} .. {mb.hi / 2 / np.pi:g} Hz; a measured FRF is not extrapolated: keep fmin/fmax inside it"
        )
    if not hi > lo:
        raise InputError(
            f"the chatter frequency band is empty: fmin {lo / 2 / np.pi:g} Hz, fmax {hi / 2 / np.pi:g} Hz"
        )
    return Band(max(lo, mb.lo), min(hi, mb.hi), False, mb.reason)


def _auto_band(plant: Plant, width_max: float) -> Band:
    """[0, hi] with hi from the gain bound when the structure has a pole-residue
    form and no pole at s = 0 (the grid then reaches w = 0 itself, where the
    loop gain bound of a stiff cut is usually above 1); otherwise a band from
    the modes, not proven."""
    w1 = _first_mode(plant)
    pmax = float(np.max(np.abs(plant.poles))) if plant.poles.size else 1.0
    rigid = plant.poles.size and float(np.min(np.abs(plant.poles))) <= 1e-9 * pmax
    if plant.residues is None or rigid:
        wn = np.sort(np.abs(plant.poles[plant.poles.imag > 0]))
        wk = float(wn[min(len(wn) - 1, 11)]) if wn.size else 10.0
        why = "a pole at s = 0 (rigid-body mode)" if rigid else "no pole-residue form of the structure"
        return Band(1e-3 * w1, 1.6 * wk, False, f"{why}: band from the modes, not proven")
    bd = certified_band(plant.residues, plant.Dl_P, plant.Dl_V, plant.Dl_O, width_max, 1e-3 * w1)
    return Band(0.0, max(bd.hi * 1.02, bd.lo), bd.certified, bd.reason)
