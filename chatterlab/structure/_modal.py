"""Modal analysis of a frozen configuration.

Natural frequencies and mode shapes from C* phi = omega^2 A* phi (Eq. 2.15
with the slide held still, no feedback), the displacement of named points in
each mode, and rigid-body modes detected and named: a floating part is a
:class:`~chatterlab.errors.ModelError` unless rigid-body modes are asked for.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import scipy.linalg

from ..errors import InputError, ModelError
from ..io import Result
from ..model._items import DIRECTIONS
from ._assembly import FrozenSystem, System

__all__ = ["Modes", "modes", "rigid_body_description"]

#: a mode is rigid if omega^2 < RIGID_TOL * (largest omega^2): a true zero
#: eigenvalue comes out at round-off level, ~1e-16 times the largest (measured
#: 1e-17..1e-16 for free beams and the free shaper up to 2300 coordinates).
#: The ratio of real elastic eigenvalues can be small too: a finely meshed
#: machine on soft mounts (the shaper, 64 elements per beam, on 1.5 Hz mounts)
#: has 2e-11, so the bound sits ~5000 eps above round-off, not higher.
RIGID_TOL = 1e-12


@dataclass(frozen=True, eq=False)
class Modes(Result):
    """Result of :func:`modes`.

    Attributes
    ----------
    omega : ndarray, shape (k,)
        Undamped natural angular frequencies, rad/s (elastic modes only).
    shapes : ndarray, shape (n_i, k)
        Mode shapes over the independent coordinates, mass-normalised
        (phi^T A* phi = I), in m/sqrt(kg) for translations.
    damping_ratio : ndarray, shape (k,)
        phi^T B* phi / (2 omega): the modal damping ratio when damping is
        light and nearly proportional (an estimate; FRFs use B* in full).
    rigid : tuple of str
        Rigid-body modes found, described by the parts they move (only when
        ``rigid="report"``).
    """

    frozen: FrozenSystem
    omega: np.ndarray
    shapes: np.ndarray
    damping_ratio: np.ndarray
    rigid: tuple[str, ...] = ()
    rigid_shapes: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))

    @property
    def frequency_hz(self) -> np.ndarray:
        return self.omega / (2 * np.pi)

    @property
    def position(self) -> float | None:
        return self.frozen.position

    def __len__(self) -> int:
        return self.omega.size

    def point_shapes(self, name: str) -> np.ndarray:
        """Displacement (u, v, theta) of a point in each mode, shape (3, k)."""
        return self.frozen.point(name) @ self.shapes

    def _point_names(self) -> list[str]:
        mdl = self.frozen.model
        if mdl.is_matrix_model:
            return [p.id for p in mdl.points]
        return [p.id for p in mdl.points] + [b.id for b in mdl.bodies] + [c.id for c in mdl.contacts]

    def to_dict(self) -> dict[str, Any]:
        """The JSON contract of ``chatterlab modes --format json`` (see
        docs/cli.md): plain numbers, SI units except frequencies in Hz."""
        from .._version import __version__

        pts = self._point_names()
        shapes = {p: self.point_shapes(p) for p in pts}
        mdl = self.frozen.model
        return {
            "chatterlab": __version__,
            "kind": "modes",
            "model": mdl.source,
            "name": mdl.name,
            "variant": mdl.variant,
            "position_m": self.position,
            "n_independent": self.frozen.n,
            "normalisation": "mass (phi^T A* phi = 1); translations in m/sqrt(kg), rotations in rad/sqrt(kg)",
            "modes": [
                {
                    "index": k + 1,
                    "frequency_hz": float(self.frequency_hz[k]),
                    "omega_rad_s": float(self.omega[k]),
                    "period_s": float(1.0 / self.frequency_hz[k]),
                    "damping_ratio": float(self.damping_ratio[k]),
                    "points": {p: [float(x) for x in shapes[p][:, k]] for p in pts},
                }
                for k in range(len(self))
            ],
            "rigid_body_modes": list(self.rigid),
        }

    def table(self) -> str:
        """A readable table: mode, frequency (Hz), period (s), damping ratio."""
        lines = [f"{'mode':>4}  {'f [Hz]':>10}  {'T [s]':>9}  {'zeta':>7}"]
        for k in range(len(self)):
            f = self.frequency_hz[k]
            lines.append(f"{k + 1:>4}  {f:>10.3f}  {1 / f:>9.5f}  {self.damping_ratio[k]:>7.4f}")
        for r in self.rigid:
            lines.append(f"rigid-body mode: {r}")
        return "\n".join(lines)

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """The modes (``mode`` 1..k) with frequency, angular frequency, period
        and damping ratio, and the mass-normalised shapes over the
        independent coordinates (``coordinate``); the model as attributes."""
        k = np.arange(1, len(self) + 1)
        f = self.frequency_hz
        mdl = self.frozen.model
        return (
            {
                "mode": (k, "1", "mode number"),
                "coordinate": (np.arange(self.frozen.n), "1", "independent coordinate"),
            },
            {
                "frequency": (f, "Hz", "undamped natural frequency", ("mode",)),
                "omega": (self.omega, "rad/s", "undamped natural angular frequency", ("mode",)),
                "period": (1.0 / f, "s", "period of the mode", ("mode",)),
                "damping_ratio": (self.damping_ratio, "1", "modal damping ratio (estimate)", ("mode",)),
                "shape": (self.shapes.T, "m/sqrt(kg)", "mass-normalised mode shape", ("mode", "coordinate")),
            },
            {
                "title": "chatterlab modes",
                "model": str(mdl.source),
                "position_m": float("nan") if self.position is None else self.position,
                "coordinates": json.dumps(list(self.frozen.names)),
                "rigid_body_modes": "; ".join(self.rigid),
            },
        )

    def to_csv(self, path: Any) -> Path | None:
        """The modes as CSV in the naming scheme of every chatterlab file:
        ``mode [1]``, ``frequency [Hz]``, ``omega [rad/s]``, ``period [s]``,
        ``damping_ratio [1]``, every number exact; written atomically."""
        from ..io import write_csv

        coords, data, _ = self.dataset_parts()
        cols = {k: v[:3] for k, v in data.items() if v[3] == ("mode",)}
        return write_csv(path, {"mode": coords["mode"]}, cols)

    def drawing(self, samples: int = 17) -> dict[str, Any]:
        """The structure in the x-y plane and each mode's displacement of it,
        as plain data for :func:`chatterlab.plot.plot_mode_shapes`.

        ``members``: one dict per beam (sampled at ``samples`` points, at
        least two per element, through the beam's own shape functions),
        body (its centre) and spring (its two ends; the ground does not
        move), with ``kind``, ``id``, ``xy`` (n, 2) in m and ``shape``
        (k, n, 2): the (u, v) of those points in each mode (mass-normalised).
        A matrix-level model has no geometry: InputError."""
        from ..model._geometry import beam_axes, point_xy
        from ..model._items import PointRef

        fz, s = self.frozen, self.position
        mdl, sy = fz.model, fz.system
        if mdl.is_matrix_model:
            raise InputError(
                f"{mdl.source}: a matrix-level model has no geometry to draw mode shapes on;"
                " plot the frequencies (Modes.plot(reference=...)) instead"
            )

        def member(kind: str, ident: str, refs: list[PointRef]) -> dict[str, Any]:
            xy = np.array([point_xy(mdl, r, s) for r in refs])
            uv = np.stack([(fz.expand(sy.point_map(r, s))[:2] @ self.shapes).T for r in refs], axis=1)
            return {"kind": kind, "id": ident, "xy": xy, "shape": uv}

        members = []
        for b in mdl.beams:
            L = beam_axes(mdl, b)[2]
            n = max(samples, 2 * b.elements + 1)
            members.append(
                member("beam", b.id, [PointRef("beam", b.id, distance=d) for d in np.linspace(0, L, n)])
            )
        for bd in mdl.bodies:
            members.append(member("body", bd.id, [PointRef("body", bd.id, label=bd.id)]))
        for sp in mdl.springs:
            m = member("spring", sp.id, [sp.a, sp.b])
            for i, r in enumerate((sp.a, sp.b)):  # a spring to the ground is drawn at its other end
                if r.kind == "ground":
                    m["xy"][i] = m["xy"][1 - i]
            members.append(m)
        return {
            "members": members,
            "frequency_hz": self.frequency_hz,
            "model": mdl.name or str(mdl.source),
            "position": s,
        }

    def plot(
        self,
        ax: Any = None,
        *,
        reference: np.ndarray | None = None,
        label: str = "chatterlab",
        shapes: bool | None = None,
    ) -> Any:
        """The mode shapes drawn on the structure (one panel per mode, the
        deformed over the undeformed shape, frequencies in the legend) when
        the model has geometry; the natural frequencies as bars (optionally
        against ``reference`` values in Hz) for a matrix-level model, with a
        reference, or with ``shapes=False``.  Imports matplotlib; returns the
        Axes (the array of panels for the mode shapes)."""
        if shapes is None:
            shapes = reference is None and not self.frozen.model.is_matrix_model
        if shapes:
            from ..plot import plot_mode_shapes

            return plot_mode_shapes(self.drawing(), ax=ax)
        from ..plot import plot_frequencies

        return plot_frequencies(self.frequency_hz, reference=reference, ax=ax, label=label)


def _items_of(sy: System, q_all: np.ndarray) -> list[str]:
    amp: dict[str, np.ndarray] = {}
    for k, nm in enumerate(sy.names):
        item, _, d = nm.rpartition(".")
        amp.setdefault(item, np.zeros(3))[DIRECTIONS.index(d) if d in DIRECTIONS else 0] = abs(q_all[k])
    peak = max(float(a.max()) for a in amp.values()) or 1.0
    out = []
    for item, a in amp.items():
        if a.max() > 0.05 * peak:
            dirs = [DIRECTIONS[j] for j in range(3) if a[j] > 0.05 * peak]
            out.append(f"{item} ({'/'.join(dirs)})")
    return out


def rigid_body_description(sy: System, phi_i: np.ndarray, W: np.ndarray) -> str:
    """Name the parts a rigid-body mode moves."""
    q = np.zeros(sy.n)
    q[sy.i] = phi_i
    if len(sy.d):
        q[sy.d] = W @ phi_i
    return ", ".join(_items_of(sy, q)[:8])


def modes(
    system: System | FrozenSystem,
    *,
    count: int | None = None,
    position: float | None = None,
    rigid: Literal["error", "report"] = "error",
) -> Modes:
    """Natural frequencies and mode shapes at a frozen configuration.

    Parameters
    ----------
    system : System or FrozenSystem
        The assembled model; a ``System`` is frozen at ``position``.
    count : int, optional
        Number of lowest elastic modes to return (default: all).
    position : float, optional
        Slide position s (m) when ``system`` is a ``System``.
    rigid : {"error", "report"}
        What a rigid-body mode (a part not held by the foundation) means: a
        :class:`ModelError` naming the floating parts (default), or a report
        in :attr:`Modes.rigid` (e.g. for a free-free structure).

    Returns
    -------
    Modes
    """
    if count is not None and (
        isinstance(count, bool) or not isinstance(count, int | np.integer) or count < 1
    ):
        raise InputError(f"count must be a positive integer, got {count!r}")
    if rigid not in ("error", "report"):
        raise InputError(f"rigid must be 'error' or 'report', got {rigid!r}")
    fz = system.at(position) if isinstance(system, System) else system
    A, B, C = fz.A, fz.B, fz.C
    lam, phi = scipy.linalg.eigh(C, A)
    lam_max = max(float(np.abs(lam).max()), 1e-300)
    is_rigid = lam < RIGID_TOL * lam_max
    sy = fz.system
    if np.any(is_rigid):
        descr = tuple(rigid_body_description(sy, phi[:, k], fz.W) for k in np.nonzero(is_rigid)[0])
        if rigid == "error":
            raise ModelError(
                f"the structure is not held by the foundation: {int(is_rigid.sum())} rigid-body mode(s);"
                f" the first moves {descr[0]} freely. Connect the part to the ground or to the rest"
                " with a [[spring]], [[attachment]] or [[support]]",
                source=fz.model.source,
            )
    else:
        descr = ()
    el = ~is_rigid
    omega = np.sqrt(lam[el])
    shapes = phi[:, el]
    if count is not None:
        omega, shapes = omega[:count], shapes[:, :count]
    zeta = np.einsum("ik,ij,jk->k", shapes, B, shapes) / (2 * omega) if omega.size else np.zeros(0)
    return Modes(fz, omega, shapes, zeta, descr, phi[:, is_rigid])
