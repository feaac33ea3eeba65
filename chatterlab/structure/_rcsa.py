"""Receptance coupling: a measured (or computed) substructure joined to a
modelled one through a rigid or a spring-damper joint.

Substructure A (the spindle-holder, known by its receptance at the coupling
point) and substructure B (the tool: chatterlab Timoshenko beams, free-free)
are joined at coupling coordinates -- the translation and the rotation of
the bending plane, (y, rz), or all three plane coordinates (x, y, rz).  With
the uncoupled receptance H = diag(H_A, H_B) over all coordinates, the
signed Boolean matrix Bc that picks u_B,c - u_A,c, and the joint's dynamic
stiffness Z(w) = diag(k_j + j w c_j) (so the interface force is
lambda = Z Bc u), the assembled receptance is (Lagrange-multiplier
frequency-based substructuring, de Klerk et al. [3])::

    G = H - H Bc^T (Bc H Bc^T + Z^-1)^-1 Bc H,

Z^-1 = 0 for a rigid joint.  For the tool point t of B with coupling
coordinates c (B side) and a (A side) this is Schmitz & Duncan's RCSA
[1, 2] in its receptance-matrix form::

    G_tt = H_tt - H_tc (H_cc + H_aa + Z^-1)^-1 H_ct

with H_aa = [[h_ff, h_fm], [n_ff, n_fm]] the holder's displacement/rotation
to force/moment receptances (2 x 2 per frequency) -- the 2 x 2 matrix
form of the equations of [1] (their eq. (4) with the joint as an extra
compliance).  It is exact: with the substructures' *computed* receptances
the result equals the full model's FRF to round-off (tests/test_rcsa.py).

Rotational receptances of a measured holder.  A tap test gives h_ff (force
to displacement) only.  Two ways to the rest, both here:

* **finite differences** (:func:`rotations_from_translations`): measure
  the translational receptances at the holder end (0) and at one or two
  points a distance ``s`` apart back along the axis; then, with two
  points, n_ff ~ (h_00 - h_10)/s, h_fm = n_ff (reciprocity) and
  n_fm ~ (h_00 - h_01 - h_10 + h_11)/s^2 (Duarte & Ewins [4]), or the
  three-point differences.  Cost, measured in tests/test_rcsa.py on a
  cantilever: the rotation per force errs by O(s^2), the rotation per
  moment by O(s) (a force couple is not a pure moment over the stencil:
  ~ s / L, 3 % at s = 4 mm on an 80 mm holder with two points, half that
  with three); differences of the deflection give its slope, which on a
  stubby Timoshenko holder includes the shear angle (9 % on the cross
  term of a 40 mm x 80 mm steel holder), and a couple on a short segment
  shears it (a spurious 1 / (kappa G A s)); the noise is amplified by ~1/s
  for n_ff and ~2/s^2 for n_fm relative to the displacement noise, since
  n_fm is a small second difference of large receptances.  The reason RCSA
  is done with rotations from a model where one exists;
* **a model of the holder** (a chatterlab model, or a modal fit's model),
  whose rotation receptances are computed (:func:`receptance`).

References
----------
.. [1] T. L. Schmitz, G. S. Duncan, "Three-component receptance coupling
   substructure analysis for tool point dynamics prediction", J. Manuf. Sci.
   Eng. 127(4), 781-790, 2005.
.. [2] T. L. Schmitz, R. R. Donalson, "Predicting high-speed machining
   dynamics by substructure analysis", CIRP Annals 49(1), 303-308, 2000.
.. [3] D. de Klerk, D. J. Rixen, S. N. Voormeeren, "General framework for
   dynamic substructuring: history, review, and classification of
   techniques", AIAA J. 46(5), 1169-1181, 2008.
.. [4] M. L. M. Duarte, D. J. Ewins, "Rotational degrees of freedom for
   structural coupling analysis via finite-difference technique with
   residual compensation", Mech. Syst. Signal Process. 14(2), 205-227, 2000.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError
from ._complex import dynamic_receptance
from ._frf import FRF

__all__ = [
    "Joint",
    "JointFit",
    "couple",
    "couple_tool",
    "identify_joint",
    "receptance",
    "rotations_from_translations",
    "tool_model",
]


# ============================================================================ the joint


@dataclass(frozen=True)
class Joint:
    """Joint between the substructures: per coupling coordinate a stiffness
    (N/m, or N m/rad for a rotation; ``inf``: rigid) and a viscous damping
    (N s/m, N m s/rad)."""

    stiffness: tuple[float, ...]
    damping: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        k = tuple(float(x) for x in self.stiffness)
        c = tuple(float(x) for x in self.damping) if self.damping else (0.0,) * len(k)
        if len(c) != len(k):
            raise InputError(
                f"Joint: damping has {len(c)} values for {len(k)} stiffnesses; give one per coordinate"
            )
        for nm, vals in (("stiffness", k), ("damping", c)):
            if any(not (v >= 0) or math.isnan(v) for v in vals):
                raise InputError(f"Joint: {nm} must be >= 0 (inf: rigid), got {vals}")
        if any(kk == 0 and cc == 0 for kk, cc in zip(k, c, strict=True)):
            raise InputError(
                "Joint: a coordinate with zero stiffness and damping is not joined; give k > 0 or inf"
            )
        object.__setattr__(self, "stiffness", k)
        object.__setattr__(self, "damping", c)

    @classmethod
    def rigid(cls, n: int = 2) -> Joint:
        """A rigid joint on n coupling coordinates."""
        return cls((math.inf,) * n)

    @classmethod
    def spring(cls, k: float, k_rot: float, c: float = 0.0, c_rot: float = 0.0) -> Joint:
        """The (y, rz) joint of a tool in its holder: translational k (N/m),
        c (N s/m), rotational k_rot (N m/rad), c_rot (N m s/rad)."""
        return cls((k, k_rot), (c, c_rot))

    @property
    def n(self) -> int:
        return len(self.stiffness)

    def compliance(self, omega: np.ndarray) -> np.ndarray:
        """Z(w)^-1, shape (n_freq, n, n): 1 / (k + j w c), 0 where rigid."""
        w = np.asarray(omega, dtype=float)
        out = np.zeros((w.size, self.n, self.n), complex)
        for j, (k, c) in enumerate(zip(self.stiffness, self.damping, strict=True)):
            if math.isinf(k) or math.isinf(c):
                continue
            out[:, j, j] = 1.0 / (k + 1j * w * c)
        return out


# ============================================================================ receptances


def _frozen(structure: Any) -> Any:
    """A FrozenSystem from a Model, System or FrozenSystem."""
    from ._system import FrozenSystem, System

    if isinstance(structure, System):
        return structure.at()
    if not isinstance(structure, FrozenSystem):
        from ._assembly import assemble

        return assemble(structure).at()
    return structure


def _stack(frozen: Any, outputs: Any, inputs: Any, omega: Any) -> np.ndarray:
    """The receptance between POINT.DIR specs, one matrix per frequency
    (n_freq, n_out, n_in) (:func:`dynamic_receptance` on the frozen
    matrices)."""
    outs = [outputs] if isinstance(outputs, str) else list(outputs)
    ins = [inputs] if isinstance(inputs, str) else list(inputs)
    w = np.asarray(omega, dtype=float)
    if w.ndim != 1 or np.any(~np.isfinite(w)) or np.any(w <= 0):
        raise InputError("receptance: omega must be a 1-D array of frequencies > 0 rad/s")
    Co = np.array([frozen.dof(s) for s in outs])
    Bi = np.array([frozen.dof(s) for s in ins]).T
    return dynamic_receptance(frozen.A, frozen.B, frozen.C, w, Co, Bi)


def receptance(structure: Any, outputs: Any, inputs: Any, omega: Any) -> FRF:
    """Receptance of a chatterlab structure (Model, System or
    FrozenSystem) between ``POINT.DIR`` specs at ``omega`` (rad/s), by one
    linear solve per frequency of (-w^2 A + j w B + C)
    (:func:`dynamic_receptance`) -- valid for a free-free structure
    (rigid-body modes) at w > 0, where the complex modes are not."""
    frozen = _frozen(structure)
    outs = [outputs] if isinstance(outputs, str) else list(outputs)
    ins = [inputs] if isinstance(inputs, str) else list(inputs)
    G = _stack(frozen, outs, ins, omega)
    return FRF(
        omega=np.asarray(omega, dtype=float),
        data=np.ascontiguousarray(np.moveaxis(G, 0, -1)),
        outputs=tuple(outs),
        inputs=tuple(ins),
        position=frozen.position,
        source=f"model {frozen.model.source}",
    )


def rotations_from_translations(H: Any, spacing: float) -> np.ndarray:
    """The 2 x 2 (y, rz) receptance at point 0 from translational
    receptances at points 0, 1 (and 2) spaced ``spacing`` (m) *back* along
    the axis (towards the spindle; the tool along +x, rz counter-clockwise),
    by finite differences (Duarte & Ewins [4]).

    ``H`` is one matrix per frequency (n_freq, n_p, n_p; an FRF's
    ``matrices``): h_ij = displacement at i per force at j,
    n_p = 2 (theta_0 ~ (y_0 - y_1)/s) or n_p = 3 (theta_0 ~ (3 y_0 - 4 y_1 +
    y_2)/(2 s)); the errors (module docstring): O(s^2) on the rotation per
    force, O(s) on the rotation per moment (half as large with three
    points), plus the shear of a Timoshenko holder.
    With the difference row d (d = (1, -1)/s or (3, -4, 1)/(2 s)) and
    e_0 = (1, 0[, 0]): [[e H e^T, e H d^T], [d H e^T, d H d^T]] -- a
    moment is applied as the force couple d, a rotation read as d y.
    Shape (n_freq, 2, 2)."""
    s = float(spacing)
    if not (math.isfinite(s) and s > 0):
        raise InputError(f"rotations_from_translations: spacing must be > 0 m (got {spacing!r})")
    Hc = np.asarray(H, dtype=complex)
    if Hc.ndim != 3 or Hc.shape[1] != Hc.shape[2] or Hc.shape[1] not in (2, 3):
        raise InputError(
            f"rotations_from_translations: H must be (n_freq, n_p, n_p) with n_p = 2 or 3 points (got {Hc.shape})"
        )
    n_p = Hc.shape[1]
    d = np.array([1.0, -1.0]) / s if n_p == 2 else np.array([3.0, -4.0, 1.0]) / (2 * s)
    T = np.vstack([np.eye(n_p)[0], d])  # (2, n_p)
    return T @ Hc @ T.T


def couple(
    HA: np.ndarray,
    HB: np.ndarray,
    a: Any,
    b: Any,
    compliance: np.ndarray | None = None,
) -> np.ndarray:
    """Assembled receptance of two substructures (module docstring).

    Parameters
    ----------
    HA : (n_freq, nA, nA), HB : (n_freq, nB, nB)
        Receptances of A and B over their coordinates, one matrix per
        frequency (an FRF's ``matrices``: the layout of the batched solve).
    a, b : sequence of int
        The coupling coordinates in A and in B, in matching order.
    compliance : (n_freq, n_c, n_c), optional
        Z^-1 of the joint (None: rigid).

    Returns
    -------
    (n_freq, nA + nB, nA + nB): G over [A's coordinates, B's coordinates].
    """
    HA = np.asarray(HA, complex)
    HB = np.asarray(HB, complex)
    a, b = list(a), list(b)
    if len(a) != len(b) or not a:
        raise InputError(
            f"couple: a and b must list the same number (>= 1) of coupling coordinates ({a}, {b})"
        )
    nf, nA, nB = HA.shape[0], HA.shape[1], HB.shape[1]
    if HB.shape[0] != nf:
        raise InputError(f"couple: HA and HB hold {nf} and {HB.shape[0]} frequencies; use the same grid")
    n = nA + nB
    H = np.zeros((nf, n, n), complex)
    H[:, :nA, :nA] = HA
    H[:, nA:, nA:] = HB
    Bc = np.zeros((len(a), n))
    for j, (ia, ib) in enumerate(zip(a, b, strict=True)):
        Bc[j, ia] = -1.0
        Bc[j, nA + ib] = 1.0
    HBt = H @ Bc.T  # (nf, n, n_c)
    S = Bc @ HBt  # (nf, n_c, n_c) = H_aa + H_bb at the interface
    if compliance is not None:
        S = S + compliance
    return H - HBt @ np.linalg.solve(S, Bc @ H)


# ============================================================================ tool model


def tool_model(
    length: float,
    diameter: float,
    *,
    E: float = 6.0e11,
    nu: float = 0.22,
    rho: float = 14500.0,
    eta: float = 0.0,
    elements: int = 8,
    effective: float = 1.0,
    name: str = "tool",
) -> Any:
    """A free-free tool: one Timoshenko beam from node ``base`` (x = 0) to
    node ``tip`` (x = length) along +x, bending in the x-y plane (points
    ``base`` and ``tip``, coordinates x, y, rz).  Defaults: solid carbide
    (E 600 GPa, rho 14 500 kg/m^3); ``effective`` scales the diameter of the
    section (about 0.8 for the fluted part of an end mill, Kops & Vo).
    ``eta``: Kelvin-Voigt damping coefficient (N s/m^2).  A circular section:
    A = pi d^2 / 4, I = pi d^4 / 64, kappa = 6 (1 + nu) / (7 + 6 nu)
    (Cowper's shear coefficient of a solid circle)."""
    from ..model._reader import build_model

    for nm, v in (
        ("length", length),
        ("diameter", diameter),
        ("E", E),
        ("rho", rho),
        ("effective", effective),
    ):
        if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
            raise InputError(f"tool_model: {nm} must be > 0 (got {v!r})")
    if isinstance(elements, bool) or not isinstance(elements, int) or elements < 1:
        raise InputError(f"tool_model: elements must be an integer >= 1 (got {elements!r})")
    d = effective * diameter
    raw = {
        "model": {"name": name},
        "node": [{"id": "base", "at": [0.0, 0.0]}, {"id": "tip", "at": [float(length), 0.0]}],
        "beam": [
            {
                "id": "tool",
                "nodes": ["base", "tip"],
                "E": float(E),
                "nu": float(nu),
                "rho": float(rho),
                "A": math.pi * d**2 / 4,
                "I": math.pi * d**4 / 64,
                "kappa": 6 * (1 + nu) / (7 + 6 * nu),
                "eta": float(eta),
                "elements": elements,
            }
        ],
    }
    return build_model(raw, source=f"tool_model({length:g} m x {diameter:g} m)")


# ============================================================================ tool on holder


def _as_frf(frf: Any, what: str) -> FRF:
    """An FRF (receptance) from an FRF or a tuple (omega rad/s, data
    (n_out, n_in, n_freq) or (n_freq,)) whose coordinate k is ``ck``."""
    if isinstance(frf, tuple) and len(frf) == 2:
        shape = np.shape(frf[1])
        n_o, n_i = shape[:2] if len(shape) == 3 else (1, 1)
        outs = tuple(f"c{k}" for k in range(n_o))
        return FRF.from_arrays(frf[0], frf[1], outs, tuple(f"c{k}" for k in range(n_i)), source="arrays")
    if not isinstance(frf, FRF):
        raise InputError(f"{what} must be an FRF or a tuple (omega, data), got {type(frf).__name__}")
    return frf.as_kind("receptance")


def _holder_arrays(
    holder: Any, coords: tuple[str, ...] | None, func: str = "couple_tool"
) -> tuple[FRF, np.ndarray, np.ndarray, tuple, str]:
    """(the holder FRF, omega, its matrices (n_freq, n_c, n_c) over the
    coupling coordinates, those coordinates, its source)."""
    frf = _as_frf(holder, f"{func}: holder")
    outs, ins = frf.outputs, frf.inputs
    use = coords if coords is not None else outs
    for c in use:
        if c not in outs or c not in ins:
            raise InputError(
                f"{func}: the holder FRF ({frf.source}) has no coupling coordinate '{c}'"
                f" as output and input (it has outputs {', '.join(outs)}; inputs {', '.join(ins)}); give its"
                " (y, rz) receptances, e.g. from rotations_from_translations"
            )
    io = [outs.index(c) for c in use]
    ii = [ins.index(c) for c in use]
    H = frf.matrices[:, io][:, :, ii]
    return frf, np.asarray(frf.omega, float), H, tuple(use), frf.source or "holder"


def couple_tool(
    holder: Any,
    tool: Any,
    *,
    joint: Joint | None = None,
    holder_coords: tuple[str, ...] | None = None,
    directions: tuple[str, ...] = ("y", "rz"),
    base: str = "base",
    outputs: Any = ("tip.y",),
    inputs: Any = None,
    omega: Any = None,
) -> Any:
    """Tool-point receptance of a modelled tool on a measured holder (RCSA).

    Parameters
    ----------
    holder : FRF or tuple (omega, data)
        The holder's receptance at the coupling point over the coupling
        coordinates (e.g. ``holder.y``, ``holder.rz``); data (n_c, n_c,
        n_freq) in the FRF's axis order.
    tool : Model, System or FrozenSystem
        The free-free tool (:func:`tool_model`); its coupling point is
        ``base``.
    joint : Joint, optional
        Default rigid.
    holder_coords : tuple of str, optional
        The holder's coordinates in the order of ``directions`` (default:
        the holder FRF's outputs).
    directions : tuple of str
        Coupling directions at the tool's base (``("y", "rz")``, or all three).
    outputs, inputs : POINT.DIR specs on the tool (inputs default: outputs).
    omega : array, optional
        Frequencies, rad/s (default: the holder's).

    Returns
    -------
    FRF
        The assembled receptance at the tool's outputs/inputs, over the
        holder's band.
    """
    hfrf, w_h, HA, hc, src = _holder_arrays(holder, holder_coords)
    if len(hc) != len(directions):
        raise InputError(
            f"couple_tool: {len(hc)} holder coordinates ({', '.join(hc)}) for {len(directions)} directions"
            f" ({', '.join(directions)}); give one holder coordinate per direction"
        )
    jt = Joint.rigid(len(directions)) if joint is None else joint
    if jt.n != len(directions):
        raise InputError(f"couple_tool: the joint has {jt.n} coordinates, the coupling {len(directions)}")
    outs = [outputs] if isinstance(outputs, str) else list(outputs)
    ins = outs if inputs is None else ([inputs] if isinstance(inputs, str) else list(inputs))
    w = w_h if omega is None else np.asarray(omega, float)
    if omega is not None:
        sub = hfrf.select(list(hc), list(hc))
        HA = np.ascontiguousarray(np.moveaxis(sub.interpolate(w), -1, 0))
    G = _tool_point(HA, tool, jt, directions, base, outs, ins, w)
    return FRF.from_arrays(
        w,
        np.moveaxis(G, 0, -1),
        tuple(outs),
        tuple(ins),
        source=f"RCSA of {src} and {getattr(_model_of(tool), 'source', 'tool')}",
        method="rcsa",
    )


def _model_of(tool: Any) -> Any:
    return getattr(tool, "model", tool)


def _tool_point(
    HA: np.ndarray,
    tool: Any,
    joint: Joint,
    directions: tuple[str, ...],
    base: str,
    outs: list[str],
    ins: list[str],
    w: np.ndarray,
) -> np.ndarray:
    """G_tt = H_tt - H_tc (H_cc + H_aa + Z^-1)^-1 H_ct (module docstring)."""
    cpl = [f"{base}.{d}" for d in directions]
    fz = _frozen(tool)
    Hcc = _stack(fz, cpl, cpl, w)
    Htc = _stack(fz, outs, cpl, w)
    Hct = _stack(fz, cpl, ins, w)
    Htt = _stack(fz, outs, ins, w)
    S = Hcc + HA + joint.compliance(w)
    return Htt - Htc @ np.linalg.solve(S, Hct)


# ============================================================================ joint identification


@dataclass(frozen=True, eq=False)
class JointFit:
    """The identified joint and how well it reproduces the measured
    tool-point FRF: ``error`` is the rms of |log(G_model / G_measured)|
    (relative, both magnitude and phase), ``std`` the standard deviations
    of the fitted parameters (in the order of ``free``)."""

    joint: Joint
    free: tuple[str, ...]
    error: float
    std: np.ndarray
    message: str


def identify_joint(
    holder: Any,
    tool: Any,
    measured: Any,
    *,
    initial: Joint,
    free: tuple[str, ...] = ("k", "k_rot", "c", "c_rot"),
    output: str = "tip.y",
    holder_coords: tuple[str, ...] | None = None,
    band: tuple[float, float] | None = None,
) -> JointFit:
    """Fit the (y, rz) joint's k, k_rot, c, c_rot to a measured tool-point
    receptance (a 1 x 1 FRF, or the ``output`` entry of a larger
    one; ``output`` is the tool's point) by least squares on the complex log ratio
    log(G_model / G_measured) (magnitude and phase errors weighted alike,
    the maximum-likelihood choice for relative noise), over the logarithms
    of the free parameters (``scipy.optimize.least_squares``).  The
    identified joint is then reused for other overhangs (the idea of
    Schmitz & Duncan [1])."""
    from scipy.optimize import least_squares

    names = ("k", "k_rot", "c", "c_rot")
    for f in free:
        if f not in names:
            raise InputError(f"identify_joint: free parameter '{f}' is not one of {', '.join(names)}")
    if initial.n != 2:
        raise InputError("identify_joint: the initial joint must be a (y, rz) joint (Joint.spring)")
    x0 = dict(zip(names, (*initial.stiffness, *initial.damping), strict=True))
    for f in free:
        if not (0 < x0[f] < math.inf):
            raise InputError(f"identify_joint: the initial {f} must be finite and > 0 (got {x0[f]!r})")
    _, w_h, HA, _, _ = _holder_arrays(holder, holder_coords, "identify_joint")
    measured = _as_frf(measured, "identify_joint: measured")
    w_m = np.asarray(measured.omega, float)
    Hm = measured.data
    if Hm.shape[:2] == (1, 1):
        Gm = Hm[0, 0]  # a tap test's one FRF, whatever its coordinates are called
    elif output in measured.outputs and output in measured.inputs:
        Gm = Hm[list(measured.outputs).index(output), list(measured.inputs).index(output)]
    else:
        raise InputError(
            f"identify_joint: the measured FRF ({getattr(measured, 'source', '')}) has no '{output}' as output"
            f" and input (outputs {', '.join(measured.outputs)}); select() the tool-point entry"
        )
    if w_m.shape != w_h.shape or not np.allclose(w_m, w_h, rtol=1e-12, atol=0):
        raise InputError(
            "identify_joint: the holder and the measured tool-point FRF must share their frequencies"
        )
    sel = np.ones(w_m.size, bool) if band is None else (w_m >= band[0]) & (w_m <= band[1])
    w, HAs, Gms = w_m[sel], HA[sel], Gm[sel]
    cpl = ["base.y", "base.rz"]
    fz = _frozen(tool)
    Hcc = _stack(fz, cpl, cpl, w)
    Htc = _stack(fz, [output], cpl, w)
    Hct = _stack(fz, cpl, [output], w)
    Htt = _stack(fz, [output], [output], w)[:, 0, 0]

    def joint_of(x: np.ndarray) -> Joint:
        v = dict(x0)
        for f, xi in zip(free, x, strict=True):
            v[f] = float(np.exp(xi))
        return Joint.spring(v["k"], v["k_rot"], v["c"], v["c_rot"])

    def resid(x: np.ndarray) -> np.ndarray:
        S = Hcc + HAs + joint_of(x).compliance(w)
        G = Htt - (Htc @ np.linalg.solve(S, Hct))[:, 0, 0]
        r = np.log(G / Gms)
        return np.concatenate([r.real, r.imag])

    from ._fit import one_blas_thread

    xs = np.log([x0[f] for f in free])
    with one_blas_thread():
        sol = least_squares(resid, xs, method="lm", x_scale=1.0, xtol=1e-12, ftol=1e-12)
    dof = max(sol.fun.size - len(free), 1)
    s2 = float(sol.fun @ sol.fun) / dof
    try:
        cov = s2 * np.linalg.inv(sol.jac.T @ sol.jac)
        std = np.exp(sol.x) * np.sqrt(np.maximum(np.diag(cov), 0.0))
    except np.linalg.LinAlgError:
        std = np.full(len(free), np.nan)
    err = float(np.sqrt(np.mean(np.abs(sol.fun[: w.size] + 1j * sol.fun[w.size :]) ** 2)))
    return JointFit(joint_of(sol.x), tuple(free), err, std, str(sol.message))
