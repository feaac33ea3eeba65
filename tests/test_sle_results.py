"""The results of the forced-vibration analyses (ForcedResponse, SurfaceLocation,
RunoutResponse) on the Result protocol, checked as tests/test_result_protocol.py
checks every public result (netCDF round trip, ``name [unit]`` CSV columns,
strict JSON, plot(ax=None) returning its Axes and drawing again on them)."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from conftest import turning_text

import chatterlab as cl
from chatterlab.frequency import forced_response, runout_response, surface_location
from chatterlab.io import Result
from chatterlab.process import Milling, milling_loop
from chatterlab.structure import Structure


def _milling():
    wn = 2 * math.pi * 922.0
    st = Structure(
        np.eye(1) * 0.03993, np.eye(1) * 2 * 0.011 * 0.03993 * wn, np.eye(1) * 0.03993 * wn**2, ("y",), "y"
    )
    return milling_loop(st, Milling.from_immersion(2, 0.02, 6e8, 2e8, 0.05, "down"))


def _results() -> dict[str, Result]:
    loop = _milling()
    turning = cl.closed_loop(cl.assemble(cl.loads_model(turning_text())).at(), width=2e-4, speed=3000.0)
    return {
        "ForcedResponse": forced_response(loop, 10000.0, 2e-4, 1e-4),
        # the last speed chatters at this depth: a NaN SLE must read back as NaN / null
        "SurfaceLocation": surface_location(loop, [9000.0, 12000.0, 15000.0], 2e-3, 1e-4, check=False),
        "RunoutResponse": runout_response(turning, [2000.0, 3000.0], 2e-5, 1e-4, 2e9, inputs="tip.x", outputs="tip.x"),
    }  # fmt: skip


@pytest.mark.parametrize("name", ["ForcedResponse", "SurfaceLocation", "RunoutResponse"])
def test_the_protocol(name, tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.axes
    import matplotlib.pyplot as plt
    import xarray as xr

    r = _results()[name]
    assert isinstance(r, Result)
    ds = r.to_xarray()
    assert all("units" in v.attrs for v in ds.variables.values())
    p = r.to_netcdf(tmp_path / "r.nc")
    with xr.open_dataset(p, engine="h5netcdf") as back:
        for k, v in ds.data_vars.items():
            np.testing.assert_array_equal(back[k].values, v.values)
    with open(r.to_csv(tmp_path / "r.csv"), newline="") as fh:
        head = next(csv.reader(fh))
    assert all(h.endswith("]") for h in head), head
    assert {h.split(" [")[0] for h in head} <= set(ds.variables)
    text = r.to_json()
    assert "NaN" not in text and "Infinity" not in text
    json.loads(text)
    drawn = r.plot()
    axes = list(np.ravel(np.asarray(drawn, dtype=object)))
    assert axes and all(isinstance(a, matplotlib.axes.Axes) for a in axes)
    again = r.plot(ax=drawn)
    assert list(np.ravel(np.asarray(again, dtype=object))) == axes
    plt.close("all")


def test_surface_location_reports_chatter_not_an_sle():
    s = _results()["SurfaceLocation"]
    assert s.verdict[-1] == "unstable" and math.isnan(s.sle[-1]) and math.isnan(s.peak_to_valley[-1])
    assert s.verdict[0] == "stable" and math.isfinite(s.sle[0])
    assert "1 unstable (chatter, no SLE)" in s.summary()
