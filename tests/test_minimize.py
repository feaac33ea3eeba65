"""chatterlab._minimize.bounded_minimum (Brent 1973, ch. 5): the one bounded
minimisation of the README main job (the absolute minimum of a lobe diagram).

Oracles: minima in closed form; Brent's stopping rule (the minimiser is known
to ``xatol + 3 sqrt(eps) |x|``); his bound on the work (never much more than
golden-section search, whose bracket shrinks by 0.618 per evaluation); the
interval's ends are never evaluated; and the same points as the reference
implementation of the same algorithm (scipy's ``minimize_scalar(method=
"bounded")``), which the absolute minimum used before."""

from __future__ import annotations

import math

import numpy as np
import pytest

from chatterlab._minimize import bounded_minimum

EPS = np.finfo(float).eps

CASES = [
    # f, a, b, the minimiser in closed form
    (lambda x: (x - 0.3) ** 2, 0.0, 1.0, 0.3),
    (math.cos, 2.0, 4.0, math.pi),
    (lambda x: abs(x - 1.234567) ** 1.5, 0.0, 3.0, 1.234567),  # not smooth at the minimum
    (lambda x: x**4 - x, 0.0, 2.0, 4.0 ** (-1.0 / 3.0)),  # f' = 4x^3 - 1
    (lambda x: math.exp(x) - 2.0 * x, 0.0, 5.0, math.log(2.0)),
    (lambda x: -x, 0.0, 1.0, 1.0),  # the minimum at an end: approached, never evaluated
]


@pytest.mark.parametrize("case", range(len(CASES)))
def test_closed_form_minimiser_to_the_stated_tolerance(case: int) -> None:
    f, a, b, x_star = CASES[case]
    xatol = 1e-10 * b
    seen: list[float] = []

    def g(x: float) -> float:
        seen.append(x)
        return f(x)

    x, fx, count = bounded_minimum(g, a, b, xatol)
    assert count == len(seen) and fx == g(x)
    # Brent's stopping rule: x within 2 tol of the bracket's ends around it, tol = sqrt(eps)|x| + xatol/3,
    # so |x - x*| <= 2 tol; the parabola's last step adds at most tol: 3 tol in all (a bound, not a fit)
    tol = math.sqrt(EPS) * abs(x) + xatol / 3.0
    # a minimum where f is flat to order p is only located to the precision f's round-off allows:
    # |x - x*| ~ (eps |f| / |f^(p)|)^(1/p); for the quadratic cases that is sqrt(eps) |x|, inside tol
    assert abs(x - x_star) <= 3.0 * tol + 4.0 * math.sqrt(EPS) * max(1.0, abs(x_star))
    assert all(a < s < b for s in seen)  # never at the ends
    golden = math.ceil(math.log(xatol / (b - a)) / math.log(0.5 * (math.sqrt(5.0) - 1.0)))
    assert count <= 2 * golden + 3  # Brent: a golden step at least every other step


def test_same_points_as_the_reference_implementation() -> None:
    """The same algorithm as scipy's bounded Brent: the same minimiser and
    value, to round-off, on every interior minimum (what the lobe diagram's
    absolute minimum returned before it stopped importing scipy.optimize).
    At a minimum on an end the two place their last steps differently within
    the tolerance: that case is checked against the closed form above."""
    from scipy.optimize import minimize_scalar

    for f, a, b, x_star in CASES:
        if not a < x_star < b:
            continue
        x, fx, _ = bounded_minimum(f, a, b, 1e-10 * b)
        ref = minimize_scalar(f, bounds=(a, b), method="bounded", options={"xatol": 1e-10 * b})
        assert abs(x - ref.x) <= 4 * math.sqrt(EPS) * max(1.0, abs(x))
        assert abs(fx - ref.fun) <= 64 * EPS * max(1.0, abs(fx))


def test_infinite_values_are_never_the_minimum() -> None:
    """Where f has no value (inf, e.g. no lobe width in the search window),
    the search moves away from it and returns a finite minimum."""
    f = lambda x: math.inf if x < 0.5 else (x - 0.7) ** 2  # noqa: E731
    x, fx, _ = bounded_minimum(f, 0.0, 1.0, 1e-10)
    assert math.isfinite(fx) and abs(x - 0.7) <= 1e-7


@pytest.mark.parametrize("a, b", [(1.0, 1.0), (2.0, 1.0), (0.0, math.inf), (math.nan, 1.0)])
def test_an_empty_or_infinite_interval_is_refused(a: float, b: float) -> None:
    with pytest.raises(ValueError, match="finite interval"):
        bounded_minimum(lambda x: x, a, b, 1e-9)
