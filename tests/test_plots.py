"""The plots of chatterlab.plot draw the result's own data, and say what it is.

Each test draws on the Agg backend from a small model (the 1-DOF turning
benchmark, a cantilever) and reads the artists back: the plotted xdata/ydata
are compared with the result's arrays (to round-off: the plot only scales
units), and where the plot computes something itself (the width at which a
Nyquist locus touches the critical point, the mode scale) it is compared with
an independent closed form.  The house rules of issue 9 are checked on the
source: no module of plot/ over 500 lines, no function over 100.
"""

from __future__ import annotations

import ast
import importlib.util
import warnings
from pathlib import Path

import numpy as np
import pytest

import chatterlab as cl

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402

from chatterlab import plot as P  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _study(rel: str):
    spec = importlib.util.spec_from_file_location("plots_" + Path(rel).stem, ROOT / rel)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def tb():
    return _study("studies/turning_benchmark.py")


@pytest.fixture(scope="module")
def turning(tb):
    return cl.assemble(cl.loads_model(tb.MODEL, source="turning_benchmark.py")).at()


@pytest.fixture(autouse=True)
def _close():
    yield
    plt.close("all")


def _by_gid(ax, gid):
    return [ln for ln in ax.get_lines() if ln.get_gid() == gid]


# ------------------------------------------------------------------ the house rules


def test_plot_modules_and_functions_are_small():
    for p in sorted((ROOT / "chatterlab" / "plot").glob("*.py")):
        text = p.read_text()
        assert text.count("\n") <= 500, f"{p.name}: {text.count(chr(10))} lines"
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.FunctionDef):
                n = node.end_lineno - node.lineno + 1
                assert n <= 100, f"{p.name}:{node.lineno} {node.name}() has {n} lines"


def test_axes_is_a_deprecated_alias_of_ax(turning):
    w = 2 * np.pi * np.linspace(300, 700, 50)
    r = cl.frf(turning, w, inputs=["tool.x"], outputs=["tool.x"])
    fig, pair = plt.subplots(2, 1)
    with pytest.warns(DeprecationWarning, match="ax="):
        got = P.plot_frf([r], axes=pair)
    assert tuple(got) == tuple(pair) and pair[0].get_lines()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert tuple(P.plot_frf([r], ax=pair)) == tuple(pair)
    with pytest.raises(TypeError, match="once"):
        P.plot_frf([r], ax=pair, axes=pair)


# ------------------------------------------------------------------ FRF


def test_frf_draws_the_frf_open_and_closed_loop(turning, tb):
    fn = np.sqrt(tb.STIFF / tb.MASS) / (2 * np.pi)
    w = 2 * np.pi * np.linspace(0.8 * fn, 1.2 * fn, 4001)
    op = cl.frf(turning, w, inputs=["tool.x"], outputs=["tool.x"])
    fb = cl.closed_loop(turning, width=1e-3, speed=3000.0, terms="pdo")
    cl_ = cl.frf(fb, w, inputs=["tool.x"], outputs=["tool.x"])
    ax_m, ax_p = P.plot_frf([op, cl_], peaks=1)
    mags, phases = _by_gid(ax_m, "magnitude"), _by_gid(ax_p, "phase")
    for r, m, p in zip((op, cl_), mags, phases, strict=True):
        z = r.data[0, 0]
        np.testing.assert_array_equal(m.get_xdata(), r.frequency_hz)
        np.testing.assert_allclose(m.get_ydata(), np.abs(z), rtol=1e-15)
        # the unwrapped phase is the phase of z up to whole turns, and continuous
        ph = np.asarray(p.get_ydata())
        turns = (ph - np.degrees(np.angle(z))) / 360.0
        np.testing.assert_allclose(turns, np.round(turns), atol=1e-9)
        assert np.max(np.abs(np.diff(ph))) < 180
    legend = [t.get_text() for t in ax_m.get_legend().get_texts()]
    assert legend[0] == "open loop" and "b = 1 mm" in legend[1] and "T = 0.02 s" in legend[1]
    # the open-loop resonance is labelled at the damped peak of 1/(k - m w^2 + j c w):
    # w_p = w_n sqrt(1 - 2 zeta^2); the label has 0.1 Hz resolution
    zeta = tb.DAMP / (2 * np.sqrt(tb.STIFF * tb.MASS))
    fp = fn * np.sqrt(1 - 2 * zeta**2)
    labels = [t for t in ax_m.texts if t.get_gid() == "peak-label"]
    assert abs(float(labels[0].get_text().split()[0]) - fp) <= 0.05 + 1e-9


def test_frf_real_and_imaginary_parts(turning):
    w = 2 * np.pi * np.linspace(300, 700, 200)
    r = cl.frf(turning, w, inputs=["tool.x"], outputs=["tool.x"])
    ax_r, ax_i = P.plot_frf([r], part="reim")
    (re,), (im,) = _by_gid(ax_r, "real"), _by_gid(ax_i, "imag")
    np.testing.assert_array_equal(re.get_ydata(), r.data[0, 0].real)
    np.testing.assert_array_equal(im.get_ydata(), r.data[0, 0].imag)
    assert ax_r.get_ylabel().startswith("Re ") and ax_i.get_ylabel().startswith("Im ")


def test_close_peak_labels_do_not_overlap():
    """Two resonances 0.2 Hz apart (the shaper's 76.3/76.1 Hz) get two readable labels."""
    from types import SimpleNamespace

    f = np.linspace(70, 82, 3001)

    def res(f0, label):
        z = 1.0 / (f0**2 - f**2 + 0.02j * f0 * f)
        return SimpleNamespace(
            outputs=("a",), inputs=("a",), data=z[None, None], frequency_hz=f, unit="m/N", label=label,
            peaks=lambda o, i, n, z=z: [(float(f[np.argmax(np.abs(z))]), float(np.abs(z).max()))],
        )  # fmt: skip

    ax_m, _ = P.plot_frf([res(76.3, "one"), res(76.1, "two")], peaks=1)
    ax_m.figure.canvas.draw()
    from matplotlib.text import Text

    # the text's own box (an Annotation's extent includes its leader line)
    boxes = [Text.get_window_extent(t) for t in ax_m.texts if t.get_gid() == "peak-label"]
    assert len(boxes) == 2 and not boxes[0].overlaps(boxes[1])


# ------------------------------------------------------------------ Nyquist


def test_nyquist_draws_the_determinant_and_zooms_on_the_origin(turning):
    from chatterlab.frequency import loop_determinant

    w = 2 * np.pi * np.linspace(1.0, 1500.0, 6000)
    fb = cl.closed_loop(turning, width=1e-3, speed=3000.0, terms="pdo")
    det = loop_determinant(fb, w)
    ax = P.plot_nyquist(w, det, verdict="stable")
    (line,) = _by_gid(ax, "nyquist")
    np.testing.assert_array_equal(line.get_xdata(), det.real)
    np.testing.assert_array_equal(line.get_ydata(), det.imag)
    j = int(np.argmin(np.abs(det)))
    (closest,) = _by_gid(ax, "closest")
    assert closest.get_xdata()[0] == det[j].real
    (inset,) = [c for c in ax.child_axes if c.get_gid() == "nyquist-zoom"]
    np.testing.assert_allclose(inset.get_xlim(), [-3 * abs(det[j]), 3 * abs(det[j])])
    assert any(t.get_text() == "stable" for t in ax.texts)
    # on a caller's Axes the zoom stays inside its frame
    _, mine = plt.subplots()
    P.plot_nyquist(w, det, ax=mine)
    (inset,) = mine.child_axes
    mine.figure.canvas.draw()
    outer, inner = mine.get_position(), inset.get_position()
    assert outer.x0 <= inner.x0 and inner.x1 <= outer.x1 and outer.y0 <= inner.y0 and inner.y1 <= outer.y1
    # ... and on a figure of its own it stands beside the plot
    own = P.plot_nyquist(w, det)
    own.figure.canvas.draw()
    assert own.child_axes[0].get_position().x0 > own.get_position().x1


def test_touching_width_is_the_closed_form_lobe_envelope(turning, tb):
    """For turning, det(I - G D) = 1 + b K_f G(jw) (1 - e^{-jwT}): the loop per
    unit width is lambda = K_f G (1 - e^{-jwT}), and the smallest width at
    which a locus reaches -1/b is b_lim(n), Tlusty's closed form.  The locus
    is crossed between samples (Re interpolated linearly): with 40000 samples
    over 0.5-3 w_n, the error is O(h^2) ~ 1e-7 relative; asserted 1e-5."""
    from chatterlab.frequency import loop_determinant

    wn = np.sqrt(tb.STIFF / tb.MASS)
    w = np.linspace(0.5 * wn, 3.0 * wn, 40000)
    for rpm in (3000.0, 4700.0, 9000.0):
        T = 60.0 / rpm
        lam = tb.KF * tb.G(w) * (1 - np.exp(-1j * w * T))
        # the convention of the docstring, against chatterlab's own determinant
        fb = cl.closed_loop(turning, width=1e-3, speed=rpm, terms="pdo")
        np.testing.assert_allclose(loop_determinant(fb, w[::997]), 1 + 1e-3 * lam[::997], rtol=1e-9)
        b, f = P.touching_width(w, lam)
        np.testing.assert_allclose(b, tb.tlusty(np.array([rpm]))[0], rtol=1e-5)
        ax = P.plot_loop_nyquist(w, lam, width=1e-3)
        (loc,) = _by_gid(ax, "locus")
        np.testing.assert_array_equal(loc.get_xdata(), lam.real)
        (touch,) = _by_gid(ax, "touching")
        assert touch.get_xdata()[0] == -1.0 / b
        assert f"{b * 1e3:.4g} mm" in touch.get_label()
        plt.close("all")


def test_loop_eigenvalues_are_the_loop_per_unit_width(turning, tb):
    """chatterlab's loop eigenvalues of the turning model are the closed form
    K_f G (1 - e^{-jwT}) (one CE direction cuts, so one locus; the others are
    0); their product rebuilds the determinant at another width.  Round-off
    of small dense solves: asserted 1e-9 relative."""
    from chatterlab.frequency import loop_determinant
    from chatterlab.frequency._frf import loop_eigenvalues

    w = 2 * np.pi * np.linspace(300.0, 700.0, 401)
    fb = cl.closed_loop(turning, width=1e-3, speed=4700.0, terms="pdo")
    lam = loop_eigenvalues(fb, w)
    T = 60.0 / 4700.0
    # the CE's directions without cutting stiffness give lambda = 0: one locus
    one = lam[np.arange(w.size), np.argmax(np.abs(lam), axis=1)]
    rest = np.sort(np.abs(lam), axis=1)[:, :-1]
    assert rest.max() <= 1e-12 * np.abs(one).max()
    np.testing.assert_allclose(
        one, tb.KF * tb.G(w) * (1 - np.exp(-1j * w * T)), rtol=1e-9, atol=1e-12 * np.abs(one).max()
    )
    fb2 = cl.closed_loop(turning, width=2.5e-3, speed=4700.0, terms="pdo")
    np.testing.assert_allclose(np.prod(1 + 2.5e-3 * lam, axis=1), loop_determinant(fb2, w), rtol=1e-9)
    ax = P.plot_loop_nyquist(w, one, width=1e-3)
    assert "b* =" in _by_gid(ax, "touching")[0].get_label()


def test_shaper_loop_touches_at_the_lobe_engines_width():
    """On the shaper (three CE directions, three loci) at 0.5 m/s, the width at
    which a locus of the loop reaches -1/b is the lobe engine's b_lim there
    (0.3406 mm at 76.24 Hz), found by two independent routes (eigenvalue
    loci crossing the axis vs the engine's D-subdivision with Newton
    refinement).  The loci are crossed between samples 2e-4 Hz apart:
    interpolation error O(h^2), measured 4.6e-6 relative; asserted 1e-4."""
    from chatterlab.frequency._frf import loop_eigenvalues
    from chatterlab.lobes import lobes

    sh = cl.assemble(cl.load_model(ROOT / "studies" / "traverse_shaper" / "model.toml")).at()
    d = lobes(sh, np.array([0.5]), width_max=1e-3, verify=0)
    w = 2 * np.pi * np.linspace(74.0, 78.0, 20001)
    lam = loop_eigenvalues(cl.closed_loop(sh, width=1e-4, speed=0.5, terms="pdo"), w)
    b, f = P.touching_width(w, lam)
    assert b == pytest.approx(d.b_lim[0], rel=1e-4) and f == pytest.approx(d.chatter_hz[0], rel=1e-6)


def test_loci_are_tracked_through_shuffled_eigenvalues():
    """Two smooth loci whose columns are shuffled at random frequencies (as
    eigvals may order them) are followed again, and the width at which one
    touches -1/b does not depend on the order: b* = 1/2 where 2 e^{j theta}
    crosses the negative real axis (theta = pi), f = omega/2pi at theta = pi."""
    w = np.linspace(0.0, 2 * np.pi, 2001)[1:]
    theta = w  # one turn
    true = np.column_stack([2 * np.exp(1j * theta), 0.3 + 0.1 * np.exp(-1j * theta)])
    rng = np.random.default_rng(0)
    flip = rng.random(w.size) < 0.3
    raw = np.where(flip[:, None], true[:, ::-1], true)
    got = P.track_loci(raw)
    assert np.array_equal(got, true) or np.array_equal(got, true[:, ::-1])
    b, f = P.touching_width(w, raw)
    assert b == pytest.approx(0.5, rel=1e-6) and f == pytest.approx(0.5, rel=1e-6)
    # without tracking, the shuffled columns would cross the axis at false places
    assert np.sum(np.diff(np.sign(raw.imag), axis=0) != 0) > 100


def test_touching_width_without_a_crossing_is_inf():
    w = np.linspace(1.0, 10.0, 50)
    assert P.touching_width(w, 1.0 / (1.0 + 1j * w)) == (
        float("inf"),
        pytest.approx(float("nan"), nan_ok=True),
    )


# ------------------------------------------------------------------ time


@pytest.fixture(scope="module")
def run(turning):
    # a 1 ms, 100 N push at the start: the response rings at the closed loop's frequencies
    return cl.simulate(
        turning.system, width=2e-3, speed=3000.0, passes=1, duration=0.3, outputs=["tool.x"],
        loads={"tool.x": lambda t: 100.0 * (t < 1e-3)},
    )  # fmt: skip


def test_time_response_draws_the_run(run):
    force = 1e7 * run.data["tool.x"]  # any array on the run's time grid
    axd, axf, axs = P.plot_time_response(run, "tool.x", force=force)
    (d,) = _by_gid(axd, "displacement")
    np.testing.assert_array_equal(d.get_xdata(), run.t)
    np.testing.assert_allclose(d.get_ydata(), run.data["tool.x"] * 1e6, rtol=1e-15)
    (fl,) = _by_gid(axf, "force")
    np.testing.assert_array_equal(fl.get_ydata(), force)
    f, a = run.spectrum("tool.x")
    (sp,) = _by_gid(axs, "spectrum")
    n = len(sp.get_xdata())
    np.testing.assert_allclose(sp.get_ydata(), a[:n] * 1e6, rtol=1e-15)
    (ch,) = _by_gid(axs, "chatter")
    assert ch.get_xdata()[0] == f[1:][np.argmax(a[1:])]
    # b = 2 mm is above b_lim at 3000 rpm: it chatters near the natural frequency (503 Hz)
    assert 450 < ch.get_xdata()[0] < 600
    teeth = [ln.get_xdata()[0] for ln in _by_gid(axs, "tooth")]
    np.testing.assert_allclose(teeth, np.arange(1, len(teeth) + 1) / run.delay, rtol=1e-12)
    assert "b = 2 mm" in axd.get_title() and "feedback pdo" in axd.get_title()
    assert "in the cut" in [t.get_text() for t in axd.get_legend().get_texts()]
    # the caller's Axes are used as given (here already sharing their x axis)
    _, mine = plt.subplots(3, 1, sharex=True)
    assert P.plot_time_response(run, "tool.x", force=force, ax=mine) == tuple(mine)


def test_histories_keep_each_run_in_one_colour(run):
    axes = P.plot_histories([run, run], ["tool.x", "tool.x"], labels=["a", "b"])
    for k in range(2):
        assert len({ax.get_lines()[k].get_color() for ax in axes}) == 1
    assert "in the cut" in [t.get_text() for t in axes[0].get_legend().get_texts()]
    np.testing.assert_allclose(axes[0].get_lines()[0].get_ydata(), run.data["tool.x"] * 1e6)


# ------------------------------------------------------------------ sweep


@pytest.fixture(scope="module")
def stable_sweep(tb):
    from chatterlab.sweep import Grid, sweep

    def point(width, speed):
        return {"stable": float(width < tb.tlusty(np.array([speed]))[0]), "b": width}

    g = Grid(
        {"width": (np.linspace(0.2e-3, 3e-3, 8), "m"), "speed": (np.linspace(2000.0, 12000.0, 9), "rpm")}
    )
    return sweep(point, g, outputs={"stable": "1", "b": "m"}, jobs=1, backend="serial", progress=False)


def test_stability_map_cells_are_the_verdicts():
    x, y = np.arange(4.0), np.arange(3.0)
    status = np.array([["stable", "unstable", "undetermined", ""]] * 3)
    ax = P.plot_stability_map(x, y, status, xlabel="speed [rpm]", ylabel="width [mm]")
    code = P._sweep.status_codes(status)
    for c in range(4):
        (pc,) = [p for p in ax.collections if p.get_gid() == f"status-{c}"]
        assert np.array_equal(~np.ma.getmaskarray(pc.get_array()).reshape(3, 4), code == c)
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert legend == [
        "stable (proven) (3 cells)",
        "chatter (3 cells)",
        "undetermined (3 cells)",
        "not computed (3 cells)",
    ]
    with pytest.raises(cl.InputError, match="unknown status 'stabel'"):
        P.plot_stability_map(x, y, np.full((3, 4), "stabel"))


def test_sweep_stable_is_a_status_map_in_mm(stable_sweep):
    ax = P.plot_sweep(stable_sweep, "stable", x="speed")
    s = np.asarray(stable_sweep["stable"])
    (pc,) = [p for p in ax.collections if p.get_gid() == "status-0"]
    assert np.array_equal(~np.ma.getmaskarray(pc.get_array()).reshape(s.shape), s == 1)
    assert ax.get_ylabel() == "width [mm]" and ax.get_xlabel() == "speed [rpm]"
    assert ax.get_ylim()[1] == pytest.approx(3e-3 * 1e3 + 0.2, rel=1e-9)  # the last cell's edge, mm
    ax = P.plot_sweep(stable_sweep, "stable", at={"speed": 7000.0})  # one free axis: one row of cells
    (pc,) = [p for p in ax.collections if p.get_gid() == "status-1"]
    assert np.array_equal(~np.ma.getmaskarray(pc.get_array()).ravel(), s[:, 4] == 0)
    ax = P.plot_sweep(stable_sweep, "b", at={"speed": 7000.0})
    (ln,) = _by_gid(ax, "sweep-line")
    np.testing.assert_allclose(ln.get_xdata(), stable_sweep.grid["width"].values * 1e3)
    np.testing.assert_allclose(ln.get_ydata(), stable_sweep["b"][:, 4] * 1e3)
    assert "speed = 7000" in ax.get_title()


# ------------------------------------------------------------------ modes


def test_mode_shapes_of_a_cantilever(beam_model_text):
    """The first bending mode of a slender cantilever (L/h = 50) drawn on
    the beam is the Euler-Bernoulli shape cosh bx - cos bx - s (sinh bx - sin bx),
    bL = 1.8751, s = 0.7341, to the shear (h/L)^2 ~ 4e-4 and discretisation
    (8 cubic elements, (1/8)^4 ~ 2e-4) errors: asserted 3e-3 of the tip."""
    L, h = 1.0, 0.02
    md = cl.modes(cl.assemble(cl.loads_model(beam_model_text(L, h, elements=8))), count=2)
    dr = md.drawing()
    axes = P.plot_mode_shapes(dr)
    assert len(axes) == 2
    (beam,) = [m for m in dr["members"] if m["kind"] == "beam"]
    (un,) = [ln for ln in axes[0].get_lines() if ln.get_gid() == "undeformed"]
    (de,) = [ln for ln in axes[0].get_lines() if ln.get_gid() == "mode-0"]
    s = P._modes.mode_scale(dr, 0)
    np.testing.assert_allclose(un.get_xdata(), beam["xy"][:, 0])
    np.testing.assert_allclose(de.get_ydata(), beam["xy"][:, 1] + s * beam["shape"][0][:, 1], atol=1e-15)
    x = beam["xy"][:, 0]
    bx, sg = 1.8751 * x / L, 0.7341
    eb = np.cosh(bx) - np.cos(bx) - sg * (np.sinh(bx) - np.sin(bx))
    v = np.asarray(de.get_ydata()) - beam["xy"][:, 1]
    np.testing.assert_allclose(v / v[-1], eb / eb[-1], atol=3e-3)
    # drawn at DRAWN_AMPLITUDE of the structure's size
    assert abs(v).max() == pytest.approx(P._modes.DRAWN_AMPLITUDE * L, rel=1e-12)
    legend = axes[0].get_legend().get_texts()[0].get_text()
    assert legend.startswith(f"mode 1: {md.frequency_hz[0]:.2f} Hz")


def test_a_matrix_model_has_its_frequencies_drawn_as_bars():
    md = cl.modes(cl.assemble(cl.load_model(ROOT / "studies" / "milling" / "benchmark_2dof.toml")))
    with pytest.raises(cl.InputError, match="matrix-level model has no geometry"):
        md.drawing()
    ax = md.plot()
    heights = [p.get_height() for p in ax.patches]
    np.testing.assert_array_equal(heights, md.frequency_hz)
    ax = md.plot(reference=md.frequency_hz * 1.01)
    np.testing.assert_allclose([p.get_height() for p in ax.patches][len(md) :], md.frequency_hz * 1.01)
