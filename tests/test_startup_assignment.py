"""The exact assignment that links boundary widths between neighbouring
frequencies (``lobes._boundary.assignment``), which replaced scipy's
``linear_sum_assignment`` on the lobes path (its import was 0.16 s of the
README main job, issue 26).

Oracle: enumerating every injective map of the smaller side into the larger
one is the definition of the minimum-cost assignment; for the sizes the lobe
engine meets (a few widths per frequency) it is cheap and exact.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from chatterlab.lobes._boundary import assignment, link

EPS = np.finfo(float).eps


def _brute(cost: np.ndarray) -> tuple[float, float, tuple[np.ndarray, np.ndarray]]:
    """(least total cost, second least, its rows and columns) over every
    injective map of the smaller side into the larger."""
    n, m = cost.shape
    flip = n > m
    c = cost.T if flip else cost
    n, m = c.shape
    totals = []
    for cols in itertools.permutations(range(m), n):
        totals.append((float(sum(c[i, j] for i, j in enumerate(cols))), cols))
    totals.sort(key=lambda t: t[0])
    best, cols = totals[0]
    second = totals[1][0] if len(totals) > 1 else np.inf
    rows, cc = np.arange(n), np.array(cols, dtype=int)
    if flip:
        rows, cc = cc, rows
        order = np.argsort(rows)
        rows, cc = rows[order], cc[order]
    return best, second, (rows, cc)


def _cases() -> list[np.ndarray]:
    rng = np.random.default_rng(20261202)
    out = []
    for n in range(1, 6):
        for m in range(1, 7):
            for scale in (1e-3, 1.0, 40.0):
                out.append(rng.random((n, m)) * scale)
    # the costs link() builds: |log a - log b| of positive widths, counts differing by 1 or 2
    for n, m in ((2, 1), (1, 2), (3, 5), (5, 3), (4, 6), (6, 4)):
        a = np.sort(rng.uniform(1e-5, 1e-3, n))
        b = np.sort(rng.uniform(1e-5, 1e-3, m))
        out.append(np.abs(np.log(a)[:, None] - np.log(b)[None, :]))
    return out


@pytest.mark.parametrize("cost", _cases(), ids=lambda c: f"{c.shape[0]}x{c.shape[1]}")
def test_assignment_is_the_minimum_over_every_permutation(cost):
    best, second, (rows, cols) = _brute(cost)
    r, c = assignment(cost)
    k = min(cost.shape)
    assert r.shape == c.shape == (k,)
    assert np.array_equal(r, np.sort(r)), "rows in increasing order"
    assert len(set(r.tolist())) == len(set(c.tolist())) == k, "a matching: no row or column twice"
    # the sum of k costs in another order: k rounding errors of the largest term
    tol = 2 * k * EPS * float(np.abs(cost).max())
    assert abs(float(cost[r, c].sum()) - best) <= tol
    if second - best > 2 * tol:  # a unique minimum (random costs: almost surely): the same pairs
        assert np.array_equal(r, rows) and np.array_equal(c, cols)


def test_assignment_ties_still_give_a_minimum():
    # every assignment of a constant matrix costs the same: any matching is a minimum
    c = np.ones((3, 4))
    r, cc = assignment(c)
    assert np.array_equal(r, [0, 1, 2]) and len(set(cc.tolist())) == 3


def test_assignment_refuses_what_is_not_a_matrix():
    with pytest.raises(ValueError, match="2-D"):
        assignment(np.ones(3))


def test_link_follows_the_nearest_width_across_a_count_change():
    # widths at three frequencies: two branches, a third width appears between them at the
    # second frequency; in |log| distance the old widths continue their own branch
    xs = [np.array([1e-4, 1e-3]), np.array([1.01e-4, 3e-4, 0.99e-3]), np.array([1.02e-4, 0.98e-3])]
    chains = link(xs)
    as_sets = sorted(sorted(ch) for ch in chains)
    assert [(0, 0), (1, 0), (2, 0)] in as_sets
    assert [(0, 1), (1, 2), (2, 1)] in as_sets
