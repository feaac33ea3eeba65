"""Record the numerical oracle of the redesign (issue 19) from the pre-move code.

Run it once, against the commit the redesign starts from, never against the
code being changed::

    git worktree add /tmp/oracle-base 63e1fc16a90e4a3b9de2b3f1a0637b86a7739835
    PYTHONPATH=/tmp/oracle-base python benchmarks/oracle/record.py
    git worktree remove --force /tmp/oracle-base

It refuses to run when the imported chatterlab is not a clean checkout of
that commit (``--force`` overrides, for a dry run into ``--out``).  It
computes every case below through the adapters of ``tests/test_oracle.py``
(one copy: the test imports nothing from here), derives the tolerance of
every number, and writes ``tests/data/oracle/<case>.npz`` (values, and
``tol/<q>`` the absolute tolerance of each element) and
``tests/data/oracle/manifest.json`` (the commit, numpy, scipy, the cases with
their arguments and models, and for every quantity its comparison and rule).
``tests/test_oracle.py`` recomputes the cases with the current code and
compares.  The data are never re-recorded after the move.

The cases
---------
* the traverse shaper (studies/traverse_shaper/model.toml) at s = 0.85 m and
  1.1 m: lobes (b_lim, chatter frequency, lobe number on 31 speeds
  0.1-1 m/s, the minima, the band, the argument-principle checks), 7 modes
  (frequency, damping), open- and closed-loop FRF (rfe5.x/y, 57 frequencies),
  roots and verdict at four (width, speed) points (one without the delayed
  term), a 1.75 s Newmark run of case (c) (b = 2 mm, v_w = 0.5 m/s), and an
  atlas (2 positions x 7 speeds) through the sweep engine;
* the 1-DOF turning tool of tests/conftest.py (``turning_text()``: closed form
  b_min = 2 k zeta (1 + zeta) / Kf): lobes on 41 speeds, its mode, FRFs,
  roots, a Newmark run from a displaced tip at about 2 b_min, and two sweeps
  (b-lim over speed; rightmost root over width x speed);
* a random 3-DOF structure of tests/test_time_verdicts.py (``random_3dof(3)``):
  lobes over 15 delays, modes, roots;
* milling: the 1- and 2-DOF benchmarks (studies/milling) by spectral
  elements on 21 speeds (a_lim, kind Hopf/flip/fold, chatter frequency,
  critical multiplier, convergence error), the 1-DOF one also by SDM and by
  ZOA, a variable-pitch cutter (4 teeth, 70/110 deg, studies/milling_benchmark.py),
  the structural end mill (tool_cantilever.toml, reduced), Floquet
  multipliers (spectral and SDM) at three points, linear and nonlinear
  time-domain runs of the 1-DOF benchmark, and the a-lim sweep quantity;
* lobes from the tap-test FRF (studies/tap_test/tool_point.csv): turning in
  y at Kf = 1e9 N/m^2 and milling by ZOA (studies/tap_test/walkthrough.py's cut).

Tolerances (``benchmarks/oracle/tolerances.py`` computes them)
--------------------------------------------------------------
u = 2^-53, gamma(n) = 3 n u the backward error of a dense LU/QR/QZ on an n x n
problem (Higham 2002, Thm 9.4).  Each tolerance bounds the difference of two
runs (the recording and the check), so it is twice one run's error bound.
Where a computation is not a fixed sequence of operations (any BLAS, any
association of a sum), bit-for-bit equality cannot be asked; where its
result is discrete, nothing else can.  The rules, by id (the manifest repeats
them and names one per quantity):
"""

from __future__ import annotations

import argparse
import hashlib
import importlib.util
import json
import math
import platform
import subprocess
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
COMMIT = "63e1fc16a90e4a3b9de2b3f1a0637b86a7739835"
U = 2.0**-53

RULES: dict[str, str] = {
    "exact": "discrete (a verdict, count, lobe number, kind, basis, status, length) or a copy of an input: "
    "equal, element by element",
    "closed-form": "a few arithmetic operations on the inputs (a delay 60/n, the (k + 1/2)/T of a flip, a "
    "step's time): at most 16 roundings, 16 u relative, twice",
    "root": "a characteristic root refined by Newton on det Delta (stops at a step < 1e-13 |lambda|; "
    "quadratic, so the root is then at its round-off floor): 2 (1e-13 |lambda| + gamma(n) kappa), kappa = "
    "|y|^T |Delta's terms| |x| / |y^H Delta'(lambda) x| the root's componentwise condition (Tisseur 2000), "
    "x, y its null vectors; the abscissa is the first root's real part",
    "boundary": "an envelope point (b_lim, omega_c) at delay T is a root j omega_c of Delta at b_lim (root "
    "rule's kappa; for a measured FRF, Delta = I + b H(s) D(s)): round-off moves it by gamma(n) kappa and the "
    "engine returns to the axis by moving b, so db = gamma kappa / |Re ds/db|, "
    "domega = gamma kappa (1 + |Im ds/db| / |Re ds/db|); the regula falsi stops within 1e-14 omega of the "
    "crossing on the boundary curve, adding |db/domega| 1e-14 omega (slope from ds/db, ds/dT); twice",
    "boundary-minimum": "the smallest b_lim on the speed grid: the tolerance of that element (the speed "
    "compared exactly)",
    "absolute-minimum": "minimize_scalar(bounded, xatol = 1e-10 omega) locates the minimum of the boundary "
    "curve to tol2 = 2 (sqrt(eps) omega + xatol / 3): omega within 2 tol2 (+ round-off), b, flat there, "
    "within b'' tol2^2 / 2 (b'' from the curve's samples) plus the curve's round-off shift at fixed omega "
    "gamma kappa |s_T| / |Im(s_b conj s_T)|; twice",
    "band": "the top of the certified band is an edge of a geometric grid between 1e-3 w_1 and 10 |p|_max: "
    "the relative round-off of the smallest and largest poles (root rule, open loop) plus 64 u for the "
    "grid's exp/log, twice; 0 and the measured band exactly",
    "frf": "a direct solve per frequency (numpy.linalg.solve, then C_o X): |dH_ij| <= gamma(n) "
    "|Delta^-H c_i|^T |Delta's terms| |Delta^-1 b_j| (Skeel's componentwise bound, Delta = s^2 A + s B + C - "
    "D(s)), twice",
    "modes": "scipy.linalg.eigh(C, A): a perturbation |E| <= gamma(n) (|C| + lambda |A|) moves lambda_i by "
    "phi_i^T E phi_i and phi_i by sum_j phi_j phi_j^T E phi_i / (lambda_i - lambda_j) (first-order theory of "
    "the symmetric definite pencil); f = sqrt(lambda) / 2 pi, zeta = phi^T B phi / 2 omega (plus the "
    "normalisation's and the product's own gamma); twice",
    "floquet-multiplier": "a multiplier is an eigenvalue of the spectral-element pencil (V, U) of size N: "
    "gamma(N) |y|^T (|V| + |mu||U|) |x| / |y^H U x|; SDM: of the monodromy Phi, a product of `steps` step "
    "matrices: steps gamma(N) |y|^T |Phi| |x| / |y^H x|; twice.  Compared as a set per point (the order "
    "within a conjugate pair is not a result)",
    "floquet-frequency": "the chatter frequency |arg mu + 2 pi k| / 2 pi T of a multiplier: d(arg mu) = "
    "|d mu| / |mu| over 2 pi T (k exact); a flip's (k + 1/2) / T: closed-form",
    "floquet-error": "the convergence estimate |mu_p - mu_p'| (two resolutions): the round-off of both, "
    "3 x one multiplier's, twice",
    "floquet-limit": "a Hopf limit (spectral) and any SDM limit are refined by scipy.optimize.brentq "
    "(xtol = rtol a, rtol = 4 eps): 2 (rtol + 4 eps) a plus the round-off |d mu| / |d|mu|/da|, and the "
    "multiplier there moves by |d mu/da| times the stop plus |d mu|; a flip or fold limit (spectral) is the "
    "eigenvalue a of the real pencil (V0 - mu0 U0) x = -a (V1 - mu0 U1) x (mu0 = -1, +1), exact but for "
    "round-off: gamma(N) kappa(a); twice",
    "series": "a step recurrence (Newmark's average acceleration; the milling step loop): each step's "
    "solve and products have a backward error gamma(n_state) of the state, and k steps add them (the "
    "scheme does not amplify beyond the solution's own growth, carried by the running maximum "
    "Y_k = max_{j<=k} |y_j|): |dy_k| <= k gamma(n_state) Y_k, twice",
    "fit": "a quantity fitted to a recorded series (the envelope's growth rate; the multiplier fitted to "
    "Poincare samples, and its ln|mu|): first order, sum_i |df/dy_i| tol_i over the fitted samples, the "
    "gradient of the base code's fit by forward differences of 100 tol_i (checked linear against 10 tol_i), "
    "twice",
}
__doc__ = (
    (__doc__ or "")
    + "\n"
    + "\n".join(f"* ``{k}``: {v}." for k, v in RULES.items())
    + """

Not recorded: the multiplier fitted to the Poincare samples of the
converged nonlinear milling run (and its ln|mu|): the fit drops singular
values below 1e-7 of the largest, and the differences of converged samples
carry a relative round-off of that order, so the rank -- and the multiplier
-- is not fixed by the arithmetic (a perturbation at the samples' round-off
moves it by O(1)); the run's verdict and samples are recorded.  The manifest
lists such omissions per case.

Checked: ``tests/test_oracle.py`` passes on the recorded commit itself (run
it from outside the repository, ``cd /tmp && PYTHONPATH=/tmp/oracle-base
python -m pytest /work/main/tests/test_oracle.py``: from the repository's
folder ``python -m`` puts the working tree's chatterlab first) and on
a8abec0 (the FRF container, the one lobe result and the milling closed loop
already moved), each also with OpenBLAS's other kernels
(``OPENBLAS_CORETYPE=Haswell``, ``Sandybridge``, ``Prescott``: another order
of the operations in every product and factorisation) and with two
threads.  The largest |difference| / tolerance seen there: 0.28 (the
shaper's natural frequencies), 0.06 (roots), 0.04 (the shaper's Newmark
series), 0.03 (b_lim, chatter frequency, modal damping), 0.02 (milling
multipliers), below 0.01 for the rest; nothing discrete changed.  And the
tolerances bite: the lobe engine's regula falsi stopped at 1e-11 instead
of 1e-14 fails six lobe cases.
"""
)

# the derivations use the pre-move internals where noted (tolerances.py); the values all go
# through the adapters of tests/test_oracle.py


def _import(name: str, path: Path) -> Any:
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


SHAPER = "studies/traverse_shaper/model.toml"
MILL1 = "studies/milling/benchmark_1dof.toml"
MILL2 = "studies/milling/benchmark_2dof.toml"
ENDMILL = "studies/milling/tool_cantilever.toml"
TOOL_POINT = "studies/tap_test/tool_point.csv"
TURNING = "generated:turning_1dof"
RANDOM3 = "generated:random_3dof_seed3"

#: the 1-DOF milling benchmark (Insperger & Stepan 2004), as studies/milling_benchmark.py builds it
BENCH_TOOL = {"mass": 0.03993, "f_hz": 922.0, "zeta": 0.011}


def _cutter(teeth: int, immersion: float, pitch_deg: list[float] | None = None) -> dict[str, Any]:
    return {
        "teeth": teeth, "diameter": 0.02, "Kt": 6e8, "Kn": 2e8, "immersion": immersion,
        "pitch_deg": pitch_deg or [],
    }  # fmt: skip


def _lin(a: float, b: float, n: int) -> list[float]:
    return [float(x) for x in np.linspace(a, b, n)]


#: what each recorded quantity is (SI; Hz for frequencies), for the manifest
MEANING = {
    "H": "receptance H[output, input, frequency], m/N (complex)",
    "a_lim": "limit axial depth of cut per speed, m (inf: stable up to depth_max)",
    "abscissa": "rightmost real part of the characteristic roots per point, 1/s",
    "absolute_minimum_chatter_hz": "chatter frequency at the smallest boundary width over all delays, Hz",
    "absolute_minimum_width": "smallest boundary width over all delays (the low-speed asymptote), m",
    "agree": "the roots and the argument principle agree, per point",
    "b_lim": "limit width of cut per speed (or position x speed), m (inf: none below width_max)",
    "band_certified": "the loop-gain bound proves the chatter band complete",
    "band_hz": "chatter-frequency band searched, Hz",
    "basis": "what each milling limit rests on (complete, scan, zoa)",
    "certified": "depth up to which stability is established, m",
    "chatter_frequency": "chatter frequency at the limit (sweep output), Hz",
    "chatter_hz": "chatter frequency on the envelope per speed, Hz",
    "checks_agree": "each argument-principle check of the diagram agrees with it",
    "checks_rhp": "right-half-plane root count of each argument-principle check",
    "damping_ratio": "modal damping ratio phi^T B phi / 2 omega per mode",
    "delay": "delay T per speed, s",
    "error": "convergence estimate of the Floquet result (multiplier, or limit depth in m)",
    "folds": "folds of the boundary curve followed",
    "frequency": "frequency of the rightmost root (sweep output), Hz",
    "frequency_hz": "natural frequency per mode, or chatter frequency of a milling limit/multiplier, Hz",
    "growth_per_period": "ln|mu| of the multiplier fitted to the Poincare samples",
    "growth_rate": "growth rate of the first output's envelope, 1/s",
    "kind": "type of the critical multiplier: hopf, flip, fold ('' where stable); sweep: code 1/2/3",
    "lobe": "lobe number k of the envelope per speed (-1: none)",
    "minimum_chatter_hz": "chatter frequency at the smallest b_lim on the speed grid, Hz",
    "minimum_speed": "speed of the smallest b_lim on the speed grid",
    "minimum_width": "smallest b_lim on the speed grid, m",
    "mu": "the two leading Floquet multipliers per point (complex)",
    "multiplier": "critical Floquet multiplier at the limit, or the one fitted to Poincare samples (complex)",
    "n_frequencies": "frequencies of the lobe engine's grid",
    "n_lobes": "lobes crossing the speed range",
    "n_t": "recorded time steps",
    "poincare": "Poincare samples (x, y, vx, vy) once per period, m and m/s",
    "rhp_count": "right-half-plane roots by the argument principle per point (-1: not run)",
    "roots": "rightmost characteristic roots per point (upper half plane), rad/s (complex)",
    "status": "the run's status",
    "t": "times of the recorded samples, s",
    "verdict": "stability verdict per point / of the run",
    "vx": "tool velocity x at the recorded samples, m/s",
    "x": "tool displacement x at the recorded samples, m",
}


#: quantities an adapter returns that a case does not record, and why
OMITTED = {
    "mill1_simulation_nonlinear": {
        q: "the converged run's fitted multiplier is not fixed by the arithmetic: its rank decision (singular "
        "values below 1e-7 of the largest dropped) sits at the round-off of the samples' differences"
        for q in ("multiplier", "growth_per_period")
    }
}


def cases() -> list[dict[str, Any]]:
    """name, adapter, arguments (models by name: a file under studies/ or a generated one)."""
    out: list[dict[str, Any]] = []

    def add(name: str, adapter: str, **args: Any) -> None:
        out.append({"name": name, "adapter": adapter, "args": args})

    v = _lin(0.1, 1.0, 31)
    for s in (0.85, 1.1):
        add(
            f"shaper_lobes_s{s}", "lobe_diagram", model=SHAPER, speeds=v, width_max=1e-3, position=s, verify=2
        )
        add(f"shaper_modes_s{s}", "natural_modes", model=SHAPER, count=7, position=s)
    f = _lin(20.0, 300.0, 57)
    pts = ["rfe5.x", "rfe5.y"]
    add("shaper_frf_open", "response", model=SHAPER, frequency_hz=f, inputs=pts, outputs=pts, position=0.85)
    add("shaper_frf_closed", "response", model=SHAPER, frequency_hz=f, inputs=pts, outputs=pts, position=0.85,
        width=1.5e-4, speed=0.5)  # fmt: skip
    add("shaper_roots", "roots", model=SHAPER, count=3, position=0.85, points=[
        {"width": 1.0e-4, "speed": 0.5}, {"width": 3.0e-4, "speed": 0.5},
        {"width": 2.0e-4, "speed": 0.9}, {"width": 2.0e-3, "speed": 0.5, "terms": "pd"}])  # fmt: skip
    add("shaper_simulation", "simulation", model=SHAPER, outputs=["rfe5.y", "rfe5.x"],
        samples=list(range(0, 3501, 175)), feedback="pdo", width=2e-3, speed=0.5, duration=1.75, step=5e-4,
        growth_skip=0.25)  # fmt: skip
    add("shaper_atlas", "atlas", model=SHAPER, positions=[0.6, 1.1], speeds=_lin(0.1, 1.0, 7), width_max=1e-3)
    # the 1-DOF turning tool (closed form: b_min = 2 k zeta (1 + zeta) / Kf)
    add(
        "turning_lobes",
        "lobe_diagram",
        model=TURNING,
        speeds=_lin(2000.0, 12000.0, 41),
        width_max=0.02,
        verify=2,
    )
    add("turning_modes", "natural_modes", model=TURNING, count=1)
    ft = _lin(100.0, 1000.0, 46)
    add("turning_frf_open", "response", model=TURNING, frequency_hz=ft, inputs=["tip.x"], outputs=["tip.x"])
    add("turning_frf_closed", "response", model=TURNING, frequency_hz=ft, inputs=["tip.x"], outputs=["tip.x"],
        width=3.0e-4, delay=0.02)  # fmt: skip
    add("turning_roots", "roots", model=TURNING, count=3, points=[
        {"width": 2.0e-4, "delay": 0.02}, {"width": 6.0e-4, "delay": 0.02}, {"width": 1.0e-3, "speed": 5000.0}])  # fmt: skip
    add("turning_simulation", "simulation", model=TURNING, outputs=["tip.x"], samples=list(range(0, 4001, 200)),
        feedback="pdo", width=6.0e-4, delay=0.02, duration=0.4, step=1e-4, forces=False,
        q0={"tip.x": 1e-6}, history="constant", growth_skip=0.1)  # fmt: skip
    add("sweep_turning_b_lim", "swept", model=TURNING, quantity="b-lim", grid={"speed": [3000.0, 4500.0, 7000.0]},
        fixed={}, width_max=0.02)  # fmt: skip
    add("sweep_turning_root", "swept", model=TURNING, quantity="rightmost-root",
        grid={"width": [2e-4, 6e-4], "speed": [3000.0, 5000.0]}, fixed={}, width_max=0.02)  # fmt: skip
    # a random 3-DOF structure of the tests
    add("random3_lobes", "lobe_diagram", model=RANDOM3, speeds=[float(x) for x in np.geomspace(2e-3, 5e-2, 15)],
        width_max=0.02, verify=2)  # fmt: skip
    add("random3_modes", "natural_modes", model=RANDOM3, count=3)
    add("random3_roots", "roots", model=RANDOM3, count=3, points=[
        {"width": 5.0e-4, "delay": 0.01}, {"width": 2.0e-3, "delay": 0.01}])  # fmt: skip
    # milling
    rpm = _lin(5000.0, 25000.0, 21)
    add("mill1_lobes", "milling_lobes_model", model=MILL1, rpm=rpm, depth_max=0.01)
    add("mill2_lobes", "milling_lobes_model", model=MILL2, rpm=rpm, depth_max=0.01)
    add("mill1_lobes_sdm", "milling_lobes_model", model=MILL1, rpm=rpm[::4], depth_max=0.01, method="sdm")
    add("mill1_lobes_zoa", "milling_lobes_model", model=MILL1, rpm=rpm, depth_max=0.01, method="zoa")
    add("variable_pitch_lobes", "milling_lobes_cutter", tool=BENCH_TOOL,
        cutter=_cutter(4, 0.25, [70.0, 110.0, 70.0, 110.0]), rpm=_lin(6000.0, 20000.0, 8), depth_max=0.01)  # fmt: skip
    add(
        "endmill_lobes",
        "milling_lobes_model",
        model=ENDMILL,
        rpm=[20000.0, 25000.0],
        depth_max=0.05,
        reduce=True,
    )
    fpts = [{"rpm": 10000.0, "depth": 1e-3}, {"rpm": 18000.0, "depth": 2e-3}, {"rpm": 5000.0, "depth": 5e-4}]
    add("mill1_multipliers_spectral", "floquet", model=MILL1, points=fpts, method="spectral")
    add("mill1_multipliers_sdm", "floquet", model=MILL1, points=fpts, method="sdm")
    add("mill2_multipliers_spectral", "floquet", model=MILL2, points=fpts[:2], method="spectral")
    add("mill1_simulation_linear", "milling_simulation", tool=BENCH_TOOL, cutter=_cutter(2, 0.05), rpm=5000.0,
        depth=3e-3, samples=list(range(0, 8001, 400)), nonlinear=False, steps_per_period=200, revolutions=20)  # fmt: skip
    add("mill1_simulation_nonlinear", "milling_simulation", tool=BENCH_TOOL, cutter=_cutter(2, 0.05),
        rpm=10000.0, depth=1e-3, samples=list(range(0, 4001, 200)), feed=1e-4, steps_per_period=100,
        revolutions=20)  # fmt: skip
    add("sweep_mill1_a_lim", "swept", model=MILL1, quantity="a-lim", grid={"speed": [9000.0, 18000.0]}, fixed={},
        width_max=0.01)  # fmt: skip
    # measured FRF (studies/tap_test/walkthrough.py's cuts)
    rt = _lin(3000.0, 30000.0, 40)
    add("tap_turning_lobes", "measured_lobes", frf=TOOL_POINT, rpm=rt, select=["tool.y"], Kf=1.0e9,
        n_frequencies=500)  # fmt: skip
    add("tap_milling_lobes", "measured_lobes", frf=TOOL_POINT, rpm=rt, n_frequencies=500,
        milling={"teeth": 3, "diameter": 0.012, "Kt": 7.0e8, "Kn": 2.1e8, "radial_immersion": 0.5, "mode": "down"})  # fmt: skip
    return out


# ============================================================================ derivations
# adapter -> function(args, out) -> {quantity: (compare, tolerance or None, rule)}

Spec = dict[str, tuple[str, Any, str]]


def _exact(out: dict[str, Any], *names: str) -> Spec:
    return {q: ("exact", None, "exact") for q in names if q in out}


def _closed(x: Any) -> np.ndarray:
    return 2.0 * 16 * U * np.abs(np.asarray(x, float))


def derive_lobe_diagram(args: dict[str, Any], out: dict[str, Any]) -> Spec:
    fz, d = out["_frozen"], out["_diagram"]
    b, f, T = out["b_lim"], out["chatter_hz"], out["delay"]
    tb, tf = np.zeros_like(b), np.zeros_like(f)
    for i in np.nonzero(np.isfinite(b))[0]:
        loop = TOL.loop_of_frozen(fz, float(T[i]))
        tb[i], dw = TOL.boundary_tol(loop, 2 * math.pi * float(f[i]), float(b[i]), float(T[i]))
        tf[i] = dw / (2 * math.pi)
    spec: Spec = {
        "delay": ("tol", _closed(T), "closed-form"),
        "b_lim": ("tol", tb, "boundary"),
        "chatter_hz": ("tol", tf, "boundary"),
    }
    j = int(np.nanargmin(np.where(np.isfinite(b), b, np.nan))) if np.any(np.isfinite(b)) else -1
    if j >= 0:
        others = np.delete(b, j)
        assert np.all(others - b[j] > 10 * (tb[j] + np.delete(tb, j))), "minimum speed not robust"
        spec["minimum_width"] = ("tol", tb[j], "boundary-minimum")
        spec["minimum_chatter_hz"] = ("tol", tf[j], "boundary-minimum")
    am_b, am_f = out["absolute_minimum_width"], out["absolute_minimum_chatter_hz"]
    if np.isfinite(am_b):
        loop = TOL.loop_of_frozen(fz, float(T[0]))
        db, dw = TOL.absolute_minimum_tol(loop, 2 * math.pi * am_f, am_b, d.lobes)
        spec["absolute_minimum_width"] = ("tol", db, "absolute-minimum")
        spec["absolute_minimum_chatter_hz"] = ("tol", dw / (2 * math.pi), "absolute-minimum")
    spec["band_hz"] = ("tol", band_tol(fz, out["band_hz"]), "band")
    spec.update(_exact(out, "lobe", "minimum_speed", "band_certified", "checks_rhp", "checks_agree",
                       "n_frequencies", "folds", "n_lobes"))  # fmt: skip
    return spec


def band_tol(fz: Any, band: np.ndarray) -> np.ndarray:
    lam = fz.complex_modes.lam
    loop = TOL.StructLoop(fz.A, fz.B, fz.C, np.zeros((1, fz.A.shape[0])), *(np.zeros((1, 1)),) * 3)
    rel = 0.0
    for p in (lam[np.argmin(np.abs(lam))], lam[np.argmax(np.abs(lam))]):
        c = TOL.root_condition(loop, complex(p), 0.0, None)
        rel += TOL.gamma(loop.n) * c["kappa"] / abs(p)
    t = 2.0 * (rel + 64 * U) * np.abs(band)
    return np.where(band == 0.0, 0.0, t)


def derive_natural_modes(args: dict[str, Any], out: dict[str, Any]) -> Spec:
    df, dz = TOL.modes_tol(out["_frozen"], len(out["frequency_hz"]))
    return {"frequency_hz": ("tol", df, "modes"), "damping_ratio": ("tol", dz, "modes")}


def derive_response(args: dict[str, Any], out: dict[str, Any]) -> Spec:
    w = 2 * np.pi * np.asarray(args["frequency_hz"], float)
    t = TOL.frf_tol(out["_frozen"], w, args["inputs"], args["outputs"], out["_feedback"])
    return {"H": ("tol", t, "frf")}


def derive_roots(args: dict[str, Any], out: dict[str, Any]) -> Spec:
    import chatterlab as cl

    fz = out["_frozen"]
    R = out["roots"]
    tr = np.zeros(R.shape)
    for i, (p, st) in enumerate(zip(args["points"], out["_stability"], strict=True)):
        terms = p.get("terms", "pdo")
        loop = TOL.loop_of_frozen(fz, st.delay, terms)
        for k, lam in enumerate(R[i]):
            if np.isfinite(lam):
                tr[i, k] = TOL.root_tol(loop, complex(lam), float(p["width"]), st.delay)
        # the order and the cut at `count` are results: well separated from the next roots
        more = cl.stability(fz, count=R.shape[1] + 2, winding=False, **p).roots.roots
        re = np.asarray(more.real)
        assert np.allclose(more[: R.shape[1]], R[i], rtol=0, atol=float(tr[i].max()) * 10)
        gaps = np.abs(np.diff(re[: R.shape[1] + 1]))
        assert np.all(gaps > 10 * tr[i].max()), f"roots at point {i} too close to reorder: {re}"
        assert abs(out["abscissa"][i]) > 10 * tr[i, 0], "verdict at round-off"
    return {
        "roots": ("tol", tr, "root"),
        "abscissa": ("tol", tr[:, 0], "root"),
        **_exact(out, "verdict", "rhp_count", "agree"),
    }


def derive_simulation(args: dict[str, Any], out_full: dict[str, Any], out: dict[str, Any]) -> Spec:
    from chatterlab.time import growth_rate

    idx = np.asarray(args["samples"], int)
    n = out_full["_system"].at(args.get("position")).A.shape[0]
    spec: Spec = {"t": ("tol", TOL.time_tol(out_full["t"])[idx], "closed-form")}
    tols = {}
    for name in args["outputs"]:
        y = out_full[f"y:{name}"]
        tols[name] = TOL.series_tol(y, n)
        spec[f"y:{name}"] = ("tol", tols[name][idx], "series")
    first = args["outputs"][0]
    t, y = out_full["t"], out_full[f"y:{first}"]
    m = t >= t[0] + args.get("growth_skip", 0.0)
    tw = t[m]
    g = TOL.propagated(lambda yy: growth_rate(tw, yy).rate, y[m], tols[first][m])
    spec["growth_rate"] = ("tol", 2.0 * g, "fit")
    spec.update(_exact(out, "n_t", "status"))
    return spec


def _milling_point(S: Any, mill: Any, rpm: float, a: float, kind: str, mu: complex, method: str,
                   steps: int, rtol: float) -> dict[str, Any]:  # fmt: skip
    """Tolerances of one milling limit (a_lim, its multiplier, frequency, error)."""
    T = mill.period(rpm)
    if method == "sdm":
        m = TOL.sdm_multiplier_tol(S, mill, rpm, a, mu, steps)
    else:
        m = TOL.spectral_multiplier_tol(S, mill, rpm, a, mu)
    if method == "spectral" and kind in ("flip", "fold"):
        da = TOL.spectral_crossing_tol(S, mill, rpm, a, -1.0 if kind == "flip" else 1.0)
        dmu = m["dmu"]
    else:
        d_abs = abs((np.conj(mu) * m["dmu_da"]).real) / abs(mu)  # d|mu|/da
        stop = (rtol + 4 * np.finfo(float).eps) * a
        da = stop + m["dmu"] / d_abs
        dmu = m["dmu"] + abs(m["dmu_da"]) * stop
    f = 2.0 * dmu / abs(mu) / (2 * math.pi * T)
    return {"a": 2.0 * da, "mu": 2.0 * dmu, "f": f, "err": 2.0 * 3.0 * m["dmu"], "flip": kind == "flip"}


def _milling_tols(S: Any, mill: Any, rpm: list[float], out: dict[str, Any], method: str, steps: int,
                  rtol: float, prefix: str = "") -> dict[str, Any]:  # fmt: skip
    a, kind = out[prefix + "a_lim"], out[prefix + "kind"]
    f = out[prefix + "frequency_hz"] if prefix + "frequency_hz" in out else out["chatter_frequency"]
    n = len(rpm)
    ta, tm, tf, te = (np.zeros(n) for _ in range(4))
    for i in range(n):
        if not np.isfinite(a[i]):
            continue
        if method == "zoa":
            loop = TOL.loop_of_tool(S, mill)
            tau = mill.tooth_period(rpm[i])
            ta[i], dw = TOL.boundary_tol(loop, 2 * math.pi * float(f[i]), float(a[i]), tau)
            tf[i] = dw / (2 * math.pi)
            continue
        k = KIND_NAMES.get(kind[i], kind[i]) if not isinstance(kind[i], str) else kind[i]
        mu = (
            complex(out["multiplier"][i]) if "multiplier" in out else _multiplier_at(S, mill, rpm[i], a[i], k)
        )
        r = _milling_point(S, mill, rpm[i], float(a[i]), str(k), mu, method, steps, rtol)
        ta[i], tm[i], te[i] = r["a"], r["mu"], r["err"]
        tf[i] = _closed(f[i]) if str(k) in ("flip", "fold") else r["f"]
    rule = "boundary" if method == "zoa" else "floquet-limit"
    return {"a": ta, "mu": tm, "f": tf, "err": te, "rule": rule}


#: the ``kind`` codes of the milling sweep quantities (chatterlab.quantities.KIND_CODES)
KIND_NAMES = {1.0: "hopf", 2.0: "flip", 3.0: "fold"}


def _multiplier_at(S: Any, mill: Any, rpm: float, a: float, kc: str) -> complex:
    from chatterlab.frequency import multipliers

    if kc in ("flip", "fold"):
        return complex(-1.0 if kc == "flip" else 1.0)
    return complex(multipliers(S, mill, rpm, a).critical)


def derive_milling_lobes(args: dict[str, Any], out: dict[str, Any]) -> Spec:
    S, mill = out["_lead"]  # 63e1fc1: a ToolStructure and the cutter
    method = args.get("method", "spectral")
    t = _milling_tols(S, mill, args["rpm"], out, method, args.get("steps", 40), args.get("rtol", 1e-8))
    fin = np.isfinite(out["a_lim"])
    spec: Spec = {
        "a_lim": ("tol", t["a"], t["rule"]),
        "frequency_hz": ("tol", t["f"], "boundary" if method == "zoa" else "floquet-frequency"),
        **_exact(out, "kind", "basis"),
    }
    if method == "zoa":
        spec.update(_exact(out, "multiplier", "error", "certified"))
    else:
        spec["multiplier"] = ("tol", t["mu"], "floquet-multiplier")
        if method == "spectral":
            spec["error"] = ("tol", t["err"], "floquet-error")
            spec["certified"] = ("tol", np.where(fin, t["a"], 0.0), t["rule"])
        else:
            spec.update(_exact(out, "error", "certified"))
    return spec


def derive_floquet(args: dict[str, Any], out: dict[str, Any]) -> Spec:
    S, mill = out["_lead"]
    method, steps = args["method"], args.get("steps", 40)
    mu = out["mu"]
    tm = np.zeros(mu.shape)
    te, tf = np.zeros(len(args["points"])), np.zeros(len(args["points"]))
    for i, p in enumerate(args["points"]):
        for k in range(mu.shape[1]):
            if method == "sdm":
                r = TOL.sdm_multiplier_tol(S, mill, p["rpm"], p["depth"], complex(mu[i, k]), steps)
            else:
                r = TOL.spectral_multiplier_tol(S, mill, p["rpm"], p["depth"], complex(mu[i, k]))
            tm[i, k] = 2.0 * r["dmu"]
        # the set's elements must be farther apart than their tolerance (no ambiguous matching)
        if abs(mu[i, 0] - mu[i, 1]) <= 10 * tm[i].max():
            raise AssertionError(f"multipliers at point {i} too close to match")
        te[i] = 3.0 * tm[i, 0]
        T = mill.period(p["rpm"])
        crit = out["_results"][i].critical
        tf[i] = (
            _closed(out["frequency_hz"][i])
            if out["kind"][i] == "flip"
            else tm[i, 0] / abs(crit) / (2 * math.pi * T)
        )
    return {
        "mu": ("set", tm, "floquet-multiplier"),
        "error": ("tol", te, "floquet-error"),
        "frequency_hz": ("tol", tf, "floquet-frequency"),
        **_exact(out, "kind"),
    }


def derive_milling_simulation(args: dict[str, Any], out_full: dict[str, Any], out: dict[str, Any]) -> Spec:
    from chatterlab.time._milling_verdict import _dmd  # the base code's fit (record time only)

    r = out_full["_result"]
    idx = np.asarray(args["samples"], int)
    n_state = 2 * 1 + 2 * args["cutter"]["teeth"]  # q, q' and the delayed positions of the teeth
    tx, tv = TOL.series_tol(r.x, n_state), TOL.series_tol(r.vx, n_state)
    ty, tvy = TOL.series_tol(r.y, n_state), TOL.series_tol(r.vy, n_state)
    ip = np.searchsorted(r.t, r.poincare_t)
    assert np.array_equal(r.t[ip], r.poincare_t)
    tp = np.column_stack([tx[ip], ty[ip], tv[ip], tvy[ip]])
    m, w, z = args["tool"]["mass"], 2 * np.pi * args["tool"]["f_hz"], args["tool"]["zeta"]
    del m, z

    def fit(pt: np.ndarray) -> complex:
        s = pt.copy()
        s[:, 2:] /= w  # the base code's scaling (chatterlab.time._milling_verdict._analyse): w_1
        win = s[s.shape[0] // 2 :]
        return _dmd(np.diff(win, axis=0))

    spec: Spec = {
        "t": ("tol", TOL.time_tol(r.t)[idx], "closed-form"),
        "x": ("tol", tx[idx], "series"),
        "vx": ("tol", tv[idx], "series"),
        "poincare": ("tol", tp, "series"),
        **_exact(out, "verdict"),
    }
    if args.get("nonlinear", True):  # a converged nonlinear run: its fit is not recorded (OMITTED)
        return spec
    mu0 = fit(r.poincare)
    assert abs(mu0 - complex(r.multiplier)) <= 1e-12 * abs(mu0), "the fit is not the base code's"
    dmu = TOL.propagated(fit, r.poincare, tp)
    spec["multiplier"] = ("tol", 2.0 * dmu, "fit")
    spec["growth_per_period"] = ("tol", 2.0 * dmu / abs(mu0), "fit")
    return spec


def derive_measured_lobes(args: dict[str, Any], out: dict[str, Any]) -> Spec:
    from chatterlab.lobes import measured_plant

    h, mill = out["_frf"], out["_milling"]
    plant = measured_plant(h, Kf=args["Kf"]) if mill is None else measured_plant(h, milling=mill)
    loop = TOL.PlantLoop(plant)
    b, f, T = out["b_lim"], out["chatter_hz"], out["delay"]
    tb, tf = np.zeros_like(b), np.zeros_like(f)
    for i in np.nonzero(np.isfinite(b))[0]:
        tb[i], dw = TOL.boundary_tol(loop, 2 * math.pi * float(f[i]), float(b[i]), float(T[i]))
        tf[i] = dw / (2 * math.pi)
    j = int(np.argmin(b))
    assert np.all(np.delete(b, j) - b[j] > 10 * (tb[j] + np.delete(tb, j))), "minimum not robust"
    return {
        "delay": ("tol", _closed(T), "closed-form"),
        "b_lim": ("tol", tb, "boundary"),
        "chatter_hz": ("tol", tf, "boundary"),
        "minimum_width": ("tol", tb[j], "boundary-minimum"),
        **_exact(out, "lobe", "band_hz"),
    }


def derive_swept(args: dict[str, Any], out: dict[str, Any]) -> Spec:
    import chatterlab as cl

    m = out["_model"]
    q = args["quantity"]
    if q == "a-lim":
        from chatterlab.lobes import milling_of, tool_structure

        S, mill = tool_structure(cl.assemble(m).at()), milling_of(m)
        rpm = args["grid"]["speed"]
        t = _milling_tols(S, mill, rpm, {"a_lim": out["a_lim"], "kind": out["kind"],
                                          "chatter_frequency": out["chatter_frequency"]}, "spectral", 40, 1e-8)  # fmt: skip
        return {
            "a_lim": ("tol", t["a"], t["rule"]),
            "chatter_frequency": ("tol", t["f"], "floquet-frequency"),
            **_exact(out, "kind"),
        }
    fz = cl.assemble(m).at()
    if q == "b-lim":
        v = np.asarray(args["grid"]["speed"], float)
        b, f = out["b_lim"], out["chatter_frequency"]
        tb, tf = np.zeros_like(b), np.zeros_like(f)
        for i, s in enumerate(v):
            T = float(m.process.delay(s))
            tb[i], dw = TOL.boundary_tol(TOL.loop_of_frozen(fz, T), 2 * math.pi * f[i], b[i], T)
            tf[i] = dw / (2 * math.pi)
        return {"b_lim": ("tol", tb, "boundary"), "chatter_frequency": ("tol", tf, "boundary")}
    if q == "rightmost-root":
        W, V = args["grid"]["width"], args["grid"]["speed"]
        a, f = out["abscissa"], out["frequency"]
        ta = np.zeros_like(a)
        for i, w in enumerate(W):
            for j, s in enumerate(V):
                T = float(m.process.delay(s))
                lam = complex(a[i, j], 2 * math.pi * f[i, j])
                ta[i, j] = TOL.root_tol(TOL.loop_of_frozen(fz, T), lam, w, T)
        return {"abscissa": ("tol", ta, "root"), "frequency": ("tol", ta / (2 * math.pi), "root")}
    raise ValueError(q)


def derive_atlas(args: dict[str, Any], out: dict[str, Any]) -> Spec:
    import chatterlab as cl

    m = out["_model"]
    sy = cl.assemble(m)
    b, f = out["b_lim"], out["chatter_frequency"]
    tb, tf = np.zeros_like(b), np.zeros_like(f)
    for i, p in enumerate(args["positions"]):
        fz = sy.at(p)
        for j, s in enumerate(args["speeds"]):
            if not np.isfinite(b[i, j]):
                continue
            T = float(m.process.delay(s))
            tb[i, j], dw = TOL.boundary_tol(TOL.loop_of_frozen(fz, T), 2 * math.pi * f[i, j], b[i, j], T)
            tf[i, j] = dw / (2 * math.pi)
    return {"b_lim": ("tol", tb, "boundary"), "chatter_frequency": ("tol", tf, "boundary")}


DERIVE = {
    "lobe_diagram": derive_lobe_diagram,
    "natural_modes": derive_natural_modes,
    "response": derive_response,
    "roots": derive_roots,
    "milling_lobes_model": derive_milling_lobes,
    "milling_lobes_cutter": derive_milling_lobes,
    "floquet": derive_floquet,
    "measured_lobes": derive_measured_lobes,
    "swept": derive_swept,
    "atlas": derive_atlas,
}
#: adapters whose derivation needs the whole series (run once more with samples=None)
SERIES = {"simulation": derive_simulation, "milling_simulation": derive_milling_simulation}

TOL: Any = None


# ============================================================================ main


def _git(*args: str, cwd: Path) -> str:
    return subprocess.run(["git", *args], cwd=cwd, capture_output=True, text=True, check=True).stdout.strip()


def main(argv: list[str] | None = None) -> int:
    global TOL
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--out", type=Path, default=REPO / "tests" / "data" / "oracle")
    ap.add_argument("--force", action="store_true", help="record from any chatterlab (a dry run)")
    ap.add_argument("--only", nargs="*", default=None, help="record these cases only (a dry run)")
    a = ap.parse_args(argv)

    import scipy

    import chatterlab as cl

    base = Path(cl.__file__).resolve().parents[1]
    head = _git("rev-parse", "HEAD", cwd=base)
    dirty = _git("status", "--porcelain", "--untracked-files=no", cwd=base)
    if (head != COMMIT or dirty) and not a.force:
        print(f"chatterlab is imported from {base} at {head}{' (modified)' if dirty else ''}, not {COMMIT}: "
              "record from a clean worktree of that commit (see the docstring), or --force", file=sys.stderr)  # fmt: skip
        return 2
    TOL = _import("oracle_tolerances", HERE / "tolerances.py")
    sys.path.insert(0, str(base / "tests"))
    from conftest import turning_text  # the tests' model builders, at the recorded commit
    from test_time_verdicts import random_3dof

    sys.path.pop(0)
    adapters = _adapters()
    models: dict[str, dict[str, str]] = {}
    for name in (SHAPER, MILL1, MILL2, ENDMILL):
        models[name] = {"source": name, "text": (base / name).read_text()}
    models[TURNING] = {"source": "tests/conftest.py: turning_text()", "text": turning_text()}
    models[RANDOM3] = {"source": "tests/test_time_verdicts.py: random_3dof(3)", "text": random_3dof(3)}
    files = {TOOL_POINT: {"sha256": hashlib.sha256((base / TOOL_POINT).read_bytes()).hexdigest()}}

    a.out.mkdir(parents=True, exist_ok=True)
    entries = []
    for case in cases():
        if a.only and case["name"] not in a.only:
            continue
        t0 = time.perf_counter()
        args = adapters.resolve(case["args"], models, base)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            out = adapters.ADAPTERS[case["adapter"]](**args)
            t1 = time.perf_counter()
            if case["adapter"] in SERIES:
                full = adapters.ADAPTERS[case["adapter"]](**{**args, "samples": None})
                spec = SERIES[case["adapter"]](case["args"], full, out)
            else:
                spec = DERIVE[case["adapter"]](case["args"], out)
        omitted = OMITTED.get(case["name"], {})
        for q in omitted:
            spec.pop(q, None)
        missing = {k for k in out if not k.startswith("_")} - set(spec) - set(omitted)
        assert not missing, f"{case['name']}: no rule for {missing}"
        arrays: dict[str, np.ndarray] = {}
        quantities = {}
        for q, (mode, tol, rule) in spec.items():
            v = np.asarray(out[q])
            arrays[q] = v
            if mode != "exact":
                t = np.broadcast_to(np.asarray(tol, float), v.shape).copy()
                fin = np.isfinite(v)
                assert np.all(np.isfinite(t[fin]) & (t[fin] >= 0)), f"{case['name']}:{q} bad tolerance"
                arrays[f"tol/{q}"] = t
            what = MEANING.get(
                q, f"output {q[2:]} at the recorded samples, m" if q.startswith("y:") else None
            )
            assert what, f"no meaning for {q}"
            quantities[q] = {"what": what, "compare": mode, "rule": rule}
        fname = f"{case['name']}.npz"
        np.savez_compressed(a.out / fname, **arrays)  # type: ignore[arg-type]
        entries.append(
            {
                **case,
                "file": fname,
                "seconds": round(t1 - t0, 2),
                "quantities": quantities,
                "omitted": omitted,
            }
        )
        print(
            f"{case['name']:30s} {t1 - t0:6.2f} s compute, {time.perf_counter() - t1:6.2f} s tolerances",
            flush=True,
        )

    manifest = {
        "about": "numerical oracle of issue 19: values of the pre-move code and their derived tolerances; "
        "written by benchmarks/oracle/record.py, checked by tests/test_oracle.py (see their docstrings)",
        "commit": head,
        "clean": not dirty,
        "recorded_with": {
            "python": platform.python_version(),
            "numpy": np.__version__,
            "scipy": scipy.__version__,
            "chatterlab": cl.__version__,
            "blas": _blas(),
            "machine": platform.machine(),
        },
        "unit_roundoff": U,
        "rules": RULES,
        "models": models,
        "files": files,
        "cases": entries,
    }
    (a.out / "manifest.json").write_text(json.dumps(manifest, indent=1) + "\n")
    return 0


def _adapters() -> Any:
    return _import("oracle_adapters", REPO / "tests" / "test_oracle.py")


def _blas() -> str:
    try:
        from threadpoolctl import threadpool_info

        return "; ".join(
            f"{d.get('internal_api')} {d.get('version')} {d.get('architecture')}" for d in threadpool_info()
        )
    except Exception:  # pragma: no cover - informative only
        return "unknown"


if __name__ == "__main__":
    sys.exit(main())
