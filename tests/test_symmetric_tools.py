"""Symmetric tools (issue 18, part 3): identical modes in x and y cut by an
isotropic process, D_O = -K_f I, and a 0.1 % asymmetric variant.

With two uncoupled modes and D_O = -K_f I on both, the characteristic matrix
is diag(d_x(s), d_y(s)) with the 1-DOF function

    d(s) = m s^2 + c s + k + K_f b (1 - e^{-sT}),

so every root of the symmetric tool is a double root, and its lobes are the
1-DOF lobes: Tlusty's b_lim = -1/(2 K_f Re G(w_c)) on the phase condition,
exactly (computed here by brentq, to 1e-15).  The nearly symmetric tool
(k_y = 1.001 k_x at the same mass) has the lower of two such envelopes.

The independent count: the roots of d(s) right of the axis, from a Chebyshev
collocation of the 1-DOF delay equation written here (Breda, Maset &
Vermiglio 2005), each refined by Newton on d itself.  Right of the axis
|e^{-sT}| < 1, so |m s^2 + c s + k + K_f b| <= K_f b there, which bounds every
such root by R (below); the collocation resolves |s| up to ~N/(2T) >> R.

Tolerances.  b_lim: the engine's widths are polynomial roots polished to
~1e-15 and its envelope is refined to 1e-14 in frequency, brentq here to
1e-15: 1e-9 relative is a margin of ~1e5 over both.  The critical double pair
at 0.999 b_lim has Re ~ -1e-2 1/s (dsigma/db ~ 11 1/s per relative width,
measured), 1e10 times the Newton accuracy of the root (~1e-13 |s|).

On the code before issue 18.3 every test here fails: the argument principle
counts 2 at 0.999 b_lim (a 2 pi turn of the double zero falls between two
samples 54 rad/s apart), the rank-two resultant loses the four-fold widths
(b_lim 7.87 mm and inf among 0.204 mm), 36 615 frequencies and 508 branches.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

import chatterlab as cl
from chatterlab.cli._main import main
from chatterlab.frequency._roots import make_system
from chatterlab.frequency._stability import stability
from chatterlab.frequency._winding import rhp_count
from chatterlab.lobes._diagram import lobes
from chatterlab.process import closed_loop

K = 1.0e7  # N/m
ZETA = 0.02
FN = 100.0  # Hz
KF = 2.0e9  # N/m^2
M = K / (2 * math.pi * FN) ** 2
C = 2 * ZETA * math.sqrt(K * M)
RPM = 8250.0


def tool_text(ky: float = K, *, rpm: float = RPM, y: bool = True) -> str:
    """Modes in x (k = K) and y (k = ky, the same mass), D_P = K_f I,
    D_O = -K_f I in the tool plane (width_ref 1 mm); ``y=False``: the x mode
    alone with the cut in x (the 1-DOF tool)."""
    fy = math.sqrt(ky / M) / (2 * math.pi)
    kf = KF * 1e-3
    ymode = (
        f'[[mode]]\nid = "y1"\nfrequency_hz = {fy!r}\ndamping_ratio = {ZETA * math.sqrt(K / ky)!r}\n'
        f'stiffness = {ky!r}\ndirection = "tool.y"\n'
        if y
        else ""
    )
    dy = kf if y else 0.0
    coords = 'x = "tool.x", y = "tool.y"' if y else 'x = "tool.x"'
    return f"""
[model]
name = "symmetric tool"
[[mode]]
id = "x1"
frequency_hz = {FN!r}
damping_ratio = {ZETA!r}
stiffness = {K!r}
direction = "tool.x"
{ymode}
[[point]]
id = "tip"
coords = {{ {coords} }}
[[coupling]]
id = "cut"
a = "tip"
b = "ground"
model = "matrices"
width_ref = 0.001
DP = [[{kf!r}, 0.0, 0.0], [0.0, {dy!r}, 0.0], [0.0, 0.0, 0.0]]
DO = [[{-kf!r}, 0.0, 0.0], [0.0, {-dy!r}, 0.0], [0.0, 0.0, 0.0]]
[process]
kind = "turning"
rpm = {rpm!r}
"""


def G(w: float, k: float = K) -> complex:
    """The 1-DOF receptance (same mass and damping coefficient for k_y: the
    modal model keeps c = 2 zeta_y sqrt(k_y m) = C)."""
    return 1.0 / (k - M * w**2 + 1j * C * w)


def tlusty(T: float, k: float = K, kmax: int = 40) -> tuple[float, float]:
    """(b_lim, w_c) of the 1-DOF tool of stiffness k at delay T: the lowest
    lobe whose phase condition w T = 3 pi + 2 arg G(w) + 2 pi j has a root
    above w_n (unique there, bracketed by [w_n, 2 pi (j + 1)/T])."""
    wn = math.sqrt(k / M)

    def h(w: float, j: int) -> float:
        return w * T - 3 * math.pi - 2 * float(np.angle(G(w, k))) - 2 * math.pi * j

    best = (math.inf, math.nan)
    for j in range(max(0, int(math.ceil(wn * T / (2 * math.pi) - 1))), kmax):
        lo, hi = wn * (1 + 1e-13), 2 * math.pi * (j + 1) / T + 1.0
        if h(lo, j) >= 0:
            continue
        w = brentq(h, lo, hi, args=(j,), xtol=1e-15 * hi, rtol=1e-15)
        b = -1.0 / (2 * KF * float(np.real(G(w, k))))
        if b < best[0]:
            best = (b, w)
    return best


def sdof_rhp(b: float, T: float, k: float = K, N: int = 48) -> int:
    """Roots of d(s) = m s^2 + c s + k + K_f b (1 - e^{-sT}) with Re s > 0.

    Chebyshev collocation of x' = A0 x + A1 x(t - T) on [-T, 0] (N + 1
    nodes), every eigenvalue refined by Newton on d; right of the axis
    |s|^2 m <= |c s| + k + 2 K_f b bounds the roots by R, which must lie well
    inside the collocation's resolution N / (2 T)."""
    a = KF * b
    A0 = np.array([[0.0, 1.0], [-(k + a) / M, -C / M]])
    A1 = np.array([[0.0, 0.0], [a / M, 0.0]])
    j = np.arange(N + 1)
    x = np.cos(np.pi * j / N)
    cc = np.where((j == 0) | (j == N), 2.0, 1.0) * (-1.0) ** j
    X = x[:, None] - x[None, :]
    D = np.outer(cc, 1 / cc) / (X + np.eye(N + 1))
    D -= np.diag(D.sum(axis=1))
    D *= 2.0 / T  # theta = T (x - 1) / 2 in [-T, 0], node 0 at theta = 0
    n = 2
    A = np.kron(D, np.eye(n))
    A[:n, :] = 0.0
    A[:n, :n] = A0
    A[:n, N * n :] = A1
    lam = np.linalg.eigvals(A)
    R = (C + math.sqrt(C * C + 4 * M * (k + 2 * a))) / (2 * M)
    assert R < 0.25 * N / T, "the collocation does not resolve the right half plane"

    def d(s):
        return M * s * s + C * s + k + a * (1 - np.exp(-s * T))

    def dd(s):
        return 2 * M * s + C + a * T * np.exp(-s * T)

    lam = lam[np.abs(lam) < 2 * R]
    for _ in range(50):
        lam = lam - d(lam) / dd(lam)
    ok = np.abs(d(lam)) < 1e-9 * (M * np.abs(lam) ** 2 + k)
    roots = np.unique(np.round(lam[ok], 6))
    return int(np.sum(roots.real > 0))


def _frozen(text: str) -> cl.FrozenSystem:
    return cl.assemble(cl.loads_model(text)).at()


def _rhp(fz: cl.FrozenSystem, b: float, T: float):
    fb = closed_loop(fz, width=b, delay=T)
    return rhp_count(make_system(fz.A, fz.B, fz.C, DP=fb.DP, DV=fb.DV, DO=(fb.U, fb.V), tau=T))


@pytest.fixture(scope="module")
def symmetric() -> cl.FrozenSystem:
    return _frozen(tool_text())


@pytest.fixture(scope="module")
def nearly() -> cl.FrozenSystem:
    return _frozen(tool_text(1.001 * K))


@pytest.fixture(scope="module")
def sym_diagram(symmetric):
    return lobes(symmetric, np.linspace(2000.0, 12000.0, 41), width_max=0.02)


@pytest.fixture(scope="module")
def near_diagram(nearly):
    return lobes(nearly, np.linspace(2000.0, 12000.0, 41), width_max=0.02)


# ----------------------------------------------------------------------------- the count


@pytest.mark.parametrize("factor", [0.999, 0.9999, 1.001, 1.01])
def test_symmetric_count_is_twice_the_1dof_count(symmetric, factor):
    """det Delta = d(s)^2: the count is twice the 1-DOF count (0 below the
    limit, 4 just above it: a double pair), proven increment by increment."""
    T = 60.0 / RPM
    b = factor * tlusty(T)[0]
    w = _rhp(symmetric, b, T)
    assert w.count == 2 * sdof_rhp(b, T), w.message
    assert (w.count == 0) == (factor < 1)
    assert w.status == "converged" and w.proven, w.message


@pytest.mark.parametrize("factor", [0.999, 1.0004, 1.001])
def test_nearly_symmetric_count_is_the_sum_of_the_two_1dof_counts(nearly, factor):
    """k_y = 1.001 k_x: the two limits differ by ~0.07 %; between them one
    pair is unstable (count 2), above both two pairs (4)."""
    T = 60.0 / RPM
    bx, by = tlusty(T)[0], tlusty(T, 1.001 * K)[0]
    b = factor * min(bx, by)
    w = _rhp(nearly, b, T)
    assert w.count == sdof_rhp(b, T) + sdof_rhp(b, T, 1.001 * K), w.message
    assert w.status == "converged" and w.proven, w.message


def test_roots_verdict_at_0999_b_lim(symmetric, tmp_path, capsys):
    """The issue's case: ``chatterlab roots`` at 0.999 b_lim, 8250 rpm, says
    stable (before: undetermined, "the argument principle counts 2")."""
    T = 60.0 / RPM
    b = 0.999 * tlusty(T)[0]
    st = stability(symmetric, width=b, speed=RPM)
    assert st.verdict == "stable" and st.agree, st.message
    assert st.winding.count == 0 and st.winding.proven, st.winding.message
    path = tmp_path / "symmetric.toml"
    path.write_text(tool_text())
    code = main(["roots", str(path), "--width", f"{b * 1e3:.9g}", "--speed", f"{RPM}"])
    out = capsys.readouterr().out
    assert code == 0
    assert out.startswith("verdict: stable"), out


# ----------------------------------------------------------------------------- the lobes


def test_symmetric_lobes_are_tlustys(sym_diagram):
    d = sym_diagram
    assert d.band_certified
    for b, T in zip(d.b_lim, d.delay, strict=True):
        assert b == pytest.approx(tlusty(T)[0], rel=1e-9), 60 / T


def test_nearly_symmetric_lobes_are_the_lower_tlusty(near_diagram):
    d = near_diagram
    for b, T in zip(d.b_lim, d.delay, strict=True):
        assert b == pytest.approx(min(tlusty(T)[0], tlusty(T, 1.001 * K)[0]), rel=1e-9), 60 / T


def test_diagram_checks_agree(sym_diagram, near_diagram):
    """The diagrams' own argument-principle checks (before: 5 of 6 failed)."""
    for d in (sym_diagram, near_diagram):
        assert d.checks and all(c["agrees"] for c in d.checks), d.checks


def test_coincident_families_are_merged(symmetric, sym_diagram, near_diagram):
    """The symmetric tool's diagram is the 1-DOF tool's: the same lobes on the
    same grid (the two equal blocks computed once); the nearly symmetric one
    has two families of them, not tens of thousands of fragments."""
    one = lobes(_frozen(tool_text(y=False)), sym_diagram.speed, width_max=0.02)
    np.testing.assert_allclose(sym_diagram.b_lim, one.b_lim, rtol=1e-12)
    assert len(sym_diagram.lobes) == len(one.lobes)
    assert sym_diagram.n_frequencies == one.n_frequencies
    assert len(near_diagram.lobes) <= 2 * len(one.lobes)
    assert near_diagram.n_frequencies <= 2 * one.n_frequencies + 10


def _coupled_text() -> str:
    """Modes along axes at 30 deg to x, k_2 = 1.001 k_1 (same mass), cut by
    D_O = -K_f diag(1, 1.001): nearly symmetric, and no constant basis
    decouples it (the commutant is the multiples of I)."""
    c, s = math.cos(math.radians(30.0)), math.sin(math.radians(30.0))
    kf = KF * 1e-3
    k2 = 1.001 * K
    return f"""
[model]
name = "nearly symmetric, coupled"
[[mode]]
id = "u1"
frequency_hz = {FN!r}
damping_ratio = {ZETA!r}
stiffness = {K!r}
shape = {{ "tool.x" = {c!r}, "tool.y" = {s!r} }}
[[mode]]
id = "u2"
frequency_hz = {math.sqrt(k2 / M) / (2 * math.pi)!r}
damping_ratio = {ZETA * math.sqrt(K / k2)!r}
stiffness = {k2!r}
shape = {{ "tool.x" = {-s!r}, "tool.y" = {c!r} }}
[[point]]
id = "tip"
coords = {{ x = "tool.x", y = "tool.y" }}
[[coupling]]
id = "cut"
a = "tip"
b = "ground"
model = "matrices"
width_ref = 0.001
DP = [[{kf!r}, 0.0, 0.0], [0.0, {1.001 * kf!r}, 0.0], [0.0, 0.0, 0.0]]
DO = [[{-kf!r}, 0.0, 0.0], [0.0, {-1.001 * kf!r}, 0.0], [0.0, 0.0, 0.0]]
[process]
kind = "turning"
rpm = {RPM!r}
"""


def test_nearly_symmetric_coupled_loop_is_not_fragmented(sym_diagram):
    """The rank-two resultant of a nearly symmetric loop that does not
    decouple has clusters of four roots; their scattered roots are refined on
    each sorted |nu_j|, so the two close families are found whole (before:
    116 folds, 496 branches, 15 137 frequencies; now 4 folds, as two 1-DOF
    families have, and ~1.6x the 1-DOF grid).  The limits are the roots'
    (bisection to 1e-6 at three speeds; the full cross-check is in
    tests/test_lobes_crosscheck_symmetric.py)."""
    fz = _frozen(_coupled_text())
    d = lobes(fz, sym_diagram.speed, width_max=0.02)
    assert d.band_certified
    assert d.checks and all(c["agrees"] for c in d.checks), d.checks
    assert d.folds <= 2 * sym_diagram.folds
    assert d.n_frequencies <= 2 * sym_diagram.n_frequencies
    for j in (0, 20, 40):
        b, T = float(d.b_lim[j]), float(d.delay[j])
        lo = stability(fz, width=b * (1 - 1e-6), delay=T, winding=False, count=2).abscissa
        hi = stability(fz, width=b * (1 + 1e-6), delay=T, winding=False, count=2).abscissa
        assert lo < 0 < hi, (60 / T, b, lo, hi)
