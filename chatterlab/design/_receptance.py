"""The structure's receptance between the coupling-element coordinates, with
the machine's actuators in it, at one frequency -- what the critical point
(:mod:`chatterlab.design._critical`) and the limits
(:mod:`chatterlab.design._limits`) evaluate.

With actuators (:class:`chatterlab.process.Actuators`) the dynamic stiffness
the cut sees is

    Z_c(w) = K - w^2 M + j w C - D_a(j w),   D_a(s) = -F_a diag(G(s)) S_a,
    G_k(s) = (P_k + s V_k + O_k e^{-s T_k}) / (1 + s L_k),                  (1)

(the controller's transfer, evaluated once by :meth:`Actuators.gains`), so
H = J Z_c^-1 J^T is :func:`chatterlab.structure.dynamic_receptance` with the
actuators' term subtracted.  The derivatives of the limit also need
dZ_c/dw and the partial derivatives of G_k with respect to its gains, delay
and time constant, which are closed forms of (1):

    dG/dw   = j [V - T O e^{-jwT}] / (1 + jwL) - j L G / (1 + jwL),
    dG/dP   = 1 / (1 + jwL),  dG/dV = j w / (1 + jwL),  dG/dO = e^{-jwT} / (1 + jwL),
    dG/dT   = -j w O e^{-jwT} / (1 + jwL),   dG/dL = -j w G / (1 + jwL).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..structure import dynamic_receptance

__all__ = ["Control", "control_at", "receptances", "receptance"]


@dataclass(frozen=True)
class Control:
    """The actuators' term at one frequency w (rad/s): D_a(jw) (n, n), its
    derivative in w, the transfers G (m,) and their partial derivatives (m,)
    by gain (``dP``, ``dV``, ``dO``), delay (``dT``) and time constant (``dL``)."""

    Da: np.ndarray
    dDa: np.ndarray
    G: np.ndarray
    dG: np.ndarray
    dP: np.ndarray
    dV: np.ndarray
    dO: np.ndarray
    dT: np.ndarray
    dL: np.ndarray


def control_at(L: Any, w: float) -> Control | None:
    """The actuators' term of the loop matrices ``L`` at w (None without actuators)."""
    acts = L.actuators
    if acts is None:
        return None
    jw = 1j * w
    G = acts.gains(jw)
    lag = 1.0 + jw * L.La
    e = np.exp(-jw * L.Ta)
    dP = 1.0 / lag
    dV = jw / lag
    dO = e / lag
    dT = -jw * L.Oa * e / lag
    dL = -jw * G / lag
    dG = 1j * (L.Va - L.Ta * L.Oa * e) / lag - 1j * L.La * G / lag
    Da = acts.D(jw)
    dDa = -(L.Fa * dG[None, :]) @ L.Sa
    return Control(Da, dDa, G, dG, dP, dV, dO, dT, dL)


def receptances(L: Any, w: float, ctl: Control | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(GR, GL, H)``: Z_c^-1 J^T (n, p), J Z_c^-1 (p, n) and H = J Z_c^-1 J^T
    (p, p) at w, from :func:`chatterlab.structure.dynamic_receptance` (GL as
    the transpose of Z_c^-T J^T: p right-hand sides, not an inverse)."""
    if ctl is None:
        ctl = control_at(L, w)
    n = L.M.shape[0]
    eye = np.eye(n)
    Jt = L.J.T.astype(complex)
    minus = None if ctl is None else ctl.Da[None]
    GR = dynamic_receptance(L.M, L.C, L.K, np.array([w]), eye, Jt, minus=minus)[0]
    minus_t = None if ctl is None else ctl.Da.T[None]
    GL = dynamic_receptance(L.M.T, L.C.T, L.K.T, np.array([w]), eye, Jt, minus=minus_t)[0].T
    return GR, GL, L.J @ GR


def receptance(L: Any, omega: Any) -> np.ndarray:
    """H(w) = J Z_c(w)^-1 J^T at the angular frequencies ``omega`` (rad/s),
    shape (len(omega), p, p): the structure with its actuators as the cut
    sees it (the controlled plant of the lobe engine)."""
    w = np.atleast_1d(np.asarray(omega, dtype=float))
    acts = L.actuators
    minus = None if acts is None else acts.D(1j * w)
    return dynamic_receptance(L.M, L.C, L.K, w, L.J, minus=minus)
