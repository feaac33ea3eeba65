"""The estimators of chatterlab.uncertainty against mathematics (issue 24, "Oracles").

* 1-DOF turning, stiffness k lognormal and damping ratio zeta normal: the
  unconditional minimum b_min = 2 k zeta (1 + zeta) / K_f is a known
  function of the inputs, so E[b_min] is exact (moments of the inputs) and
  P(b_min < b0) a one-dimensional quadrature (b_min grows with k: given
  zeta, b_min < b0 is k < k*(zeta)).  Over many seeds the randomised QMC and
  the Monte Carlo intervals must contain the truth in the nominal fraction
  of runs, within its binomial error.
* On the same smooth quantity the QMC error falls faster than the Monte
  Carlo error: the rates fitted on a log-log scale.
* Sobol' indices against the closed forms of an additive and a product
  model, with a named group of fields and a correlated group as factors.
* The input space: each marginal's mean and standard deviation, a
  truncation's bounds and a covariance group's covariance, from the samples.

All on closed forms, vectorised: no lobe diagram (tests/test_uncertainty_lobes.py has them).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, stats

from chatterlab.errors import InputError
from chatterlab.uncertainty import InputSpace, propagate

KF = 2.0e9  # N/m^2
K0, CV_K = 1.0e7, 0.1  # modal stiffness: lognormal, mean 1e7 N/m, cv 10 %
Z0, SD_Z = 0.03, 0.003  # damping ratio: normal, truncated at 0 (10 sd away)
B0 = 2.8e-4  # m: the width whose probability of chatter is estimated

SPACE = InputSpace.from_dict(
    {
        "k": {"distribution": "lognormal", "cv": CV_K},
        "zeta": {"distribution": "normal", "std": SD_Z, "lower": 0.0},
    },
    nominal={"k": K0, "zeta": Z0},
)


def b_min(x: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    k, z = x["k"], x["zeta"]
    b = 2.0 * k * z * (1.0 + z) / KF
    return {"b": b, "chatter": (b < B0).astype(float)}


def _lognormal_k() -> stats.rv_continuous:
    s2 = math.log1p(CV_K**2)
    return stats.lognorm(math.sqrt(s2), scale=K0 * math.exp(-0.5 * s2))


def exact_mean() -> float:
    # independent inputs: E[2 k z (1 + z) / Kf] = 2 E[k] (E z + E z^2) / Kf; the truncation at
    # zeta = 0 (10 sd) moves E z by phi(10) sd ~ 1e-23: below round-off
    return 2.0 * K0 * (Z0 + Z0**2 + SD_Z**2) / KF


def exact_probability() -> float:
    """P(b_min < B0) = int F_k(k*(z)) f_z(z) dz, k*(z) = B0 Kf / (2 z (1 + z))."""
    fk = _lognormal_k()
    fz = stats.truncnorm(-Z0 / SD_Z, np.inf, loc=Z0, scale=SD_Z)
    # over zeta = Z0 +- 10 sd: the density outside is below 1e-22
    val, err = integrate.quad(
        lambda z: fk.cdf(B0 * KF / (2 * z * (1 + z))) * fz.pdf(z), Z0 - 10 * SD_Z, Z0 + 10 * SD_Z,
        epsabs=1e-12, points=[Z0 - 3 * SD_Z, Z0, Z0 + 3 * SD_Z], limit=200,
    )  # fmt: skip
    assert err < 1e-6  # negligible: 1e-4 of the sampling error of the runs below (512 samples: ~0.015)
    return float(val)


def test_truth_by_two_routes():
    """The oracle itself: the quadrature and the closed-form mean against a
    direct Monte Carlo of 1e6 draws (within 5 sd of that Monte Carlo)."""
    rng = np.random.default_rng(12345)
    n = 1_000_000
    k = _lognormal_k().rvs(n, random_state=rng)
    z = stats.truncnorm(-Z0 / SD_Z, np.inf, loc=Z0, scale=SD_Z).rvs(n, random_state=rng)
    b = b_min({"k": k, "zeta": z})
    p = exact_probability()
    assert 0.05 < p < 0.5  # a probability worth estimating
    assert abs(b["chatter"].mean() - p) < 5 * math.sqrt(p * (1 - p) / n)
    assert abs(b["b"].mean() - exact_mean()) < 5 * b["b"].std() / math.sqrt(n)


@pytest.mark.parametrize("method", ["qmc", "mc"])
def test_intervals_cover_the_truth_at_their_stated_confidence(method):
    """Over 400 seeds (8 replicates x 64 points each), the 95 % intervals of
    P(b_min < b0) and of E[b_min] contain the exact values in 95 % of the
    runs, within 3 binomial standard deviations of the fraction (0.033)."""
    seeds, level = 400, 0.95
    p_true, m_true = exact_probability(), exact_mean()
    hit_p = hit_m = 0
    for seed in range(seeds):
        run = propagate(b_min, SPACE, samples=512, replicates=8, seed=seed, method=method, level=level)
        ep, em = run.mean("chatter"), run.mean("b")
        hit_p += bool(ep.low <= p_true <= ep.high)
        hit_m += bool(em.low <= m_true <= em.high)
    tol = 3 * math.sqrt(level * (1 - level) / seeds)
    for hits in (hit_p, hit_m):
        assert abs(hits / seeds - level) <= tol, (method, hit_p / seeds, hit_m / seeds)


UNIFORM = InputSpace.from_dict(
    {"k": {"distribution": "uniform", "low": 0.8e7, "high": 1.2e7},
     "zeta": {"distribution": "uniform", "low": 0.024, "high": 0.036}}
)  # fmt: skip
#: E[b_min] with uniform inputs: 2 E[k] (E z + E z^2) / Kf, E z^2 = 0.03^2 + 0.012^2 / 12
UNIFORM_MEAN = 2.0 * 1e7 * (0.03 + 0.03**2 + 0.012**2 / 12) / KF


def _slope(
    space: InputSpace, exact: float, method: str, ns: np.ndarray, reps: int = 32
) -> tuple[float, float]:
    """The fitted log-log slope of the RMSE of the n-point estimate of
    E[b_min] (from ``reps`` independent randomisations) against n, and the
    RMSE at the largest n."""
    err = []
    for n in ns:
        run = propagate(b_min, space, samples=int(n) * reps, replicates=reps, seed=7, method=method)
        assert run.n == n
        err.append(math.sqrt(np.mean((run.outputs["b"].mean(axis=1) - exact) ** 2)))
    return float(np.polyfit(np.log(ns), np.log(err), 1)[0]), err[-1]


def test_qmc_error_falls_faster_than_monte_carlo():
    """RMSE against n = 16 .. 2048 on a log-log scale, 32 randomisations per n.

    The slope's standard error: an RMSE from 32 replicates has a relative sd
    of 1/sqrt(2 * 32), so the fitted slope's is that over the root sum of
    squares of ln n about its mean (0.028).

    * Monte Carlo: slope -1/2, within 3 standard errors.
    * b_min with uniform inputs (smooth on the unit cube): scrambled Sobol'
      RMSE ~ n^-3/2 (ln n)^(1/2) in two dimensions (Owen 1997), whose local
      slope is -3/2 + 1/(2 ln n), at most -3/2 + 0.18 here; so the slope
      must be below that plus 3 standard errors.
    * b_min with the lognormal stiffness and the normal damping ratio (the
      inverse distribution functions are unbounded at the cube's faces: not
      of bounded variation, no n^-3/2): still faster than Monte Carlo --
      the two slopes apart by more than 3 standard errors of their
      difference -- and 10 times more accurate at n = 2048.
    """
    ns = 2 ** np.arange(4, 12)
    x = np.log(ns)
    se = (1 / math.sqrt(2 * 32)) / math.sqrt(np.sum((x - x.mean()) ** 2))
    mc, mc_err = _slope(SPACE, exact_mean(), "mc", ns)
    assert abs(mc + 0.5) < 3 * se, mc
    smooth, _ = _slope(UNIFORM, UNIFORM_MEAN, "qmc", ns)
    assert smooth < -1.5 + 1 / (2 * math.log(ns[0])) + 3 * se, smooth
    qmc, qmc_err = _slope(SPACE, exact_mean(), "qmc", ns)
    assert qmc < mc - 3 * math.sqrt(2) * se, (qmc, mc)
    assert qmc_err < 0.1 * mc_err, (qmc_err, mc_err)


def test_sobol_indices_of_a_product_model():
    """Y = X1 X2, X1, X2 ~ U(0, 1): V = 1/9 - 1/16 = 7/144, V1 = V2 = Var(X/2)
    = 1/48, so S1 = S2 = 3/7 and ST1 = ST2 = 4/7 (the interaction 1/7 in
    both totals).  Each estimate within 4 of its standard errors of the
    closed form, and the errors small enough to tell 3/7 from 4/7."""
    sp = InputSpace.from_dict(
        {"x1": {"distribution": "uniform", "low": 0.0, "high": 1.0},
         "x2": {"distribution": "uniform", "low": 0.0, "high": 1.0}}
    )  # fmt: skip
    run = propagate(lambda x: {"y": x["x1"] * x["x2"]}, sp, samples=8 * 1024, sensitivity=True)
    s1, st = run.sobol("y")
    for est, exact in ((s1, 3 / 7), (st, 4 / 7)):
        assert np.all(np.abs(est.value - exact) < 4 * est.se), (est.value, est.se)
        assert np.all(est.half_width < (4 / 7 - 3 / 7) / 4)


def test_sobol_indices_of_an_additive_model_with_groups():
    """Y = a X1 + b X2 + c X3 with independent normals: S_i = ST_i = a_i^2
    s_i^2 / sum; a named factor {X2, X3} has S = ST = the sum of its own.
    Then X2, X3 correlated (rho): the group is one factor with S = ST =
    Var(b X2 + c X3) / Var(Y), Var(b X2 + c X3) = b^2 s2^2 + c^2 s3^2 + 2 b c
    rho s2 s3 -- the correlation enters through the copula."""
    a, s = np.array([1.0, 2.0, -1.5]), np.array([0.5, 0.3, 0.4])
    spec = {f"x{i}": {"distribution": "normal", "mean": 1.0, "std": float(s[i])} for i in range(3)}

    def f(x):
        return {"y": sum(a[i] * x[f"x{i}"] for i in range(3))}

    v = (a * s) ** 2
    run = propagate(f, InputSpace.from_dict(spec), samples=8 * 512, sensitivity=True)
    s1, st = run.sobol("y")
    for est in (s1, st):
        assert np.all(np.abs(est.value - v / v.sum()) < 4 * est.se + 1e-12), (est.value, v / v.sum())
    run = propagate(f, InputSpace.from_dict(spec), samples=8 * 512, sensitivity=True,
                    factors={"pair": ["x1", "x2"]})  # fmt: skip
    s1, st = run.sobol("y")
    exact = np.array([v[1] + v[2], v[0]]) / v.sum()  # the named factor first, then x0
    for est in (s1, st):
        assert np.all(np.abs(est.value - exact) < 4 * est.se + 1e-12), (est.value, exact)
    rho = 0.6
    corr = {**spec, "group": [{"parameters": ["x1", "x2"], "correlation": [[1.0, rho], [rho, 1.0]]}]}
    run = propagate(f, InputSpace.from_dict(corr), samples=8 * 512, sensitivity=True)
    s1, st = run.sobol("y")
    vg = v[1] + v[2] + 2 * a[1] * a[2] * rho * s[1] * s[2]
    exact = np.array([v[0], vg]) / (v[0] + vg)  # x0 (ungrouped) first, then the group
    for est in (s1, st):
        assert np.all(np.abs(est.value - exact) < 4 * est.se + 1e-12), (est.value, exact)


def test_a_factor_may_not_split_a_correlated_group():
    corr = {
        "x": {"distribution": "normal", "mean": 0.0, "std": 1.0},
        "y": {"distribution": "normal", "mean": 0.0, "std": 1.0},
        "group": [{"parameters": ["x", "y"], "correlation": [[1.0, 0.5], [0.5, 1.0]]}],
    }
    with pytest.raises(InputError, match="part of a correlated group"):
        InputSpace.from_dict(corr).sensitivity_factors({"only x": ["x"]})
    with pytest.raises(InputError, match="names no uncertain field"):
        InputSpace.from_dict(corr).sensitivity_factors({"z": ["z*"]})


def test_the_marginals_and_a_covariance_group_from_their_samples():
    """Sample moments of 2^14 scrambled Sobol' points against each
    distribution's own (within 5 standard errors of a Monte Carlo of that
    size: QMC is more accurate, so the bound is safe), the truncation's
    bounds held exactly, and a covariance group's sample covariance."""
    C = np.array([[4.0, 1.2], [1.2, 1.0]])
    sp = InputSpace.from_dict(
        {
            "ln": {"distribution": "lognormal", "mean": 2.0, "std": 0.5},
            "tn": {"distribution": "normal", "mean": 0.0, "std": 1.0, "lower": -0.5, "upper": 2.0},
            "un": {"distribution": "uniform", "low": 3.0, "high": 5.0},
            "group": [{"parameters": ["a", "b"], "covariance": C.tolist(), "mean": [1.0, -1.0]}],
        }
    )
    run = propagate(lambda x: {k: v for k, v in x.items()}, sp, samples=8 * 2048)
    n = run.samples

    def check(name, mean, sd):
        y = run.outputs[name].ravel()
        assert abs(y.mean() - mean) < 5 * sd / math.sqrt(n), name
        assert abs(y.std() / sd - 1) < 5 / math.sqrt(2 * n), name  # sd of a sample sd: sd / sqrt(2 n)

    check("ln", 2.0, 0.5)
    tn = stats.truncnorm(-0.5, 2.0)
    check("tn", tn.mean(), tn.std())
    y = run.outputs["tn"]
    assert y.min() >= -0.5 and y.max() <= 2.0
    check("un", 4.0, 2 / math.sqrt(12))
    ab = np.stack([run.outputs["a"].ravel(), run.outputs["b"].ravel()])
    assert np.allclose(ab.mean(axis=1), [1.0, -1.0], atol=5 * 2 / math.sqrt(n))
    # the sample covariance: each entry's sd is about sqrt((C_ii C_jj + C_ij^2) / n)
    sd = np.sqrt((np.outer(np.diag(C), np.diag(C)) + C**2) / n)
    assert np.all(np.abs(np.cov(ab) - C) < 5 * sd)


def test_zero_width_gives_the_nominal_values_exactly():
    sp = InputSpace.from_dict(
        {"k": {"distribution": "lognormal", "cv": 0.0}, "z": {"distribution": "normal", "std": 0.0},
         "u": {"distribution": "uniform", "half_width": 0.0}},
        nominal={"k": 1.2345678901234e7, "z": 0.0311, "u": 7.77},
    )  # fmt: skip
    assert sp.zero_width
    x = sp.transform(np.random.default_rng(0).random((50, 3)))
    assert np.all(x == np.array([1.2345678901234e7, 0.0311, 7.77]))
