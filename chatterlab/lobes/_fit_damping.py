"""Identification of the process-damping coefficient C_pd from cutting tests
(docs/process-damping.md, "Identifying C_pd").

Each test is a cut at a speed V_i (delay T_i) and a width b_i, and what was
seen there: ``stable``, ``chatter``, or ``onset`` (b_i is the width at which
chatter started: a measured limit).  With process damping the model's limit
at one speed is the constant-gain limit at the gain g = C_pd / V_i, and it
rises with g; so each test has one critical coefficient

    C_i = V_i g_i*,   b_lim(T_i; g_i*) = b_i,                                 (1)

the coefficient at which the model's limit passes through the test: a
stable cut says C_pd >= C_i, a chattering one C_pd <= C_i, an onset
C_pd = C_i (up to the width's error).  g_i* is found by Brent's method on
log g with the exact damped envelope (:meth:`DampedBoundary.envelope_at`),
bracketed from the first-order change of the limit with the gain at g = 0.

The estimate is the least-squares fit in u = ln C_pd (scale free, C_pd > 0):

    S(u) = sum_onset ((u - u_i) / s_i)^2
         + sum_stable max(0, u_i - u)^2 / s_i^2 + sum_chatter max(0, u - u_i)^2 / s_i^2,   (2)

u_i = ln C_i, s_i = sigma_b / (b_i |d ln b_lim / d ln g|) the width's error
mapped to u (sigma_b: the row's ``sigma``, else 2 % of b_i).  The violated
inequalities of the cut tests enter as one-sided residuals.  The minimiser
is unique when any onset or violated test is present, and its standard error
is the Gauss-Newton one, 1 / sqrt(sum of the active weights), scaled by
sqrt(S / (n - 1)) when the residuals say the errors are larger than assumed;
when only consistent cut tests are given, S = 0 on the whole interval
[max stable C_i, min chatter C_i], which is reported (the estimate is its
geometric mean; the data say no more).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..io import Result
from ..io._files import note_input

__all__ = ["DampingFit", "fit_process_damping", "read_cuts", "RESULTS"]

#: what a test row can say
RESULTS = ("stable", "chatter", "onset")
#: the relative error of a width when the file gives none
DEFAULT_SIGMA = 0.02


@dataclass(frozen=True, eq=False)
class DampingFit(Result):
    """The fitted process-damping coefficient and what each test says.

    Attributes
    ----------
    C_pd : float
        The estimate, N/m.
    std : float
        Its standard error, N/m (first order: C_pd times the error of ln C_pd;
        nan when only consistent cut tests bound it).
    interval : tuple of float
        (lower, upper), N/m: the 95 % interval exp(ln C_pd +- 1.96 s) with
        onsets or violated tests; the interval the cut tests leave open
        otherwise (inf: no chattering cut bounds it from above).
    speed, width, result : ndarray
        The tests (speed in the process's unit, width m, what was seen).
    critical : ndarray
        C_i of Eq. (1), N/m (0: the cut is below the limit without any process
        damping; inf: no coefficient makes it stable below the width ceiling).
    consistent : ndarray of bool
        The test agrees with the estimate (a stable cut with C_i <= C_pd, a
        chattering one with C_i >= C_pd; an onset with |ln C_i - ln C_pd| <= 1.96 s_i,
        its width's error mapped to ln C: within its 95 % interval).
    model : str
    """

    C_pd: float
    std: float
    interval: tuple[float, float]
    speed: np.ndarray
    width: np.ndarray
    result: np.ndarray
    critical: np.ndarray
    consistent: np.ndarray
    model: str
    speed_unit: str = ""
    meta: dict[str, Any] = field(default_factory=dict)

    def summary(self) -> str:
        lo, hi = self.interval
        n = self.speed.size
        bad = int(np.sum(~self.consistent))
        head = f"process damping fitted to {n} test(s) of {self.model}"
        if math.isfinite(self.std):
            est = f"  C_pd = {self.C_pd:.6g} N/m, standard error {self.std:.3g} N/m; 95 % interval {lo:.6g} .. {hi:.6g} N/m"
        else:
            est = f"  C_pd = {self.C_pd:.6g} N/m: the cut tests bound it to {lo:.6g} .. {hi:.6g} N/m"
        lines = [head, est]
        lines.append(
            f"  {n - bad} of {n} tests agree with it"
            + (f"; {bad} contradict it (see the table: measurement or model error)" if bad else "")
        )
        return "\n".join(lines)

    def table(self) -> str:
        rows = [f"{'speed':>12} {'width mm':>10} {'result':>8} {'critical C_pd N/m':>18} agrees"]
        for v, b, r, c, ok in zip(
            self.speed, self.width, self.result, self.critical, self.consistent, strict=True
        ):
            rows.append(f"{v:12.6g} {b * 1e3:10.5g} {r:>8} {c:18.6g} {'yes' if ok else 'NO'}")
        return "\n".join(rows)

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """``(coords, data, attrs)``: one row per test, the estimate as attributes."""
        coords = {"test": (np.arange(self.speed.size, dtype=float), "1", "test number")}
        data = {
            "speed": (self.speed, self.speed_unit, "speed of the test"),
            "width": (self.width, "m", "width of cut b (milling: axial depth a_p)"),
            "result": (
                np.array([RESULTS.index(r) for r in self.result], float),
                "1",
                "0 stable, 1 chatter, 2 onset",
            ),  # fmt: skip
            "critical_C_pd": (
                self.critical,
                "N/m",
                "C_pd at which the model's limit passes through the test",
            ),
            "consistent": (self.consistent.astype(float), "1", "1: the test agrees with the estimate"),
        }
        attrs = {
            "title": "chatterlab process-damping fit",
            "model": self.model,
            "C_pd": self.C_pd,
            "C_pd_std": self.std,
            "C_pd_lower": self.interval[0],
            "C_pd_upper": self.interval[1],
            "C_pd_units": "N/m",
            **{k: v for k, v in self.meta.items() if isinstance(v, int | float | str)},
        }
        return coords, data, attrs


def read_cuts(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The tests of a CSV file (docs/process-damping.md, "The tests file"):
    a header with ``speed``, ``width_mm``, ``result`` and optionally
    ``sigma_mm``; ``#`` starts a comment.  Returns speed (as written, the
    process's unit), width (m), result, sigma (m, nan where not given)."""
    p = Path(path)
    note_input(p)  # an input of the running command: never one of its outputs
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{p}: file not found; check the path") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{p}: cannot be read as a text CSV file ({exc.__class__.__name__})") from None
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise InputError(f"{p}: no tests; write a header speed,width_mm,result and one row per cut")
    rows = list(csv.reader(lines))
    head = [h.strip() for h in rows[0]]
    need = ("speed", "width_mm", "result")
    for h in need:
        if h not in head:
            raise InputError(
                f"{p}: the header has no '{h}' column (it has {', '.join(head)}); write speed,width_mm,result[,sigma_mm]"
            )
    extra = set(head) - {*need, "sigma_mm"}
    if extra:
        raise InputError(
            f"{p}: unknown column(s) {', '.join(sorted(extra))}; the columns are speed, width_mm, result, sigma_mm"
        )
    idx = {h: head.index(h) for h in head}
    speed, width, result, sigma = [], [], [], []
    for k, r in enumerate(rows[1:], start=2):
        if len(r) != len(head):
            raise InputError(f"{p}: row {k} has {len(r)} fields, the header {len(head)}")
        try:
            v = float(r[idx["speed"]])
            b = float(r[idx["width_mm"]])
            s = float(r[idx["sigma_mm"]]) if "sigma_mm" in idx and r[idx["sigma_mm"]].strip() else math.nan
        except ValueError:
            raise InputError(
                f"{p}: row {k}: speed, width_mm and sigma_mm must be numbers ({', '.join(r)})"
            ) from None
        res = r[idx["result"]].strip().lower()
        if res not in RESULTS:
            raise InputError(f"{p}: row {k}: result must be stable, chatter or onset (got {res!r})")
        if not (math.isfinite(v) and v > 0):
            raise InputError(f"{p}: row {k}: speed must be a number > 0 (got {v:g})")
        if not (math.isfinite(b) and b > 0):
            raise InputError(f"{p}: row {k}: width_mm must be a number > 0 (got {b:g})")
        if not (math.isnan(s) or (math.isfinite(s) and s > 0)):
            raise InputError(f"{p}: row {k}: sigma_mm must be > 0 or empty (got {s:g})")
        speed.append(v)
        width.append(b * 1e-3)
        result.append(res)
        sigma.append(s * 1e-3)
    if not speed:
        raise InputError(f"{p}: the header is there but no test row follows it")
    return np.array(speed), np.array(width), np.array(result), np.array(sigma)


def fit_process_damping(
    model: Any,
    speeds: Any,
    widths: Any,
    results: Any,
    *,
    sigma: Any = None,
    position: float | None = None,
    width_max: float | None = None,
) -> DampingFit:
    """Fit C_pd (N/m) of ``model`` to cutting tests (module docstring).

    Parameters
    ----------
    model : Model
        The machine with its ``[process]`` (turning, shaping or milling by
        ZOA) and, for turning, ``[machine] workpiece_diameter``; its own
        ``[process_damping]`` (if any) gives the coupling and the normal,
        not the coefficient.
    speeds : array
        The tests' speeds in the process's unit (rpm, or m/s for a shaper).
    widths : array
        The tests' widths of cut (milling: axial depth), m.
    results : array of str
        ``"stable"``, ``"chatter"`` or ``"onset"`` for each test.
    sigma : array, optional
        Standard deviation of each width, m (nan or None: 2 % of the width).
    width_max : float, optional
        The ceiling of the limits searched, m (default: twice the widest test).
    """
    from ..structure._assembly import assemble
    from ._damped import DampedBoundary

    v = np.atleast_1d(np.asarray(speeds, dtype=float))
    b = np.atleast_1d(np.asarray(widths, dtype=float))
    res = np.atleast_1d(np.asarray(results, dtype=str))
    if not (v.shape == b.shape == res.shape) or v.ndim != 1 or v.size == 0:
        raise InputError("speeds, widths and results must be 1-D arrays of the same, non-zero length")
    bad = sorted(set(res.tolist()) - set(RESULTS))
    if bad:
        raise InputError(f"results must be stable, chatter or onset (got {', '.join(bad)})")
    if not np.all(np.isfinite(b) & (b > 0)):
        raise InputError("every width must be a finite number > 0 (m)")
    s = np.full(v.size, np.nan) if sigma is None else np.broadcast_to(np.asarray(sigma, dtype=float), v.shape)
    s = np.where(np.isfinite(s) & (s > 0), s, DEFAULT_SIGMA * b)
    proc = model.process
    if proc is None or proc.kind == "delay":
        raise InputError(
            f"{model.source}: fitting C_pd needs a [process] of kind turning, shaping or milling"
        )
    if model.process_damping is None or model.process_damping.C_pd == 0.0:
        model = model.with_parameter("process_damping.C_pd", 1.0)  # the term's structure; C_pd is fitted
    T = np.asarray(proc.delay(v), dtype=float)
    ceiling = float(width_max) if width_max is not None else 2.0 * float(b.max())
    over = np.nonzero(b >= ceiling)[0]
    if over.size:  # its critical coefficient would be the ceiling's, not the test's
        k = int(over[0])
        raise InputError(
            f"test {k + 1}: its width {b[k] * 1e3:.4g} mm is not below the width ceiling {ceiling * 1e3:.4g} mm"
            " of the limits searched; raise the ceiling (--width-max) above the widest test"
        )
    bd = DampedBoundary(assemble(model).at(position), width_max=ceiling)
    V = np.asarray(bd.term.speed(T), dtype=float)
    g_star, slope = _critical_gains(bd, T, b)
    crit = g_star * V  # C_i, N/m
    with np.errstate(divide="ignore", invalid="ignore"):
        su = s / (b * slope)  # the width's error in ln C
    with np.errstate(divide="ignore"):  # C_i = 0 (below the limit undamped): ln C_i = -inf, one-sided
        u = np.log(crit)
    est, std, interval = _estimate(u, su, res)
    C = float(np.exp(est))
    with np.errstate(divide="ignore", invalid="ignore"):  # an onset: C_i = C_pd within its 95 % interval
        onset_ok = np.abs(u - est) <= 1.96 * su
    consistent = np.where(
        res == "stable", crit <= C * (1 + 1e-9), np.where(res == "chatter", crit >= C * (1 - 1e-9), onset_ok)
    )
    return DampingFit(
        C_pd=C,
        std=float(C * std),
        interval=(float(interval[0]), float(interval[1])),
        speed=v,
        width=b,
        result=res,
        critical=crit,
        consistent=np.asarray(consistent, bool),
        model=str(model.source),
        speed_unit=str(proc.speed_unit),
        meta={"width_max": ceiling, "cells": len(bd.cells)},
    )


def _critical_gains(bd: Any, T: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """g_i* of Eq. (1) per test (0 where the width is below the limit without
    damping, inf where no gain lifts the limit above it below the ceiling), and
    d ln b_lim / d ln g there."""
    from scipy.optimize import brentq

    from ._envelope import Boundary as ConstantBoundary

    b0 = ConstantBoundary(None, width_max=bd.width_max, plant=bd.plant).envelope(T)[0]
    g = np.zeros(T.size)
    slope = np.full(T.size, np.nan)
    for i in range(T.size):
        if b[i] <= b0[i]:
            continue  # stable without any process damping: no information on C_pd

        def f(u: float, i: int = i) -> float:
            lim = float(bd.envelope_at(T[i : i + 1], np.array([math.exp(u)]))[0][0])
            return math.log(lim) - math.log(b[i]) if math.isfinite(lim) else 50.0

        u_hi = math.log(_first_guess(bd, T[i], b[i], b0[i]))
        while f(u_hi) < 0:
            u_hi += math.log(4.0)
            if u_hi > 200:
                g[i] = np.inf
                break
        if np.isinf(g[i]):
            continue
        u_lo = u_hi - math.log(4.0)
        while f(u_lo) > 0:
            u_lo -= math.log(4.0)
        u = brentq(f, u_lo, u_hi, xtol=1e-12, rtol=1e-12)
        g[i] = math.exp(u)
        h = 1e-3
        slope[i] = (f(u + h) - f(u - h)) / (2 * h)
    return g, slope


def _first_guess(bd: Any, T: float, b: float, b0: float) -> float:
    """A gain of the right size: the first-order change of the limit with the
    gain at the undamped boundary point, d b / d g, reaches b - b0."""
    from ._damped import continue_at_delay
    from ._envelope import Boundary as ConstantBoundary

    cb = ConstantBoundary(None, width_max=bd.width_max, plant=bd.plant)
    bb, f, _ = cb.envelope(np.array([T]))
    g1 = 1e-6 * max(float(np.max(np.abs(bd.plant.Dl_P))), 1.0) / max(2 * np.pi * float(f[0]), 1.0)
    w1, b1, ok = continue_at_delay(bd.loop, np.array([T]), np.array([0.0]), np.array([g1]), 2 * np.pi * f, bb)
    if ok[0] and b1[0] > bb[0]:
        return max(g1 * (b - b0) / (float(b1[0]) - float(bb[0])), 1e-300)
    return 1.0


def _estimate(u: np.ndarray, su: np.ndarray, res: np.ndarray) -> tuple[float, float, tuple[float, float]]:
    """The minimiser of S(u) (Eq. 2), its standard error and the interval."""
    onset = (res == "onset") & np.isfinite(u)
    stable = (res == "stable") & np.isfinite(u)  # u = -inf (C_i = 0): no bound
    chatter = (res == "chatter") & np.isfinite(u)
    if np.any(res == "chatter") and np.any((res == "chatter") & (u == -np.inf)):
        pass  # a chattering cut below the undamped limit contradicts the model for every C_pd
    w = np.where(np.isfinite(su) & (su > 0), 1.0 / su**2, 0.0)
    lo = float(np.max(u[stable])) if np.any(stable) else -np.inf
    hi = float(np.min(u[chatter])) if np.any(chatter) else np.inf

    def S(x: float) -> float:
        r = np.sum(w[onset] * (x - u[onset]) ** 2)
        r += np.sum(w[stable] * np.maximum(0.0, u[stable] - x) ** 2)
        r += np.sum(w[chatter] * np.maximum(0.0, x - u[chatter]) ** 2)
        return float(r)

    if not np.any(onset) and lo <= hi:
        if not math.isfinite(lo):
            raise InputError(
                "the tests do not bound C_pd from below: add a stable cut above the limit without process"
                " damping, or a measured onset"
            )
        mid = lo if not math.isfinite(hi) else 0.5 * (lo + hi)
        return mid, float("nan"), (math.exp(lo), math.exp(hi))
    # S is convex and piecewise quadratic: Newton on its pieces converges in a few steps
    x = float(np.sum(w[onset] * u[onset]) / np.sum(w[onset])) if np.any(onset) else 0.5 * (lo + hi)
    for _ in range(60):
        act_s = stable & (u > x)
        act_c = chatter & (u < x)
        W = np.sum(w[onset]) + np.sum(w[act_s]) + np.sum(w[act_c])
        x_new = (np.sum(w[onset] * u[onset]) + np.sum(w[act_s] * u[act_s]) + np.sum(w[act_c] * u[act_c])) / W
        if abs(x_new - x) <= 1e-14 * max(1.0, abs(x)):
            x = float(x_new)
            break
        x = float(x_new)
    act = onset | (stable & (u > x)) | (chatter & (u < x))
    W = float(np.sum(w[act]))
    n = int(np.sum(act))
    chi2 = S(x) * (1.0 if n <= 1 else 1.0 / (n - 1))
    se = math.sqrt(max(chi2, 1.0) / W)  # never below what the widths' errors allow
    return x, se, (math.exp(x - 1.96 * se), math.exp(x + 1.96 * se))
