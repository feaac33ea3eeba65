"""The model file's process damping in ``chatterlab.time.simulate`` and
``chatterlab simulate`` (docs/process-damping.md, "In the time domain").

Before, ``simulate`` took neither the linear C_pd nor the indentation
model: a run with ``[process_damping]`` was the run without it.  Oracles:

* the linear model's run decays at the rightmost characteristic root of the
  same loop (the frequency-domain engine, an independent route) within the
  verdict's own error bar, and moves from the undamped root by the flank's
  share;
* the indentation model's run (K_sp, wear_land, clearance_deg) at small
  amplitude decays at the root of the linear model with C_pd = K_sp w^2 / 4
  within the linearisation's small parameters (their sum, a relative error
  of the flank's share, tests/test_indentation.py) plus the verdict's error
  bar (Newmark's Richardson estimate and the fit);
* with the flank's K_sp = 0 the run is the run without process damping to
  round-off (the same Newmark recurrence in the step map's arithmetic);
* the published trend (Altintas, Eynian & Onozuka 2008; Budak & Tunc 2010):
  at 2.3 times the lobe minimum the cut decays at low cutting speed and
  chatters at ten times the speed, the flank's damping b C_pd / V falling
  like 1/V, each as the linear model's root says;
* bad input: one line, exit 2, nothing written.

The tool is the 1-DOF turning tool of studies/process_damping (m = 2 kg,
k = 2e7 N/m, c = 400 N s/m, K_f = 2e9 N/m^2) at 20000 rpm (T = 3 ms) on a
workpiece of D = 0.5 mm (V = 0.52 m/s) or 5 mm (5.2 m/s).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

import chatterlab as cl
from chatterlab.errors import InputError
from chatterlab.frequency import characteristic_roots
from chatterlab.process import closed_loop
from chatterlab.time import Initial, Integration, simulate, simulate_milling

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "studies/process_damping/turning.toml"
RPM = 20000.0
M, OMEGA_N = 2.0, math.sqrt(2e7 / 2.0)
C_PD = 2e5
GAMMA_DEG = 7.0
V0 = {"tool.x": 1e-4}  # m/s: X ~ v0 / omega = 30 nm


def indentation_file(tmp_path: Path, D: float, w: float, name: str = "ind.toml") -> Path:
    """The study's tool with the indentation model whose equivalent is C_pd = 2e5 N/m."""
    text = STUDY.read_text().replace("workpiece_diameter = 0.05", f"workpiece_diameter = {D!r}")
    text += (
        f"\n[process_damping]\nK_sp = {4 * C_PD / w**2!r}\nwear_land = {w!r}\nclearance_deg = {GAMMA_DEG}\n"
    )
    path = tmp_path / name
    path.write_text(text)
    return path


def linear_model(D: float, C_pd: float) -> cl.Model:
    model = cl.load_model(STUDY).with_parameter("machine.workpiece_diameter", D)
    return model.with_parameter("process_damping.C_pd", C_pd)


def roots(model: cl.Model, b: float):
    """The loop's characteristic roots (the indentation model's: its linearisation, C_pd = K_sp w^2 / 4)."""
    r = characteristic_roots(closed_loop(cl.assemble(model).at(), width=b, speed=RPM), count=3)
    assert r.converged
    return r


def root(model: cl.Model, b: float) -> complex:
    return complex(roots(model, b).roots[0])


def run(model: cl.Model, b: float, duration: float, step: float | None = None, v0=V0, with_roots=False):
    return simulate(
        cl.assemble(model), width=b, speed=RPM, roots=roots(model, b) if with_roots else None,
        integration=Integration(duration=duration, step=step), initial=Initial(v0=v0),
    )  # fmt: skip


def test_linear_process_damping_decays_at_the_loops_root():
    b, D = 1e-3, 5e-4
    lam, lam0 = root(linear_model(D, C_PD), b), root(linear_model(D, 0.0), b)
    assert lam0.real > 0 > lam.real  # the flank turns a chattering cut into a stable one
    # the step resolves the root: 40 steps per period (Newmark's rate error |Re c| h^2 well inside the bar)
    sim = run(linear_model(D, C_PD), b, 0.05, step=2 * math.pi / lam.imag / 40)
    assert sim.meta["process_damping"].startswith("linear, C_pd = 200000 N/m")
    v = sim.verdict("tool.x")
    assert v.classification == "decaying"
    assert abs(v.rate - lam.real) <= v.error, (v.rate, v.error, lam)
    # and the run is not the run without the table (what simulate gave before)
    assert abs(v.rate - lam0.real) > 10 * v.error
    # the exponential step map integrates the same matrices (the term in B): the same root
    ex = simulate(
        cl.assemble(linear_model(D, C_PD)), width=b, speed=RPM, roots=roots(linear_model(D, C_PD), b),
        integration=Integration(duration=0.05, integrator="exponential"), initial=Initial(v0=V0),
    )  # fmt: skip
    ve = ex.verdict("tool.x")
    assert ve.classification == "decaying" and not ve.contradiction
    assert abs(ve.rate - lam.real) <= ve.error, (ve.rate, ve.error, lam)


def test_indentation_run_at_small_amplitude_is_the_linear_root(tmp_path):
    b, D, w = 1e-3, 5e-4, 30e-6
    model = cl.load_model(indentation_file(tmp_path, D, w))
    assert model.process_damping.indentation
    lam, lam0 = root(linear_model(D, C_PD), b), root(linear_model(D, 0.0), b)
    assert root(model, b) == pytest.approx(lam, rel=1e-12)  # the frequency domain takes Eq. 6
    sim = run(model, b, 0.05, with_roots=True)
    assert sim.meta["process_damping"].startswith("indentation, K_sp = 8.889e+14 N/m^3, wear land 30 um")
    assert sim.response.attrs["method"] == "indentation"
    V = math.pi * D * RPM / 60
    assert sim.step <= w / (8 * V) * (1 + 1e-12)  # the land holds eight samples
    v = sim.verdict("tool.x")
    assert v.classification == "decaying"
    X = float(np.max(np.abs(sim.data["tool.x"])))
    om = lam.imag
    # the linearisation's small parameters (tests/test_indentation.py): the land against the wave, the
    # decay over the land, the flank's own damping ratio, the wave's slope against the clearance (X / w
    # the amplitude ratio: X om / V = (X / w)(om w / V))
    small = (
        (om * w / V) ** 2 / 6
        + abs(lam.real) * w / V
        + b * C_PD / V / (2 * M * om)
        + X * om / (V * math.tan(math.radians(GAMMA_DEG)))
    )
    share = lam.real - lam0.real
    assert abs(v.rate - lam.real) <= small * abs(share) + v.error, (v.rate, v.error, lam, small)
    # the comparison is resolved: the bound is a small part of what the flank adds
    assert small * abs(share) + v.error < 0.1 * abs(share)


def test_indentation_rate_converges_at_newmarks_order(tmp_path):
    """The verdict's Richardson estimate takes the scheme as second order
    (Simulation._order): the flank's run must be so too -- its area is exact
    for the surface linear between samples (error O((V h)^2)) and the land's
    end is Hermite-interpolated (O(h^4)).  Successive differences of the
    rate at h, h/2, h/4 then shrink by 4 (1 + O((omega h)^2)); omega h =
    0.025, so 4 within 5 %."""
    model = cl.load_model(indentation_file(tmp_path, 5e-4, 30e-6))
    V = math.pi * 5e-4 * RPM / 60
    h0 = 3e-3 / math.ceil(3e-3 / (30e-6 / (8 * V)))  # the default: 8 steps across the land
    rates = [
        run(model, 1e-3, 0.02, step=h0 / f).growth("tool.x", window="all", skip=3e-3).rate for f in (1, 2, 4)
    ]
    d = np.diff(rates)
    assert d[0] / d[1] == pytest.approx(4.0, rel=0.05), rates


def test_zero_indentation_coefficient_is_the_run_without_process_damping(tmp_path):
    b, D, w = 1e-3, 5e-4, 30e-6
    model = cl.load_model(indentation_file(tmp_path, D, w))
    V = math.pi * D * RPM / 60
    h = 3e-3 / math.ceil(3e-3 / (w / (8 * V)))  # the flank's step, on the delay's grid
    plain = run(linear_model(D, 0.0), b, 0.01, step=h)
    # K_sp = 0 exactly (the reader asks K_sp > 0): the flank's loop with no force
    pd = dataclasses.replace(model.process_damping, K_sp=0.0)
    zero = run(dataclasses.replace(model, process_damping=pd), b, 0.01, step=h)
    assert zero.response.attrs["method"] == "indentation" and plain.response.attrs.get("method") is None
    x0, x1 = plain.data["tool.x"], zero.data["tool.x"]
    assert x0.shape == x1.shape and np.max(np.abs(x0)) > 0
    # the same recurrence in two arithmetic forms (increment form / step map): round-off of
    # 1400 steps of a contracting map, steps x eps = 3e-13 of the amplitude; 1e-11 leaves 30x room
    assert np.max(np.abs(x1 - x0)) <= 1e-11 * np.max(np.abs(x0))


def test_low_speed_stability_far_above_the_lobe(tmp_path):
    """Budak & Tunc (2010), Altintas et al. (2008): the flank stabilises a
    slow cut far above the lobe; ten times faster the same width chatters."""
    b = 1.5e-3  # 2.3 x Tlusty's lobe minimum 0.6525 mm, where the cut without the flank grows
    assert root(linear_model(5e-4, 0.0), b).real > 0
    rates = {}
    for D, w in ((5e-4, 30e-6), (5e-3, 300e-6)):  # V = 0.52 and 5.2 m/s, the same w / V (same cost)
        lam = root(linear_model(D, C_PD), b)
        sim = run(cl.load_model(indentation_file(tmp_path, D, w, f"ind{D}.toml")), b, 0.05, with_roots=True)
        v = sim.verdict("tool.x")
        rates[D] = (v.classification, lam.real)
        # each as the linear model's root says, at the distance the small parameters allow
        assert (v.classification == "decaying") == (lam.real < 0), (D, v, lam)
    assert rates[5e-4][0] == "decaying" and rates[5e-3][0] == "growing", rates


def test_a_finite_amplitude_decay_is_not_claimed(tmp_path):
    """At b = 3 mm the linearisation grows (+11 1/s) and the flank holds the
    vibration on a limit cycle (tests/test_indentation.py): started above it
    (15 um) the run decays towards it, which proves nothing about small
    disturbances -- the verdict is undetermined and says why; without the
    linearisation's roots no decay of the nonlinear run is claimed either."""
    b = 3e-3
    model = cl.load_model(indentation_file(tmp_path, 5e-4, 30e-6))
    assert root(model, b).real > 5.0
    above = run(model, b, 0.1, v0={"tool.x": 5e-2}, with_roots=True)
    v = above.verdict("tool.x")
    assert v.rate + v.error < 0  # the fit does decay...
    assert v.classification == "undetermined" and "finite-amplitude" in v.message, v.message  # ...unclaimed
    small = run(model, 1e-3, 0.03)  # a decaying cut, but no roots given
    v = small.verdict("tool.x")
    assert v.classification == "undetermined" and "give roots=" in v.message, v.message


def test_moving_slide_and_exponential_are_refused_in_one_line(tmp_path):
    model = cl.load_model(indentation_file(tmp_path, 5e-4, 30e-6))
    with pytest.raises(InputError, match="integrates with Newmark"):
        simulate(
            cl.assemble(model), width=1e-3, speed=RPM,
            integration=Integration(duration=0.01, integrator="exponential"),
        )  # fmt: skip
    with pytest.raises(InputError, match="wear land must hold several steps"):
        run(model, 1e-3, 0.01, step=1e-4)
    shaper = cl.load_model(ROOT / "studies/traverse_shaper/model.toml").with_parameters(
        {
            "process_damping.K_sp": 1e14,
            "process_damping.wear_land": 1e-4,
            "process_damping.clearance_deg": 7.0,
        }
    )
    with pytest.raises(InputError, match=r"runs on a continuous cut: hold the slide .* or give C_pd"):
        simulate(cl.assemble(shaper), width=0.002, integration=Integration(periods=1))


def test_the_material_side_is_asked_for_when_the_coupling_does_not_show_it(tmp_path):
    """The flank's area is not symmetric in the penetration: a ``matrices``
    coupling without a static force does not say which side is material."""
    text = STUDY.read_text().replace("workpiece_diameter = 0.05", "workpiece_diameter = 0.0005")
    text = text.replace(
        'model = "regenerative"\nKf = 2000000000.0',
        'model = "matrices"\nDP = [[2e6, 0, 0], [0, 0, 0], [0, 0, 0]]\nDO = [[-2e6, 0, 0], [0, 0, 0], [0, 0, 0]]',
    )
    text += f"\n[process_damping]\nK_sp = {4 * C_PD / 30e-6**2!r}\nwear_land = 30e-6\nclearance_deg = 7.0\n"
    model = cl.loads_model(text, source="m.toml")
    with pytest.raises(InputError, match="give normal_deg, the direction that thins the chip"):
        run(model, 1e-3, 0.01)
    # with normal_deg (the side named) the run goes
    ok = run(model.with_parameter("process_damping.normal_deg", 0.0), 1e-3, 0.003)
    assert ok.status == "ok" and ok.meta["process_damping"].startswith("indentation")


def _cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str]:
    """``chatterlab ARGS`` in this process: (exit status, stderr)."""
    from chatterlab.cli._main import main

    capsys.readouterr()
    code = main(list(args))
    return code, capsys.readouterr().err


def milling_file(tmp_path: Path, table: str) -> Path:
    text = (ROOT / "studies/milling/benchmark_2dof.toml").read_text() + "\n[process_damping]\n" + table
    path = tmp_path / "mill.toml"
    path.write_text(text)
    return path


def test_milling_time_domain_runs_the_indentation_model(tmp_path, capsys):
    """Not refused any more, and not replaced by its linear equivalent: the
    API reads the FrozenSystem's table (K_sp, wear land, clearance) and runs
    the flank per tooth -- the run given ``indentation=`` explicitly, to
    round-off -- and ``chatterlab simulate`` runs the same and names the
    model (tests/test_indentation_milling.py holds the oracles).  The wear
    land of 1 mm at V = 10.5 m/s keeps eight steps across it at ~250 steps
    per tooth period."""
    from chatterlab.cli._main import main
    from chatterlab.cli._milling import PERTURBATION
    from chatterlab.lobes._milling_model import milling_of
    from chatterlab.time import Initial, Integration

    path = milling_file(tmp_path, "K_sp = 8e10\nwear_land = 1e-3\nclearance_deg = 7\n")
    model = cl.load_model(path)
    fz = cl.assemble(model).at()
    (cm,) = [c for c in fz.couplings() if c.coupling.kind == "milling"]
    P = np.asarray(cm.J, dtype=float)[:2]
    kw = dict(
        feed=model.process.milling.feed_per_tooth,
        integration=Integration(periods=2),
        initial=Initial(q0=np.linalg.pinv(P) @ np.full(2, PERTURBATION)),
    )
    api = simulate_milling(fz, milling_of(model), 10000.0, 1e-4, tool_point=("tip.x", "tip.y"), **kw)
    ind = (8e10, 1e-3, math.radians(7.0))
    given = simulate_milling(
        (fz.A, fz.B, fz.C), milling_of(model), 10000.0, 1e-4, tool_point=P, indentation=ind, **kw
    )
    assert api.attrs["process_damping"].startswith("indentation, K_sp = 8e+10 N/m^3, wear land 1000 um")
    assert np.abs(api.x - given.x).max() <= 1e-12 * np.abs(api.x).max()
    out = tmp_path / "mill.csv"
    capsys.readouterr()
    code = main(
        ["simulate", str(path), "--speed", "10000", "--width", "0.1", "--revolutions", "2", "--out", str(out)]
    )
    text = capsys.readouterr().out
    assert code in (0, 1) and "process damping: indentation, K_sp = 8e+10 N/m^3" in text, text
    cli = np.loadtxt(out, delimiter=",", skiprows=1, usecols=(1,), comments="#")  # x [m]
    assert np.abs(api.x[: cli.size] - cli).max() <= 1e-9 * np.abs(api.x).max()


def test_chatterlab_simulate_of_a_milling_model_takes_its_linear_c_pd(tmp_path, capsys):
    """The command hands the model's C_pd to the milling time domain: its
    run is the API's run of the model (which reads the table itself), and
    not the run without the table."""
    from chatterlab.cli._main import main
    from chatterlab.lobes._milling_model import milling_of

    path = milling_file(tmp_path, "C_pd = 2e5\n")
    out = tmp_path / "mill.csv"
    capsys.readouterr()
    code = main(["simulate", str(path), "--speed", "10000", "--width", "0.1", "--revolutions", "20",
                 "--linear", "--out", str(out)])  # fmt: skip
    text = capsys.readouterr().out
    assert code in (0, 1) and "process damping: linear, C_pd = 200000 N/m" in text, text
    model = cl.load_model(path)
    fz = cl.assemble(model).at()
    from chatterlab.cli._milling import PERTURBATION

    (cm,) = [c for c in fz.couplings() if c.coupling.kind == "milling"]
    P = np.asarray(cm.J, dtype=float)[:2]
    from chatterlab.time import Initial, Integration

    kw = dict(
        nonlinear=False,
        integration=Integration(periods=20),
        initial=Initial(q0=np.linalg.pinv(P) @ np.full(2, PERTURBATION)),
    )
    api = simulate_milling(fz, milling_of(model), 10000.0, 1e-4, tool_point=("tip.x", "tip.y"), **kw)
    bare = simulate_milling((fz.A, fz.B, fz.C), milling_of(model), 10000.0, 1e-4, tool_point=P, **kw)
    cli = np.loadtxt(out, delimiter=",", skiprows=1, usecols=(1,), comments="#")  # x [m]
    assert np.abs(api.x[: cli.size] - cli).max() <= 1e-9 * np.abs(api.x).max()
    assert np.abs(bare.x[: cli.size] - cli).max() > 1e-3 * np.abs(api.x).max()


# ----------------------------------------------------------------------------- milling: rubbing teeth
MILL_MASS, MILL_WN, MILL_ZETA = 0.03993, 2 * math.pi * 922.0, 0.011  # the Insperger-Stepan benchmark
KT, KN, CUTTER_D, MILL_CPD = 6e8, 2e8, 0.02, 2e4


def test_slotting_rubbing_is_a_constant_viscous_damping():
    """Four teeth slotting: two teeth in the arc at right angles, so the
    rubbing sum_j n_j n_j^T = I and the flanks are a viscous damping
    a_p C_pd / V on the tool point: the linear run with C_pd is the run of
    the structure with that damping added to C, to round-off (the same
    implicit Newmark force, once in the coupling's solve, once in C)."""
    from chatterlab.model._items import cutting_speed
    from chatterlab.process import Milling

    M = np.eye(2) * MILL_MASS
    C = np.eye(2) * 2 * MILL_ZETA * MILL_MASS * MILL_WN
    K = np.eye(2) * MILL_MASS * MILL_WN**2
    mill = Milling.from_immersion(4, CUTTER_D, KT, KN, 1.0, "down")
    rpm, ap = 3000.0, 5e-5
    g = ap * MILL_CPD / cutting_speed(rpm, CUTTER_D)
    kw = {
        "nonlinear": False,
        "tool_point": np.eye(2),
        "integration": Integration(steps_per_period=100, periods=20),
    }
    a = simulate_milling((M, C, K), mill, rpm, ap, C_pd=MILL_CPD, **kw)
    b = simulate_milling((M, C + g * np.eye(2), K), mill, rpm, ap, **kw)
    c = simulate_milling((M, C, K), mill, rpm, ap, **kw)
    x, y, z = (r.history("x") for r in (a, b, c))
    scale = float(np.max(np.abs(y)))
    # round-off: 8000 steps x 2.2e-16 = 1.8e-12 of the amplitude; 1e-11 leaves 5x for the growth
    # (measured 2e-13)
    assert np.max(np.abs(x - y)) <= 1e-11 * scale
    assert np.max(np.abs(z - y)) > 1e-3 * scale  # the term is there


@pytest.mark.parametrize(("immersion", "teeth"), [(1.0, 2), (0.5, 4)])
def test_milling_run_with_rubbing_teeth_has_the_damped_floquet_multiplier(immersion, teeth):
    """The periodic term W(t) = sum_j g_j n_j n_j^T itself (not only its
    slotting sum): the linear run's growth per period, Richardson-bounded over
    100, 200, 400 steps per period, is ln |mu| of the damped spectral Floquet
    multiplier (chatterlab.frequency, an independent route converged to 1e-14);
    and the term moves the multiplier by more than three times that bound."""
    from test_milling_time import richardson

    from chatterlab.frequency import SpectralMonodromy
    from chatterlab.process import Milling, milling_loop
    from chatterlab.structure import Structure

    one = ([[MILL_MASS]], [[2 * MILL_ZETA * MILL_MASS * MILL_WN]], [[MILL_MASS * MILL_WN**2]])
    mill = Milling.from_immersion(teeth, CUTTER_D, KT, KN, immersion, "down")
    rpm, ap = 5000.0, 5e-4
    st = Structure.single_dof(MILL_MASS, MILL_WN, MILL_ZETA)

    def ln_mu(C_pd: float) -> float:
        mu = SpectralMonodromy(milling_loop(st, mill, C_pd=C_pd), rpm, 24).at(ap)
        return math.log(float(np.max(np.abs(mu))))

    td = [
        simulate_milling(
            one, mill, rpm, ap, nonlinear=False, C_pd=MILL_CPD,
            integration=Integration(steps_per_period=m, periods=40),
        )
        for m in (100, 200, 400)
    ]  # fmt: skip
    g_td, err_td = richardson([r.growth_per_period for r in td])
    bound = err_td + td[-1].growth_error
    ref = ln_mu(MILL_CPD)
    assert abs(g_td - ref) <= bound, (g_td, ref, bound)
    assert abs(ln_mu(0.0) - ref) > 3 * bound


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--step", "1e-4"], "step: the indentation model's wear land must hold several steps"),
        (["--integrator", "exponential"], "integrates with Newmark"),
        (["--set", "process_damping.clearance_deg=95"], "clearance_deg: must lie in (0, 90) deg (got 95)"),
        (["--set", "process_damping.wear_land=-1e-5"], "wear_land"),
        (["--set", "process_damping.K_sp=8e3"], "K_sp: 8000 N/m^3 is outside the plausible range"),
    ],
)
def test_cli_bad_input_is_one_line_exit_2_nothing_written(tmp_path, capsys, extra, message):
    path = indentation_file(tmp_path, 5e-4, 30e-6)
    out = tmp_path / "run.csv"
    code, err = _cli(
        capsys, "simulate", str(path), "--speed", "20000", "--duration", "0.01", "--out", str(out), "--quiet",
        *extra,
    )  # fmt: skip
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1 and message in err, err
    assert not out.exists()


def test_moving_slide_takes_the_linear_term_while_in_the_cut():
    """The shaper's moving slide with ``C_pd``: the flank's b C_pd / V along
    the chip's normal (a grasso cut's axis 2) is, at the work speed V, the
    cut's own K6 (F_y per rate of chip-thickness change) raised by
    b_ref C_pd / V -- an independent route through the coupling's D_V, which
    switches with the cut too: the two runs agree to round-off."""
    shaper = cl.load_model(ROOT / "studies/traverse_shaper/model.toml")
    C_pd, V = 3e5, shaper.process.speed
    damped = shaper.with_parameter("process_damping.C_pd", C_pd)
    K6 = dict(shaper.couplings[0].params)["K6"]
    raised = shaper.with_parameter("coupling.cut.K6", K6 + 0.002 * C_pd / V)
    integ = Integration(periods=1)
    a = simulate(cl.assemble(damped), width=0.002, integration=integ)
    b = simulate(cl.assemble(raised), width=0.002, integration=integ)
    plain = simulate(cl.assemble(shaper), width=0.002, integration=integ)
    assert a.meta["kinematics"] == "ShapingKinematics" and a.meta["process_damping"].startswith("linear")
    assert a.step == b.step and not a.in_cut.all() and a.in_cut.any()
    x, y, z = (s.data["rfe5.y"] for s in (a, b, plain))
    scale = float(np.max(np.abs(y)))
    # the same matrices summed in another order: round-off of the run, steps x eps = 7396 x 2.2e-16
    # = 1.6e-12 of its amplitude; 1e-11 leaves 6x for the loop's amplification (measured: 1.1e-13)
    assert np.max(np.abs(x - y)) <= 1e-11 * scale
    assert np.max(np.abs(z - y)) > 1e-4 * scale  # and the term is there: the run without it differs
