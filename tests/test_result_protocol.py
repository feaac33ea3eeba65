"""One result protocol over every public result type (issue 19, finding 5).

Every class a public analysis returns to the user -- found by walking the
subpackages' ``__all__``, so a new result type cannot escape this test --
inherits the one implementation of the files, :class:`chatterlab.io.Result`,
and for an instance built here:

* ``to_xarray()`` is an :class:`xarray.Dataset` with a ``units`` attribute on
  every variable;
* ``to_netcdf(path)`` returns the path of a netCDF-4 file that reads back
  (through xarray) to the same numbers, bit for bit (doubles stored as doubles);
* ``to_csv(path)`` returns the path of a CSV file whose header cells are
  ``name [unit]`` (or a bare name for a text column) in the naming scheme of
  the netCDF variables, and whose every number reads back to the same double;
* ``to_json()`` is strict JSON (no NaN token);
* ``plot(ax=ax)`` draws on the Axes it is given and returns them.

The protocol is written down in docs/architecture.md.
"""

from __future__ import annotations

import csv
import importlib
import inspect
import json
import math
from pathlib import Path

import numpy as np
import pytest

import chatterlab as cl
from chatterlab.io import Result

ROOT = Path(__file__).resolve().parents[1]
SHAPER = ROOT / "studies" / "traverse_shaper" / "model.toml"
ONE = ROOT / "studies" / "milling" / "benchmark_1dof.toml"
TOOL = ROOT / "studies" / "tap_test" / "tool_point.csv"

SUBPACKAGES = (
    "model",
    "structure",
    "process",
    "frequency",
    "time",
    "lobes",
    "sweep",
    "design",
    "uncertainty",
    "selection",
)
#: public classes with such methods that are not results: the protocol itself,
#: and the base class every time history shares
NOT_RESULTS = {"Result", "TimeHistory", "Model", "System"}
#: result types still on their own file code, each with the reason; to be emptied
PENDING: dict[str, str] = {}

#: results whose CSV is a wide table of time histories (columns named as the model names the
#: recorded quantities, e.g. ``rfe5.x [m]``, ``q:tip.x``), not the long table of their variables
WIDE_HISTORIES = {"Simulation", "TimeResponse", "MillingSimulation"}


def _public_classes() -> dict[str, type]:
    """Every public class with any of the protocol's methods (a result)."""
    out: dict[str, type] = {}
    for sub in SUBPACKAGES:
        try:
            mod = importlib.import_module(f"chatterlab.{sub}")
        except ImportError:
            continue
        for name in getattr(mod, "__all__", ()):
            obj = getattr(mod, name, None)
            if (
                inspect.isclass(obj)
                and not issubclass(obj, BaseException)
                and obj.__module__.startswith("chatterlab")
                and any(
                    hasattr(obj, m) for m in ("plot", "to_csv", "to_netcdf", "to_xarray", "summary", "table")
                )
            ):
                out[name] = obj
    return out


# ----------------------------------------------------------------------------- instances


@pytest.fixture(scope="module")
def shaper():
    return cl.assemble(cl.load_model(SHAPER)).at(0.85)


@pytest.fixture(scope="module")
def milling_loop():
    from chatterlab.lobes import milling_loop_of

    return milling_loop_of(cl.assemble(cl.load_model(ONE)).at())


def _time_and_design(turning, milling_loop) -> dict[str, object]:
    """The time-domain and design results, each from the smallest run that
    makes it (the 1-DOF turning tool of docs/model-format.md, the milling
    benchmark)."""
    from chatterlab.design import design_active, sensitivity, tune_absorbers, with_absorber
    from chatterlab.lobes import confirm
    from chatterlab.time import Integration, simulate, simulate_milling

    tool = cl.assemble(turning)
    rpm = np.linspace(2500.0, 3500.0, 6)
    sim = simulate(tool, width=2e-4, speed=3000.0, integration=Integration(duration=0.05))
    mil = milling_loop
    active = cl.loads_model(
        turning.text
        + '\n[[actuator]]\nid = "damper"\nsensor = "tip"\nsensor_direction = "x"\nvelocity_gain = 100.0\n'
    )
    return {
        "Simulation": sim,
        "TimeResponse": sim.response,
        "MillingSimulation": simulate_milling(
            (np.asarray(mil.M), np.asarray(mil.C), np.asarray(mil.K)), mil.milling, 10000.0, 2e-4,
            integration=Integration(periods=4, steps_per_period=40),
        ),
        "Confirmation": confirm(
            tool, cl.lobes(tool.at(None), np.array([3000.0]), width_max=0.02, verify=0), count=1, periods=4,
            min_duration=0.05,
        ),
        "Sensitivity": sensitivity(turning, rpm, fields=["spring.holder.c1"], width_max=0.02),
        "AbsorberDesign": tune_absorbers(
            with_absorber(turning, "tva", "tip", direction="x", mass=0.05, frequency_hz=480.0, damping_ratio=0.1),
            rpm, starts=1, verify=0, width_max=0.02,
        ),
        "ActiveDesign": design_active(
            active, rpm, free=("velocity",), bounds={"velocity": (0.0, 500.0)}, starts=1, verify=0, width_max=0.02,
            confirm=False,
        ),
    }  # fmt: skip


def _instances(shaper, milling_loop) -> dict[str, object]:
    from conftest import turning_text

    from chatterlab.frequency import (
        characteristic_roots,
        forced_response,
        multipliers,
        runout_response,
        ssv_limits,
        surface_location,
    )
    from chatterlab.selection import chatter_frequency, chatter_rule, recommend
    from chatterlab.structure import fit_modes
    from chatterlab.sweep import Grid, sweep
    from chatterlab.uncertainty import risk

    w = 2 * np.pi * np.linspace(70.0, 90.0, 7)
    loop = cl.closed_loop(shaper, width=2e-4, speed=0.5)
    fit = fit_modes(
        cl.FRF.read(TOOL).select(["tool.x"], ["tool.x"]),
        band=(2 * np.pi * 400.0, 2 * np.pi * 1000.0),
        max_order=12,
    )

    def rate(width: float, speed: float) -> dict[str, float]:
        return {"abscissa": float(cl.stability(shaper, width=width, speed=speed, winding=False).abscissa)}

    turning = cl.loads_model(
        turning_text(name="1-DOF turning")
        + '\n[uncertainty]\n"coupling.cut.Kf" = { distribution = "lognormal", cv = 0.1 }\n',
        source="turning.toml",
    )
    rpm = np.linspace(2000.0, 12000.0, 40)
    # a 2-tooth cutter at 10000 rpm (166.7 Hz) and its harmonics, with a chatter tone at
    # 951.3 Hz between the 5th and the 6th
    fs, f_sp = 20000.0, 10000.0 / 60.0
    t = np.arange(int(0.5 * fs)) / fs
    signal = sum((3.0 / m) * np.sin(2 * np.pi * m * f_sp * t + m) for m in range(1, 50))
    heard = chatter_frequency((t, signal + 0.1 * np.sin(2 * np.pi * 951.3 * t)), spindle_hz=f_sp, teeth=2)
    return {
        "ProbabilisticLobes": risk(turning, rpm, width_max=2e-3, samples=4, replicates=2, backend="serial"),
        "Recommendation": recommend(turning, rpm, margin=0.2, count=2, check=False),
        "ChatterFrequency": heard,
        "SpeedRule": chatter_rule(heard, 60.0 * f_sp, teeth=2, count=2),
        "LobeDiagram": cl.lobes(shaper, np.linspace(0.4, 0.6, 5), width_max=1e-3, verify=0),
        "Stability": cl.stability(shaper, width=2e-4, speed=0.5),
        "RootsResult": characteristic_roots(loop, count=4),
        "Multipliers": multipliers(milling_loop, 18000.0, 1e-3, check=False),
        "ForcedResponse": forced_response(milling_loop, 10000.0, 2e-4, 1e-4),
        "SurfaceLocation": surface_location(milling_loop, [9000.0, 10000.0], 2e-4, 1e-4, check=False),
        "RunoutResponse": runout_response(
            cl.closed_loop(cl.assemble(turning).at(), width=2e-4, speed=3000.0), [2000.0, 3000.0], 2e-5, 1e-4, 2e9,
            inputs="tip.x", outputs="tip.x",
        ),
        "SsvLimits": ssv_limits(milling_loop, [18000.0], [0.0, 0.1], [0.25], width_max=2e-3, scan=4),
        "Modes": cl.modes(shaper, count=4),
        **_time_and_design(turning, milling_loop),
        "FRF": cl.frf(loop, w, inputs="rfe5.x", outputs=["rfe5.x", "rfe5.y"]),
        "ModalFit": fit,
        "Stabilisation": fit.stabilisation,
        "SweepResult": sweep(
            rate, Grid({"width": [1e-4, 2e-4], "speed": [0.5]}), outputs={"abscissa": "1/s"}, backend="serial",
            progress=False,
        ),
    }  # fmt: skip


@pytest.fixture(scope="module")
def instances(shaper, milling_loop) -> dict[str, object]:
    return _instances(shaper, milling_loop)  # built once for the module's tests


def test_every_public_result_type_is_covered(instances):
    classes = _public_classes()
    results = {n for n, c in classes.items() if n not in NOT_RESULTS}
    built = set(instances)
    assert results <= built | set(PENDING), sorted(results - built - set(PENDING))
    assert not (built & set(PENDING))
    for name in built:
        assert issubclass(classes[name], Result), name


@pytest.mark.parametrize(
    "name",
    ["LobeDiagram", "Stability", "RootsResult", "Multipliers", "Modes", "FRF", "ModalFit", "Stabilisation",
     "SweepResult", "ProbabilisticLobes", "Recommendation", "ChatterFrequency", "SpeedRule", "ForcedResponse",
     "SurfaceLocation", "RunoutResponse", "SsvLimits", "Simulation", "TimeResponse", "MillingSimulation",
     "Confirmation", "Sensitivity", "AbsorberDesign", "ActiveDesign"],
)  # fmt: skip
def test_the_protocol(name, instances, tmp_path):
    import matplotlib
    import matplotlib.axes

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import xarray as xr

    r = instances[name]
    assert isinstance(r, Result)
    ds = r.to_xarray()
    assert isinstance(ds, xr.Dataset)
    assert all("units" in v.attrs for v in ds.variables.values()), [
        k for k, v in ds.variables.items() if "units" not in v.attrs
    ]
    p = r.to_netcdf(tmp_path / "r.nc")
    assert Path(p) == tmp_path / "r.nc" and p.is_file()
    with xr.open_dataset(p, engine="h5netcdf") as back:
        for k, v in ds.data_vars.items():
            if v.dtype.kind == "f":
                np.testing.assert_array_equal(back[k].values, v.values)
    c = r.to_csv(tmp_path / "r.csv")
    assert Path(c) == tmp_path / "r.csv"
    with open(c, newline="") as fh:  # an FRF file starts with its units as comment lines
        rows = [r for r in csv.reader(fh) if r and not r[0].startswith("#")]
    head = rows[0]
    names = set(ds.variables) | {"frequency", "re", "im", "magnitude", "phase", "reason"}
    if name in WIDE_HISTORIES:
        # a time history's CSV is wide (docs/time-domain.md): the time, then one column per
        # recorded history as the model names it, then the run's status; one row per instant
        assert head[0] == "t [s]" and head[-1] == "status", head
        assert len(rows) == ds.sizes["time"] + 1, (len(rows), ds.sizes)
        head = []
    for h in head:
        stem = h.split(" [")[0].split(" ")[-1]
        assert h.endswith("]") or h.isidentifier(), h  # name [unit], or a bare word column
        assert stem in names or any(stem.startswith(n) for n in names) or "/" in h, (h, sorted(names))
    text = r.to_json()
    assert "NaN" not in text and "Infinity" not in text
    json.loads(text)
    drawn = r.plot()  # a new figure: its Axes (a tuple or array of them for several panels)
    axes = list(np.ravel(np.asarray(drawn, dtype=object)))
    assert axes and all(isinstance(a, matplotlib.axes.Axes) for a in axes), drawn
    again = r.plot(ax=drawn)  # drawn again on those Axes, and they are returned
    assert list(np.ravel(np.asarray(again, dtype=object))) == axes
    plt.close("all")


def test_csv_numbers_are_exact(shaper, tmp_path):
    """Every number of a result CSV is the shortest decimal that reads back to its double."""
    d = cl.lobes(shaper, np.linspace(0.4, 0.6, 5), width_max=1e-3, verify=0)
    with open(d.to_csv(tmp_path / "l.csv"), newline="") as fh:
        rows = list(csv.DictReader(fh))
    got = np.array([float(r["b_lim [m]"]) for r in rows])
    np.testing.assert_array_equal(got, d.b_lim)
    assert all(math.isfinite(float(r["delay [s]"])) for r in rows)
