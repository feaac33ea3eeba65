"""The Python API takes the same things the same way (found by a review of
the API as a researcher scripts it): a result's ``to_json(path)`` writes the
file, a point may be one name where a list is taken, outputs and inputs go
by name, and a wrong kind of argument is an InputError naming it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import chatterlab as cl
from chatterlab.errors import InputError

SHAPER = Path(__file__).resolve().parents[1] / "studies" / "traverse_shaper" / "model.toml"


@pytest.fixture(scope="module")
def frozen():
    return cl.assemble(cl.load_model(SHAPER)).at(0.85)


def test_to_json_writes_the_file_it_returns(frozen, tmp_path):
    md = cl.modes(frozen, count=2)
    text = md.to_json(tmp_path / "m.json")
    assert (tmp_path / "m.json").read_text() == text and json.loads(text)["kind"] == "modes"
    assert md.to_json() == text  # no path: returned only
    with pytest.raises(TypeError, match="indent by keyword"):
        md.to_json(2)  # the old positional indent would have been taken for a path
    omega = 2 * np.pi * np.linspace(70.0, 90.0, 50)
    F = cl.frf(frozen, omega, inputs="rfe5.x", outputs="rfe5.x")
    assert F.to_json(tmp_path / "f.json") == (tmp_path / "f.json").read_text()


def test_frf_peaks_by_name_and_feedback_of_the_wrong_kind(frozen):
    omega = 2 * np.pi * np.linspace(60.0, 100.0, 400)
    F = cl.frf(frozen, omega, inputs=["rfe5.x", "rfe5.y"], outputs=["rfe5.x", "rfe5.y"])
    assert F.peaks(output="rfe5.y", input="rfe5.y") == F.peaks(output=1, input=1)
    with pytest.raises(InputError, match="output 'rfe5.z' is not one of"):
        F.peaks(output="rfe5.z")
    # a wrong type is a one-line InputError that says what to pass, never an AttributeError
    with pytest.raises(InputError, match="FrozenSystem .*ClosedLoop"):
        cl.frf("pdo", omega, inputs="rfe5.x", outputs="rfe5.x")
    with pytest.raises(InputError, match=r"assembled System: give system.at\(position\)"):
        cl.frf(frozen.system, omega, inputs="rfe5.x", outputs="rfe5.x")


def test_simulate_takes_one_output_name(frozen):
    system = cl.assemble(cl.load_model(SHAPER))
    sim = cl.simulate(system, width=2e-4, speed=0.5, position=0.85, duration=0.05, outputs="rfe5.x")
    assert [n for n in sim.histories() if n.startswith("rfe5")] == ["rfe5.x"]
