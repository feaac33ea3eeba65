"""Interoperability with python-control.

The one way in each direction is the FRF's: :meth:`FRF.to_control
<chatterlab.structure.FRF.to_control>` and :meth:`FRF.from_control
<chatterlab.structure.FRF.from_control>`; here

* :func:`lti_plant` -- a python-control LTI system (``StateSpace`` or
  ``TransferFunction``) standing in for the structure: its inputs are the
  forces at the coupling element (on point a, in CE axes) and its outputs
  the relative displacements dw there (m/N).  With it, :func:`lobes_lti`
  draws stability lobes and :func:`closed_loop_lti` gives the closed-loop
  response, with the same cutting-process matrices as a model file's
  ``[[coupling]]`` and exact delays (python-control itself offers only Padé
  approximations of e^{-sT}).

python-control is imported inside the functions.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import InputError, check_delay, check_width
from ..model._items import Coupling, Process
from ..process import coupling_matrix
from ..structure import FRF
from ._diagram import LobeDiagram, Plant, lobes

__all__ = ["lti_plant", "lobes_lti", "closed_loop_lti", "coupling_matrices"]


def coupling_matrices(coupling: Coupling) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(DP, DV, DO, width_ref) of a model's coupling element (3 x 3 each)."""
    return (np.array(coupling.DP), np.array(coupling.DV), np.array(coupling.DO), coupling.width_ref)


def _check_lti(lti: Any) -> int:
    import control

    if not isinstance(lti, control.LTI):
        raise InputError(
            f"expected a python-control LTI system (StateSpace or TransferFunction), got {type(lti).__name__}"
        )
    if lti.ninputs != lti.noutputs:
        raise InputError(
            f"the LTI system must map the coupling forces to the coupling displacements: as many inputs as"
            f" outputs (got {lti.ninputs} inputs, {lti.noutputs} outputs)"
        )
    if not lti.isctime():
        raise InputError("the LTI system must be continuous-time")
    return int(lti.ninputs)


def _matrices(m: int, DP: Any, DV: Any, DO: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    out = []
    for name, X in (("DP", DP), ("DV", DV), ("DO", DO)):
        A = np.zeros((m, m)) if X is None else np.atleast_2d(np.asarray(X, dtype=float))
        if A.shape == (3, 3) and m < 3:
            A = A[:m, :m]  # a 3x3 CE matrix on a plant with fewer coordinates
        if A.shape != (m, m):
            raise InputError(
                f"{name} must be {m}x{m} to match the LTI system's {m} inputs (got shape {A.shape})"
            )
        if not np.all(np.isfinite(A)):
            raise InputError(f"{name} holds non-finite entries")
        out.append(A)
    return out[0], out[1], out[2]


def lti_plant(lti: Any, *, DP: Any = None, DV: Any = None, DO: Any, width_ref: float) -> Plant:
    """A :class:`~chatterlab.lobes._diagram.Plant` from a python-control LTI system.

    Parameters
    ----------
    lti : control.StateSpace or control.TransferFunction
        m inputs (forces at the CE, N) and m outputs (relative displacements
        dw = w_a - w_b, m), continuous time.
    DP, DV, DO : array (m, m)
        The cutting process at ``width_ref`` with the CE convention: force on
        point a = P0 - (DP dw + DV dw' + DO dw(t - T)).
    width_ref : float
        Width of cut (m) the matrices are given for.
    """
    m = _check_lti(lti)
    width_ref = check_width(width_ref, "width_ref")
    P, V, O = _matrices(m, DP, DV, DO)

    def H(omega: np.ndarray) -> np.ndarray:
        # the system at j w through the one route in (FRF.from_control), one matrix per frequency
        return np.moveaxis(FRF.from_control(lti, omega).data, -1, 0)

    return Plant(
        H, np.asarray(lti.poles()), P / width_ref, V / width_ref, O / width_ref, _pole_residue(lti, m)
    )


def _pole_residue(lti: Any, m: int) -> Any:
    """H(s) = C S (s - Lambda)^-1 S^-1 B + D from the state space, or None
    when the eigenvector matrix is ill-conditioned (the band is then not
    certified)."""
    import control

    from ..frequency._bounds import PoleResidue

    ss = control.ss(lti)
    A, B, C, D = (np.asarray(x, dtype=float) for x in (ss.A, ss.B, ss.C, ss.D))
    if A.size == 0:
        return PoleResidue(np.zeros(0, complex), np.zeros((m, 0)), np.zeros((0, m)), D.reshape(m, m))
    p, S = np.linalg.eig(A)
    if np.linalg.cond(S) > 1e8:
        return None
    return PoleResidue(p, C @ S, np.linalg.solve(S, B.astype(complex)), D.reshape(m, m))


def lobes_lti(
    lti: Any,
    speeds: np.ndarray,
    *,
    process: Process,
    DO: Any,
    width_ref: float,
    DP: Any = None,
    DV: Any = None,
    width_max: float = 0.02,
    fmin: float | None = None,
    fmax: float | None = None,
    name: str = "python-control LTI structure",
) -> LobeDiagram:
    """Stability lobes of a python-control LTI structure (see :func:`lti_plant`).

    The D-subdivision is the same as for a model (with the band certified
    from the state space's pole-residue form); the argument-principle checks
    need the structure's matrices and are not run.
    """
    plant = lti_plant(lti, DP=DP, DV=DV, DO=DO, width_ref=width_ref)
    return lobes(
        None,
        speeds,
        width_max=width_max,
        process=process,
        fmin=fmin,
        fmax=fmax,
        verify=0,
        plant=plant,
        name=name,
    )


def closed_loop_lti(
    lti: Any,
    omega: np.ndarray,
    *,
    width: float,
    delay: float | None,
    width_ref: float,
    DP: Any = None,
    DV: Any = None,
    DO: Any = None,
) -> FRF:
    """Closed-loop FRF at the CE coordinates, H_cl = (I + H Dl)^-1 H with
    Dl(jw) = (b / b_ref)(DP + jw DV + DO e^{-jwT}) and the exact delay."""
    m = _check_lti(lti)
    P, V, O = _matrices(m, DP, DV, DO)
    width = check_width(width, "width")
    if np.any(O):
        if delay is None:
            raise InputError("the delayed term needs a delay > 0 s (got None)")
        delay = check_delay(delay, "delay")
    w = np.asarray(omega, dtype=float)
    H = lti_plant(lti, DP=P, DV=V, DO=O, width_ref=width_ref).H(w)
    f = width / width_ref
    Dl = f * coupling_matrix(1j * w, P, V, O, delay if np.any(O) else None)
    Hcl = np.linalg.solve(np.eye(m)[None] + H @ Dl, H)
    names = tuple(f"ce.{k + 1}" for k in range(m))
    return FRF(
        omega=w,
        data=np.transpose(Hcl, (1, 2, 0)),
        outputs=names,
        inputs=names,
        closed_loop=True,
        method="lti",
        width=float(width),
        delay=delay,
        terms="pdo" if np.any(O) else "pd",
    )
