"""The Python examples of the README and docs/ run as written.

Each ```python block is run in a fresh interpreter in a scratch folder where
``studies/`` is the repository's (the examples load the shipped shaper); it
must exit 0.  Blocks that need a file made by an earlier command of their
page are run after that command (``PREREQUISITES``); blocks that depend on a
user's own files are listed in ``NOT_RUN`` with the reason and are not
collected, so that a new block is run unless someone says why not (and an
entry that no longer matches exactly one block fails).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

#: commands run before a page's blocks (the files they make are what the block reads)
PREREQUISITES = {
    "docs/cli.md": [
        [
            "lobes",
            "studies/traverse_shaper/model.toml",
            "--speed",
            "0.1",
            "1.0",
            "--width-max",
            "1",
            "--verify",
            "0",
            "--out",
            "lobes.nc",
        ],
    ],
}
#: blocks that read a user's own model file, by page and a phrase of the block
NOT_RUN = {
    ("docs/model-format.md", 'load_model("model.toml")'): "a user's own model.toml",
    ("docs/time-domain.md", 'load_model("turning.toml")'): "a user's own turning.toml",
}


def _blocks() -> list[tuple[str, int, str]]:
    out = []
    for page in PAGES:
        text = page.read_text()
        for m in re.finditer(r"^```python\n(.*?)^```", text, flags=re.M | re.S):
            line = text[: m.start()].count("\n") + 1
            out.append((str(page.relative_to(ROOT)), line, m.group(1)))
    return out


def _excluded(page: str, code: str) -> bool:
    return any(pg == page and phrase in code for pg, phrase in NOT_RUN)


ALL_BLOCKS = _blocks()
BLOCKS = [b for b in ALL_BLOCKS if not _excluded(b[0], b[2])]


def test_every_page_with_python_is_found():
    assert {p for p, _, _ in ALL_BLOCKS} >= {"README.md", "docs/index.md", "docs/lobes.md"}


def test_each_exclusion_names_exactly_one_block():
    """An entry of NOT_RUN that matches no block (the example was changed) or
    several fails here, so nothing is left unrun without a stated reason."""
    for (pg, phrase), why in NOT_RUN.items():
        hits = [n for p, n, c in ALL_BLOCKS if p == pg and phrase in c]
        assert len(hits) == 1, f"NOT_RUN entry {pg} {phrase!r} ({why}) matches blocks at lines {hits}"


@pytest.mark.slow
@pytest.mark.parametrize(("page", "line", "code"), BLOCKS, ids=[f"{p}:{n}" for p, n, _ in BLOCKS])
def test_python_example_runs(page, line, code, tmp_path):
    (tmp_path / "studies").symlink_to(ROOT / "studies")
    env = dict(os.environ, MPLBACKEND="Agg")
    for cmd in PREREQUISITES.get(page, []):
        r = subprocess.run(
            [sys.executable, "-m", "chatterlab.cli", *cmd],
            cwd=tmp_path,
            env=env,
            capture_output=True,
            text=True,
        )
        assert r.returncode == 0, r.stderr[-2000:]
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert r.returncode == 0, f"{page}:{line}\n{r.stderr[-3000:]}"


@pytest.mark.slow
def test_readme_example_prints_what_the_cli_prints(tmp_path):
    """The README's Python example and its main command report the same
    minimum b_lim (both 0.1778 mm on the shaper) and the example saves its figure."""
    code = next(c for p, _, c in ALL_BLOCKS if p == "README.md")
    (tmp_path / "studies").symlink_to(ROOT / "studies")
    env = dict(os.environ, MPLBACKEND="Agg")
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "minimum b_lim in range: 0.1778 mm" in r.stdout
    assert (tmp_path / "shaper_lobes.png").stat().st_size > 0
    import matplotlib.image

    img = matplotlib.image.imread(tmp_path / "shaper_lobes.png")
    assert img.ndim == 3 and (img[..., :3].std(axis=(0, 1)) > 0.01).any()  # not a blank canvas
