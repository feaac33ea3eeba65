"""Readers of the structural tables of a model file: [movable], [[body]],
[[node]], [[beam]], [[contact]], [[attachment]], [[support]] and
[[constraint]], each checked against the items read before it."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import ModelError
from ._fields import _id_of, _Ids, _Item
from ._items import (
    DIRECTIONS,
    GROUND,
    Attachment,
    Beam,
    Body,
    Constraint,
    Contact,
    Model,
    Movable,
    Node,
    Section,
    Support,
)


def _read_movable(src: str, raw: dict[str, Any]) -> Movable | None:
    """[movable]: the moving bodies, the direction of s, the position and range (read first: bodies need to know)."""
    movable: Movable | None = None
    if "movable" in raw:
        it = _Item(src, "[movable]", raw["movable"], ("bodies", "direction", "position", "range"))
        bl = it.raw("bodies")
        if not isinstance(bl, list) or not bl or not all(isinstance(b, str) for b in bl):
            raise it.err("bodies", f"must be a non-empty list of body ids, got {bl!r}")
        d = it.vec("direction", 2, (1.0, 0.0))
        nd = math.hypot(*d)
        if nd == 0:
            raise it.err("direction", "must be a non-zero vector")
        pos = it.num("position", unit="m")
        rng = it.vec("range", 2, (pos, pos), unit="m")
        if not (rng[0] <= pos <= rng[1]):
            raise it.err("range", f"must contain position {pos:g} m (got {list(rng)})")
        movable = Movable(tuple(bl), (d[0] / nd, d[1] / nd), pos, (rng[0], rng[1]))
    return movable


def _read_bodies(src: str, raw: dict[str, Any], ids: _Ids, movable: Movable | None) -> list[Body]:
    """[[body]]: rigid bodies (the movable ones marked); every [movable] body must be one."""
    mov_bodies = set(movable.bodies) if movable is not None else set()
    bodies: list[Body] = []
    for k, t in enumerate(raw.get("body", [])):
        iid = _id_of(src, "body", k, t)
        it = _Item(
            src, f'[[body]] "{iid}"', t, ("id", "mass", "inertia", "centre", "angle_deg", "description")
        )
        ids.register("body", iid)
        m = it.num("mass", unit="kg", nonneg=True)
        J = it.num("inertia", unit="kg m^2", nonneg=True)
        if (m == 0) != (J == 0):
            raise it.err(
                "inertia" if m > 0 else "mass",
                f"mass and inertia must both be > 0, or both 0 for a massless body (got {m:g} kg, {J:g} kg m^2)",
            )
        c = it.vec("centre", 2, unit="m")
        ang = math.radians(it.num("angle_deg", 0.0))
        bodies.append(Body(iid, m, J, (c[0], c[1]), ang, iid in mov_bodies))
    body_ids = {b.id for b in bodies}
    if movable is not None:
        for b in movable.bodies:
            if b not in body_ids:
                raise ModelError(
                    f"bodies: {b!r} is not a [[body]] (known: {', '.join(sorted(body_ids)) or 'none'})",
                    source=src,
                    item="[movable]",
                    field="bodies",
                )
    return bodies


def _read_nodes(src: str, raw: dict[str, Any], ids: _Ids) -> list[Node]:
    """[[node]]: named points of the plane."""
    nodes: list[Node] = []
    for k, t in enumerate(raw.get("node", [])):
        iid = _id_of(src, "node", k, t)
        it = _Item(src, f'[[node]] "{iid}"', t, ("id", "at", "description"))
        ids.register("node", iid)
        xy = it.vec("at", 2, unit="m")
        nodes.append(Node(iid, (xy[0], xy[1])))
    return nodes


def _read_beams(
    src: str, raw: dict[str, Any], ids: _Ids, node_xy: dict[str, np.ndarray]
) -> tuple[list[Beam], dict[str, float]]:
    """[[beam]]: Timoshenko beams between two nodes, and their lengths (m)."""
    beams: list[Beam] = []
    beam_len: dict[str, float] = {}
    for k, t in enumerate(raw.get("beam", [])):
        iid = _id_of(src, "beam", k, t)
        it = _Item(
            src,
            f'[[beam]] "{iid}"',
            t,
            ("id", "nodes", "E", "nu", "G", "rho", "A", "I", "kappa", "eta", "elements", "description"),
        )
        ids.register("beam", iid)
        nl = it.raw("nodes")
        if not (isinstance(nl, list) and len(nl) == 2 and all(isinstance(x, str) for x in nl)):
            raise it.err("nodes", f"must be a list of two node ids, got {nl!r}")
        for n in nl:
            if n not in node_xy:
                raise it.err(
                    "nodes", f"node {n!r} is not defined (known: {', '.join(sorted(node_xy)) or 'none'})"
                )
        if nl[0] == nl[1]:
            raise it.err("nodes", "the two nodes must differ")
        L = float(np.hypot(*(node_xy[nl[1]] - node_xy[nl[0]])))
        if L <= 1e-12:
            raise it.err(
                "nodes",
                f"beam has zero length: nodes '{nl[0]}' and '{nl[1]}' are at the same place; move one",
            )
        E = it.num("E", unit="Pa", positive=True)
        if it.has("G") and it.has("nu"):
            raise it.err("G", "give either G or nu, not both")
        if it.has("G"):
            G = it.num("G", unit="Pa", positive=True)
        else:
            nu = it.num("nu", 0.3)
            if not -1.0 < nu < 0.5:
                raise it.err("nu", f"Poisson's ratio must be in (-1, 0.5) (got {nu:g})")
            G = E / (2.0 * (1.0 + nu))
        sec = Section(
            E=E,
            G=G,
            rho=it.num("rho", unit="kg/m^3", positive=True),
            A=it.num("A", unit="m^2", positive=True),
            I=it.num("I", unit="m^4", positive=True),
            kappa=it.num("kappa", 5.0 / 6.0, positive=True),
            eta=it.num("eta", 0.0, unit="N s/m^2", nonneg=True),
        )
        ne = it.raw("elements", 1)
        if isinstance(ne, bool) or not isinstance(ne, int) or ne < 1:
            raise it.err("elements", f"must be an integer >= 1, got {ne!r}")
        beams.append(Beam(iid, (nl[0], nl[1]), sec, ne))
        beam_len[iid] = L
    return beams, beam_len


def _read_contacts(
    src: str,
    raw: dict[str, Any],
    ids: _Ids,
    beams: list[Beam],
    node_xy: dict[str, np.ndarray],
    body_ids: set[str],
    mov_bodies: set[str],
) -> list[Contact]:
    """[[contact]]: massless points that follow a moving body along a track of beams."""
    beam_by_id = {b.id: b for b in beams}
    contacts: list[Contact] = []
    for k, t in enumerate(raw.get("contact", [])):
        iid = _id_of(src, "contact", k, t)
        it = _Item(
            src,
            f'[[contact]] "{iid}"',
            t,
            ("id", "beams", "follows", "offset", "shift", "outside", "description"),
        )
        ids.register("contact", iid)
        bl = it.raw("beams")
        if isinstance(bl, str):
            bl = [bl]
        if not isinstance(bl, list) or not bl or not all(isinstance(b, str) for b in bl):
            raise it.err("beams", f"must be a beam id or a list of collinear beam ids, got {bl!r}")
        for b in bl:
            if b not in beam_by_id:
                raise it.err(
                    "beams", f"beam '{b}' is not defined (known: {', '.join(sorted(beam_by_id)) or 'none'})"
                )
        _check_track(it, [beam_by_id[b] for b in bl], node_xy)
        fol = it.str("follows")
        if fol not in body_ids:
            raise it.err("follows", f"body '{fol}' is not defined (known: {', '.join(sorted(body_ids))})")
        if fol not in mov_bodies:
            raise it.err(
                "follows", f"body '{fol}' is not in [movable] bodies; a contact follows a moving body"
            )
        outside = it.raw("outside", "error")
        if outside not in ("error", "clamp"):
            raise it.err(
                "outside",
                f"must be 'error' (the contact may not leave its track) or 'clamp' (it waits at the track end), got {outside!r}",
            )
        contacts.append(
            Contact(
                iid, tuple(bl), fol, it.num("offset", 0.0, unit="m"), it.num("shift", 0.0, unit="m"), outside
            )
        )
    return contacts


def _read_attachments(
    src: str,
    raw: dict[str, Any],
    ids: _Ids,
    node_xy: dict[str, np.ndarray],
    body_ids: set[str],
    mov_bodies: set[str],
) -> list[Attachment]:
    """[[attachment]]: nodes clamped to a body or the ground (once each)."""
    attachments: list[Attachment] = []
    for k, t in enumerate(raw.get("attachment", [])):
        iid = _id_of(src, "attachment", k, t, required=False)
        it = _Item(src, f'[[attachment]] "{iid}"', t, ("id", "node", "body", "description"))
        if "id" in t:
            ids.register("attachment", iid)
        n = it.str("node")
        if n not in node_xy:
            raise it.err("node", f"node {n!r} is not defined (known: {', '.join(sorted(node_xy)) or 'none'})")
        b = it.str("body")
        if b != GROUND and b not in body_ids:
            raise it.err(
                "body", f"body '{b}' is not defined (known: {', '.join(sorted(body_ids | {GROUND}))})"
            )
        if b in mov_bodies:
            raise it.err(
                "body",
                f"body '{b}' is movable and node '{n}' is not; attach moving parts through a [[contact]]",
            )
        attachments.append(Attachment(iid, n, b))
    att_nodes = [a.node for a in attachments]
    for n in set(att_nodes):
        if att_nodes.count(n) > 1:
            raise ModelError(
                f"node '{n}' is attached twice; a node can be clamped to one body only",
                source=src,
                item="[[attachment]]",
                field="node",
            )
    return attachments


def _read_supports(
    src: str,
    raw: dict[str, Any],
    node_xy: dict[str, np.ndarray],
    body_ids: set[str],
    coord_names: set[str],
) -> list[Support]:
    """[[support]]: fixed coordinates of a node, a body or (matrix models) a coordinate."""
    supports: list[Support] = []
    for k, t in enumerate(raw.get("support", [])):
        iid = _id_of(src, "support", k, t, required=False)
        it = _Item(src, f'[[support]] "{iid}"', t, ("id", "node", "body", "coordinate", "fix", "description"))
        targets = [f for f in ("node", "body", "coordinate") if f in t]
        if len(targets) != 1:
            raise it.err(None, "give exactly one of node, body or coordinate")
        tgt = it.str(targets[0])
        if targets[0] == "node" and tgt not in node_xy:
            raise it.err("node", f"node '{tgt}' is not defined (known: {', '.join(sorted(node_xy))})")
        if targets[0] == "body" and tgt not in body_ids:
            raise it.err("body", f"body '{tgt}' is not defined (known: {', '.join(sorted(body_ids))})")
        if targets[0] == "coordinate":
            if tgt not in coord_names:
                raise it.err("coordinate", f"coordinate '{tgt}' is not in [matrices] coordinates")
            supports.append(Support(iid, tgt, ("",)))
            continue
        fix = it.raw("fix", list(DIRECTIONS))
        if not isinstance(fix, list) or not fix or any(f not in DIRECTIONS for f in fix):
            raise it.err("fix", f"must be a list drawn from {list(DIRECTIONS)}, got {fix!r}")
        supports.append(Support(iid, tgt, tuple(fix)))
    return supports


def _read_constraints(src: str, raw: dict[str, Any], all_coords: list[str]) -> list[Constraint]:
    """[[constraint]]: linear equations that make coordinates dependent."""
    constraints: list[Constraint] = []
    for k, t in enumerate(raw.get("constraint", [])):
        iid = _id_of(src, "constraint", k, t, required=False)
        it = _Item(src, f'[[constraint]] "{iid}"', t, ("id", "dependent", "equations", "description"))
        dep = it.raw("dependent")
        if not isinstance(dep, list) or not dep or not all(isinstance(x, str) for x in dep):
            raise it.err("dependent", f"must be a non-empty list of coordinate names, got {dep!r}")
        for x in dep:
            if x not in all_coords:
                raise it.err(
                    "dependent",
                    f"'{x}' is not a coordinate of the model (e.g. {', '.join(list(all_coords)[:6])}, ...)",
                )
        eqs = it.raw("equations")
        if not isinstance(eqs, list) or not eqs or not all(isinstance(e, dict) and e for e in eqs):
            raise it.err("equations", 'must be a list of tables {"coordinate" = coefficient, ...}')
        rows = []
        for e in eqs:
            row = []
            for cname, coef in e.items():
                if cname not in all_coords:
                    raise it.err("equations", f"'{cname}' is not a coordinate of the model")
                if isinstance(coef, bool) or not isinstance(coef, int | float) or not math.isfinite(coef):
                    raise it.err(
                        "equations", f"coefficient of '{cname}' must be a finite number, got {coef!r}"
                    )
                row.append((cname, float(coef)))
            rows.append(tuple(row))
        constraints.append(Constraint(iid, tuple(dep), tuple(rows)))
    return constraints


def _check_massless(src: str, bodies: list[Body], constraints: list[Constraint]) -> None:
    """A massless body must have all its coordinates dependent."""
    constrained = {x for c in constraints for x in c.dependent}
    for body in bodies:
        if body.mass == 0.0:
            missing = [d for d in DIRECTIONS if f"{body.id}.{d}" not in constrained]
            if missing:
                raise ModelError(
                    "mass must be > 0 (got 0 kg): a massless body is allowed only where all its coordinates"
                    f" are dependent, and {', '.join(body.id + '.' + m for m in missing)} are not; give it a mass,"
                    " make it a [[contact]], or declare it in a [[constraint]]",
                    source=src,
                    item=f'[[body]] "{body.id}"',
                    field="mass",
                )


def _coordinate_names(bodies, nodes, beams, contacts, matrices) -> list[str]:
    if matrices is not None:
        return list(matrices.coordinates)
    names = []
    for b in bodies:
        names += [f"{b.id}.{d}" for d in DIRECTIONS]
    for c in contacts:
        names += [f"{c.id}.{d}" for d in DIRECTIONS]
    for n in nodes:
        names += [f"{n.id}.{d}" for d in DIRECTIONS]
    for bm in beams:
        for j in range(1, bm.elements):
            names += [f"{bm.id}#{j}.{d}" for d in DIRECTIONS]
    return names


def _check_track(it: _Item, beams: list[Beam], node_xy: dict[str, np.ndarray]) -> None:
    """A contact's beams must form one straight, contiguous track."""
    if len(beams) == 1:
        return
    p0 = node_xy[beams[0].nodes[0]]
    e = node_xy[beams[0].nodes[1]] - p0
    e = e / np.linalg.norm(e)
    prev_end = node_xy[beams[0].nodes[1]]
    for b in beams[1:]:
        a, c = node_xy[b.nodes[0]], node_xy[b.nodes[1]]
        d = (c - a) / np.linalg.norm(c - a)
        if abs(d @ e - 1.0) > 1e-9 or np.linalg.norm(a - prev_end) > 1e-9:
            raise it.err(
                "beams",
                f"beam '{b.id}' does not continue the track straight from the previous beam's end;"
                " list collinear beams in order, each starting where the previous one ends",
            )
        prev_end = c


def _check_movable(model: Model) -> None:
    from ._geometry import contact_track_position

    mv = model.movable
    src = model.source
    if model.contacts and mv is None:
        raise ModelError(
            "a [[contact]] needs a [movable] table naming the moving bodies",
            source=src,
            item=f'[[contact]] "{model.contacts[0].id}"',
        )
    assert mv is not None
    for c in model.contacts:
        for s in (mv.range[0], mv.position, mv.range[1]):
            try:
                contact_track_position(model, c, s)
            except ValueError as exc:
                raise ModelError(
                    f"{exc}; narrow [movable] range or extend the track",
                    source=src,
                    item=f'[[contact]] "{c.id}"',
                    field="beams",
                ) from None
