"""The indentation model of process damping in the time domain
(chatterlab.time._indentation; docs/process-damping.md, Eq. 5-6).

Oracles: at small amplitude the simulated decay rate is the rightmost
characteristic root of the linear model with C_pd = K_sp w^2 / 4 (the
frequency-domain engine, an independent route), within the linearisation's
small parameters, and its error halves when they are halved (first order);
above the linear limit the vibration is bounded: started below and above, the
amplitudes approach each other (an attracting limit cycle: finite-amplitude
stability), where the linear model grows.

The tool is the 1-DOF turning tool of studies/process_damping (m = 2 kg,
k = 2e7 N/m, c = 400 N s/m, K_f = 2e9 N/m^2) at 20000 rpm on a workpiece of
D = 0.5 mm (V = 0.52 m/s, T = 3 ms: several revolutions per decay), where at
b = 1 mm the cut without the flank chatters and with it is stable.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import chatterlab as cl
from chatterlab.errors import InputError
from chatterlab.frequency import characteristic_roots
from chatterlab.process import closed_loop
from chatterlab.structure import Structure
from chatterlab.time import growth_rate
from chatterlab.time._indentation import simulate_indentation

ROOT = Path(__file__).resolve().parents[1]
M, K, C, KF = 2.0, 2e7, 400.0, 2e9
RPM, D = 20000.0, 5e-4
T = 60.0 / RPM
V = np.pi * D * RPM / 60.0
GAMMA = math.radians(7.0)


def tool() -> Structure:
    return Structure(np.array([[M]]), np.array([[C]]), np.array([[K]]), ("x",), "tool")


def linear_root(b: float, C_pd: float) -> complex:
    """The rightmost characteristic root of the linear model (the frequency-domain engine)."""
    model = cl.load_model(ROOT / "studies/process_damping/turning.toml")
    model = model.with_parameter("machine.workpiece_diameter", D).with_parameter("process_damping.C_pd", C_pd)
    return complex(
        characteristic_roots(closed_loop(cl.assemble(model).at(), width=b, speed=RPM), count=3).roots[0]
    )


def run(b: float, C_pd: float, w: float, v0: float, t_end: float):
    K_sp = 4.0 * C_pd / w**2  # Eq. 6: C_pd = K_sp w^2 / 4
    h = w / V / 8  # eight steps across the land (the area's samples; the rate moves < 1e-3 from 5 to 20)
    return simulate_indentation(
        tool(), [1.0], width=b, Kf=KF, delay=T, speed=V, K_sp=K_sp, wear_land=w, clearance=GAMMA, h=h,
        t_end=t_end, v0=v0,
    )  # fmt: skip


def test_small_amplitude_decay_is_the_linear_models_rightmost_root():
    b = 1e-3
    assert linear_root(b, 0.0).real > 0  # without the flank this cut chatters
    rel = []
    for C_pd, w in ((2e5, 30e-6), (1e5, 15e-6)):
        lam, lam0 = linear_root(b, C_pd), linear_root(b, 0.0)
        assert lam.real < 0  # with it, it is stable
        r = run(b, C_pd, w, 1e-4, 0.05)
        assert r.status == "ok"
        g = growth_rate(r.t, r.u, skip=0.3)
        X = float(np.max(np.abs(r.u)))
        om = lam.imag
        # the linearisation's small parameters, each a relative error of the flank's share of the
        # rate to first order: the land against the wave (w om / V)^2 / 6 (Eq. 5), the decay over the
        # land |sigma| w / V (the surface was cut when the amplitude differed), the flank's own damping
        # ratio b g / (2 m om) (averaging: the half-wave's harmonics act at second order in the
        # damping, relative first), the slope of the wave against the clearance X om / (V tan gamma)
        small = (
            (om * w / V) ** 2 / 6
            + abs(lam.real) * w / V
            + b * C_pd / V / (2 * M * om)
            + X * om / (V * math.tan(GAMMA))
        )
        share = lam.real - lam0.real  # what the flank adds to the rate
        err = abs(g.rate - lam.real) / abs(share)
        assert err <= small, (g.rate, lam, err, small)
        assert 3 * g.se < small * abs(share)  # the fit resolves the comparison
        rel.append(err)
    # halving the small parameters (w and C_pd halved) halves the error: first order, 0.96 % -> 0.47 %
    assert rel[1] < 0.6 * rel[0], rel


def test_finite_amplitude_stability_above_the_linear_limit():
    b, C_pd, w = 3e-3, 2e5, 30e-6
    assert linear_root(b, C_pd).real > 5.0  # the linear model grows: e^{sigma t} > 2.7 over 0.2 s
    below = run(b, C_pd, w, 2e-3, 0.2)  # X ~ v0 / om = 0.6 um
    above = run(b, C_pd, w, 5e-2, 0.2)  # 15 um
    assert below.status == above.status == "ok"

    def amplitude(r, i: int) -> float:
        seg = r.u.size // 8
        return float(np.ptp(r.u[i * seg : (i + 1) * seg])) / 2

    lo = [amplitude(below, i) for i in range(8)]
    hi = [amplitude(above, i) for i in range(8)]
    # from below it grows, from above it decays, and the two approach each other: an attracting
    # limit cycle between them (the linear model from above would grow without bound)
    assert np.all(np.diff(lo[2:]) > 0) and np.all(np.diff(hi) < 0), (lo, hi)
    assert hi[-1] / lo[-1] < 0.5 * hi[2] / lo[2], (lo, hi)
    # the mechanism: at large amplitude the clearance face touches beyond the wear land
    assert above.contact.max() > 1.5 * w and below.contact.max() < w * 1.5


def test_bad_input_is_one_line():
    with pytest.raises(InputError, match="wear land must hold several steps"):
        simulate_indentation(
            tool(), [1.0], width=1e-3, Kf=KF, delay=T, speed=V, K_sp=1e14, wear_land=30e-6, clearance=GAMMA,
            h=1e-4, t_end=0.01,
        )  # fmt: skip
    with pytest.raises(InputError, match="clearance"):
        simulate_indentation(
            tool(), [1.0], width=1e-3, Kf=KF, delay=T, speed=V, K_sp=1e14, wear_land=30e-6, clearance=2.0,
            h=1e-6, t_end=0.01,
        )  # fmt: skip
