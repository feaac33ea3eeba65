"""Active damping with the paper's feedback: the [[actuator]] item, the
machine with its actuators in the one closed loop, and the co-design of the
gains (chatterlab.design.design_active).

Oracles:

* velocity feedback without delay on a 1-DOF tool is extra damping: the
  absolute minimum of the limit is Tlusty's 2 k zeta' (1 + zeta') / K_f with
  zeta' = zeta + g_V / (2 sqrt(k m)), and its derivative in g_V that
  expression differentiated by hand;
* the other gains' and the delay's derivatives against central differences
  of the polished minimum (step derived below);
* with an actuator delay and a bandwidth, the co-design under a phase margin
  agrees with a brute-force grid over the gains computed here, independently:
  the limit from Tlusty's min Re G of the controlled receptance on a dense
  frequency grid, the phase margin and the controller's stability (the
  winding of 1 + L about 0, Nyquist) from the loop transfer written out;
* a delayed gain destabilises the controller at the critical delay given in
  closed form (the crossing frequency from |k - m w^2 + j c w| = |g_O|): the
  rightmost exact-delay root crosses the axis there, and past it the result
  says so (ControllerUnstable) and nothing is optimised.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import turning_text

import chatterlab as cl
from chatterlab.design import (
    ControllerUnstable,
    controller_roots,
    design_active,
    design_lobes,
    loop_margins,
    sensitivity,
    with_actuator,
    without_actuators,
)
from chatterlab.errors import InputError, ModelError

M, K, C, KF = 1.0, 1.0e7, 189.7, 2.0e9
ZETA = C / (2 * np.sqrt(K * M))
SPEEDS = np.linspace(2000.0, 6000.0, 30)


def tool(**actuator: float | str) -> cl.Model:
    """The 1-DOF turning tool of docs/model-format.md with one [[actuator]]
    "damper" sensing and pushing at its tip along x."""
    text = turning_text(mass=M, stiffness=K, damping=C, Kf=KF, forces=(200.0, 0.0, 0.0))
    lines = "".join(
        f"{k} = {v!r}\n" if not isinstance(v, str) else f'{k} = "{v}"\n' for k, v in actuator.items()
    )
    return cl.loads_model(
        text + '\n[[actuator]]\nid = "damper"\nsensor = "tip"\nsensor_direction = "x"\n' + lines
    )


def tlusty(zeta: float) -> float:
    return 2 * K * zeta * (1 + zeta) / KF


# ------------------------------------------------------------------ the item and the loop
def test_velocity_feedback_is_extra_damping():
    """b_min = 2 k zeta' (1 + zeta') / K_f, zeta' = zeta + g / (2 sqrt(k m)): the lobe
    engine's minimum is polished to round-off (its Brent refinement stops at 1e-10 of
    the frequency, a second-order error in the width), so 1e-10 relative."""
    for g in (100.0, 300.0, 3000.0):
        fz = cl.assemble(tool(velocity_gain=g)).at()
        d = design_lobes(fz, SPEEDS, width_max=0.05, verify=2)
        want = tlusty(ZETA + g / (2 * np.sqrt(K * M)))
        assert d.absolute_minimum["width"] == pytest.approx(want, rel=1e-10)
        assert d.verified


def test_the_actuator_is_a_term_of_the_closed_loop():
    """D(s) gains -b G(s) c with G = (P + s V + O e^{-s T_a}) / (1 + s / w_b), the
    structure untouched; Delta = s^2 M + s C + K - D(s) is what the roots solve."""
    from chatterlab.frequency import newton_refine
    from chatterlab.process import closed_loop

    fz = cl.assemble(tool(proportional_gain=1e5, velocity_gain=200.0, delayed_gain=3e5, delay=4e-4,
                          bandwidth_hz=700.0)).at()  # fmt: skip
    loop = closed_loop(fz, width=1e-4, speed=3000.0)
    s = np.array([300j + 20.0, 4000j - 5.0])
    G = (1e5 + s * 200.0 + 3e5 * np.exp(-s * 4e-4)) / (1 + s / (2 * np.pi * 700.0))
    bare = closed_loop(cl.assemble(without_actuators(fz.model)).at(), width=1e-4, speed=3000.0)
    assert np.allclose(loop.D(s)[:, 0, 0] - bare.D(s)[:, 0, 0], -G, rtol=1e-14)
    assert np.array_equal(loop.M, bare.M) and np.array_equal(loop.K, bare.K)
    # a root of the loop (two delays, a lag) solves the scalar characteristic equation
    lam, ok = newton_refine(np.array([-200 + 3300j]), loop)
    x = lam[0]
    Gx = (1e5 + x * 200.0 + 3e5 * np.exp(-x * 4e-4)) / (1 + x / (2 * np.pi * 700.0))
    char = M * x * x + C * x + K + Gx + 1e-4 / 1e-3 * KF * 1e-3 * (1 - np.exp(-x * 60 / 3000.0))
    assert ok[0] and abs(char) <= 1e-9 * K


# ------------------------------------------------------------------ derivatives in the gains
def test_the_derivative_in_the_velocity_gain_is_tlustys_by_hand():
    """d b_min / d g = (2 k / K_f) (1 + 2 zeta') / (2 sqrt(k m)); exact up to the
    round-off of the polished point (1e-9 relative)."""
    g = 300.0
    s = sensitivity(tool(velocity_gain=g), SPEEDS, width_max=0.05, fields=["actuator.damper.velocity_gain"])
    zp = ZETA + g / (2 * np.sqrt(K * M))
    want = 2 * K / KF * (1 + 2 * zp) / (2 * np.sqrt(K * M))
    assert s.d_absolute[0] == pytest.approx(want, rel=1e-9)
    assert s.methods == ("affine",)


def test_gain_delay_and_bandwidth_derivatives_against_central_differences():
    """The exact derivatives of the absolute minimum against central differences of
    the polished minimum over h = 1e-4 |p| (truncation h^2 b''' / 6 ~ 1e-8 relative for
    a smooth limit, round-off 1e-13 / 1e-4 = 1e-9): agreement to 1e-6."""
    mdl = tool(velocity_gain=100.0, delayed_gain=2e5, delay=2e-4, bandwidth_hz=2000.0)
    fields = ["actuator.damper.velocity_gain", "actuator.damper.delayed_gain", "actuator.damper.delay",
              "actuator.damper.bandwidth_hz"]  # fmt: skip
    s = sensitivity(mdl, SPEEDS, width_max=0.05, fields=fields)

    def bmin(path: str, value: float) -> float:
        fz = cl.assemble(mdl.with_parameter(path, value)).at()
        return float(design_lobes(fz, SPEEDS, width_max=0.05, verify=0).absolute_minimum["width"])

    for path, value, d in zip(s.fields, s.values, s.d_absolute, strict=True):
        h = 1e-4 * abs(value)
        fd = (bmin(path, value + h) - bmin(path, value - h)) / (2 * h)
        assert d == pytest.approx(fd, rel=1e-6), path


# ------------------------------------------------------------------ the co-design against brute force
T_A, F_B, PM = 3e-4, 300.0, 45.0
W = np.linspace(1.0, 40000.0, 80001)  # rad/s, step 0.5: the test's own dense grid
P_W = 1 / (K - M * W**2 + 1j * W * C)


def _G(gv: np.ndarray, go: np.ndarray) -> np.ndarray:
    return (1j * W * gv[..., None] + go[..., None] * np.exp(-1j * W * T_A)) / (1 + 1j * W / (2 * np.pi * F_B))


def _width(gv: np.ndarray, go: np.ndarray) -> np.ndarray:
    """Tlusty's absolute minimum -1 / (2 K_f min_w Re G_c), G_c the receptance with
    the controller, on the dense grid (a parabola through the lowest sample and its
    neighbours: error O(step^3))."""
    g = (1 / (K - M * W**2 + 1j * W * C + _G(gv, go))).real
    i = np.clip(np.argmin(g, axis=-1), 1, W.size - 2)
    g0, g1, g2 = (np.take_along_axis(g, (i + d)[..., None], -1)[..., 0] for d in (-1, 0, 1))
    den = g0 - 2 * g1 + g2
    gmin = np.where(den > 0, g1 - (g2 - g0) ** 2 / (8 * np.where(den > 0, den, 1.0)), g1)
    return -1 / (2 * KF * gmin)


def _pm_and_stable(gv: np.ndarray, go: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The phase margin (each |L| = 1 crossing by linear interpolation of log|L|, the
    phase there interpolated) and Nyquist's verdict: 1 + L (L -> 0, the open loop
    stable) does not wind about 0 from w = 0 to infinity and back (conjugate)."""
    L = _G(gv, go) * P_W
    with np.errstate(divide="ignore"):  # L = 0 where both gains are 0
        a = np.log(np.abs(L))
    ph = np.angle(L)
    pm = np.full(gv.shape, np.inf)
    for idx in np.ndindex(gv.shape):
        j = np.nonzero(np.sign(a[idx][:-1]) * np.sign(a[idx][1:]) < 0)[0]
        for i in j:
            t = a[idx][i] / (a[idx][i] - a[idx][i + 1])
            p = ph[idx][i] + t * np.angle(np.exp(1j * (ph[idx][i + 1] - ph[idx][i])))
            pm[idx] = min(pm[idx], 180 - abs(np.degrees(np.angle(np.exp(1j * p)))))
    f = np.unwrap(np.angle(1 + L), axis=-1)
    wind = (f[..., -1] - f[..., 0]) / np.pi
    return pm, np.abs(wind) < 0.5


def brute_force(lo: tuple[float, float], hi: tuple[float, float]) -> tuple[float, float, float]:
    """The best feasible point (PM >= 45 deg, stable) of nested 11 x 11 grids over
    (g_V, g_O), each level +-2 cells of the previous best (8 levels): every grid point's
    width is one the design takes, so the best is a lower bound of the optimum."""
    cv, co = 0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])
    hv, ho = 0.5 * (hi[0] - lo[0]), 0.5 * (hi[1] - lo[1])
    best = (-np.inf, cv, co)
    for _ in range(8):
        gv, go = np.meshgrid(
            np.clip(np.linspace(cv - hv, cv + hv, 11), lo[0], hi[0]),
            np.clip(np.linspace(co - ho, co + ho, 11), lo[1], hi[1]),
            indexing="ij",
        )
        pm, ok = _pm_and_stable(gv, go)
        b = np.where(ok & (pm >= PM), _width(gv, go), -np.inf)
        i, j = np.unravel_index(np.argmax(b), b.shape)
        if b[i, j] > best[0]:
            best = (float(b[i, j]), float(gv[i, j]), float(go[i, j]))
        cv, co = best[1], best[2]
        hv, ho = 2 * hv / 10, 2 * ho / 10
    return best


@pytest.fixture(scope="module")
def constrained():
    mdl = tool(velocity_gain=200.0, delay=T_A, bandwidth_hz=F_B)
    return design_active(
        mdl, SPEEDS, objective="absolute", free=("velocity", "delayed"),
        bounds={"velocity": (0.0, 3000.0), "delayed": (-1e6, 1e6)}, gain_margin=1.0, phase_margin=PM,
        starts=2, width_max=0.05, verify=4,
    )  # fmt: skip


def test_the_co_design_reaches_the_brute_force_optimum(constrained):
    """The optimiser (exact gradients, SQP) against the independent brute force: the
    brute force's best is feasible, so the optimum is at least it (less the brute
    force's own error: its PM interpolated on a 0.5 rad/s grid, ~1e-3 deg, i.e. 0.1
    N s/m of g_V at d PM / d g_V = 0.013 deg per N s/m, 4e-8 m of width); the grid's
    last step (3000 x 0.4^7 / 10 = 0.5 N s/m in g_V) leaves it below the optimum by at
    most d b / d g_V (3.6e-7 m per N s/m here) x that: 2e-4 relative bounds both."""
    des = constrained
    b_bf, gv_bf, go_bf = brute_force((0.0, -1e6), (3000.0, 1e6))
    (a,) = des.actuators
    assert des.width >= b_bf * (1 - 4e-5)
    assert des.width == pytest.approx(b_bf, rel=2e-4)
    assert a["velocity_gain"] == pytest.approx(gv_bf, abs=1.0)
    assert a["delayed_gain"] == pytest.approx(go_bf, abs=1e-3 * 1e6)
    # the optimum's own limit and margin, recomputed here, are the ones it reports
    assert des.width == pytest.approx(float(_width(np.array(a["velocity_gain"]), np.array(a["delayed_gain"]))),
                                      rel=1e-6)  # fmt: skip
    pm, ok = _pm_and_stable(np.array([a["velocity_gain"]]), np.array([a["delayed_gain"]]))
    assert ok[0] and pm[0] == pytest.approx(a["phase_margin_deg"], abs=1e-2)
    assert a["phase_margin_deg"] >= PM - 1e-4  # the constraint holds (SLSQP's tolerance)
    assert des.verified and des.abscissa < 0


def test_the_phase_margin_is_the_loop_transfers(constrained):
    """loop_margins against the loop transfer written out: the PM of the test's dense
    grid (linear interpolation over 0.5 rad/s: ~1e-3 deg)."""
    from chatterlab.design._active import _loop_matrices, margin_grid

    fz = cl.assemble(constrained.model).at()
    L = _loop_matrices(fz, "pdo")
    mg = loop_margins(L, 0, margin_grid(L))
    (a,) = constrained.actuators
    pm, _ = _pm_and_stable(np.array([a["velocity_gain"]]), np.array([a["delayed_gain"]]))
    assert mg.phase_deg == pytest.approx(pm[0], abs=1e-2)


# ------------------------------------------------------------------ a delay that destabilises the controller
G_O = 2.0e6


def critical_delay() -> tuple[float, float]:
    """(T_c, w_c): the smallest delay at which m s^2 + c s + k + g_O e^{-s T} has a
    root j w_c: |k - m w^2 + j c w| = g_O (a quadratic in w^2), e^{-j w T} =
    -(k - m w^2 + j c w) / g_O."""
    x = np.roots([M * M, C * C - 2 * K * M, K * K - G_O * G_O])
    best = (np.inf, np.nan)
    for w in np.sqrt(x[(x.imag == 0) & (x.real > 0)].real):
        phi = np.angle(-(K - M * w * w + 1j * C * w) / G_O)  # = -w T mod 2 pi
        T = np.mod(-phi, 2 * np.pi) / w
        best = min(best, (float(T), float(w)))
    return best


def test_a_large_delay_destabilises_the_controller_at_the_closed_form_delay():
    T_c, w_c = critical_delay()
    assert 0 < T_c < 1e-2
    # at T_c the rightmost exact-delay root is on the axis at w_c (Newton to 1e-13)
    r = controller_roots(cl.assemble(tool(delayed_gain=G_O, delay=T_c)).at())
    assert abs(r.roots[0].real) <= 1e-9 * w_c and r.roots[0].imag == pytest.approx(w_c, rel=1e-9)
    below = controller_roots(cl.assemble(tool(delayed_gain=G_O, delay=0.99 * T_c)).at())
    above = controller_roots(cl.assemble(tool(delayed_gain=G_O, delay=1.01 * T_c)).at())
    assert below.abscissa < 0 < above.abscissa
    fz = cl.assemble(tool(delayed_gain=G_O, delay=1.01 * T_c)).at()
    with pytest.raises(ControllerUnstable, match="unstable without cutting") as exc:
        design_lobes(fz, SPEEDS, width_max=0.05)
    assert "\n" not in str(exc.value) and "T_a" in str(exc.value)
    with pytest.raises(ControllerUnstable):  # nothing optimised
        design_active(fz.model, SPEEDS, width_max=0.05)
    assert isinstance(exc.value, InputError)


# ------------------------------------------------------------------ bad input
ACT = '\n[[actuator]]\nid = "damper"\n'


@pytest.mark.parametrize(
    ("fields", "words"),
    [
        (
            'sensor = "tip"\nsensor_direction = "x"\nvelocity_gain = -10.0\n',
            ["velocity_gain", "must be >= 0"],
        ),
        ('sensor = "nowhere"\nsensor_direction = "x"\nvelocity_gain = 10.0\n', ["'nowhere' is not a point"]),
        ('sensor = "ground"\nsensor_direction = "x"\nvelocity_gain = 10.0\n', ["sensor", "on the ground"]),
        ('sensor = "tip"\nvelocity_gain = 10.0\n', ["sensor_direction", "missing"]),
        ('sensor = "tip"\nsensor_direction = "z"\nvelocity_gain = 10.0\n', ['"x" or "y"']),
        ('sensor = "tip"\nsensor_direction = "x"\n', ["every gain is 0"]),
        ('sensor = "tip"\nsensor_direction = "x"\nvelocity_gain = 1.0\ndelay = -1e-3\n', ["delay", ">= 0"]),
        (
            'sensor = "tip"\nsensor_direction = "x"\nvelocity_gain = 1.0\nbandwidth_hz = 0.0\n',
            ["bandwidth_hz", "> 0"],
        ),
        (
            'sensor = "tip"\nsensor_direction = "x"\nvelocity_gain = 1.0\nforce_limit = -5.0\n',
            ["force_limit", "> 0"],
        ),
        (
            'sensor = "tip"\nsensor_direction = "x"\nvelocity_gain = 1.0\ngain = 1.0\n',
            ["unknown field 'gain'"],
        ),
    ],
)
def test_bad_actuator_fields_are_refused_in_one_line(fields, words):
    with pytest.raises(ModelError) as exc:
        cl.loads_model(turning_text() + ACT + fields)
    msg = str(exc.value)
    assert "\n" not in msg and '[[actuator]] "damper"' in msg
    for w in words:
        assert w in msg


@pytest.mark.parametrize(
    ("kw", "words"),
    [
        ({"bounds": {"velocity": (-5.0, 10.0)}}, ["velocity gain must be >= 0"]),
        ({"bounds": {"delayed": (5.0, 5.0)}}, ["the bound is empty"]),
        ({"bounds": {"velocity": (10.0, 1.0)}}, ["the bound is empty"]),
        ({"free": ("stiffness",)}, ["free gains must be among"]),
        ({"free": ("delayed",)}, ["the delayed gain needs a delay"]),
        ({"actuators": ["nope"]}, ["unknown actuator 'nope'"]),
        ({"gain_margin": 0.5}, ["gain_margin"]),
        ({"force_limit": -1.0}, ["force_limit"]),
        ({"places": [("tip.z", "tip.x")]}, ["POINT.DIR"]),
    ],
)
def test_bad_co_design_options_are_one_line(kw, words):
    with pytest.raises(InputError) as exc:
        design_active(tool(velocity_gain=10.0), SPEEDS, width_max=0.05, **kw)
    msg = str(exc.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg


def test_with_actuator_names_the_unknown_point():
    with pytest.raises(ModelError, match="'nowhere' is not a point"):
        with_actuator(cl.loads_model(turning_text()), "d", "nowhere.x", velocity_gain=1.0)


# ------------------------------------------------------------------ the time domain confirms
def test_the_time_domain_confirms_velocity_feedback_proven():
    """Velocity feedback without delay or lag: one delay (the cut's), so the
    argument principle's count is proven and the verdict may say stable; at 1.1
    times the old limit (below the new one, Tlusty's closed form with zeta') the
    run decays at the rightmost root's rate within its own error bar (2 fit
    standard errors + Richardson's step error), and above the new limit the
    verdict is unstable."""
    from chatterlab.design._confirm import confirm_loop

    g = 300.0
    fz = cl.assemble(tool(velocity_gain=g)).at()
    old, new = tlusty(ZETA), tlusty(ZETA + g / (2 * np.sqrt(K * M)))
    # by the closed forms old = 0.309 mm and new = 0.834 mm: 1.1 old is well below the new limit
    c = confirm_loop(fz, 3000.0, 1.1 * old, old)
    assert c.verdict == "stable" and c.count_proven and c.rhp_count == 0
    assert c.abscissa < 0 and c.time_class == "decaying"
    assert abs(c.rate - c.abscissa) <= c.rate_error and c.rate_agrees
    # the actuator's force is -g v: bounded by g times the largest velocity, positive
    assert 0 < c.forces[0] < np.inf and c.force_ok
    up = confirm_loop(fz, 3000.0, 1.05 * new, old, duration=0.02)
    assert up.verdict == "unstable" and up.abscissa > 0


def test_the_run_with_lag_and_delay_ends_at_the_static_force():
    """The run of the loop with an actuator lag (its own coordinate) and
    delay (stepped against the cut's) ends at the static balance: at s = 0 the
    cut's proportional and delayed terms cancel (b K_f (1 - e^0) = 0), so
    y_s = F_0 / (k + g_P + g_O) and f_a = -(g_P + g_O) y_s, whatever the lag and
    the delays; after 10 / |sigma_1| of decay the transient is e^-10 = 4.5e-5 of
    its start and the trapezoidal rule is exact for a constant state: 1e-4."""
    from chatterlab.design._confirm import _augmented, _run
    from chatterlab.process import closed_loop

    gp, go = 2e5, 3e5
    fz = cl.assemble(tool(proportional_gain=gp, velocity_gain=300.0, delayed_gain=go, delay=3e-4,
                          bandwidth_hz=300.0)).at()  # fmt: skip
    loop = closed_loop(fz, width=1e-4, speed=3000.0)
    sysm = _augmented(loop)
    assert sysm["M"].shape == (2, 2) and len(sysm["delays"]) == 2  # the lag's coordinate, two delays
    from chatterlab.design import controller_roots

    lam = controller_roots(fz).roots[0]
    t, y, F, status = _run(sysm, 2e-5, 10.0 / 50.0)
    assert status == "ok" and lam.real < 0
    F0 = float(loop.force[0])
    ys = F0 / (K + gp + go)
    assert abs(y[-1]) == pytest.approx(ys, rel=1e-4)  # the signal's sign is its SVD's
    assert F[0, -1] == pytest.approx(-(gp + go) * ys, rel=1e-4)


def test_the_co_design_carries_its_confirmation(constrained):
    """The design's confirmation: the cut at the optimised gains and 1.1 times
    the bare limit, with the actuator's delay and lag (two delays: the count
    sampled, so never "stable"); the run decays at the rightmost root's rate."""
    c = constrained.confirmation
    assert c is not None
    assert c.width == pytest.approx(1.1 * constrained.bare_width, rel=1e-12)
    assert c.count_proven is False and c.verdict == "undetermined" and c.rhp_count == 0
    assert c.abscissa < 0 and c.time_class == "decaying" and c.rate_agrees
    assert "time-domain confirmation" in constrained.summary()
    assert "UNDETERMINED" in constrained.summary()
