"""Process damping: the flank of the tool rubbing on the wavy surface it has
just cut, as the speed-dependent ideal-derivative term of the one closed
loop (docs/process-damping.md).

The linear model (Altintas, Eynian & Onozuka 2008; Budak & Tunc 2010) adds
to the cut's force on the tool, per unit width b,

    F_d = -C_pd (b / V) (n^T dw/dt) n,                                     (1)

n the cut's normal (the direction the delayed term regenerates), V the
cutting speed.  It is the seed paper's ideal-derivative feedback k s
(Table 1) with the gain k = C_pd b / V: on the coupling coordinates

    D_V(T) = D_V + b g(T) W,   g(T) = C_pd / V(T),   W = n n^T,           (2)

and V(T) comes from the process's own speed <-> delay formula
(:meth:`chatterlab.model.Process.speed_for_delay`): a shaper's work speed
itself, and pi D n / 60 (:func:`chatterlab.model._items.cutting_speed`) at a
spindle speed n for turning (D the workpiece's, ``[machine]
workpiece_diameter``) and milling (D the cutter's).  1/V is affine in T in
all three cases (turning T/(pi D), milling N T/(pi D), shaping
(T - S/v_l)/S), so g grows with the delay: the slower the cut, the more the
flank damps.

Milling.  Each tooth j in the cut rubs along its own radial direction
r_j = (sin phi_j, cos phi_j): W(t) = sum_j g_j(t) r_j r_j^T, the directional
matrix of a cutter with K_t = 0, K_n = 1 (:meth:`DampingTerm.milling_cutter`),
whose mean over a revolution W_0 = (N / 2 pi) int r r^T dphi is the
zeroth-order (averaged) term.

References
----------
Y. Altintas, M. Eynian, H. Onozuka, Identification of dynamic cutting force
coefficients and chatter stability with process damping, CIRP Annals 57
(2008) 371-374.
E. Budak, L. T. Tunc, Identification and modeling of process damping in
turning and milling using a new approach, CIRP Annals 59 (2010) 403-408.
D. W. Wu, A new approach of formulating the transfer function for dynamic
cutting processes, J. Eng. Ind. 111 (1989) 37-47.
R. Y. Chiou, S. Y. Liang, Chatter stability of a slender cutting tool in
turning with tool wear effect, Int. J. Mach. Tools Manuf. 38 (1998) 315-327.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..errors import InputError
from ..model._items import cutting_speed

__all__ = [
    "DampingTerm",
    "LoopDamping",
    "damping_term",
    "milling_damping",
    "milling_rubbing",
    "cutting_speed_at",
    "penetration",
]


def cutting_speed_at(process: Any, T: Any, diameter: float | None) -> Any:
    """The cutting speed V (m/s) at the delay T (s): the process's speed for
    T (:meth:`speed_for_delay`), a shaper's work speed itself, a spindle
    speed turned into pi D n / 60 at the diameter D (m)."""
    v = process.speed_for_delay(T)
    if process.kind == "shaping":
        return v
    if process.kind in ("turning", "milling"):
        if diameter is None:
            raise InputError(f"the cutting speed of {process.kind} needs a diameter")
        return cutting_speed(v, diameter)
    raise InputError(
        f"a {process.kind} process has no cutting speed: process damping needs turning, shaping or milling"
    )


@dataclass(frozen=True, eq=False)
class DampingTerm:
    """The process-damping term of one closed loop, Eq. (2): the loop's
    D_V is ``D_V + width * gain(T) * W``.

    Attributes
    ----------
    W : ndarray, shape (p, p)
        n n^T on the loop's process coordinates (milling: the averaged W_0),
        per unit width and unit gain.
    C_pd : float
        The linear coefficient, N/m.
    process : Process or Milling
        The kinematics whose ``speed_for_delay`` gives the speed at T.
    diameter : float or None
        D of pi D n / 60, m (None for a shaper).
    K_sp, wear_land, clearance : float
        The indentation model when given (N/m^3, m, rad; nan otherwise):
        the time domain's nonlinear force; C_pd = K_sp wear_land^2 / 4.
    block : slice
        The rows of the process coordinates the damped coupling occupies.
    """

    W: np.ndarray
    C_pd: float
    process: Any
    diameter: float | None
    K_sp: float = float("nan")
    wear_land: float = float("nan")
    clearance: float = float("nan")
    block: slice = field(default_factory=lambda: slice(None))

    def speed(self, T: Any) -> Any:
        """Cutting speed V (m/s) at the delay T (s)."""
        return cutting_speed_at(self.process, T, self.diameter)

    def gain(self, T: Any) -> Any:
        """g(T) = C_pd / V(T), N s/m^2: the damping per unit width at the delay T."""
        return self.C_pd / self.speed(T)

    def matrix(self, T: float, width: float) -> np.ndarray:
        """The term of D_V at the delay T and width b: b g(T) W, N s/m."""
        return (width * float(self.gain(T))) * self.W

    @property
    def indentation(self) -> bool:
        return not math.isnan(self.K_sp)

    def meta(self) -> dict[str, Any]:
        """What a result says of this term (files, plots): the coefficient, which
        model gave it, the indentation fields and the cutting diameter."""
        return {
            "C_pd": float(self.C_pd),
            "model": "indentation (linearised: C_pd = K_sp w^2 / 4)" if self.indentation else "linear",
            "K_sp": float(self.K_sp),
            "wear_land": float(self.wear_land),
            "clearance_deg": float(np.degrees(self.clearance)),
            "diameter": float("nan") if self.diameter is None else float(self.diameter),
        }

    def milling_cutter(self) -> Any:
        """The cutter whose directional matrices are the rubbing teeth's
        r_j r_j^T (K_t = 0, K_n = 1): :meth:`Milling.directional` of it is
        W_j(t), its :meth:`Milling.zoa` is W_0 (milling only)."""
        if self.process.kind != "milling":
            raise InputError("the rubbing teeth belong to a milling process")
        return replace(self.process, Kt=0.0, Kn=1.0, Kte=0.0, Kne=0.0)


@dataclass(frozen=True, eq=False)
class LoopDamping:
    """A :class:`DampingTerm` at the delay of a loop (s): the loop's D_V
    holds ``matrix(width)`` (:attr:`chatterlab.process.ClosedLoop.damping`)."""

    term: DampingTerm
    delay: float

    def matrix(self, width: float) -> np.ndarray:
        """b g(T) W at the loop's delay T, N s/m (zero while a milling loop
        has no speed yet: delay nan)."""
        if math.isnan(self.delay):
            return np.zeros_like(self.term.W)
        return self.term.matrix(self.delay, width)


def milling_rubbing(loop: Any, rpm: float) -> tuple[float, Any] | None:
    """The periodic process-damping term of a milling loop at the spindle
    speed ``rpm`` for the Floquet engines: (g, cutter) with g = C_pd / V the
    gain per unit depth (N s/m^2, V = pi D n / 60 at the cutter's diameter,
    a constant at one speed) and the cutter of the rubbing teeth (the loop's
    own cutter with K_t = 0, K_n = 1: its directional matrices are
    W_j(t) = g_j(t) r_j r_j^T, Eq. 4 of docs/process-damping.md), so that
    the tool feels -a_p g sum_j W_j(t) r'(t); None without process damping
    (the loop's equations are then exactly those without the term)."""
    damping = getattr(loop, "damping", None)
    if damping is None or damping.term.C_pd == 0.0:
        return None
    if hasattr(loop.milling, "delays_at"):
        # a varying spindle speed varies the gain too: not in the Floquet engines yet
        # (docs/process-damping.md, "What is not there yet"); the SSV routes take the loop without it
        return None
    term = damping.term
    g = term.C_pd / cutting_speed(float(rpm), term.diameter)
    return float(g), replace(loop.milling, Kt=0.0, Kn=1.0, Kte=0.0, Kne=0.0)


def _normal(coupling: Any, angle: float | None) -> np.ndarray:
    """Unit normal of the cut in CE axes (3,): at ``angle`` (rad), or the
    direction the coupling's delayed term regenerates (the right singular
    vector of its D_O, rank one: the chip thickness)."""
    if angle is not None:
        return np.array([math.cos(angle), math.sin(angle), 0.0])
    _, _, vt = np.linalg.svd(np.array(coupling.DO, dtype=float))
    return vt[0]


def milling_damping(milling: Any, C_pd: float, **indentation: float) -> DampingTerm:
    """The averaged term of a milling cutter on the tool's (x, y): W_0 of the
    rubbing teeth (:meth:`DampingTerm.milling_cutter`), the cutting speed
    pi D n / 60 at the cutter's diameter."""
    W0 = replace(milling, Kt=0.0, Kn=1.0, Kte=0.0, Kne=0.0).zoa()
    return DampingTerm(W0, float(C_pd), milling, milling.diameter, block=slice(0, 2), **indentation)


def damping_term(model: Any, couplings: list[str] | None = None, milling: Any = None) -> DampingTerm | None:
    """The model's ``[process_damping]`` on the stacked CE coordinates of the
    couplings selected (the layout of :func:`chatterlab.process.ce_maps`), or
    None when the model has none, its C_pd is 0 (the loop is then exactly
    today's) or its coupling is not selected.  ``milling``: the cutter of a
    milling loop, whose process coordinates are the tool's (x, y)."""
    pd = getattr(model, "process_damping", None)
    if pd is None or pd.C_pd == 0.0:
        return None
    proc = model.process
    extra = {"K_sp": pd.K_sp, "wear_land": pd.wear_land, "clearance": pd.clearance}
    if milling is not None or proc.kind == "milling":
        from ._milling import Milling

        cutter = milling if milling is not None else Milling.from_cut(proc.milling, proc.speed)
        if milling is not None:  # a milling loop: the tool's (x, y)
            return milling_damping(cutter, pd.C_pd, **extra)
        W0 = milling_damping(cutter, pd.C_pd).W
    chosen = [c for c in model.couplings if couplings is None or c.id in couplings]
    ids = [c.id for c in chosen]
    if pd.coupling not in ids:
        return None
    k = ids.index(pd.coupling)
    c = chosen[k]
    W = np.zeros((3 * len(chosen), 3 * len(chosen)))
    if c.kind == "milling":
        W[3 * k : 3 * k + 2, 3 * k : 3 * k + 2] = W0
        diameter: float | None = proc.milling.diameter
    else:
        n = _normal(c, pd.normal)
        W[3 * k : 3 * k + 3, 3 * k : 3 * k + 3] = np.outer(n, n)
        diameter = model.machine.workpiece_diameter if proc.kind == "turning" else None
    return DampingTerm(W, pd.C_pd, proc, diameter, block=slice(3 * k, 3 * k + 3), **extra)


# ---------------------------------------------------------------------------- the indentation model
def flank_interference(
    u_now: float, xi: np.ndarray, surface: np.ndarray, wear_land: float, clearance: float
) -> np.ndarray:
    """The interference depth of the flank with the surface behind the edge,
    m, at the distances ``xi`` (m, increasing from 0) where the surface is
    ``surface`` (the tool's penetration into the material when it passed
    there, m; the edge cuts at ``u_now`` now): the flank is flat along the
    wear land and rises at the clearance angle beyond it,

        delta(xi) = u_now - max(xi - w, 0) tan(gamma) - surface(xi)

    (positive: material under the flank; docs/process-damping.md, Eq. 5)."""
    xi = np.asarray(xi, dtype=float)
    return u_now - np.maximum(xi - wear_land, 0.0) * math.tan(clearance) - np.asarray(surface, dtype=float)


def indented_area(delta: np.ndarray, xi: np.ndarray) -> float:
    """Area of material under the flank per unit width, m^2: the integral of
    the positive part of ``delta`` over ``xi``, exact for ``delta`` linear
    between the samples (a crossing of zero is located in its interval; the
    wear land's end should be a sample)."""
    d = np.asarray(delta, dtype=float)
    x = np.asarray(xi, dtype=float)
    d0, d1, h = d[:-1], d[1:], x[1:] - x[:-1]
    p0, p1 = d0 > 0, d1 > 0
    area = 0.5 * float(np.dot(p0 & p1, (d0 + d1) * h))
    cross = p0 != p1
    if cross.any():
        # the positive part is a triangle from the positive end to the zero crossing:
        # height pos, base h pos / (|d0| + |d1|)
        c0, c1, hc = d0[cross], d1[cross], h[cross]
        pos = np.where(c0 > 0, c0, c1)
        area += 0.5 * float(np.sum(pos * pos * hc / (np.abs(c0) + np.abs(c1))))
    return area


def penetration(model: Any) -> np.ndarray:
    """The indentation model's penetration direction p in CE axes (3,), unit,
    pointing into the material: u = p . dw grows as the tool digs in (the
    flank's area, docs/process-damping.md Eq. 6a, is not symmetric in u).

    The sign is the chip's: ``normal_deg`` (and a ``regenerative``
    coupling's ``normal_angle_deg``) is the direction in which a displacement
    of a relative to b thins the chip, so p = -n; a ``grasso`` coupling's axis
    2 thins it (its thrust points away from the workpiece); a ``matrices``
    coupling's n is its D_O's direction signed by the static cutting force,
    which pushes the tool out of the material (n . P0 > 0).  The linear
    terms alone cannot tell (they are odd in dw)."""
    pd = model.process_damping
    c = next(c for c in model.couplings if c.id == pd.coupling)
    if pd.normal is not None:
        n = _normal(c, pd.normal)
    elif c.kind == "regenerative":
        n = _normal(c, math.radians(dict(c.params)["normal_angle_deg"]))
    elif c.kind == "grasso":
        n = np.array([0.0, 1.0, 0.0])
    else:
        n = _normal(c, None)
        side = float(n @ np.array(c.forces, dtype=float))
        if side == 0.0:
            raise InputError(
                f"[process_damping]: the indentation model needs the side of the material, which coupling"
                f" '{c.id}' does not show (no static force along its normal): give normal_deg, the direction"
                " that thins the chip (deg, from CE axis 1)"
            )
        n = n if side > 0 else -n
    return -n
