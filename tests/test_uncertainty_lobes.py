"""Probabilistic lobes through the lobe engine and the sweep engine (issue 24).

* Zero-width distributions give today's lobe diagram exactly, on every
  route: the shaper (the cut shared with the nominal structure), a modal
  model rebuilt per sample, milling (Floquet) and a measured FRF.
* Every sample of a 1-DOF turning model is its own Tlusty: the sample's
  smallest boundary width equals 2 k zeta (1 + zeta) / K_f of its own k,
  zeta and K_f (the engine's refinement to round-off: 1e-9, as
  tests/test_studies.py holds the turning benchmark).
* The structure shared between samples (only the cut uncertain) gives the
  same bits as rebuilding it; the backends (serial, loky, dask) give the
  same bits; a run interrupted in its second stage resumes from its
  checkpoint, computes only what is missing and ends with the same bits.
* The files, plots and queries of the result; the modal fit's uncertainty
  carried into a modal model whose lobes are the fitted model's.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import chatterlab as cl
from chatterlab.io import read_netcdf
from chatterlab.uncertainty import InputSpace, risk, uncertain_modal_model
from chatterlab.uncertainty import _risk as risk_module
from chatterlab.uncertainty import _task as task_module

ROOT = Path(__file__).resolve().parents[1]
SHAPER = ROOT / "studies" / "traverse_shaper" / "model.toml"

ONE_DOF = """
[model]
name = "1-DOF turning with uncertain modes and cut"

[[mode]]
id = "x1"
frequency_hz = 500.0
damping_ratio = 0.03
stiffness = 1.0e7
direction = "tool.x"

[[point]]
id = "tip"
coords = {{ x = "tool.x" }}

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

[uncertainty]
{uncertainty}
"""
FULL = """
"mode.x1.stiffness" = { distribution = "lognormal", cv = 0.1 }
"mode.x1.damping_ratio" = { distribution = "normal", std = 0.003, lower = 0.0 }
"coupling.cut.Kf" = { distribution = "uniform", low = 1.8e9, high = 2.2e9 }
"""
RPM = np.linspace(2000.0, 12000.0, 12)


def one_dof(tmp_path: Path, uncertainty: str = FULL) -> cl.Model:
    p = tmp_path / "one.toml"
    p.write_text(ONE_DOF.format(uncertainty=uncertainty))
    return cl.load_model(p)


@pytest.fixture(scope="module")
def full_run(tmp_path_factory):
    """4 replicates x 4 samples, Sobol' matrices of the 3 fields (80 diagrams), one operating point."""
    m = one_dof(tmp_path_factory.mktemp("full"))
    return m, risk(m, RPM, width_max=2e-3, samples=16, replicates=4, sensitivity=True,
                   points=[(6000.0, 3.1e-4)], backend="serial")  # fmt: skip


def test_each_sample_is_its_own_tlusty_minimum(full_run):
    m, r = full_run
    x = {p: r.inputs[..., i] for i, p in enumerate(r.paths)}
    k, z, kf = x["mode.x1.stiffness"], x["mode.x1.damping_ratio"], x["coupling.cut.Kf"]
    exact = 2 * k * z * (1 + z) / kf
    assert np.all(np.abs(r.sample_abs_min / exact - 1) < 1e-9)
    # the inputs are spread: 16 different stiffnesses, none equal to the nominal one
    assert np.unique(k).size == 16 and not np.any(k == 1e7)
    # a range minimum is never below the all-speeds minimum (both from the same diagram)
    assert np.all(r.sample_min >= r.sample_abs_min * (1 - 1e-12))
    assert r.n_checked == r.evaluations == 16 * 5 and r.n_unverified == 0 and r.n_contradicted == 0


def test_estimates_read_from_the_samples(full_run):
    """Every estimate is what its definition says of the kept samples."""
    _, r = full_run
    j = np.searchsorted(r.all_speeds, r.speed)
    b = r.samples[:, :, j]  # (R, n, speeds)
    w = r.width[57]
    assert np.array_equal(r.p_stable.value[:, 57], (b > w).mean(axis=1).mean(axis=0))
    q = np.quantile(b.reshape(16, -1), 0.5, axis=0, method="inverted_cdf")
    assert np.array_equal(r.quantiles.value[1], q)
    jp = np.searchsorted(r.all_speeds, 6000.0)
    assert float(r.p_chatter.value[0]) == float((r.samples[:, :, jp] <= 3.1e-4).mean())
    e = r.p_chatter_at(6000.0, 3.1e-4)
    assert float(e.value) == float(r.p_chatter.value[0])
    # the safe width at a risk: with 16 samples, P(chatter) = 1/16 from the smallest sample's limit up
    # to (not including) the second smallest
    w = r.safe_width(1 / 16, conservative=False)
    second = np.sort(b.reshape(16, -1), axis=0)[1]
    assert np.array_equal(w, np.nextafter(second, 0.0))
    assert all(float(r.p_chatter_at(v, x).value) == 1 / 16 for v, x in zip(r.speed, w, strict=True))
    # the safe side: the upper end of the interval within the risk, at least the rule of three 3/16
    cons = r.safe_width(0.25)
    assert np.all(cons <= r.safe_width(0.25, conservative=False))
    for v, x in zip(r.speed, cons, strict=True):
        e = r.p_chatter_at(v, x)
        assert x == 0 or (float(e.high) <= 0.25 and -math.log(0.05) / 16 <= 0.25)
    lim = r.risk_limit(0.25)  # the plug-in width limit of a speed recommendation
    assert np.array_equal(lim.max_width(r.speed, np.full(r.speed.size, np.inf)), cons)
    mid = 0.5 * (r.speed[3] + r.speed[4])  # between two computed speeds: the smaller of the two
    assert lim.max_width([mid], [1.0])[0] == min(cons[3], cons[4])
    assert lim.max_width([r.speed[0] - 1.0, r.speed[5]], [1.0, 1e-9]).tolist() == [0.0, min(1e-9, cons[5])]
    # 16 samples cannot claim 10 % (the rule of three: 3/16 > 0.1): no top at width 0 is an operating point
    assert r.recommend(0.1) == []
    rec = r.recommend(0.25)
    assert rec and rec[0]["width"] == max(x["width"] for x in rec) and all(x["width"] > 0 for x in rec)
    assert set(r.sobol) == {"b_min", "chatter@0"}
    s1, st = r.sobol["b_min"]
    assert np.shape(s1.value) == (3,) and r.factor_names == r.paths
    with pytest.raises(cl.InputError, match="was not computed"):
        r.p_chatter_at(6001.0, 3e-4)


def test_files_and_plots(full_run, tmp_path):
    m, r = full_run
    f = r.to_netcdf(tmp_path / "risk.nc", attrs={"model_text": m.text})
    d = read_netcdf(f)
    assert d.attrs["n_samples"] == 16 and d.attrs["replicates"] == 4 and d.attrs["confidence_level"] == 0.95
    assert d.attrs["error"] == r.error and "stop" in d.attrs
    assert d.dims["p_stable"] == ("speed", "width") and d.dims["b_lim_quantile"] == ("quantile", "speed")
    assert np.array_equal(d.data["p_stable"][0], r.p_stable.value)
    assert np.array_equal(
        d.data["b_lim_sample"][0], r.samples.reshape(16, -1)[:, np.searchsorted(r.all_speeds, r.speed)]
    )
    assert np.array_equal(d.coords["quantile"][0], [0.05, 0.5, 0.95])
    assert d.dims["sobol_total_b_min"] == ("factor",)
    c = r.to_csv(tmp_path / "risk.csv")
    lines = Path(c).read_text().splitlines()
    assert (
        lines[0].startswith("speed [rpm],width [m],p_stable [1],p_stable_se [1]")
        and "b_lim_quantile_0.95 [m]" in lines[0]
    )
    assert len(lines) == 1 + r.speed.size * r.width.size
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    ax = r.plot(risk=0.05)
    assert ax.get_xlabel() == "spindle speed [rpm]"
    lo, hi = r.plot_sensitivity().get_xlim()
    assert lo == -0.05 and hi >= 1.25  # every bar and its interval inside
    import matplotlib.pyplot as plt

    plt.close("all")
    text = r.summary()
    assert "P(chatter) at 6000 rpm, 0.31 mm" in text and "80/80 sample diagrams verified" in text


def test_zero_width_is_todays_lobe_diagram(tmp_path):
    """The shaper with its Grasso coefficients K7, K8 of zero width (the cut
    shared with the nominal structure) and a modal model with a zero-width
    stiffness (rebuilt per sample): every sample, every quantile, the map
    are today's diagram, bit for bit."""
    text = SHAPER.read_text() + (
        '\n[uncertainty]\n"coupling.cut.K7" = { distribution = "normal", std = 0.0 }\n'
        '"coupling.cut.K8" = { distribution = "lognormal", cv = 0.0 }\n'
    )
    p = tmp_path / "shaper.toml"
    p.write_text(text)
    shaper = cl.load_model(p)
    v = np.linspace(0.4, 0.6, 25)
    today = cl.lobes(cl.load_model(SHAPER), v, width_max=1e-3)
    r = risk(shaper, v, width_max=1e-3, samples=4, replicates=2, backend="serial")
    assert r.shared
    _same_as(r, today)
    m = one_dof(tmp_path, '"mode.x1.stiffness" = { distribution = "normal", std = 0.0 }')
    r = risk(m, RPM, width_max=2e-3, samples=4, replicates=2, backend="serial")
    assert not r.shared
    _same_as(r, cl.lobes(m, RPM, width_max=2e-3))


def _same_as(r, today):
    b = np.asarray(today.b_lim)
    assert np.array_equal(r.samples, np.broadcast_to(b, r.samples.shape))
    for row in np.asarray(r.quantiles.value):
        assert np.array_equal(row, b)
    assert np.array_equal(r.p_stable.value, (r.width[None, :] < b[:, None]).astype(float))
    assert np.all(r.p_stable.se == 0)


def test_zero_width_on_the_milling_and_measured_frf_routes(tmp_path):
    """Floquet milling (the cutter's Kt) and a measured FRF ([frf], its cut's
    Kf) at zero width: today's diagram of each route."""
    text = (ROOT / "studies" / "milling" / "benchmark_1dof.toml").read_text()
    p = tmp_path / "mill.toml"
    p.write_text(text + '\n[uncertainty]\n"process.Kt" = { distribution = "normal", cv = 0.0 }\n')
    mill = cl.load_model(p)
    v = np.linspace(5000.0, 20000.0, 6)
    r = risk(mill, v, width_max=5e-3, samples=4, replicates=2, backend="serial")
    _same_as(r, cl.lobes(mill, v, width_max=5e-3))
    assert r.limit_name == "a_lim" and r.n_checked == 0
    (tmp_path / "tool_point.csv").write_bytes((ROOT / "studies" / "tap_test" / "tool_point.csv").read_bytes())
    q = tmp_path / "frf.toml"
    q.write_text(
        '[frf]\nfile = "tool_point.csv"\n[[point]]\nid = "tool"\ncoords = { x = "tool.y" }\n'
        '[[coupling]]\nid = "cut"\na = "tool"\nb = "ground"\nmodel = "regenerative"\nwidth_ref = 0.001\nKf = 1e9\n'
        '[process]\nkind = "turning"\nrpm = 10000\n[uncertainty]\n"coupling.cut.Kf" = { distribution = "normal", std = 0.0 }\n'
    )  # fmt: skip
    frf = cl.load_model(q)
    v = np.linspace(3000.0, 30000.0, 8)
    r = risk(frf, v, width_max=2e-3, samples=4, replicates=2, backend="serial")
    _same_as(r, cl.lobes(frf, v, width_max=2e-3))


def test_the_shared_structure_gives_the_rebuilt_bits(tmp_path):
    m = one_dof(tmp_path, '"coupling.cut.Kf" = { distribution = "lognormal", cv = 0.15 }')
    a = risk(m, RPM, width_max=2e-3, samples=8, replicates=2, backend="serial")
    b = risk(m, RPM, width_max=2e-3, samples=8, replicates=2, backend="serial", share=False)
    assert a.shared and not b.shared
    assert np.array_equal(a.samples, b.samples)
    # a Kf-only run: b_lim scales as 1/Kf at every speed (Tlusty), the chatter frequency unchanged
    kf = a.inputs[..., 0]
    ratio = a.samples * kf[..., None]
    assert np.allclose(ratio, ratio[0, 0], rtol=1e-9)


def test_backends_give_the_same_bits(tmp_path):
    m = one_dof(tmp_path)
    kw = dict(width_max=2e-3, samples=8, replicates=2, points=[(6000.0, 3e-4)])
    serial = risk(m, RPM, backend="serial", **kw)
    for backend in ("loky", "dask"):
        other = risk(m, RPM, backend=backend, jobs=2, **kw)
        assert np.array_equal(other.samples, serial.samples), backend
        assert np.array_equal(other.p_stable.value, serial.p_stable.value), backend


def test_a_run_interrupted_in_a_stage_resumes_with_nothing_lost(tmp_path, monkeypatch):
    """Stages of 2, 4 and 8 rows per replicate (tol too small to stop): a
    KeyboardInterrupt in the second stage leaves the first stage's
    checkpoint complete and part of the second; the resumed run computes
    only the missing samples and equals an uninterrupted run bit for bit."""
    m = one_dof(tmp_path)
    monkeypatch.setattr(risk_module, "FIRST_STAGE", 2)
    kw = dict(width_max=2e-3, samples=16, replicates=2, tol=1e-6, backend="serial")
    clean = risk(m, RPM, **kw)
    assert clean.stages == (4, 8, 16) and "budget reached" in clean.stop
    calls: list[int] = []
    real = task_module.LobeSampleTask.diagram

    def counted(self, eid):
        calls.append(int(eid))
        if len(calls) == 7 and interrupt:  # in the second stage (4 diagrams in the first)
            raise KeyboardInterrupt
        return real(self, eid)

    monkeypatch.setattr(task_module.LobeSampleTask, "diagram", counted)
    monkeypatch.setattr(task_module, "_ROWS", type(task_module._ROWS)())
    interrupt = True
    ck = tmp_path / "ck"
    with pytest.raises(KeyboardInterrupt):
        risk(m, RPM, checkpoint=ck, **kw)
    assert len(calls) == 7
    monkeypatch.setattr(task_module, "_ROWS", type(task_module._ROWS)())
    calls.clear()
    interrupt = False
    resumed = risk(m, RPM, checkpoint=ck, resume=True, **kw)
    # stage 1 (2 replicates x rows 0-1) whole from its checkpoint; stage 2 (rows 2-3) saved chunk by
    # chunk (one sample each here): its 2 samples done before the interrupt kept, 2 left; stage 3: 8
    assert len(calls) == 2 + 8
    assert np.array_equal(resumed.samples, clean.samples)
    assert np.array_equal(resumed.p_stable.value, clean.p_stable.value)
    with pytest.raises(cl.InputError, match="not empty"):
        risk(m, RPM, checkpoint=ck, **kw)


def test_the_stopping_rule_stops_at_its_tolerance(tmp_path, monkeypatch):
    """With tol, the run stops at the first stage whose error is at most tol
    (each earlier stage's above it), and no error is below the rule of
    three, -ln(1 - 0.95) / N."""
    m = one_dof(tmp_path)
    monkeypatch.setattr(risk_module, "FIRST_STAGE", 2)
    r = risk(m, RPM, width_max=2e-3, samples=64, replicates=2, tol=0.2, points=[(6000.0, 3e-4)],
             backend="serial")  # fmt: skip
    assert r.errors[-1] <= 0.2 and all(e > 0.2 for e in r.errors[:-1]) and "tol reached" in r.stop
    assert len(r.errors) == len(r.stages) > 1 and r.n_samples == r.stages[-1] < 64
    for n, e in zip(r.stages, r.errors, strict=True):
        assert e >= -math.log(1 - 0.95) / n * (1 - 1e-12)


def test_the_fits_uncertainty_in_a_modal_model():
    """The tap test's fit as [[mode]] tables: the fit's real-mode sum
    sum phi phi^T / (w_r^2 - w^2 + 2 j zeta_r w_r w) (to 1e-10 of its peak,
    as tests/test_modal_fit.py holds ModalFit.to_model), each
    fitted pole's frequency and damping normal with the fit's standard
    deviations, the tool's pole (two real modes) one correlated pair."""
    from chatterlab.structure import FRF, fit_modes

    frf = FRF.read(ROOT / "studies" / "tap_test" / "tool_point.csv")
    fit = fit_modes(frf, max_order=16, band=(2 * np.pi * 100.0, 2 * np.pi * 4000.0))
    cut = {
        "coupling": [{"id": "cut", "a": "tool", "b": "ground", "model": "regenerative", "width_ref": 0.001,
                      "Kf": 1e9, "force_angle_deg": 90.0, "normal_angle_deg": 90.0}],
        "process": {"kind": "turning", "rpm": 10000.0},
    }  # fmt: skip
    m = uncertain_modal_model(
        fit, tables=cut, uncertainty={"coupling.cut.Kf": {"distribution": "lognormal", "cv": 0.1}}
    )
    w = 2 * np.pi * np.linspace(100.0, 4000.0, 800)
    ours = cl.frf(cl.assemble(m).at(), w, inputs=["tool.x", "tool.y"], outputs=["tool.x", "tool.y"]).data
    om, ze, Phi = fit.real_modes()  # the fit's real modes and its upper residual's pseudo-modes
    den = om[:, None] ** 2 - w[None, :] ** 2 + 2j * (ze * om)[:, None] * w[None, :]
    fitted = np.einsum("ir,jr,rw->ijw", Phi, Phi, 1 / den)
    assert np.max(np.abs(ours - fitted)) < 1e-10 * np.max(np.abs(fitted))
    sp = InputSpace.of(m)
    for r in range(fit.n_modes):
        f = fit.frequency_hz[r]
        hit = [mg for mg in sp.marginals if mg.path.endswith("frequency_hz") and mg.mean == f]
        assert hit and all(mg.std == fit.std_omega[r] / (2 * np.pi) for mg in hit)
        zs = [mg for mg in sp.marginals if mg.path.endswith("damping_ratio") and mg.mean == fit.damping[r]]
        assert zs and all(mg.std == fit.std_damping[r] for mg in zs)
    pairs = [g for g in sp.groups if len(g.paths) == 2]
    assert pairs and all(np.array_equal(g.correlation, np.ones((2, 2))) for g in pairs)
    x = sp.transform(np.random.default_rng(1).random((5, sp.dims)))
    for g in pairs:
        i, j = (sp.paths.index(p) for p in g.paths)
        assert np.allclose(x[:, i], x[:, j], rtol=1e-14)  # one pole: its two modes move together


def test_the_risk_lobe_feeds_the_speed_recommendation(full_run):
    """chatterlab.selection.recommend with the 25 % risk lobe as a plug-in
    limit (and no margin): every recommended width is within the risk
    limit at its speed, and where the risk limit binds it sets the width."""
    from chatterlab.selection import recommend

    m, r = full_run
    lim = r.risk_limit(0.25)
    rec = recommend(m, speeds=RPM, limits=[lim], margin=0.0, check=False, width_max=2e-3)
    v, w = np.asarray(rec.speed), np.asarray(rec.width)
    assert v.size and np.all(w <= lim.max_width(v, np.full(v.size, np.inf)))
    bound = np.array([lim.name in str(b) for b in rec.binding])
    assert bound.any() and np.array_equal(w[bound], lim.max_width(v[bound], np.full(bound.sum(), np.inf)))
