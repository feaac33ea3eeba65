"""Stability lobes straight from a measured FRF (no modal fit).

:func:`measured_plant` turns a measured :class:`~chatterlab.structure.FRF`
into the lobe engine's :class:`~chatterlab.lobes._diagram.Plant`:

* **H(jw)** between the cut's coordinates is the measured receptance,
  interpolated between the measured frequencies by the FRF's cubic spline
  on Re H and Im H (:meth:`FRF.interpolate`); NaN outside the band,
  which the engine never asks for.
* **The process** is the same as a model's ``[[coupling]]``: the
  regenerative model (D_P = K_f f n^T, D_O = -D_P, D_V = K_v f n^T per unit
  width, f the force direction on the tool and n the chip-thickness normal
  in the plane of the measured coordinates; docs/model-format.md) or the
  matrices D_P, D_V, D_O at a reference width.  For the classical
  regenerative cut the boundary is Tlusty's b_lim = -1 / (2 K_f Re[n^T H f])
  with the oriented FRF n^T H f [1].
* **Milling** (zeroth-order approximation, Altintas & Budak [3]): with the
  2 x 2 FRF on the cutter's (x, y) and the averaged directional matrix H0
  of :meth:`chatterlab.process.Milling.zoa`, the force F = -a_p H0
  [r(t) - r(t - tau)] gives D_P = H0, D_O = -H0 per unit axial depth, and
  the delay is the tooth period tau = 60 / (N n) (uniform pitch only).
* **The band** is the measured one, never certified: a measured FRF says
  nothing about frequencies it does not cover, so where the diagram finds
  no boundary it says "undetermined", and a finite b_lim is the boundary
  within the band only (:attr:`LobeDiagram.claim` 2 and 4).
* **The frequency grid** is the measured frequencies plus ``n_frequencies``
  uniform points across the band; folds are bisected and each envelope
  crossing is refined by regula falsi on the spline-interpolated FRF, as for
  a model.  The lobes are then those of the spline through the data: their
  error is the interpolation error of H near the chatter frequency, carried
  to b_lim to first order by |db|/b <= |dG|/|Re G| + |d ln b/dT| |dpsi|/w
  (dG the error of the oriented FRF, dpsi <= |dG|/|G| its phase error), so
  the envelope converges like the spline, O(h^4) in the spacing h
  (docs/measured-frf.md derives and tests it).

References
----------
.. [1] J. Tlusty, M. Polacek, "The stability of machine tools against self
   excited vibrations in machining", Int. Res. Prod. Eng., ASME, 465-474, 1963.
.. [2] Y. Altintas, *Manufacturing Automation*, 2nd ed., Cambridge
   University Press, 2012, ch. 3.3 (lobes from a measured, oriented FRF).
.. [3] Y. Altintas, E. Budak, "Analytical prediction of stability lobes in
   milling", CIRP Annals 44(1), 357-362, 1995.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from ..errors import InputError, check_finite, check_nonneg, check_positive, check_width
from ..frequency._bounds import Band
from ..model._items import Process
from ..process._milling import Milling
from ..structure import FRF
from ._control import _matrices
from ._diagram import LobeDiagram, Plant, lobes

__all__ = [
    "measured_plant",
    "lobes_measured",
    "regenerative_matrices",
    "zoa_matrices",
    "model_frf",
    "model_frf_summary",
    "lobes_model_frf",
]


def regenerative_matrices(
    m: int, Kf: float, force_angle: float = 0.0, normal_angle: float = 0.0, Kv: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(D_P, D_V, D_O) per unit width (m x m) of the regenerative cut on m
    measured coordinates (1: axis 1 only; 2: axes 1 and 2 of the plane).

    f = (cos a_f, sin a_f), n = (cos a_n, sin a_n) truncated to m entries:
    D_P = K_f f n^T, D_O = -D_P, D_V = K_v f n^T (N/m^2, N s/m^2)."""
    Kf = check_positive(Kf, "Kf", "N/m^2")
    Kv = check_nonneg(Kv, "Kv", "N s/m^2")
    af = check_finite(force_angle, "force_angle", "rad")
    an = check_finite(normal_angle, "normal_angle", "rad")
    if m not in (1, 2):
        raise InputError(
            f"the regenerative cut acts in a plane: give an FRF on 1 or 2 coordinates (got {m}); select() them"
        )
    f = np.array([np.cos(af), np.sin(af)])[:m]
    n = np.array([np.cos(an), np.sin(an)])[:m]
    fn = np.outer(f, n)
    if not np.any(np.abs(fn) > 1e-12):
        raise InputError(
            "the force and the chip-thickness normal have no component on the measured coordinate:"
            " with one coordinate, the angles must not be +-90 deg"
        )
    return Kf * fn, Kv * fn, -Kf * fn


def zoa_matrices(milling: Milling) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(D_P, D_V, D_O) per unit axial depth (2 x 2, on the cutter's x, y)
    of the zeroth-order approximation: H0, 0, -H0 with H0 =
    :meth:`Milling.zoa` (N/m^2), from F = -a_p H0 [r(t) - r(t - tau)]."""
    if not isinstance(milling, Milling):
        raise InputError(f"milling must be a chatterlab.process.Milling (got {type(milling).__name__})")
    if not milling.uniform:
        raise InputError(
            "the zeroth-order approximation with one delay needs a uniform pitch; a variable-pitch cutter"
            " has one delay per tooth: use the Floquet methods"
        )
    H0 = np.asarray(milling.zoa(), dtype=float)
    return H0, np.zeros((2, 2)), -H0


def measured_plant(
    frf: FRF,
    *,
    coordinates: Sequence[str] | None = None,
    milling: Milling | None = None,
    Kf: float | None = None,
    force_angle: float = 0.0,
    normal_angle: float = 0.0,
    Kv: float = 0.0,
    DP: Any = None,
    DV: Any = None,
    DO: Any = None,
    width_ref: float | None = None,
) -> Plant:
    """A lobe-engine plant from a measured FRF.

    Parameters
    ----------
    frf : FRF
        Receptance (m/N) of the tool relative to the workpiece at the cut
        (an FRF of another kind is converted).
    coordinates : sequence of str, optional
        The coordinates of the cut, in the order of the process matrices'
        axes (default: the FRF's outputs).  The FRF must hold every
        (output, input) pair among them: a driving-point matrix.  A 1 x 1
        FRF may name different response and reference (a tap test names
        hammer and accelerometer separately).
    Kf : float
        Regenerative model: cutting-force coefficient, N/m^2 ...
    force_angle, normal_angle : float
        ... the force direction on the tool and the chip-thickness normal,
        rad from coordinate 1 towards coordinate 2 ...
    Kv : float
        ... and the process damping, N s/m^2.
    DP, DV, DO : array (m, m), optional
        Instead of ``Kf``: the process matrices at ``width_ref`` (m), the
        CE convention of a model's ``[[coupling]]`` (a 3 x 3 matrix is cut
        to the m measured coordinates).
    milling : Milling, optional
        Instead of ``Kf``: milling by the zeroth-order approximation
        (:func:`zoa_matrices`); ``coordinates`` are then the cutter's x and
        y (in that order) and the width is the axial depth a_p.

    Returns
    -------
    Plant
        For :func:`chatterlab.lobes.lobes` ``(None, speeds, plant=...,
        process=...)``; its band is the measured band, not certified.
    """
    if not isinstance(frf, FRF):
        raise InputError(f"expected an FRF (chatterlab.structure.FRF), got {type(frf).__name__}")
    sub = _driving_point(frf.as_kind("receptance"), coordinates)
    m = sub.data.shape[0]
    if milling is not None:
        if Kf is not None or DP is not None or DV is not None or DO is not None or width_ref is not None:
            raise InputError("give one process: milling=, Kf= (regenerative cut) or DP/DV/DO with width_ref")
        if m != 2:
            raise InputError(
                f"milling needs the 2 x 2 FRF on the cutter's x and y (got {m} coordinate(s)); name them"
                " with coordinates=(X, Y)"
            )
        P, V, O = zoa_matrices(milling)
    elif Kf is not None:
        if DP is not None or DV is not None or DO is not None or width_ref is not None:
            raise InputError("give either Kf (regenerative cut) or DP/DV/DO with width_ref, not both")
        P, V, O = regenerative_matrices(m, Kf, force_angle, normal_angle, Kv)
    else:
        if DO is None or width_ref is None:
            raise InputError("give Kf (regenerative cut) or DO (and DP, DV) with width_ref")
        bref = check_width(width_ref, "width_ref")
        P, V, O = (x / bref for x in _matrices(m, DP, DV, DO))
    lo, hi = sub.band
    band = Band(
        lo,
        hi,
        False,
        f"measured FRF ({sub.source}) covers {lo / 2 / np.pi:.6g} .. {hi / 2 / np.pi:.6g} Hz:"
        " chatter outside it is unknown",
    )

    def H(omega: np.ndarray) -> np.ndarray:
        # the engine's layout: one matrix per frequency
        h = sub.interpolate(np.atleast_1d(np.asarray(omega, dtype=float)), outside="nan")
        return np.ascontiguousarray(np.moveaxis(h, -1, 0))

    return Plant(H, np.zeros(0, complex), P, V, O, None, measured_band=band, grid=np.asarray(sub.omega))


#: the (output, input) names the FRF readers give a single FRF whose coordinates the file does not name
_UNNAMED = ("response", "reference")


def _driving_point(frf: FRF, coordinates: Sequence[str] | None) -> FRF:
    pair = (frf.outputs[0], frf.inputs[0])
    if frf.data.shape[:2] == (1, 1) and pair != _UNNAMED and pair[0] != pair[1]:
        # the response at one named coordinate to a force at another: the cut feeds back at one point
        raise InputError(
            f"{frf.source}: the lobes need a driving-point FRF (response and force at the same coordinate);"
            f" this one is {frf.outputs[0]}/{frf.inputs[0]}, a cross FRF: give the {frf.outputs[0]}/"
            f"{frf.outputs[0]} (or {frf.inputs[0]}/{frf.inputs[0]}) measurement"
        )
    if coordinates is None:
        if frf.data.shape[:2] == (1, 1):
            return frf
        if set(frf.outputs) != set(frf.inputs):
            raise InputError(
                f"{frf.source}: the lobes need a driving-point FRF matrix (the same coordinates as outputs and"
                f" inputs); outputs {list(frf.outputs)}, inputs {list(frf.inputs)}: name the coordinates"
            )
        coordinates = frf.outputs
    coords = [coordinates] if isinstance(coordinates, str) else list(coordinates)
    if len(coords) == 1 and frf.data.shape[:2] == (1, 1) and coords[0] in frf.outputs + frf.inputs:
        return frf
    return frf.select(coords, coords)


def lobes_measured(
    frf: FRF,
    speeds: np.ndarray,
    *,
    process: Process | None = None,
    milling: Milling | None = None,
    width_max: float = 0.02,
    fmin: float | None = None,
    fmax: float | None = None,
    n_frequencies: int | None = None,
    name: str | None = None,
    **cut: Any,
) -> LobeDiagram:
    """Stability lobes of a measured FRF: :func:`measured_plant` (``cut``:
    ``Kf``, ``force_angle``, ``normal_angle``, ``Kv``, ``coordinates`` or
    ``DP``/``DV``/``DO``/``width_ref``) handed to :func:`lobes`.  The
    argument-principle checks need matrices and are not run; the band is the
    measured one (``fmin``/``fmax`` in Hz may narrow it).

    Milling (``milling=``, no ``process``): ``speeds`` are spindle speeds in
    rpm, the delay the tooth period 60 / (N n), the width the axial depth;
    the ZOA plant of :func:`measured_plant`."""
    label = name or f"measured FRF {frf.source}"
    if milling is None:
        if process is None:
            raise InputError("give the process (process=, the speed -> delay kinematics) or milling=")
        plant = measured_plant(frf, **cut)
        return lobes(
            None,
            speeds,
            width_max=width_max,
            process=process,
            fmin=fmin,
            fmax=fmax,
            n_frequencies=n_frequencies,
            verify=0,
            plant=plant,
            name=label,
        )
    if process is not None:
        raise InputError("milling sets the delay (the tooth period): give milling= or process=, not both")
    plant = measured_plant(frf, milling=milling, **cut)
    rpm = np.asarray(speeds, dtype=float)
    if rpm.ndim != 1 or rpm.size == 0:
        raise InputError("speeds must be a non-empty 1-D array of spindle speeds (rpm)")
    d = lobes(
        None,
        rpm,
        width_max=width_max,
        process=milling,
        fmin=fmin,
        fmax=fmax,
        n_frequencies=n_frequencies,
        verify=0,
        plant=plant,
        name=label + f" (milling, ZOA, {milling.teeth} teeth)",
    )
    # the averaged cut's limits (claim 6: the flip lobes are not modelled), as milling_lobes' ZOA gives
    return replace(
        d, method="zoa", basis=np.full(np.shape(d.b_lim), "zoa"),
        resolution=f"D-subdivision on {d.n_frequencies} measured frequencies",
    )  # fmt: skip


def model_frf(model: Any) -> FRF:
    """The measured FRF of a model's ``[frf]`` table (receptance)."""
    src = getattr(model, "frf", None)
    if src is None:
        raise InputError(f"{model.source} has no [frf] table: its structure is not a measured FRF")
    return FRF.from_record(src.table, source=src.file)


def _frf_cut(model: Any, frf: FRF, c: Any) -> tuple[list[str], tuple[np.ndarray, ...]]:
    """The coordinates of the FRF that the coupling ``c`` acts on and its
    (D_P, D_V, D_O) on them: the coupling must join a point on the FRF's
    coordinates to the ground, with the measured directions as its axes."""
    if c.b.kind != "ground" or c.a.kind != "coords" or c.a.weights:
        raise InputError(
            f'{model.source}: [[coupling]] "{c.id}" must join a point on the FRF\'s coordinates (a, coords ='
            ' { x = "...", y = "..." }) to "ground": the measured FRF is the tool relative to the workpiece'
        )
    if c.angle != 0.0:
        raise InputError(
            f'{model.source}: [[coupling]] "{c.id}" has angle_deg = {np.degrees(c.angle):g}; with a measured FRF'
            " the CE axes are the measured directions: rotate the FRF's coordinates instead (angle_deg = 0)"
        )
    axes = [k for k, name in enumerate(c.a.coords) if name]
    coords = [c.a.coords[k] for k in axes]
    missing = [n for n in coords if n not in frf.outputs or n not in frf.inputs]
    if missing and not (len(coords) == 1 and frf.data.shape[:2] == (1, 1)):
        raise InputError(
            f"{frf.source}: the coupling's point names {', '.join(missing)}, which the FRF does not hold as both"
            f" response and reference (outputs {list(frf.outputs)}, inputs {list(frf.inputs)})"
        )
    sel = np.ix_(axes, axes)
    mats: tuple[Any, ...] = (c.DP, c.DV, c.DO)
    if c.kind == "milling":
        # a model = "milling" coupling carries no matrices (since d9d55eb they come from the cutter):
        # the zeroth-order average H0, 0, -H0 per metre of a_p, in the feed/normal axes, at width_ref
        H0, _, _ = zoa_matrices(Milling.from_cut(model.process.milling))
        D = np.zeros((3, 3))
        D[:2, :2] = c.width_ref * H0
        mats = (D, np.zeros((3, 3)), -D)
    return coords, tuple(np.asarray(X, dtype=float)[sel] for X in mats)


def model_frf_summary(model: Any) -> dict[str, Any]:
    """What ``chatterlab check`` says of a model whose structure is a
    measured FRF (``[frf]``): the file, its units, band and coordinates, and
    each ``[[coupling]]`` checked as :func:`lobes_model_frf` checks it."""
    frf = model_frf(model)
    src = model.frf
    cuts = {c.id: _frf_cut(model, frf, c)[0] for c in model.couplings}
    lo, hi = frf.band_hz
    return {
        "name": model.name,
        "source": model.source,
        "variant": model.variant,
        "structure": "measured FRF",
        "file": src.file,
        "format": src.table.meta.get("format"),
        "units": src.table.meta.get("units"),
        "quantity": src.table.meta.get("quantity"),
        "frequencies": int(frf.omega.size),
        "band [Hz]": [float(lo), float(hi)],
        "outputs": list(frf.outputs),
        "inputs": list(frf.inputs),
        "coherence": frf.coherence is not None,
        "couplings": {k: list(v) for k, v in cuts.items()},
        "points": len(model.points),
    }


def lobes_model_frf(
    model: Any,
    speeds: np.ndarray,
    *,
    frf: FRF | None = None,
    coupling: str | None = None,
    width_max: float = 0.02,
    fmin: float | None = None,
    fmax: float | None = None,
    n_frequencies: int | None = None,
) -> LobeDiagram:
    """Lobes of a model whose structure is a measured FRF (``[frf]``, or
    ``frf=`` in place of the model's structure, e.g. ``--frf FILE``): the
    model's ``[process]`` maps speeds to delays and its ``[[coupling]]``
    (against ``"ground"``, the FRF being the tool relative to the
    workpiece) gives the process matrices on the coordinates its point
    names; a ``model = "milling"`` coupling is the zeroth-order
    approximation (speeds in rpm, the width the axial depth)."""
    frf = frf if frf is not None else model_frf(model)
    if model.process is None:
        raise InputError(f"{model.source} has no [process] table: add one so that speeds map to delays")
    cs = [c for c in model.couplings if coupling is None or c.id == coupling]
    if len(cs) != 1:
        known = ", ".join(c.id for c in model.couplings) or "none"
        raise InputError(
            f"{model.source}: lobes from a measured FRF take one [[coupling]] (known: {known}); name it with coupling="
        )
    c = cs[0]
    coords, (DP, DV, DO) = _frf_cut(model, frf, c)
    d = lobes_measured(
        frf,
        speeds,
        process=model.process,
        width_max=width_max,
        fmin=fmin,
        fmax=fmax,
        n_frequencies=n_frequencies,
        name=f"{model.source} with the measured FRF {frf.source}"
        + (
            " (milling by the zeroth-order approximation, Altintas & Budak 1995: flip lobes are not modelled;"
            " at low immersion the limits can be several times too deep)"
            if model.process is not None and model.process.kind == "milling"
            else ""
        ),
        coordinates=coords,
        DP=DP,
        DV=DV,
        DO=DO,
        width_ref=c.width_ref,
    )
    if model.process.kind == "milling":  # the averaged cut's limits: claim 6 (flip lobes not modelled)
        d = replace(d, basis=np.full(np.shape(d.b_lim), "zoa"))
    return d
