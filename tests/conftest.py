"""Shared fixtures: the shipped traverse-shaper model and builders of small
model files (TOML text for :func:`chatterlab.loads_model`).

The builders are fixtures that return functions, so every test module can
use them without importing from ``conftest``.
"""

from __future__ import annotations

import os
import signal
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import settings

# CI runs the property tests on the same examples every time (a failure is
# reproducible, never a coin toss between two runs of one commit); locally
# hypothesis explores new examples on each run.
settings.register_profile("ci", derandomize=True)
if os.environ.get("CI"):
    settings.load_profile("ci")

# A shell starts a background job with SIGINT ignored, and a child process
# inherits the ignoring: the tests that send Ctrl-C (SIGINT) to chatterlab
# then see it ignored.  A handler of our own is reset to the default in the
# children at exec, so they get Python's KeyboardInterrupt as from a terminal.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

ROOT = Path(__file__).resolve().parents[1]

#: Steel, the values used throughout the tests (SI).
STEEL = {"E": 2.1e11, "nu": 0.3, "rho": 7850.0}


@pytest.fixture(scope="session")
def shaper_path() -> Path:
    """The traverse shaper of the seed paper, as shipped in studies/."""
    p = ROOT / "studies" / "traverse_shaper" / "model.toml"
    assert p.is_file(), p
    return p


def _section_toml(b: float, h: float, E: float, nu: float, rho: float, kappa: float) -> str:
    A = b * h
    I = b * h**3 / 12.0
    return f"A = {A!r}\nI = {I!r}\nE = {E!r}\nnu = {nu!r}\nrho = {rho!r}\nkappa = {kappa!r}\n"


def rect_section(b: float, h: float, E: float, nu: float, kappa: float = 5.0 / 6.0) -> dict[str, float]:
    """A, I, G, kappa of a b x h rectangle (h in the bending plane)."""
    return {"A": b * h, "I": b * h**3 / 12.0, "E": E, "G": E / (2.0 * (1.0 + nu)), "kappa": kappa}


@pytest.fixture
def section() -> Callable[..., dict[str, float]]:
    """``section(b, h, E=..., nu=..., kappa=...)`` -> dict of A, I, E, G, kappa."""

    def make(b: float, h: float, E: float = STEEL["E"], nu: float = STEEL["nu"], kappa: float = 5.0 / 6.0):
        return rect_section(b, h, E, nu, kappa)

    return make


@pytest.fixture
def beam_model_text() -> Callable[..., str]:
    """``beam_model_text(L, h, ...)``: one straight beam from node "a" to node
    "b" (length L, rectangle b x h), subdivided into ``elements``, at
    ``angle_deg`` to global X.

    ``clamp``: ``"support"`` clamps node a with a [[support]], ``"ground"``
    attaches it to the ground with an [[attachment]], ``None`` leaves the
    beam free-free.
    """
    import math

    def make(
        L: float,
        h: float,
        *,
        b: float = 0.05,
        elements: int = 1,
        angle_deg: float = 0.0,
        clamp: str | None = "support",
        E: float = STEEL["E"],
        nu: float = STEEL["nu"],
        rho: float = STEEL["rho"],
        kappa: float = 5.0 / 6.0,
        x0: tuple[float, float] = (0.0, 0.0),
    ) -> str:
        c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
        xb = (x0[0] + L * c, x0[1] + L * s)
        text = (
            '[model]\nname = "beam"\n\n'
            f'[[node]]\nid = "a"\nat = [{x0[0]!r}, {x0[1]!r}]\n\n'
            f'[[node]]\nid = "b"\nat = [{xb[0]!r}, {xb[1]!r}]\n\n'
            '[[beam]]\nid = "beam"\nnodes = ["a", "b"]\n'
            + _section_toml(b, h, E, nu, rho, kappa)
            + f"elements = {elements}\n\n"
        )
        if clamp == "support":
            text += '[[support]]\nid = "clamp"\nnode = "a"\n'
        elif clamp == "ground":
            text += '[[attachment]]\nid = "clamp"\nnode = "a"\nbody = "ground"\n'
        elif clamp is not None:  # pragma: no cover - test misuse
            raise ValueError(clamp)
        return text

    return make


@pytest.fixture
def block_text() -> Callable[..., str]:
    """``block_text(extra="")``: a valid minimal model, one rigid body "block"
    (100 kg, 2 kg m^2 at the origin) on three springs to the ground, plus
    ``extra`` TOML appended (for the bad-input tests to spoil)."""

    def make(extra: str = "", *, mass: float = 100.0, inertia: float = 2.0) -> str:
        return (
            f'[[body]]\nid = "block"\nmass = {mass!r}\ninertia = {inertia!r}\ncentre = [0.0, 0.0]\n\n'
            '[[spring]]\nid = "mount"\na = "block"\nb = "ground"\n'
            "c1 = 1.0e7\nc2 = 2.0e7\nc6 = 3.0e5\n\n" + extra
        )

    return make


def turning_text(
    *,
    mass: float = 1.0,
    stiffness: float = 1.0e7,
    damping: float = 189.7,
    Kf: float = 2.0e9,
    rpm: float = 3000.0,
    forces: tuple[float, float, float] | None = None,
    name: str = "turning tool, one degree of freedom",
) -> str:
    """docs/model-format.md's 1-DOF turning tool: a body free along x on a
    spring-damper to the ground, cut by a regenerative coupling (K_f b
    [x(t) - x(t - T)]) at b_ref = 1 mm, turning at ``rpm``.  The tests'
    shared oracle model: G(jw) = 1 / (k - m w^2 + j c w)."""
    force_line = "" if forces is None else f"forces = [{forces[0]!r}, {forces[1]!r}, {forces[2]!r}]\n"
    return f"""
[model]
name = "{name}"
[[body]]
id = "tool"
mass = {float(mass)!r}
inertia = 1.0e-3
centre = [0.0, 0.0]
[[support]]
id = "guide"
body = "tool"
fix = ["y", "rz"]
[[spring]]
id = "holder"
a = "tool"
b = "ground"
c1 = {float(stiffness)!r}
d1 = {float(damping)!r}
[[point]]
id = "tip"
body = "tool"
[[coupling]]
id = "cut"
a = "tip"
b = "ground"
model = "regenerative"
width_ref = 0.001
Kf = {float(Kf)!r}
{force_line}[process]
kind = "turning"
rpm = {float(rpm)!r}
"""


def assert_clean_error(code, err, *words):
    """A refused input: status 2 and one line ``chatterlab: error: ...`` on
    standard error (no traceback) holding every one of ``words``."""
    assert code == 2, err
    lines = [ln for ln in err.strip().splitlines() if ln]
    assert len(lines) == 1, err  # one line, no traceback
    assert lines[0].startswith("chatterlab: error:"), err
    assert "Traceback" not in err
    for w in words:
        assert w in lines[0], lines[0]
