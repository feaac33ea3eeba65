"""Spindle-speed variation on the 1-DOF turning benchmark and the 1-DOF
milling benchmark: where does varying the speed raise the stability limit?

The classic finding (Sexton & Stone 1978; Insperger & Stepan 2004; Zatarain
et al. 2008; Seguy et al. 2010): a sinusoidal variation of the spindle speed
about its mean scrambles the phase between the surface left by one
revolution (tooth) and the next, which raises the limit at low speeds --
high lobe numbers, where many vibrations fit in one revolution and a few
per cent of speed is a large change of that phase -- but not at the
high-speed lobes, where the phase changes little and the constant-speed
lobe peaks are already higher than what SSV gives.

Both structures are the benchmarks of ``studies/turning_benchmark.py``
(m = 2 kg, k = 2e7 N/m, c = 400 N s/m, K_f = 2e9 N/m^2) and
``studies/milling/benchmark_1dof.toml`` (Insperger & Stepan 2004: 922 Hz,
zeta 0.011, two teeth, 5 % down-milling).  The limits are searched from the
spectral-element Floquet multipliers of the varying-delay loop
(:func:`chatterlab.frequency.ssv_multipliers`; the RVA = 0 rows are the
constant speed, which equals Tlusty's closed form for turning, tested in
tests/test_ssv.py) on a scan of widths refined by Brent's method, in
parallel through the sweep engine.

Run: ``python studies/ssv_lobes.py [--figures docs/figures]`` (prints the
limits and the gain of SSV at low and high speed; a few minutes on two
cores).

References: J. S. Sexton, B. J. Stone, Annals of the CIRP 27 (1978) 321-326;
T. Insperger, G. Stepan, J. Vib. Control 10 (2004) 1835-1855; M. Zatarain,
I. Bediaga, J. Munoa, R. Lizarralde, CIRP Annals 57 (2008) 379-384;
S. Seguy, T. Insperger, L. Arnaud, G. Dessein, G. Peigne, Int. J. Adv.
Manuf. Technol. 48 (2010) 883-895.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

import chatterlab as cl
from chatterlab.frequency import ssv_limits
from chatterlab.lobes import milling_loop_of

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _figures import figures_dir  # noqa: E402
from turning_benchmark import MODEL as TURNING  # noqa: E402

RVA = [0.0, 0.1, 0.2]


def turning(jobs: int = 2) -> Any:
    fz = cl.assemble(cl.loads_model(TURNING)).at()
    speeds = np.geomspace(1200.0, 24000.0, 40)
    return ssv_limits(
        fz, speeds, RVA, [0.5], width_max=5e-3, scan=20, rtol=1e-5, jobs=jobs,
        backend="loky" if jobs > 1 else "serial",
    )  # fmt: skip


def milling(jobs: int = 2) -> Any:
    loop = milling_loop_of(cl.assemble(cl.load_model(HERE / "milling" / "benchmark_1dof.toml")).at())
    speeds = np.linspace(5000.0, 25000.0, 41)
    return ssv_limits(
        loop, speeds, RVA[:2], [0.1], width_max=10e-3, scan=20, rtol=1e-5, jobs=jobs,
        backend="loky" if jobs > 1 else "serial",
    )  # fmt: skip


def summary(name: str, r: Any, low: float, high: float) -> str:
    """The mean gain b_lim(RVA) / b_lim(0) below ``low`` and above ``high`` (speed unit)."""
    g = r.gain()[:, :, 0]
    lines = [f"{name}: gain of SSV (b_lim / b_lim at constant speed), mean over the speeds"]
    for j, a in enumerate(r.rva):
        if a == 0:
            continue
        lo = np.nanmean(np.where(np.isfinite(g[r.speeds <= low, j]), g[r.speeds <= low, j], np.nan))
        hi = np.nanmean(np.where(np.isfinite(g[r.speeds >= high, j]), g[r.speeds >= high, j], np.nan))
        lines.append(
            f"  RVA {a:g}: {lo:.3f} at <= {low:g} {r.speed_unit}, {hi:.3f} at >= {high:g} {r.speed_unit}"
        )
    return "\n".join(lines)


def main() -> None:
    out = figures_dir(__doc__.splitlines()[0])
    t0 = time.perf_counter()
    rt = turning()
    print(rt.table())
    print(summary("turning", rt, 3000.0, 12000.0))
    rm = milling()
    print(rm.table())
    print(summary("milling", rm, 8000.0, 15000.0))
    print(f"({time.perf_counter() - t0:.0f} s)")
    if out is not None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, (a1, a2) = plt.subplots(1, 2, figsize=(12.0, 4.5))
        rt.plot(ax=a1, title="1-DOF turning benchmark, sine SSV, RVF 0.5")
        rm.plot(ax=a2, title="1-DOF milling benchmark (5 % down-milling), sine SSV, RVF 0.1")
        a1.set_xscale("log")
        fig.tight_layout()
        fig.savefig(out / "ssv_lobes.png", dpi=130)
        print(f"wrote {out / 'ssv_lobes.png'}")


if __name__ == "__main__":
    main()
