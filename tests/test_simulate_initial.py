"""Initial conditions of ``simulate``: q0, v0 and the delay history.

The oracle is the method of steps (Bellman & Cooke 1963, ch. 3; Hale &
Verduyn Lunel 1993, sec. 2.1): for the 1-DOF regenerative tool of
docs/model-format.md,

    m x'' + c x' + k x = -K (x(t) - x(t - T)),    K = K_f b,

the delayed term on [0, T] is the known history, so x on [0, T] solves a
linear ODE with a known forcing; on [T, 2T] the forcing is the first
interval's solution.  Each interval is integrated by scipy's DOP853 at
rtol 1e-12 (dense output for the next one), far below Newmark's error.

Tolerances (derived, not tuned):

* Newmark (average acceleration) moves the phase of an oscillation of
  circular frequency w by (w h)^2/12 per radian, so after t_end its error
  is at most max|x| (w h)^2/12 w t_end to leading order.  The loop's
  frequencies lie below w_max = sqrt((k + 2K)/m) (the delayed term adds a
  stiffness of modulus <= K to k + K), giving the bound used;
  halving h divides the error by 4 (fitted slope 2 +- 0.1).
* a table history: the interpolation error e = max |s(t) - f(t)| on
  [-T, 0] (s the not-a-knot cubic spline through the nodes: O(dt^4),
  fitted slope 4 +- 0.5) enters as a force K e on [0, T]; the difference
  of the table run and the callable run obeys the same equation with zero
  initial state, so |dx| <= L K e on [0, T] and <= L K e (1 + L K) on
  [0, 2T], L = int |g| <= 1/(m w_d zeta w_n) the L1 norm of the impulse
  response g of m, c, k + K.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_clean_error, turning_text

import chatterlab as cl
from chatterlab.cli._main import main
from chatterlab.errors import InputError
from chatterlab.time import Initial, Integration, simulate

M, C, KS, KF = 1.0, 189.7, 1.0e7, 2.0e9
T, B = 0.02, 0.3e-3  # delay (3000 rpm) and width (below b_lim ~ 0.4 mm)
K = KF * B
A, WH, PH = 1.0e-5, 2 * math.pi * 1.5 / T, 0.7  # the callable history a sin(w_h t + phi)


def hist(t):
    return A * np.sin(WH * np.asarray(t) + PH)


Q0S, V0S = float(hist(0.0)), A * WH * math.cos(PH)  # a start consistent with the history
NODES = np.linspace(-T, 0.0, 41)


@pytest.fixture(scope="module")
def tool():
    return cl.assemble(cl.loads_model(turning_text()))


def method_of_steps(history, q0: float, v0: float):
    """x(t) on [0, 2T]: two intervals, each an ODE with the delayed term known."""
    from scipy.integrate import solve_ivp

    sols: list = []
    y0 = [q0, v0]
    for j in range(2):
        prev = sols[-1] if sols else None

        def rhs(t, y, prev=prev):
            xd = prev.sol(t - T)[0] if prev is not None else float(history(t - T))
            return [y[1], (-C * y[1] - (KS + K) * y[0] + K * xd) / M]

        s = solve_ivp(
            rhs, (j * T, (j + 1) * T), y0, method="DOP853", rtol=1e-12, atol=1e-20, dense_output=True
        )
        assert s.success
        sols.append(s)
        y0 = s.y[:, -1]

    def x(t):
        idx = np.minimum((t / T).astype(int), 1)
        return np.array([sols[i].sol(ti)[0] for i, ti in zip(idx, t, strict=True)])

    return x


CASES = {
    # name: (simulate's arguments, the history for the reference, q0, v0)
    "v0 only": (dict(v0=[0.01]), lambda t: 0.0, 0.0, 0.01),
    "q0, zero history": (dict(q0={"tip.x": 1e-5}), lambda t: 0.0, 1e-5, 0.0),
    "constant history": (dict(q0={"tip.x": 1e-5}, history="constant"), lambda t: 1e-5, 1e-5, 0.0),
    "callable history": (dict(q0=[Q0S], v0=[V0S], history=hist), hist, Q0S, V0S),
    "table history": (dict(q0=[Q0S], v0=[V0S], history=(NODES, hist(NODES))), hist, Q0S, V0S),
}


def run(tool, N: int, **kw):
    """The cut at h = T/N over two delays from the initial condition ``kw``
    (q0, v0, history: the fields of Initial)."""
    return simulate(
        tool,
        feedback="pdo",
        width=B,
        delay=T,
        outputs=["tip.x"],
        integration=Integration(duration=2 * T, step=T / N),
        initial=Initial(**kw),
    )


@pytest.mark.parametrize("case", list(CASES))
def test_against_the_method_of_steps(tool, case):
    """Measured (relative to max|x|, h = T/1000, T/2000, T/4000): 5.9e-3,
    1.5e-3, 3.7e-4 for v0 only, 5.2e-3 to 5.6e-3 at T/1000 for the others, 0.10-0.12 of the
    phase bound, slopes 1.997-2.005."""
    kw, history, q0, v0 = CASES[case]
    ref = method_of_steps(history, q0, v0)
    w_max = math.sqrt((KS + 2 * K) / M)
    errs = []
    for N in (1000, 2000, 4000):
        h = T / N
        sim = run(tool, N, **kw)
        assert sim.status == "ok"
        x, r = sim.data["tip.x"], ref(sim.t)
        assert x[0] == pytest.approx(q0, rel=1e-12, abs=1e-20)
        err = float(np.abs(x - r).max() / np.abs(r).max())
        assert err <= (w_max * h) ** 2 / 12 * w_max * 2 * T, (N, err)
        errs.append(err)
    slopes = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(np.abs(slopes - 2.0) < 0.1), (errs, slopes)
    assert sim.response.v[0, 0] == pytest.approx(v0, rel=1e-12, abs=1e-20)


def test_table_history_agrees_with_its_callable(tool):
    """The table run minus the callable run (same h) within the propagated
    interpolation error; the spline's own error is fourth order.  Measured:
    e = 7.0e-10 m at 41 nodes, |dx| = 3.7e-11 m against the bound 4.0e-9 m."""
    from scipy.interpolate import CubicSpline

    wn = math.sqrt((KS + K) / M)
    zeta = C / (2 * M * wn)
    L = 1.0 / (M * wn * math.sqrt(1 - zeta**2) * zeta * wn)
    fine = np.linspace(-T, 0.0, 20001)
    kw = dict(CASES["callable history"][0])
    base = run(tool, 2000, **kw).data["tip.x"]
    errs = []
    for nodes in (21, 41, 81):
        tn = np.linspace(-T, 0.0, nodes)
        e = float(np.abs(CubicSpline(tn, hist(tn))(fine) - hist(fine)).max())
        errs.append(e)
        kw["history"] = (tn, hist(tn))
        sim = run(tool, 2000, **kw)
        assert "not-a-knot cubic spline" in sim.meta["initial_condition"]
        dx = np.abs(sim.data["tip.x"] - base)
        first = sim.t <= T
        assert dx[first].max() <= L * K * e, nodes
        assert dx.max() <= L * K * e * (1 + L * K), nodes
    slopes = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(np.abs(slopes - 4.0) < 0.5), slopes


def test_meta_says_what_was_used(tool):
    assert run(tool, 100).meta["initial_condition"].startswith("at rest")
    ic = run(tool, 100, q0={"tip.x": 1e-5}, history="constant").meta["initial_condition"]
    assert "tip.x = 1e-05 m" in ic and "constant (q0 held)" in ic
    ic = run(tool, 100, v0=[0.01], history=hist).meta["initial_condition"]
    assert "tool.x 0.01 m/s" in ic and "callable hist(t)" in ic
    # no delayed term: the history is not read, and the meta says so
    sim = simulate(
        tool,
        feedback="pd",
        width=B,
        delay=T,
        integration=Integration(duration=T, step=T / 100),
        initial=Initial(history="constant"),
    )
    assert "not read" in sim.meta["initial_condition"]


def test_named_displacement_on_a_beam_is_its_static_shape(shaper_path):
    """A named q0 on a multi-coordinate structure: the output takes the
    value, and the state is the static shape under a force there (C q0 is
    parallel to the output's row R: C q0 = R^T lambda)."""
    sy = cl.assemble(cl.load_model(shaper_path))
    sim = simulate(
        sy,
        feedback="pdo",
        position=0.85,
        delay=0.05,
        integration=Integration(duration=0.002, step=0.0001),
        initial=Initial(q0={"rfe5.y": 1e-05}),
    )
    assert sim.data["rfe5.y"][0] == pytest.approx(1e-5, rel=1e-9)
    from chatterlab.time._parametric import ParametricProblem, _output_map
    from chatterlab.time._simulate import _kinematics

    prob = ParametricProblem(sy, _kinematics(sy, None, 0.05, 0.85), width=0.002)
    R = prob.maps(np.array([0.0]), _output_map(sy, "rfe5.y")[None])[0, 0]
    Cq = prob.matrices(np.array([0.0]))[2][0] @ sim.response.q[:, 0]
    lam = float(Cq @ R / (R @ R))
    assert np.abs(Cq - lam * R).max() <= 1e-9 * np.abs(Cq).max()


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        (dict(q0=[0.0, 0.0]), "q0 must have shape (1,)"),
        (dict(v0=[float("nan")]), "v0 contains NaN"),
        (dict(q0={"nope.x": 1e-5}), "nope"),
        (dict(v0={"tip.q": 1.0}), "tip.q"),
        (dict(q0={"tip.x": float("inf")}), "q0['tip.x'] must be finite"),
        (dict(history="steady"), "history must be"),
        (dict(history=[1.0, 2.0]), "history must have shape (1,)"),
        (dict(history=(NODES[NODES >= -T / 2], hist(NODES[NODES >= -T / 2]))), "must cover [-T, 0]"),
        (dict(history=(NODES, hist(NODES)[:-1])), "q must have shape"),
        (dict(history=(NODES[::-1], hist(NODES))), "strictly increasing"),
        (dict(history=(NODES, np.where(NODES < -0.01, np.nan, 0.0))), "NaN"),
        (dict(history=lambda t: np.zeros((np.size(t), 3))), "history(t) must return shape"),
    ],
)
def test_bad_input_is_one_line(tool, kw, match):
    with pytest.raises(InputError) as exc:
        run(tool, 100, **kw)
    assert match in str(exc.value) and "\n" not in str(exc.value)


# ----------------------------------------------------------------------------- command line


@pytest.fixture
def model_file(tmp_path):
    path = tmp_path / "turning.toml"
    path.write_text(turning_text())
    return path


def test_cli_initial_condition(model_file, tmp_path, capsys):
    """--q0 in mm, --v0 in mm/s, --history constant: the run equals the API's."""
    out = tmp_path / "ic.csv"
    args = ["simulate", str(model_file), "--width", "0.3", "--delay", "0.02", "--duration", "0.04"]
    assert main([*args, "--step", "2e-5", "--v0", "tip.x=5"]) == 0
    assert "v0 = tip.x = 0.005 m/s (the state after impulses there)" in capsys.readouterr().out
    code = main([*args, "--step", "2e-5", "--q0", "tip.x=0.01", "--history", "constant", "--out", str(out)])
    assert code == 0
    text = capsys.readouterr().out
    assert "initial condition: q0 = tip.x = 1e-05 m" in text and "constant (q0 held)" in text
    import csv

    rows = list(csv.DictReader(out.open()))
    x = np.array([float(r["tool.x [m]"]) for r in rows])
    api = simulate(
        cl.assemble(cl.load_model(model_file)),
        feedback="pdo",
        width=B,
        delay=T,
        outputs=["tip.x"],
        integration=Integration(duration=2 * T, step=2e-05),
        initial=Initial(q0={"tip.x": 1e-05}, history="constant"),
    )
    np.testing.assert_allclose(x, api.data["tip.x"], rtol=1e-15, atol=0)


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        (["--q0", "tip.x"], ["--q0", "P.DIR=VALUE"]),
        (["--q0", "tip.x=abc"], ["--q0", "not a number"]),
        (["--v0", "tip.x=nan"], ["--v0", "finite"]),
        (["--q0", "nope.x=0.01"], ["nope"]),
        (["--q0", "tip.x=1", "--q0", "tip.x=2"], ["given twice"]),
    ],
)
def test_cli_bad_initial_condition_exits_2_writing_nothing(model_file, tmp_path, capsys, extra, words):
    out = tmp_path / "bad.nc"
    code = main(
        ["simulate", str(model_file), "--delay", "0.02", "--duration", "0.04", "--out", str(out), *extra]
    )
    assert_clean_error(code, capsys.readouterr().err, *words)
    assert not out.exists()


def test_cli_milling_refuses_initial_conditions(capsys):
    milling = str(Path(__file__).resolve().parents[1] / "studies" / "milling" / "benchmark_1dof.toml")
    code = main(["simulate", milling, "--width", "2", "--speed", "18000", "--q0", "tool.x=0.001"])
    assert_clean_error(code, capsys.readouterr().err, "--q0", "milling")
