"""What the design commands (``chatterlab sensitivity``, ``absorber``,
``active``) share: the speed range and the lobe options they take, the model
they refuse (no process, milling), the speeds and the width ceiling, the
result written to ``--out`` and ``--plot``, and the status of a design whose
lobes failed an argument-principle check."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from ..errors import InputError
from ._common import load, warn, width_max_m, width_slips


def speed_args(p: argparse.ArgumentParser) -> None:
    """``--speed MIN MAX`` (required) and ``--points``."""
    p.add_argument(
        "--speed",
        type=float,
        nargs=2,
        required=True,
        metavar=("MIN", "MAX"),
        help="speed range in the process unit",
    )
    p.add_argument("--points", type=int, default=300, help="number of speeds (default 300)")


def objective_arg(p: argparse.ArgumentParser) -> None:
    """``--objective minimum|absolute``."""
    p.add_argument(
        "--objective",
        choices=["minimum", "absolute"],
        default="minimum",
        help="maximise the minimum b_lim over the speed range (default) or the absolute minimum over all speeds",
    )


def lobe_args(p: argparse.ArgumentParser, *, verify: bool = True) -> None:
    """``--position``, ``--width-max`` (mm) and, for a design whose lobes are
    checked, ``--verify``."""
    p.add_argument("--position", type=float, metavar="S", help="slide position s, m (default: the model's)")
    p.add_argument(
        "--width-max", type=float, default=20.0, metavar="B", help="largest width considered, mm (default 20)"
    )
    if verify:
        p.add_argument(
            "--verify",
            type=int,
            default=16,
            metavar="N",
            help="argument-principle checks of the lobes (default 16)",
        )


def lobe_model(args: argparse.Namespace, milling: str) -> Any:
    """The model of ``args``, refused in one line without a ``[process]`` or
    for milling (``milling``: why, after "is a milling model: ")."""
    model = load(args)
    if model.process is None:
        raise InputError(f"{model.source} has no [process] table: add one so that speeds map to delays")
    if model.process.kind == "milling":
        raise InputError(f"{model.source} is a milling model: {milling}")
    return model


def speeds_and_ceiling(args: argparse.Namespace, model: Any) -> tuple[Any, float]:
    """The speeds of ``--speed``/``--points`` and the ceiling ``--width-max``
    in metres (warned when it slips below the lobes' floor)."""
    from ._lobes import speeds

    v = speeds(args, model.process)
    wmax = width_max_m(args)
    warn(args, width_slips(wmax, "--width-max"))
    return v, wmax


def refuse_json(args: argparse.Namespace, what: str) -> None:
    """A result written only as CSV or netCDF: ``--out X.json`` refused."""
    if args.out and args.out.lower().endswith(".json"):
        raise InputError(f"--out: write {what} as .csv or .nc (not JSON)")


def verified_status(verified: bool | None, what: str) -> int:
    """1 (with a line on stderr) when ``what``'s lobes failed an
    argument-principle check, else 0."""
    if verified is False:
        print(f"chatterlab: {what}'s lobes failed an argument-principle check", file=sys.stderr)
        return 1
    return 0


# ----------------------------------------------------------------------------- the mesh
def fine_objective(model: Any, speeds: Any, objective: str, position: Any, width_max: float) -> float:
    """The design objective of ``model`` on the mesh twice as fine
    (:meth:`Model.with_finer_mesh`): its lobes (actuators included,
    :func:`chatterlab.design.design_lobes`) polished to the minimum over the
    speeds or the absolute minimum as the design polishes its own
    (:func:`chatterlab.design.limits_of`); inf: none below ``width_max``."""
    from ..design import design_lobes, limits_of, loop_matrices
    from ..structure import assemble

    fine = model.with_finer_mesh()
    d = design_lobes(assemble(fine).at(position), speeds, width_max=width_max, verify=0)
    L = loop_matrices(fine, position=position, speeds=speeds)
    lim = limits_of(d, L, speeds=False)
    cp = lim.minimum if objective == "minimum" else lim.absolute
    return float(cp.b) if cp is not None else float("inf")


def design_mesh(
    bare: Any, designed: Any, width: float, bare_width: float, objective: str, speeds: Any,
    position: Any, width_max: float, what: str,
) -> tuple[list[str], dict[str, Any]] | None:  # fmt: skip
    """A design's discretisation error (None for a model without beams): the
    objective without (``bare``) and with the design (``designed``, the same
    absorbers or gains: the design is tuned on h, not again) on the mesh
    twice as fine, each by :func:`chatterlab.model._mesh.limit_line`, and
    whether the gain width / bare_width holds: the gain is a result of the
    mesh like any other, so its error on h is bounded by twice its change on
    h/2 (docs/lobes.md, Eq. M3); the design is said to help when the gain is
    above 1 on h/2 and its lower bound on h, gain - bound, is above 1 too.
    Returns the summary's lines and the files' ``mesh_*`` attributes."""
    import math
    import time

    from ..model._mesh import MeshEstimate, converged_tail, limit_line, mesh_record, pct

    if not designed.beams:
        return None
    t0 = time.perf_counter()
    fine_bare = fine_objective(bare, speeds, objective, position, width_max)
    fine_width = fine_objective(designed, speeds, objective, position, width_max)
    name = "minimum" if objective == "minimum" else "absolute minimum"
    lines = [
        limit_line(designed, f"{name} without the {what}", bare_width, fine_bare),
        limit_line(designed, f"{name} with the {what}", width, fine_width),
    ]
    meta: dict[str, Any] = {
        **mesh_record(designed),
        "mesh_fine_width_m": fine_width,
        "mesh_fine_bare_width_m": fine_bare,
        "mesh_width_error_bound": float(MeshEstimate(width, fine_width).relative_bound),
        "mesh_bare_width_error_bound": float(MeshEstimate(bare_width, fine_bare).relative_bound),
    }
    finite = all(math.isfinite(x) and x > 0 for x in (width, bare_width, fine_width, fine_bare))
    if finite:
        g, g2 = float(width / bare_width), float(fine_width / fine_bare)
        e = MeshEstimate(g, g2)
        low = g - float(e.bound)
        helps = g2 > 1 and low > 1
        lines.append(
            f"mesh: the gain x {g:.3g} is x {g2:.3g} on the mesh twice as fine with the same {what}"
            f" ({pct(float(e.relative_change), '+')}); its discretisation error <= {pct(float(e.relative_bound))}"
            + (
                f": the {what} help on both meshes, by at least x {low:.3g}"
                if helps
                else f": that the {what} help is not established{converged_tail(designed)}"
            )
        )
        meta.update({"mesh_gain": g, "mesh_fine_gain": g2, "mesh_gain_error_bound": float(e.relative_bound),
                     "mesh_gain_holds": "true" if helps else "undetermined"})  # fmt: skip
    else:
        above = math.isinf(width) and math.isinf(fine_width) and 0 < bare_width and math.isfinite(fine_bare)
        lines.append(
            f"mesh: the {what} lift the {name} above the ceiling on both meshes: the gain is more than"
            f" x {width_max / bare_width:.3g} on this mesh and x {width_max / fine_bare:.3g} on the one twice as fine"
            if above
            else "mesh: no estimate of the gain's error (a minimum at the ceiling on one mesh only, or none)"
        )
        meta["mesh_gain_holds"] = "true" if above else "undetermined"
    meta["mesh_seconds"] = time.perf_counter() - t0
    meta["mesh"] = " | ".join(lines)
    return lines, meta


def with_attributes(result: Any, attrs: dict[str, Any]) -> Any:
    """``result`` written with more global attributes (the ``mesh_*`` of
    :func:`design_mesh`): ``attrs`` added to its netCDF and JSON attributes,
    its CSV and plot its own."""
    from ..io import Result

    class _WithAttributes(Result):
        def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
            coords, data, a = result.dataset_parts()
            return coords, data, {**a, **attrs}

        def to_csv(self, path: Any) -> Any:
            return result.to_csv(path)

        def plot(self, *a: Any, **k: Any) -> Any:
            return result.plot(*a, **k)

    return _WithAttributes()
