"""Where things are: positions of bodies, nodes, beam points and moving
contacts at a configuration s, and the geometric checks of a model.

The geometry is needed for the rigid arms of the element kinematics and for
the checks that every spring-damping and coupling element is a point (its two
ends coincide) at every configuration of the movable subsystem.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError
from ._items import Beam, Contact, Model, PointRef

__all__ = [
    "TrackPosition",
    "body_centre",
    "contact_track_position",
    "point_xy",
    "check_geometry",
    "is_movable",
]

_TOL = 1e-6  # m: two points closer than this coincide


@dataclass(frozen=True)
class TrackPosition:
    """Where a contact sits on its track at one configuration."""

    beam: Beam  #: the beam of the track under the contact
    element: int  #: index of the sub-element (0-based) when the beam is subdivided
    xi: float  #: fraction 0..1 of that sub-element
    distance: float  #: distance along ``beam`` from its first node, m
    rate: float  #: d(distance)/ds: how fast the contact runs along the beam per unit s


def _node_xy(model: Model, nid: str) -> np.ndarray:
    for n in model.nodes:
        if n.id == nid:
            return np.array(n.xy, float)
    raise KeyError(nid)


def body_centre(model: Model, bid: str, s: float | None = None) -> np.ndarray:
    """Centre of body ``bid`` (or the position of contact ``bid``) at s."""
    mv = model.movable
    for b in model.bodies:
        if b.id == bid:
            c = np.array(b.centre, float)
            if b.movable and mv is not None and s is not None:
                c = c + (s - mv.position) * np.array(mv.direction)
            return c
    for ct in model.contacts:
        if ct.id == bid:
            tp = contact_track_position(model, ct, s)
            return beam_point_xy(model, tp.beam, tp.distance, ct.offset)
    raise KeyError(bid)


def beam_axes(model: Model, beam: Beam) -> tuple[np.ndarray, np.ndarray, float]:
    """First node position, unit axis and length of a beam."""
    p0 = _node_xy(model, beam.nodes[0])
    d = _node_xy(model, beam.nodes[1]) - p0
    L = float(np.hypot(*d))
    return p0, d / L, L


def beam_point_xy(model: Model, beam: Beam, distance: float, offset: float) -> np.ndarray:
    p0, e, _ = beam_axes(model, beam)
    n = np.array([-e[1], e[0]])
    return p0 + distance * e + offset * n


def contact_track_position(model: Model, contact: Contact, s: float | None) -> TrackPosition:
    """Beam, sub-element and local coordinate under a moving contact at s.

    The contact sits at the along-track coordinate of the followed body's
    centre (plus ``shift``).  Raises ``ValueError`` if that is off the track.
    """
    mv = model.movable
    if s is None:
        s = mv.position if mv is not None else 0.0
    beams = [next(b for b in model.beams if b.id == bid) for bid in contact.beams]
    p0, e, _ = beam_axes(model, beams[0])
    c = body_centre(model, contact.follows, s)
    x = float((c - p0) @ e) + contact.shift
    rate = float(np.array(mv.direction) @ e) if mv is not None else 0.0
    total = sum(beam_axes(model, b)[2] for b in beams)
    if contact.outside == "clamp" and not (0.0 <= x <= total):
        x = min(max(x, 0.0), total)
        rate = 0.0
    start = 0.0
    for k, b in enumerate(beams):
        _, _, L = beam_axes(model, b)
        last = k == len(beams) - 1
        if start - 1e-9 <= x <= start + L + 1e-9:
            # a contact exactly on the joint belongs to the next beam
            if x >= start + L - 1e-12 and not last:
                start += L
                continue
            dist = min(max(x - start, 0.0), L)
            h = L / b.elements
            el = min(int(dist / h), b.elements - 1)
            return TrackPosition(b, el, (dist - el * h) / h, dist, rate)
        start += L
    raise ValueError(
        f"at s = {s:g} m the contact is {x:g} m along its track, which is {start:g} m long:"
        " it leaves the beams " + ", ".join(contact.beams)
    )


def point_xy(model: Model, ref: PointRef, s: float | None = None) -> np.ndarray:
    """Global position (m) of a point reference at configuration s."""
    if ref.kind == "ground":
        return np.array(ref.offset, float)
    if ref.kind == "node":
        return _node_xy(model, ref.target) + np.array(ref.offset)
    if ref.kind == "beam":
        beam = next(b for b in model.beams if b.id == ref.target)
        return beam_point_xy(model, beam, ref.distance, ref.offset[1])
    if ref.kind == "body":
        c = body_centre(model, ref.target, s)
        ang = 0.0
        for b in model.bodies:
            if b.id == ref.target:
                ang = b.angle
        ca, sa = np.cos(ang), np.sin(ang)
        off = np.array([ca * ref.offset[0] - sa * ref.offset[1], sa * ref.offset[0] + ca * ref.offset[1]])
        return c + off
    raise ValueError(f"point {ref.label} has no position (matrix-level model)")


def on_track(model: Model, ref: PointRef, s: float | None) -> bool:
    """False if ``ref`` is a clamped contact waiting beyond its track at s."""
    for c in model.contacts:
        if ref.kind == "body" and c.id == ref.target and c.outside == "clamp":
            return contact_track_position(model, c, s).rate != 0.0 or model.movable is None
    return True


def is_movable(model: Model, ref: PointRef) -> bool:
    """True if the point moves with the configuration parameter."""
    if ref.kind != "body":
        return False
    if any(c.id == ref.target for c in model.contacts):
        return True
    return any(b.id == ref.target and b.movable for b in model.bodies)


def check_geometry(model: Model) -> None:
    """Every spring and coupling is a point element: its two ends must
    coincide, at every configuration.  Raises :class:`ModelError`."""
    if model.is_matrix_model or model.frf is not None:
        return
    mv = model.movable
    configs = [None] if mv is None else sorted({mv.range[0], mv.position, mv.range[1]})
    for kind, items in (("spring", model.springs), ("coupling", model.couplings)):
        for el in items:
            label = f'[[{kind}]] "{el.id}"'
            ma, mb = is_movable(model, el.a), is_movable(model, el.b)
            if ma != mb and el.a.kind != "ground" and el.b.kind != "ground":
                mov, fix = (el.a, el.b) if ma else (el.b, el.a)
                raise ModelError(
                    f"connects the moving '{mov.target}' to the immovable '{fix.target}': as the movable"
                    " subsystem travels the two ends separate; connect them through a [[contact]] point",
                    source=model.source,
                    item=label,
                )
            for s in configs:
                pa = point_xy(model, el.a, s) if el.a.kind != "ground" else None
                pb = point_xy(model, el.b, s) if el.b.kind != "ground" else None
                if pa is None or pb is None or not (on_track(model, el.a, s) and on_track(model, el.b, s)):
                    continue
                gap = float(np.hypot(*(pa - pb)))
                if gap > _TOL:
                    where = "" if s is None else f" at s = {s:g} m"
                    raise ModelError(
                        f"its ends a at ({pa[0]:.4g}, {pa[1]:.4g}) and b at ({pb[0]:.4g}, {pb[1]:.4g}) m are"
                        f" {gap:.4g} m apart{where}; an SDE/CE is a point element: change the offsets so"
                        " that both ends coincide",
                        source=model.source,
                        item=label,
                        field="b",
                    )
