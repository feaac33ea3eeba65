"""Exact sensitivities of the stability limit (chatterlab.design).

Oracles:

* the 1-DOF tool's absolute minimum b_min = 2 k zeta (1 + zeta) / K_f with
  zeta = c / (2 sqrt(k m)) (Tlusty; tests/test_lobes.py), differentiated by
  hand:  db/dk = c / (2 sqrt(k m) K_f),  db/dc = (sqrt(k/m) + c/m) / K_f,
  db/dm = -(c sqrt(k) / (2 m^1.5) + c^2 / (2 m^2)) / K_f,  db/dK_f = -b/K_f;
* fourth-order central finite differences of the lobe engine's own b_lim (at
  fixed speeds) and absolute minimum, with the derived step h = eps_b^(1/5) |p|
  and the error bound of :func:`fd` (eps_b = 1e-12, the engine's relative
  accuracy of a limit: tests/test_lobes.py finds its envelope within 4e-13 of
  Tlusty's closed form);
* invariants: a process field that changes only the delay leaves the
  absolute minimum unchanged (its derivative is exactly 0) and moves b_lim.
"""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from conftest import turning_text

import chatterlab as cl
from chatterlab.design import design_fields, field_derivative, field_value, loop_matrices, sensitivity
from chatterlab.errors import InputError
from chatterlab.io import read_netcdf
from chatterlab.lobes import lobes

EPS = float(np.finfo(float).eps)
M, K, C, KF = 1.0, 1.0e7, 189.7, 2.0e9
ZETA = C / (2 * np.sqrt(K * M))
EPS_B = 1e-12  #: the lobe engine's relative accuracy of a limit (module docstring)

TWO_DOF = """
[model]
name = "2-DOF tool with an absorber"
[[body]]
id = "tool"
mass = 1.0
inertia = 1.0e-3
centre = [0.0, 0.0]
[[support]]
body = "tool"
fix = ["rz"]
[[spring]]
id = "holder"
a = "tool"
b = "ground"
c1 = 1.0e7
c2 = 1.6e7
d1 = 190.0
d2 = 300.0
[[coupling]]
id = "cut"
a = "tool"
b = "ground"
model = "regenerative"
width_ref = 0.001
Kf = 2.0e9
force_angle_deg = 70.0
normal_angle_deg = 30.0
[[absorber]]
id = "tva"
at = "tool"
angle_deg = 20.0
mass = 0.05
frequency_hz = 480.0
damping_ratio = 0.08
[process]
kind = "turning"
rpm = 3000.0
"""


def one_dof(**kw: float) -> cl.Model:
    return cl.loads_model(turning_text(mass=M, stiffness=K, damping=C, Kf=KF, **kw))


@pytest.fixture(scope="module")
def turning_sens():
    return sensitivity(
        one_dof(),
        np.linspace(9000.0, 14000.0, 40),
        fields=["spring.holder.c1", "spring.holder.d1", "body.tool.mass", "coupling.cut.Kf"],
    )


def test_one_dof_minimum_and_its_derivatives_are_the_closed_form(turning_sens):
    s = turning_sens
    b = 2 * K * ZETA * (1 + ZETA) / KF
    hand = {
        "spring.holder.c1": C / (2 * np.sqrt(K * M) * KF),
        "spring.holder.d1": (np.sqrt(K / M) + C / M) / KF,
        "body.tool.mass": -(C * np.sqrt(K) / (2 * M**1.5) + C**2 / (2 * M**2)) / KF,
        "coupling.cut.Kf": -b / KF,
    }
    # the boundary is solved to 4 eps by Newton's method; the 2x2 system of the implicit
    # derivative has a condition of order 1/zeta; the matrix derivatives of these affine
    # fields are exact to a few eps: 1e3 eps / zeta bounds the relative error
    tol = 1e3 * EPS / ZETA
    assert s.absolute_minimum["width"] == pytest.approx(b, rel=tol)
    # 9000..14000 rpm holds the bottom of lobe k = 2 (11 286 rpm): the range minimum is the same point
    assert s.minimum["at"] == "bottom"
    assert s.minimum["width"] == pytest.approx(b, rel=tol)
    assert 9000 < s.minimum["speed"] < 14000
    for i, f in enumerate(s.fields):
        assert s.methods[i] == "affine"
        assert s.d_absolute[i] == pytest.approx(hand[f], rel=tol), f
        assert s.d_minimum[i] == pytest.approx(hand[f], rel=tol), f
        assert s.err_absolute[i] <= tol * abs(hand[f])


def test_the_table_ranks_what_raises_the_minimum(turning_sens):
    s = turning_sens
    order = [s.fields[i] for i in s.ranked()]
    # p db/dp: damping raises b_min most (elasticity 1 + zeta/(1+zeta) ... > 0), K_f lowers it (-1)
    assert order[0] == "spring.holder.d1"
    assert order[-1] == "coupling.cut.Kf"
    el = s.values * s.d_minimum / s.minimum["width"]
    assert el[s.fields.index("coupling.cut.Kf")] == pytest.approx(-1.0, rel=1e-12)
    text = s.table()
    assert "spring.holder.d1" in text.splitlines()[3]


def fd(fun, p: float, f0, scale: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Fourth-order central difference of fun (array-valued; f0 = fun(p)) at p with the
    derived step h = eps_b^(1/5) s (truncation h^4 f^(5) / 30 against round-off
    1.5 eps_b |f| / h, for a function that varies on the scale s of p: s = |p| unless
    given), and its error bound: the distance to the second-order difference on the
    same points (the size of the h^2 term, which the fourth-order difference removes:
    an upper bound of what remains) plus the round-off."""
    h = EPS_B**0.2 * (abs(p) if scale is None else scale)
    f2m, f1m, f1p, f2p = (np.asarray(fun(p + k * h)) for k in (-2, -1, 1, 2))
    d2 = (f1p - f1m) / (2 * h)
    d4 = (8 * (f1p - f1m) - (f2p - f2m)) / (12 * h)
    return d4, np.abs(d4 - d2) + 1.5 * EPS_B * np.abs(f0) / h


@pytest.fixture(scope="module")
def two_dof_sens():
    model = cl.loads_model(TWO_DOF)
    speeds = np.array([4000.0, 7100.0, 12500.0])
    fields = [
        "spring.holder.c2",
        "body.tool.mass",
        "coupling.cut.force_angle_deg",  # not affine
        "absorber.tva.frequency_hz",  # not affine: k = m (2 pi f)^2
        "absorber.tva.damping_ratio",  # affine: c = 2 zeta sqrt(k m) at fixed k and m
    ]
    return model, speeds, sensitivity(model, speeds, fields=fields)


def test_methods_are_found(two_dof_sens):
    _, _, s = two_dof_sens
    assert s.methods == ("affine", "affine", "central", "central", "affine")


@pytest.mark.parametrize("i", range(5))
def test_b_lim_derivatives_agree_with_finite_differences(two_dof_sens, i):
    model, speeds, s = two_dof_sens
    path = s.fields[i]

    def limits(p: float) -> np.ndarray:
        """b_lim at the speeds and the absolute minimum, by the lobe engine."""
        d = lobes(cl.assemble(model.with_parameter(path, p)).at(), speeds, width_max=0.02, verify=0)
        return np.r_[d.b_lim, d.absolute_minimum["width"]]

    exact = np.r_[s.d_b_lim[i], s.d_absolute[i]]
    d, err = fd(limits, s.values[i], np.r_[s.b_lim, s.absolute_minimum["width"]])
    assert np.all(np.isfinite(exact))
    err[-1] += s.err_absolute[i]
    assert np.all(np.abs(exact - d) <= err), (path, exact, d, err)


SHAPING = """[process]
kind = "shaping"
speed = 0.5
return_speed = 2.0
run_in = 0.01
cut = 0.02
coast = 0.01
"""


def test_a_process_field_moves_b_lim_but_not_the_absolute_minimum():
    """return_speed changes the delay T = L/v + L/v_l at every speed, so b_lim at a
    speed on a lobe's flank moves; the boundary curve b(w) -- and so its minimum
    over all delays -- does not depend on the kinematics at all."""
    text = turning_text(mass=M, stiffness=K, damping=C, Kf=KF).split("[process]")[0] + SHAPING
    model = cl.loads_model(text)
    speeds = np.array([0.31, 0.47])
    s = sensitivity(model, speeds, fields=["process.return_speed"])
    assert s.d_absolute[0] == 0.0

    def b_lim(p: float) -> np.ndarray:
        m = model.with_parameter("process.return_speed", p)
        return lobes(cl.assemble(m).at(), speeds, width_max=0.02, verify=0).b_lim

    # b_lim(T) varies on the scale of one lobe, a delay of one chatter period 1/f_c: in
    # return_speed v_l that is (1/f_c) / |dT/dv_l|, dT/dv_l = -L / v_l^2 (L = 0.04 m)
    scale = (1 / s.diagram.chatter_hz.max()) / (0.04 / 2.0**2)
    d, err = fd(b_lim, 2.0, s.b_lim, scale)
    assert np.all(s.d_b_lim[0] != 0.0)
    assert np.all(np.abs(s.d_b_lim[0] - d) <= err), (s.d_b_lim[0], d, err)


def test_affine_fields_are_exact_and_the_others_detected():
    model = cl.loads_model(TWO_DOF)
    L = loop_matrices(model)
    c2 = field_derivative(model, "spring.holder.c2", base=L)
    assert c2.method == "affine"
    # dK/dc2 of a spring along the axes is e2 e2^T exactly (y is coordinate 1)
    assert c2.d.K[1, 1] == pytest.approx(1.0, rel=1e-12, abs=1e-12)
    assert abs(c2.d.K[0, 0]) <= 1e-9 and not np.any(c2.d.M) and not np.any(c2.d.P)
    fa = field_derivative(model, "coupling.cut.force_angle_deg", base=L)
    assert fa.method == "central"
    # P = K_f f n^T (b = 1 m), f = (cos a, sin a): dP/da = K_f (-sin a, cos a) n^T pi/180
    a, n = np.radians(70.0), np.radians(30.0)
    exact = 2e9 * np.outer([-np.sin(a), np.cos(a), 0], [np.cos(n), np.sin(n), 0]) * np.pi / 180
    # central difference with the derived step: relative error ~ eps^(2/3) ~ 4e-11 of |P|, and
    # |P| / |dP| = 180 / pi here: 1e-8 of |dP| is 4e-11 with a factor 4 to spare
    assert np.allclose(fa.d.P, exact, rtol=0, atol=1e-8 * np.abs(exact).max())
    # its error estimate (the truncation term from a third difference) bounds the actual error
    err = np.abs(fa.d.P - fa.alt.P).max()
    assert np.abs(fa.d.P - exact).max() <= err + 64 * EPS * np.abs(L.P).max() / fa.step


MODAL = """
[[mode]]
id = "x1"
frequency_hz = 500.0
damping_ratio = 0.03
stiffness = 1.0e7
direction = "tool.x"
[[point]]
id = "tip"
coords = { x = "tool.x" }
[[coupling]]
id = "cut"
a = "tip"
b = "ground"
model = "regenerative"
width_ref = 0.001
Kf = 2.0e9
[process]
kind = "turning"
rpm = 3000.0
"""


@pytest.mark.parametrize(
    ("which", "path", "affine"),
    [
        ("two_dof", "spring.holder.c1", True),
        ("two_dof", "spring.holder.d2", True),
        ("two_dof", "body.tool.mass", True),
        ("two_dof", "body.tool.inertia", True),
        ("two_dof", "coupling.cut.Kf", True),
        ("two_dof", "absorber.tva.damping_ratio", True),
        ("two_dof", "absorber.tva.mass", True),  # f and zeta written: k, c and m all scale with m
        ("two_dof", "absorber.tva.frequency_hz", False),
        ("two_dof", "coupling.cut.force_angle_deg", False),
        ("shaper", "beam.table.rho", True),
        ("shaper", "beam.table.eta", True),
        ("shaper", "beam.table.E", True),  # G follows E through nu
        ("shaper", "coupling.cut.K3", True),
        ("shaper", "beam.table.I", False),
        ("shaper", "beam.table.A", False),
        ("shaper", "beam.table.nu", False),
        ("modal", "mode.x1.stiffness", True),
        ("modal", "mode.x1.damping_ratio", True),
        ("modal", "mode.x1.frequency_hz", False),
    ],
)
def test_the_affinity_table_is_right(which, path, affine, shaper_path):
    """Every field the table calls affine has a vanishing second difference of all the
    loop's matrices over a step of a quarter of its value (relative 1e-9 of each block:
    round-off of a few assemblies), every one it calls non-affine a nonvanishing one."""
    from chatterlab.design import field_affinity
    from chatterlab.design._matrices import _vanishes

    model = {"two_dof": lambda: cl.loads_model(TWO_DOF), "modal": lambda: cl.loads_model(MODAL)}.get(
        which, lambda: cl.load_model(shaper_path)
    )()
    assert field_affinity(model, path) is affine
    p = field_value(model, path)
    pos = 0.85 if which == "shaper" else None
    X = [loop_matrices(model.with_parameter(path, p * f), position=pos) for f in (0.75, 1.0, 1.25)]
    second = X[0].combine([1.0, -2.0, 1.0], X)
    assert _vanishes(second, X) is affine


def test_default_fields_include_the_joint_damping():
    model = cl.loads_model(TWO_DOF)
    f = design_fields(model)
    assert "spring.holder.c1" in f and "spring.holder.d1" in f
    assert "absorber.tva.mass" in f and "absorber.tva.frequency_hz" in f
    assert "coupling.cut.Kf" in f and "coupling.cut.force_angle_deg" not in f
    assert "coupling.cut.width_ref" not in f


def test_files_and_plot(turning_sens, tmp_path):
    s = turning_sens
    p = s.to_csv(tmp_path / "s.csv")
    rows = list(csv.reader(open(p)))
    assert rows[0][:3] == ["rank", "field", "field_unit"]
    assert rows[1][1] == "spring.holder.d1"
    col = rows[0].index("d_minimum [m/unit]")
    got = {r[1]: float(r[col]) for r in rows[1:]}
    for i, f in enumerate(s.fields):
        assert got[f] == s.d_minimum[i]  # the shortest repr reads back exactly
    nc = s.to_netcdf(tmp_path / "s.nc")
    back = read_netcdf(nc)
    assert np.array_equal(back.data["d_minimum"][0], s.d_minimum)
    assert back.dims["d_b_lim"] == ("field", "speed") and back.data["d_b_lim"][0].shape == (4, 40)
    assert json.loads(back.attrs["fields"]) == list(s.fields)
    import matplotlib

    matplotlib.use("Agg")
    ax = s.plot()
    assert len(ax.patches) == 4
    assert ax.get_yticklabels()[0].get_text() == "spring.holder.d1"


@pytest.mark.parametrize(
    ("fields", "words"),
    [
        (["spring.nothere.c1"], ["spring.nothere.c1", "no [[spring]] with id 'nothere'"]),
        (["spring.holder.c9"], ["spring.holder.c9", "has no field 'c9'"]),
        (["body.tool.centre"], ["body.tool.centre", "not a number"]),
        (["holder"], ["holder", "KIND.ID.FIELD"]),
        ([], ["no fields"]),
    ],
)
def test_bad_fields_are_refused_in_one_line(fields, words):
    with pytest.raises(InputError) as exc:
        sensitivity(one_dof(), np.linspace(9000.0, 14000.0, 5), fields=fields)
    msg = str(exc.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg


SYMMETRIC = """
[[body]]
id = "tool"
mass = 1.0
inertia = 1.0e-3
centre = [0.0, 0.0]
[[support]]
body = "tool"
fix = ["rz"]
[[spring]]
id = "holder"
a = "tool"
b = "ground"
c1 = 1.0e7
c2 = 1.0e7
d1 = 190.0
d2 = 190.0
[[coupling]]
id = "cut"
a = "tool"
b = "ground"
width_ref = 0.001
DP = [[2.0e6, 0.0, 0.0], [0.0, 2.0e6, 0.0], [0.0, 0.0, 0.0]]
DO = [[-2.0e6, 0.0, 0.0], [0.0, -2.0e6, 0.0], [0.0, 0.0, 0.0]]
[process]
kind = "turning"
rpm = 3000.0
"""


def test_two_boundaries_meeting_have_no_derivative():
    """Equal x and y modes under an isotropic cut: det X = (1 + b K_f (1 - z) G)^2, every
    boundary point a double zero.  Stiffening x moves x's boundary only, so the minimum (the
    lower of two equal boundaries) has two one-sided derivatives and no derivative: nan,
    and the table says why."""
    s = sensitivity(cl.loads_model(SYMMETRIC), np.linspace(9000.0, 14000.0, 20), fields=["spring.holder.c1"])
    assert s.degenerate
    assert np.isnan(s.d_minimum[0]) and np.isnan(s.d_absolute[0])
    assert "no derivative" in s.table()
    # the limit itself is the 1-DOF closed form with c = 190 N s/m
    z = 190.0 / (2 * np.sqrt(K * M))
    assert s.absolute_minimum["width"] == pytest.approx(2 * K * z * (1 + z) / KF, rel=1e3 * EPS / z)


def test_field_value_reads_the_model_after_its_variant_and_overrides():
    """The value a sensitivity is taken at is the model's own
    (chatterlab.model.parameter_value): an override (--set) and a variant
    (--variant) change it; a field the file leaves out reads its default."""
    text = (
        turning_text(mass=M, stiffness=K, damping=C, Kf=KF)
        + '\n[variant.stiff]\n"spring.holder.c1" = 2.5e7\n'
    )
    base = cl.loads_model(text)
    assert field_value(base, "spring.holder.c1") == K
    assert field_value(base.with_parameter("spring.holder.c1", 3e7), "spring.holder.c1") == 3e7
    assert field_value(cl.loads_model(text, variant="stiff"), "spring.holder.c1") == 2.5e7
    assert field_value(base, "spring.holder.d6") == 0.0  # not written: the spring's default
