"""Readers of the items that name points: [[point]], [[spring]] and
[[coupling]] (a point given by name or as an inline table, resolved by
:class:`_RefContext`), and of [process]."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from ..errors import ModelError
from ._fields import _id_of, _Ids, _Item
from ._items import (
    DIRECTIONS,
    GROUND,
    HELIX_MAX_DEG,
    SPEED_PLAUSIBLE,
    SPEED_RANGE,
    Coupling,
    MillingCut,
    Movable,
    Point,
    PointRef,
    Process,
    Spring,
)


class _RefContext:
    """Resolves how the file names a point into a :class:`PointRef`."""

    def __init__(self, src, body_ids, node_xy, beam_len, contact_ids, coord_names, points, shapes=None):
        self.src = src
        #: modal models: physical coordinate -> ((mode id, shape entry), ...)
        self.shapes: dict[str, tuple[tuple[str, float], ...]] = shapes or {}
        self.body_ids = body_ids
        self.node_xy = node_xy
        self.beam_len = beam_len
        self.contact_ids = contact_ids
        self.coord_names = coord_names
        self.points: dict[str, PointRef] = points

    def known(self) -> str:
        names = sorted(set(self.points) | self.body_ids | set(self.node_xy) | self.contact_ids | {GROUND})
        return ", ".join(names)

    def ref(self, it: _Item, key: str) -> PointRef:
        v = it.raw(key)
        if isinstance(v, str):
            if v in self.points:
                return self.points[v]
            if v == GROUND:
                return PointRef("ground", GROUND, label=v)
            if v in self.body_ids or v in self.contact_ids:
                return PointRef("body", v, label=v)
            if v in self.node_xy:
                return PointRef("node", v, label=v)
            raise it.err(
                key, f"'{v}' is not a point, body, contact, node or '{GROUND}' (known: {self.known()})"
            )
        if isinstance(v, dict):
            sub = _Item(self.src, it.label, v, ("body", "node", "beam", "distance", "offset", "coords"))
            return self.ref_from_table(sub, key, v)
        raise it.err(
            key,
            f'must be a point name or an inline table like {{ body = "frame", offset = [0.0, -0.5] }}, got {v!r}',
        )

    def ref_from_table(self, it: _Item, key: str | None, t: dict[str, Any]) -> PointRef:
        f = (lambda s: f"{key}.{s}") if key else (lambda s: s)
        kinds = [k for k in ("body", "node", "beam", "coords") if k in t]
        if len(kinds) != 1:
            raise it.err(key, "give exactly one of body, node, beam or coords")
        kind = kinds[0]
        label = json.dumps(t)
        if kind == "coords":
            cs = t["coords"]
            if not isinstance(cs, dict) or not cs or any(d not in DIRECTIONS for d in cs):
                raise it.err(
                    f("coords"),
                    f'must be a table like {{ x = "q1", y = "q2" }} with keys from {list(DIRECTIONS)}',
                )
            where = "the [[mode]] shapes" if self.shapes else "[matrices] coordinates"
            for c in cs.values():
                if c not in self.coord_names:
                    raise it.err(
                        f("coords"),
                        f"'{c}' is not in {where} (known: {', '.join(sorted(self.coord_names))})",
                    )
            coords = tuple(cs.get(d, "") for d in DIRECTIONS)
            if self.shapes:  # a modal model: the physical coordinate is a weighted sum of modes
                weights = tuple(self.shapes[c] if c else () for c in coords)
                return PointRef("coords", "", coords=coords, label=label, weights=weights)
            return PointRef("coords", "", coords=coords, label=label)
        target = t[kind]
        if not isinstance(target, str):
            raise it.err(f(kind), f"must be an id string, got {target!r}")
        if kind == "beam":
            if target not in self.beam_len:
                raise it.err(
                    f("beam"),
                    f"beam '{target}' is not defined (known: {', '.join(sorted(self.beam_len)) or 'none'})",
                )
            dist = it.num("distance", unit="m")
            L = self.beam_len[target]
            if not (-1e-12 <= dist <= L + 1e-12):
                raise it.err(
                    f("distance"),
                    f"point is outside its beam: distance must be in [0, {L:g}] m (the beam's length), got {dist:g} m",
                )
            off = it.num("offset", 0.0, unit="m")
            return PointRef("beam", target, (0.0, off), min(max(dist, 0.0), L), label=label)
        ox, oy = it.vec("offset", 2, (0.0, 0.0), unit="m")
        off2 = (ox, oy)
        if it.has("distance"):
            raise it.err(f("distance"), "only a point on a beam has a distance")
        if kind == "body":
            if target == GROUND:
                return PointRef("ground", GROUND, off2, label=label)
            if target not in self.body_ids and target not in self.contact_ids:
                raise it.err(
                    f("body"),
                    f"body '{target}' is not defined (known: {', '.join(sorted(self.body_ids | self.contact_ids | {GROUND}))})",
                )
            return PointRef("body", target, off2, label=label)
        if target not in self.node_xy:
            raise it.err(
                f("node"),
                f"node '{target}' is not defined (known: {', '.join(sorted(self.node_xy)) or 'none'})",
            )
        return PointRef("node", target, off2, label=label)


def _read_points(src: str, raw: dict[str, Any], ids: _Ids, ctx: _RefContext) -> list[Point]:
    """[[point]]: named points (each known to the items read after it)."""
    points: list[Point] = []
    for k, t in enumerate(raw.get("point", [])):
        iid = _id_of(src, "point", k, t)
        it = _Item(
            src,
            f'[[point]] "{iid}"',
            t,
            ("id", "body", "node", "beam", "distance", "offset", "coords", "description"),
        )
        ids.register("point", iid)
        ref = ctx.ref_from_table(it, None, dict(t))
        points.append(Point(iid, ref))
        ctx.points[iid] = ref
    return points


def _read_springs(src: str, raw: dict[str, Any], ids: _Ids, ctx: _RefContext) -> list[Spring]:
    """[[spring]]: spring-damping elements between two points."""
    springs: list[Spring] = []
    for k, t in enumerate(raw.get("spring", [])):
        iid = _id_of(src, "spring", k, t)
        it = _Item(
            src,
            f'[[spring]] "{iid}"',
            t,
            ("id", "a", "b", "c1", "c2", "c6", "d1", "d2", "d6", "angle_deg", "description"),
        )
        ids.register("spring", iid)
        pa = ctx.ref(it, "a")
        pb = ctx.ref(it, "b")
        c = tuple(
            it.num(f, 0.0, unit=u, nonneg=True) for f, u in (("c1", "N/m"), ("c2", "N/m"), ("c6", "N m/rad"))
        )
        d = tuple(
            it.num(f, 0.0, unit=u, nonneg=True)
            for f, u in (("d1", "N s/m"), ("d2", "N s/m"), ("d6", "N m s/rad"))
        )
        if not any(c) and not any(d):
            raise it.err(
                "c1",
                "a spring needs a stiffness (c1, c2 or c6 > 0) or a damping (d1, d2, d6 > 0); all are zero",
            )
        if pa.kind == "ground" and pb.kind == "ground":
            raise it.err("b", "both ends are on the ground; connect at least one end to the structure")
        springs.append(
            Spring(
                iid, pa, pb, (c[0], c[1], c[2]), (d[0], d[1], d[2]), math.radians(it.num("angle_deg", 0.0))
            )
        )
    return springs


def _read_couplings(src: str, raw: dict[str, Any], ids: _Ids, ctx: _RefContext) -> list[Coupling]:
    """[[coupling]]: the coupling (cutting) elements."""
    couplings: list[Coupling] = []
    for k, t in enumerate(raw.get("coupling", [])):
        iid = _id_of(src, "coupling", k, t)
        couplings.append(_read_coupling(src, iid, t, ctx))
        ids.register("coupling", iid)
    return couplings


def _read_coupling(src: str, iid: str, t: Any, ctx: _RefContext) -> Coupling:
    label = f'[[coupling]] "{iid}"'
    base: tuple[str, ...] = ("id", "a", "b", "angle_deg", "width_ref", "forces", "model", "description")
    model_kind = t.get("model", "matrices") if isinstance(t, dict) else "matrices"
    extra = {
        "matrices": ("DP", "DV", "DO"),
        "grasso": tuple(f"K{i}" for i in range(1, 9)),
        "regenerative": ("Kf", "force_angle_deg", "normal_angle_deg", "Kv"),
        "milling": (),
    }
    if not isinstance(model_kind, str) or model_kind not in extra:
        raise ModelError(
            f"model: must be one of {', '.join(extra)} (got {model_kind!r})",
            source=src,
            item=label,
            field="model",
        )
    if model_kind == "milling":
        base = tuple(k for k in base if k != "width_ref")  # the width is the axial depth a_p itself
    it = _Item(src, label, t, base + extra[model_kind])
    a = ctx.ref(it, "a")
    b = ctx.ref(it, "b")
    width_ref = 1.0 if model_kind == "milling" else it.num("width_ref", unit="m", positive=True)
    f1, f2, f3 = it.vec("forces", 3, (0.0, 0.0, 0.0), unit="N")
    forces = (f1, f2, f3)
    angle = math.radians(it.num("angle_deg", 0.0))
    params: tuple[tuple[str, float], ...] = ()
    if model_kind == "milling":  # its averaged directional matrix comes from [process] (process.ce_maps)
        zero = ((0.0, 0.0, 0.0),) * 3
        return Coupling(iid, a, b, zero, zero, zero, width_ref, forces, angle, model_kind, params)
    if model_kind == "matrices":
        DP, DV, DO = it.matrix3("DP"), it.matrix3("DV"), it.matrix3("DO")
        if not any(any(r) for r in DP + DV + DO):
            raise it.err("DP", "all of DP, DV, DO are zero; give at least one feedback matrix")
    elif model_kind == "grasso":
        K = [it.num(f"K{i}") for i in range(1, 9)]
        params = tuple((f"K{i}", K[i - 1]) for i in range(1, 9))
        K1, K2, K3, K4, K5, K6, K7, K8 = K
        # Eqs. (3.7)-(3.9) of the seed paper, dw = (q_z, dh, 0)
        DV = ((K1, K4, 0.0), (K2, K6, 0.0), (0.0, 0.0, 0.0))
        DP = ((0.0, K3, 0.0), (0.0, K5, 0.0), (0.0, 0.0, 0.0))
        DO = ((0.0, -K7, 0.0), (0.0, -K8, 0.0), (0.0, 0.0, 0.0))
    else:
        Kf = it.num("Kf", unit="N/m^2", positive=True)
        Kv = it.num("Kv", 0.0, unit="N s/m^2", nonneg=True)
        fa = math.radians(it.num("force_angle_deg", 0.0))
        na = math.radians(it.num("normal_angle_deg", 0.0))
        params = (
            ("Kf", Kf),
            ("Kv", Kv),
            ("force_angle_deg", math.degrees(fa)),
            ("normal_angle_deg", math.degrees(na)),
        )
        f = np.array([math.cos(fa), math.sin(fa), 0.0])
        n = np.array([math.cos(na), math.sin(na), 0.0])
        G = np.outer(f, n)
        # F_a = K_f b (h - h0) f with h = h0 - n.dw(t) + n.dw(t-T): D_P = Kf b f n^T, D_O = -Kf b f n^T
        DP = tuple(tuple(float(x) for x in r) for r in Kf * width_ref * G)
        DO = tuple(tuple(float(x) for x in r) for r in -Kf * width_ref * G)
        DV = tuple(tuple(float(x) for x in r) for r in Kv * width_ref * G)
    return Coupling(iid, a, b, DP, DV, DO, width_ref, forces, angle, model_kind, params)


def milling_couplings(src: str, couplings: list[Coupling], process: Process | None) -> list[Coupling]:
    """``model = "milling"`` couplings need the cutter of a milling [process]
    (whose time-averaged feedback the process layer gives them:
    :func:`chatterlab.process.ce_maps`); a milling process needs one."""
    out = []
    for c in couplings:
        if c.kind == "milling":
            if process is None or process.milling is None:
                raise ModelError(
                    'model = "milling" needs [process] kind = "milling" (the cutter: teeth, diameter, Kt, Kn,'
                    " immersion); add it or use another coupling model",
                    source=src,
                    item=f'[[coupling]] "{c.id}"',
                    field="model",
                )
        out.append(c)
    if process is not None and process.kind == "milling" and not any(c.kind == "milling" for c in out):
        raise ModelError(
            'kind = "milling" needs a [[coupling]] with model = "milling" between the tool point and the'
            ' workpiece (or "ground")',
            source=src,
            item="[process]",
            field="kind",
        )
    return out


def _read_process(src: str, t: Any) -> Process:
    kind = t.get("kind") if isinstance(t, dict) else None
    allowed = {
        "shaping": (
            "kind",
            "speed",
            "return_speed",
            "run_in",
            "cut",
            "coast",
            "start",
            "direction",
            "description",
        ),
        "turning": ("kind", "rpm", "description"),
        "delay": ("kind", "delay", "description"),
        "milling": _MILLING_FIELDS,
    }
    if not isinstance(kind, str) or kind not in allowed:
        raise ModelError(
            f"kind: must be one of {', '.join(allowed)} (got {kind!r})",
            source=src,
            item="[process]",
            field="kind",
        )
    it = _Item(src, "[process]", t, allowed[kind])
    if kind == "shaping":
        direction = it.num("direction", -1.0)
        if direction not in (-1.0, 1.0):
            raise it.err(
                "direction", f"must be +1 or -1 (the sign of ds/dt in the work stroke), got {direction:g}"
            )
        return Process(
            "shaping",
            speed=it.num("speed", unit="m/s", positive=True),
            return_speed=it.num("return_speed", unit="m/s", positive=True),
            run_in=it.num("run_in", unit="m", nonneg=True),
            cut=it.num("cut", unit="m", positive=True),
            coast=it.num("coast", unit="m", nonneg=True),
            start=it.num("start", 0.0, unit="m"),
            direction=direction,
        )
    if kind == "turning":
        return Process("turning", speed=it.num("rpm", unit="rpm", positive=True))
    if kind == "milling":
        return Process("milling", speed=_spindle_rpm(it), milling=_read_milling(it))
    return Process(
        "delay",
        speed=it.num("delay", unit="s", positive=True),
        delay_value=it.num("delay", unit="s", positive=True),
    )


_MILLING_FIELDS = (
    "kind",
    "rpm",
    "teeth",
    "diameter",
    "Kt",
    "Kn",
    "Kte",
    "Kne",
    "radial_immersion",
    "milling",
    "entry_deg",
    "exit_deg",
    "pitch_deg",
    "helix_deg",
    "runout",
    "feed_per_tooth",
    "description",
)


def _spindle_rpm(it: _Item) -> float:
    """A milling process's spindle speed, rpm, within :data:`SPEED_RANGE` (as
    :func:`chatterlab.process.check_spindle_speed` asks of every speed)."""
    rpm = it.num("rpm", unit="rpm", positive=True)
    lo, hi = SPEED_RANGE
    if not lo <= rpm <= hi:
        raise it.err(
            "rpm",
            f"must be within {lo:g}..{hi:g} rpm (got {rpm:g} rpm); spindles run"
            f" {SPEED_PLAUSIBLE[0]:g}..{SPEED_PLAUSIBLE[1]:g} rpm",
        )
    return rpm


def _read_milling(it: _Item) -> MillingCut:
    """The cutter and the cut of ``[process] kind = "milling"``."""
    teeth = it.raw("teeth")
    if isinstance(teeth, bool) or not isinstance(teeth, int) or teeth < 1:
        raise it.err("teeth", f"must be a whole number of teeth >= 1 (got {teeth!r})")
    if teeth > 1000:
        raise it.err("teeth", f"{teeth} teeth: at most 1000 are allowed")
    diameter = it.num("diameter", unit="m", positive=True)
    Kt = it.num("Kt", unit="N/m^2", positive=True)
    Kn = it.num("Kn", unit="N/m^2", nonneg=True)
    by_angles = it.has("entry_deg") or it.has("exit_deg")
    if by_angles == it.has("radial_immersion"):
        raise it.err(
            "radial_immersion",
            'give either radial_immersion (a_e/D, with milling = "down" or "up") or entry_deg and exit_deg',
        )
    if by_angles:
        if it.has("milling"):
            raise it.err(
                "milling", "up/down milling goes with radial_immersion; entry_deg and exit_deg say it all"
            )
        a, b = it.num("entry_deg", unit="deg"), it.num("exit_deg", unit="deg")
        if not (0.0 <= a <= 180.0 and 0.0 <= b <= 180.0):
            raise it.err("entry_deg", f"entry and exit angles must lie in [0, 180] deg (got {a:g}, {b:g})")
        if not a < b:
            raise it.err("exit_deg", f"the entry angle {a:g} deg must come before the exit angle {b:g} deg")
        entry, exit_ = math.radians(a), math.radians(b)
    else:
        r = it.num("radial_immersion")
        if not 0.0 < r <= 1.0:
            raise it.err(
                "radial_immersion", f"a_e/D must be in (0, 1] (got {r:g}); a_e is at most the diameter"
            )
        mode = it.str("milling", "down")
        if mode not in ("down", "up"):
            raise it.err("milling", f'must be "down" or "up" (got {mode!r})')
        # Insperger & Stepan (2004): down-milling cuts from arccos(2 a_e/D - 1) to pi, up-milling from 0
        if mode == "down":
            entry, exit_ = math.acos(2.0 * r - 1.0), math.pi
        else:
            entry, exit_ = 0.0, math.acos(1.0 - 2.0 * r)
    pitch: tuple[float, ...] = ()
    if it.has("pitch_deg"):
        p = it.vec("pitch_deg", teeth, unit="deg")
        if min(p) <= 0:
            raise it.err("pitch_deg", f"every pitch angle must be > 0 deg (got {list(p)})")
        if abs(sum(p) - 360.0) > 1e-9 * 360.0:
            raise it.err("pitch_deg", f"the pitch angles sum to {sum(p):.10g} deg; they must sum to 360 deg")
        pitch = tuple(math.radians(x) for x in p)
    helix = it.num("helix_deg", 0.0, unit="deg")
    if not 0.0 <= helix <= HELIX_MAX_DEG:
        raise it.err(
            "helix_deg",
            f"must be from 0 to at most {HELIX_MAX_DEG:g} deg (got {helix:g}): near 90 deg the flute wraps"
            " the tool without bound; end mills have up to about 60 deg",
        )
    runout = it.vec("runout", teeth, (), unit="m")
    return MillingCut(
        teeth=teeth,
        diameter=diameter,
        Kt=Kt,
        Kn=Kn,
        entry=entry,
        exit=exit_,
        pitch=pitch,
        helix=math.radians(helix),
        Kte=it.num("Kte", 0.0, unit="N/m"),
        Kne=it.num("Kne", 0.0, unit="N/m"),
        runout=tuple(runout),
        feed_per_tooth=it.num("feed_per_tooth", 0.0, unit="m", nonneg=True),
    )


def _check_stroke(src: str, process: Process | None, movable: Movable | None) -> None:
    """A shaping stroke must stay inside the movable range."""
    if process is not None and process.kind == "shaping" and movable is not None:
        x0 = process.start
        x1 = process.start + process.direction * (process.run_in + process.cut + process.coast)
        lo, hi = min(x0, x1), max(x0, x1)
        if lo < movable.range[0] - 1e-9 or hi > movable.range[1] + 1e-9:
            raise ModelError(
                f"the stroke from start = {x0:g} m over {process.run_in + process.cut + process.coast:g} m"
                f" in direction {process.direction:+g} spans [{lo:g}, {hi:g}] m, outside [movable] range"
                f" [{movable.range[0]:g}, {movable.range[1]:g}] m; move start, flip direction or widen the range",
                source=src,
                item="[process]",
                field="start",
            )
