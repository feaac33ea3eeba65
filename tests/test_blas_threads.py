"""One BLAS thread where chatterlab's work is many small dense problems.

threadpoolctl limits only the libraries loaded when the limit is entered.
Since ``import chatterlab`` loads no scipy, scipy's own OpenBLAS must be
loaded before the limit, or it keeps one thread per core: on 2 shared cores
that made the milling example 60-120x slower and the README's Python
example 4x (found by a review).  Each check runs in a fresh interpreter, so
that nothing imported by the test session hides the order of loading.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHAPER = ROOT / "studies" / "traverse_shaper" / "model.toml"

#: prints the thread counts of every BLAS library outside and inside the call
PROBE = """
import json, sys
from threadpoolctl import threadpool_info
def blas():
    return sorted({{d["filepath"]: d["num_threads"] for d in threadpool_info() if d["user_api"] == "blas"}}.items())
seen = {{}}
{setup}
print(json.dumps({{"inside": seen["inside"], "outside": blas()}}))
"""


def _run(setup: str) -> dict[str, list[list[object]]]:
    env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
    out = subprocess.run(
        [sys.executable, "-c", PROBE.format(setup=setup)],
        capture_output=True,
        text=True,
        check=True,
        env=env,
        cwd=ROOT,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def _check(res: dict[str, list[list[object]]]) -> None:
    inside = dict(map(tuple, res["inside"]))  # type: ignore[arg-type]
    outside = dict(map(tuple, res["outside"]))  # type: ignore[arg-type]
    assert any("scipy" in p for p in inside), inside  # scipy's own BLAS is among them
    assert set(inside.values()) == {1}, inside
    if (os.cpu_count() or 1) > 1:  # the probe sees a real limit, not a 1-thread default
        assert max(outside.values()) > 1, outside


def test_every_blas_has_one_thread_during_a_command() -> None:
    setup = f"""
from chatterlab.cli import _main
def probe(args):
    import scipy.linalg
    seen["inside"] = blas()
    return 0
_main.COMMANDS["check"] = probe
assert _main.main(["check", {str(SHAPER)!r}]) == 0
"""
    _check(_run(setup))


def test_every_blas_has_one_thread_inside_lobes() -> None:
    setup = f"""
import numpy as np
import chatterlab as cl
import chatterlab.lobes._diagram as dg
from chatterlab.lobes import lobes
verify = dg._verify
def probe(*a, **k):
    seen["inside"] = blas()
    return verify(*a, **k)
dg._verify = probe
fz = cl.assemble(cl.load_model({str(SHAPER)!r})).at(0.85)
lobes(fz, np.linspace(0.5, 0.6, 3), width_max=1e-3, verify=1)
"""
    _check(_run(setup))


def test_every_blas_has_one_thread_in_a_serial_sweep() -> None:
    """The serial backend's limit, with a task that reaches scipy only inside
    the sweep (a user's function; import chatterlab loads no scipy)."""
    setup = """
from chatterlab.sweep import sweep
def task(x):
    import scipy.linalg
    seen["inside"] = blas()
    return {"y": x}
sweep(task, {"x": [1.0]}, outputs={"y": ""}, backend="serial", progress=False)
"""
    _check(_run(setup))
