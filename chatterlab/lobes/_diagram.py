"""Stability lobes by D-subdivision in the coupling-element coordinates.

On the stability boundary a characteristic root sits on the imaginary axis,
s = j w.  With the cutting process D(s) = -(b/b_ref) J^T Dl(s) J and the
structure's FRF between the CE coordinates H(jw) = J G(jw) J^T, Sylvester's
identity turns det Delta(jw) = 0 into

    det(I + beta H (A + z O)) = 0,   beta = b / b_ref,  A = D_P + jw D_V,  z = e^{-jwT}.

Factor the delayed matrix O = U V^T (rank r, 1 for the usual chip-thickness
regeneration).  The matrix determinant lemma gives, for each w,

    det(I + beta H A) det(I_r + z N(beta)),   N(beta) = beta V^T (I + beta H A)^-1 H U,

so the boundary is where an eigenvalue nu of N(beta) has |nu| = 1, and then
z = -1/nu fixes the delay: wT = -arg z + 2 pi k, k = 0, 1, 2, ... (one lobe
per k).  chatterlab finds every real positive beta with |nu(beta)| = 1 up to
the width range at every w of a grid (exactly: real roots of a polynomial,
:mod:`chatterlab.lobes._boundary`), follows the curve around its folds, and
so knows every lobe as a curve (T_k(w), b(w)); the grid's band is proven to
hold every boundary point by a gain bound (:mod:`chatterlab.frequency._bounds`).
The lower envelope at each requested speed is then refined to round-off by
regula falsi on the phase condition, re-solving beta exactly at each trial
frequency, and checked by the argument principle.

For the classical regenerative model (D_P = K_f b f n^T, D_O = -D_P, D_V = 0)
this reduces to Tlusty's b_lim = -1/(2 K_f Re[n^T G f]) with the phase
condition; for the paper's D_P + s D_V + D_O e^{-sT} (Eq. 2.23, 3.7-3.9) it is
the small eigenvalue problem above at each frequency.

The engine, by what each module holds: the result :class:`Lobe`,
:class:`LobeDiagram` (:mod:`chatterlab.lobes._result`); the structure
:class:`Plant` and the inner solve (:mod:`chatterlab.lobes._plant`); the
frequency band and grid (:mod:`chatterlab.lobes._band`); the boundary curve,
:class:`Boundary` and the envelope refinement
(:mod:`chatterlab.lobes._envelope`); the argument-principle checks
(:mod:`chatterlab.lobes._verification`).  This module is the entry point
:func:`lobes` and re-exports those names.

References
----------
.. [1] J. Tlusty, M. Polacek, "The stability of machine tools against self
   excited vibrations in machining", Int. Res. Prod. Eng., ASME, 465-474, 1963.
.. [2] Y. Altintas, E. Budak, "Analytical prediction of stability lobes in
   milling", CIRP Annals 44(1), 357-362, 1995 (eigenvalue form of the boundary).
.. [3] T. Insperger, G. Stépán, *Semi-Discretization for Time-Delay Systems*,
   Springer, 2011, ch. 1-2 (D-subdivision).
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any, Literal

import numpy as np

from ..errors import InputError, check_speed, check_width
from ..frequency._delay_system import single_threaded
from ..structure._assembly import FrozenSystem
from ._damped import Boundary, DampedLobeDiagram
from ._envelope import _check_terms, boundary
from ._lobe_set import _lobe_curves
from ._plant import Plant
from ._result import Lobe, LobeDiagram
from ._verification import VERIFY_OFFSET as VERIFY_OFFSET
from ._verification import _check_speeds as _check_speeds
from ._verification import _verify

__all__ = ["Lobe", "LobeDiagram", "Boundary", "Plant", "lobes", "boundary"]


@single_threaded
def lobes(
    frozen: FrozenSystem | None,
    speeds: np.ndarray,
    *,
    width_max: float = 0.02,
    terms: Literal["pdo", "o"] = "pdo",
    process: Any = None,
    fmin: float | None = None,
    fmax: float | None = None,
    n_frequencies: int | None = None,
    verify: int = 16,
    couplings: list[str] | None = None,
    plant: Plant | None = None,
    name: str | None = None,
    damping: Any = None,
    mesh_error: bool = False,
) -> LobeDiagram:
    """Stability lobe diagram b_lim(speed) at a frozen configuration.

    Parameters
    ----------
    frozen : FrozenSystem
        The structure with the slide held at a position (``system.at(s)``).
    speeds : array, shape (n,)
        Cutting speeds in the process's unit (shaping: work speed m/s;
        turning: rpm; ``process.kind == "delay"``: the delay in s).
    width_max : float
        Largest width of cut considered, m; b_lim = inf above it.
    terms : {"pdo", "o"}
        All feedback terms (the paper's case c) or the delayed term only.
    process : Process or Milling, optional
        Kinematics mapping speed to delay (default: the model's ``[process]``):
        anything with ``kind``, ``speed_unit``, ``speed_name``, ``min_delay``,
        ``delay(speed)`` and ``speed_for_delay(T)`` (a milling cutter's speed
        is the spindle speed, its delay the tooth period).
    fmin, fmax : float, optional
        Chatter frequency band searched, Hz (default: from the modes).
    n_frequencies : int, optional
        Size of the uniform part of the frequency grid (default 2000); every
        resonance in the band adds a cluster of points that resolves it.
    verify : int
        How many envelope claims are checked by the argument principle
        (0 to skip; not available with a ``plant``): the global minimum just
        below and above the envelope, the ``verify - 1`` highest cusps and
        ``verify // 2`` lobe bottoms just below it (relative offset
        ``VERIFY_OFFSET``), and every run of ``inf`` at the width ceiling.
    plant : Plant, optional
        A structure given by its FRF instead of a model (e.g. a python-control
        LTI system, :func:`chatterlab.lobes._control.lti_plant`); ``frozen`` is then
        None and ``process`` must be given.
    name : str, optional
        Label of the structure in the result (default: the model file).
    damping : DampingTerm, optional
        Process damping of a ``plant`` (:mod:`chatterlab.process._damping`);
        a model's ``[process_damping]`` is taken from the model.  With it the
        boundary couples the width and the delay through the cutting speed
        (:mod:`chatterlab.lobes._damped`) and ``meta["process_damping"]``
        says so.
    mesh_error : bool
        A model with beams: the absolute minimum and the envelope again on
        the mesh twice as fine, and the discretisation error in ``meta``
        (:func:`chatterlab.lobes.with_mesh_error`; docs/lobes.md, Eqs.
        M1-M5), as ``chatterlab lobes`` reports it.  Off, the summary of a
        model with beams says that the error was not estimated.

    Returns
    -------
    LobeDiagram
    """
    t0 = time.perf_counter()
    proc = _process_of(frozen, process)
    speeds = _checked_speeds(speeds, proc)
    width_max = check_width(width_max, "width_max")
    _check_terms(terms)
    bd = Boundary(
        frozen,
        width_max=width_max,
        terms=terms,
        fmin=fmin,
        fmax=fmax,
        n_base=n_frequencies,
        couplings=couplings,
        plant=plant,
        damping=damping,
    )
    T = np.asarray(proc.delay(speeds), dtype=float) if proc.kind != "delay" else speeds.copy()
    envelope = bd.envelope(T)
    damped = getattr(bd, "term", None) is not None
    if damped:
        lobe_list, n_in_range = bd.lobe_curves(T, envelope[2], proc)  # type: ignore[attr-defined]
    else:
        lobe_list, n_in_range = _lobe_curves(bd.segments, T, envelope[2], proc, 1.0)
    diagram = _diagram_of(
        bd, frozen, proc, speeds, T, envelope, lobe_list, n_in_range, width_max, terms, name
    )
    if not damped:  # the boundary itself: every lobe at every speed follows from it (the plot's curves)
        branches = tuple(
            np.column_stack([np.full(sg.omega.size, float(sg.branch)), sg.omega,
                             np.mod(-np.angle(sg.z), 2 * np.pi), sg.beta])
            for sg in bd.segments
            if sg.omega.size >= 2
        )  # fmt: skip
        diagram = replace(diagram, branches=branches)
    if damped:
        diagram = DampedLobeDiagram.of(
            replace(diagram, meta={**diagram.meta, "process_damping": _damping_meta(bd)})
        )
    checks = _verify(frozen, diagram, verify, couplings) if verify and frozen is not None else ()
    diagram = replace(diagram, checks=checks, elapsed=time.perf_counter() - t0)
    if frozen is not None and frozen.model.beams:
        from ._mesh_error import not_estimated, with_mesh_error

        if not mesh_error:
            return replace(diagram, meta={**diagram.meta, **not_estimated(frozen.model)})
        return with_mesh_error(diagram, frozen, fmin=fmin, fmax=fmax, couplings=couplings)
    return diagram


def _damping_meta(bd: Any) -> dict[str, Any]:
    """What a damped diagram says of its process damping (files, plot)."""
    return {**bd.term.meta(), "cells": len(bd.cells)}


def _process_of(frozen: FrozenSystem | None, process: Any) -> Any:
    """The kinematics mapping speed to delay: ``process`` or the model's."""
    proc = process if process is not None else (frozen.model.process if frozen is not None else None)
    if proc is None:
        src = frozen.model.source if frozen is not None else "the plant"
        raise InputError(
            f"{src} has no [process] table: add one (shaping, turning or delay), or pass process=, so that"
            " speeds map to delays"
        )
    return proc


def _checked_speeds(speeds: np.ndarray, proc: Any) -> np.ndarray:
    """The speeds as a non-empty 1-D float array, each end checked in the
    process's unit (or the first one that is not finite)."""
    speeds = np.asarray(speeds, dtype=float)
    if speeds.ndim != 1 or speeds.size == 0:
        raise InputError("speeds must be a non-empty 1-D array")
    for v in (
        (speeds.min(), speeds.max()) if np.all(np.isfinite(speeds)) else speeds[~np.isfinite(speeds)][:1]
    ):
        check_speed(v, "speeds", proc.speed_unit)
    return speeds


def _diagram_of(
    bd: Boundary,
    frozen: FrozenSystem | None,
    proc: Any,
    speeds: np.ndarray,
    T: np.ndarray,
    envelope: tuple[np.ndarray, np.ndarray, np.ndarray],
    lobe_list: list[Lobe],
    n_in_range: int,
    width_max: float,
    terms: Literal["pdo", "o"],
    name: str | None,
) -> LobeDiagram:
    """The diagram (not yet checked) from the boundary, the envelope at the
    requested speeds and the lobe curves, with its minima."""
    b_lim, chatter, lobe_k = envelope
    if np.any(np.isfinite(b_lim)):
        j = int(np.nanargmin(b_lim))
        minimum = {"width": float(b_lim[j]), "speed": float(speeds[j]), "chatter_hz": float(chatter[j])}
    else:
        minimum = {"width": float("inf"), "speed": float("nan"), "chatter_hz": float("nan")}
    absolute = bd.absolute_minimum()
    return LobeDiagram(
        speed=speeds,
        delay=T,
        b_lim=b_lim,
        chatter_hz=chatter,
        lobe=lobe_k,
        lobes=tuple(lobe_list),
        minimum=minimum,
        absolute_minimum=absolute,
        process=proc,
        width_max=width_max,
        terms=terms,
        position=frozen.position if frozen is not None else None,
        model=name or (frozen.model.source if frozen is not None else "plant"),
        elapsed=0.0,
        n_frequencies=bd.n_frequencies,
        band_hz=(bd.band.lo / (2 * np.pi), bd.band.hi / (2 * np.pi)),
        band_certified=bd.band.certified,
        band_note=bd.band.reason,
        folds=bd.folds,
        n_lobes=n_in_range,
        band_measured=bd.plant.measured_band is not None,
    )
