"""The milling cut as the Newmark core's unilateral coupling
(:mod:`._contact`): its teeth are the contacts, the chip is the gap.

Everything the cut's speed gives -- the spindle's angular speed, the tooth
period, the delays of the teeth and the instants where a tooth enters or
leaves the arc -- comes from the process (:class:`chatterlab.process.Milling`:
``omega``, ``tooth_period``, ``delays``, ``breakpoints``); this module turns
them into the coupling's data on the step grid:

* the periodic pattern of one revolution (:func:`._contact.pattern`): the
  steps, split where a tooth enters or leaves the arc, the teeth in the arc
  on each substep;
* per point, the coefficients of the teeth, c_j = a_p (K_t t_j + K_n n_j)
  and e_j = a_p (K_te t_j + K_ne n_j), and their directions n_j;
* the known part of the chip, s_j = min over the previous passes k of
  [v_f d_jk sin phi_j + rho_j - rho_{j-k} - n_j . r(t - d_jk)] (multiple
  regeneration, the model's Eq. (2); :mod:`._milling`), from the tool
  point's history at the passes' delays d_jk -- several delays for a variable
  pitch -- through the core's Hermite interpolation; in a linear run only
  the preceding tooth's pass, without feed or runout.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..process import Milling
from ._contact import Cut, pattern
from ._core import FloatArray, delay_on_grid, hermite_weights

__all__: list[str] = []


class _MillingCut:
    """The cut of one milling run on the step grid (see the module docstring).

    ``m`` steps per mean tooth period (``N m`` per revolution); ``rho``: the
    runout of each tooth, m; ``passes``: the previous passes K in the chip.
    ``deepest`` counts the points whose chip the deepest pass set.
    """

    def __init__(
        self, milling: Milling, rpm: float, depth: float, feed: float, rho: FloatArray, passes: int, nonlinear: bool,
        m: int,
    ) -> None:  # fmt: skip
        N = self.teeth = milling.teeth
        self.mill, self.depth, self.nonlinear, self.K_pass = milling, depth, nonlinear, passes
        self.omega = milling.omega(rpm)
        tau = milling.tooth_period(rpm)
        self.n_rev = N * m
        self.h = h = tau / m
        # the arc's edges on the grid, over one revolution: the process's breakpoints of one period of
        # its coefficients (the tooth period of a uniform pitch, the revolution otherwise), repeated
        T = milling.period(rpm)
        reps = int(round(N * tau / T))
        jumps = [float(tb + r * T) / h for r in range(reps) for tb in milling.breakpoints(rpm)]
        omega, lags = self.omega, milling.lags
        pat = self.pattern = pattern(
            jumps, self.n_rev, h, lambda t: milling.in_cut(omega * t[:, None] - lags)
        )
        phi = omega * pat.t[:, None] - lags
        s, c = np.sin(phi), np.cos(phi)
        self.sin, self.cos = s, c
        ap, mi = depth, milling
        c1 = (ap * (mi.Kt * c + mi.Kn * s)).tolist()
        c2 = (ap * (-mi.Kt * s + mi.Kn * c)).tolist()
        if nonlinear:
            e1 = (ap * (mi.Kte * c + mi.Kne * s)).tolist()
            e2 = (ap * (-mi.Kte * s + mi.Kne * c)).tolist()
        else:
            e1 = e2 = np.zeros_like(s).tolist()
        n1, n2 = s.tolist(), c.tolist()
        self.pdata: list[Cut] = [
            (pat.left[e], c1[e], c2[e], e1[e], e2[e], n1[e], n2[e]) for e in range(len(pat.left))
        ]
        # passes: delay d_jk (s and steps), the tooth that made the pass
        delays = milling.delays(rpm)
        d = np.zeros((N, passes))
        prev_tooth = np.zeros((N, passes), dtype=int)
        for j in range(N):
            acc = 0.0
            for k in range(passes):
                acc += delays[(j - k) % N]
                d[j, k] = acc
                prev_tooth[j, k] = (j - k - 1) % N
        D = d / h
        self.Dint, self.Dfrac = delay_on_grid(D)
        self.chunk = max(1, int(math.floor(float(np.min(D)) + 1e-9)))
        self.off0 = int(np.max(self.Dint)) + 2
        # static part of the chip per pattern point: feed travelled since pass k, f_z d_jk / tau,
        # along n_j, and the runout difference
        self.vf_steps = feed * d / tau  # (N, K)
        self.rho_diff = rho[:, None] - rho[prev_tooth]
        self.static = self.vf_steps[None, :, :] * s[:, :, None] + self.rho_diff[None]
        self.deepest = 0

    def _delayed(self, run: Any, base: Any, frac: Any) -> Any:
        """r at the delayed instants ``t_base + frac h`` (rows of the history), (..., 2)."""
        w0, w1, w2, w3 = hermite_weights(frac, self.h)
        rb, vb = run.rbuf, run.vbuf
        return (
            w0[..., None] * rb[base]
            + w1[..., None] * vb[base]
            + w2[..., None] * rb[base + 1]
            + w3[..., None] * vb[base + 1]
        )

    def gaps(self, run: Any, i0: int, L: int) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Point indices (pattern), global steps and s_j (E, N) for steps i0+1 .. i0+L."""
        pat, n_rev = self.pattern, self.n_rev
        ps = (np.arange(i0, i0 + L)) % n_rev  # pattern step - 1 of each global step
        start = int(pat.first[ps[0]])
        count = int(np.sum(pat.count[ps]))
        E = pat.step.size
        idx = (start + np.arange(count)) % E
        gstep = i0 + 1 + ((pat.step[idx] - 1 - ps[0]) % n_rev)
        theta = pat.theta[idx]
        # delayed position: u = (gstep - 1 - Dint) + (theta - Dfrac)
        x = theta[:, None, None] - self.Dfrac[None]
        fl = np.floor(x)
        frac = x - fl
        up = frac > 1.0 - 1e-9
        fl = np.where(up, fl + 1.0, fl)
        frac = np.where(up, 0.0, frac)
        base = (gstep[:, None, None] - 1 - self.Dint[None] + fl.astype(int)) + self.off0
        rd = self._delayed(run, base, frac)  # (E, N, K, 2)
        sn, cs = self.sin[idx], self.cos[idx]
        proj = sn[:, :, None] * rd[..., 0] + cs[:, :, None] * rd[..., 1]
        if self.nonlinear:
            cand = self.static[idx] - proj
            arg = np.argmin(cand, axis=2)
            s = np.take_along_axis(cand, arg[..., None], axis=2)[..., 0]
            if self.K_pass > 1:
                self.deepest += int(np.sum((arg == self.K_pass - 1) & pat.g_left[idx]))
        else:
            s = -proj[..., 0]
        return idx, gstep, s

    def at(self, run: Any, t: float, screen: list[int]) -> tuple[Cut, list[float]]:
        """The cut's data at a time t off the pattern (an instant where a tooth
        leaves or re-enters the material): directions, coefficients and s_j
        (Hermite on the history, as in :meth:`gaps`)."""
        mi, ap, h = self.mill, self.depth, self.h
        phi = self.omega * t - mi.lags
        sn, cs = np.sin(phi), np.cos(phi)
        x = t / h - self.Dint - self.Dfrac
        base = np.floor(x)
        frac = x - base
        rd = self._delayed(run, base.astype(int) + self.off0, frac)
        proj = sn[:, None] * rd[..., 0] + cs[:, None] * rd[..., 1]
        stat = self.vf_steps * sn[:, None] + self.rho_diff
        sj = np.min(stat - proj, axis=1).tolist()
        cut = (
            screen,
            (ap * (mi.Kt * cs + mi.Kn * sn)).tolist(),
            (ap * (-mi.Kt * sn + mi.Kn * cs)).tolist(),
            (ap * (mi.Kte * cs + mi.Kne * sn)).tolist(),
            (ap * (-mi.Kte * sn + mi.Kne * cs)).tolist(),
            sn.tolist(),
            cs.tolist(),
        )
        return cut, sj
