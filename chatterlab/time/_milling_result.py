"""The result of a milling run (:class:`MillingSimulation`) and its assembly
from the integration's buffers and the verdict."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from ._contact import _Contacts
from ._core import FloatArray
from ._history import TimeHistory
from ._milling_verdict import _analyse, _chatter_frequency, natural_frequencies

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
        Cutting force on the tool, N (with the flanks' of process damping
        when the run models it).
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
    attrs : dict
        The run's constants: ``teeth``, ``passes``, ``revolutions``,
        ``n_steps``, ``tooth_period`` (s) and ``process_damping``, the model
        of process damping that ran (``"none"``, ``"linear, C_pd = ..."`` or
        ``"indentation, K_sp = ..."``).
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
        """The tooth passing frequency, Hz: 1 / the process's tooth period of the run."""
        return 1.0 / float(self.attrs["tooth_period"])

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
            "process_damping": str(self.attrs.get("process_damping", "none")),
        }

    def plot(self, names: Sequence[str] | str | None = None, *, ax: Any = None, **style: Any) -> Any:
        """Without ``names``: the vibration, the cutting forces and the
        Poincare samples (:func:`chatterlab.plot._milling_time.plot_milling_run`;
        ``ax`` three Axes), returns the three Axes; with ``names``: those
        histories against time (:meth:`TimeHistory.plot`)."""
        if names is not None:
            return super().plot(names, ax=ax, **style)
        from ..plot._milling_time import plot_milling_run

        return plot_milling_run(self, ax=ax, **style)


def _result(run: Any, cut: _Contacts, status: str, reason: str, done: int, wall: float) -> MillingSimulation:
    """The :class:`MillingSimulation` of a run (``run``: what was asked,
    :class:`chatterlab.time._milling._MillingRun`) from its coupling's records
    up to step ``done``: the samples, the verdict and the message."""
    h, off0, nonlinear, mill = cut.h, cut.cut.off0, run.nonlinear, run.milling
    k = done + 1
    t = h * np.arange(k)
    r = cut.rbuf[off0 : off0 + k]
    rv = cut.vbuf[off0 : off0 + k]
    hraw = cut.hraw[:k].T.copy()
    chip = np.where(np.isnan(hraw), 0.0, np.maximum(hraw, 0.0)) if nonlinear else np.nan_to_num(hraw)
    ip = np.arange(0, k, run.per_sample)
    pt = np.column_stack([r[ip], rv[ip]])
    w = natural_frequencies(cut.M, cut.K)
    w_pos = w[w > 0]
    w1 = float(np.min(w_pos)) if w_pos.size else mill.omega(run.rpm)
    T = run.per_sample * h
    fc, res = _chatter_frequency(t, r[:, 0], r[:, 1], 1.0 / T)
    growth, g_err, slope, mu, verdict, why = _analyse(pt, w1, nonlinear, fc, T, res, status == "diverged")
    if verdict not in ("Hopf chatter", "flip chatter"):
        fc = math.nan
    half = k // 2
    arc = ~np.isnan(hraw[:, half:])
    n_arc = int(np.sum(arc))
    out_frac = float(np.sum(hraw[:, half:][arc] <= 0.0)) / n_arc if n_arc and nonlinear else math.nan
    wall_rev = wall / max(done / cut.cut.n_rev, 1e-12)
    return MillingSimulation(
        t=t,
        x=r[:, 0].copy(),
        y=r[:, 1].copy(),
        vx=rv[:, 0].copy(),
        vy=rv[:, 1].copy(),
        Fx=cut.F[:k, 0].copy(),
        Fy=cut.F[:k, 1].copy(),
        chip=chip,
        would_be_chip=hraw,
        poincare_t=t[ip],
        poincare=pt,
        sample_period=T,
        growth_per_period=growth,
        growth_error=g_err,
        growth_slope=slope,
        multiplier=mu,
        verdict=verdict,
        reason=why,
        chatter_frequency=fc,
        fraction_out_of_cut=out_frac,
        rpm=run.rpm,
        depth=run.depth,
        feed=run.feed,
        nonlinear=nonlinear,
        steps_per_period=run.steps_per_period,
        h=h,
        status=status,
        message=_message(run, cut, status, reason, done, wall, wall_rev),
        wall_time=wall,
        time_per_revolution=wall_rev,
        attrs={
            "teeth": mill.teeth,
            "passes": cut.cut.K_pass,
            "revolutions": run.revolutions,
            "n_steps": run.n_total,
            "tooth_period": mill.tooth_period(run.rpm),
            "process_damping": run.process_damping,
        },
    )


def _message(
    run: Any, cut: _Contacts, status: str, reason: str, done: int, wall: float, wall_rev: float
) -> str:
    """What the run did: its steps and cost, the instants located, the
    active-set iterations that did not settle, a chip set by the deepest pass."""
    notes = [
        f"{done} steps of h = {cut.h:.4g} s ({run.steps_per_period} per tooth period) in {wall:.3g} s "
        f"({1e3 * wall_rev:.3g} ms per revolution)"
    ]
    if status != "ok":
        notes.insert(0, reason or status)
    if cut.located:
        notes.append(f"{cut.located} instants where a tooth left or re-entered the material located")
    if cut.active_fail:
        notes.append(f"active-set iteration not converged at {cut.active_fail} points")
    if cut.flanks is not None:
        notes.append(f"{cut.flanks.land_steps(cut.h):.3g} steps across the wear land")
    if cut.flank_fail:
        notes.append(f"the flanks' fixed point not converged at {cut.flank_fail} points: take more steps")
    deepest, K_pass = cut.cut.deepest, cut.cut.K_pass
    if run.nonlinear and K_pass > 1 and deepest:
        notes.append(f"the deepest of {K_pass} passes set the chip at {deepest} points: raise passes")
    return "; ".join(notes)
