"""Benchmark of the probabilistic lobes (chatterlab.uncertainty, issue 24).

Run from the repository root::

    python benchmarks/bench_uncertainty.py            # about 5 minutes on 2 cores
    python benchmarks/bench_uncertainty.py --quick    # fewer samples and repeats

Everything is measured in this run, each timing repeated ``--repeat`` times
with the configurations interleaved, min and median reported, with the
1-minute load average before and after (above 0.5 on this 2-core machine:
flagged LOADED -- other processes then share the cores):

1. **samples per second** of the shaper's probabilistic diagram (its four
   Grasso cutting coefficients K3, K5, K7, K8 normal with cv 10 %; 300 work
   speeds 0.1-1 m/s, widths to 1 mm, each sample a full diagram with its
   argument-principle check, ``verify=1``) on 1 core (serial backend), on 2
   cores (loky, 2 workers) and on a 2-worker dask ``LocalCluster`` (started
   by the sweep, as ``--backend dask`` does), the three runs' samples
   checked bit-identical; the time 10 000 samples take at the measured
   rate;
2. **the saving from shared modes**: the same run with the structure shared
   between the samples (only the cut is uncertain) and rebuilt per sample,
   serial;
3. **QMC against Monte Carlo at equal error**: the RMSE of E[b_min] and of
   P(b_min < b0) for 1-DOF turning (stiffness lognormal cv 10 %, damping
   normal sd 10 %; b_min = 2 k zeta (1 + zeta) / K_f), from 32
   randomisations at n = 16 .. 16384, and the n each method needs for the
   same RMSE (log-log interpolation).

Numbers go to ``benchmarks/results/uncertainty.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

try:
    import chatterlab  # noqa: F401
except ImportError:  # run from a checkout without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import load1 as _load
from _common import loadavg

import chatterlab as cl
from chatterlab.uncertainty import InputSpace, propagate, risk

ROOT = Path(__file__).resolve().parents[1]
LOADED = 0.5
SHAPER_UNCERTAINTY = """
[uncertainty]
"coupling.cut.K3" = { distribution = "normal", cv = 0.1 }
"coupling.cut.K5" = { distribution = "normal", cv = 0.1 }
"coupling.cut.K7" = { distribution = "normal", cv = 0.1 }
"coupling.cut.K8" = { distribution = "normal", cv = 0.1 }
"""


def _stats(times: list[float], loads: list[float]) -> dict[str, Any]:
    return {
        "min_s": min(times),
        "median_s": float(np.median(times)),
        "times_s": times,
        "load_before_after": loads,
        "loaded": max(loads) > LOADED,
    }


def shaper_model(tmp: Path) -> Any:
    p = tmp / "shaper_uncertain.toml"
    p.write_text((ROOT / "studies" / "traverse_shaper" / "model.toml").read_text() + SHAPER_UNCERTAINTY)
    return cl.load_model(p)


def throughput(model: Any, samples: int, repeat: int) -> dict[str, Any]:
    """Samples per second on 1 core, 2 loky workers and a 2-worker LocalCluster."""
    v = np.linspace(0.1, 1.0, 300)
    kw = dict(width_max=1e-3, samples=samples, replicates=8, verify=1)
    configs = {"serial_1_core": {"backend": "serial"}, "loky_2_workers": {"backend": "loky", "jobs": 2},
               "dask_localcluster_2_workers": {"backend": "dask", "jobs": 2}}  # fmt: skip
    times: dict[str, list[float]] = {k: [] for k in configs}
    loads: dict[str, list[float]] = {k: [] for k in configs}
    first: dict[str, np.ndarray] = {}
    for _ in range(repeat):
        for name, c in configs.items():  # interleaved
            l0 = _load()
            t = time.perf_counter()
            r = risk(model, v, **kw, **c)
            times[name].append(time.perf_counter() - t)
            loads[name] += [l0, _load()]
            first.setdefault(name, r.samples)
    n = samples
    out: dict[str, Any] = {
        "samples": n,
        "speeds": v.size,
        "task": "shaper, K3 K5 K7 K8 normal cv 10 %, verify=1",
    }
    for name in configs:
        s = _stats(times[name], loads[name])
        s["samples_per_s_best"] = n / s["min_s"]
        s["samples_per_s_median"] = n / s["median_s"]
        s["hours_for_10000_at_median"] = 10000 / s["samples_per_s_median"] / 3600
        out[name] = s
    base = out["serial_1_core"]["median_s"]
    out["speedup_median"] = {k: base / out[k]["median_s"] for k in configs}
    out["speedup_min"] = {k: out["serial_1_core"]["min_s"] / out[k]["min_s"] for k in configs}
    out["bit_identical"] = all(
        np.array_equal(first[k], first["serial_1_core"], equal_nan=True) for k in configs
    )
    return out


def shared_modes(model: Any, samples: int, repeat: int) -> dict[str, Any]:
    """The same serial run with the structure shared and rebuilt per sample."""
    from chatterlab.structure import assemble

    v = np.linspace(0.1, 1.0, 300)
    kw = dict(width_max=1e-3, samples=samples, replicates=8, verify=1, backend="serial")
    times: dict[str, list[float]] = {"shared": [], "rebuilt": []}
    loads: dict[str, list[float]] = {"shared": [], "rebuilt": []}
    same = True
    for _ in range(repeat):
        res = {}
        for name, share in (("shared", True), ("rebuilt", False)):
            l0 = _load()
            t = time.perf_counter()
            res[name] = risk(model, v, share=share, **kw)
            times[name].append(time.perf_counter() - t)
            loads[name] += [l0, _load()]
        same &= np.array_equal(res["shared"].samples, res["rebuilt"].samples, equal_nan=True)
    one = []
    for _ in range(5):  # what a sample saves: assembly, reduction and complex modes
        t = time.perf_counter()
        assemble(model).at().complex_modes  # noqa: B018
        one.append(time.perf_counter() - t)
    out = {k: _stats(times[k], loads[k]) for k in times}
    out["samples"] = samples
    out["saving_median"] = 1 - out["shared"]["median_s"] / out["rebuilt"]["median_s"]
    out["saving_min"] = 1 - out["shared"]["min_s"] / out["rebuilt"]["min_s"]
    out["assembly_and_modes_per_sample_s"] = {"min": min(one), "median": float(np.median(one))}
    out["bit_identical"] = bool(same)
    return out


def qmc_vs_mc(quick: bool) -> dict[str, Any]:
    """RMSE against n for E[b_min] (smooth) and P(b_min < b0) (an indicator),
    and the n each method needs for the same RMSE."""
    kf, b0 = 2.0e9, 2.8e-4
    space = InputSpace.from_dict(
        {"k": {"distribution": "lognormal", "cv": 0.1}, "zeta": {"distribution": "normal", "std": 0.003, "lower": 0.0}},
        nominal={"k": 1.0e7, "zeta": 0.03},
    )  # fmt: skip

    def f(x: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        b = 2 * x["k"] * x["zeta"] * (1 + x["zeta"]) / kf
        return {"b": b, "p": (b < b0).astype(float)}

    from scipy import integrate, stats

    # the exact values (tests/test_uncertainty_oracle.py): E[b_min] from the moments of the inputs,
    # P(b_min < b0) = int F_k(b0 Kf / (2 z (1 + z))) f_z(z) dz over zeta = 0.03 +- 10 sd
    s2 = math.log1p(0.01)
    fk = stats.lognorm(math.sqrt(s2), scale=1e7 * math.exp(-0.5 * s2))
    fz = stats.truncnorm(-10.0, np.inf, loc=0.03, scale=0.003)
    p, _ = integrate.quad(lambda z: fk.cdf(b0 * kf / (2 * z * (1 + z))) * fz.pdf(z), 0.0, 0.06, epsabs=1e-12,
                          points=[0.021, 0.03, 0.039], limit=200)  # fmt: skip
    exact = {"b": 2 * 1e7 * (0.03 + 0.03**2 + 0.003**2) / kf, "p": float(p)}
    ns = 2 ** np.arange(4, 13 if quick else 15)
    reps = 32
    out: dict[str, Any] = {"n": ns.tolist(), "randomisations": reps, "exact": exact}
    for q in ("b", "p"):
        rm: dict[str, list[float]] = {}
        for method in ("mc", "qmc"):
            e = []
            for n in ns:
                run = propagate(f, space, samples=int(n) * reps, replicates=reps, seed=7, method=method)
                e.append(math.sqrt(np.mean((run.outputs[q].mean(axis=1) - exact[q]) ** 2)))
            rm[method] = e
        slope = {m: float(np.polyfit(np.log(ns), np.log(rm[m]), 1)[0]) for m in rm}
        # equal error: the RMSE Monte Carlo reaches at its largest n; the n QMC needs for it (interpolated)
        target = rm["mc"][-1]
        lq = np.log(rm["qmc"])
        n_qmc = (
            float(np.exp(np.interp(-np.log(target), -lq, np.log(ns))))
            if target >= min(rm["qmc"])
            else float("nan")
        )
        out["mean_b_min" if q == "b" else "p_b_min_below_b0"] = {
            "rmse": rm,
            "fitted_slope": slope,
            "equal_error": {"rmse": target, "n_mc": int(ns[-1]), "n_qmc": n_qmc, "ratio": ns[-1] / n_qmc},
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--samples", type=int, default=32)
    args = ap.parse_args()
    import tempfile

    repeat = 2 if args.quick else args.repeat
    samples = 16 if args.quick else args.samples
    res: dict[str, Any] = {
        "benchmark": "bench_uncertainty",
        "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "cpu_count": os.cpu_count(),
        "load_average_start": list(loadavg()),
        "loaded_threshold": LOADED,
        "repeats": repeat,
    }
    res["qmc_vs_mc"] = qmc_vs_mc(args.quick)
    with tempfile.TemporaryDirectory() as tmp:
        model = shaper_model(Path(tmp))
        risk(
            model, np.linspace(0.1, 1.0, 30), width_max=1e-3, samples=16, replicates=8, backend="serial"
        )  # warm-up
        res["throughput"] = throughput(model, samples, repeat)
        res["shared_modes"] = shared_modes(model, 16, repeat)
    res["load_average_end"] = list(loadavg())
    out = ROOT / "benchmarks" / "results" / "uncertainty.json"
    if not args.quick:
        out.write_text(json.dumps(res, indent=1) + "\n")
    t = res["throughput"]
    for k in ("serial_1_core", "loky_2_workers", "dask_localcluster_2_workers"):
        s = t[k]
        print(f"{k:30s} {s['samples_per_s_median']:6.2f} samples/s (best {s['samples_per_s_best']:.2f});"
              f" 10 000 samples: {s['hours_for_10000_at_median']:.2f} h{'  LOADED' if s['loaded'] else ''}")  # fmt: skip
    print(f"bit-identical across backends: {t['bit_identical']}; speed-up (median) {t['speedup_median']}")
    s = res["shared_modes"]
    print(f"shared modes: saving {100 * s['saving_median']:.1f} % (median), {100 * s['saving_min']:.1f} % (min);"
          f" assembly + modes {1e3 * s['assembly_and_modes_per_sample_s']['median']:.1f} ms per sample")  # fmt: skip
    for q in ("mean_b_min", "p_b_min_below_b0"):
        e = res["qmc_vs_mc"][q]
        print(
            f"{q}: slopes {e['fitted_slope']}; equal error {e['equal_error']['rmse']:.3g}: MC n ="
            f" {e['equal_error']['n_mc']}, QMC n = {e['equal_error']['n_qmc']:.0f} (x{e['equal_error']['ratio']:.0f})"
        )
    if not args.quick:
        print(f"wrote {out.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
