"""The step loop of a milling run (:mod:`chatterlab.time._milling`): Newmark
(sub)steps on the periodic pattern, the chip from the delayed history, the
implicit cutting force with its active set of teeth, and the instants where
a tooth leaves or re-enters the material located and stepped to."""

from __future__ import annotations

import math

import numpy as np

from ..process import Milling
from ._milling_setup import TWO_PI, FloatArray, _Cut, _Family, _family, _hermite, _pattern
from ._options import NewmarkOptions

__all__: list[str] = []


class _Run:
    """One integration: the periodic pattern, the history buffers and the step loop."""

    #: locate the instants where a tooth leaves or re-enters the material (h_j = 0)
    locate = True

    def __init__(
        self,
        M: FloatArray,
        C: FloatArray,
        K: FloatArray,
        P: FloatArray,
        Minv: FloatArray,
        milling: Milling,
        omega: float,
        h: float,
        n_rev: int,
        depth: float,
        feed: float,
        rho: FloatArray,
        K_pass: int,
        nonlinear: bool,
        opts: NewmarkOptions,
    ) -> None:
        self.M, self.C, self.K, self.P, self.n = M, C, K, P, M.shape[0]
        self.mill, self.omega, self.h, self.n_rev = milling, omega, h, n_rev
        self.nonlinear, self.opts = nonlinear, opts
        N = milling.teeth
        self.N = N
        pat = _pattern(milling, n_rev, omega, h)
        self.pat = pat
        self.fams = [_family(M, C, K, P, hs * h, opts.gamma, opts.beta) for hs in pat.hs]
        n = self.n
        self.Ra = np.hstack([-Minv @ K, -Minv @ C, Minv @ P.T])  # a = Ra [q, v, F]
        self.Pv = np.ascontiguousarray(np.hstack([np.zeros((2, n)), P, np.zeros((2, n))]))
        # per-point cut coefficients (pattern level): c = a_p (Kt t + Kn n), e = a_p (Kte t + Kne n)
        s, c = pat.sin, pat.cos
        ap, mi = depth, milling
        self.c1 = (ap * (mi.Kt * c + mi.Kn * s)).tolist()
        self.c2 = (ap * (-mi.Kt * s + mi.Kn * c)).tolist()
        if nonlinear:
            self.e1 = (ap * (mi.Kte * c + mi.Kne * s)).tolist()
            self.e2 = (ap * (-mi.Kte * s + mi.Kne * c)).tolist()
        else:
            self.e1 = self.e2 = np.zeros_like(s).tolist()
        self.n1, self.n2 = s.tolist(), c.tolist()
        self.pdata: list[_Cut] = [
            (pat.left[e], self.c1[e], self.c2[e], self.e1[e], self.e2[e], self.n1[e], self.n2[e])
            for e in range(len(pat.left))
        ]
        self.depth = depth
        self.located = 0
        # passes: delay d_jk (in steps), the tooth that made the pass
        pitch = milling.pitches
        D = np.zeros((N, K_pass))
        prev_tooth = np.zeros((N, K_pass), dtype=int)
        for j in range(N):
            acc = 0.0
            for k in range(K_pass):
                acc += pitch[(j - k) % N]
                D[j, k] = acc / omega / h
                prev_tooth[j, k] = (j - k - 1) % N
        Dint = np.floor(D + 1e-9)
        Dfrac = D - Dint
        Dfrac[np.abs(Dfrac) < 1e-9] = 0.0
        self.Dint, self.Dfrac = Dint.astype(int), Dfrac
        self.chunk = max(1, int(math.floor(float(np.min(D)) + 1e-9)))
        self.off0 = int(np.max(Dint)) + 2
        v_f = feed * N * omega / TWO_PI
        # static part of Eq. (2) per pattern point: v_f d_jk sin(phi_j) + rho_j - rho_prev
        self.vf_steps = v_f * (D * h)  # (N, K): feed travelled since pass k
        self.rho_diff = rho[:, None] - rho[prev_tooth]
        self.static = self.vf_steps[None, :, :] * s[:, :, None] + self.rho_diff[None]
        self.K_pass = K_pass
        self.deepest = 0  # points where the deepest pass gave the minimum
        self.active_fail = 0

    # ---------------------------------------------------------------- delayed part of the chip
    def _chunk_s(self, i0: int, L: int) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Point indices (pattern), global steps and s_j (E, N) for steps i0+1 .. i0+L."""
        pat, n_rev = self.pat, self.n_rev
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
        w0, w1, w2, w3 = _hermite(frac, self.h)
        rb, vb = self.rbuf, self.vbuf
        rd = (
            w0[..., None] * rb[base]
            + w1[..., None] * vb[base]
            + w2[..., None] * rb[base + 1]
            + w3[..., None] * vb[base + 1]
        )  # (E, N, K, 2)
        sn, cs = self.pat.sin[idx], self.pat.cos[idx]
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

    # ---------------------------------------------------------------- the cut at one instant
    def _point_data(self, t: float, screen: list[int]) -> tuple[_Cut, list[float]]:
        """The cut's data at a time t off the pattern (an instant where a tooth
        leaves or re-enters the material): directions, coefficients and s_j
        (Hermite on the history, as in :meth:`_chunk_s`)."""
        mi, ap, h = self.mill, self.depth, self.h
        phi = self.omega * t - mi.lags
        sn, cs = np.sin(phi), np.cos(phi)
        x = t / h - self.Dint - self.Dfrac
        base = np.floor(x)
        frac = x - base
        idx = base.astype(int) + self.off0
        w0, w1, w2, w3 = _hermite(frac, h)
        rb, vb = self.rbuf, self.vbuf
        rd = (
            w0[..., None] * rb[idx]
            + w1[..., None] * vb[idx]
            + w2[..., None] * rb[idx + 1]
            + w3[..., None] * vb[idx + 1]
        )
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

    # ---------------------------------------------------------------- force at a point
    def _force(
        self,
        d: _Cut,
        sj: list[float],
        r1s: float,
        r2s: float,
        Z: tuple[float, float, float, float],
        guess: tuple[float, float],
        fixed: list[int] | None = None,
    ) -> tuple[float, float, float, float, list[int]]:
        """Implicit force: F with r = r* + Z F, the active teeth consistent with
        h > 0 (or the teeth ``fixed``); returns F, r and the active teeth."""
        screen, c1, c2, e1, e2, n1, n2 = d
        z11, z12, z21, z22 = Z
        iterate = self.nonlinear and fixed is None
        if fixed is not None:
            act = fixed
        elif self.nonlinear:
            g1, g2 = guess
            ra1 = r1s + z11 * g1 + z12 * g2
            ra2 = r2s + z21 * g1 + z22 * g2
            act = [j for j in screen if n1[j] * ra1 + n2[j] * ra2 + sj[j] > 0.0]
        else:
            act = screen
        for _ in range(2 * self.N + 3):
            W11 = W12 = W21 = W22 = b1 = b2 = 0.0
            for j in act:
                W11 += c1[j] * n1[j]
                W12 += c1[j] * n2[j]
                W21 += c2[j] * n1[j]
                W22 += c2[j] * n2[j]
                b1 += c1[j] * sj[j] + e1[j]
                b2 += c2[j] * sj[j] + e2[j]
            A11 = 1.0 + W11 * z11 + W12 * z21
            A12 = W11 * z12 + W12 * z22
            A21 = W21 * z11 + W22 * z21
            A22 = 1.0 + W21 * z12 + W22 * z22
            g1 = -(W11 * r1s + W12 * r2s + b1)
            g2 = -(W21 * r1s + W22 * r2s + b2)
            det = A11 * A22 - A12 * A21
            F1 = (A22 * g1 - A12 * g2) / det
            F2 = (A11 * g2 - A21 * g1) / det
            ra1 = r1s + z11 * F1 + z12 * F2
            ra2 = r2s + z21 * F1 + z22 * F2
            if not iterate:
                break
            new = [j for j in screen if n1[j] * ra1 + n2[j] * ra2 + sj[j] > 0.0]
            if new == act:
                break
            act = new
        else:
            self.active_fail += 1
        return F1, F2, ra1, ra2, act

    def _explicit_force(
        self, d: _Cut, teeth: list[int], sj: list[float], r1: float, r2: float, test: bool = True
    ) -> tuple[float, float, list[int]]:
        """Force of the teeth ``teeth`` at the known position r (restart, start),
        those with h <= 0 left out in the nonlinear model when ``test``."""
        _, c1, c2, e1, e2, n1, n2 = d
        F1 = F2 = 0.0
        act = []
        for j in teeth:
            hj = n1[j] * r1 + n2[j] * r2 + sj[j]
            if test and self.nonlinear and hj <= 0.0:
                continue
            act.append(j)
            F1 -= c1[j] * hj + e1[j]
            F2 -= c2[j] * hj + e2[j]
        return F1, F2, act

    def _advance(
        self,
        z: FloatArray,
        fm: _Family,
        d: _Cut,
        sj: list[float],
        guess: tuple[float, float],
        fixed: list[int] | None = None,
    ) -> tuple[FloatArray, float, float, float, float, list[int]]:
        """One Newmark (sub)step: the new state, F, r and the active teeth."""
        n = self.n
        rs = np.dot(fm.PL, z)
        F1, F2, r1, r2, act = self._force(d, sj, float(rs[0]), float(rs[1]), fm.Z, guess, fixed)
        w = self.w
        w[: 3 * n] = z
        w[3 * n] = F1
        w[3 * n + 1] = F2
        return np.dot(fm.PhiPsi, w), F1, F2, r1, r2, act

    def _restart(self, z: FloatArray, F1: float, F2: float) -> None:
        """Acceleration from the equation of motion with the force F (in place)."""
        n, wa = self.n, self.wa
        wa[: 2 * n] = z[: 2 * n]
        wa[2 * n] = F1
        wa[2 * n + 1] = F2
        z[2 * n :] = np.dot(self.Ra, wa)

    def _split(
        self,
        z: FloatArray,
        t_a: float,
        hs: float,
        th: float,
        d: _Cut,
        sj: list[float],
        act_a: list[int],
        act_b: list[int],
        changed: list[int],
        guess: tuple[float, float],
    ) -> tuple[FloatArray, float, float, float, float, list[int]]:
        """The substep [t_a, t_a + hs] in which tooth ``changed`` leaves or
        re-enters the material, split at t* = t_a + th hs (h_j linearly
        interpolated to 0): the old set of teeth up to t*, a restart with the
        new one there, the active-set step after."""
        o = self.opts
        t_s = t_a + th * hs
        fm1 = _family(self.M, self.C, self.K, self.P, th * hs, o.gamma, o.beta)
        fm2 = _family(self.M, self.C, self.K, self.P, (1.0 - th) * hs, o.gamma, o.beta)
        d_s, sj_s = self._point_data(t_s, d[0])
        z1, F1, F2, r1, r2, _ = self._advance(z, fm1, d_s, sj_s, guess, fixed=act_a)
        new = [j for j in d[0] if (j in act_b) if j in changed] + [j for j in act_a if j not in changed]
        G1, G2, _ = self._explicit_force(d_s, sorted(new), sj_s, r1, r2, test=False)
        self._restart(z1, G1, G2)
        self.located += 1
        return self._advance(z1, fm2, d, sj, (G1, G2))

    # ---------------------------------------------------------------- the loop
    def _start(
        self, q0: FloatArray, v0: FloatArray, n_total: int
    ) -> tuple[FloatArray, tuple[float, float], list[int], _Cut, list[float], FloatArray]:
        """The buffers, and the state at t = 0: the force of the first
        substep's teeth at r0 (history zero before t = 0).  Returns the state
        z, that force, its teeth, the cut and s_j at t = 0, and r0."""
        n, N, off0, pat = self.n, self.N, self.off0, self.pat
        size = n_total + 1 + off0 + 2
        self.rbuf = np.zeros((size, 2))
        self.vbuf = np.zeros((size, 2))  # r' = P v
        self.F = np.zeros((n_total + 1, 2))
        self.hraw = np.full((n_total + 1, N), np.nan)
        self.w = np.zeros(3 * n + 2)
        self.wa = np.zeros(2 * n + 2)
        P = self.P
        r0, rv0 = P @ q0, P @ v0
        self.rbuf[off0], self.vbuf[off0] = r0, rv0
        idx0, _, s0 = self._chunk_s(-1, 1)  # the point at t = 0 (end of step 0)
        e0 = int(idx0[-1])
        sj0 = s0[-1].tolist()
        pdata = self.pdata
        F1, F2, act_prev = self._explicit_force(pdata[e0], pat.right[e0], sj0, float(r0[0]), float(r0[1]))
        self.F[0] = (F1, F2)
        for j in pat.right[e0]:
            self.hraw[0, j] = pat.sin[e0, j] * r0[0] + pat.cos[e0, j] * r0[1] + sj0[j]
        z = np.concatenate([q0, v0, self.Ra @ np.concatenate([q0, v0, [F1, F2]])])
        return z, (F1, F2), act_prev, pdata[e0], sj0, r0

    def _relocate(
        self,
        z_a: FloatArray,
        step: tuple[FloatArray, float, float, float, float, list[int]],
        changed: list[int],
        h_prev: list[float],
        t_prev: float,
        hs: float,
        fm: _Family,
        d: _Cut,
        sj: list[float],
        act_prev: list[int],
        prev: tuple[_Cut, list[float], tuple[float, float]],
        guess: tuple[float, float],
    ) -> tuple[FloatArray, float, float, float, float, list[int]]:
        """The (sub)step from z_a that gave ``step`` changed the teeth in the
        material (``changed``): redone split at the instant h_j = 0 (linear
        in the step), or restarted at its start when the change is there."""
        z, F1, F2, r1, r2, act = step
        n1, n2 = d[5], d[6]
        th = 1.0
        for j in changed:
            hb = n1[j] * r1 + n2[j] * r2 + sj[j]
            if h_prev[j] != hb:
                th = min(th, h_prev[j] / (h_prev[j] - hb))
        if 1e-6 < th < 1.0 - 1e-6:
            return self._split(z_a, t_prev, hs, th, d, sj, act_prev, act, changed, guess)
        if th <= 1e-6:
            # the change happened at t_a itself (a tooth entering the arc with
            # h = 0 to round-off, e.g. at phi = 0 in a periodic motion): restart
            # there with the new set and redo the step
            d_prev, sj_prev, ra_prev = prev
            keep = [j for j in act_prev if j not in changed]
            new = sorted(keep + [j for j in changed if j in act])
            G1, G2, _ = self._explicit_force(d_prev, new, sj_prev, ra_prev[0], ra_prev[1], test=False)
            z_a = z_a.copy()
            self._restart(z_a, G1, G2)
            out = self._advance(z_a, fm, d, sj, (G1, G2))
            self.located += 1
            return out
        return step

    def integrate(self, q0: FloatArray, v0: FloatArray, n_total: int) -> tuple[str, str, int]:
        """Step the run to n_total steps (or until it diverges): (status, message, steps done)."""
        n, N, off0, pat, h = self.n, self.N, self.off0, self.pat, self.h
        z, guess, act_prev, d0, sj0, r0 = self._start(q0, v0, n_total)
        pdata = self.pdata
        Pv, fams = self.Pv, self.fams
        fam, restart, grid, right, theta = pat.fam, pat.restart, pat.grid, pat.right, pat.theta.tolist()
        hs_len = [x * h for x in pat.hs]
        locate = self.nonlinear and self.locate
        h_prev = [d0[5][j] * r0[0] + d0[6][j] * r0[1] + sj0[j] for j in range(N)]
        t_prev = 0.0
        d_prev, sj_prev, ra_prev = d0, sj0, (float(r0[0]), float(r0[1]))
        dot = np.dot
        limit = float(self.opts.divergence_limit)
        i_done = 0
        while i_done < n_total:
            L = min(self.chunk, n_total - i_done)
            idx, gstep, s = self._chunk_s(i_done, L)
            sl = s.tolist()
            idl = idx.tolist()
            gl = gstep.tolist()
            rbuf, vbuf, Fout, hraw = self.rbuf, self.vbuf, self.F, self.hraw
            for k, e in enumerate(idl):
                fm = fams[fam[e]]
                d = pdata[e]
                sj = sl[k]
                z_a = z
                z, F1, F2, r1, r2, act = self._advance(z_a, fm, d, sj, guess)
                n1, n2 = d[5], d[6]
                if locate:
                    changed = [j for j in d[0] if (j in act_prev) != (j in act)]
                    if changed:
                        z, F1, F2, r1, r2, act = self._relocate(
                            z_a, (z, F1, F2, r1, r2, act), changed, h_prev, t_prev, hs_len[fam[e]], fm,
                            d, sj, act_prev, (d_prev, sj_prev, ra_prev), guess,
                        )  # fmt: skip
                guess = (F1, F2)
                act_prev = act
                if grid[e]:
                    i = gl[k]
                    rbuf[i + off0, 0] = r1
                    rbuf[i + off0, 1] = r2
                    vbuf[i + off0] = dot(Pv, z)
                    Fout[i, 0] = F1
                    Fout[i, 1] = F2
                    for j in d[0]:
                        hraw[i, j] = n1[j] * r1 + n2[j] * r2 + sj[j]
                if restart[e]:
                    G1, G2, act_prev = self._explicit_force(d, right[e], sj, r1, r2)
                    self._restart(z, G1, G2)
                    guess = (G1, G2)
                if locate:
                    h_prev = [n1[j] * r1 + n2[j] * r2 + sj[j] for j in range(N)]
                    t_prev = (gl[k] - 1 + theta[e]) * h
                    d_prev, sj_prev, ra_prev = d, sj, (r1, r2)
            i_new = i_done + L
            block = self.rbuf[i_done + 1 + off0 : i_new + 1 + off0]
            if not np.all(np.isfinite(z)) or not np.all(np.isfinite(block)) or np.max(np.abs(z[:n])) > limit:
                return (
                    "diverged",
                    f"diverged by t = {i_new * self.h:.6g} s (|q| > {limit:.3g} or not finite)",
                    i_done,
                )
            i_done = i_new
        return "ok", "", i_done
