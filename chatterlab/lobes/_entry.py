"""The one entry point of the lobe engine: :func:`lobes`.

Whatever the structure and the process -- a model file, a frozen
configuration, a milling closed loop, a measured FRF, a python-control
system -- ``chatterlab.lobes(source, speeds, ...)`` returns the one lobe
result, :class:`~chatterlab.lobes.LobeDiagram`.  Like
:func:`scipy.integrate.solve_ivp`, the route is chosen from what is given
(and ``method=``), and each route takes its own options as keywords; an
option the chosen route does not use is an :class:`~chatterlab.errors.InputError`
naming the options it takes, never silently ignored.

=========================  ==========================================  =====================================
source                     route                                       options
=========================  ==========================================  =====================================
``Model``                  the model's structure and process:          ``position`` and the options of the
                           turning/shaping (D-subdivision), milling    route taken
                           (Floquet; ``method="zoa"``: averaged), a
                           measured FRF in ``[frf]``
``FrozenSystem``           D-subdivision (:mod:`._diagram`)            ``terms``, ``process``, ``fmin``,
                                                                       ``fmax``, ``n_frequencies``,
                                                                       ``verify``, ``couplings``, ``name``,
                                                                       ``mesh_error``
``ClosedLoop`` (milling)   Floquet multipliers or ZOA                  ``method``, ``scan``, ``rtol``,
                           (:mod:`._milling`)                          ``degree``, ``elements``, ``steps``,
                                                                       ``check``
``FRF``                    the measured FRF as the structure           ``process`` or ``milling``, ``fmin``,
                           (:mod:`._measured`)                         ``fmax``, ``n_frequencies``, ``name``
                                                                       and the cut: ``Kf``, ``force_angle``,
                                                                       ``normal_angle``, ``Kv``,
                                                                       ``coordinates`` or ``DP``/``DV``/
                                                                       ``DO``/``width_ref``
``Plant``                  D-subdivision of a given plant              ``process`` (required) and the
                                                                       ``FrozenSystem`` options
python-control LTI         the LTI as the structure (:mod:`._control`) ``process``, ``DO``, ``width_ref``,
                                                                       ``DP``, ``DV``, ``fmin``, ``fmax``,
                                                                       ``name``
=========================  ==========================================  =====================================

``width_max`` is the largest width of cut searched (for milling the axial
depth), m; ``None`` takes the route's default (0.02 m; milling 0.01 m).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from ..errors import InputError
from ..process import ClosedLoop
from ..structure import FRF, FrozenSystem
from ._diagram import lobes as _d_subdivision
from ._plant import Plant
from ._result import LobeDiagram

__all__ = ["lobes"]

_FROZEN = ("terms", "process", "fmin", "fmax", "n_frequencies", "verify", "couplings", "name")
_MESH = (*_FROZEN, "mesh_error")  # a frozen configuration of a model (beams: its mesh error)
_FLOQUET = ("method", "scan", "rtol", "degree", "elements", "steps", "check")
_MEASURED = ("process", "milling", "fmin", "fmax", "n_frequencies", "name", "Kf", "force_angle",
             "normal_angle", "Kv", "coordinates", "DP", "DV", "DO", "width_ref")  # fmt: skip
_LTI = ("process", "DO", "width_ref", "DP", "DV", "fmin", "fmax", "name")


def _only(route: str, given: dict[str, Any], accepted: tuple[str, ...]) -> None:
    bad = sorted(set(given) - set(accepted))
    if bad:
        raise InputError(
            f"lobes ({route}): {', '.join(bad)} {'is' if len(bad) == 1 else 'are'} not an option of this route"
            f" (it takes {', '.join(accepted) or 'no options'})"
        )


def lobes(
    source: Any,
    speeds: Any,
    *,
    width_max: float | None = None,
    position: float | None = None,
    **options: Any,
) -> LobeDiagram:
    """The stability lobe diagram of ``source`` at ``speeds``.

    Parameters
    ----------
    source : Model, FrozenSystem, ClosedLoop, FRF, Plant or python-control LTI
        The structure with (or without, then ``process=``) its process: see
        the table of :mod:`chatterlab.lobes._entry`.
    speeds : array, shape (n,)
        Speeds in the process's unit (shaping: work speed m/s; turning and
        milling: spindle speed rpm; ``kind = "delay"``: the delay in s).
    width_max : float, optional
        Largest width of cut (milling: axial depth) searched, m.
    position : float, optional
        A model's slide position s, m (default: the model's frozen one).
    **options
        The route's options (the table above).

    Returns
    -------
    LobeDiagram
    """
    if isinstance(source, FrozenSystem):
        _only("a frozen configuration", options, _MESH)
        return _d_subdivision(source, speeds, width_max=_w(width_max, 0.02), **options)
    if isinstance(source, Plant):
        _only("a plant", options, _FROZEN)
        if "process" not in options:
            raise InputError("lobes of a plant: give process= (the speed -> delay kinematics)")
        return _d_subdivision(None, speeds, plant=source, width_max=_w(width_max, 0.02), **options)
    if isinstance(source, ClosedLoop):
        if source.process is None:
            raise InputError(
                "lobes of a constant-coefficient closed loop: give its configuration, lobes(loop.frozen, speeds,"
                " terms=..., couplings=...) (the diagram scans the width and the delay of the loop)"
            )
        from ._milling import milling_lobes

        _only("a milling loop", options, _FLOQUET)
        return milling_lobes(source, np.asarray(speeds, float), depth_max=width_max or 0.01, **options)
    if isinstance(source, FRF):
        from ._measured import lobes_measured

        _only("a measured FRF", options, _MEASURED)
        return lobes_measured(source, speeds, width_max=_w(width_max, 0.02), **options)
    from ..model import Model

    if isinstance(source, Model):
        return _model(source, speeds, width_max, position, options)
    if _is_lti(source):
        from ._control import lobes_lti

        _only("a python-control LTI system", options, _LTI)
        return lobes_lti(source, speeds, width_max=_w(width_max, 0.02), **options)
    raise InputError(
        "lobes: source must be a Model, a FrozenSystem (system.at(s)), a milling ClosedLoop"
        f" (milling_loop(...)), a measured FRF, a Plant or a python-control LTI system; got {type(source).__name__}"
    )


def _w(width_max: float | None, default: float) -> float:
    return default if width_max is None else width_max


def _model(model: Any, speeds: Any, width_max: float | None, position: float | None, options: dict) -> Any:
    """A model file's route: its [frf], its milling cutter, or its structure."""
    from ..structure import assemble

    if model.frf is not None:
        from ._measured import lobes_model_frf

        _only("a model with [frf]", options, ("fmin", "fmax", "n_frequencies"))
        if position is not None:
            raise InputError("a measured FRF has one configuration: position= does not apply")
        return lobes_model_frf(model, np.asarray(speeds, float), width_max=_w(width_max, 0.02), **options)
    frozen = assemble(model).at(position)
    if model.process is not None and model.process.kind == "milling" and options.get("method") != "zoa":
        from ._milling_model import model_milling_loop

        loop = model_milling_loop(frozen)[0]  # a structural model: the modes that matter
        mesh_error = bool(options.pop("mesh_error", False))
        d = lobes(loop, speeds, width_max=width_max, **options)
        # a beam tool: its mesh error (lobes._mesh_error), or the word that it was not estimated
        if model.beams:
            from ._mesh_error import not_estimated
            from ._milling_mesh import milling_with_mesh_error

            if mesh_error:
                return milling_with_mesh_error(d, model, position, speeds, **options)
            d = replace(d, meta={**d.meta, **not_estimated(model)})
        return d
    zoa = options.pop("method", None) == "zoa"
    d = lobes(frozen, speeds, width_max=width_max, **options)
    # a milling model's coupling is the time-averaged cut (process.ce_maps): the zeroth-order approximation
    # the averaged loop's limits, so a zoa basis (claim 6: flip lobes not modelled), as milling_lobes gives
    return replace(d, method="zoa", basis=np.full(np.shape(d.b_lim), "zoa")) if zoa else d


def _is_lti(x: Any) -> bool:
    """A python-control LTI system (without importing python-control when it is not)."""
    import sys

    control = sys.modules.get("control")
    return control is not None and isinstance(x, control.LTI)
