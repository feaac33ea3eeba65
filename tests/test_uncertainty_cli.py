"""``chatterlab risk`` from the model file to the files (issue 24, "Done
means"): the summary, the netCDF with the probability and the quantiles
as labelled variables and the sample count and error as attributes, the
CSV, both plots, the default checkpoint gone after a complete run, and a
--resume of a kept checkpoint that computes nothing and writes the same
numbers."""

from __future__ import annotations

import matplotlib
import numpy as np
import pytest
from test_uncertainty_badinput import BASE, RISK, run

from chatterlab.io import read_netcdf

matplotlib.use("Agg")

TABLE = """
[uncertainty]
"mode.x1.stiffness" = { distribution = "lognormal", cv = 0.1 }
"mode.x1.damping_ratio" = { distribution = "normal", std = 0.003, lower = 0.0 }
"coupling.cut.Kf" = { distribution = "uniform", low = 1.8e9, high = 2.2e9 }
"""


def test_risk_writes_what_it_prints(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "m.toml").write_text(BASE + TABLE)
    argv = ["risk", "m.toml", *RISK, "--samples", "8", "--replicates", "2", "--point", "6000", "0.3",
            "--risk", "10", "--sensitivity", "--factor", "structure=mode.*"]  # fmt: skip
    code, out, err = run(capsys, *argv, "--out", "r.nc", "--plot", "r.png", "--plot-sobol", "s.png")
    assert code == 0, err
    assert "probabilistic lobes of m.toml: 8 samples (2 replicates x 4" in out
    assert "P(chatter) at 6000 rpm, 0.3 mm" in out and "operating points with P(chatter) <= 10 %" in out
    assert "Sobol' indices of the smallest b_lim" in out and "    structure: S1" in out
    assert (tmp_path / "r.png").stat().st_size > 0 and (tmp_path / "s.png").stat().st_size > 0
    assert not (tmp_path / "r.nc.ckpt").exists()  # removed once the files were in place
    d = read_netcdf(tmp_path / "r.nc")
    assert d.attrs["n_samples"] == 8 and d.attrs["error"] > 0 and "[uncertainty]" in d.attrs["model_text"]
    assert d.dims["p_stable"] == ("speed", "width") and d.data["b_lim_quantile"][1] == "m"
    assert d.dims["sobol_first_b_min"] == ("factor",) and d.data["sobol_first_b_min"][0].shape == (2,)
    # a kept checkpoint: --resume computes nothing and gives the same numbers
    code, _, err = run(capsys, *argv, "--out", "again.csv", "--checkpoint", "ck")
    assert code == 0 and (tmp_path / "ck").is_dir()
    from chatterlab.uncertainty import _task

    def no_work(self, eid):
        raise AssertionError("the resume computed a diagram")

    monkeypatch.setattr(_task.LobeSampleTask, "diagram", no_work)
    monkeypatch.setattr(_task, "_ROWS", type(_task._ROWS)())
    code, out2, err = run(capsys, *argv, "--out", "resumed.csv", "--checkpoint", "ck", "--resume")
    assert code == 0, err
    assert (tmp_path / "again.csv").read_text() == (tmp_path / "resumed.csv").read_text()
    header = (tmp_path / "again.csv").read_text().splitlines()[0]
    assert header.startswith("speed [rpm],width [m],p_stable [1]") and "b_lim_quantile_0.5 [m]" in header
    p = np.loadtxt(tmp_path / "again.csv", delimiter=",", skiprows=1, usecols=2)
    assert np.array_equal(p, d.data["p_stable"][0].ravel())


def test_the_shipped_uncertain_model_is_what_the_study_writes(tmp_path):
    """studies/tap_test/fit_uncertain.toml (the docs' command line example)
    is the fit's model as studies/tap_test/risk.py writes it today."""
    import importlib.util
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    spec = importlib.util.spec_from_file_location("tap_test_risk", root / "studies" / "tap_test" / "risk.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    import tomllib

    made = tomllib.loads(mod.write_model(tmp_path / "fit_uncertain.toml").read_text())
    shipped = tomllib.loads((root / "studies" / "tap_test" / "fit_uncertain.toml").read_text())

    # The fit is Levenberg-Marquardt on a 2-point finite-difference Jacobian (structure/_fit.py): another
    # CPU or BLAS rounds the residuals differently by ~eps, which the difference quotient (step
    # sqrt(eps) |x|) amplifies to ~sqrt(eps) = 1.5e-8 in J, in the steps and in the covariance
    # s^2 (J^T J)^-1 (times its conditioning).  Measured between two CPUs: 3e-9 (parameters) and 3.2e-8
    # (covariances).  Numbers are compared to 100 sqrt(eps) = 1.5e-6, far below the fit's own
    # uncertainty (its standard deviations are 9e-5 of the values and more).
    rtol = 100.0 * float(np.sqrt(np.finfo(float).eps))

    def same(a, b):
        if isinstance(a, dict):
            return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
        if isinstance(a, list):
            return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
        if isinstance(a, float):
            return abs(a - b) <= rtol * max(abs(a), abs(b))
        return a == b

    assert same(made, shipped)


@pytest.mark.slow  # three interpreters (10-25 s); the in-process interrupt of test_uncertainty_lobes.py is fast
def test_a_killed_run_resumes_with_nothing_lost(tmp_path):
    """SIGKILL in the middle of a run (after its first saved chunk), then the
    same command with --resume: the file an uninterrupted run writes."""
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    (tmp_path / "m.toml").write_text(BASE + TABLE)
    cmd = [
        sys.executable,
        "-m",
        "chatterlab.cli",
        "risk",
        "m.toml",
        *RISK,
        "--samples",
        "16",
        "--replicates",
        "2",
    ]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    clean = subprocess.run(
        [*cmd, "--out", "clean.csv"], cwd=tmp_path, env=env, capture_output=True, text=True
    )
    assert clean.returncode == 0, clean.stderr
    p = subprocess.Popen([*cmd, "--out", "killed.csv"], cwd=tmp_path, env=env, start_new_session=True,
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
    ck = Path(tmp_path / "killed.csv.ckpt")
    t0 = time.monotonic()
    while not list(ck.glob("stage_*/chunk_*.npz")) and p.poll() is None and time.monotonic() - t0 < 60:
        time.sleep(0.05)
    os.killpg(p.pid, signal.SIGKILL)
    p.wait()
    assert not (tmp_path / "killed.csv").exists() and ck.is_dir()
    resumed = subprocess.run([*cmd, "--out", "killed.csv", "--resume"], cwd=tmp_path, env=env, capture_output=True,
                             text=True)  # fmt: skip
    assert resumed.returncode == 0, resumed.stderr
    assert (tmp_path / "killed.csv").read_text() == (tmp_path / "clean.csv").read_text()
    assert not ck.exists()


def test_samples_that_establish_nothing_are_never_counted_stable(capsys, tmp_path):
    """Review: on the tap-test model with its search band cut to 100-1000 Hz
    and the checks off, every sample's diagram found no boundary in a band it
    did not prove complete (claim 2: inf, establishing nothing), and risk
    printed P(chatter) = 0 at 12850 rpm, 0.3 mm, exit 0 -- where the cut
    chatters (its rightmost characteristic root is positive, computed here
    independently by `roots` on the nominal model).  Such samples are now
    NaN: the estimate is undetermined, no operating point is offered, and
    the command exits 1 saying why."""
    from chatterlab.frequency import stability
    from chatterlab.model._reader import load_model
    from chatterlab.structure._assembly import assemble

    model = "studies/tap_test/fit_uncertain.toml"
    code, out, err = run(
        capsys, "risk", model, "--speed", "10000", "16000", "--points", "20", "--width-max", "1", "--samples",
        "16", "--fmin", "100", "--fmax", "1000", "--point", "12850", "0.3", "--risk", "5", "--jobs", "1",
        "--quiet", "--verify", "0", "--checkpoint", str(tmp_path / "ck"),
    )  # fmt: skip
    assert code == 1 and "establishing nothing at some speeds" in err
    assert "P(chatter) at 12850 rpm, 0.3 mm: undetermined" in out
    assert "0.0000" not in out.split("P(chatter) at 12850 rpm")[1].splitlines()[0]
    fz = assemble(load_model(model)).at()
    assert stability(fz, width=0.3e-3, speed=12850.0).verdict == "unstable"
