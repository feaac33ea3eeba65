"""The behaviour every time-history result shares (chatterlab.time._history.TimeHistory):
TimeResponse (the Newmark solver's q/v/a) and Simulation (a cut's named
histories) give the same spectrum and growth of the same signal, their CSV and
netCDF files read back bit for bit, and a third result type plugs in with a
class attribute."""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
import pytest

from chatterlab.errors import InputError
from chatterlab.io import Result, read_dataset
from chatterlab.time import MillingSimulation, Simulation, TimeResponse, peaks
from chatterlab.time._history import TimeHistory

DT = 1e-3
T_END = 4.0
F0 = 7.3  # Hz
SIGMA1, SIGMA2 = -1.5, 2.0  # 1/s: decaying on [0, 2) s, growing on [2, 4] s


def signal(t: np.ndarray) -> np.ndarray:
    """exp(sigma t) sin(2 pi f0 t + 0.3) with sigma = SIGMA1 before 2 s and SIGMA2 after
    (continuous), plus a static offset that neither estimator may see."""
    log_env = np.where(t < 2.0, SIGMA1 * t, SIGMA1 * 2.0 + SIGMA2 * (t - 2.0))
    return 1e-6 * (0.7 + np.exp(log_env) * np.sin(2 * np.pi * F0 * t + 0.3))


def pair(x: np.ndarray, t: np.ndarray, in_cut: np.ndarray | None = None) -> tuple[TimeResponse, Simulation]:
    """The same history as a TimeResponse output "tip.x" and a Simulation output "tip.x"."""
    tr = TimeResponse(
        t=t, q=x[None, :], v=np.gradient(x, t)[None, :], a=np.zeros((1, t.size)), names=("tip.x",),
        status="ok", message="synthetic", n_steps=t.size - 1, wall_time=0.0, h=DT,
    )  # fmt: skip
    cut = np.ones(t.size, bool) if in_cut is None else in_cut
    sim = Simulation(
        t=t, data={"tip.x": x}, position=np.zeros(t.size), in_cut=cut,
        cut_distance=np.where(cut, t, np.nan), response=tr, terms="pdo", width=1e-3, delay=0.02,
        step=DT, passes=1, units={"tip.x": "m"}, model="synthetic",
    )  # fmt: skip
    return tr, sim


@pytest.fixture
def runs() -> tuple[np.ndarray, np.ndarray, TimeResponse, Simulation]:
    t = np.arange(0.0, T_END + DT / 2, DT)
    x = signal(t)
    return (t, x, *pair(x, t))


# --------------------------------------------------------------------------- spectrum and growth


def test_same_growth_from_both_types_and_the_window_decides(runs):
    t, x, tr, sim = runs
    # The extrema estimator is exact for exp(sigma t) sin(w t) up to the parabolic
    # refinement of sampled extremes, O((w dt)^4) ~ 4e-6 in each log-envelope point, so
    # a slope error of order 1e-5 1/s over a window of >= 1.6 s: 1e-4 |sigma| is 10-20x that
    # (measured 2e-7 and 1e-8 1/s).
    # The whole run mixes the two rates (a least-squares slope between them, > 20 % off
    # either), so a window that is not applied fails the test.
    for run, name in ((tr, "tip.x"), (sim, "tip.x")):
        late = run.growth(name, window=(2.0, T_END))
        assert abs(late.rate - SIGMA2) < 1e-4 * SIGMA2, late
        early = run.growth(name, window=(0.0, 2.0 - DT))
        assert abs(early.rate - SIGMA1) < 1e-4 * abs(SIGMA1), early
        # skip is seconds dropped from the start, then growth_rate drops 20 % of the rest
        assert run.growth(name, skip=2.0) == run.growth(name, window=(2.0, T_END))
        whole = run.growth(name)
        assert min(abs(whole.rate - SIGMA1), abs(whole.rate - SIGMA2)) > 0.2 * abs(SIGMA1)
    assert tr.growth("tip.x", skip=2.0) == sim.growth("tip.x", skip=2.0)
    assert tr.growth(0, window=(1.0, 3.0), method="hilbert") == sim.growth(
        "tip.x", window=(1.0, 3.0), method="hilbert"
    )


def test_same_spectrum_from_both_types_and_the_amplitude_is_the_sines(runs):
    t, _, _, _ = runs
    x = 2e-6 * np.sin(2 * np.pi * F0 * t) + 3e-7  # a steady sine on a static offset
    tr, sim = pair(x, t)
    f1, a1 = tr.spectrum("tip.x")
    f2, a2 = sim.spectrum("tip.x", window="all")
    np.testing.assert_array_equal(f1, f2)
    np.testing.assert_array_equal(a1, a2)
    # peaks(): the refined height of an isolated sine with pad = 4 is within 1e-4 of
    # its amplitude and its frequency within 2e-4 of the resolution (its docstring)
    fp, ap = peaks(f1, a1, 1)
    assert abs(ap[0] / 2e-6 - 1) < 1e-4 and abs(fp[0] - F0) < 2e-4 / T_END
    np.testing.assert_array_equal(
        tr.spectrum(0, window=(1.0, 3.0), taper=None, pad=1)[1],
        sim.spectrum("tip.x", window=(1.0, 3.0), taper=None, pad=1)[1],
    )


def test_simulation_spectrum_defaults_to_the_last_pass_in_the_cut(runs):
    t, x, _, _ = runs
    cut = ((t >= 1.0) & (t < 2.0)) | ((t >= 3.0) & (t <= 3.5))
    _, sim = pair(x, t, cut)
    last = sim.window("last-cut")
    assert t[last][0] == 3.0 and t[last][-1] == 3.5 and np.count_nonzero(last) == 501
    np.testing.assert_array_equal(sim.spectrum("tip.x")[1], sim.spectrum("tip.x", window=(3.0, 3.5))[1])
    assert sim.spectrum("tip.x")[1].shape != sim.spectrum("tip.x", window="all")[1].shape


# --------------------------------------------------------------------------- files


def _read_csv(path) -> tuple[list[str], list[list[str]]]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


def test_csv_reads_back_bit_for_bit(tmp_path):
    rng = np.random.default_rng(11)
    t = np.arange(0.0, 0.2, DT) + 1e-3 / 3  # times that are no short decimals
    # doubles spanning many orders of magnitude, with all 17 significant digits in use
    x = rng.standard_normal(t.size) * 10.0 ** rng.integers(-12, 6, t.size)
    x[5] = math.nan
    tr, sim = pair(x, t, in_cut=rng.random(t.size) < 0.5)
    tr = TimeResponse(**{**tr.__dict__, "status": "diverged"})
    head, rows = _read_csv(tr.to_csv(tmp_path / "tr.csv", fields=("q", "v")))
    assert head == ["t [s]", "q:tip.x", "v:tip.x", "status"]
    got = np.array([[float(v) for v in r[:3]] for r in rows])
    np.testing.assert_array_equal(got[:, 0], t)
    np.testing.assert_array_equal(got[:, 1], tr.q[0])  # NaN equals NaN here
    np.testing.assert_array_equal(got[:, 2], tr.v[0])
    assert {r[3] for r in rows} == {"diverged"}

    head, rows = _read_csv(sim.to_csv(tmp_path / "sim.csv"))
    assert head == ["t [s]", "position [m]", "in_cut [-]", "cut_distance [m]", "tip.x [m]", "status"]
    np.testing.assert_array_equal([float(r[4]) for r in rows], x)
    np.testing.assert_array_equal([float(r[3]) for r in rows], sim.cut_distance)
    assert [int(r[2]) for r in rows] == sim.in_cut.astype(int).tolist()
    assert {r[5] for r in rows} == {"ok"}


def test_netcdf_reads_back_bit_for_bit(runs, tmp_path):
    t, x, tr, sim = runs
    ds = read_dataset(sim.to_netcdf(tmp_path / "sim.nc", attrs={"study": "round trip"}))
    np.testing.assert_array_equal(ds["time"].values, t)
    assert ds["time"].attrs["units"] == "s"
    np.testing.assert_array_equal(ds["tip_x"].values, x)
    assert ds["tip_x"].attrs["units"] == "m" and ds["tip_x"].attrs["long_name"] == "tip.x"
    np.testing.assert_array_equal(ds["in_cut"].values, 1.0)
    assert ds.attrs["status"] == "ok" and ds.attrs["study"] == "round trip" and ds.attrs["width_m"] == 1e-3
    xr_ds = sim.to_xarray()
    assert set(xr_ds.data_vars) == set(ds.data_vars)

    back = read_dataset(tr.to_netcdf(tmp_path / "tr.nc"))
    for f in ("q", "v", "a"):
        np.testing.assert_array_equal(back[f].values, getattr(tr, f))
        assert back[f].dims == ("output", "time")
    assert back.attrs["output_names"] == "tip.x" and back.attrs["status"] == "ok"


# --------------------------------------------------------------------------- a third result type


@dataclass(frozen=True, eq=False)
class _Toy(TimeHistory):
    """A result that adopts TimeHistory with one class attribute (as a milling run would)."""

    t: np.ndarray
    x: np.ndarray
    chip: np.ndarray
    status: str = "ok"
    message: str = ""
    attrs: dict[str, Any] = field(default_factory=dict)

    history_fields: ClassVar[dict[str, tuple[str, str]]] = {
        "x": ("m", "tool displacement x"),
        "chip": ("m", "chip thickness of tooth"),
    }


def test_a_result_adopts_it_with_a_class_attribute(runs, tmp_path):
    t, x, _, sim = runs
    toy = _Toy(t=t, x=x, chip=np.vstack([x, 2 * x]))
    assert list(toy.histories()) == ["x", "chip.1", "chip.2"]
    np.testing.assert_array_equal(toy.spectrum("chip.2")[1], 2 * sim.spectrum("tip.x", window="all")[1])
    assert toy.growth("x", skip=2.0) == sim.growth("tip.x", skip=2.0)
    head, rows = _read_csv(toy.to_csv(tmp_path / "toy.csv"))
    assert head == ["t [s]", "x [m]", "chip.1 [m]", "chip.2 [m]", "status"]
    np.testing.assert_array_equal([float(r[3]) for r in rows], 2 * x)
    ds = read_dataset(toy.to_netcdf(tmp_path / "toy.nc"))
    np.testing.assert_array_equal(ds["chip_2"].values, 2 * x)
    assert ds["chip_2"].attrs["long_name"] == "chip.2"


# --------------------------------------------------------------------------- names and bad input


def test_deprecated_growth_rate_warns_and_keeps_its_meaning(runs):
    _, _, tr, _ = runs
    with pytest.warns(DeprecationWarning, match="growth"):
        old = tr.growth_rate(0, skip=0.5)  # a fraction of the run, as before
    assert old == tr.growth("tip.x", t_min=2.0)


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda tr, sim: sim.spectrum("nope"), "no history 'nope'.*tip.x"),
        (lambda tr, sim: tr.spectrum("nope"), "not one of the output names"),
        (lambda tr, sim: sim.growth("tip.x", window="first-cut"), "window must be"),
        (lambda tr, sim: tr.growth(0, window="cut"), "window must be 'all' or"),
        (lambda tr, sim: tr.growth(0, skip=-1.0), "skip must be a time >= 0"),
        (lambda tr, sim: sim.to_csv("x.csv", names=["tip.y"]), "no history 'tip.y'"),
        (lambda tr, sim: tr.to_csv("x.csv", fields=("u",)), "field must be 'q', 'v' or 'a'"),
    ],
)
def test_bad_names_and_windows_say_what_exists(runs, call, match):
    _, _, tr, sim = runs
    with pytest.raises(InputError, match=match):
        call(tr, sim)


def test_cut_over_several_passes_is_refused_by_name(runs):
    """Two passes in the cut are two stretches with a gap: a spectrum or a
    growth rate needs one, so window='cut' is refused naming the window (it
    was 't must be increasing and uniformly spaced', a t the user never
    passed); one pass in the cut is accepted."""
    t, x, _, _ = runs
    cut = (t < 1.0) | (t > 2.0)
    _, sim = pair(x, t, in_cut=cut)
    for call in (sim.spectrum, sim.growth):
        with pytest.raises(InputError, match="window 'cut' selects 2 separate stretches.*'last-cut'"):
            call("tip.x", window="cut")
    assert sim.growth("tip.x", window="last-cut") == sim.growth("tip.x", window=(float(t[t > 2.0][0]), T_END))


def test_plot_draws_the_histories(runs):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, x, tr, sim = runs
    ax = tr.plot("tip.x", field="v")
    (line,) = ax.get_lines()
    np.testing.assert_array_equal(line.get_ydata(), tr.v[0])
    assert line.get_label() == "tip.x" and ax.get_ylabel() == "v"
    ax = TimeHistory.plot(sim, ["tip.x", "cut_distance"])
    assert [ln.get_label() for ln in ax.get_lines()] == ["tip.x", "cut_distance"]
    assert ax.get_ylabel() == "[m]"
    plt.close("all")


def test_one_implementation_of_the_shared_methods():
    # issue 9: the two result types had two copies of these, with different names;
    # an override in either would be a second copy again (issue 19: the milling
    # run too, and the files are the one result protocol's)
    for cls in (TimeResponse, Simulation, MillingSimulation):
        for method in ("spectrum", "growth"):
            assert getattr(cls, method) is getattr(TimeHistory, method), (cls.__name__, method)
        for method in ("to_xarray", "to_netcdf", "to_json"):
            assert getattr(cls, method) is getattr(Result, method), (cls.__name__, method)
        assert issubclass(cls, Result)
    assert "to_csv" not in vars(Simulation) and "growth" not in vars(TimeResponse)
    assert "to_csv" not in vars(MillingSimulation)


@pytest.mark.parametrize("cls", [TimeResponse, Simulation, MillingSimulation])
@pytest.mark.parametrize("method", ["plot", "to_csv"])
def test_no_result_narrows_a_shared_method(cls, method):
    """Where a result overrides a shared method, every call the base accepts
    is accepted: each parameter of the base is there, of the same kind, with a
    default where the base has one (the substitution principle, checked on
    the signatures; no override needs ``type: ignore``)."""
    import inspect

    base = inspect.signature(getattr(TimeHistory, method)).parameters
    got = inspect.signature(getattr(cls, method)).parameters
    var_kw = any(p.kind is p.VAR_KEYWORD for p in got.values())
    for name, p in base.items():
        if p.kind is p.VAR_KEYWORD:
            assert var_kw, (cls.__name__, method, "**")
            continue
        q = got.get(name)
        if q is None:
            assert var_kw and p.kind is p.KEYWORD_ONLY, (cls.__name__, method, name)
            continue
        assert q.kind is p.kind, (cls.__name__, method, name)
        assert (p.default is p.empty) or (q.default is not q.empty), (cls.__name__, method, name)


def test_json_reads_back(runs, tmp_path):
    """to_json (the result protocol's, from dataset_parts): the time axis and
    every history with its unit, strict JSON, the numbers bit for bit."""
    import json

    _, x, tr, sim = runs
    text = sim.to_json(tmp_path / "sim.json")
    data = json.loads((tmp_path / "sim.json").read_text())
    assert text.strip() == (tmp_path / "sim.json").read_text().strip() and "NaN" not in text
    assert data["data"]["tip_x"]["units"] == "m" and data["attrs"]["status"] == "ok"
    np.testing.assert_array_equal(np.array(data["data"]["tip_x"]["values"]), x)  # repr round-trips
    np.testing.assert_array_equal(np.array(data["coords"]["time"]["values"]), sim.t)
    assert data["data"]["cut_distance"]["values"][0] == 0.0
    assert json.loads(tr.to_json())["data"]["q"]["values"][0][5] == x[5]


def test_growth_claims_a_class_only_when_the_fit_decides_it():
    """Two modes 1 Hz apart beat: the envelope swings by a factor of 19 each
    second while its trend is a slow growth of 0.02 1/s (3 % over the fit):
    neither "growing" nor "steady" can be claimed from it (it was "growing"
    from the slope's sign alone).  One clean mode decides: its rate is exact
    and its class follows."""
    from chatterlab.time import growth_rate

    t = np.arange(0.0, 2.0, 1e-4)
    beat = np.exp(0.02 * t) * (np.sin(2 * np.pi * 50 * t) + 0.9 * np.sin(2 * np.pi * 51 * t))
    g = growth_rate(t, beat)
    assert g.classification == "undetermined" and g.r2 < 0.5, g
    assert "does not decide" in g.message
    for sigma, cls in ((0.5, "growing"), (-0.5, "decaying"), (0.0, "steady")):
        clean = np.exp(sigma * t) * np.sin(2 * np.pi * 50 * t)
        g = growth_rate(t, clean)
        assert g.classification == cls and abs(g.rate - sigma) < 1e-3, g


def test_every_time_result_follows_the_result_protocol(runs, tmp_path):
    """TimeResponse, Simulation and MillingSimulation are results of the one
    protocol: files that return their path, strict JSON, and plot(ax=ax)
    drawing on the Axes given (a multi-panel plot given one Axes draws its
    first panel there)."""
    import json
    from pathlib import Path

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from chatterlab.process import Milling
    from chatterlab.time import Integration, simulate_milling

    _, _, tr, sim = runs
    wn = 2 * math.pi * 922.0
    mill = simulate_milling(
        ([[0.04]], [[2 * 0.011 * 0.04 * wn]], [[0.04 * wn**2]]),
        Milling.from_immersion(2, 0.02, 6e8, 2e8, 0.05, "down"), 10000.0, 1e-3, feed=1e-4,
        integration=Integration(steps_per_period=30, periods=2),
    )  # fmt: skip
    for k, r in enumerate((tr, sim, mill)):
        assert isinstance(r, Result)
        assert r.to_netcdf(tmp_path / f"{k}.nc") == Path(tmp_path / f"{k}.nc")
        assert r.to_csv(tmp_path / f"{k}.csv") == Path(tmp_path / f"{k}.csv")
        text = r.to_json()
        assert "NaN" not in text and "Infinity" not in text and json.loads(text)["attrs"]["status"] == "ok"
        fig, ax = plt.subplots()
        assert r.plot(ax=ax) is ax and ax.get_lines()
        plt.close(fig)
