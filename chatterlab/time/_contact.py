"""The unilateral coupling of the Newmark core (:mod:`._core`).

A structure ``M q'' + C q' + K q = P^T F`` (``P``: 2 x n, the coupling's
output ``r = P q``, e.g. the tool point) is coupled to contacts ``j`` whose
gap is affine in ``r``,

    h_j = n_j . r + s_j,        F = - sum_{j active} (c_j h_j + e_j),

where ``n_j`` (direction), ``c_j`` (stiffness vector), ``e_j`` (a force
independent of the gap) and the candidates (the contacts that may act) are
the coupling's data at the point, periodic in time, and ``s_j`` is the part
of the gap known before the step (it may read the coupling's history at any
number of delays).  A candidate is active while ``h_j > 0``: the milling
cut's teeth, whose chip is the gap (:mod:`._milling_cut`).

Per point of the core's step loop (:meth:`_Contacts.point`):

* **the implicit force**: the step map of the substep (:func:`._core.step_map`)
  gives ``r = r* + Z F``; F and the active set follow from a 2 x 2 solve,
  repeated until the set of contacts with ``h_j > 0`` is consistent (an
  active-set iteration; it converges because ``|Z| ~ beta h^2 / m`` is small);
* **the instant a gap crosses zero** (a contact's active state differs at
  the two ends of the substep) is located by interpolating ``h_j`` linearly
  to 0, and the substep is split there: the old set of contacts up to it, a
  restart with the new set, the active-set substep after.  Without ``e_j``
  the force is only kinked there (``h_j -> 0``); with it the force jumps by
  ``e_j``, which unlocated would cost one order of the scheme;
* **restarts** where the pattern's candidates change (the acceleration
  from the equation of motion with the new candidates' force);
* **a rubbing damping** (process damping, Eq. 4a of docs/process-damping.md):
  the active contacts also push ``-g_d sum_j n_j n_j^T r'`` with the rate
  ``r' = r'* + Y F`` of the step map (``Y`` its velocity rows' compliance),
  so the 2 x 2 solve becomes ``(I + W Z + D Y) F = -(W r* + b + D r'*)``,
  ``D = g_d sum_j n_j n_j^T`` (zero: the equations without it);
* **the flanks of the indentation model** (Eq. 6a of docs/process-damping.md,
  :class:`._indentation.ToothFlanks`): each active contact's flank pushes
  ``-K_sp a_p A_j n_j``, ``A_j`` the area under it with the penetration
  ``u_j = n_j . r`` and the surface behind the edge ``n_j . r(t - xi / V)``
  (the recorded ``r`` at the steps, and at the land's end ``xi = w`` by the
  cubic Hermite interpolation of the delays).  The force is implicit: a
  fixed point around the 2 x 2 solve, ``r = r* + Z (F_c + F_f)`` with the
  flank's ``F_f`` of the last iterate, a contraction since ``Z dF_f/du ~
  beta h^2 K_sp a_p L / m`` (L the contact length) is tiny;
* **the record** at every step of ``r`` (the solved one), ``r' = P v``,
  ``F`` and the gaps of the candidates (NaN elsewhere): the coupling's
  history (read by the gaps of later steps) and its outputs.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ._core import FloatArray, StepMap, hermite_weights, step_map

__all__: list[str] = []

#: the coupling at a point: (candidate contacts, c_x, c_y, e_x, e_y, n_x, n_y), lists over the contacts
Cut = tuple[list[int], list[float], list[float], list[float], list[float], list[float], list[float]]
#: iterations of the flanks' fixed point stop at this change of their force, relative to the whole force
FLANK_TOL = 1e-13
#: one substep's result: the state at its end, F, r and the active contacts
Step = tuple[FloatArray, float, float, float, float, list[int]]


# =========================================================================== the periodic pattern


@dataclass(frozen=True)
class Pattern:
    """The points of one period of the coupling (the steps, split where a
    coefficient jumps off the grid), repeated over the run."""

    step: FloatArray  # (E,) step 1..n_period whose interval holds the point
    theta: FloatArray  # (E,) position in the step, (0, 1]
    t: FloatArray  # (E,) time of the point in the period, s
    fam: list[int]  # index of the substep length (its step map)
    hs: list[float]  # substep length (in steps) of each family
    restart: list[bool]  # the candidates change at the point: restart the acceleration there
    grid: list[bool]  # the point ends a step
    g_left: FloatArray  # (E, N) bool: candidate on the substep ending at the point
    left: list[list[int]]  # candidates on the substep ending at the point
    right: list[list[int]]  # ... on the substep starting there
    first: FloatArray  # (n_period,) index of the first point of each step
    count: FloatArray  # (n_period,)


def pattern(jumps: list[float], n_period: int, h: float, candidates: Any) -> Pattern:
    """The :class:`Pattern` of a period of ``n_period`` steps of ``h`` whose
    coefficients jump at ``jumps`` (positions in steps, in ``[0,
    n_period)``); ``candidates(t)`` (times (E,), s) -> (E, N) bool.  A jump
    within 1e-6 of a step of the grid is taken as on it (a tinier substep
    loses digits): it is found by comparing the candidates of neighbouring
    steps."""
    off: dict[int, list[float]] = {}
    for u in jumps:
        k = round(u)
        if abs(u - k) <= 1e-6:
            continue
        off.setdefault(int(math.floor(u)) + 1, []).append(u - math.floor(u))
    steps: list[int] = []
    thetas: list[float] = []
    for s in range(1, n_period + 1):
        for th in sorted(set(off.get(s, []))):
            steps.append(s)
            thetas.append(th)
        steps.append(s)
        thetas.append(1.0)
    step = np.array(steps)
    theta = np.array(thetas)
    prev = np.where(np.r_[True, step[1:] != step[:-1]], 0.0, np.r_[0.0, theta[:-1]])
    hs_rel = theta - prev
    mid = (step - 1 + 0.5 * (prev + theta)) * h
    g_left = candidates(mid)
    g_right = np.roll(g_left, -1, axis=0)
    fams: dict[float, int] = {}
    fam = []
    for v in np.round(hs_rel, 12):
        fam.append(fams.setdefault(float(v), len(fams)))
    teeth = np.arange(g_left.shape[1])
    return Pattern(
        step=step,
        theta=theta,
        t=(step - 1 + theta) * h,
        fam=fam,
        hs=list(fams),
        restart=[bool(v) for v in np.any(g_left != g_right, axis=1)],
        grid=[bool(v) for v in theta == 1.0],
        g_left=g_left,
        left=[teeth[g].tolist() for g in g_left],
        right=[teeth[g].tolist() for g in g_right],
        first=np.searchsorted(step, np.arange(1, n_period + 1)),
        count=np.bincount(step - 1, minlength=n_period),
    )


# =========================================================================== the run of a coupling


class _Contacts:
    """A unilateral coupling in one run: its history and records, the state
    of the active set between points, and the work of one point of the
    core's step loop.

    ``cut``: the coupling's data (:class:`._milling_cut._MillingCut`:
    ``pattern``, ``pdata``, ``gaps``, ``at``, ``nonlinear``, ``teeth``,
    ``off0``, ``chunk``); ``structure``: ``(M, C, K, P)``.
    """

    #: locate the instants where a contact's gap crosses zero (tests switch it off)
    locate = True

    def __init__(
        self,
        cut: Any,
        structure: tuple[FloatArray, ...],
        h: float,
        opts: Any,
        n_total: int,
        rubbing: float = 0.0,
        flanks: Any = None,
    ) -> None:
        M, C, K, P = structure
        self.cut, self.M, self.C, self.K, self.P, self.h, self.opts = cut, M, C, K, P, h, opts
        self.gd = float(rubbing)  # N s/m: the rubbing damping per active contact along n_j (0: none)
        self.flanks = flanks  # the indentation model's flanks (ToothFlanks) or None
        self.flank_fail = 0  # points where the flanks' fixed point did not settle
        self.flank_prev = (0.0, 0.0)  # the flanks' force at the last point (the fixed point's guess)
        self.rmax = 0.0  # max |r| recorded: bounds how far back the flank can touch
        n = self.n = M.shape[0]
        N = self.N = cut.teeth
        Minv = np.linalg.inv(M)
        self.Ra = np.hstack([-Minv @ K, -Minv @ C, Minv @ P.T])  # a = Ra [q, v, F]
        self.Pv = np.ascontiguousarray(np.hstack([np.zeros((2, n)), P, np.zeros((2, n))]))
        pat = cut.pattern
        self.maps = [step_map(M, C, K, P, hs * h, opts.gamma, opts.beta) for hs in pat.hs]
        self.vmaps = [self.rate_map(fm) for fm in self.maps]
        self.hs_len = [x * h for x in pat.hs]
        self.fam, self.restart_at, self.grid = pat.fam, pat.restart, pat.grid
        self.right, self.theta = pat.right, pat.theta.tolist()
        self.pdata: list[Cut] = cut.pdata
        self.nonlinear = bool(cut.nonlinear)
        self.locating = self.nonlinear and self.locate
        off0 = cut.off0
        size = n_total + 1 + off0 + 2
        self.rbuf = np.zeros((size, 2))  # r at every step (the solved one), history zero before t = 0
        self.vbuf = np.zeros((size, 2))  # r' = P v
        self.F = np.zeros((n_total + 1, 2))
        self.hraw = np.full((n_total + 1, N), np.nan)
        self.w = np.zeros(3 * n + 2)
        self.wa = np.zeros(2 * n + 2)
        self.located = 0
        self.active_fail = 0
        self.chunk_data: list[Any] = [[], [], []]  # the chunk's points, their steps, the known gaps
        self.last = np.zeros(3 * n)  # the state after advance() without ``out``
        self.point: Callable[[int, int, FloatArray, FloatArray], None] = self._unstarted

    def rate_map(self, fm: StepMap) -> tuple[FloatArray, tuple[float, float, float, float]]:
        """The coupling's rate at the end of a substep as the step map gives
        it: ``r' = PV z + Y F`` (PV: (2, 3n); Y: 2 x 2, row by row)."""
        n, P = self.n, self.P
        PV = np.ascontiguousarray(P @ fm.PhiPsi[n : 2 * n, : 3 * n])
        Y = P @ fm.PhiPsi[n : 2 * n, 3 * n :]
        return PV, (float(Y[0, 0]), float(Y[0, 1]), float(Y[1, 0]), float(Y[1, 1]))

    def _unstarted(self, k: int, e: int, z_a: FloatArray, z_out: FloatArray) -> None:
        raise RuntimeError("_Contacts.start() must run before the step loop")

    # ---------------------------------------------------------------- the start
    def start(self, q0: FloatArray, v0: FloatArray) -> FloatArray:
        """The record and the active set at t = 0 -- the force of the first
        substep's candidates at r0, with the coupling's history (zero
        before t = 0) -- and the acceleration a0 it gives; :attr:`point` is
        then ready for the core's step loop."""
        N, off0, pat = self.N, self.cut.off0, self.cut.pattern
        P = self.P
        r0, rv0 = P @ q0, P @ v0
        self.rbuf[off0], self.vbuf[off0] = r0, rv0
        idx0, _, s0 = self.cut.gaps(self, -1, 1)  # the point at t = 0 (end of step 0)
        e0 = int(idx0[-1])
        sj0 = s0[-1].tolist()
        d0 = self.pdata[e0]
        self.rmax = float(np.hypot(r0[0], r0[1]))
        F1, F2, act = self.explicit_force(
            d0, pat.right[e0], sj0, float(r0[0]), float(r0[1]), rate=(float(rv0[0]), float(rv0[1])), t=0.0
        )
        self.F[0] = (F1, F2)
        for j in pat.right[e0]:
            self.hraw[0, j] = d0[5][j] * r0[0] + d0[6][j] * r0[1] + sj0[j]
        h0 = [d0[5][j] * r0[0] + d0[6][j] * r0[1] + sj0[j] for j in range(N)]
        self.point = self._point(
            (F1, F2), act, h0, (d0, sj0, (float(r0[0]), float(r0[1])), (float(rv0[0]), float(rv0[1])))
        )
        a0: FloatArray = self.Ra @ np.concatenate([q0, v0, [F1, F2]])
        return a0

    def prepare(self, i0: int, L: int) -> tuple[list[int], list[int]]:
        """The points of steps i0+1 .. i0+L (pattern indices), the step each
        ends in, and the known part of their gaps (kept for :attr:`point`)."""
        idx, gstep, s = self.cut.gaps(self, i0, L)
        data = self.chunk_data
        data[0], data[1], data[2] = idx.tolist(), gstep.tolist(), s.tolist()
        return data[0], data[1]

    # ---------------------------------------------------------------- one point of the step loop
    def _point(
        self, guess: tuple[float, float], act_prev: list[int], h_prev: list[float], prev: Any
    ) -> Callable[[int, int, FloatArray, FloatArray], None]:
        """The work of one point of the core's step loop, as a function of
        (k, e, z_a, z_out) -- point k of the chunk, pattern point e: the
        substep from the state ``z_a`` to ``z_out`` with the implicit force,
        a crossing located, the record at a step's end and the restart where
        the candidates change.  The active set, the force guess and the
        gaps at the last point live in the function (locals for speed)."""
        maps, fam, pdata, grid, restart_at = self.maps, self.fam, self.pdata, self.grid, self.restart_at
        vmaps, rubbing = self.vmaps, self.gd != 0.0
        right, theta, hs_len, h, N, n3 = self.right, self.theta, self.hs_len, self.h, self.N, 3 * self.n
        force, explicit_force, restart = self.force, self.explicit_force, self.restart
        flanks = self.flanks is not None
        flank_force = self.flank_force
        rbuf, vbuf, Fout, hraw, Pv, off0 = self.rbuf, self.vbuf, self.F, self.hraw, self.Pv, self.cut.off0
        w, data, dot = self.w, self.chunk_data, np.dot
        wz = w[:n3]
        locating = self.locating
        t_prev = 0.0

        def point(k: int, e: int, z_a: FloatArray, z_out: FloatArray) -> None:
            nonlocal guess, act_prev, h_prev, t_prev, prev
            gl, sl = data[1], data[2]
            fm = maps[fam[e]]
            d = pdata[e]
            sj = sl[k]
            # the substep by its step map (as :meth:`advance`, inline: the hot path)
            r1s, r2s = dot(fm.PL, z_a).tolist()
            t_pt = (gl[k] - 1 + theta[e]) * h
            if rubbing:
                PV, Y = vmaps[fam[e]]
                F1, F2, r1, r2, act = force(d, sj, r1s, r2s, fm.Z, guess, rate=(dot(PV, z_a).tolist(), Y))
            elif flanks:
                F1, F2, r1, r2, act = flank_force(d, sj, r1s, r2s, fm.Z, guess, t=t_pt)
            else:
                F1, F2, r1, r2, act = force(d, sj, r1s, r2s, fm.Z, guess)
            wz[:] = z_a
            w[n3] = F1
            w[n3 + 1] = F2
            dot(fm.PhiPsi, w, out=z_out)
            if locating:
                changed = [j for j in d[0] if (j in act_prev) != (j in act)]
                if changed:
                    z_start = self.w[:n3].copy()  # the state at the substep's start
                    ctx = (act_prev, guess, h_prev, t_prev, prev)
                    step = (z_out, F1, F2, r1, r2, act)
                    z, F1, F2, r1, r2, act = self.relocate(
                        z_start, step, changed, hs_len[fam[e]], fm, d, sj, ctx
                    )
                    np.copyto(z_out, z)
            guess = (F1, F2)
            act_prev = act
            n1, n2 = d[5], d[6]
            if grid[e]:  # the record of the step: r, r' = P v, F and the candidates' gaps
                i = gl[k]
                rbuf[i + off0, 0] = r1
                rbuf[i + off0, 1] = r2
                vbuf[i + off0] = dot(Pv, z_out)
                Fout[i, 0] = F1
                Fout[i, 1] = F2
                for j in d[0]:
                    hraw[i, j] = n1[j] * r1 + n2[j] * r2 + sj[j]
                if flanks:
                    self.rmax = max(self.rmax, math.hypot(r1, r2))
            rv = tuple(dot(Pv, z_out).tolist()) if rubbing else (0.0, 0.0)
            if restart_at[e]:
                G1, G2, act_prev = explicit_force(d, right[e], sj, r1, r2, rate=rv, t=t_pt)
                restart(z_out, G1, G2)
                guess = (G1, G2)
            if locating:
                h_prev = [n1[j] * r1 + n2[j] * r2 + sj[j] for j in range(N)]
                t_prev = t_pt
                prev = (d, sj, (r1, r2), rv)

        return point

    # ---------------------------------------------------------------- force at a point
    def force(
        self,
        d: Cut,
        sj: list[float],
        r1s: float,
        r2s: float,
        Z: tuple[float, float, float, float],
        guess: tuple[float, float],
        fixed: list[int] | None = None,
        rate: tuple[list[float], tuple[float, float, float, float]] | None = None,
    ) -> tuple[float, float, float, float, list[int]]:
        """Implicit force: F with r = r* + Z F, the active contacts consistent
        with h > 0 (or the contacts ``fixed``); returns F, r and the active
        ones.  ``rate``: (r'*, Y) of the substep when the contacts rub
        (r' = r'* + Y F, the damping -g_d sum_j n_j n_j^T r')."""
        screen, c1, c2, e1, e2, n1, n2 = d
        z11, z12, z21, z22 = Z
        gd = self.gd if rate is not None else 0.0
        if rate is not None:
            (v1s, v2s), (y11, y12, y21, y22) = rate
        else:
            v1s = v2s = y11 = y12 = y21 = y22 = 0.0
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
            if gd:  # the rubbing flanks: + D Y in the matrix, - D r'* on the right
                D11 = D12 = D22 = 0.0
                for j in act:
                    D11 += n1[j] * n1[j]
                    D12 += n1[j] * n2[j]
                    D22 += n2[j] * n2[j]
                D11, D12, D22 = gd * D11, gd * D12, gd * D22
                A11 += D11 * y11 + D12 * y21
                A12 += D11 * y12 + D12 * y22
                A21 += D12 * y11 + D22 * y21
                A22 += D12 * y12 + D22 * y22
                g1 -= D11 * v1s + D12 * v2s
                g2 -= D12 * v1s + D22 * v2s
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

    def flank_force(
        self, d: Cut, sj: list[float], r1s: float, r2s: float, Z: tuple[float, float, float, float],
        guess: tuple[float, float], fixed: list[int] | None = None, t: float = 0.0,
    ) -> tuple[float, float, float, float, list[int]]:  # fmt: skip
        """The implicit force with the flanks of the indentation model at
        the time t (the end of the substep): the fixed point of the flanks'
        force F_f around the 2 x 2 solve of the cut (:meth:`force` at
        ``r* + Z F_f``); returns the whole force, r and the active contacts."""
        z11, z12, z21, z22 = Z
        surface = self.flank_surface(t, r1s, r2s)
        f1, f2 = self.flank_prev
        F1 = F2 = ra1 = ra2 = 0.0
        act: list[int] = []
        for _ in range(50):
            a1 = r1s + z11 * f1 + z12 * f2
            a2 = r2s + z21 * f1 + z22 * f2
            F1, F2, ra1, ra2, act = self.force(d, sj, a1, a2, Z, (guess[0] - f1, guess[1] - f2), fixed)
            g1, g2 = self.flank_push(surface, d, act, ra1, ra2)
            change = abs(g1 - f1) + abs(g2 - f2)
            if change <= FLANK_TOL * (abs(F1) + abs(F2) + abs(g1) + abs(g2)) or change == 0.0:
                break
            f1, f2 = g1, g2
        else:  # Z dF_f/du >= 1: a flank this stiff needs a shorter step
            self.flank_fail += 1
        self.flank_prev = (f1, f2)
        return F1 + f1, F2 + f2, ra1, ra2, act

    def flank_surface(
        self, t: float, r1: float, r2: float
    ) -> tuple[FloatArray, FloatArray, dict[int, FloatArray]]:
        """The surface behind the edges at the time t: the distances xi from
        the edge (0, then V (t - t_i) of the recorded steps t_i < t, newest
        first, and the land's end w) and r there (k, 2: the steps' records,
        Hermite at t - w / V; the edge's row a placeholder), far enough back
        that no flank touches beyond (u_j - n_j . r(t - xi / V) <= |r| + max
        |r| recorded; twice that for the iterates of the fixed point); and
        an empty cache of the teeth's surfaces."""
        fl, h, off0 = self.flanks, self.h, self.cut.off0
        V, w = fl.speed, fl.wear_land
        i_last = int(math.ceil(t / h - 1e-9)) - 1
        reach = w + 2.0 * (math.hypot(r1, r2) + self.rmax) / math.tan(fl.clearance)
        want = int(math.ceil(reach / (V * h))) + 2
        k = min(want, i_last + off0 + 1)
        idx = i_last - np.arange(k)
        xi = V * (t - idx * h)
        rows = self.rbuf[idx + off0]
        if k < want:  # the reach goes back before the buffer: the zero history held there
            xi = np.append(xi, max(reach, float(xi[-1])) + V * h)
            rows = np.vstack((rows, np.zeros((1, 2))))
        pos = int(np.searchsorted(xi, w))
        if pos < xi.size and abs(xi[pos] - w) <= 1e-12 * w:  # the land's end on a step
            return np.concatenate(((0.0,), xi)), np.vstack((rows[:1], rows)), {}
        x = (t - w / V) / h
        base = math.floor(x)
        b = base + off0
        land = np.zeros(2)
        if b >= 0:
            w0, w1, w2, w3 = hermite_weights(x - base, h)
            land = w0 * self.rbuf[b] + w1 * self.vbuf[b] + w2 * self.rbuf[b + 1] + w3 * self.vbuf[b + 1]
        xs = np.concatenate(((0.0,), xi[:pos], (w,), xi[pos:]))
        return xs, np.vstack((rows[:1], rows[:pos], land, rows[pos:])), {}

    def flank_push(
        self, surface: tuple[FloatArray, FloatArray, dict[int, FloatArray]], d: Cut, act: list[int], r1: float,
        r2: float,
    ) -> tuple[float, float]:  # fmt: skip
        """The flanks' force on the tool, -K_sp a_p sum_j A_j n_j over the
        contacts ``act`` with the tool at r (:meth:`flank_surface`'s surface;
        each tooth's n_j . r there kept in its cache for the fixed point's
        iterates)."""
        fl = self.flanks
        if not act or fl.K_sp == 0.0:
            return 0.0, 0.0
        xs, rows, cache = surface
        n1, n2 = d[5], d[6]
        F1 = F2 = 0.0
        gain = fl.K_sp * fl.depth
        for j in act:
            surf = cache.get(j)
            if surf is None:
                surf = cache[j] = rows[:, 0] * n1[j] + rows[:, 1] * n2[j]
            u = n1[j] * r1 + n2[j] * r2
            surf[0] = u
            A = fl.area(u, xs, surf)
            F1 -= gain * A * n1[j]
            F2 -= gain * A * n2[j]
        return F1, F2

    def explicit_force(
        self, d: Cut, teeth: list[int], sj: list[float], r1: float, r2: float, test: bool = True,
        rate: tuple[float, float] = (0.0, 0.0), t: float = 0.0,
    ) -> tuple[float, float, list[int]]:  # fmt: skip
        """Force of the contacts ``teeth`` at the known position r and rate
        r' (restart, start) at the time t (the flanks' surface), those with
        h <= 0 left out in the nonlinear model when ``test``."""
        _, c1, c2, e1, e2, n1, n2 = d
        F1 = F2 = 0.0
        act = []
        gd, (v1, v2) = self.gd, rate
        for j in teeth:
            hj = n1[j] * r1 + n2[j] * r2 + sj[j]
            if test and self.nonlinear and hj <= 0.0:
                continue
            act.append(j)
            F1 -= c1[j] * hj + e1[j]
            F2 -= c2[j] * hj + e2[j]
            if gd:
                vn = gd * (n1[j] * v1 + n2[j] * v2)
                F1 -= n1[j] * vn
                F2 -= n2[j] * vn
        if self.flanks is not None:
            f1, f2 = self.flank_push(self.flank_surface(t, r1, r2), d, act, r1, r2)
            F1 += f1
            F2 += f2
        return F1, F2, act

    def advance(
        self,
        z: FloatArray,
        fm: StepMap,
        d: Cut,
        sj: list[float],
        guess: tuple[float, float],
        fixed: list[int] | None = None,
        out: FloatArray | None = None,
        vm: tuple[FloatArray, tuple[float, float, float, float]] | None = None,
        t: float = 0.0,
    ) -> tuple[float, float, float, float, list[int]]:
        """One Newmark (sub)step from ``z`` by the step map ``fm`` (``vm``
        its :meth:`rate_map`, made when None and needed; ``t`` the time at
        its end, for the flanks): the new state into ``out`` (or a new
        array, :attr:`last`), F, r and the active contacts."""
        n = self.n
        r1s, r2s = np.dot(fm.PL, z).tolist()
        rate = None
        if self.gd:
            PV, Y = self.rate_map(fm) if vm is None else vm
            rate = (np.dot(PV, z).tolist(), Y)
        if self.flanks is not None:
            F1, F2, r1, r2, act = self.flank_force(d, sj, r1s, r2s, fm.Z, guess, fixed, t)
        else:
            F1, F2, r1, r2, act = self.force(d, sj, r1s, r2s, fm.Z, guess, fixed, rate)
        w = self.w
        w[: 3 * n] = z
        w[3 * n] = F1
        w[3 * n + 1] = F2
        if out is None:
            self.last = np.dot(fm.PhiPsi, w)
        else:
            np.dot(fm.PhiPsi, w, out=out)
        return F1, F2, r1, r2, act

    def restart(self, z: FloatArray, F1: float, F2: float) -> None:
        """Acceleration from the equation of motion with the force F (in place)."""
        n, wa = self.n, self.wa
        wa[: 2 * n] = z[: 2 * n]
        wa[2 * n] = F1
        wa[2 * n + 1] = F2
        z[2 * n :] = np.dot(self.Ra, wa)

    # ---------------------------------------------------------------- a gap crossing zero
    def split(
        self, z: FloatArray, hs: float, th: float, d: Cut, sj: list[float], act_b: list[int], changed: list[int],
        ctx: tuple[Any, ...],
    ) -> Step:  # fmt: skip
        """The substep [t_a, t_a + hs] from ``z`` in which the contacts
        ``changed`` leave or re-enter, split at t* = t_a + th hs (h_j linearly
        interpolated to 0): the old set up to t*, a restart with the new one
        there, the active-set substep after.  ``ctx``: the active set, the
        force guess, the gaps, the time and the data at t_a."""
        o = self.opts
        act_a, guess, _, t_a, _ = ctx
        t_s = t_a + th * hs
        fm1 = step_map(self.M, self.C, self.K, self.P, th * hs, o.gamma, o.beta)
        fm2 = step_map(self.M, self.C, self.K, self.P, (1.0 - th) * hs, o.gamma, o.beta)
        d_s, sj_s = self.cut.at(self, t_s, d[0])
        F1, F2, r1, r2, _ = self.advance(z, fm1, d_s, sj_s, guess, fixed=act_a, t=t_s)
        z1 = self.last
        new = [j for j in d[0] if (j in act_b) if j in changed] + [j for j in act_a if j not in changed]
        rv = tuple(np.dot(self.Pv, z1).tolist()) if self.gd else (0.0, 0.0)
        G1, G2, _ = self.explicit_force(d_s, sorted(new), sj_s, r1, r2, test=False, rate=rv, t=t_s)
        self.restart(z1, G1, G2)
        self.located += 1
        out = self.advance(z1, fm2, d, sj, (G1, G2), t=t_a + hs)
        return (self.last,) + out

    def relocate(
        self, z_a: FloatArray, step: Step, changed: list[int], hs: float, fm: StepMap, d: Cut, sj: list[float],
        ctx: tuple[Any, ...],
    ) -> Step:  # fmt: skip
        """The (sub)step from ``z_a`` that gave ``step`` changed the contacts
        in action (``changed``): redone split at the instant h_j = 0 (linear
        in the step), or restarted at its start when the change is there
        (``ctx`` as in :meth:`split`)."""
        _, F1, F2, r1, r2, act = step
        n1, n2 = d[5], d[6]
        act_prev, _, h_prev, t_a, prev = ctx
        th = 1.0
        for j in changed:
            hb = n1[j] * r1 + n2[j] * r2 + sj[j]
            if h_prev[j] != hb:
                th = min(th, h_prev[j] / (h_prev[j] - hb))
        if 1e-6 < th < 1.0 - 1e-6:
            return self.split(z_a, hs, th, d, sj, act, changed, ctx)
        if th <= 1e-6:
            # the change happened at t_a itself (a tooth entering the arc with
            # h = 0 to round-off, e.g. at phi = 0 in a periodic motion): restart
            # there with the new set and redo the step
            d_prev, sj_prev, ra_prev, rv_prev = prev
            keep = [j for j in act_prev if j not in changed]
            new = sorted(keep + [j for j in changed if j in act])
            G1, G2, _ = self.explicit_force(
                d_prev, new, sj_prev, ra_prev[0], ra_prev[1], test=False, rate=rv_prev, t=t_a
            )
            z_a = z_a.copy()
            self.restart(z_a, G1, G2)
            out = self.advance(z_a, fm, d, sj, (G1, G2), t=t_a + hs)
            self.located += 1
            return (self.last,) + out
        return step
