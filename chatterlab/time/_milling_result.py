"""The result of a milling run (:class:`MillingSimulation`) and its assembly
from the integration's buffers and the verdict."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from ._history import TimeHistory
from ._milling_setup import TWO_PI, FloatArray, _natural_frequencies
from ._milling_step import _Run
from ._milling_verdict import _analyse, _chatter_frequency

__all__ = ["MillingSimulation"]


@dataclass(frozen=True, eq=False)
class MillingSimulation(TimeHistory):
    """A milling transient: tool-point vibration, chips, forces, Poincare samples.

    Attributes
    ----------
    t : ndarray (n_t,)
        Times of the grid, s.
    x, y : ndarray (n_t,)
        Tool displacement relative to the workpiece, m.
    vx, vy : ndarray (n_t,)
        Its velocity, m/s.
    Fx, Fy : ndarray (n_t,)
        Cutting force on the tool, N.
    chip : ndarray (N, n_t)
        Chip thickness of each tooth, m (0 where the tooth does not cut); in a
        linear run the dynamic chip n_j . (r(t) - r(t - tau_j)) while in the arc.
    would_be_chip : ndarray (N, n_t)
        Eq. (2) while the tooth is in the arc [entry, exit] (negative: the tooth
        has left the material), NaN outside the arc.
    poincare_t : ndarray (n_p,)
        Times of the Poincare samples (multiples of ``sample_period``), s.
    poincare : ndarray (n_p, 4)
        Samples (x, y, vx, vy) at those times, m and m/s.
    sample_period : float
        The period of the coefficients sampled, s.
    growth_per_period : float
        ln|mu| of the dominant multiplier fitted to the Poincare samples
        (per ``sample_period``); NaN when it cannot be estimated.
    growth_error : float
        Its change when fitted to the last quarter of the run only: the
        uncertainty of the fit (not of the time step).
    growth_slope : float
        Least-squares slope of ln|s_{p+1} - s_p| over the analysed window.
    multiplier : complex
        The fitted dominant multiplier mu.
    verdict : str
        "stable", "Hopf chatter", "flip chatter" or "undetermined".
    reason : str
        Why (the rule and the numbers it used).
    chatter_frequency : float
        Largest spectral peak away from the harmonics of 1 / ``sample_period``,
        Hz (NaN when stable or undetermined).
    fraction_out_of_cut : float
        Fraction of the time a tooth is in the arc but has left the material
        (h <= 0), over the analysed window.
    """

    #: the histories shared with every time result (spectrum, growth, CSV, netCDF: TimeHistory)
    history_fields: ClassVar[dict[str, tuple[str, str]]] = {
        "x": ("m", "tool displacement x relative to the workpiece"),
        "y": ("m", "tool displacement y relative to the workpiece"),
        "vx": ("m/s", "tool velocity x"),
        "vy": ("m/s", "tool velocity y"),
        "Fx": ("N", "cutting force on the tool x"),
        "Fy": ("N", "cutting force on the tool y"),
        "chip": ("m", "chip thickness of tooth"),
    }

    t: FloatArray
    x: FloatArray
    y: FloatArray
    vx: FloatArray
    vy: FloatArray
    Fx: FloatArray
    Fy: FloatArray
    chip: FloatArray
    would_be_chip: FloatArray
    poincare_t: FloatArray
    poincare: FloatArray
    sample_period: float
    growth_per_period: float
    growth_error: float
    growth_slope: float
    multiplier: complex
    verdict: str
    reason: str
    chatter_frequency: float
    fraction_out_of_cut: float
    rpm: float
    depth: float
    feed: float
    nonlinear: bool
    steps_per_period: int
    h: float
    status: str
    message: str
    wall_time: float
    time_per_revolution: float
    attrs: dict[str, Any] = field(default_factory=dict)

    @property
    def tooth_passing_frequency(self) -> float:
        """N n / 60, Hz."""
        return float(self.attrs.get("teeth", 1)) * self.rpm / 60.0

    def file_attrs(self) -> dict[str, Any]:
        """The files' global attributes: the run's status and the cut."""
        return {
            **super().file_attrs(),
            "title": "chatterlab milling simulation",
            "rpm": float(self.rpm),
            "depth_m": float(self.depth),
            "feed_m": float(self.feed),
            "nonlinear": str(self.nonlinear),
            "verdict": self.verdict,
            "growth_per_period": float(self.growth_per_period),
        }

    def plot(self, axes: Any = None) -> Any:  # type: ignore[override]
        """Vibration, forces and the Poincare map; returns the three Axes."""
        import matplotlib.pyplot as plt

        if axes is None:
            fig = plt.figure(figsize=(10, 7), layout="constrained")
            gs = fig.add_gridspec(2, 2)
            axes = [fig.add_subplot(gs[0, 0]), fig.add_subplot(gs[1, 0]), fig.add_subplot(gs[:, 1])]
        a0, a1, a2 = axes
        a0.plot(self.t, 1e6 * self.x, lw=0.6, label="x")
        a0.plot(self.t, 1e6 * self.y, lw=0.6, label="y")
        a0.set_ylabel("tool vibration [µm]")
        a0.set_title(
            f"{self.rpm:.0f} rpm, a_p = {1e3 * self.depth:.3g} mm: {self.verdict} "
            f"(ln|mu| = {self.growth_per_period:.3g} per period)",
            fontsize=9,
        )
        a0.legend(fontsize=8)
        a1.plot(self.t, self.Fx, lw=0.6, label="Fx")
        a1.plot(self.t, self.Fy, lw=0.6, label="Fy")
        a1.set_xlabel("t [s]")
        a1.set_ylabel("cutting force [N]")
        a1.legend(fontsize=8)
        p = self.poincare
        half = p.shape[0] // 2
        c = 0 if np.ptp(p[:, 0]) >= np.ptp(p[:, 1]) else 1  # the coordinate that moves more
        a2.plot(1e6 * p[:half, c], 1e3 * p[:half, 2 + c], ".", ms=3, color="0.7", label="first half")
        a2.plot(1e6 * p[half:, c], 1e3 * p[half:, 2 + c], ".", ms=4, color="C3", label="last half")
        a2.set_xlabel(f"{'xy'[c]} at t = k T [µm]")
        a2.set_ylabel(f"{'xy'[c]}' at t = k T [mm/s]")
        a2.set_title("Poincaré samples", fontsize=9)
        a2.legend(fontsize=8)
        return axes


def _result(
    run: _Run, status: str, msg: str, done: int, per_sample: int, m: int, rpm: float, depth: float,
    feed: float, nonlinear: bool, wall: float, revolutions: float, n_total: int,
) -> MillingSimulation:  # fmt: skip
    h, off0 = run.h, run.off0
    k = done + 1
    t = h * np.arange(k)
    r = run.rbuf[off0 : off0 + k]
    rv = run.vbuf[off0 : off0 + k]
    hraw = run.hraw[:k].T.copy()
    chip = np.where(np.isnan(hraw), 0.0, np.maximum(hraw, 0.0)) if nonlinear else np.nan_to_num(hraw)
    ip = np.arange(0, k, per_sample)
    pt = np.column_stack([r[ip], rv[ip]])
    w = _natural_frequencies(run.M, run.K)
    w_pos = w[w > 0]
    w1 = float(np.min(w_pos)) if w_pos.size else TWO_PI * rpm / 60.0
    T = per_sample * h
    fc, res = _chatter_frequency(t, r[:, 0], r[:, 1], 1.0 / T)
    growth, g_err, slope, mu, verdict, reason = _analyse(pt, w1, nonlinear, fc, T, res, status == "diverged")
    if verdict not in ("Hopf chatter", "flip chatter"):
        fc = math.nan
    half = k // 2
    arc = ~np.isnan(hraw[:, half:])
    n_arc = int(np.sum(arc))
    out_frac = float(np.sum(hraw[:, half:][arc] <= 0.0)) / n_arc if n_arc and nonlinear else math.nan
    wall_rev = wall / max(done / run.n_rev, 1e-12)
    notes = [
        f"{done} steps of h = {h:.4g} s ({m} per tooth period) in {wall:.3g} s "
        f"({1e3 * wall_rev:.3g} ms per revolution)"
    ]
    if msg:
        notes.insert(0, msg)
    if run.located:
        notes.append(f"{run.located} instants where a tooth left or re-entered the material located")
    if run.active_fail:
        notes.append(f"active-set iteration not converged at {run.active_fail} points")
    if nonlinear and run.K_pass > 1 and run.deepest:
        notes.append(f"the deepest of {run.K_pass} passes set the chip at {run.deepest} points: raise passes")
    return MillingSimulation(
        t=t,
        x=r[:, 0].copy(),
        y=r[:, 1].copy(),
        vx=rv[:, 0].copy(),
        vy=rv[:, 1].copy(),
        Fx=run.F[:k, 0].copy(),
        Fy=run.F[:k, 1].copy(),
        chip=chip,
        would_be_chip=hraw,
        poincare_t=t[ip],
        poincare=pt,
        sample_period=per_sample * h,
        growth_per_period=growth,
        growth_error=g_err,
        growth_slope=slope,
        multiplier=mu,
        verdict=verdict,
        reason=reason,
        chatter_frequency=fc,
        fraction_out_of_cut=out_frac,
        rpm=rpm,
        depth=depth,
        feed=feed,
        nonlinear=nonlinear,
        steps_per_period=m,
        h=h,
        status=status,
        message="; ".join(notes),
        wall_time=wall,
        time_per_revolution=wall_rev,
        attrs={"teeth": run.N, "passes": run.K_pass, "revolutions": revolutions, "n_steps": n_total},
    )
