"""Assembly: Model -> :class:`~chatterlab.structure.System` (Eqs. 2.2-2.13 of
the seed paper): coordinates, element matrices of the decoupled system, the
constraint rows of attachments, [[constraint]] equations and moving
contacts, the partition into independent, dependent and given coordinates,
and the checks that W(s) exists and the reduced inertia is regular.

The classes live in ``_system`` (System, FrozenSystem, CouplingMatrices)
and ``_moving`` (MovingReduction) and are importable from here too.

References
----------
.. [1] E. Wittbrodt, K. J. Kaliński, "Transient vibration of unsteady linear
   closed loop systems", Eqs. (2.2)-(2.18).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from types import MappingProxyType

import numpy as np

from ..errors import InputError, ModelError
from ..model._geometry import beam_axes, body_centre
from ..model._items import DIRECTIONS, GROUND, Model
from ._elements import beam_matrices, rigid_point_matrix, rotation3
from ._moving import MovingReduction, _ContactRows, _Element
from ._system import CouplingMatrices, FrozenSystem, System

__all__ = ["System", "FrozenSystem", "CouplingMatrices", "MovingReduction", "assemble"]


# ===================================================================== assembly


def assemble(model: Model) -> System:
    """Assemble a :class:`System` from a :class:`Model`.

    Raises
    ------
    ModelError
        When the constraints do not determine the dependent coordinates
        (W_d^T W_d singular), or a coordinate is both dependent and given.
    """
    if getattr(model, "frf", None) is not None:
        raise InputError(
            f"{model.source}: its structure is a measured FRF ([frf]), which has no matrices to assemble;"
            " draw its lobes (chatterlab lobes, chatterlab.lobes.lobes_model_frf), or fit modes to it"
            " (chatterlab.structure fit) for roots, Floquet and the time domain"
        )
    if model.is_matrix_model:
        return _assemble_matrices(model)
    src = model.source
    names = _coordinate_names(model)
    index = {nm: k for k, nm in enumerate(names)}
    n = len(names)

    def cols(item: str) -> np.ndarray:
        return np.array([index[f"{item}.{d}"] for d in DIRECTIONS])

    M, L, K, elements = _element_matrices(model, n, cols)
    given: set[int] = set(cols(GROUND).tolist())
    dependent: dict[int, str] = {}

    def mark_dependent(k: int, why: str) -> None:
        if k in dependent:
            raise ModelError(
                f"coordinate '{names[k]}' is made dependent twice ({dependent[k]} and {why}); remove one",
                source=src,
                item=why,
            )
        dependent[k] = why

    rows = _constraint_rows(model, index, n, cols, given, mark_dependent)
    contact_rows = _contact_rows(model, elements, cols, mark_dependent)

    overlap = sorted(set(dependent) & given)
    if overlap:
        k = overlap[0]
        raise ModelError(
            f"coordinate '{names[k]}' is both given (a support or ground attachment) and dependent"
            f" ({dependent[k]}); remove one of them",
            source=src,
        )
    d_idx = np.array(sorted(dependent), dtype=int)
    g_idx = np.array(sorted(given), dtype=int)
    i_idx = np.array([k for k in range(n) if k not in dependent and k not in given], dtype=int)

    for X in (M, L, K):
        X[:] = 0.5 * (X + X.T)
    for X in (M, L, K):
        X.setflags(write=False)
    const_rows = np.array(rows).reshape(len(rows), n)
    sysm = System(
        model=model,
        names=tuple(names),
        i=i_idx,
        d=d_idx,
        g=g_idx,
        M=M,
        L=L,
        K=K,
        _const_rows=const_rows,
        _contacts=tuple(contact_rows),
        _elements=MappingProxyType(elements),
        index=MappingProxyType(index),
    )
    sysm = _absorbers_into(_springs_into(sysm))
    _check_constraints(sysm)
    _check_mass(sysm)
    return sysm


def _coordinate_names(model: Model) -> list[str]:
    """All coordinates: bodies, contacts, nodes, inner beam nodes, the ground."""
    names: list[str] = []
    for b in model.bodies:
        names += [f"{b.id}.{d}" for d in DIRECTIONS]
    for c in model.contacts:
        names += [f"{c.id}.{d}" for d in DIRECTIONS]
    for nd in model.nodes:
        names += [f"{nd.id}.{d}" for d in DIRECTIONS]
    for bm in model.beams:
        for j in range(1, bm.elements):
            names += [f"{bm.id}#{j}.{d}" for d in DIRECTIONS]
    names += [f"{GROUND}.{d}" for d in DIRECTIONS]
    return names


def _element_matrices(
    model: Model, n: int, cols: Callable[[str], np.ndarray]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, tuple[_Element, ...]]]:
    """M, L, K of the decoupled system (Eq. 2.13): rigid bodies and beam
    elements, and each beam's elements."""
    M = np.zeros((n, n))
    L = np.zeros((n, n))
    K = np.zeros((n, n))

    for b in model.bodies:
        c3 = cols(b.id)
        M[c3, c3] += (b.mass, b.mass, b.inertia)

    elements: dict[str, tuple[_Element, ...]] = {}
    for bm in model.beams:
        p0, e, Lb = beam_axes(model, bm)
        ids = [bm.nodes[0]] + [f"{bm.id}#{j}" for j in range(1, bm.elements)] + [bm.nodes[1]]
        h = Lb / bm.elements
        els = []
        for j in range(bm.elements):
            xy_i = p0 + j * h * e
            xy_j = p0 + (j + 1) * h * e
            c6 = np.concatenate([cols(ids[j]), cols(ids[j + 1])])
            sec = bm.section
            Me, Le, Ke = beam_matrices(
                xy_i, xy_j, E=sec.E, G=sec.G, A=sec.A, I=sec.I, kappa=sec.kappa, rho=sec.rho, eta=sec.eta
            )
            ix = np.ix_(c6, c6)
            M[ix] += Me
            L[ix] += Le
            K[ix] += Ke
            els.append(_Element(bm, j * h, h, xy_i, xy_j, c6))
        elements[bm.id] = tuple(els)
    return M, L, K, elements


def _constraint_rows(
    model: Model,
    index: dict[str, int],
    n: int,
    cols: Callable[[str], np.ndarray],
    given: set[int],
    mark_dependent: Callable[[int, str], None],
) -> list[np.ndarray]:
    """The constant constraint rows (attachments to bodies, [[constraint]]
    equations); supports and ground attachments add to ``given``."""
    rows: list[np.ndarray] = []
    for s_ in model.supports:
        if s_.target in index:  # pragma: no cover - coordinate supports are matrix-model only
            given.add(index[s_.target])
            continue
        for d in s_.dofs:
            given.add(index[f"{s_.target}.{d}"])

    for a in model.attachments:
        nc = cols(a.node)
        if a.body == GROUND:
            given.update(nc.tolist())
            continue
        bc = cols(a.body)
        arm = node_xy_of(model, a.node) - body_centre(model, a.body)
        R = rigid_point_matrix(arm)
        for r in range(3):
            row = np.zeros(n)
            row[nc[r]] = 1.0
            row[bc] -= R[r]
            rows.append(row)
            mark_dependent(int(nc[r]), f'[[attachment]] "{a.id}"')

    for con in model.constraints:
        for dname in con.dependent:
            mark_dependent(index[dname], f'[[constraint]] "{con.id}"')
        for eq in con.equations:
            row = np.zeros(n)
            for cname, coef in eq:
                row[index[cname]] += coef
            rows.append(row)
    return rows


def _contact_rows(
    model: Model,
    elements: dict[str, tuple[_Element, ...]],
    cols: Callable[[str], np.ndarray],
    mark_dependent: Callable[[int, str], None],
) -> list[_ContactRows]:
    """Each contact's track (its beams' elements end to end) and where it is
    on it as the slide moves."""
    contact_rows = []
    mv = model.movable
    for c in model.contacts:
        for k in cols(c.id):
            mark_dependent(int(k), f'[[contact]] "{c.id}"')
        track: list[_Element] = []
        start = 0.0
        for bid in c.beams:
            for el in elements[bid]:
                track.append(_Element(el.beam, start + el.start, el.length, el.xy_i, el.xy_j, el.cols))
            start += beam_axes(model, next(b for b in model.beams if b.id == bid))[2]
        beams0 = next(b for b in model.beams if b.id == c.beams[0])
        p0, e, _ = beam_axes(model, beams0)
        s_ref = mv.position if mv is not None else 0.0
        x_ref = float((body_centre(model, c.follows, s_ref) - p0) @ e) + c.shift
        rate = float(np.array(mv.direction) @ e) if mv is not None else 0.0
        contact_rows.append(
            _ContactRows(
                cols(c.id), tuple(track), x_ref, s_ref, rate, c.offset, start, c.id, c.outside == "clamp"
            )
        )
    return contact_rows


def node_xy_of(model: Model, nid: str) -> np.ndarray:
    for nd in model.nodes:
        if nd.id == nid:
            return np.array(nd.xy, float)
    raise KeyError(nid)


def _springs_into(sy: System) -> System:
    """Add the spring-damping elements to K and L (their maps do not depend
    on s: check_geometry refuses springs that mix moving and fixed parts)."""
    K = np.array(sy.K)
    L = np.array(sy.L)
    for sp in sy.model.springs:
        Jl = rotation3(sp.angle).T @ (sy.point_map(sp.a) - sy.point_map(sp.b))
        K += Jl.T @ np.diag(sp.c) @ Jl
        L += Jl.T @ np.diag(sp.d) @ Jl
    K = 0.5 * (K + K.T)
    L = 0.5 * (L + L.T)
    K.setflags(write=False)
    L.setflags(write=False)
    return replace(sy, K=K, L=L)


def _absorbers_into(sy: System) -> System:
    """Add each [[absorber]] (chatterlab.model._absorber): one independent
    coordinate ``ID.u`` after all others (the absorber's displacement along
    its unit direction e), the mass m on it and, across e, on the host
    point's motion (the absorber is guided rigidly across e), and the spring
    k and damper c on u - e . w_P, w_P the host point's (x, y) motion."""
    absorbers = sy.model.absorbers
    if not absorbers:
        return sy
    n0, na = sy.n, len(absorbers)
    n = n0 + na
    M, L, K = (np.zeros((n, n)) for _ in range(3))
    M[:n0, :n0], L[:n0, :n0], K[:n0, :n0] = sy.M, sy.L, sy.K
    for j, ab in enumerate(absorbers):
        P = sy.point_map(ab.at)[:2]  # the host point's (x, y), over the first n0 coordinates
        e = np.array(ab.direction)
        rel = np.zeros(n)
        rel[n0 + j] = 1.0
        rel[:n0] -= e @ P  # u - e . w_P
        across = np.zeros(n)
        across[:n0] = np.array([-e[1], e[0]]) @ P
        M[n0 + j, n0 + j] += ab.mass
        M += ab.mass * np.outer(across, across)
        K += ab.stiffness * np.outer(rel, rel)
        L += ab.damping * np.outer(rel, rel)
    for X in (M, L, K):
        X[:] = 0.5 * (X + X.T)
        X.setflags(write=False)
    names = (*sy.names, *(f"{ab.id}.u" for ab in absorbers))
    rows = np.zeros((sy._const_rows.shape[0], n))
    rows[:, :n0] = sy._const_rows
    return replace(
        sy,
        names=names,
        index=MappingProxyType({nm: k for k, nm in enumerate(names)}),
        i=np.concatenate([sy.i, np.arange(n0, n)]).astype(int),
        M=M,
        L=L,
        K=K,
        _const_rows=rows,
    )


def _check_constraints(sy: System) -> None:
    if len(sy.d) == 0:
        return
    G = sy.constraint_matrix(None)[0]
    Gd = G[:, sy.d]
    N = Gd.T @ Gd
    w, V = np.linalg.eigh(N)
    tol = 1e-10 * max(1.0, w.max())
    if w.min() <= tol:
        v = V[:, 0]
        culprits = [sy.names[sy.d[k]] for k in np.argsort(-np.abs(v))[:4] if abs(v[k]) > 1e-3]
        # name the [[constraint]] items that declared the undetermined coordinates
        owners = [
            f'[[constraint]] "{c.id}"'
            for c in sy.model.constraints
            if any(x in c.dependent for x in culprits)
        ]
        raise ModelError(
            ("dependent: " if owners else "")
            + "the constraint equations do not determine the dependent coordinates"
            f" {', '.join(culprits)} (W_d^T W_d of Eq. 2.6 is singular); give each dependent"
            " coordinate an equation in which it appears, and no dependent coordinate twice",
            source=sy.model.source,
            item=", ".join(owners)
            or ("[[constraint]]" if sy.model.constraints else "[[contact]]/[[attachment]]"),
            field="dependent" if owners else None,
        )
    # Eq. 2.6 is the least-squares solution of W_i + W_d W = 0; it solves the
    # constraints only if they are consistent.  More equations than dependent
    # coordinates that also tie independent coordinates together would
    # otherwise give a silent compromise W.
    W = sy.W(None)
    res = np.abs(G[:, sy.i] + Gd @ W).max(axis=1) if len(sy.i) else np.zeros(G.shape[0])
    scale = np.abs(G).max(axis=1) * max(1.0, float(np.abs(W).max(initial=0.0)))
    bad = np.nonzero(res > 1e-9 * scale)[0]
    if bad.size:
        mdl = sy.model
        owners = [f'[[attachment]] "{a.id}"' for a in mdl.attachments if a.body != GROUND for _ in range(3)]
        owners += [f'[[constraint]] "{c.id}"' for c in mdl.constraints for _ in c.equations]
        owners += [f'[[contact]] "{c.id}"' for c in mdl.contacts for _ in range(3)]
        items = list(dict.fromkeys(owners[k] for k in bad if k < len(owners)))
        raise ModelError(
            "equations: the constraint equations cannot all hold: together they also tie"
            " independent coordinates to each other, so no W satisfies W_i + W_d W = 0 (Eq. 2.6);"
            " drop the redundant equation or declare one more coordinate dependent",
            source=mdl.source,
            item=", ".join(items) or "[[constraint]]",
            field="equations",
        )


def _check_mass(sy: System) -> None:
    A = sy.reduce(None)[0]
    try:
        np.linalg.cholesky(A)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(A)
        v = V[:, 0]
        culprits = [sy.names_i[k] for k in np.argsort(-np.abs(v))[:3]]
        raise ModelError(
            f"the reduced inertia matrix A* is singular: coordinates {', '.join(culprits)} carry no mass;"
            " give the body a mass or make its coordinates dependent",
            source=sy.model.source,
        ) from None


def _assemble_matrices(model: Model) -> System:
    mb = model.matrices
    assert mb is not None
    names = list(mb.coordinates)
    index = {nm: k for k, nm in enumerate(names)}
    given = sorted({index[g] for g in mb.given} | {index[s.target] for s in model.supports})
    i_idx = np.array([k for k in range(len(names)) if k not in given], dtype=int)
    sysm = System(
        model=model,
        names=tuple(names),
        i=i_idx,
        d=np.zeros(0, dtype=int),
        g=np.array(given, dtype=int),
        M=mb.M,
        L=mb.L,
        K=mb.K,
        _const_rows=np.zeros((0, len(names))),
        _contacts=(),
        _elements=MappingProxyType({}),
        index=MappingProxyType(index),
    )
    if len(i_idx) == 0:
        raise ModelError(
            "every coordinate is given (fixed): nothing can move; remove some from [matrices] given / [[support]]",
            source=model.source,
            item="[matrices]",
            field="given",
        )
    # springs between named-coordinate points add to L and K (e.g. a joint added to an imported model)
    return _absorbers_into(_springs_into(sysm) if model.springs else sysm)
