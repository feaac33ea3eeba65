"""A loky sweep and a joblib ``Parallel`` in one process (the CLI's atlas and
a milling diagram's speeds; a test session): each must find its executor as
it made it.  The sweep once used loky's process-wide reusable executor, which
joblib's Parallel then reused without its memmapping state and failed with
AttributeError '_temp_folder_manager' (seen in CI when pytest-xdist ran
test_sweep and test_milling_defaults in the same worker).  Oracle: the
parallel results equal the serial ones bit for bit."""

from __future__ import annotations

from pathlib import Path

import numpy as np

import chatterlab as cl
from chatterlab.lobes import milling_lobes, milling_loop_of
from chatterlab.sweep import Grid, sweep

MILL = Path(__file__).resolve().parents[1] / "studies" / "milling" / "benchmark_1dof.toml"


def _square(width: float, speed: float) -> dict[str, float]:
    return {"y": width * width + speed}


def test_a_loky_sweep_then_a_parallel_milling_diagram():
    grid = Grid({"width": [1.0, 2.0, 3.0, 4.0], "speed": [0.5, 1.5]})
    par = sweep(_square, grid, outputs={"y": "1"}, backend="loky", jobs=2, chunk_size=1, progress=False)
    ser = sweep(_square, grid, outputs={"y": "1"}, backend="serial", progress=False)
    assert np.array_equal(np.asarray(par["y"]), np.asarray(ser["y"]))
    loop = milling_loop_of(cl.assemble(cl.load_model(str(MILL))).at())
    rpm = np.linspace(9000.0, 12000.0, 4)
    a = milling_lobes(loop, rpm, depth_max=0.005, jobs=2)
    b = milling_lobes(loop, rpm, depth_max=0.005)
    assert np.array_equal(a.a_lim, b.a_lim)
