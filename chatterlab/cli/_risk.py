"""``chatterlab risk``: the probabilistic lobe diagram of a model with an
``[uncertainty]`` table -- a lobe diagram per sample on the sweep engine
(workers, dask, checkpoints), the probability of chatter over speed and
width, quantile lobes, P(chatter) at operating points, Sobol' indices and
the operating points below a risk.  Widths in mm, speeds in the process's
unit, probabilities in %."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from ..errors import InputError
from ..io._files import DATA_SUFFIXES, PLOT_SUFFIXES
from ._common import CommandOutputs, load, mm_to_m, model_args, outputs, warn, width_max_m, width_slips
from ._parallel import check_checkpoint, checkpoint, parallel_args, resume_refusal, sweep_opts


def _count(text: str) -> float:
    """A sample count as typed (``1e4`` too), checked by the run."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None


def add_parser(sub: Any) -> None:
    rk = sub.add_parser(
        "risk", help="probabilistic lobes: P(chatter), quantile lobes and Sobol' indices from [uncertainty]"
    )
    model_args(rk)
    rk.add_argument("--speed", type=float, nargs=2, required=True, metavar=("MIN", "MAX"),
                    help="speed range in the process unit")  # fmt: skip
    rk.add_argument("--points", type=int, default=100, help="number of speeds (default 100)")
    rk.add_argument("--width-max", type=float, default=20.0, metavar="B", help="largest width considered, mm")
    rk.add_argument(
        "--widths", type=int, default=200, metavar="N", help="widths of the probability map (200)"
    )
    rk.add_argument("--samples", type=_count, default=1024, metavar="N",
                    help="sample budget (default 1024): R replicates x a power of two")  # fmt: skip
    rk.add_argument("--replicates", type=int, default=8, metavar="R", help="independent randomisations (8)")
    rk.add_argument("--seed", type=int, default=0, help="the run's seed (0)")
    rk.add_argument(
        "--method", choices=["qmc", "mc"], default="qmc", help="scrambled Sobol' (qmc) or Monte Carlo"
    )
    rk.add_argument("--quantiles", type=float, nargs="+", default=[5.0, 50.0, 95.0], metavar="Q",
                    help="levels of the quantile lobes, %% (default 5 50 95)")  # fmt: skip
    rk.add_argument("--point", type=float, nargs=2, action="append", metavar=("SPEED", "WIDTH"),
                    help="operating point: speed (process unit) and width (mm); repeatable")  # fmt: skip
    rk.add_argument(
        "--risk", type=float, metavar="PCT", help="acceptable P(chatter), %%: the safe operating points"
    )
    rk.add_argument("--tol", type=float, metavar="PCT",
                    help="stop when the error of P(chatter) (at the points, else on the map) is at most PCT %%")  # fmt: skip
    rk.add_argument("--level", type=float, default=95.0, metavar="PCT", help="confidence level, %% (95)")
    rk.add_argument("--sensitivity", action="store_true", help="Sobol' indices (k + 2 diagrams per sample)")
    rk.add_argument("--factor", action="append", metavar="NAME=PATTERN[,PATTERN]",
                    help="a Sobol' factor: the fields whose paths match the patterns, e.g. 'tap test=mode.*'")  # fmt: skip
    rk.add_argument("--position", type=float, metavar="S", help="slide position s, m (default: the model's)")
    rk.add_argument("--terms", choices=["pdo", "o"], default=None, help="feedback terms (default pdo)")
    rk.add_argument("--fmin", type=float, help="lowest chatter frequency searched, Hz")
    rk.add_argument("--fmax", type=float, help="highest chatter frequency searched, Hz")
    rk.add_argument(
        "--verify", type=int, default=1, metavar="N", help="argument-principle checks per diagram (1)"
    )
    rk.add_argument("--out", metavar="FILE.nc|FILE.csv")
    rk.add_argument("--plot", metavar="FILE.png", help="the probability map with the quantile lobes")
    rk.add_argument("--plot-sobol", metavar="FILE.png", help="the Sobol' indices (with --sensitivity)")
    parallel_args(rk)


def run(args: argparse.Namespace) -> int:
    with outputs(
        args,
        (args.out, "--out", DATA_SUFFIXES),
        (args.plot, "--plot", PLOT_SUFFIXES),
        (args.plot_sobol, "--plot-sobol", PLOT_SUFFIXES),
    ) as outs:
        check_checkpoint(args, outs)
        return _run(args, outs)


def _pct(value: float, option: str) -> float:
    """A probability typed in % as a fraction, strictly between 0 and 100 %."""
    if not 0 < value < 100:
        raise InputError(f"{option} is a probability in %: it must lie between 0 and 100 (got {value:g})")
    return value / 100.0


def _run(args: argparse.Namespace, outs: CommandOutputs) -> int:
    import shutil

    import numpy as np

    from ..uncertainty import risk
    from ._lobes import speeds

    if args.plot_sobol and not args.sensitivity:
        raise InputError("--plot-sobol draws the Sobol' indices: add --sensitivity")
    model = load(args)
    if model.process is None:
        raise InputError(f"{model.source} has no [process] table: add one so that speeds map to delays")
    v = speeds(args, model.process)
    wmax = width_max_m(args)
    warn(args, width_slips(wmax, "--width-max"))
    if args.widths < 2:
        raise InputError(f"--widths must be >= 2 (got {args.widths})")
    points = [(p[0], mm_to_m(p[1])) for p in args.point or []]
    opts: dict[str, Any] = {
        k: getattr(args, k) for k in ("terms", "fmin", "fmax") if getattr(args, k) is not None
    }
    level = _pct(args.level, "--level")
    risk_level = None if args.risk is None else _pct(args.risk, "--risk")
    eng = sweep_opts(args)
    ck = checkpoint(args)
    with resume_refusal(args):
        res = risk(
            model,
            v,
            width_max=wmax,
            samples=args.samples,
            replicates=args.replicates,
            seed=args.seed,
            method=args.method,
            quantiles=[_pct(q, "--quantiles") for q in args.quantiles],
            widths=np.linspace(wmax / args.widths, wmax, args.widths),
            points=points,
            sensitivity=args.sensitivity,
            factors=_factors(args.factor),
            tol=None if args.tol is None else _pct(args.tol, "--tol"),
            level=level,
            position=args.position,
            verify=args.verify,
            checkpoint=ck,
            resume=args.resume,
            keep_checkpoint=True,
            jobs=eng["jobs"],
            backend=eng["backend"],
            scheduler=eng["scheduler"],
            security=eng["security"],
            progress=eng["progress"],
            **opts,
        )
    if ck is not None and not args.checkpoint and res.n_failed == 0:
        outs.then(lambda: shutil.rmtree(ck, ignore_errors=True))  # once the files below are in place
    print(res.summary())
    if risk_level is not None:
        _recommend(res, risk_level)
    mesh = _mesh(res, model, args, opts)
    if mesh is not None:  # a model with beams: the nominal limit on the mesh twice as fine
        print("\n".join(f"  {ln}" for ln in mesh[0]))
    if args.out:
        if args.out.lower().endswith(".csv"):
            res.to_csv(outs.path(args.out))
        else:
            res.to_netcdf(
                outs.path(args.out),
                attrs={"model_text": model.text, "command": " ".join(sys.argv), **(mesh[1] if mesh else {})},
            )
    if args.plot or args.plot_sobol:
        from ..plot import savefig

        if args.plot:
            savefig(res.plot(risk=risk_level), outs.path(args.plot))
        if args.plot_sobol:
            savefig(res.plot_sensitivity(), outs.path(args.plot_sobol))
    if res.n_contradicted or res.n_failed or res.n_undetermined:
        print(
            f"chatterlab: {res.n_contradicted} sample diagram(s) contradicted by their checks, {res.n_failed}"
            f" failed task(s), {res.n_undetermined} establishing nothing at some speeds: the estimates there"
            " are undetermined (NaN)",
            file=sys.stderr,
        )
        return 1
    return 0


def _factors(items: list[str] | None) -> dict[str, list[str]] | None:
    """``--factor NAME=PATTERN[,PATTERN]`` options as named groups of fields."""
    if not items:
        return None
    out: dict[str, list[str]] = {}
    for it in items:
        name, sep, pats = it.partition("=")
        if not sep or not name.strip() or not pats.strip():
            raise InputError(
                f"--factor {it!r}: write NAME=PATTERN[,PATTERN], e.g. --factor 'tap test=mode.*'"
            )
        out[name.strip()] = [p.strip() for p in pats.split(",") if p.strip()]
    return out


def _recommend(res: Any, risk_level: float) -> None:
    """The tops of the risk lobe: where the widest cut stays below the risk."""
    u = res.speed_unit
    rec = res.recommend(risk_level)
    print(
        f"  operating points with P(chatter) <= {100 * risk_level:g} % (safe side of the {100 * res.level:g} % interval):"
    )
    if not rec:
        print("    none: no speed has a width whose P(chatter) is established at most this")
    for r in rec:
        v = f"{r['speed']:.0f} {u}" if u == "rpm" else f"{r['speed']:.5g} {u}"
        print(
            f"    {v}: width up to {r['width'] * 1e3:.4g} mm (P(chatter) there {r['p_chatter']:.4f},"
            f" at most {min(r['p_chatter_high'], 1.0):.4f})"
        )


def _mesh(res: Any, model: Any, args: argparse.Namespace, opts: dict[str, Any]) -> Any:
    """A model with beams (else None): the nominal model's smallest limit over
    the speeds on the mesh twice as fine (:meth:`Model.with_finer_mesh`; one
    lobe diagram, the samples are not run again) by
    :func:`chatterlab.model._mesh.limit_line` (its change and the bound of its
    error, docs/lobes.md Eq. M3); a line that says the probabilities are
    those of the model's own mesh; and the nominal model at each ``--point``
    judged on both meshes by :func:`chatterlab.model._mesh.width_verdict`
    (its limit at the point's speed on h and h/2).  Returns the summary's
    lines and the netCDF file's ``mesh_*`` attributes."""
    if not model.beams:
        return None
    import json
    import time

    import numpy as np

    from ..lobes import lobes
    from ..model._mesh import MeshEstimate, limit_line, mesh_record, mesh_words, width_verdict

    t0 = time.perf_counter()
    nom = res.nominal
    fine = lobes(model.with_finer_mesh(), nom.speed, width_max=float(nom.width_max), position=args.position,
                 verify=0, **opts)  # fmt: skip
    b, b2 = float(nom.minimum["width"]), float(fine.minimum["width"])
    e = MeshEstimate(b, b2)
    lines = [
        limit_line(model, f"nominal smallest {nom.limit_name}", b, b2),
        f"mesh: the probabilities, quantile lobes and safe points above are those of this mesh ({mesh_words(model)}"
        f" in every sample; not recomputed twice as fine): the nominal limit's error is not in their intervals",
    ]
    verdicts = []
    for sp, w in np.asarray(res.points, float).reshape(-1, 2):
        k = int(np.argmin(np.abs(np.asarray(nom.speed, float) - sp)))
        lim, lim2 = float(nom.b_lim[k]), float(fine.b_lim[k])
        verdict, why = width_verdict(model, float(w), lim, lim2)
        verdicts.append(verdict)
        at = f"{sp:.0f} {nom.speed_unit}" if nom.speed_unit == "rpm" else f"{sp:.5g} {nom.speed_unit}"
        lines.append(
            f"mesh: the nominal model at {at}, {w * 1e3:.4g} mm: {verdict} ({nom.limit_name} {lim * 1e3:.4g} mm"
            f" on this mesh, {lim2 * 1e3:.4g} mm twice as fine; {why.removeprefix('mesh: ')})"
        )
    meta = {
        **mesh_record(model),
        "mesh_fine_nominal_min_m": b2,
        "mesh_nominal_min_change": float(e.relative_change),
        "mesh_nominal_min_error_bound": float(e.relative_bound),
        "mesh_probabilities": "on the coarse mesh",
        "mesh_point_verdicts": json.dumps(verdicts),
        "mesh_seconds": time.perf_counter() - t0,
        "mesh": " | ".join(lines),
    }
    return lines, meta
