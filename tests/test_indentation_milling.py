"""The indentation model of process damping per tooth in the milling time
domain (chatterlab.time.simulate_milling(..., indentation=...);
docs/process-damping.md, "Milling in the time domain").

Each tooth in the cut pushes -K_sp a_p A_j along its radial direction n_j,
A_j the area of material under its flank (Eq. 6a) with the penetration
u_j = n_j . r and the surface behind the edge the tool's own path
n_j . r(t - xi / V).  Oracles:

* with K_sp = 0 the run is the run without process damping to round-off
  (the flanks' fixed point adds exact zeros);
* at small amplitude the growth per period is that of the linear run with
  C_pd = K_sp w^2 / 4 (Eq. 6, the linearisation's equivalent), within the
  linearisation's small parameters (tests/test_indentation.py, as in
  tests/test_indentation_simulate.py) times the flank's share plus the
  Richardson step error and the fit's error of both runs;
* the published trend (Altintas, Eynian & Onozuka 2008; Budak & Tunc 2010):
  above the undamped lobe, where the linear damped Floquet multiplier says
  stable, the nonlinear cut (feed, teeth leaving the cut) at V = 0.5 m/s
  settles on its forced periodic orbit, while the same cut without the flank
  and the same cut at ten times the speed (the damping a_p C_pd / V ten times
  smaller: Floquet unstable) chatter.

The structure is the 1-DOF milling benchmark of Insperger & Stepan (2004;
studies/milling/benchmark_1dof.toml: 922 Hz, zeta = 0.011, m = 0.03993 kg,
K_t = 6e8, K_n = 2e8 N/m^2), two teeth, full immersion, down-milling, at
20000 rpm.  The cutter's diameter only sets the cutting speed V = pi D n / 60
(straight teeth, the arc a circle about the centre, the flank straight behind
the edge): D = 0.477 mm gives V = 0.5 m/s, a slow cut, while the tooth period
stays short (1.5 ms), so that eight steps across the wear land cost ~230 steps
per tooth period.  The wear land w = 0.3 V / omega_n (26 um) keeps the land
short against the wave (omega w / V = 0.3, the first small parameter).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from chatterlab.errors import InputError
from chatterlab.frequency import SpectralMonodromy
from chatterlab.process import Milling, milling_loop
from chatterlab.structure import Structure
from chatterlab.time import Initial, Integration, simulate_milling

MASS, WN, ZETA = 0.03993, 2 * math.pi * 922.0, 0.011
ONE = ([[MASS]], [[2 * ZETA * MASS * WN]], [[MASS * WN**2]])
KT, KN = 6e8, 2e8
RPM = 20000.0
GAMMA = math.radians(7.0)
C_PD = 2e4  # N/m: the linear equivalent K_sp w^2 / 4


def cut(V: float) -> tuple[Milling, tuple[float, float, float]]:
    """The cutter at the cutting speed V (m/s) and the indentation model whose equivalent is C_PD."""
    D = 60.0 * V / (math.pi * RPM)
    w = 0.3 * V / WN
    return Milling.from_immersion(2, D, KT, KN, 1.0, "down"), (4.0 * C_PD / w**2, w, GAMMA)


def ln_mu(mill: Milling, ap: float, C_pd: float) -> float:
    """ln |mu| of the spectral Floquet multiplier of the linear model (an independent route)."""
    st = Structure.single_dof(MASS, WN, ZETA)
    mu = SpectralMonodromy(milling_loop(st, mill, C_pd=C_pd), RPM, 24).at(ap)
    return math.log(float(np.max(np.abs(mu))))


def test_zero_indentation_coefficient_is_the_run_without_process_damping():
    """The nonlinear cut (feed, teeth leaving the cut, located crossings) with
    K_sp = 0: the flanks' fixed point adds exact zeros to the same solve."""
    mill, (_, w, gamma) = cut(0.5)
    integ = Integration(steps_per_period=232, periods=6)
    zero = simulate_milling(ONE, mill, RPM, 1e-3, feed=1e-5, indentation=(0.0, w, gamma), integration=integ)
    plain = simulate_milling(ONE, mill, RPM, 1e-3, feed=1e-5, integration=integ)
    assert zero.attrs["process_damping"].startswith("indentation, K_sp = 0 N/m^3")
    assert plain.attrs["process_damping"] == "none"
    assert "instants where a tooth left or re-entered the material located" in zero.message
    scale = float(np.max(np.abs(plain.x)))
    assert scale > 0
    # the same arithmetic (r* + Z 0 = r*, F + 0 = F): identical; 1e-12 leaves room for round-off
    assert np.max(np.abs(zero.x - plain.x)) <= 1e-12 * scale
    assert np.max(np.abs(zero.Fx - plain.Fx)) <= 1e-12 * float(np.max(np.abs(plain.Fx)))


def test_small_amplitude_growth_is_the_linear_equivalents():
    """Linear cut (the teeth in the arc), started 10 nm off: the flank's
    contact stays on the wear land, where A_j is its first harmonic's
    a_p C_pd / V n_j n_j^T r' (Eq. 6) up to the small parameters."""
    from test_milling_time import richardson

    mill, ind = cut(0.5)
    V, w = math.pi * mill.diameter * RPM / 60.0, ind[1]
    ap = 5e-4
    init = Initial(q0=[1e-8])
    steps = (232, 464, 928)  # 232: eight steps across the land (the default), halved twice

    def runs(**kw):
        return [
            simulate_milling(
                ONE, mill, RPM, ap, nonlinear=False, initial=init,
                integration=Integration(steps_per_period=m, periods=20), **kw,
            )
            for m in steps
        ]  # fmt: skip

    ind_runs = runs(indentation=ind)
    assert (
        ind_runs[0].steps_per_period
        == simulate_milling(
            ONE, mill, RPM, ap, nonlinear=False, indentation=ind, integration=Integration(periods=0.01)
        ).steps_per_period
    )  # the default step: eight samples across the wear land
    g_ind, e_ind = richardson([r.growth_per_period for r in ind_runs])
    lin_runs = runs(C_pd=C_PD)
    g_lin, e_lin = richardson([r.growth_per_period for r in lin_runs])
    g_0 = ln_mu(mill, ap, 0.0)
    share = g_lin - g_0
    tau = mill.tooth_period(RPM)
    X = float(np.max(np.abs(ind_runs[-1].x)))
    om = WN  # the vibration's frequency: the mode's (the cut moves it by a few %, inside the squares' room)
    # the linearisation's small parameters (tests/test_indentation.py): the land against the wave, the
    # decay over the land, the flank's own damping ratio, the wave's slope against the clearance
    small = (
        (om * w / V) ** 2 / 6
        + abs(g_lin / tau) * w / V
        + ap * C_PD / V / (2 * MASS * om)
        + X * om / (V * math.tan(GAMMA))
    )
    # Richardson's step errors and the fits' of both runs
    fit = e_ind + ind_runs[-1].growth_error + e_lin + lin_runs[-1].growth_error
    bound = small * abs(share) + fit
    print(f"indentation {g_ind:.6f} linear {g_lin:.6f} share {share:.5f} small {small:.4f} fit {fit:.2e}")
    assert abs(g_ind - g_lin) <= bound, (g_ind, g_lin, share, small, fit)
    # resolved: the bound is a small part of what the flank adds, and the linear run is the Floquet one
    assert bound < 0.3 * abs(share), (bound, share)
    assert abs(g_lin - ln_mu(mill, ap, C_PD)) <= e_lin + lin_runs[-1].growth_error


def test_slow_cut_above_the_lobe_settles_where_the_fast_one_chatters():
    """Budak & Tunc (2010), Altintas et al. (2008): a_p = 2 mm is above the
    undamped limit (Floquet unstable); with the flank at V = 0.5 m/s the
    linear model is stable and the nonlinear run settles on its forced
    periodic orbit (its Poincare samples converge); without the flank it
    chatters, and at V = 5 m/s (w ten times wider: the same K_sp w^2 / 4 and
    w / V, the same cost) the damping a_p C_pd / V is ten times smaller, the
    Floquet multiplier unstable and the run chatters too.  The verdict says
    what the run shows from its start (the tool displaced by the feed's
    force): a larger disturbance is not claimed."""
    ap, fz = 2e-3, 1e-5
    slow, ind = cut(0.5)
    assert ln_mu(slow, ap, 0.0) > 0 > ln_mu(slow, ap, C_PD)
    integ = Integration(periods=40)
    run = simulate_milling(ONE, slow, RPM, ap, feed=fz, indentation=ind, integration=integ)
    assert run.status == "ok" and run.verdict == "stable", run.reason
    m = run.steps_per_period
    bare = simulate_milling(
        ONE, slow, RPM, ap, feed=fz, integration=Integration(periods=40, steps_per_period=m)
    )
    assert bare.verdict.endswith("chatter"), bare.reason
    fast, ind_fast = cut(5.0)
    assert ln_mu(fast, ap, C_PD) > 0
    hot = simulate_milling(ONE, fast, RPM, ap, feed=fz, indentation=ind_fast, integration=integ)
    assert hot.steps_per_period == m and hot.verdict.endswith("chatter"), hot.reason


def test_bad_input_is_one_line():
    mill, ind = cut(0.5)
    with pytest.raises(InputError, match=r"^integration.steps_per_period: the indentation model's wear land"):
        simulate_milling(ONE, mill, RPM, 1e-3, indentation=ind, integration=Integration(steps_per_period=50))
    with pytest.raises(InputError, match=r"^C_pd and indentation: give one"):
        simulate_milling(ONE, mill, RPM, 1e-3, indentation=ind, C_pd=C_PD)
    with pytest.raises(InputError, match=r"^indentation clearance: must lie in"):
        simulate_milling(ONE, mill, RPM, 1e-3, indentation=(ind[0], ind[1], 2.0))
    with pytest.raises(InputError, match=r"^indentation wear_land"):
        simulate_milling(ONE, mill, RPM, 1e-3, indentation=(ind[0], -1.0, GAMMA))
