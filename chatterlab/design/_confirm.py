"""The time domain confirms an active damper's co-design: the cut at the
optimised gains and at 1.1 times the old (uncontrolled) limit, on the closed
loop with the actuators as its second coupling term.

The loop (:class:`chatterlab.process.ClosedLoop` with its
:class:`chatterlab.process.Actuators`) is

    M q'' + (C - D_V) q' + (K - D_P) q = f_0 + D_O q(t - T) + B f_a,
    f_a = -G(s) y,  y = S q,  G(s) = (g_P + s g_V + g_O e^{-s T_a}) / (1 + s tau),     (1)

two delays (the cut's T, the actuator's T_a) and a first-order lag per
bandwidth.  :func:`chatterlab.time.simulate` integrates the cut's loop alone
(one delay, no actuator), so the confirmation integrates (1) itself with the
public Newmark solver (:func:`chatterlab.time.newmark` on a
:class:`chatterlab.time.ConstantProblem`), exactly:

* a lag is a coordinate u of its own: with u = -y / (1 + tau s) the force is
  f_a = g_P u + g_V u' + g_O u(t - T_a), and u obeys tau u' + u + y = 0,
  integrated in its differentiated, second-order form
  tau u'' + u' + S q' = 0 (mass tau, damping 1, a damping coupling to q).
  The trapezoidal rule keeps the integral tau u' + u + y exactly (its
  increment is h/2 times the sum of the equation at both ends of a step), so
  the zero root the differentiation adds is never excited: u starts with
  tau u' + u + y = 0 and stays there;
* without a lag, g_P and g_V are a stiffness and a damping between the
  sensor and the force (M q'' + (C + B g_V S) q' + (K + B g_P S) q = ...);
* of the two delays the shorter is the solver's own (its delayed term, read
  by cubic Hermite interpolation) and the longer is stepped (the method of
  steps, Bellman & Cooke 1963): the run is cut into pieces of the longer
  delay, on each of which its term is a known force, read from the stored
  run at t - T_long exactly (the step divides T_long).

The run starts at rest with a step of the static cutting force (the cut's
entry).  Its sensor-side signal, the displacement the cut's delayed term
reads, gives the envelope's growth rate (:func:`chatterlab.time.growth_rate`)
and the verdict with the integrator's error (Richardson from a second run at
twice the step, :func:`chatterlab.time._signals.time_verdict`), compared with
the rightmost characteristic root of the same loop
(:func:`chatterlab.frequency.characteristic_roots`, the exact delays,
searched in the chatter band: up to twice the highest chatter frequency of
the lobes before and after the design, where the regenerative motion's
decay is decided; a root further up, of a mode the cut hardly moves, is not
compared).  The
number of roots right of the axis is counted by the argument principle
(:func:`chatterlab.frequency.rhp_count`, or with two delays
:func:`chatterlab.lobes._verification.multi_delay_count`, whose phase is
sampled, not proven).  The verdict is "stable" only when that count is 0 and
proven, the rightmost root left of the axis and the time domain not against
it; "unstable" when a root right of the axis was found; else "undetermined".
The actuator's force f_a(t) -- with its bandwidth and delay, as the run
computes it -- is compared with its force limit.

References
----------
.. [1] R. Bellman, K. L. Cooke, *Differential-Difference Equations*,
   Academic Press 1963, ch. 3 (the method of steps).
.. [2] N. M. Newmark, "A method of computation for structural dynamics",
   J. Eng. Mech. Div. ASCE 85(EM3) (1959) 67-94.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError, UnitWarning, check_width
from ..process._loop import closed_loop_unwarned

__all__ = ["ActiveConfirmation", "confirm_loop"]

#: steps per period of the highest relevant root at the *check* run's (coarser) step
STEPS_PER_PERIOD = 20
#: the run's budget of steps (main run; the check run takes half as many)
MAX_STEPS = 400_000


@dataclass(frozen=True)
class ActiveConfirmation:
    """The time-domain confirmation of a controlled cut (module docstring).

    Attributes
    ----------
    verdict : {"stable", "unstable", "undetermined"}
        "stable" only when the argument principle proves no root right of
        the axis and neither the roots nor the run say otherwise.
    reason : str
        One line: why that verdict.
    speed, delay, width : float
        The cut checked (process unit, s, m).
    old_width : float
        The old (uncontrolled) limit, m; ``width / old_width`` the factor.
    abscissa, root_hz : float
        The rightmost characteristic root of the controlled loop: real part
        (1/s) and frequency (Hz).
    roots_converged : bool
    rhp_count : int
        Roots right of the axis by the argument principle (-1: not counted).
    count_proven : bool
        Every phase increment bounded (one delay); False when sampled.
    count_message : str
    rate, rate_error : float
        The run's envelope growth rate and its error bar (2 fit standard
        errors + Richardson's step error), 1/s.
    time_class : str
        :class:`chatterlab.time._signals.TimeVerdict` class of the run.
    rate_agrees : bool
        |rate - abscissa| within the error bar: the run decays at the
        rightmost root's rate.
    step, duration : float
        The main run's step and length, s.
    forces : tuple of float
        Each actuator's largest |f_a(t)| over the run, N.
    force_limits : tuple of float
        Each actuator's limit, N (inf: none).
    time_message : str
    """

    verdict: str
    reason: str
    speed: float
    delay: float
    width: float
    old_width: float
    abscissa: float
    root_hz: float
    roots_converged: bool
    rhp_count: int
    count_proven: bool
    count_message: str
    rate: float
    rate_error: float
    time_class: str
    rate_agrees: bool
    step: float
    duration: float
    forces: tuple[float, ...]
    force_limits: tuple[float, ...]
    time_message: str

    @property
    def force_ok(self) -> bool:
        """Every actuator's largest force within its limit."""
        return all(f <= lim for f, lim in zip(self.forces, self.force_limits, strict=True))

    def lines(self, speed_unit: str = "") -> list[str]:
        """The confirmation as summary lines."""
        fac = self.width / self.old_width if self.old_width > 0 else math.inf
        u = f" {speed_unit}" if speed_unit else ""
        out = [
            f"  time-domain confirmation at {self.width * 1e3:.4g} mm ({fac:.3g} x the old limit"
            f" {self.old_width * 1e3:.4g} mm), {self.speed:.6g}{u}: {self.verdict.upper()} ({self.reason})",
            f"    rightmost root of the controlled loop {self.abscissa:+.5g} 1/s at {self.root_hz:.5g} Hz;"
            f" argument principle: {self.rhp_count} root(s) right of the axis"
            f" ({'proven' if self.count_proven else 'sampled, not proven'})",
        ]
        if math.isfinite(self.rate):
            out.append(
                f"    run of {self.duration:.4g} s at h = {self.step:.3g} s: envelope rate {self.rate:+.5g}"
                f" +- {self.rate_error:.2g} 1/s ({self.time_class};"
                f" {'agrees with' if self.rate_agrees else 'differs from'} the rightmost root)"
            )
        else:
            out.append(f"    run: {self.time_message}")
        for k, (f, lim) in enumerate(zip(self.forces, self.force_limits, strict=True)):
            tail = (
                f" (limit {lim:.4g} N: {'inside' if f <= lim else 'EXCEEDED'})"
                if math.isfinite(lim)
                else " (no limit)"
            )
            out.append(f"    actuator {k + 1}: largest force in the run {f:.4g} N" + tail)
        return out


def _augmented(loop: Any) -> dict[str, Any]:
    """The matrices of (1) on (q, u): M, C, K, the delayed matrices and
    delays ``[(G, tau), ...]``, the static force, the rows that give each
    actuator's force ``f = Fq x + Fv x' + Fd x(t - T_a)`` and the signal row."""
    acts = loop.actuators
    n = loop.M.shape[0]
    lagged = [k for k in range(acts.m) if acts.lag[k] > 0] if acts is not None else []
    N = n + len(lagged)
    M, C, K = (np.zeros((N, N)) for _ in range(3))
    M[:n, :n] = loop.M
    C[:n, :n] = loop.C - loop.DV
    K[:n, :n] = loop.K - loop.DP
    G_cut = np.zeros((N, N))
    G_cut[:n, :n] = loop.DO
    m = acts.m if acts is not None else 0
    Fq, Fv, Fd = np.zeros((m, N)), np.zeros((m, N)), np.zeros((m, N))
    G_act: dict[float, np.ndarray] = {}
    if acts is not None:
        for k in range(m):
            B, S = acts.B[:, k], acts.S[k]
            P, V, O, Ta = float(acts.P[k]), float(acts.V[k]), float(acts.O[k]), float(acts.delay[k])
            if Ta == 0.0:  # an undelayed g_O is a proportional gain
                P, O = P + O, 0.0
            if k in lagged:
                i = n + lagged.index(k)
                M[i, i], C[i, i] = float(acts.lag[k]), 1.0
                C[i, :n] = S
                col = np.zeros(N)
                col[i] = 1.0
                Fq[k], Fv[k], Fd[k] = P * col, V * col, O * col
            else:
                row = np.zeros(N)
                row[:n] = S
                Fq[k], Fv[k], Fd[k] = -P * row, -V * row, -O * row
            Bf = np.zeros(N)
            Bf[:n] = B
            K -= np.outer(Bf, Fq[k])
            C -= np.outer(Bf, Fv[k])
            if O != 0.0:
                G_act.setdefault(Ta, np.zeros((N, N)))
                G_act[Ta] += np.outer(Bf, Fd[k])
    delays = [(G_cut, float(loop.delay))] if np.any(loop.DO) else []
    delays += [(G, Ta) for Ta, G in G_act.items()]
    f0 = np.zeros(N)
    f0[:n] = loop.force
    # the signal: what the cut's delayed term reads (its strongest direction)
    _, _, vt = np.linalg.svd(loop.Dl_O if np.any(loop.Dl_O) else loop.Dl_P)
    sig = np.zeros(N)
    sig[:n] = vt[0] @ loop.J
    act_delay = np.array([float(acts.delay[k]) if acts.O[k] != 0 else 0.0 for k in range(m)])
    return {"M": M, "C": C, "K": K, "delays": delays, "f0": f0, "Fq": Fq, "Fv": Fv, "Fd": Fd,
            "act_delay": act_delay, "signal": sig}  # fmt: skip


def _run(sysm: dict[str, Any], h: float, duration: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """(t, signal(t), forces (m, n_t), status) of (1) from rest with the step
    of the static force: the shorter delay the solver's, the longer stepped."""
    from ..time import ConstantProblem, newmark

    M, C, K, f0 = sysm["M"], sysm["C"], sysm["K"], sysm["f0"]
    N = M.shape[0]
    ds = sorted(sysm["delays"], key=lambda d: d[1])
    native = ds[0] if ds else None
    stepped = ds[1] if len(ds) > 1 else None
    cols = sorted(
        {int(j) for G, _ in ds for j in np.nonzero(np.any(G != 0, axis=0))[0]}
        | {
            int(j)
            for F in (sysm["Fq"], sysm["Fv"], sysm["Fd"])
            for j in np.nonzero(np.any(F != 0, axis=0))[0]
        }
        | {int(j) for j in np.nonzero(sysm["signal"])[0]}
    )
    sel = np.zeros((len(cols), N))
    sel[np.arange(len(cols)), cols] = 1.0
    seg = stepped[1] if stepped is not None else duration
    n_seg = max(int(round(seg / h)), 1)
    ts: list[np.ndarray] = []
    qs: list[np.ndarray] = []
    vs: list[np.ndarray] = []
    q0, v0 = np.zeros(N), np.zeros(N)
    t0, status = 0.0, "ok"
    total = int(round(duration / h))
    done = 0
    while done < total:
        k = min(n_seg, total - done)
        t_all = np.concatenate(ts) if ts else np.zeros(0)
        q_all = np.concatenate(qs, axis=1) if qs else np.zeros((len(cols), 0))

        def past(
            t: np.ndarray, lag: float, t_all: np.ndarray = t_all, q_all: np.ndarray = q_all
        ) -> np.ndarray:
            """x(t - lag) on the stored run (zero before t = 0), (len(t), N)."""
            out = np.zeros((np.size(t), N))
            if t_all.size:
                tt = np.asarray(t, float) - lag
                for i, c in enumerate(cols):
                    out[:, c] = np.where(tt >= -1e-12 * h, np.interp(tt, t_all, q_all[i], left=0.0), 0.0)
            return out

        force: Any = f0
        if stepped is not None:
            Gs, Ts = stepped

            def force(t: np.ndarray, Gs: np.ndarray = Gs, Ts: float = Ts, past: Any = past) -> np.ndarray:
                return f0[None, :] + past(t, Ts) @ Gs.T

        hist = None
        if native is not None and t_all.size:
            Tn = native[1]
            keep = t_all >= t0 - Tn - 4 * h
            tq = t_all[keep]
            hq = np.zeros((tq.size, N))
            hq[:, cols] = q_all[:, keep].T
            hist = (tq, hq)
        prob = ConstantProblem(M, C, K, force, *(native if native is not None else (None, None)))
        last: dict[str, np.ndarray] = {}

        def keep_state(t: float, q: np.ndarray, v: np.ndarray, a: np.ndarray, last: dict = last) -> None:
            last["q"], last["v"] = q, v

        res = newmark(
            prob, (t0, t0 + k * h * (1 + 1e-12)), h, q0, v0, outputs=sel, history=hist, callback=keep_state
        )
        if res.status != "ok":
            status = res.status
            break
        sl = slice(1, None) if ts else slice(None)  # the piece's first step is the last one's end
        ts.append(res.t[sl])
        qs.append(res.q[:, sl])
        vs.append(res.v[:, sl])
        # the next piece starts from the last state (the one-step scheme restarts exactly)
        q0, v0 = last["q"], last["v"]
        t0 = float(res.t[-1])
        done += k
    t = np.concatenate(ts)
    x = np.concatenate(qs, axis=1)  # the recorded columns only: (len(cols), n_t)
    xv = np.concatenate(vs, axis=1)
    signal = sysm["signal"][cols] @ x
    forces = sysm["Fq"][:, cols] @ x + sysm["Fv"][:, cols] @ xv
    for k, Ta in enumerate(sysm["act_delay"]):
        for i, c in enumerate(cols):
            if sysm["Fd"][k, c] != 0.0:
                forces[k] += sysm["Fd"][k, c] * np.interp(t - Ta, t, x[i], left=0.0)
    return t, signal, forces, status


def _step(lam: np.ndarray, delays: list[float], T_cut: float, h_max: float | None) -> float:
    """The main run's step: its check run at twice the step keeps
    STEPS_PER_PERIOD steps per period of every relevant root (the eight
    rightmost of the band searched: a mode above it, which the cut hardly
    moves, is not resolved) and a regeneration phase error w T (w 2h)^2 / 12 of at most
    half of :data:`chatterlab.time._signals.ASYMPTOTIC_PHASE` at the
    rightmost root's frequency, and is no longer than the shorter delay."""
    from ..time._signals import ASYMPTOTIC_PHASE

    top = lam[:8]  # the rightmost, among the roots of the band searched
    w_hi = float(np.max(np.abs(top.imag))) if top.size else 1.0
    w1 = abs(float(lam[0].imag)) if lam.size else w_hi
    h2 = 2 * math.pi / (STEPS_PER_PERIOD * max(w_hi, 1e-300))
    if T_cut > 0 and w1 > 0:
        h2 = min(h2, math.sqrt(12 * 0.5 * ASYMPTOTIC_PHASE / (w1**3 * T_cut)))
    if delays:
        h2 = min(h2, min(delays))
    if h_max is not None:
        h2 = min(h2, 2 * h_max)
    return 0.5 * h2


def confirm_loop(
    frozen: Any,
    speed: float,
    width: float,
    old_width: float,
    *,
    terms: str = "pdo",
    step: float | None = None,
    duration: float | None = None,
    tol: float = 0.05,
    omega_max: float | None = None,
) -> ActiveConfirmation:
    """Confirm in the time domain that the cut of ``frozen`` (its actuators
    included) at ``width`` (m) and ``speed`` (the process's unit) is stable
    (module docstring); ``old_width`` is the uncontrolled limit it is
    compared with (m).  ``step`` and ``duration`` (s) override the rules;
    ``omega_max`` (rad/s) is the top of the band the roots are searched in
    (default 1.5 times the bare structure's certified chatter band at the
    width, :func:`chatterlab.design._controlled.bare_band`)."""
    from ..frequency import characteristic_roots, rhp_count
    from ..frequency._delay_system import loop_systems
    from ..lobes._verification import multi_delay_count
    from ..time import amplitude_spectrum, growth_rate, peaks
    from ..time._signals import GrowthEstimate, time_verdict

    width = check_width(width, "width")
    proc = frozen.model.process
    T = float(proc.delay(np.array([speed]))[0]) if proc.kind != "delay" else float(speed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnitWarning)
        loop = closed_loop_unwarned(frozen, width=width, delay=T, terms=terms)  # type: ignore[arg-type]
    acts = loop.actuators
    if acts is None:
        raise InputError(f"{frozen.model.source} has no [[actuator]]: nothing to confirm")
    # the roots in the chatter band: given, or 1.5 times the bare structure's certified one at this
    # width (the gain bound: beyond it the cut moves no root across the axis)
    if omega_max is None:
        from ._controlled import _matrices, bare_band

        omega_max = 1.5 * bare_band(_matrices(frozen, terms), width)
    roots = characteristic_roots(loop, count=8, omega_max=omega_max)
    lam = np.asarray(roots.roots, dtype=complex)
    lam = lam[np.argsort(-lam.real)]
    conv = roots.status == "converged" and lam.size > 0
    s1 = float(lam[0].real) if lam.size else math.nan
    sy = loop_systems([loop])[0]
    wc = multi_delay_count(sy) if sy.multi_delay else rhp_count(sy)
    counted = wc.status == "converged"
    sysm = _augmented(loop)
    act_T = sorted({float(t) for t in sysm["act_delay"] if t > 0})
    limits = tuple(float(x) for x in acts.force_limit)
    if len(act_T) > 1:
        return _verdict(
            "undetermined", "the actuators have different delays: the run takes one besides the cut's",
            speed, T, width, old_width, lam, conv, wc, math.nan, math.nan, "not run", False, math.nan,
            math.nan, tuple(math.nan for _ in limits), limits, "not run: more than two delays",
        )  # fmt: skip
    dl = [d for _, d in sysm["delays"]]
    in_band = lam[np.abs(lam.imag) <= omega_max * (1 + 1e-9)] if omega_max is not None else lam
    h = step if step is not None else _step(in_band, dl, T, None)
    if step is not None and dl and 2 * h > min(dl):
        raise InputError(f"step {h:g} s: the check run at twice it must not exceed the delay {min(dl):g} s")
    rate_hint = max(abs(s1), 1e-3) if math.isfinite(s1) else 1.0
    w1 = abs(float(lam[0].imag)) if lam.size else 1.0
    dur = (
        duration
        if duration is not None
        else max(10.0 / rate_hint, 3 * max(dl, default=0.0), 60 * math.pi / max(w1, 1e-300))
    )
    dur = min(dur, MAX_STEPS * h)
    long_T = max(dl, default=0.0) if len(dl) > 1 else 0.0
    if long_T > 0:  # the stepped delay a whole number of (both runs') steps
        h = long_T / (2 * math.ceil(long_T / (2 * h)))
    try:
        t, x, F, status = _run(sysm, h, dur)
        t2, x2, _, status2 = _run(sysm, 2 * h, dur)
    except InputError as exc:  # the solver's memory limits: the run is not made, the verdict says so
        return _verdict(
            "undetermined", f"not run: {exc}", speed, T, width, old_width, lam, conv, wc, math.nan, math.nan,
            "not run", False, h, 0.0, tuple(math.nan for _ in limits), limits, f"not run: {exc}",
        )  # fmt: skip
    skip = min(T, 0.2 * dur)
    if status != "ok":
        none = GrowthEstimate(math.nan, "undetermined", math.nan, "the run diverged")
        tv = time_verdict("the cut's displacement", none, None, h, 2 * h, roots=lam, diverged=True, delay=T)
    else:
        main = growth_rate(t, x, t_min=skip, tol=tol)
        check = growth_rate(t2, x2, t_min=skip, tol=tol) if status2 == "ok" else None
        m = t >= skip
        f, a = amplitude_spectrum(t[m], x[m] - np.mean(x[m]))
        fp, _ = peaks(f, a, 1, fmin=2.0 / max(t[-1] - skip, 1e-300))
        freq = float(fp[0]) if fp.size else math.nan
        certain = bool(conv and counted and wc.proven)
        tv = time_verdict("the cut's displacement", main, check, h, 2 * h, frequency=freq, tol=tol, roots=lam,
                          roots_certain=certain, delay=T)  # fmt: skip
    err = tv.fit_error + tv.step_error
    agrees = bool(math.isfinite(tv.rate) and math.isfinite(err) and abs(tv.rate - s1) <= err)
    forces = tuple(float(np.max(np.abs(F[k]))) if F.size else math.nan for k in range(acts.m))
    # the verdict: stable only when proven
    if conv and s1 > 0:
        v, why = "unstable", f"a root right of the axis, {s1:+.4g} 1/s"
    elif counted and wc.count > 0:
        v, why = "unstable", f"the argument principle counts {wc.count} root(s) right of the axis"
    elif tv.classification in ("growing", "diverged"):
        v, why = "undetermined", f"the run is {tv.classification} while the roots say stable"
    elif counted and wc.count == 0 and wc.proven and conv and s1 < 0:
        v = "stable"
        why = "no root right of the axis, proven" + (
            "; the run decays at the rightmost root's rate" if agrees else f"; the run is {tv.classification}"
        )
    else:
        what = "the count is sampled over two delays, not proven" if counted else f"no count ({wc.status})"
        v = "undetermined"
        why = f"{what}; " + (
            "the run decays at the rightmost root's rate"
            if agrees and tv.classification == "decaying"
            else f"the run is {tv.classification}"
        )
    return _verdict(v, why, speed, T, width, old_width, lam, conv, wc, tv.rate, err, tv.classification, agrees,
                    h, float(t[-1]) if t.size else 0.0, forces, limits, tv.message)  # fmt: skip


def _verdict(
    v: str, why: str, speed: float, T: float, width: float, old: float, lam: np.ndarray, conv: bool, wc: Any,
    rate: float, err: float, cls: str, agrees: bool, h: float, dur: float, forces: tuple[float, ...],
    limits: tuple[float, ...], msg: str,
) -> ActiveConfirmation:  # fmt: skip
    return ActiveConfirmation(
        verdict=v, reason=why, speed=float(speed), delay=T, width=float(width), old_width=float(old),
        abscissa=float(lam[0].real) if lam.size else math.nan,
        root_hz=abs(float(lam[0].imag)) / (2 * math.pi) if lam.size else math.nan,
        roots_converged=conv, rhp_count=int(wc.count) if wc.status == "converged" else -1,
        count_proven=bool(wc.proven), count_message=str(wc.message), rate=float(rate), rate_error=float(err),
        time_class=cls, rate_agrees=agrees, step=float(h), duration=float(dur), forces=forces,
        force_limits=limits, time_message=msg,
    )  # fmt: skip
