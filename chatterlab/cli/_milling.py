"""The milling branches of ``lobes``, ``roots`` and ``simulate``.

A model whose ``[process]`` is ``kind = "milling"`` (docs/model-format.md)
is analysed with its periodic directional matrices, not their average:

* ``lobes``: the limit axial depth a_lim against rpm by the spectral-element
  Floquet method (default), first-order semi-discretisation (``--method
  sdm --steps M``) or the zeroth-order approximation (``--method zoa``,
  the averaged matrix through the D-subdivision engine), Hopf and flip
  lobes told apart;
* ``roots``: the Floquet multipliers at (``--width`` a_p, ``--speed`` rpm),
  the critical one with its type and the convergence check;
* ``simulate``: the Newmark solution with the tooth leaving the cut
  (``--linear`` for the linearised equation), with a Poincare verdict.

Widths (axial depths) are typed and printed in mm, speeds in rpm, as for
every command.  A structural model is reduced to the modes that matter
(:func:`chatterlab.lobes.reduce_structure`) and the reduction and its
tool-point FRF error are printed.
"""

from __future__ import annotations

import argparse
from typing import Any

from ..errors import InputError, check_count

#: initial displacement of the tool point in x and y of a milling simulation, m
PERTURBATION = 1e-6

__all__ = ["milling_lobe_args", "milling_lobes", "milling_verdict", "milling_simulation"]


def milling_lobe_args(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group('milling models ([process] kind = "milling", docs/milling.md)')
    g.add_argument(
        "--method",
        choices=["spectral", "sdm", "zoa"],
        help="Floquet by spectral elements (default), semi-discretisation, or the zeroth-order approximation",
    )
    g.add_argument("--steps", type=int, default=40, metavar="M", help="sdm: steps per period (default 40)")
    g.add_argument(
        "--scan",
        type=int,
        default=40,
        metavar="N",
        help="depths scanned up to --width-max before refining (default 40)",
    )


def _typed(option: str) -> bool:
    """Whether ``option`` (or an abbreviation argparse accepts) is on the
    command line being run: an option left at its default is not."""
    from ._main import _ARGV

    for tok in _ARGV:
        head = tok.split("=", 1)[0]
        if len(head) > 2 and head.startswith("--") and option.startswith(head):
            return True
    return False


def refuse_unused(args: argparse.Namespace, method: str) -> None:
    """An option that the chosen milling route ignores is refused, not
    accepted silently: ``--steps`` is semi-discretisation's (``--method
    sdm``), ``--scan`` the Floquet depth scan's (spectral, sdm; the
    zeroth-order approximation scans no depth)."""
    if method != "sdm" and _typed("--steps"):
        raise InputError(
            f"--steps is the number of semi-discretisation steps (--method sdm); the {method} method"
            " does not use it: drop --steps or add --method sdm"
        )
    if method == "zoa" and _typed("--scan"):
        raise InputError(
            "--scan is the depth scan of the Floquet methods (spectral, sdm); the zeroth-order"
            " approximation (--method zoa) scans no depth: drop --scan"
        )


def _speeds(rpm: Any, option: str) -> None:
    """Every spindle speed within the accepted range, named by its option."""
    import numpy as np

    from ..process._milling import check_spindle_speed

    for v in np.atleast_1d(np.asarray(rpm, dtype=float)).tolist():
        check_spindle_speed(v, option)


def _helix_cost(mill: Any, depth: float) -> None:
    """The helix's cost estimate at the deepest cut searched, before the work."""
    if mill.helix > 0:
        mill.lag_angle(depth)


def _structure(
    model: Any, position: float | None, args: argparse.Namespace | None = None
) -> tuple[Any, Any, str]:
    from ..lobes._milling_model import model_milling_loop
    from ..structure._assembly import assemble

    S, info = model_milling_loop(assemble(model).at(position))  # a structural model: the modes that matter
    return S, S.milling, "" if info is None else info.note()


def milling_lobes(args: argparse.Namespace, model: Any, rpm: Any, wmax: float | None) -> Any:
    """``lobes`` on a milling model: :func:`chatterlab.lobes.milling_lobes`
    (``wmax`` None: the ceiling from the problem), with a progress bar and
    --jobs processes over the speeds (default: 2 from 40 speeds up)."""
    from ..lobes._milling import milling_lobes as compute
    from ._common import progress_bar

    for opt, val in (
        ("--positions", args.positions),
        ("--confirm", args.confirm or None),
        ("--terms o", args.terms == "o" or None),
    ):
        if val is not None:
            raise InputError(
                f"{opt} is not available for milling models (the Floquet lobes are one configuration, all terms)"
            )
    method: Any = args.method or "spectral"
    refuse_unused(args, method)
    _speeds(rpm, "--speed")
    S, mill, note = _structure(model, args.position, args)
    why = ""
    if wmax is None:
        from ..lobes._milling import milling_ceiling

        wmax, why = milling_ceiling(S, rpm)
    _helix_cost(mill, wmax)
    if note:
        print(note)
    jobs = args.jobs if args.jobs != 2 else (2 if len(rpm) >= 40 else 1)
    ml = compute(
        S, rpm, method=method, depth_max=wmax, scan=check_count(args.scan, "--scan", 2),
        steps=check_count(args.steps, "--steps", 2), jobs=jobs,
        progress=None if getattr(args, "quiet", False) else progress_bar(f"milling lobes ({len(rpm)} speeds)"),
    )  # fmt: skip
    if why:
        import dataclasses

        ml = dataclasses.replace(ml, meta={**ml.meta, "ceiling": why + " (--width-max sets it)"})
    if model.beams and method != "zoa" and getattr(args, "no_mesh_check", False):
        import dataclasses

        from ._common import unchecked_mesh

        ml = dataclasses.replace(ml, meta={**ml.meta, **unchecked_mesh(model)})
    elif model.beams and method != "zoa":
        # the same limits on the mesh twice as fine: the smallest, and every claim of none below the ceiling
        kw = {"method": method, "depth_max": wmax, "scan": check_count(args.scan, "--scan", 2),
              "steps": check_count(args.steps, "--steps", 2)}  # fmt: skip
        from ..lobes._milling_mesh import milling_with_mesh_error

        ml = milling_with_mesh_error(ml, model, args.position, rpm, **kw)
    return ml


class _MultiplierTable:
    """``roots`` output for a milling cut: the multipliers (the first
    ``count``), the reduction note, and the one ``roots`` JSON contract
    (:meth:`chatterlab.frequency.Multipliers.to_dict`)."""

    def __init__(self, r: Any, count: int, note: str, mesh: dict[str, Any] | None = None) -> None:
        self.r, self.count, self.note, self.mesh = r, count, note, mesh or {}

    def undetermined(self) -> bool:
        """|mu| within its own convergence error of 1, or (a tool with beams)
        the mesh twice as fine does not confirm the verdict: neither claim is
        proven."""
        return bool(self.r.verdict == "undetermined" or self.mesh.get("verdict") == "undetermined")

    def verdict(self) -> str:
        if self.mesh.get("verdict") == "undetermined" and self.r.verdict != "undetermined":
            return (
                f"undetermined: on this mesh {self.r.verdict_line()}, not confirmed on the mesh twice as fine"
            )
        return str(self.r.verdict_line())

    def table(self) -> str:
        import numpy as np

        from ..frequency._floquet import classify

        r = self.r
        lines = [
            f"Floquet multipliers ({r.method}, {r.resolution}) at a_p = {r.depth * 1e3:g} mm, {r.rpm:g} rpm"
            f" (period {r.period * 1e3:.6g} ms)"
        ]
        if self.note:
            lines.append(self.note)
        lines.append("    |mu|        arg mu [deg]   type")
        for mu in r.mu[: self.count]:
            lines.append(f"  {abs(mu):10.6f}  {np.degrees(np.angle(mu)):12.4f}   {classify(complex(mu))}")
        lines.append(f"critical: {self.verdict()}; chatter frequency {r.frequency_hz:.2f} Hz")
        if self.mesh:
            lines.append(self.mesh["line"])
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        d = self.r.to_dict()
        d["roots"] = d["roots"][: self.count]
        d["multipliers"] = d["multipliers"][: self.count]
        d["reduction"] = self.note
        if self.mesh:
            d["verdict"] = self.mesh["verdict"]
            d["mesh"] = dict(self.mesh)
        return d


def milling_verdict(args: argparse.Namespace, model: Any) -> Any:
    """``roots`` on a milling model: the Floquet multipliers at (a_p, rpm)."""
    from ..frequency._floquet import multipliers
    from ._common import width_m

    if args.delay is not None:
        raise InputError(
            "milling: give the spindle speed with --speed RPM (the delays follow from the pitch)"
        )
    method = args.method or "spectral"
    refuse_unused(args, method)
    rpm = args.speed if args.speed is not None else model.process.speed
    _speeds(rpm, "--speed" if args.speed is not None else f"{model.source}: [process] rpm")
    a = width_m(args)
    S, mill, note = _structure(model, args.position, args)
    _helix_cost(mill, a)
    r = multipliers(S, float(rpm), a, method="sdm" if method == "sdm" else "spectral", steps=args.steps)
    mesh: dict[str, Any] = {}
    if model.beams:  # the same cut on the mesh twice as fine (docs/milling.md, "The beam mesh")
        S2, _, _ = _structure(model.with_finer_mesh(), args.position, args)
        r2 = multipliers(S2, float(rpm), a, method="sdm" if method == "sdm" else "spectral", steps=args.steps)
        mesh = _mesh_facts(model, r, r2)
    return _MultiplierTable(r, args.count, note, mesh)


def _mesh_facts(model: Any, r: Any, r2: Any) -> dict[str, Any]:
    """The verdict of a milling cut of a tool with beams on h and h/2 judged
    by :func:`chatterlab.model._mesh.mesh_verdict` on the Floquet exponent
    ln|mu| / T (1/s, T the multipliers' period: the margin's analogue of a
    root's real part), as ``roots`` judges a continuous cut."""
    import math

    from ..model._mesh import MeshEstimate, mesh_record, mesh_verdict

    def margin(x: Any) -> float:
        rho = float(x.spectral_radius)
        return math.log(rho) / float(x.period) if rho > 0 else -math.inf

    a_h, a_h2 = margin(r), margin(r2)
    verdict, line = mesh_verdict(model, str(r.verdict), a_h, str(r2.verdict), a_h2)
    return {
        **mesh_record(model, prefix=""),
        "coarse_verdict": str(r.verdict),
        "fine_verdict": str(r2.verdict),
        "abscissa_per_s": a_h,
        "fine_abscissa_per_s": a_h2,
        "abscissa_error_bound_per_s": float(MeshEstimate(a_h, a_h2).bound),
        "verdict": verdict,
        "line": line,
    }


def milling_simulation(args: argparse.Namespace, model: Any) -> Any:
    """``simulate`` on a milling model: :func:`chatterlab.time.simulate_milling`."""
    import numpy as np

    from ..lobes._milling_model import milling_of
    from ..structure._assembly import assemble
    from ..time import Initial, Integration
    from ..time._milling import model_indentation, simulate_milling
    from ._common import width_m

    if args.width is None:
        raise InputError("milling: give the axial depth of cut with --width A_P (mm)")
    if args.delay is not None:
        raise InputError(
            "milling: give the spindle speed with --speed RPM (the delays follow from the pitch)"
        )
    if not args.linear and model.process.milling.feed_per_tooth <= 0:
        raise InputError(
            f"{model.source}: [process] feed_per_tooth is 0, so the teeth cut no chip and a nonlinear run"
            " shows only free vibration (its 'stable' would prove nothing): give feed_per_tooth, or --linear"
        )
    fz = assemble(model).at(args.position)
    cm = [c for c in fz.couplings() if c.coupling.kind == "milling"]
    if len(cm) != 1:
        raise InputError(f'{model.source}: simulate takes one model = "milling" coupling')
    P = np.asarray(cm[0].J, dtype=float)[:2]
    cut = model.process.milling
    # a run at rest with no feed would never be excited, and its "stable" would prove nothing: start
    # from the tool point displaced by PERTURBATION in x and y (printed with the verdict)
    q0 = np.linalg.pinv(P) @ np.full(2, PERTURBATION)
    pd = model.process_damping
    return simulate_milling(
        (fz.A, fz.B, fz.C),
        milling_of(model),
        float(args.speed if args.speed is not None else model.process.speed),
        width_m(args),
        feed=cut.feed_per_tooth,
        nonlinear=not args.linear,
        tool_point=P,
        runout=cut.runout or None,
        integration=Integration(periods=args.revolutions),
        initial=Initial(q0=q0),
        # the model's table: its indentation model (K_sp, wear land, clearance) per tooth, or its linear C_pd
        C_pd=None if pd is None or pd.indentation else pd.C_pd,
        indentation=model_indentation(model),
    )
