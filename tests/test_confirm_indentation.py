"""``lobes.confirm`` (``chatterlab lobes --confirm N``) on a model with the
indentation model of process damping: its runs integrate the flank's
nonlinear force at the step the wear land needs (8 samples across it, as
``simulate``'s own rule), where they stopped with "the wear land must hold
several steps" before.  Oracle: the lobes are the linearised loop's
(C_pd = K_sp w^2 / 4, an independent route: the D-subdivision); from the
small disturbance of the confirmation the flank acts at small amplitude, so
the run below the limit decays and the run above it grows, as the diagram
says (tests/test_indentation_simulate.py shows the small-amplitude rate is
the linear root's to the linearisation's small parameters)."""

from __future__ import annotations

import numpy as np
from test_indentation_simulate import RPM, indentation_file

import chatterlab as cl
from chatterlab.lobes import confirm, lobes
from chatterlab.time._simulate import LAND_STEPS


def test_confirmation_with_the_indentation_model_steps_across_the_wear_land(tmp_path):
    w, D = 1e-4, 5e-4  # wear land 0.1 mm, workpiece 0.5 mm: V = 0.52 m/s at 20000 rpm
    system = cl.assemble(cl.load_model(indentation_file(tmp_path, D, w)))
    d = lobes(system.at(None), np.array([0.98, 1.0, 1.02]) * RPM, width_max=0.05, verify=0)
    conf = confirm(system, d, count=1, periods=20, min_duration=0.05)
    assert len(conf.rows) == 2
    for r in conf.rows:
        V = np.pi * D * r["speed"] / 60.0  # the cutting speed of the row's spindle speed (rpm)
        assert r["step"] <= w / (LAND_STEPS * V) * (1 + 1e-12), r
    assert conf.agrees, conf.table()
