"""The lobes of a constant-gain boundary: every lobe k of every branch in a
range of delays, as curves on the frequency grid (T_k = (phi + 2 pi k) / w),
and the count of lobes crossing the range (:func:`chatterlab.lobes.lobes`;
the process-damping engine takes them cell by cell)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ._envelope import _Segment
from ._result import Lobe

__all__: list[str] = []


def _lobe_curves(
    segs: list[_Segment], T: np.ndarray, lobe_k: np.ndarray, proc: Any, b_ref: float
) -> tuple[list[Lobe], int]:
    """Every lobe in the range of delays, as curves on the frequency grid, and
    the number of lobes crossing the range (when more than 400 of a branch do,
    only the lobe numbers k of the envelope are kept as curves, on every
    branch)."""
    lobe_list: list[Lobe] = []
    Tlo, Thi = float(T.min()), float(T.max())
    n_in_range = 0
    for sg in segs:
        phi = np.mod(-np.angle(sg.z), 2 * np.pi)  # w T = phi + 2 pi k, phi in [0, 2 pi)
        kmin = max(int(np.floor((sg.omega * Tlo - phi).min() / (2 * np.pi))), 0)
        kmax = int(np.ceil((sg.omega * Thi - phi).max() / (2 * np.pi)))
        n_in_range += _lobes_crossing(sg.omega, phi, Tlo, Thi)
        if kmax - kmin > 400:  # a dense diagram: keep the lobes that form the envelope
            ks = np.unique(lobe_k[lobe_k >= 0])
            krange = ks if ks.size else np.arange(kmin, kmin + 50)
        else:
            krange = np.arange(kmin, kmax + 1)
        for k in krange:
            with np.errstate(divide="ignore", invalid="ignore"):  # w = 0: T = inf, outside
                Tk = (phi + 2 * np.pi * k) / sg.omega
            inside = (Tk >= Tlo) & (Tk <= Thi) & (Tk > proc.min_delay)
            if np.count_nonzero(inside) < 2:
                continue
            Ts = Tk[inside]
            lobe_list.append(
                Lobe(
                    int(k),
                    sg.branch,
                    Ts,
                    np.asarray(proc.speed_for_delay(Ts)) if proc.kind != "delay" else Ts,
                    sg.beta[inside] * b_ref,
                    sg.omega[inside] / (2 * np.pi),
                )
            )
    return lobe_list, n_in_range


def _lobes_crossing(omega: np.ndarray, phi: np.ndarray, Tlo: float, Thi: float) -> int:
    """Number of lobes k of one branch that cross [Tlo, Thi]: the union over
    the branch's samples of the integers k with T_k = (phi + 2 pi k) / w in it."""
    ok = omega > 0
    lo = np.ceil((omega[ok] * Tlo - phi[ok]) / (2 * np.pi)).astype(np.int64)
    hi = np.floor((omega[ok] * Thi - phi[ok]) / (2 * np.pi)).astype(np.int64)
    lo = np.maximum(lo, 0)
    keep = hi >= lo
    if not np.any(keep):
        return 0
    order = np.argsort(lo[keep])
    a, b = lo[keep][order], hi[keep][order]
    reach = np.maximum.accumulate(b)
    starts = np.r_[True, a[1:] > reach[:-1] + 1]
    # merge overlapping intervals: each run from a start to the next start
    idx = np.nonzero(starts)[0]
    ends = np.r_[idx[1:] - 1, a.size - 1]
    return int(np.sum(reach[ends] - a[idx] + 1))
