"""The machine with its actuators: the controlled machine's own roots
(without cutting) and the lobe diagram of the cut on it.

Without cutting, a machine with actuators (``[[actuator]]``) is the delay
system

    Delta_c(s) = s^2 M + s C + K + F_a diag(G(s)) S_a,                       (1)

G_k(s) = (P_k + s V_k + O_k e^{-s T_k}) / (1 + s L_k): one delay per
actuator (one in all for a single actuator), a first-order state per
bandwidth.  Its characteristic roots are computed exactly
(:func:`chatterlab.frequency.characteristic_roots` on
:func:`controller_system`, the spectral method with the delay kept as it
is, no Pade approximation): the controller must leave them all in the left
half plane before a lobe means anything.

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

import math
import warnings
from dataclasses import replace
from typing import Any, Literal

import numpy as np

from ..errors import InputError, UnitWarning
from ..frequency import characteristic_roots
from ..frequency._bounds import certified_band
from ..frequency._delay_system import DelaySystem, loop_system
from ..frequency._roots_result import RootsResult
from ..lobes import Plant, lobes
from ..lobes._verification import verify_diagram
from ..process._loop import closed_loop_unwarned
from ._receptance import receptance

__all__ = ["controller_system", "controller_roots", "controlled_plant", "design_lobes", "ControllerUnstable"]


class ControllerUnstable(InputError):
    """The machine with its actuators is unstable without cutting: no width
    of cut is chatter-free, and nothing is optimised from there."""


def controller_system(frozen: Any) -> DelaySystem:
    """The delay system (1) of the machine with its actuators, without the cut."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnitWarning)
        loop = closed_loop_unwarned(frozen, width=1.0, delay=1.0, terms="none")
    return loop_system(loop)


def _count(frozen: Any) -> int:
    """Roots asked for: one per structural degree of freedom and actuator state,
    and a few more (the delay's own roots lie far left for a short T_a)."""
    acts = frozen.model.actuators
    return int(frozen.structure.n + sum(1 for a in acts if math.isfinite(a.bandwidth_hz)) + 4)


def controller_roots(frozen: Any, count: int | None = None) -> RootsResult:
    """The rightmost characteristic roots (rad/s) of the machine with its
    actuators, without cutting (exact delays)."""
    sys = controller_system(frozen)
    return characteristic_roots(sys, count=count or _count(frozen))


def check_controller(frozen: Any, roots: RootsResult) -> None:
    """A :class:`ControllerUnstable` one-liner when the controlled machine has
    a root in the right half plane (or on the axis), naming it and the
    actuators' delays."""
    if roots.roots.size == 0:
        raise InputError(f"{frozen.model.source}: no root of the machine with its actuators was found")
    lam = roots.roots[0]
    if lam.real >= -1e-12 * max(abs(lam), 1.0):
        acts = frozen.model.actuators
        delays = ", ".join(f"{a.id}: T_a = {a.delay * 1e3:.4g} ms" for a in acts)
        raise ControllerUnstable(
            f"{frozen.model.source}: the machine with its actuators is unstable without cutting (root"
            f" {lam.real:.4g} {'+' if lam.imag >= 0 else '-'} {abs(lam.imag):.4g}j 1/s, {lam.imag / (2 * np.pi):.4g} Hz;"
            f" {delays}): lower the gains or the delay -- nothing is computed on an unstable controller"
        )


def controlled_plant(
    frozen: Any,
    roots: RootsResult,
    *,
    width_max: float,
    terms: str = "pdo",
    couplings: list[str] | None = None,
) -> tuple[Plant, float]:
    """The plant the cut sees (H_c, the controlled roots as its poles, the CE
    matrices at b = 1 m) and the top of its chatter band (rad/s)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnitWarning)
        loop = closed_loop_unwarned(frozen, width=1.0, delay=1.0, terms=terms, couplings=couplings)  # type: ignore[arg-type]

    def H(omega: np.ndarray) -> np.ndarray:
        return receptance(loop, omega)

    lam = np.asarray(roots.roots, dtype=complex)
    poles = np.concatenate([lam, lam[lam.imag != 0].conj()])
    bare = Plant.from_loop(loop)  # the structure's own modes (from_loop reads no actuator)
    assert bare.residues is not None
    w1 = float(np.min(np.abs(bare.poles[bare.poles.imag > 0]))) if np.any(bare.poles.imag > 0) else 1.0
    band = certified_band(bare.residues, loop.Dl_P, loop.Dl_V, loop.Dl_O, width_max, 1e-3 * w1)
    top = max(float(band.hi), 1.6 * float(np.max(np.abs(lam.imag))) if lam.size else 0.0)
    return Plant(H, poles, loop.Dl_P, loop.Dl_V, loop.Dl_O), top


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
    if roots is None:
        roots = controller_roots(frozen)
    check_controller(frozen, roots)
    plant, top = controlled_plant(frozen, roots, width_max=width_max, terms=terms, couplings=couplings)
    lo = 0.0 if fmin is None else fmin
    hi = top / (2 * np.pi) if fmax is None else fmax
    d = lobes(
        plant, speeds, width_max=width_max, terms=terms, n_frequencies=n_frequencies, verify=0,
        process=frozen.model.process, fmin=lo, fmax=hi, name=frozen.model.source,
    )  # fmt: skip
    note = (
        f"the structure with its actuators: band {lo:.4g}..{hi:.4g} Hz from the bare structure's gain bound"
        " and the controlled roots, not proven for the controlled machine"
        if fmin is None and fmax is None
        else d.band_note
    )
    d = replace(
        d, position=frozen.position, band_note=note, meta={**d.meta, "controller_abscissa": roots.abscissa}
    )
    if verify:
        d = replace(d, checks=verify_diagram(frozen, d, verify, couplings))
    return d
