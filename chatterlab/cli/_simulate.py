"""``chatterlab simulate``: the Newmark transient of the moving, delayed
closed loop (Eq. 2.28), one run per feedback case (``--feedback all``: the
paper's three cases), with a summary line per recorded output.

Where a new kind of input plugs in: ``_runner`` turns what the command
line names (today: a model file with a cutting process) into a function
``feedback case -> Simulation``; a milling process (periodic coupling) or
another input is a branch there.  The summary, files, plot and exit status
(``run``, ``_report``) are shared by every kind.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal

from ..errors import InputError
from ..io._files import DATA_SUFFIXES, PLOT_SUFFIXES, Outputs
from ._common import load, model_args, outputs, progress_bar, width_m


def add_parser(sub: Any) -> None:
    si = sub.add_parser("simulate", help="Newmark transient of the moving, delayed closed loop (Eq. 2.28)")
    model_args(si)
    si.add_argument(
        "--feedback",
        choices=["none", "pd", "pdo", "all"],
        default="pdo",
        help="paper's cases: none (a), pd = proportional + derivative (b), pdo = + delayed (c), all = the three",
    )
    si.add_argument(
        "--passes", type=int, default=2, help="stroke cycles (or delay periods) simulated (default 2)"
    )
    si.add_argument("--duration", type=float, metavar="S", help="simulated time, s (overrides --passes)")
    si.add_argument(
        "--step",
        type=float,
        metavar="H",
        help="time step, s (default: 1/20 of the highest period below 300 Hz and, for a continuous cut, fine "
        "enough for the chatter band of the characteristic roots)",
    )
    si.add_argument(
        "--integrator",
        choices=["auto", "newmark", "exponential"],
        default="auto",
        help="auto (default): the exponential step map (the exact step map of the delayed loop, order 6, its "
        "step chosen for --rtol) for a continuous cut (--delay, --position or turning) without --step, "
        "newmark (the paper's scheme, every cut) otherwise; or either one by name",
    )
    si.add_argument(
        "--rtol",
        type=float,
        metavar="R",
        help="the exponential integrator's error target, relative to the largest displacement (default 1e-3)",
    )
    si.add_argument(
        "--width",
        type=float,
        metavar="B",
        help="width of cut b, mm (default: the coupling's reference width)",
    )
    g2 = si.add_mutually_exclusive_group()
    g2.add_argument(
        "--speed", type=float, metavar="V", help="work speed (shaping, m/s) or spindle speed (turning, rpm)"
    )
    g2.add_argument(
        "--delay", type=float, metavar="T", help="hold the slide still and cut continuously with delay T, s"
    )
    si.add_argument("--position", type=float, metavar="S", help="hold the slide at s, m (continuous cut)")
    si.add_argument(
        "--output",
        action="append",
        metavar="P.DIR",
        help="time history to record (default: the contact point x, y)",
    )
    si.add_argument("--out", metavar="FILE.nc|FILE.csv")
    si.add_argument("--plot", metavar="FILE.png")
    g4 = si.add_argument_group("initial condition (default: at rest, zero history before t = 0)")
    g4.add_argument(
        "--q0",
        action="append",
        metavar="P.DIR=VALUE",
        help="initial displacement of a point, mm (rad for rz); repeatable. Other coordinates: the static "
        "shape under forces at the named points",
    )
    g4.add_argument(
        "--v0",
        action="append",
        metavar="P.DIR=VALUE",
        help="initial velocity of a point, mm/s (rad/s for rz); repeatable. Other coordinates: the state "
        "right after impulses at the named points",
    )
    g4.add_argument(
        "--history",
        choices=["zero", "constant"],
        default="zero",
        help="displacement before t = 0 read by the delayed term: zero (default) or constant (the --q0 state held)",
    )
    g3 = si.add_argument_group('milling models ([process] kind = "milling")')
    g3.add_argument(
        "--revolutions",
        type=float,
        default=50.0,
        metavar="N",
        help="spindle revolutions simulated (default 50)",
    )
    g3.add_argument(
        "--linear", action="store_true", help="the linearised equation (no tooth leaving the cut)"
    )


def run(args: argparse.Namespace) -> int:
    if args.rtol is not None and (args.integrator == "newmark" or args.step is not None):
        raise InputError(
            "--rtol is the exponential step map's error target: give --rtol or --step, not both, and not"
            " with --integrator newmark"
        )
    model = load(args)
    if model.process is not None and model.process.kind == "milling":
        if args.integrator == "exponential" or args.rtol is not None:
            raise InputError(
                f"{'--rtol' if args.rtol is not None else '--integrator exponential'} is the exponential step"
                " map's, which needs a linear cut with constant coefficients; a milling run integrates with"
                f" Newmark (its teeth enter and leave the cut): drop {'--rtol' if args.rtol is not None else '--integrator'}"
            )
        if args.q0 or args.v0 or args.history != "zero":
            raise InputError(
                "--q0, --v0 and --history apply to cutting-process models; a milling run starts from the "
                "tool point displaced by 1 um, at rest, on the nominal path"
            )
        return _milling(args, model)
    q0 = _named(args.q0, "--q0", "mm")
    v0 = _named(args.v0, "--v0", "mm/s")
    cases: list[Literal["none", "pd", "pdo"]] = (
        ["none", "pd", "pdo"] if args.feedback == "all" else [args.feedback]
    )
    files = [args.out if len(cases) == 1 else _suffixed(args.out, fb) for fb in cases] if args.out else []
    with outputs(
        args, *((f, "--out", DATA_SUFFIXES) for f in files), (args.plot, "--plot", PLOT_SUFFIXES)
    ) as outs:
        simulate_case = _runner(args, model, q0, v0)
        mesh_check = _mesh_checker(args, model)
        sims, contradictions = [], []
        for fb in cases:
            sim = simulate_case(fb)
            sims.append(sim)
            contradictions += _summary(sim, fb)
            mesh_check(sim, fb)
        code = _report(args, outs, sims, files)
    if contradictions:
        # the time domain and the roots of the same frozen system cannot both be right
        print(f"chatterlab: error: {contradictions[0]}", file=sys.stderr)
        return max(code, 1)
    return code


def _milling(args: argparse.Namespace, model: Any) -> int:
    """The milling branch: one run with the tooth leaving the cut (or
    ``--linear``), its verdict from the once-per-period samples."""
    from ._milling import milling_simulation

    with outputs(args, (args.out, "--out", DATA_SUFFIXES), (args.plot, "--plot", PLOT_SUFFIXES)) as outs:
        run = milling_simulation(args, model)
        print(
            f"milling at {run.rpm:g} rpm, a_p = {run.depth * 1e3:g} mm ({'nonlinear' if run.nonlinear else 'linear'},"
            f" {run.steps_per_period} steps per period): {run.verdict}"
        )
        print(f"  {run.reason}")
        damping = run.attrs.get("process_damping", "none")
        if damping != "none":  # the run names the model it ran: each cutting tooth's rubbing or flank
            print(f"  process damping: {damping}")
        said = [f"growth per period {run.growth_per_period:+.5f} (|mu| = {abs(run.multiplier):.5f})"]
        if math.isfinite(run.chatter_frequency):  # none when the samples converge (a periodic motion)
            said.append(f"chatter {run.chatter_frequency:.2f} Hz")
        if math.isfinite(run.fraction_out_of_cut):  # a linear run never leaves the cut
            said.append(f"tooth out of the material {run.fraction_out_of_cut:.1%} of its time in the arc")
        print("  " + ", ".join(said))
        from ._milling import PERTURBATION

        print(
            f"  initial condition: the tool point displaced by {PERTURBATION * 1e6:g} um in x and y, at rest;"
            f" feed per tooth {run.feed * 1e3:g} mm"
        )
        print(f"  {run.message}")
        mesh = _milling_mesh(args, model, run)
        if args.out:
            if args.out.lower().endswith(".csv"):
                run.to_csv(outs.path(args.out))
            else:
                run.to_netcdf(outs.path(args.out), attrs={"model_text": model.text, **mesh})
        if args.plot:
            from ..plot import savefig

            savefig(run.plot(), outs.path(args.plot))
    return 0 if run.status == "ok" else 1


def _milling_mesh(args: argparse.Namespace, model: Any, run: Any) -> dict[str, Any]:
    """A milling model with beams: the linearised cut's Floquet verdict at the
    run's (a_p, rpm) on its mesh and on the mesh twice as fine
    (:func:`chatterlab.cli._mesh_checks.milling_run_check`), printed; its
    facts as the netCDF attributes ``mesh_*``.  Without beams: {} and
    nothing printed."""
    if not model.beams:
        return {}
    from ._mesh_checks import milling_run_check

    facts, lines = milling_run_check(model, run, args.position)
    for line in lines:
        print(line)
    return facts


def _named(values: list[str] | None, option: str, unit: str) -> dict[str, float] | None:
    """``P.DIR=VALUE`` options (mm or mm/s; rad or rad/s for ``rz``) as
    ``{"P.DIR": value in m, m/s, rad or rad/s}``, checked."""
    if not values:
        return None
    out: dict[str, float] = {}
    for item in values:
        name, eq, text = item.partition("=")
        name = name.strip()
        if not eq or not name:
            raise InputError(
                f"{option} {item!r}: expected P.DIR=VALUE with VALUE in {unit}, e.g. {option} tip.x=0.01"
            )
        try:
            value = float(text)
        except ValueError:
            raise InputError(f"{option} {item!r}: {text!r} is not a number ({unit})") from None
        if not math.isfinite(value):
            raise InputError(f"{option} {item!r}: the value must be finite")
        if name in out:
            raise InputError(f"{option}: {name} is given twice")
        out[name] = value if name.endswith(".rz") else value * 1e-3
    return out


def _runner(
    args: argparse.Namespace,
    model: Any,
    q0: dict[str, float] | None = None,
    v0: dict[str, float] | None = None,
) -> Callable[[str], Any]:
    """The model of the command line as ``feedback case -> Simulation``."""
    from ..structure._assembly import assemble
    from ..time import Initial, Integration, simulate

    sy = assemble(model)
    width = width_m(args) if args.width is not None else None
    initial = Initial(q0=q0, v0=v0, history="constant" if args.history == "constant" else None)

    def simulate_case(fb: Any) -> Any:
        roots = _frozen_roots(sy, fb, width, args)
        integration = Integration(
            duration=args.duration,
            periods=args.passes,
            step=args.step,
            progress=None if args.quiet else progress_bar(f"simulate ({fb})"),
            integrator=args.integrator,
            **({} if args.rtol is None else {"rtol": args.rtol}),
        )
        return simulate(
            sy,
            feedback=fb,
            width=width,
            speed=args.speed,
            delay=args.delay,
            position=args.position,
            outputs=args.output,
            roots=roots,
            integration=integration,
            initial=initial,
        )

    return simulate_case


def _mesh_checker(args: argparse.Namespace, model: Any) -> Callable[[Any, str], None]:
    """A model with beams: ``(run, feedback case) -> None`` printing the
    verdict of the run's frozen system on its mesh and on the mesh twice as
    fine -- :func:`chatterlab.frequency.stability` on both and
    :func:`chatterlab.frequency.mesh_checked`, the one verdict rule of
    ``roots`` -- and putting the facts in the run's ``meta`` (its netCDF
    attributes ``mesh_*``, :func:`chatterlab.cli._mesh_checks.simulate_check`).
    Without beams: does nothing (the output is unchanged)."""
    if not model.beams:
        return lambda sim, fb: None
    from ..frequency._stability import mesh_checked, stability
    from ..structure._assembly import assemble
    from ._mesh_checks import simulate_check, simulate_lines

    systems: list[Any] = []
    # the width the run used: --width, else the cut's reference width (time._simulate._check_run)
    width = width_m(args) if args.width is not None else model.couplings[0].width_ref

    def check(sim: Any, fb: str) -> None:
        st = None
        if sim.roots is not None:  # a continuous cut: a frozen system (a moving slide has none)
            if not systems:
                systems.extend([assemble(model), assemble(model.with_finer_mesh())])
            kw = {"width": width, "speed": args.speed, "delay": args.delay, "terms": fb, "count": ROOTS_COUNT}
            coarse, fine = (stability(sy.at(args.position), **kw) for sy in systems)
            st = mesh_checked(coarse, fine, model)
        facts = simulate_check(model, st)
        sim.meta.update(facts)
        for line in simulate_lines(facts):
            print(line)

    return check


#: characteristic roots computed for a continuous cut: enough to hold the
#: relevant ones of a short run (the step rule says when they are all relevant)
ROOTS_COUNT = 12


def _frozen_roots(sy: Any, fb: Any, width: float | None, args: argparse.Namespace) -> Any:
    """The rightmost characteristic roots of the frozen system a continuous
    cut integrates (the same matrices, :func:`chatterlab.time._simulate.constant_loop`),
    in the band the loop's gain bound certifies; None for a moving slide."""
    from ..frequency import characteristic_roots, make_system
    from ..time._simulate import constant_loop

    mats = constant_loop(
        sy, feedback=fb, width=width, speed=args.speed, delay=args.delay, position=args.position
    )
    if mats is None:
        return None
    A, B, C, G, T = mats
    try:
        ds = make_system(A, B, C, DO=G, tau=T if G is not None else None)
    except InputError:  # e.g. a mass matrix that is not symmetric: no roots to show
        return None
    return characteristic_roots(ds, count=ROOTS_COUNT)


def _summary(sim: Any, fb: str) -> list[str]:
    """The printed summary of one run: its message, a line per output, the
    rightmost root of the same frozen system beside the time-domain rates
    and, when the run is too short for a spectrum or a growth rate, what
    could not be estimated, the initial condition and how to ask for more.
    Returns the contradictions between the time domain and the roots."""
    import numpy as np

    print(f"feedback {fb}: {sim.message}")
    short: dict[str, str] = {}
    contradictions: list[str] = []
    for name in sim.data:
        line, missing = _history(sim, name, contradictions)
        print(line)
        for what, why in missing.items():
            short.setdefault(what, why)
    if sim.in_cut.all():
        print(f"  step: {sim.meta.get('step_rule', 'given')}")
    if sim.meta.get("process_damping", "none") != "none":
        print(f"  process damping: {sim.meta['process_damping']}")
    if sim.roots is not None and sim.roots.size:
        z = sim.roots[0]
        print(
            f"  roots of the frozen system: rightmost {z.real:+.4g} 1/s at {abs(z.imag) / (2 * np.pi):.2f} Hz"
            + (" (every root right of it found: certified band)" if sim.roots_certain else " (not certified)")
        )
    from ..time._initial import AT_REST

    if short or not any(np.any(x) for x in sim.data.values()) or _initial_condition(sim) != AT_REST:
        print(f"  initial condition: {_initial_condition(sim)}")
    if short:
        print("  too short to estimate " + "; ".join(f"the {w} ({why})" for w, why in short.items()))
        print(
            f"  ask for a longer run with --duration S (this run: {sim.t[-1]:.3g} s) or, without --duration,"
            f" --passes N (the delay T is {sim.delay:.3g} s)"
        )
    if sim.status != "ok":
        print(f"  status: {sim.status}", file=sys.stderr)
    return contradictions


def _report(args: argparse.Namespace, outs: Outputs, sims: list[Any], files: list[str]) -> int:
    """--out files, --plot and the exit status of the runs."""
    for sim, out in zip(sims, files, strict=bool(files)):  # no --out: no files
        if out.lower().endswith(".csv"):
            sim.to_csv(outs.path(out))
        else:
            sim.to_netcdf(outs.path(out))
    if args.plot:
        _plot(sims, outs.path(args.plot))
    if any(s.status == "interrupted" for s in sims):
        print("chatterlab: interrupted: the partial time histories above were kept", file=sys.stderr)
        return 130
    return 0 if all(s.status == "ok" for s in sims) else 1


def _plot(sims: list[Any], path: str) -> None:
    """One run: histories of the first two outputs over the spectrum of the
    first; several (``--feedback all``): one column per case, shared y axes."""
    import matplotlib.pyplot as plt

    from ..plot import plot_cases, plot_histories, plot_spectra, savefig

    names = list(sims[0].data)[:2]
    if len(sims) > 1:
        savefig(plot_cases(sims, names), path)
        return
    fig, axs = plt.subplots(len(names) + 1, 1, figsize=(8.5, 2.6 * (len(names) + 1) + 0.5))
    plot_histories(sims, names, ax=axs[: len(names)], against="time")
    plot_spectra(sims, names[0], ax=axs[-1])
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


#: periods of a component the last cut must hold for its spectral peak: the
#: Hann window's main lobe spans 2 bins either side, so a peak at bin >= 4
#: (f >= 4 / L for a cut of length L) lies clear of the lobe of the removed mean
SPECTRUM_PERIODS = 4


def _history(sim: Any, name: str, contradictions: list[str]) -> tuple[str, dict[str, str]]:
    """One printed line per recorded output: mean, peak-to-peak and spectral
    peak of the last cut and, for a continuous cut, the verdict of its
    envelope with its error bar (:meth:`Simulation.verdict`) -- or, for a
    run that diverged, how large the response grew and when (a mean of a
    blown-up history means nothing) -- and what a run too short could not
    estimate (estimate -> why).  A verdict that contradicts the roots is
    appended to ``contradictions``."""
    import numpy as np

    x = sim.data[name]
    unit, scale = ("rad", 1.0) if sim.units.get(name) == "rad" else ("um", 1e6)
    if sim.status == "diverged" or not np.all(np.isfinite(x)):
        fin = np.abs(x[np.isfinite(x)])
        peak = f"largest |value| {fin.max() * scale:.3g} {unit}" if fin.size else "no finite value"
        if sim.in_cut.all() and sim.status == "diverged":
            v = sim.verdict(name)
            if v.contradiction:
                contradictions.append(v.contradiction)
        return f"  {name:10s} {peak} up to t = {sim.t[-1]:.6g} s (no mean or spectrum: the run diverged)", {}
    if not np.any(x):
        return f"  {name:10s} identically 0 (nothing excited it: no mean, spectrum or growth to show)", {}
    m = sim.window("last-cut")
    missing: dict[str, str] = {}
    fp, why = _spectral_peak(sim, name, m)
    if why:
        missing["spectrum"] = why
    line = (
        f"  {name:10s} mean {x[m].mean() * scale:9.3f} {unit}   peak-to-peak {(x[m].max() - x[m].min()) * scale:8.3f} {unit}"
        + (f"   main spectral peak {fp:7.2f} Hz" if not why else "   main spectral peak     n/a")
    )
    if sim.in_cut.all():  # a continuous cut: the envelope's growth rate is meaningful
        from ..errors import InputError

        try:
            v = sim.verdict(name)
        except InputError as exc:  # fewer samples than the estimator needs
            missing["envelope growth"] = str(exc)
            return line + "   envelope: not estimated", missing
        line += f"   envelope: {v.summary()}"
        if v.classification == "undetermined" and not math.isfinite(v.decide_step):
            missing["envelope growth"] = v.message  # the fit decides nothing: a longer run
        if v.contradiction:
            contradictions.append(v.contradiction)
    return line, missing


def _spectral_peak(sim: Any, name: str, m: Any) -> tuple[float, str]:
    """The main spectral peak above 1 Hz of the last cut, Hz, or why there is
    none: a cut shorter than SPECTRUM_PERIODS periods of it."""
    t = sim.t[m]
    length = float(t[-1] - t[0]) if t.size > 1 else 0.0
    why = f"the last cut lasts {length:.3g} s, fewer than {SPECTRUM_PERIODS} periods of any component" + (
        f" below {SPECTRUM_PERIODS / length:.4g} Hz" if length > 0 else ""
    )
    if t.size < 4:
        return float("nan"), why
    f, a = sim.spectrum(name)
    sel = f > 1.0
    fp = f[sel][int(a[sel].argmax())] if sel.any() else float("nan")
    if not fp * length >= SPECTRUM_PERIODS:
        return fp, why
    return fp, ""


def _initial_condition(sim: Any) -> str:
    """The initial state the run started from (``--q0``, ``--v0``,
    ``--history``; by default at rest, with a zero history before t = 0)."""
    return str(sim.meta.get("initial_condition", "at rest (q = 0, v = 0, zero delay history before t = 0)"))


def _suffixed(path: str, tag: str) -> str:
    p = Path(path)
    return str(p.with_name(f"{p.stem}_{tag}{p.suffix}"))
