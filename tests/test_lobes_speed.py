"""The lobe engine's faster routes (issue 26, rows 3 and 4) against the slower
ones they replace, and the work they save (counted, not timed).

Two kinds of oracle:

* **The engine before the change** (commit 476e1b1), recorded in
  ``tests/data/lobes_476e1b1.json`` by ``python tests/test_lobes_speed.py
  --record`` run against that commit (``PYTHONPATH`` at a worktree of it):
  every case's diagram -- b_lim, chatter frequency and lobe number at every
  speed, the minima, folds, grid size, lobes listed and the checks' verdicts
  -- on the shaper (all terms and the delayed term alone), the 1-DOF
  regenerative tool (Tlusty), a random 3-DOF structure with rank-one and
  rank-two regeneration, and the symmetric and nearly symmetric tools.
* **The slower route kept in the code** (the same function with the
  shortcut off): the widths without the root-free screen, the fold bisection
  one midpoint per batch, the certified band bounded interval by interval,
  the certified phase from the old pi/(8 tau) grid, each count alone.

Tolerances.  The structure's FRF is now one matrix product over the modes
(a different summation order): H moves by a few ulp, ~1e-16 relative.  A
boundary width is a root of Q and moves by cond x 1e-16; at a simple root
cond ~1, at the shaper's fold nose (83.3719 Hz, where two widths merge) the
recorded worst is 3.8e-13, so 1e-12 everywhere (cond up to ~1e3-1e4).  The
chatter frequency is refined by regula falsi to 1e-14 relative in w:
1e-13.  The lobe number floor(f_c T) is an integer of f_c T ~ 10-500, which
moves by < 1e-10: equal unless f_c T lies within 1e-10 of an integer (not
the case in these diagrams).  Folds, the grid, the lobes listed and every
check's kind, verdict, count and proof are integers and must be equal.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import chatterlab as cl
from chatterlab.lobes._diagram import lobes

HERE = Path(__file__).resolve().parent
RECORDING = HERE / "data" / "lobes_476e1b1.json"
SHAPER = HERE.parent / "studies" / "traverse_shaper" / "model.toml"


# ---------------------------------------------------------------------------- the cases


def _random_frozen(seed: int, rank: int) -> cl.FrozenSystem:
    from test_lobes_crosscheck import _random_model

    return cl.assemble(cl.loads_model(_random_model(np.random.default_rng(1000 + seed), rank))).at()


def _random_delays(fz: cl.FrozenSystem) -> np.ndarray:
    from scipy.linalg import eigh

    f1 = np.sqrt(eigh(fz.C, fz.A, eigvals_only=True).min()) / (2 * np.pi)
    return np.geomspace(0.5 / f1, 40.0 / f1, 40)


def _cases() -> dict[str, dict[str, Any]]:
    """name -> frozen system, speeds and lobes() keywords."""
    from conftest import turning_text
    from test_symmetric_tools import K, tool_text

    shaper = cl.assemble(cl.load_model(SHAPER)).at(0.85)
    turning = cl.assemble(
        cl.loads_model(turning_text(mass=1.0, stiffness=1.0e7, damping=2 * 0.03 * np.sqrt(1e7), Kf=2e9))
    ).at()
    r1, r2 = _random_frozen(0, 1), _random_frozen(1, 2)
    rpm = np.linspace(2000.0, 12000.0, 60)
    return {
        "shaper": {
            "fz": shaper,
            "speeds": np.linspace(0.1, 1.0, 300),
            "kw": {"width_max": 1e-3, "verify": 16},
        },
        "shaper_o": {
            "fz": shaper,
            "speeds": np.linspace(0.3, 0.6, 40),
            "kw": {"width_max": 1e-3, "verify": 6, "terms": "o"},
        },
        "turning": {
            "fz": turning,
            "speeds": np.linspace(2000.0, 15000.0, 200),
            "kw": {"width_max": 0.02, "verify": 16},
        },
        "turning_o": {
            "fz": turning,
            "speeds": np.linspace(2000.0, 15000.0, 50),
            "kw": {"width_max": 0.02, "verify": 8, "terms": "o"},
        },
        "random_rank1": {"fz": r1, "speeds": _random_delays(r1), "kw": {"width_max": 0.02, "verify": 8}},
        "random_rank2": {"fz": r2, "speeds": _random_delays(r2), "kw": {"width_max": 0.02, "verify": 8}},
        "symmetric": {
            "fz": cl.assemble(cl.loads_model(tool_text())).at(),
            "speeds": rpm,
            "kw": {"width_max": 0.02, "verify": 8},
        },
        "nearly_symmetric": {
            "fz": cl.assemble(cl.loads_model(tool_text(1.001 * K))).at(),
            "speeds": rpm,
            "kw": {"width_max": 0.02, "verify": 8},
        },
    }


def _summary(d: Any) -> dict[str, Any]:
    return {
        "b_lim": [float(x) for x in d.b_lim],
        "chatter_hz": [float(x) for x in d.chatter_hz],
        "lobe": [int(x) for x in d.lobe],
        "minimum": float(d.minimum["width"]),
        "absolute_minimum": float(d.absolute_minimum["width"]),
        "absolute_minimum_hz": float(d.absolute_minimum["chatter_hz"]),
        "folds": int(d.folds),
        "n_frequencies": int(d.n_frequencies),
        "n_lobes_listed": len(d.lobes),
        "n_lobes": int(d.n_lobes),
        "band_hz": [float(x) for x in d.band_hz],
        "checks": [[c["kind"], c["width"], c["verdict"], c["rhp_roots"], c["proven"]] for c in d.checks],
    }


def record(path: Path) -> None:
    """Write the recording (run against the commit it is named after)."""
    out = {name: _summary(lobes(c["fz"], c["speeds"], **c["kw"])) for name, c in _cases().items()}
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=0) + "\n")


# ---------------------------------------------------------------------------- the diagram as before


@pytest.fixture(scope="module")
def cases() -> dict[str, dict[str, Any]]:
    return _cases()


@pytest.fixture(scope="module")
def recorded() -> dict[str, Any]:
    return json.loads(RECORDING.read_text())


@pytest.mark.parametrize(
    "name",
    [
        "shaper",
        "shaper_o",
        "turning",
        "turning_o",
        "random_rank1",
        "random_rank2",
        "symmetric",
        "nearly_symmetric",
    ],
)
def test_diagram_equals_the_recording_before_the_change(cases, recorded, name):
    """The recording was made on another CPU and BLAS: the numbers may differ
    by round-off, within the tolerance that the boundary's measured
    sensitivity to one rounding of the structure gives (tests/_roundoff.py);
    the counts and lobe numbers are exact."""
    from _roundoff import roundoff_tolerance

    c, ref = cases[name], recorded[name]
    new = _summary(lobes(c["fz"], c["speeds"], **c["kw"]))
    kw0 = {**c["kw"], "verify": 0}  # the checks do not change the numbers compared

    def numbers(d: Any) -> np.ndarray:
        return np.concatenate([d.b_lim, d.chatter_hz, [d.minimum["width"], d.absolute_minimum["width"]]])

    got = np.concatenate([new["b_lim"], new["chatter_hz"], [new["minimum"], new["absolute_minimum"]]])
    want = np.concatenate([ref["b_lim"], ref["chatter_hz"], [ref["minimum"], ref["absolute_minimum"]]])
    tol = roundoff_tolerance(lambda fz, sp: numbers(lobes(fz, sp, **kw0)), c["fz"], c["speeds"], got)
    b0, b1 = np.array(ref["b_lim"]), np.array(new["b_lim"])
    fin = np.isfinite(b0)
    assert np.array_equal(fin, np.isfinite(b1)), name
    m = b0.size
    keep = np.concatenate([fin, fin, [True, True]])  # chatter_hz is nan where b_lim is inf
    bad = np.nonzero(keep & ~(np.abs(got - want) <= tol))[0]
    assert not bad.size, [(int(i % m), got[i], want[i], tol[i]) for i in bad[:5]]
    assert new["lobe"] == ref["lobe"]
    for key in ("folds", "n_frequencies", "n_lobes_listed", "n_lobes"):
        assert new[key] == ref[key], key
    # the band and the checks' widths are computed from the same boundary: its relative round-off level
    rtol = float(np.max(tol[keep] / np.abs(got[keep])))
    np.testing.assert_allclose(new["band_hz"], ref["band_hz"], rtol=rtol)
    assert [c[:1] + c[2:] for c in new["checks"]] == [c[:1] + c[2:] for c in ref["checks"]]
    np.testing.assert_allclose([c[1] for c in new["checks"]], [c[1] for c in ref["checks"]], rtol=rtol)
    assert all(c[2] == ("unstable" if c[0] == "above" else "stable") for c in new["checks"]), new["checks"]


def test_tlusty_minimum_still_holds(cases):
    """The 1-DOF tool's absolute minimum is 2 k zeta (1 + zeta)/K_f (Tlusty;
    tests/test_lobes.py derives it): to the 1e-10 of the Brent refinement."""
    d = lobes(cases["turning"]["fz"], cases["turning"]["speeds"], **cases["turning"]["kw"])
    k, zeta, kf = 1.0e7, 0.03, 2.0e9
    assert d.absolute_minimum["width"] == pytest.approx(2 * k * zeta * (1 + zeta) / kf, rel=1e-9)


# ---------------------------------------------------------------------------- each shortcut against its slow route


def _grid_ops(fz: cl.FrozenSystem, width_max: float, terms: str = "pdo") -> tuple[Any, Any, np.ndarray]:
    from chatterlab.lobes._envelope import Boundary
    from chatterlab.lobes._plant import _ops

    bd = Boundary(fz, width_max=width_max, terms=terms)  # type: ignore[arg-type]
    return bd, _ops(bd.plant, bd.omega), bd.omega


@pytest.mark.parametrize(
    ("name", "terms"), [("shaper", "pdo"), ("shaper", "o"), ("turning", "pdo"), ("random_rank1", "pdo")]
)
def test_root_free_screen_skips_no_width(cases, name, terms):
    """The disc test only skips frequencies where Q has no root near the
    searched segment: with and without it the widths are the same, bit for
    bit (a row's arithmetic does not depend on the others), and so is every
    proximity below 0.05 (the only use of it).  On the shaper's grid it spares
    the companion matrix for > 95 % of the frequencies."""
    from chatterlab.lobes import _boundary as B

    c = cases[name]
    wm = c["kw"]["width_max"]
    _, ops, w = _grid_ops(c["fz"], wm, terms)
    fast, pf = B.widths_rank1(ops, wm)
    slow, ps = B.widths_rank1(ops, wm, screen=False)
    assert all(np.array_equal(a, b) for a, b in zip(fast, slow, strict=True))
    near = (pf < 0.05) | (ps < 0.05)
    np.testing.assert_array_equal(pf[near], ps[near])
    HA = ops.HA * wm
    q = B._q_coefficients(B._char_poly(HA), B._char_poly(HA + wm * (ops.HU @ ops.Vt)))
    skipped = B._no_root_near_segment(q)
    assert not np.any(skipped & np.array([x.size > 0 for x in slow]))
    if name == "shaper" and terms == "pdo":
        assert skipped.sum() > 0.95 * w.size, (skipped.sum(), w.size)


def test_screen_sees_a_root_it_must_not_skip():
    """Polynomials with a root planted in the searched region (a real one in
    (0, 1], a complex one of proximity < 0.05, one on a disc's rim) are never
    passed; one whose roots are all far is."""
    from chatterlab.lobes import _boundary as B

    P = np.polynomial.polynomial
    far = [3.0, -2.0, 5.0 + 4.0j, 5.0 - 4.0j, -1.5, 2.5]
    cases = [
        [0.37, *far[1:]],
        [0.6 + 0.02j, 0.6 - 0.02j, *far[2:]],
        [1.05, *far[1:]],
        [-0.05, *far[1:]],
    ]
    q = np.array([P.polyfromroots(r).real for r in cases + [far]])
    assert list(B._no_root_near_segment(q)) == [False, False, False, False, True]


def test_fold_bisection_in_batches_visits_the_same_points(cases):
    """Four levels of the fold bisection per batch give the same frequencies
    (bit for bit) and folds as one midpoint per batch, in ~1/4 of the calls."""
    from chatterlab.lobes import _boundary as B
    from chatterlab.lobes._plant import _ops

    bd, _, w = _grid_ops(cases["shaper"]["fz"], 1e-3)
    out = {}
    for depth in (1, B._BISECT_DEPTH):
        calls = []

        def make(x: np.ndarray, calls: list[int] = calls) -> Any:
            calls.append(x.size)
            return _ops(bd.plant, x)

        old = B._BISECT_DEPTH
        B._BISECT_DEPTH = depth
        try:
            out[depth] = (*B.refine_folds(make, w, 1e-3), len(calls))
        finally:
            B._BISECT_DEPTH = old
    (w1, x1, f1, n1), (w4, x4, f4, n4) = out[1], out[B._BISECT_DEPTH]
    assert np.array_equal(w1, w4) and f1 == f4 == 5
    # the widths at each point: the same but for the batch's BLAS blocking, i.e. within each width's
    # round-off (tests/_roundoff.py): its change when the structure is moved by one ulp, at the same
    # frequencies, times 2 N; near a fold a width is a near-double root of Q and far more sensitive
    from _roundoff import EPS, perturbed

    fz = cases["shaper"]["fz"]
    flat, spread, measured = np.concatenate(x1), np.zeros(sum(a.size for a in x1)), 0
    for seed in (11, 12, 13):
        bp, _, _ = _grid_ops(perturbed(fz, seed), 1e-3)
        xp, _ = B.widths(_ops(bp.plant, w1), 1e-3)
        if [a.size for a in xp] != [a.size for a in x1]:
            continue  # a fold moved across a point: no measure from this seed
        measured += 1
        spread = np.maximum(spread, np.abs(np.concatenate(xp) - flat))
    assert measured >= 1
    tol = 2.0 * (2 * fz.n) * np.maximum(spread, EPS * np.abs(flat))
    assert all(a.size == b.size for a, b in zip(x1, x4, strict=True))
    assert np.all(np.abs(np.concatenate(x4) - flat) <= tol)
    assert n1 >= 30 and n4 <= n1 // 3 + 1, (n1, n4)


def test_nearest_width_by_newton_equals_the_long_way(cases):
    """The envelope's re-solve: Newton on Q from the target, accepted only when
    the disc test proves the root the nearest, gives the width and z of the
    long way (every root of Q by its companion matrix, polished, the nearest
    chosen): both are Newton-polished roots of one Q from other starts, so
    they agree to the attainable accuracy of the root, ~eps sum_k |c_k x^k| /
    |Q'(x)| (x = beta/hi) -- 1e-16 relative for a simple root, ~1e-12 next
    to the fold at the nose of the shaper's 83 Hz branch, where Q' is small;
    asserted to 64 times that.  Where the two widths of the fold are close it
    declines and the long way answers."""
    from chatterlab.lobes import _boundary as B
    from chatterlab.lobes import _plant as P
    from chatterlab.lobes._boundary import near_root

    bd, _, _ = _grid_ops(cases["shaper"]["fz"], 1e-3)
    sg = min(bd.segments, key=lambda s: float(s.beta.min()))  # the 83 Hz mode's, U-shaped
    j = int(np.argmin(sg.omega))  # its nose: the fold, where two widths merge
    # around the nose: the branch's points, and targets off them on both sides
    sel = np.arange(max(j - 40, 0), min(j + 40, sg.omega.size))
    w = np.concatenate([sg.omega[sel], 0.5 * (sg.omega[sel][:-1] + sg.omega[sel][1:])])
    b = np.concatenate([sg.beta[sel], 0.5 * (sg.beta[sel][:-1] + sg.beta[sel][1:])])
    ops = P._ops(bd.plant, w)
    for f in (1.0, 1.001, 0.97):
        target = b * f
        lo, hi = target / 1.5, target * 1.5
        fast_b, fast_z = P._nearest_width(ops, lo, hi, target)
        _, sure = near_root(ops, hi, target / hi)
        fi, bb, zz = P._widths_between(ops, lo, hi)
        slow_b = np.full(w.size, np.nan)
        slow_z = np.full(w.size, np.nan + 0j)
        order = np.argsort(-np.abs(np.log(bb / target[fi])))
        slow_b[fi[order]], slow_z[fi[order]] = bb[order], zz[order]
        assert np.array_equal(np.isfinite(fast_b), np.isfinite(slow_b))
        ok = np.isfinite(slow_b)
        HA = ops.HA * hi[:, None, None]
        q = B._q_coefficients(B._char_poly(HA), B._char_poly(HA + hi[:, None, None] * (ops.HU @ ops.Vt)))
        x = slow_b / hi
        powers = x[:, None] ** np.arange(q.shape[1])
        dq = np.sum(q[:, 1:] * np.arange(1, q.shape[1]) * powers[:, :-1], axis=1)
        tol_x = 64 * np.finfo(float).eps * np.sum(np.abs(q) * powers, axis=1) / np.abs(dq)
        assert np.all(np.abs(fast_b - slow_b)[ok] <= (tol_x * hi)[ok]), np.max(
            (np.abs(fast_b - slow_b) / (tol_x * hi))[ok]
        )
        # z follows its width: the same z where the widths are the same, else within dz/dbeta times the difference
        zb = P._z_at(ops, slow_b[ok] * (1 + 1e-7), np.nonzero(ok)[0])
        dz = np.abs(zb - slow_z[ok]) / (1e-7 * slow_b[ok])
        assert np.all(np.abs(fast_z - slow_z)[ok] <= 2 * dz * (tol_x * hi)[ok] + 1e-13)
        assert sure.sum() > w.size // 2 and (~sure).sum() > 0, (sure.sum(), w.size)


def test_block_bounded_band_equals_bounding_every_interval(cases):
    """The certified band's last bad interval found block-wise is the one of
    bounding every interval of the partition (shaper, turning, random)."""
    from chatterlab.frequency import _bounds as Bo

    for name in ("shaper", "turning", "random_rank1"):
        bd, _, _ = _grid_ops(cases[name]["fz"], cases[name]["kw"]["width_max"])
        pl = bd.plant
        pr = pl.residues
        nP, nV, nO = (float(np.linalg.norm(x, 2)) for x in (pl.Dl_P, pl.Dl_V, pl.Dl_O))
        w1 = float(np.abs(pl.poles[pl.poles.imag > 0]).min())
        top = 10.0 * max(float(np.max(np.abs(pr.p))), 1e-3 * w1)
        edges = np.geomspace(1e-3 * w1, top, int(np.ceil(np.log(top / (1e-3 * w1)) / np.log(1.002))) + 1)
        wm = cases[name]["kw"]["width_max"]
        every = Bo._gain_bound(pr, edges[:-1], edges[1:], nP, nV, nO, wm)
        bad = np.nonzero(every >= 1.0)[0]
        assert Bo._last_bad_interval(pr, edges, nP, nV, nO, wm, 0.0) == (bad[-1] if bad.size else -1), name


def test_pole_residue_form_is_the_modal_superposition(cases):
    """Plant.H (one GEMM over the modes) against the complex-mode
    superposition of chatterlab.structure (einsum): a few ulp of |H|."""
    from chatterlab.structure._complex import modal_response

    bd, _, w = _grid_ops(cases["shaper"]["fz"], 1e-3)
    fz = cases["shaper"]["fz"]
    from chatterlab.process._loop import closed_loop_unwarned

    J = closed_loop_unwarned(fz, width=1.0, delay=1.0).J
    cm = fz.complex_modes
    ref = np.transpose(modal_response(cm, J, J.T, 1j * w, np.arange(cm.lam.size), False), (2, 0, 1))
    assert np.max(np.abs(bd.plant.H(w) - ref)) <= 1e-14 * np.max(np.abs(ref))


# ---------------------------------------------------------------------------- the checks


def _check_loops(fz: cl.FrozenSystem, d: Any) -> list[Any]:
    from chatterlab.process._loop import closed_loop_unwarned

    return [closed_loop_unwarned(fz, width=c["width"], delay=c["delay"], terms=d.terms) for c in d.checks]


def test_checks_decompose_once_without_proportional_feedback(cases):
    """Only the delayed term (terms="o"): the delay-free loop is the same at
    every width, so the checks' verification does one eigendecomposition in
    all (was one per check), and one open-loop root computation."""
    from chatterlab.frequency import _delay_system as DS
    from chatterlab.lobes import _verification as V

    for name in ("shaper_o", "turning_o"):
        c = cases[name]
        d = lobes(c["fz"], c["speeds"], **{**c["kw"], "verify": 0})
        before = DS.EIG_COUNT[0]
        checks = V._verify(c["fz"], d, c["kw"]["verify"], None)
        assert DS.EIG_COUNT[0] - before == 1, name
        assert len(checks) >= 5 and all(ch["agrees"] and ch["proven"] for ch in checks), checks
        systems = DS.loop_systems(_check_loops(c["fz"], d))
        assert all(s.open_loop_poles() is systems[0].open_loop_poles() for s in systems)


def test_checks_decompose_once_per_width_with_feedback(cases):
    """All terms (the shaper, case c): the delay-free loop depends on the
    width, so one eigendecomposition per distinct width of the checks."""
    from chatterlab.frequency import _delay_system as DS
    from chatterlab.lobes import _verification as V

    c = cases["shaper"]
    d = lobes(c["fz"], c["speeds"], **{**c["kw"], "verify": 0})
    before = DS.EIG_COUNT[0]
    checks = V._verify(c["fz"], d, 16, None)
    assert DS.EIG_COUNT[0] - before == len({ch["width"] for ch in checks}) == 26


def test_batched_counts_equal_single_counts(cases):
    """rhp_counts (all the checks' phases bisected together, shared
    factorisations) gives each system's rhp_count alone, to the sample."""
    from chatterlab.frequency._delay_system import loop_system, loop_systems
    from chatterlab.frequency._winding import rhp_count, rhp_counts

    for name in ("shaper", "symmetric", "random_rank2"):
        c = cases[name]
        d = lobes(c["fz"], c["speeds"], **{**c["kw"], "verify": 0})
        from chatterlab.lobes._verification import _check_speeds

        loops = []
        from chatterlab.process._loop import closed_loop_unwarned

        for j, kind in _check_speeds(d, 6):
            b = d.width_max if kind == "ceiling" else d.b_lim[j] * (1.001 if kind == "above" else 0.999)
            loops.append(closed_loop_unwarned(c["fz"], width=float(b), delay=float(d.delay[j])))
        many = rhp_counts(loop_systems(loops))
        for lp, m in zip(loops, many, strict=True):
            one = rhp_count(loop_system(lp))
            assert (one.count, one.status, one.proven, one.n_samples) == (
                m.count,
                m.status,
                m.proven,
                m.n_samples,
            )
            assert one.winding == pytest.approx(m.winding, abs=1e-9)


def test_certification_from_the_pole_frequencies_equals_the_dense_start(cases):
    """The certified count from the lean start (0, the delay-free poles'
    frequencies, W) equals the one from the old pi/(8 tau) grid -- both are
    proven -- with ~50x fewer samples on the shaper (a work count)."""
    from chatterlab.frequency._delay_system import loop_system
    from chatterlab.frequency._phase_sampling import (
        Sampler,
        band_end,
        certification_grid,
        certified_phase,
        initial_grid,
    )

    c = cases["shaper"]
    d = lobes(c["fz"], c["speeds"], **{**c["kw"], "verify": 0})
    loops = _check_loops(c["fz"], lobes(c["fz"], c["speeds"], width_max=1e-3, verify=3))
    for lp in loops:
        sys_ = loop_system(lp)
        p0, p = sys_.open_loop_poles(), sys_.delay_free_poles()
        scale = max(float(np.max(np.abs(p0))), float(np.max(np.abs(p))))
        F = Sampler(sys_, "factored", p0, 0.0)
        poles = np.concatenate([p, p0])
        W, _ = band_end(sys_, "factored", None, poles, scale)
        pieces, _, _ = initial_grid(sys_, "factored", W, poles, scale, None)
        old = certified_phase(F, np.unique(np.concatenate(pieces)), W)
        new = certified_phase(F, certification_grid(p, W), W)
        assert old is not None and new is not None and old.complete and new.complete
        assert round(old.total / math.pi) == round(new.total / math.pi)
        assert abs(new.total - old.total) < 1e-6
        assert new.w.size * 20 < old.w.size, (new.w.size, old.w.size)
    assert d.n_frequencies == 6169


if __name__ == "__main__":
    if "--record" in sys.argv:
        sys.path.insert(0, str(HERE))
        record(RECORDING)
        print(f"wrote {RECORDING}")
