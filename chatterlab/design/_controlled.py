"""The machine with its actuators: the controlled machine's own roots
(without cutting) and the lobe diagram of the cut on it.

Without cutting, a machine with actuators (``[[actuator]]``) is the delay
system

    Delta_c(s) = s^2 M + s C + K + F_a diag(G(s)) S_a,                       (1)

G_k(s) = (P_k + s V_k + O_k e^{-s T_k}) / (1 + s L_k): one delay per
actuator (one in all for a single actuator), a first-order state per
bandwidth.  Its characteristic roots are computed exactly
(:func:`chatterlab.frequency.characteristic_roots` on
:func:`machine_system`, the spectral method with the delay kept as it
is, no Pade approximation; :func:`machine_roots`): the controller must
leave them all in the left half plane before a lobe means anything.

The cut then sees the structure through H_c(w) = J Delta_c(jw)^-1 J^T
(:func:`chatterlab.design._receptance.receptance`), and the lobe engine's
D-subdivision runs unchanged on that plant (:class:`chatterlab.lobes.Plant`):
the cut's delay T is the one scanned, the actuator's T_a sits inside H_c.
The plant's poles -- which place the frequency grid's resonance clusters and
must be damped -- are the controlled roots of (1).  The chatter band is the
bare structure's certified one (the gain bound of
:mod:`chatterlab.frequency._bounds` on its pole-residue form) widened to
hold every controlled root found, not proven for the controlled machine
(H_c has no finite pole-residue form with a delay).  The diagram's claims
are then checked by the argument principle on the full closed loop -- the
structure, the actuators and the cut, two delays
(:func:`chatterlab.lobes.verify_diagram`): a route independent of the
boundary computation.
"""

from __future__ import annotations

import warnings
from dataclasses import replace
from typing import Any, Literal

import numpy as np

from ..errors import InputError, UnitWarning
from ..frequency import characteristic_roots
from ..frequency._bounds import PoleResidue, certified_band
from ..frequency._delay_system import DelaySystem, loop_system
from ..frequency._roots_result import RootsResult
from ..lobes import Plant, lobes
from ..lobes._verification import verify_diagram
from ..process import ClosedLoop
from ..process._loop import closed_loop_unwarned
from ..structure import Structure
from ._matrices import LoopMatrices, matrices_of
from ._receptance import receptance

__all__ = [
    "machine_system",
    "machine_roots",
    "controller_roots",
    "check_controller",
    "plant_of",
    "plant_lobes",
    "bare_band",
    "design_lobes",
    "ControllerUnstable",
]


class ControllerUnstable(InputError):
    """The machine with its actuators is unstable without cutting: no width
    of cut is chatter-free, and nothing is optimised from there."""


def machine_system(L: LoopMatrices) -> DelaySystem:
    """The delay system (1) of the structure with its actuators (the loop
    matrices ``L``), without the cut."""
    n = L.M.shape[0]
    p = L.J.shape[0]
    zero = np.zeros((p, p))
    loop = ClosedLoop(
        Structure(L.M, L.C, L.K), L.J, zero, zero, zero, np.zeros(n), 1.0, None, "none", actuators=L.actuators
    )
    return loop_system(loop)


def machine_roots(L: LoopMatrices, count: int | None = None) -> RootsResult:
    """The rightmost characteristic roots (rad/s) of the structure with its
    actuators, without cutting (exact delays): one per structural degree of
    freedom and actuator state, and a few more (the delay's own roots lie far
    left for a short T_a)."""
    if count is None:
        count = int(L.M.shape[0] + np.count_nonzero(L.La > 0) + 4)
    return characteristic_roots(machine_system(L), count=count)


def controller_roots(frozen: Any, count: int | None = None) -> RootsResult:
    """:func:`machine_roots` of a frozen configuration with its actuators."""
    return machine_roots(_matrices(frozen), count)


def _matrices(frozen: Any, terms: str = "pdo", couplings: list[str] | None = None) -> LoopMatrices:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnitWarning)
        loop = closed_loop_unwarned(frozen, width=1.0, delay=1.0, terms=terms, couplings=couplings)  # type: ignore[arg-type]
    return matrices_of(loop)


def check_controller(source: str, roots: RootsResult, delays: str = "") -> None:
    """A :class:`ControllerUnstable` one-liner when the controlled machine has
    a root in the right half plane (or on the axis), naming it and the
    actuators' delays."""
    if roots.roots.size == 0:
        raise InputError(f"{source}: no root of the machine with its actuators was found ({roots.message})")
    lam = roots.roots[0]
    if lam.real >= -1e-12 * max(abs(lam), 1.0):
        raise ControllerUnstable(
            f"{source}: the machine with its actuators is unstable without cutting (root"
            f" {lam.real:.4g} {'+' if lam.imag >= 0 else '-'} {abs(lam.imag):.4g}j 1/s, {lam.imag / (2 * np.pi):.4g} Hz"
            f"{'; ' + delays if delays else ''}): lower the gains or the delay -- nothing is computed on an"
            " unstable controller"
        )


def _delays(model: Any) -> str:
    return ", ".join(f"{a.id}: T_a = {a.delay * 1e3:.4g} ms" for a in model.actuators)


def bare_band(L: LoopMatrices, width_max: float) -> float:
    """The top (rad/s) of the bare structure's certified chatter band (the gain
    bound on its pole-residue form, :func:`chatterlab.frequency._bounds.certified_band`)."""
    from ..structure import complex_modes

    cm = complex_modes(L.M, L.C, L.K)
    Jphi = L.J @ cm.phi
    pr = PoleResidue(cm.lam, Jphi, Jphi.T, np.zeros((L.J.shape[0],) * 2))
    up = cm.lam[cm.lam.imag > 0]
    w1 = float(np.min(np.abs(up))) if up.size else 1.0
    return float(certified_band(pr, L.P, L.V, L.O, width_max, 1e-3 * w1).hi)


def plant_of(L: LoopMatrices, roots: RootsResult) -> Plant:
    """The plant the cut sees: H_c(w) = J Z_c(w)^-1 J^T, the controlled roots
    as its poles, the CE matrices of ``L`` (at b = 1 m)."""

    def H(omega: np.ndarray) -> np.ndarray:
        return receptance(L, omega)

    lam = np.asarray(roots.roots, dtype=complex)
    poles = np.concatenate([lam, lam[lam.imag != 0].conj()])
    return Plant(H, poles, L.P, L.V, L.O)


def plant_lobes(
    L: LoopMatrices,
    roots: RootsResult,
    speeds: Any,
    process: Any,
    *,
    width_max: float,
    top: float,
    terms: str = "pdo",
    n_frequencies: int | None = None,
    fmin: float | None = None,
    fmax: float | None = None,
    name: str = "plant",
) -> Any:
    """The D-subdivision lobes of :func:`plant_of` on the band 0 ..
    max(``top``, 1.6 x the highest controlled root) (not verified)."""
    lam = np.asarray(roots.roots)
    hi_auto = max(top, 1.6 * float(np.max(np.abs(lam.imag))) if lam.size else 0.0) / (2 * np.pi)
    lo = 0.0 if fmin is None else fmin
    hi = hi_auto if fmax is None else fmax
    d = lobes(
        plant_of(L, roots), speeds, width_max=width_max, terms=terms, n_frequencies=n_frequencies, verify=0,
        process=process, fmin=lo, fmax=hi, name=name,
    )  # fmt: skip
    if fmin is None and fmax is None:
        note = (
            f"the structure with its actuators: band {lo:.4g}..{hi:.4g} Hz from the bare structure's gain bound"
            " and the controlled roots, not proven for the controlled machine"
        )
        d = replace(d, band_note=note)
    return replace(d, meta={**d.meta, "controller_abscissa": float(roots.abscissa)})


def design_lobes(
    frozen: Any,
    speeds: Any,
    *,
    width_max: float = 0.02,
    terms: Literal["pdo", "o"] = "pdo",
    n_frequencies: int | None = None,
    verify: int = 16,
    couplings: list[str] | None = None,
    fmin: float | None = None,
    fmax: float | None = None,
    roots: RootsResult | None = None,
) -> Any:
    """The lobe diagram of a frozen configuration, its actuators included:
    :func:`chatterlab.lobes.lobes` when it has none, else the D-subdivision
    of the controlled plant (module docstring) checked by the argument
    principle on the full closed loop.  A :class:`ControllerUnstable` when
    the machine with its actuators is unstable without cutting."""
    if not frozen.model.actuators:
        return lobes(
            frozen, speeds, width_max=width_max, terms=terms, n_frequencies=n_frequencies, verify=verify,
            couplings=couplings, fmin=fmin, fmax=fmax,
        )  # fmt: skip
    L = _matrices(frozen, terms, couplings)
    if roots is None:
        roots = machine_roots(L)
    check_controller(frozen.model.source, roots, _delays(frozen.model))
    d = plant_lobes(
        L, roots, speeds, frozen.model.process, width_max=width_max, top=bare_band(L, width_max), terms=terms,
        n_frequencies=n_frequencies, fmin=fmin, fmax=fmax, name=frozen.model.source,
    )  # fmt: skip
    d = replace(d, position=frozen.position)
    if verify:
        d = replace(d, checks=verify_diagram(frozen, d, verify, couplings))
    return d
