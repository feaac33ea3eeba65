"""The style gates of CI as tests: ruff (lint) over the repository and mypy
over the package, run from the repository root so they read the settings in
pyproject.toml.  Both tools come with the ``test`` extra; a test skips only
where its tool is not installed.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(tool: str, *args: str) -> subprocess.CompletedProcess[str]:
    if importlib.util.find_spec(tool) is None:
        pytest.skip(f"{tool} is not installed (it comes with the 'test' extra: pip install -e '.[test]')")
    return subprocess.run(
        [sys.executable, "-m", tool, *args], cwd=ROOT, capture_output=True, text=True, check=False
    )


def test_ruff_check() -> None:
    r = _run("ruff", "check", ".")
    assert r.returncode == 0, f"ruff check . failed:\n{r.stdout}{r.stderr}"


def test_ruff_format() -> None:
    r = _run("ruff", "format", "--check", ".")
    assert r.returncode == 0, f"ruff format --check . failed (run 'ruff format .'):\n{r.stdout}{r.stderr}"


@pytest.mark.slow
def test_mypy() -> None:
    r = _run("mypy", "chatterlab")
    assert r.returncode == 0, f"mypy chatterlab failed:\n{r.stdout}{r.stderr}"
