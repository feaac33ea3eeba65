"""A modal fit's own uncertainty, carried into a modal model:
:func:`uncertain_modal_model`.

:func:`chatterlab.structure.fit_modes` estimates the covariance of each
fitted pole's natural frequency and damping ratio from the refinement's
Jacobian, s^2 (J^T J)^-1 (``ModalFit.std_omega``, ``std_damping``).  The
model built here is the fit's real-mode model written as ``[[mode]]``
tables -- the same receptance at the measured coordinates as
``ModalFit.to_model`` (mass-normalised shapes, ``mass = 1``) -- with an
``[uncertainty]`` table giving every fitted mode's ``frequency_hz`` and
``damping_ratio`` a normal distribution of the fit's standard deviation.
A pole that stands for two real modes (two modes closer than their
half-power width, fitted as one pole with a rank-two residue, e.g. a
tool's x and y bending) is one parameter: its modes move together (a
covariance group of correlation 1).  The residual pseudo-modes above the
band are kept fixed.

What the fit does not estimate is not carried: the covariance between a
pole's frequency and damping (the fit reports their standard deviations
only: they are taken as independent) and the uncertainty of the residues
(the modal stiffnesses).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import InputError
from ..structure._fit_result import point_tables

__all__ = ["uncertain_modal_model"]


def uncertain_modal_model(
    fit: Any,
    *,
    name: str = "modal fit",
    tables: dict[str, Any] | None = None,
    uncertainty: dict[str, Any] | None = None,
    residuals: str = "upper",
) -> Any:
    """A ``[[mode]]`` model of a modal fit with the fit's uncertainty.

    Parameters
    ----------
    fit : ModalFit
        From :func:`chatterlab.structure.fit_modes`.
    name : str
        The model's name.
    tables : dict, optional
        Model-file tables added to it (``{"coupling": [...], "process":
        {...}}``); points for the driving-point coordinates are made
        (``tool.x``, ``tool.y`` -> point ``tool``) as ``ModalFit.to_model``
        does.
    uncertainty : dict, optional
        More ``[uncertainty]`` entries (e.g. the cutting coefficient's:
        ``{"coupling.cut.Kf": {"distribution": "lognormal", "cv": 0.1}}``).
    residuals : str
        The residual pseudo-modes kept (``ModalFit.real_modes``).

    Returns
    -------
    Model
        Modes ``f1``, ``f2``, ... (fitted) and ``r1``, ... (residual), with
        the ``[uncertainty]`` table.
    """
    from ..model import build_model

    om, ze, Phi = fit.real_modes(residuals=residuals)
    coords = list(fit.driving_points)
    if not coords:
        raise InputError("uncertain_modal_model: the fit has no driving point, so its shapes have no scale")
    pole = [
        int(np.argmin(np.abs(fit.omega_n - w))) if np.min(np.abs(fit.omega_n - w)) == 0 else -1 for w in om
    ]
    modes, unc, groups = [], dict(uncertainty or {}), []
    by_pole: dict[int, list[str]] = {}
    n_res = 0
    for k, (w, z) in enumerate(zip(om, ze, strict=True)):
        if pole[k] >= 0:
            mid = f"f{k + 1}"
            by_pole.setdefault(pole[k], []).append(mid)
        else:
            n_res += 1
            mid = f"r{n_res}"
        shape = {c: float(Phi[i, k]) for i, c in enumerate(coords) if Phi[i, k] != 0.0}
        modes.append({"id": mid, "frequency_hz": float(w / (2 * np.pi)), "damping_ratio": float(z),
                      "mass": 1.0, "shape": shape})  # fmt: skip
    for r, ids in by_pole.items():
        sf = float(fit.std_omega[r] / (2 * np.pi))
        sz = float(fit.std_damping[r])
        if not (np.isfinite(sf) and np.isfinite(sz)):
            raise InputError(
                f"uncertain_modal_model: pole {r + 1} ({fit.frequency_hz[r]:.6g} Hz) has no standard deviation"
                " (the fit was not refined): fit with refinement"
            )
        if len(ids) == 1:
            unc[f"mode.{ids[0]}.frequency_hz"] = {"distribution": "normal", "std": sf}
            unc[f"mode.{ids[0]}.damping_ratio"] = {"distribution": "normal", "std": sz, "lower": 0.0}
        else:  # one pole, several real modes: one parameter each for frequency and damping
            for fld, s in (("frequency_hz", sf), ("damping_ratio", sz)):
                groups.append(
                    {
                        "parameters": [f"mode.{i}.{fld}" for i in ids],
                        "covariance": (s * s * np.ones((len(ids),) * 2)).tolist(),
                    }
                )
    raw: dict[str, Any] = {
        "model": {
            "name": name,
            "description": f"modal model of the fit of {fit.source}, with its uncertainty",
        },
        "mode": modes,
        "point": point_tables(coords),
    }
    for key, val in (tables or {}).items():
        if key in ("mode", "uncertainty"):
            raise InputError(f"uncertain_modal_model: tables may not replace [{key}] (give uncertainty=)")
        raw[key] = raw["point"] + list(val) if key == "point" else val
    if groups:
        unc["group"] = list(unc.get("group", [])) + groups
    raw["uncertainty"] = unc
    return build_model(raw, source=f"modal fit of {fit.source}")
