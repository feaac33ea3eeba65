"""What the README main job loads (issue 26, "Start-up"): a command imports
what it needs when it needs it.

The main job, ``chatterlab lobes studies/traverse_shaper/model.toml --speed
0.1 1.0 --width-max 1 --out shaper_lobes.nc --plot shaper_lobes.png``, is run
in a fresh interpreter and what it loaded is read from ``sys.modules``: none
of the subpackages' other modules (milling, Floquet, python-control, modal
fits), no parallel machinery for this serial job, no xarray for the netCDF
file, no pyplot for a figure that is only saved.  Its time is measured, not
asserted, by benchmarks/bench_startup.py (a timing bound is not an oracle).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "studies" / "traverse_shaper" / "model.toml"
JOB = ["lobes", str(MODEL), "--speed", "0.1", "1.0", "--width-max", "1"]
JOB += ["--out", "shaper_lobes.nc", "--plot", "shaper_lobes.png"]

#: what the main job must not load (module name prefixes)
NOT_LOADED = (
    "matplotlib.pyplot",
    "joblib",
    "loky",
    "xarray",
    "control",
    "scipy.interpolate",
    "scipy.signal",
    "scipy.integrate",
    "scipy.stats",
    "chatterlab.sweep",
    "chatterlab.time",
    "chatterlab.lobes._milling",
    "chatterlab.lobes._control",
    "chatterlab.lobes._confirm",
    "chatterlab.lobes._measured",
    "chatterlab.frequency._floquet",
    "chatterlab.frequency._forced",
    "chatterlab.structure._fit",
    "chatterlab.structure._rcsa",
    "chatterlab.process._milling",
    "chatterlab.plot._atlas",
    "chatterlab.plot._frf",
    "chatterlab.plot._time",
)

_PROBE = """
import json, os, sys
from chatterlab.cli import main
code = main()  # as the console script calls it: the command owns the process
tasks = len(os.listdir("/proc/self/task")) if os.path.isdir("/proc/self/task") else -1
print("PROBE " + json.dumps({"code": code, "modules": sorted(sys.modules), "threads": tasks,
      "openblas_env": os.environ.get("OPENBLAS_NUM_THREADS")}))
"""


def _probe(cwd: Path, extra_env: dict[str, str] | None = None) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS")}
    env.pop("OMP_NUM_THREADS", None)
    env.update(MPLBACKEND="Agg", **(extra_env or {}))
    r = subprocess.run(
        [sys.executable, "-c", _PROBE, *JOB], cwd=cwd, env=env, capture_output=True, text=True, timeout=300
    )
    assert r.returncode == 0, r.stderr[-2000:]
    line = next(x for x in r.stdout.splitlines() if x.startswith("PROBE "))
    return json.loads(line[len("PROBE ") :])


@pytest.fixture(scope="module")
def main_job(tmp_path_factory):
    cwd = tmp_path_factory.mktemp("main_job")
    return cwd, _probe(cwd)


def test_the_main_job_loads_what_it_needs_only(main_job):
    cwd, got = main_job
    assert got["code"] == 0
    assert (cwd / "shaper_lobes.nc").is_file() and (cwd / "shaper_lobes.png").is_file()
    mods = got["modules"]
    assert "chatterlab.lobes._diagram" in mods and "h5netcdf" in mods  # the record is complete
    loaded = sorted(m for m in mods if any(m == p or m.startswith(p + ".") for p in NOT_LOADED))
    assert not loaded, f"the main job loaded {loaded[:10]}"


@pytest.mark.skipif(
    not sys.platform.startswith("linux") or (os.cpu_count() or 1) < 2, reason="/proc, 2 cores"
)
def test_the_main_job_starts_no_blas_thread_and_leaves_the_environment(main_job):
    # OpenBLAS starts (cores - 1) workers per library when loaded unless told one thread; the
    # command runs on one (chatterlab._threads.one_blas_thread), so none is started: the process
    # has its main thread only
    _, got = main_job
    assert got["threads"] == 1, f"{got['threads']} threads after the command"
    assert got["openblas_env"] is None, "OPENBLAS_NUM_THREADS left set for the command's child processes"


def test_a_users_blas_setting_is_kept(tmp_path):
    got = _probe(tmp_path, {"OPENBLAS_NUM_THREADS": "2"})
    assert got["code"] == 0 and got["openblas_env"] == "2"


def test_a_figure_made_without_pyplot_is_the_same_picture(tmp_path):
    """plot_lobes inside plot.headless() (the command line) against pyplot's
    figure: the same pixels (the PNG is printed on the Agg canvas either way)."""
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    from PIL import Image

    from chatterlab.lobes import lobes
    from chatterlab.model import load_model
    from chatterlab.plot import headless, plot_lobes, savefig
    from chatterlab.structure import assemble

    d = lobes(assemble(load_model(MODEL)).at(None), np.linspace(0.15, 0.2, 40), width_max=1e-3, verify=0)
    with headless():
        ax = plot_lobes(d, title="t")
        made_by = type(ax[0].figure.canvas).__name__
        savefig(ax, str(tmp_path / "headless.png"))
    savefig(plot_lobes(d, title="t"), str(tmp_path / "pyplot.png"))
    assert made_by == "FigureCanvasAgg"
    a = np.asarray(Image.open(tmp_path / "headless.png"))
    b = np.asarray(Image.open(tmp_path / "pyplot.png"))
    assert a.shape == b.shape and np.array_equal(a, b)
