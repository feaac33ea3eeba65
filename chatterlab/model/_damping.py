"""The ``[process_damping]`` table (docs/model-format.md, "[process_damping]";
the theory in docs/process-damping.md): the linear coefficient C_pd, or the
indentation model (K_sp, wear land, clearance angle), of one coupling
element, checked against the process whose cutting speed it needs."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import ModelError
from ._fields import _Item
from ._items import Coupling, Machine, Process, ProcessDamping

__all__ = ["read_process_damping", "PD_RANGES"]

#: plausible magnitudes of the fields (a nonzero value outside is a unit
#: slip: C_pd of turned steel and titanium is 1e4..1e6 N/m, K_sp about
#: 1e13..1e14 N/m^3, wear lands 0.01..0.5 mm); six decades of room on each side
PD_RANGES: dict[str, tuple[float, float, str]] = {
    "C_pd": (1e-2, 1e12, "N/m"),
    "K_sp": (1e7, 1e20, "N/m^3"),
    "wear_land": (1e-8, 1e-2, "m"),
}

_FIELDS = ("coupling", "C_pd", "K_sp", "wear_land", "clearance_deg", "normal_deg", "description")


def read_process_damping(
    src: str,
    raw: dict[str, Any],
    process: Process | None,
    couplings: list[Coupling] | tuple[Coupling, ...],
    machine: Machine | None,
) -> ProcessDamping | None:
    """The ``[process_damping]`` table, or None when the file has none."""
    if "process_damping" not in raw:
        return None
    it = _Item(src, "[process_damping]", raw["process_damping"], _FIELDS)
    if process is None or process.kind == "delay":
        raise it.err(
            None,
            "needs a [process] of kind turning, shaping or milling: the damping falls with the cutting"
            " speed, which a delay process does not have",
        )
    if process.kind == "turning" and (machine is None or not math.isfinite(machine.workpiece_diameter)):
        raise it.err(
            None,
            "turning needs the workpiece diameter for the cutting speed V = pi D n: give [machine]"
            " workpiece_diameter (m)",
        )
    ids = [c.id for c in couplings]
    if it.has("coupling"):
        cid = it.str("coupling")
        if cid not in ids:
            raise it.err(
                "coupling", f"no [[coupling]] has the id '{cid}' (known: {', '.join(ids) or 'none'})"
            )
    elif len(ids) == 1:
        cid = ids[0]
    else:
        raise it.err(
            "coupling",
            f"the model has {len(ids)} couplings ({', '.join(ids) or 'none'}): name the one the flank rubs on",
        )
    coupling = next(c for c in couplings if c.id == cid)
    linear = it.has("C_pd")
    indent = [k for k in ("K_sp", "wear_land", "clearance_deg") if it.has(k)]
    if linear and indent:
        raise it.err(
            indent[0],
            "give either C_pd (the linear model) or K_sp, wear_land and clearance_deg (the indentation"
            " model), not both",
        )
    if not linear and len(indent) < 3:
        missing = [k for k in ("K_sp", "wear_land", "clearance_deg") if not it.has(k)]
        raise it.err(
            missing[0] if indent else "C_pd",
            "give C_pd (N/m) or all of K_sp (N/m^3), wear_land (m) and clearance_deg (deg)"
            + (f": {', '.join(missing)} missing" if indent else ""),
        )
    normal = _normal(it, coupling)
    if linear:
        C = _ranged(it, "C_pd", nonneg=True)
        return ProcessDamping(cid, C, normal=normal)
    K_sp = _ranged(it, "K_sp", nonneg=False)
    w = _ranged(it, "wear_land", nonneg=False)
    gamma = it.num("clearance_deg", unit="deg")
    if not 0.0 < gamma < 90.0:
        raise it.err("clearance_deg", f"must lie in (0, 90) deg (got {gamma:g}); relief angles are 3..15 deg")
    # the small-vibration equivalent of the indentation force (docs/process-damping.md, Eq. 6)
    return ProcessDamping(cid, K_sp * w * w / 4.0, K_sp, w, math.radians(gamma), normal)


def _ranged(it: _Item, key: str, *, nonneg: bool) -> float:
    lo, hi, unit = PD_RANGES[key]
    v = it.num(key, unit=unit, nonneg=nonneg, positive=not nonneg)
    if v != 0.0 and not lo <= v <= hi:
        raise it.err(
            key,
            f"{v:g} {unit} is outside the plausible range {lo:g}..{hi:g} {unit}: correct the value (a model"
            f" file is in SI units: {unit})",
        )
    return v


def _normal(it: _Item, coupling: Coupling) -> float | None:
    """The cut's normal in CE axes, rad: ``normal_deg``, or None (the
    coupling's own: the direction its delayed term regenerates)."""
    if coupling.kind == "milling":
        if it.has("normal_deg"):
            raise it.err(
                "normal_deg",
                "a milling cut's normal is each tooth's radial direction (sin phi, cos phi): drop normal_deg",
            )
        return None
    if it.has("normal_deg"):
        return math.radians(it.num("normal_deg", unit="deg"))
    O = np.array(coupling.DO, dtype=float)
    sv = np.linalg.svd(O, compute_uv=False)
    if sv[0] == 0.0 or np.sum(sv > 1e-12 * sv[0]) != 1:
        raise ModelError(
            "normal_deg: the coupling's DO is not of rank one, so it does not say which direction is the"
            " cut's normal: give normal_deg (deg, from CE axis 1)",
            source=it.src,
            item=it.label,
            field="normal_deg",
        )
    return None
