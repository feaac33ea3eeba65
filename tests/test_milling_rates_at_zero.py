"""The multipliers' rates d mu / d a_p at a_p = 0, where they repeat.

The free map X0 = [[C_d, 0], [C_r, 0]] has the multiplier 0 k - d times
(semisimple) and a symmetric tool every free multiplier twice; the rates of
the multipliers leaving a repeated one are the eigenvalues of the projected
derivative (SpectralMonodromy._tangent_free), not the diagonal of W^-1 X' W
from one eigendecomposition, which depends on the basis LAPACK returns (it
was ~1/2 of the true rates of the zeros on the 1-DOF benchmark at full
immersion, ~1/3 of the symmetric 2-DOF tool's free multiplier's).  The
complete search sizes its first step from 0 on these rates.

Checked against Richardson-extrapolated finite differences: for each group
of multipliers equal to mu0 at 0, r(a) = max |mu(a) - mu0| / a over the
group's multipliers at a (the ones nearest mu0) is |nu|_max + c a + ...; the
extrapolation R = 2 r(a) - r(2a) removes the O(a) term, and |r(a) - r(2a)|
(= |c| a + ...: the one-sided difference's own error, larger than R's while
the expansion converges) is the tolerance.  The depths are chosen where that
holds and rounding does not dominate."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import chatterlab as cl
from chatterlab.frequency import SpectralMonodromy
from chatterlab.frequency._floquet import spectral_mesh
from chatterlab.lobes import milling_loop_of
from chatterlab.lobes._milling_search import SAFE, _step, certified_crossing

STUDIES = Path(__file__).resolve().parents[1] / "studies" / "milling"


def _loop(name: str, immersion: float):
    text = (STUDIES / f"{name}.toml").read_text()
    text, n = re.subn(
        r"^radial_immersion = [0-9.e+-]+", f"radial_immersion = {immersion!r}", text, flags=re.M
    )
    assert n == 1
    return milling_loop_of(cl.assemble(cl.loads_model(text)).at())


def _search_mesh(loop, rpm: float) -> SpectralMonodromy:
    """The discretisation the search starts from at 0 (the benchmark's settings:
    depths to 10 mm, target 1e-6: the first stage's mesh)."""
    return SpectralMonodromy(
        loop, rpm, mesh=spectral_mesh(loop, rpm, None, depth_hint=0.01 / 16, tol=1e-6 / 30)
    )


def _group_rate(sm: SpectralMonodromy, mu0: complex, n: int, a: float) -> float:
    """max |mu(a) - mu0| / a over the n multipliers at depth a nearest mu0."""
    d = np.sort(np.abs(sm.at(a) - mu0))[:n]
    return float(d.max() / a)


def _richardson(sm: SpectralMonodromy, mu0: complex, n: int, a: float) -> tuple[float, float]:
    """R = 2 r(a) - r(2a) and its tolerance |r(a) - r(2a)|."""
    r1, r2 = _group_rate(sm, mu0, n, a), _group_rate(sm, mu0, n, 2 * a)
    return 2 * r1 - r2, abs(r1 - r2)


@pytest.mark.parametrize(
    "name, immersion, rpm, a, group",
    [
        ("benchmark_1dof", 0.05, 10000.0, 1e-9, "zero"),
        ("benchmark_1dof", 0.05, 5000.0, 1e-9, "zero"),
        ("benchmark_1dof", 1.0, 20000.0, 1e-9, "zero"),
        ("benchmark_1dof", 1.0, 10000.0, 1e-11, "zero"),
        ("benchmark_2dof", 0.05, 10000.0, 1e-8, "free"),
        ("benchmark_2dof", 1.0, 10000.0, 1e-8, "free"),
    ],
)
def test_rates_at_zero_agree_with_richardson_differences(name, immersion, rpm, a, group):
    """The zeros' projected derivative is nearly defective (eigenvector condition
    1e8-1e13), so their expansion settles late at full immersion (1-DOF, 10000 rpm:
    |mu|/a = 52.5 at 1e-9, 44.08 at 1e-11, the rate 44.03), and on the 2-DOF tool it
    does not settle above the rounding: the cases here are ones where it has.  That
    rounding does not dominate is checked too: the extrapolations at a and a/10
    agree within the larger tolerance (rounding, ~eps/a relative or more for
    ill-conditioned multipliers, would grow tenfold)."""
    sm = _search_mesh(_loop(name, immersion), rpm)
    mu, dmu = sm.tangent(0.0)
    top = float(np.abs(mu).max())
    mu0 = 0.0 if group == "zero" else complex(mu[0])
    members = np.abs(mu - mu0) <= 1e-10 * top
    n = int(members.sum())
    assert n >= 2
    richardson, tol = _richardson(sm, mu0, n, a)
    finer, tol_finer = _richardson(sm, mu0, n, a / 10)
    assert tol < 0.05 * richardson  # the difference is in its asymptotic range
    assert abs(finer - richardson) <= tol
    claimed = float(np.abs(dmu[members]).max())
    assert abs(claimed - richardson) <= tol, (mu0, n, claimed, richardson, tol)


def test_symmetric_tools_free_multiplier_rate_at_full_immersion():
    """The case where the basis mattered most: the double free multiplier of the
    symmetric 2-DOF benchmark at full immersion moves at ~2527 /m, the
    diagonal said ~824 (its first step from 0 three times too long)."""
    sm = _search_mesh(_loop("benchmark_2dof", 1.0), 10000.0)
    mu, dmu = sm.tangent(0.0)
    i = np.abs(mu) > 0.0
    assert np.abs(dmu[i]).max() == pytest.approx(2527.0, rel=1e-3)


def _constructed(w: float, c: float = 0.5) -> SpectralMonodromy:
    """X(a) = X0 + a P (I + a K)^-1 Q with X0 = diag(c, 0, 0) (the free form, d = 1),
    P = I, K = 0 and Q = [[0, 0, 0], [0, 0, -w], [0, w, 0]]: the multipliers are c
    and +-i w a exactly.  LAPACK's eigenvectors of X0 are the unit vectors, in which
    Q's diagonal (the old rates) is 0: no rate, so the step from 0 was the whole room."""
    sm = SpectralMonodromy.__new__(SpectralMonodromy)
    sm.X0 = np.diag([c, 0.0, 0.0])
    sm.P = np.eye(3)
    sm.K = np.zeros((3, 3))
    sm.Q = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, -w], [0.0, w, 0.0]])
    sm.k, sm.m_f, sm.d = 3, 3, 1
    sm._I = np.eye(3)
    sm._eigs = {}
    sm.helix_depth = None
    return sm


def test_constructed_rates_are_the_projected_eigenvalues():
    w = 1000.0
    sm = _constructed(w)
    mu, dmu = sm.tangent(0.0)
    zero = mu == 0.0
    assert np.sort(dmu[zero].imag) == pytest.approx([-w, w], rel=1e-14)
    assert dmu[zero].real == pytest.approx([0.0, 0.0], abs=1e-12 * w)
    # the batch gives the same numbers
    (mu_b, dmu_b), _ = sm.tangents(np.array([0.0, 1e-4]))
    assert np.array_equal(mu_b, mu) and np.array_equal(dmu_b, dmu)


def test_constructed_step_from_zero_does_not_overshoot():
    """The step from 0 keeps every multiplier within SAFE of its way to the unit
    circle (exactly, the paths being straight): with the old rates (0) the step
    was the whole room, 1 m, and the pair reached |mu| = w = 1000."""
    w = 1000.0
    sm = _constructed(w)
    mu0, dmu0 = sm.tangent(0.0)
    h = _step(mu0, dmu0, 1.0)
    allowed = np.abs(mu0) + SAFE * (1.0 - np.abs(mu0))
    mu_h = np.linalg.eigvals(sm.monodromy(h))
    born = np.abs(mu_h - 0.5) > 1e-9  # the pair leaving 0 (0.5 stays)
    assert born.sum() == 2
    assert np.abs(mu_h[born]).max() <= SAFE * (1 + 1e-12), (h, mu_h)
    assert allowed.min() == SAFE


def test_constructed_search_finds_the_crossing():
    """The pair +-i w a crosses the unit circle at a = 1/w (a Hopf crossing; no
    multiplier ever at +-1)."""
    w = 1000.0
    sm = _constructed(w)
    c = certified_crossing(sm, 0.01, 40, 1e-9)
    assert c.status == "crossing" and c.kind == "hopf"
    assert c.depth == pytest.approx(1.0 / w, rel=1e-8)
