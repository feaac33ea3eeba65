"""The installed package runs its own examples (issue 20, item 1).

The wheel is built from a copy of the working tree (``pip wheel``: setuptools
from the package index in pip's isolated build, as any user's build), and
installed into a new venv outside the tree (``--system-site-packages``, so the
dependencies come from this environment without a download; ``--no-deps``).
From a temporary folder, with no repository in sight, the venv's
``chatterlab`` then runs the README's main job on ``example:traverse_shaper``,
copies the milling examples with ``chatterlab example milling`` and draws the
1-DOF benchmark's lobes from the copy, and runs a ``--frf`` job on
``example:tool_point``.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

from chatterlab._examples import EXAMPLES

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.slow

#: what a build needs of the tree (the studies: only the example files)
_TREE = ("chatterlab", "pyproject.toml", "setup.py", "MANIFEST.in", "README.md", "LICENSE")


def _run(cmd: list[str], cwd: Path, env: dict[str, str], timeout: float = 240) -> subprocess.CompletedProcess:
    r = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert r.returncode == 0, f"{' '.join(cmd)} -> {r.returncode}\n{r.stdout}\n{r.stderr}"
    return r


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> tuple[Path, dict[str, str]]:
    """(the venv's bin folder, an environment without the repository on any path)."""
    base = tmp_path_factory.mktemp("wheel")
    src = base / "src"
    src.mkdir()
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info")
    for name in _TREE:
        p = ROOT / name
        (shutil.copytree(p, src / name, ignore=ignore) if p.is_dir() else shutil.copy2(p, src / name))
    for rel, _ in EXAMPLES.values():
        (src / "studies" / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / "studies" / rel, src / "studies" / rel)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    env["MPLBACKEND"] = "Agg"
    dist = base / "dist"
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", str(src), "-w", str(dist)], base, env, 400)
    (wheel,) = dist.glob("chatterlab-*.whl")
    with zipfile.ZipFile(wheel) as z:
        shipped = set(z.namelist())
    assert {f"chatterlab/examples/{rel}" for rel, _ in EXAMPLES.values()} <= shipped
    assert not any(n.startswith(("studies/", "tests/")) for n in shipped)
    venv = base / "venv"
    # no pip and no dependencies of its own: the test environment's
    # site-packages (a venv's or the system's) are put on its path by a .pth
    # file, after its own site-packages, so the wheel's chatterlab comes first
    _run([sys.executable, "-m", "venv", "--without-pip", str(venv)], base, env)
    py = venv / "bin" / "python"
    ours = subprocess.run(
        [str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        capture_output=True, text=True, check=True,
    ).stdout.strip()  # fmt: skip
    here = {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}
    (Path(ours) / "_test_env.pth").write_text("".join(f"{p}\n" for p in sorted(here)))
    _run([str(py), "-m", "pip", "install", "--no-deps", "--no-index", str(wheel)], base, env)
    return venv / "bin", env


def test_the_installed_package_is_the_wheel(installed, tmp_path):
    bin_, env = installed
    code = "import chatterlab, chatterlab._examples as e; print(chatterlab.__file__); print(e.example_path('tool_point'))"
    out = _run([str(bin_ / "python"), "-c", code], tmp_path, env).stdout.split()
    venv = bin_.parent
    assert all(Path(p).is_relative_to(venv) for p in out), out
    assert "/chatterlab/examples/tap_test/tool_point.csv" in out[1]


def test_readme_main_job_from_the_wheel(installed, tmp_path):
    """The README's main job, on the bundled shaper, from a folder with no repository."""
    bin_, env = installed
    cmd = [str(bin_ / "chatterlab"), "lobes", "example:traverse_shaper", "--speed", "0.1", "1.0"]
    r = _run(
        [*cmd, "--width-max", "1", "--out", "shaper_lobes.nc", "--plot", "shaper_lobes.png"], tmp_path, env
    )
    assert "0.1778 mm" in r.stdout, r.stdout  # the README's minimum b_lim
    assert (tmp_path / "shaper_lobes.nc").stat().st_size > 0 and (
        tmp_path / "shaper_lobes.png"
    ).stat().st_size > 0


def test_milling_example_copied_and_run(installed, tmp_path):
    bin_, env = installed
    cl = str(bin_ / "chatterlab")
    listing = _run([cl, "example"], tmp_path, env).stdout
    assert all(name in listing for name in EXAMPLES)
    _run([cl, "example", "milling"], tmp_path, env)
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "benchmark_1dof.toml",
        "benchmark_2dof.toml",
        "tool_cantilever.toml",
    ]
    # never over an existing file: one line, status 2, the file as it was
    (tmp_path / "benchmark_1dof.toml").write_text("# mine\n")
    again = subprocess.run(
        [cl, "example", "benchmark_1dof"], cwd=tmp_path, env=env, capture_output=True, text=True
    )
    assert again.returncode == 2 and len(again.stderr.strip().splitlines()) == 1, again.stderr
    assert "never overwrites" in again.stderr and (tmp_path / "benchmark_1dof.toml").read_text() == "# mine\n"
    (tmp_path / "benchmark_1dof.toml").unlink()
    _run([cl, "example", "benchmark_1dof"], tmp_path, env)
    r = _run(
        [
            cl,
            "lobes",
            "benchmark_1dof.toml",
            "--speed",
            "5000",
            "25000",
            "--points",
            "41",
            "--width-max",
            "10",
            "--out",
            "lobes_milling.csv",
        ],
        tmp_path,
        env,
    )
    assert "benchmark_1dof.toml" in r.stdout and "rpm" in r.stdout, r.stdout
    assert (tmp_path / "lobes_milling.csv").stat().st_size > 0


def test_frf_example_from_the_wheel(installed, tmp_path):
    bin_, env = installed
    r = _run(
        [
            str(bin_ / "chatterlab"),
            "lobes",
            "--frf",
            "example:tool_point",
            "--teeth",
            "3",
            "--kt",
            "6e8",
            "--kn",
            "2e8",
            "--immersion",
            "0.5",
            "--speed",
            "4000",
            "12000",
            "--points",
            "60",
            "--width-max",
            "5",
            "--out",
            "frf_lobes.csv",
        ],
        tmp_path,
        env,
    )
    assert "tool_point" in r.stdout and "rpm" in r.stdout, r.stdout
    assert (tmp_path / "frf_lobes.csv").stat().st_size > 0


def test_every_example_is_in_the_sdist_manifest():
    """MANIFEST.in carries the example files into an sdist (a wheel built from it has them too)."""
    import fnmatch

    pats = [
        ln.split(None, 1)[1]
        for ln in (ROOT / "MANIFEST.in").read_text().splitlines()
        if ln.startswith("include ")
    ]
    for rel, _ in EXAMPLES.values():
        assert any(fnmatch.fnmatch(f"studies/{rel}", p) for p in " ".join(pats).split()), rel
        assert (ROOT / "studies" / rel).is_file(), rel
