"""The numerical oracle of the redesign (issue 19): every number recorded
from the pre-move code is computed again by the current code and must agree
within the tolerance recorded with it.

What is compared
----------------
``tests/data/oracle/manifest.json`` lists the cases (lobes, roots, FRFs,
modes, simulations, milling lobes and multipliers, measured-FRF lobes,
sweeps and an atlas on the bundled models and on models built as the tests
build them), the commit they were recorded from, the numpy and scipy of the
recording, and for every quantity how it is compared and the rule its
tolerance comes from; ``tests/data/oracle/<case>.npz`` holds the values and,
for the compared-within-a-tolerance ones, the tolerance of each element
(``tol/<quantity>``, absolute, in the quantity's unit).  The recorder,
``benchmarks/oracle/record.py``, explains how each tolerance is derived
(its docstring): discrete results (verdicts, counts, lobe numbers, kinds)
must be equal; floating-point results within a bound derived from the
method -- a solver's stopping rule where it stops short of round-off,
otherwise the round-off of a backward-stable computation times the
problem's condition number, computed per element when recorded -- which
holds when the order of the floating-point operations changes (another
BLAS, another association of a sum) but not when the arithmetic does.

The adapters
------------
Each quantity is computed by one small adapter function below, calling
the public API as it is today (``chatterlab.lobes.lobes``, ``chatterlab.stability``,
``chatterlab.frf``, ``chatterlab.modes``, ``chatterlab.simulate``,
``chatterlab.lobes.milling_lobes``, ``chatterlab.frequency.multipliers``,
``chatterlab.time.simulate_milling``, ``chatterlab.lobes.lobes_measured``,
``chatterlab.sweep.sweep``).  The recorder calls the same functions (it
imports this module).  When the redesign changes the API, the adapters are
what gets updated -- their names, arguments and returned keys stay -- and
the recorded data never is: a number that moves is a finding, not a file
to regenerate.  Where the API has already moved, an adapter takes the new
call and falls back to the recorded commit's (so the test also runs there,
which is how its tolerances were checked: ``cd /tmp && PYTHONPATH=<worktree
of 63e1fc1> python -m pytest <repo>/tests/test_oracle.py``).  Keys starting with ``_`` carry objects for the recorder's
derivation and are not compared.

The models are recorded with the data (their text in the manifest), so an
edit of ``studies/`` does not move the oracle; the tap-test FRF file is
read from ``studies/tap_test`` and checked against its recorded SHA-256.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import chatterlab as cl

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data" / "oracle"

Out = dict[str, Any]

# ============================================================================ adapters
# One function per quantity, calling the public API as it is today.  When the
# redesign changes the API, these are what gets updated (the recording never is).


def load(ref: dict[str, str]) -> Any:
    """A model from its recorded text (a bundled file's or a generated one's)."""
    return cl.loads_model(ref["text"], source=ref["name"])


def _pick(x: np.ndarray, samples: list[int] | None) -> np.ndarray:
    return x if samples is None else x[np.asarray(samples, int)]


def lobe_diagram(
    model: dict[str, str],
    speeds: list[float],
    width_max: float,
    position: float | None = None,
    verify: int = 0,
) -> Out:
    """chatterlab.lobes.lobes on one frozen configuration: the envelope,
    its minima, band and argument-principle checks."""
    from chatterlab.lobes import lobes

    fz = cl.assemble(load(model)).at(position)
    d = lobes(fz, np.asarray(speeds, float), width_max=width_max, verify=verify)
    return {
        "delay": d.delay,
        "b_lim": d.b_lim,
        "chatter_hz": d.chatter_hz,
        "lobe": d.lobe,
        "minimum_width": d.minimum["width"],
        "minimum_speed": d.minimum["speed"],
        "minimum_chatter_hz": d.minimum["chatter_hz"],
        "absolute_minimum_width": d.absolute_minimum["width"],
        "absolute_minimum_chatter_hz": d.absolute_minimum["chatter_hz"],
        "band_hz": np.asarray(d.band_hz, float),
        "band_certified": bool(d.band_certified),
        "checks_rhp": np.array([int(c["rhp_roots"]) for c in d.checks], int),
        "checks_agree": np.array([bool(c["agrees"]) for c in d.checks], bool),
        "n_frequencies": int(d.n_frequencies),
        "folds": int(d.folds),
        "n_lobes": int(d.n_lobes),
        "_frozen": fz,
        "_diagram": d,
    }


def natural_modes(model: dict[str, str], count: int, position: float | None = None) -> Out:
    """chatterlab.modes: undamped natural frequencies and modal damping."""
    sy = cl.assemble(load(model))
    m = cl.modes(sy, count=count, position=position)
    return {"frequency_hz": m.frequency_hz, "damping_ratio": m.damping_ratio, "_frozen": sy.at(position)}


def response(
    model: dict[str, str],
    frequency_hz: list[float],
    inputs: list[str],
    outputs: list[str],
    position: float | None = None,
    width: float | None = None,
    speed: float | None = None,
    delay: float | None = None,
    terms: str = "pdo",
) -> Out:
    """chatterlab.frf (receptance, direct solve), open loop (width None) or
    closed by the cut at (width, speed or delay)."""
    fz = cl.assemble(load(model)).at(position)
    # 63e1fc1: chatterlab.feedback; since 3600882 the closed loop, chatterlab.closed_loop
    close = cl.closed_loop if hasattr(cl, "closed_loop") else cl.feedback
    fb = None if width is None else close(fz, width=width, speed=speed, delay=delay, terms=terms)  # type: ignore[arg-type]
    w = 2 * np.pi * np.asarray(frequency_hz, float)
    if hasattr(cl, "closed_loop"):  # since 84a185d the FRF of the closed loop is frf(loop, ...)
        h = cl.frf(fz if fb is None else fb, w, inputs=inputs, outputs=outputs)
    else:
        h = cl.frf(fz, w, inputs=inputs, outputs=outputs, feedback=fb)
    return {"H": h.data, "_frozen": fz, "_feedback": fb}


def roots(
    model: dict[str, str], points: list[dict[str, Any]], count: int, position: float | None = None
) -> Out:
    """chatterlab.stability at (width, speed or delay[, terms]) points: the
    verdict, the rightmost roots, the argument principle's count."""
    fz = cl.assemble(load(model)).at(position)
    rs, verdict, absc, wind, agree, sts = [], [], [], [], [], []
    for p in points:
        st = cl.stability(fz, count=count, **p)
        r = np.full(count, np.nan + 0j)
        r[: len(st.roots.roots)] = st.roots.roots[:count]
        rs.append(r)
        verdict.append(st.verdict)
        absc.append(st.abscissa)
        wind.append(-1 if st.winding is None else int(st.winding.count))
        agree.append(bool(st.agree))
        sts.append(st)
    return {
        "roots": np.array(rs),
        "abscissa": np.array(absc),
        "verdict": np.array(verdict),
        "rhp_count": np.array(wind, int),
        "agree": np.array(agree, bool),
        "_frozen": fz,
        "_stability": sts,
    }


def simulation(
    model: dict[str, str], samples: list[int] | None, outputs: list[str], growth_skip: float = 0.0, **kw: Any
) -> Out:
    """chatterlab.simulate (Newmark, the delayed closed loop of Eq. 2.28):
    the outputs at a few recorded samples and the envelope's growth rate of
    the first output (after ``growth_skip`` s)."""
    sy = cl.assemble(load(model))
    sim = cl.simulate(sy, outputs=outputs, **kw)
    out: Out = {"t": _pick(sim.t, samples), "n_t": int(sim.t.size), "status": str(sim.status)}
    for name in outputs:
        out[f"y:{name}"] = _pick(sim.data[name], samples)
    out["growth_rate"] = float(sim.growth(outputs[0], skip=growth_skip).rate)
    out["_system"] = sy
    return out


def _milling_args(model: Any, reduce: bool) -> tuple[Any, ...]:
    """The leading arguments of milling_lobes / multipliers for a milling
    model file: since d293b4e its closed loop (milling_loop_of), at 63e1fc1
    the tool point as a ToolStructure and the cutter; reduced to the modes
    that matter when ``reduce`` (as the command line does for a structural
    model)."""
    import chatterlab.lobes as L

    fz = cl.assemble(model).at()
    if hasattr(L, "milling_loop_of"):
        loop = L.milling_loop_of(fz)
        return (L.reduce_structure(loop)[0] if reduce else loop,)
    S = L.tool_structure(fz)
    return (L.reduce_structure(S)[0] if reduce else S, L.milling_of(model))


def _milling_lobes_out(L: Any) -> Out:
    # 63e1fc1: a MillingLobes (frequency_hz); since 8e2cccc a LobeDiagram (chatter_hz)
    return {
        "a_lim": L.a_lim,
        "kind": np.asarray(L.kind, str),
        "frequency_hz": L.chatter_hz if hasattr(L, "chatter_hz") else L.frequency_hz,
        "multiplier": L.multiplier,
        "error": L.error,
        "basis": np.asarray(L.basis, str),
        "certified": np.asarray(L.certified, float),
    }


def milling_lobes_model(
    model: dict[str, str],
    rpm: list[float],
    depth_max: float,
    method: str = "spectral",
    reduce: bool = False,
    steps: int = 40,
    rtol: float = 1e-8,
) -> Out:
    """chatterlab.lobes.milling_lobes on a milling model file: its tool point
    as a ToolStructure (reduced to the modes that matter when ``reduce``,
    as the command line does for a structural model), its cutter."""
    from chatterlab.lobes import milling_lobes

    lead = _milling_args(load(model), reduce)
    L = milling_lobes(
        *lead,
        np.asarray(rpm, float),
        method=method,  # type: ignore[arg-type]
        depth_max=depth_max,
        steps=steps,
        rtol=rtol,
    )
    return {**_milling_lobes_out(L), "_lead": lead}


def _tool_args(mass: float, f_hz: float, zeta: float, cutter: Any) -> tuple[Any, ...]:
    """One mode along x under ``cutter``: since d293b4e a closed loop
    (chatterlab.process.milling_loop of a Structure), at 63e1fc1 a
    ToolStructure and the cutter."""
    try:
        from chatterlab.process import milling_loop  # type: ignore[attr-defined]
        from chatterlab.structure import Structure  # type: ignore[attr-defined]
    except ImportError:
        from chatterlab.frequency import ToolStructure  # type: ignore[attr-defined]

        return (ToolStructure.single_dof(mass, 2 * np.pi * f_hz, zeta), cutter)
    return (milling_loop(Structure.single_dof(mass, 2 * np.pi * f_hz, zeta), cutter),)


def _cutter(
    teeth: int, diameter: float, Kt: float, Kn: float, immersion: float, pitch_deg: list[float]
) -> Any:
    from chatterlab.process import Milling

    return Milling.from_immersion(
        teeth, diameter, Kt, Kn, immersion, "down", pitch=tuple(np.radians(pitch_deg))
    )


def milling_lobes_cutter(
    tool: dict[str, float], cutter: dict[str, Any], rpm: list[float], depth_max: float, rtol: float = 1e-8
) -> Out:
    """chatterlab.lobes.milling_lobes on a ToolStructure and a Milling given
    directly (studies/milling_benchmark.py's variable-pitch cutter)."""
    from chatterlab.lobes import milling_lobes

    lead = _tool_args(**tool, cutter=_cutter(**cutter))
    L = milling_lobes(*lead, np.asarray(rpm, float), depth_max=depth_max, rtol=rtol)
    return {**_milling_lobes_out(L), "_lead": lead}


def floquet(model: dict[str, str], points: list[dict[str, float]], method: str, steps: int = 40) -> Out:
    """chatterlab.frequency.multipliers at (rpm, depth) points: the two
    leading multipliers, the critical one's kind, chatter frequency and
    convergence error."""
    from chatterlab.frequency import multipliers

    lead = _milling_args(load(model), False)
    rs = [multipliers(*lead, p["rpm"], p["depth"], method=method, steps=steps) for p in points]  # type: ignore[arg-type]
    return {
        "mu": np.array([r.mu[:2] for r in rs]),
        "kind": np.array([r.kind for r in rs]),
        "error": np.array([r.error for r in rs]),
        "frequency_hz": np.array([r.frequency_hz for r in rs]),
        "_lead": lead,
        "_results": rs,
    }


def milling_simulation(
    tool: dict[str, float],
    cutter: dict[str, Any],
    rpm: float,
    depth: float,
    samples: list[int] | None,
    **kw: Any,
) -> Out:
    """chatterlab.time.simulate_milling on the 1-DOF benchmark tool (its M,
    C, K): the tool point at a few samples, the Poincare samples, the
    multiplier fitted to them and the verdict."""
    from chatterlab.time import simulate_milling

    m, w, z = tool["mass"], 2 * np.pi * tool["f_hz"], tool["zeta"]
    r = simulate_milling(([[m]], [[2 * z * m * w]], [[m * w * w]]), _cutter(**cutter), rpm, depth, **kw)
    return {
        "t": _pick(r.t, samples),
        "x": _pick(r.x, samples),
        "vx": _pick(r.vx, samples),
        "poincare": r.poincare,
        "growth_per_period": float(r.growth_per_period),
        "multiplier": complex(r.multiplier),
        "verdict": str(r.verdict),
        "_result": r,
    }


def measured_lobes(
    frf: dict[str, str],
    rpm: list[float],
    select: list[str] | None = None,
    Kf: float | None = None,
    milling: dict[str, Any] | None = None,
    n_frequencies: int | None = None,
) -> Out:
    """chatterlab.lobes.lobes_measured from a tap-test FRF file: turning (a
    regenerative cut at Kf in the selected direction) or milling (ZOA)."""
    from chatterlab.lobes import lobes_measured
    from chatterlab.model import Process
    from chatterlab.process import Milling

    try:  # 63e1fc1: MeasuredFRF; since 50e6641 the one container chatterlab.structure.FRF
        from chatterlab.structure import MeasuredFRF as Measured  # type: ignore[attr-defined]
    except ImportError:
        from chatterlab.structure import FRF as Measured

    h = Measured.read(frf["path"])
    if select is not None:
        h = h.select(select, select)
    v = np.asarray(rpm, float)
    mill = None if milling is None else Milling.from_immersion(**milling)
    if mill is None:
        d = lobes_measured(
            h, v, process=Process(kind="turning", speed=10000.0), Kf=Kf, n_frequencies=n_frequencies
        )
    else:
        d = lobes_measured(h, v, milling=mill, n_frequencies=n_frequencies)
    return {
        "delay": d.delay,
        "b_lim": d.b_lim,
        "chatter_hz": d.chatter_hz,
        "lobe": d.lobe,
        "minimum_width": d.minimum["width"],
        "band_hz": np.asarray(d.band_hz, float),
        "_frf": h,
        "_milling": mill,
    }


def swept(
    model: dict[str, str],
    quantity: str,
    grid: dict[str, list[float]],
    fixed: dict[str, float],
    width_max: float,
) -> Out:
    """chatterlab.sweep.sweep of a chatter quantity (chatterlab.quantities.QuantityTask,
    serial backend)."""
    from chatterlab.quantities import QuantityTask
    from chatterlab.sweep import Grid, sweep

    m = load(model)
    task = QuantityTask(m, quantity, fixed=fixed, width_max=width_max)
    res = sweep(task, Grid(grid), outputs=task.outputs, backend="serial", progress=False)
    return {**{k: np.asarray(v, float) for k, v in res.data.items()}, "_model": m}


def atlas(model: dict[str, str], positions: list[float], speeds: list[float], width_max: float) -> Out:
    """The stability atlas: b_lim over slide position x speed
    (chatterlab.quantities.AtlasTask through chatterlab.sweep.sweep, serial)."""
    from chatterlab.quantities import AtlasTask
    from chatterlab.sweep import sweep

    m = load(model)
    task = AtlasTask(m, width_max, tuple(float(x) for x in speeds))
    unit = m.process.speed_unit
    res = sweep(
        task, {"position": (np.asarray(positions, float), "m"), "speed": (np.asarray(speeds, float), unit)},
        outputs={"b_lim": "m", "chatter_frequency": "Hz"}, backend="serial", progress=False,
    )  # fmt: skip
    return {**{k: np.asarray(v, float) for k, v in res.data.items()}, "_model": m}


ADAPTERS = {
    f.__name__: f
    for f in (
        lobe_diagram,
        natural_modes,
        response,
        roots,
        simulation,
        milling_lobes_model,
        milling_lobes_cutter,
        floquet,
        milling_simulation,
        measured_lobes,
        swept,
        atlas,
    )  # fmt: skip
}

# ============================================================================ comparison


def resolve(args: dict[str, Any], models: dict[str, dict[str, str]], root: Path) -> dict[str, Any]:
    """The case's recorded arguments with its model (recorded text) and FRF
    file (a path under ``root``) filled in."""
    a = dict(args)
    if "model" in a:
        a["model"] = {"name": a["model"], "text": models[a["model"]]["text"]}
    if "frf" in a:
        a["frf"] = {"name": a["frf"], "path": str(root / a["frf"])}
    return a


def mismatch(got: Any, rec: np.ndarray, tol: np.ndarray | None, mode: str) -> str | None:
    """Why ``got`` does not agree with the recorded ``rec`` (None if it does).

    ``exact``: equal, element by element (NaN equal to NaN);
    ``tol``: the same shape and the same non-finite elements (NaN, +-inf),
    the finite ones within ``tol`` (absolute, per element);
    ``set``: per row, every recorded element has a computed one within its
    ``tol`` (for multipliers, whose order within a conjugate pair is not a
    result)."""
    g = np.asarray(got)
    if g.shape != rec.shape:
        return f"shape {g.shape}, recorded {rec.shape}"
    if mode == "exact":
        same = np.array_equal(g, rec, equal_nan=rec.dtype.kind in "fc")
        return None if same else f"{g.tolist()} != recorded {rec.tolist()}"
    assert tol is not None
    t = np.broadcast_to(tol, rec.shape)
    if mode == "set":
        g2, r2, t2 = (
            g.reshape(-1, rec.shape[-1]),
            rec.reshape(-1, rec.shape[-1]),
            t.reshape(-1, rec.shape[-1]),
        )
        bad = []
        for gi, ri, ti in zip(g2, r2, t2, strict=True):
            for r, tt in zip(ri, ti, strict=True):
                d = float(np.min(np.abs(gi - r)))
                if not d <= tt:
                    bad.append(
                        f"{r}: nearest computed {gi[np.argmin(np.abs(gi - r))]} (|d| {d:.3g} > tol {tt:.3g})"
                    )
        return "; ".join(bad) or None
    fin = np.isfinite(rec)
    nonfin_same = np.array_equal(np.isfinite(g), fin) and np.array_equal(g[~fin], rec[~fin], equal_nan=True)
    if not nonfin_same:
        return f"non-finite elements differ: {g[~fin | ~np.isfinite(g)]} vs recorded {rec[~fin | ~np.isfinite(g)]}"
    d = np.abs(g[fin] - rec[fin])
    ratio = d / np.where(t[fin] > 0, t[fin], np.inf)
    ratio[(d == 0)] = 0.0
    if np.all(ratio <= 1.0):
        return None
    k = int(np.argmax(ratio))
    return (
        f"{int(np.count_nonzero(ratio > 1))} of {d.size} outside the tolerance; worst: {g[fin][k]!r} vs recorded"
        f" {rec[fin][k]!r}, |d| = {d[k]:.3g} > tol {t[fin][k]:.3g}"
    )


#: the condition number the spectral engine's scaled collocation blocks are held near
#: (docs/milling.md, "The monodromy in factored form"; unscaled they reached 1e12)
KAPPA_BLOCKS = 1e4
#: the largest block a factored solve works on (nodes x states of one element, degree <= 48)
BLOCK_SIZE = 64


def factored_roundoff(a: np.ndarray) -> np.ndarray:
    """The round-off of a milling limit on the factored monodromy (issue 26):
    a flip or fold depth is -1/nu for an eigenvalue nu of M = K + Q (X0 - z I)^-1 P,
    built by element-by-element solves with the free structure's collocation
    blocks, not the eigenvalue of the N x N pencil the recording's tolerance
    was derived for (``floquet-limit``: gamma(N) kappa(a)).  The same exact
    depth by other arithmetic: the solves' forward error gamma(BLOCK_SIZE)
    KAPPA_BLOCKS relative, twice (the rules' convention), is added to the
    recorded bound."""
    eps = np.finfo(float).eps / 2
    gamma = BLOCK_SIZE * eps / (1 - BLOCK_SIZE * eps)
    return np.where(np.isfinite(a), 2 * gamma * KAPPA_BLOCKS * np.abs(a), 0.0)


def compare(case: dict[str, Any], out: Out, data: Any) -> list[str]:
    """Every quantity of one case against the recording: the list of failures."""
    fails = []
    for q, spec in case["quantities"].items():
        if q not in out:
            fails.append(f"{q}: not computed by the adapter")
            continue
        tol = data[f"tol/{q}"] if f"tol/{q}" in data.files else None
        if tol is not None and spec["rule"] == "floquet-limit" and q.endswith(("a_lim", "certified")):
            tol = tol + factored_roundoff(np.asarray(data[q], float))
        why = mismatch(out[q], data[q], tol, spec["compare"])
        if why:
            fails.append(f"{q} ({spec['rule']}): {why}")
    return fails


def _manifest() -> dict[str, Any]:
    p = DATA / "manifest.json"  # absent only while the recorder imports the adapters
    return json.loads(p.read_text()) if p.is_file() else {"cases": [], "files": {}, "rules": {}, "models": {}}


MANIFEST = _manifest()
CASES = {c["name"]: c for c in MANIFEST["cases"]}


def test_the_recording_is_there():
    assert (DATA / "manifest.json").is_file() and len(CASES) >= 30, "tests/data/oracle is missing"


def test_inputs_are_the_recorded_ones():
    """The files read from the repository (not recorded with the data) are
    the ones recorded from (SHA-256)."""
    for name, meta in MANIFEST["files"].items():
        digest = hashlib.sha256((ROOT / name).read_bytes()).hexdigest()
        assert digest == meta["sha256"], f"{name} is not the file the oracle was recorded with"


def test_every_quantity_has_a_rule():
    for c in MANIFEST["cases"]:
        for q, spec in c["quantities"].items():
            assert spec["compare"] in ("exact", "tol", "set"), (c["name"], q)
            assert spec["rule"] in MANIFEST["rules"], (c["name"], q, spec["rule"])


@pytest.mark.parametrize("name", list(CASES))
def test_oracle(name):
    case = CASES[name]
    out = ADAPTERS[case["adapter"]](**resolve(case["args"], MANIFEST["models"], ROOT))
    with np.load(DATA / case["file"], allow_pickle=False) as data:
        fails = compare(case, out, data)
    assert not fails, f"{name}: " + "\n  ".join(fails)
