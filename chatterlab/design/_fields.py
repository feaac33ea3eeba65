"""Which model fields a design study varies, their values and units.

A field is addressed by its parameter path (``spring.holder.c1``,
``beam.table.I``, ``coupling.cut.Kf``; docs/model-format.md, "parameter
paths"), the same paths ``Model.with_parameter``, ``--set`` and the sweep
engine use.  :func:`design_fields` lists the default set of a model: every
number written in the file for a body, beam, spring, coupling, absorber,
mode or actuator (its gains, delay and bandwidth), and the damping of every joint direction that has a stiffness (a
designer's "damp this joint" is a field the file leaves at its default 0).
Geometry (centres, offsets, distances, angles), reference widths and the
process kinematics are not in the default set: their paths may be given
explicitly.
"""

from __future__ import annotations

import json
import math
from typing import Any

from ..errors import InputError, ModelError
from ..model import Model

__all__ = ["design_fields", "field_value", "field_unit", "field_affinity"]

#: the fields of each list table a design study varies by default (when the file writes them)
_DESIGN = {
    "body": ("mass", "inertia"),
    "beam": ("E", "G", "nu", "rho", "A", "I", "kappa", "eta"),
    "spring": ("c1", "c2", "c6", "d1", "d2", "d6"),
    "absorber": ("mass", "stiffness", "frequency_hz", "damping", "damping_ratio"),
    "mode": ("frequency_hz", "damping_ratio", "stiffness", "mass"),
    "actuator": ("proportional_gain", "velocity_gain", "delayed_gain", "delay", "bandwidth_hz"),
}
#: coupling fields that are geometry or a reference, not a cutting coefficient
_NOT_COEFFICIENTS = ("width_ref", "angle_deg", "force_angle_deg", "normal_angle_deg")

#: units of the fields, by (kind, field); "1" for a ratio
_UNITS = {
    ("body", "mass"): "kg",
    ("body", "inertia"): "kg m^2",
    ("beam", "E"): "Pa",
    ("beam", "G"): "Pa",
    ("beam", "nu"): "1",
    ("beam", "rho"): "kg/m^3",
    ("beam", "A"): "m^2",
    ("beam", "I"): "m^4",
    ("beam", "kappa"): "1",
    ("beam", "eta"): "N s/m^2",
    ("spring", "c1"): "N/m",
    ("spring", "c2"): "N/m",
    ("spring", "c6"): "N m/rad",
    ("spring", "d1"): "N s/m",
    ("spring", "d2"): "N s/m",
    ("spring", "d6"): "N m s/rad",
    ("spring", "angle_deg"): "deg",
    ("coupling", "Kf"): "N/m^2",
    ("coupling", "Kv"): "N s/m^2",
    ("coupling", "width_ref"): "m",
    ("coupling", "angle_deg"): "deg",
    ("coupling", "force_angle_deg"): "deg",
    ("coupling", "normal_angle_deg"): "deg",
    ("absorber", "mass"): "kg",
    ("absorber", "stiffness"): "N/m",
    ("absorber", "frequency_hz"): "Hz",
    ("absorber", "damping"): "N s/m",
    ("absorber", "damping_ratio"): "1",
    ("absorber", "angle_deg"): "deg",
    ("mode", "frequency_hz"): "Hz",
    ("mode", "damping_ratio"): "1",
    ("mode", "stiffness"): "N/m",
    ("mode", "mass"): "kg",
    ("actuator", "proportional_gain"): "N/m",
    ("actuator", "velocity_gain"): "N s/m",
    ("actuator", "delayed_gain"): "N/m",
    ("actuator", "delay"): "s",
    ("actuator", "bandwidth_hz"): "Hz",
    ("actuator", "force_limit"): "N",
    ("actuator", "angle_deg"): "deg",
    ("actuator", "sensor_angle_deg"): "deg",
    ("process", "return_speed"): "m/s",
    ("process", "run_in"): "m",
    ("process", "cut"): "m",
    ("process", "coast"): "m",
    ("process", "delay"): "s",
}
#: defaults of fields a file may leave out (docs/model-format.md), by (kind, field)
_DEFAULTS = {
    ("spring", "c1"): 0.0,
    ("spring", "c2"): 0.0,
    ("spring", "c6"): 0.0,
    ("spring", "d1"): 0.0,
    ("spring", "d2"): 0.0,
    ("spring", "d6"): 0.0,
    ("spring", "angle_deg"): 0.0,
    ("beam", "kappa"): 5.0 / 6.0,
    ("beam", "eta"): 0.0,
    ("coupling", "angle_deg"): 0.0,
    ("coupling", "force_angle_deg"): 0.0,
    ("coupling", "normal_angle_deg"): 0.0,
    ("coupling", "Kv"): 0.0,
    ("absorber", "damping"): 0.0,
    ("actuator", "proportional_gain"): 0.0,
    ("actuator", "velocity_gain"): 0.0,
    ("actuator", "delayed_gain"): 0.0,
    ("actuator", "delay"): 0.0,
}


#: fields that enter M, C, K, J and the CE matrices linearly, by the assembly's construction
#: (docs/model-format.md: a spring adds c J^T J, a body diag(m, m, J), a beam's mass and
#: damping are proportional to rho and eta, a coupling's matrices to its coefficients, a
#: mode's matrices to its stiffness or mass, an actuator's gains and delay are entries of the
#: loop's actuator blocks); tests/test_design_sensitivity.py confirms each by a vanishing
#: second difference
_AFFINE = (
    {("spring", f) for f in ("c1", "c2", "c6", "d1", "d2", "d6")}
    | {
        ("body", "mass"),
        ("body", "inertia"),
        ("beam", "rho"),
        ("beam", "eta"),
        ("absorber", "stiffness"),
        ("absorber", "damping"),
        ("absorber", "damping_ratio"),
        ("mode", "stiffness"),
        ("mode", "mass"),
        ("mode", "damping_ratio"),
        ("coupling", "Kf"),
        ("coupling", "Kv"),
        ("actuator", "proportional_gain"),
        ("actuator", "velocity_gain"),
        ("actuator", "delayed_gain"),
        ("actuator", "delay"),
    }
    | {("coupling", f"K{i}") for i in range(1, 9)}
)
#: fields that do not (a section's shear parameter, Poisson's ratio, angles, frequencies)
_NOT_AFFINE = {
    ("beam", "A"),
    ("beam", "I"),
    ("beam", "nu"),
    ("beam", "G"),
    ("beam", "kappa"),
    ("spring", "angle_deg"),
    ("coupling", "angle_deg"),
    ("coupling", "force_angle_deg"),
    ("coupling", "normal_angle_deg"),
    ("coupling", "width_ref"),
    ("absorber", "frequency_hz"),
    ("absorber", "angle_deg"),
    ("mode", "frequency_hz"),
    ("actuator", "bandwidth_hz"),
    ("actuator", "angle_deg"),
    ("actuator", "sensor_angle_deg"),
}


def field_affinity(model: Model, path: str) -> bool | None:
    """Whether the loop's matrices are affine in the field: True or False
    where the model format says so, None where it does not (then it is
    tested).  Young's modulus is affine when G follows it through nu (no
    ``G`` written), an absorber's mass unless its stiffness and damping
    ratio are written (then c = 2 zeta sqrt(k m) grows like sqrt(m))."""
    kind, iid, name = _split(path)
    if (kind, name) in _AFFINE:
        return True
    if (kind, name) in _NOT_AFFINE:
        return False
    if iid is None:
        return None
    items = _raw(model).get(kind, [])
    item = (
        next((it for it in items if isinstance(it, dict) and it.get("id") == iid), None)
        if isinstance(items, list)
        else None
    )
    if item is None:
        return None
    if (kind, name) == ("beam", "E"):
        return "G" not in item
    if (kind, name) == ("absorber", "mass"):  # c = 2 zeta sqrt(k m) is not linear in m at fixed k
        return not ("stiffness" in item and "damping_ratio" in item)
    return None


def _raw(model: Model) -> dict[str, Any]:
    return dict(json.loads(model.raw)) if model.raw else {}


def _number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(float(v))


def design_fields(model: Model) -> list[str]:
    """The default fields of a design study of ``model`` (module docstring),
    in file order."""
    raw = _raw(model)
    out: list[str] = []
    for kind in ("body", "beam", "spring", "coupling", "absorber", "mode", "actuator"):
        items = raw.get(kind, [])
        for it in items if isinstance(items, list) else []:
            if not isinstance(it, dict) or "id" not in it:
                continue
            iid = it["id"]
            if kind == "coupling":
                names = [k for k, v in it.items() if _number(v) and k not in _NOT_COEFFICIENTS]
            else:
                names = [k for k in _DESIGN[kind] if _number(it.get(k))]
            if kind == "spring":  # the damping of every direction that has a stiffness
                names += [f"d{j}" for j in (1, 2, 6) if _number(it.get(f"c{j}")) and f"d{j}" not in it]
            out += [f"{kind}.{iid}.{k}" for k in names]
    return out


def _split(path: str) -> tuple[str, str | None, str]:
    parts = str(path).split(".")
    if len(parts) == 3:
        return parts[0], parts[1], parts[2]
    if len(parts) == 2:
        return parts[0], None, parts[1]
    raise InputError(
        f"field '{path}' is not a parameter path: write KIND.ID.FIELD (e.g. spring.holder.c1) or"
        " TABLE.FIELD (e.g. process.return_speed)"
    )


def field_value(model: Model, path: str) -> float:
    """The number a field holds in ``model`` -- after its variant and
    overrides (``--variant``, ``--set``), as
    :func:`chatterlab.model.parameter_value` reads it -- or its default when
    the file leaves it out; an :class:`InputError` naming the field when it is
    not a number of the model."""
    from ..model import parameter_value

    kind, iid, name = _split(path)
    try:
        return parameter_value(model, path)
    except ModelError as exc:
        if "is not a number" in str(exc):
            raise InputError(f"field '{path}' is not a number; a sensitivity needs a numeric field") from None
    # not written in the file: the item's default, if the item exists and the field has one
    if iid is None:
        where = f"[{kind}]"
    else:
        items = _raw(model).get(kind, [])
        ids = [str(it.get("id")) for it in items if isinstance(it, dict)] if isinstance(items, list) else []
        if iid not in ids:
            raise InputError(
                f"field '{path}': {model.source} has no [[{kind}]] with id '{iid}'"
                f" (known: {', '.join(ids) or 'none'}); check the path"
            )
        where = f'[[{kind}]] "{iid}"'
    value = _DEFAULTS.get((kind, name)) if iid is not None else None
    if value is None:
        raise InputError(
            f"field '{path}': {where} of {model.source} has no field '{name}' and it has no default;"
            " write it in the file or choose another field"
        )
    return float(value)


def field_unit(path: str) -> str:
    """The field's unit (``""`` when not known: a matrix entry's or a coefficient's)."""
    kind, _, name = _split(path)
    return _UNITS.get((kind, name), "")
