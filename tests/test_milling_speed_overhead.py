"""Issue 26, third pass: the per-call overhead taken out of the milling search
(the automatic degree's loop started where it can first pass, the fast path of
an interval end's test, the state matrix's modes computed once per structure)
decides exactly as the plain definitions do."""

from __future__ import annotations

import math

import numpy as np

import chatterlab.lobes._milling_search as search
from chatterlab.frequency._floquet import auto_degree
from chatterlab.frequency._floquet_spectral import P_MIN, SpectralMonodromy, _state_modes
from chatterlab.process import Milling, milling_loop
from chatterlab.structure import Structure


def _auto_degree_plain(omega_L: float, tol: float) -> int:
    """The rule of :func:`auto_degree` as written before: every p from P_MIN - 6 up."""
    wl = max(float(omega_L), 1e-3)
    goal = math.log(1.0 / max(tol, 1e-15))
    p = max(P_MIN - 6, 2)
    while p < 200:
        base = 4.0 * p / (math.e * wl)
        if base > 1.0 and p * math.log(base) >= goal:
            break
        p += 1
    return max(P_MIN, p + 1 + math.ceil(wl / 10.0))


def test_auto_degree_equals_the_plain_rule():
    rng = np.random.default_rng(26)
    # random turns, a fine grid and the points where e omega L / 4 is an integer (the start)
    wls = np.r_[rng.uniform(0.0, 400.0, 3000), np.arange(0.0, 300.0, 0.25), 4.0 * np.arange(100) / math.e]
    for tol in (1e-3, 1e-6 / 30, 1e-10, 1e-15, 1e-20):
        got = [auto_degree(float(w), tol) for w in wls]
        want = [_auto_degree_plain(float(w), tol) for w in wls]
        assert got == want


def _end_safe_plain(mu, dmu, h, skip, miss=0.0):
    """:func:`_end_safe` as written before: every term first, then the decision."""
    with np.errstate(invalid="ignore", over="ignore"):
        move = np.abs(dmu) * abs(h) + miss
        move = np.where(np.isnan(move), np.inf, move)
        reach = np.maximum(np.abs(mu), np.abs(mu + dmu * h)) + miss
    reach = np.where(np.isnan(reach), np.inf, reach)
    ok = reach < 1.0
    if skip is not None:
        ok |= np.abs(mu - skip) <= 1e-6
    if np.all(ok):
        return True
    real = np.nonzero(mu.imag == 0.0)[0]
    for i in np.nonzero(~ok)[0]:
        if mu[i].imag != 0.0 or abs(mu[i]) >= 1.0 or not np.isfinite(move[i]):
            return False
        others = real[real != i]
        if np.any(np.abs(mu[others] - mu[i]) <= move[others] + move[i]):
            return False
    return True


def test_end_safe_decides_as_the_plain_test():
    rng = np.random.default_rng(7)
    seen = set()
    for trial in range(4000):
        k = int(rng.integers(2, 9))
        r = rng.uniform(0.0, 1.05, k)
        ang = np.where(rng.random(k) < 0.4, rng.choice([0.0, np.pi], k), rng.uniform(-np.pi, np.pi, k))
        mu = r * np.exp(1j * ang)
        mu[ang == 0.0] = r[ang == 0.0]
        mu[ang == np.pi] = -r[ang == np.pi]
        dmu = (rng.standard_normal(k) + 1j * rng.standard_normal(k)) * 10.0 ** rng.uniform(-2, 2, k)
        if trial % 7 == 0:
            dmu[int(rng.integers(k))] = np.inf  # a defective multiplier's rate
        if trial % 11 == 0:
            dmu[int(rng.integers(k))] = complex(np.nan, 0.0)
        h = float(rng.choice([-1.0, 1.0]) * 10.0 ** rng.uniform(-4, -1))
        miss = rng.uniform(0.0, 0.05, k) if trial % 3 else 0.0
        skip = float(rng.choice([-1.0, 1.0])) if trial % 5 == 0 else None
        if skip is not None:
            mu[0] = skip
        want = _end_safe_plain(mu, dmu, h, skip, miss)
        assert search._end_safe(mu, dmu, h, skip, miss) == want
        seen.add(want)
    assert seen == {True, False}


def test_state_modes_once_per_structure():
    st = Structure.single_dof(0.03993, 2 * np.pi * 922.0, 0.011)
    loop = milling_loop(st, Milling.from_immersion(2, 0.02, 6e8, 2e8, 1.0, "down"))
    a = SpectralMonodromy(loop, 9000.0, None)
    b = SpectralMonodromy(loop, 17000.0, None)
    assert a._modes_A() is b._modes_A() is _state_modes(loop)
    lam, V, well = a._modes_A()
    assert well and np.allclose(loop.state_matrix @ V, V * lam[None, :], atol=1e-9 * np.abs(lam).max())
