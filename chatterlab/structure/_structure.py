"""The structure as every engine sees it: :class:`Structure`,
M q'' + C q' + K q = f on n named coordinates.

One value for the three ways a structure enters an analysis: a frozen RDFEM
configuration (:attr:`chatterlab.structure.FrozenSystem.structure`: M = A*,
C = B*, K = C* of Eq. 2.16-2.18), a matrix-level or modal model, and the few
lines of a benchmark (:meth:`Structure.single_dof`, :meth:`Structure.modal`).
The cutting process is not here: with the map J from these coordinates to
the process's and the process itself it makes the closed loop
(:class:`chatterlab.process.ClosedLoop`).

Modal reduction (:meth:`Structure.reduce`): a Rayleigh-Ritz projection on the
undamped modes below a frequency augmented by the static residual of given
load directions (modal truncation augmentation; Dickens, Nakagawa &
Wittbrodt, Comput. Struct. 62 (1997) 985-998): the kept modes stay exact and
the static compliance in the load directions is exact.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np
import scipy.linalg as sla

from ..errors import InputError, check_nonneg, check_positive
from ._complex import ComplexModes, complex_modes, dynamic_receptance

__all__ = ["Structure"]


@dataclass(frozen=True, eq=False)
class Structure:
    """M q'' + C q' + K q = f.

    Parameters
    ----------
    M, C, K : array, shape (n, n)
        Mass (kg), damping (N s/m) and stiffness (N/m) matrices.
    names : tuple of str, optional
        The coordinates' names (default ``q1 .. qn``).
    name : str
        A label for results (the model file, "1-DOF x", ...).
    """

    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    names: tuple[str, ...] = ()
    name: str = "structure"
    _cache: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self) -> None:
        M, C, K = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (self.M, self.C, self.K))
        n = M.shape[0]
        for nm, X in (("M", M), ("C", C), ("K", K)):
            if X.shape != (n, n) or not np.all(np.isfinite(X)):
                raise InputError(f"structure {nm} must be a finite {n} x {n} matrix (got shape {X.shape})")
        for nm, X in (("M", M), ("C", C), ("K", K)):
            object.__setattr__(self, nm, X)
        names = tuple(str(x) for x in self.names) or tuple(f"q{i + 1}" for i in range(n))
        if len(names) != n:
            raise InputError(f"structure names: {len(names)} names for {n} coordinates")
        object.__setattr__(self, "names", names)

    # ------------------------------------------------------------------ constructors
    @classmethod
    def single_dof(cls, mass: float, omega: float, zeta: float, name: str = "x") -> Structure:
        """One mode: m q'' + 2 zeta m omega q' + m omega^2 q = f, the
        coordinate called ``name`` (``"x"``: along the feed for milling)."""
        m = check_positive(mass, "mass", "kg")
        w = check_positive(omega, "natural frequency", "rad/s")
        z = check_nonneg(zeta, "damping ratio")
        return cls(
            np.array([[m]]),
            np.array([[2 * z * m * w]]),
            np.array([[m * w * w]]),
            (str(name),),
            f"1-DOF {name}",
        )

    @classmethod
    def modal(
        cls,
        omega: Any,
        zeta: Any,
        stiffness: Any,
        names: tuple[str, ...] = (),
        name: str = "modal",
    ) -> Structure:
        """Modes in modal coordinates: omega (rad/s), damping ratios and modal
        stiffness k_k (N/m), one value per mode; m_k = k_k / omega_k^2."""
        w = np.atleast_1d(np.asarray(omega, dtype=float))
        z = np.atleast_1d(np.asarray(zeta, dtype=float))
        k = np.atleast_1d(np.asarray(stiffness, dtype=float))
        if not w.shape == z.shape == k.shape:
            raise InputError("modal: omega, zeta and stiffness need one value per mode")
        for i in range(w.size):
            check_positive(w[i], f"mode {i + 1} natural frequency", "rad/s")
            check_positive(k[i], f"mode {i + 1} stiffness", "N/m")
            check_nonneg(z[i], f"mode {i + 1} damping ratio")
        m = k / w**2
        names = names or tuple(f"mode {i + 1}" for i in range(w.size))
        return cls(np.diag(m), np.diag(2 * z * m * w), np.diag(k), names, name)

    # ------------------------------------------------------------------ derived
    @property
    def n(self) -> int:
        """Number of coordinates."""
        return int(self.M.shape[0])

    @cached_property
    def state_matrix(self) -> np.ndarray:
        """First-order matrix of x = (q, q'), (2n, 2n)."""
        n = self.n
        Mi = np.linalg.inv(self.M)
        return np.block([[np.zeros((n, n)), np.eye(n)], [-Mi @ self.K, -Mi @ self.C]])

    @cached_property
    def complex_modes(self) -> ComplexModes:
        """Complex modes of s^2 M + s C + K (computed once)."""
        return complex_modes(self.M, self.C, self.K)

    @cached_property
    def omega_max(self) -> float:
        """Largest |Im| of the structure's poles, rad/s."""
        return float(np.max(np.abs(np.linalg.eigvals(self.state_matrix).imag), initial=0.0))

    def stable(self) -> bool:
        """Every pole of the free structure in the open left half plane."""
        return bool(np.all(np.linalg.eigvals(self.state_matrix).real < 0))

    def receptance(self, omega: Any, rows: np.ndarray, cols: np.ndarray | None = None) -> np.ndarray:
        """rows (K - w^2 M + j w C)^-1 cols, m/N, shape (len(w), n_rows, n_cols)."""
        w = np.atleast_1d(np.asarray(omega, dtype=float))
        return dynamic_receptance(self.M, self.C, self.K, w, rows, cols)

    def reduce(self, freq_max: float, loads: np.ndarray) -> tuple[Structure, np.ndarray]:
        """The structure on its undamped modes below ``freq_max`` (Hz) plus
        the static residual of the load directions ``loads`` (n, k) (the
        part of K^-1 loads those modes do not carry, residual flexibility),
        M-orthonormalised: a Ritz basis T (n, n_r), so that the reduced
        static compliance in the load directions is exact.  Returns the
        reduced structure (T^T M T, T^T C T, T^T K T) and T."""
        fmax = check_positive(freq_max, "freq_max", "Hz")
        w2, Phi = sla.eigh(self.K, self.M)
        keep = w2 < (2 * np.pi * fmax) ** 2
        P = Phi[:, keep]
        S = np.linalg.solve(self.K, loads)  # static deflections under the unit loads
        R = S - P @ (P.T @ (self.M @ S))  # what the kept modes do not carry
        rn = np.sqrt(np.maximum(np.einsum("ij,ik,kj->j", R, self.M, R), 0.0))
        R = R[:, rn > 1e-12 * np.sqrt(np.einsum("ij,ik,kj->j", S, self.M, S)).max()]
        R = R / np.sqrt(np.einsum("ij,ik,kj->j", R, self.M, R))  # unit M-norm, like the modes
        T = np.hstack([P, R])
        # M-orthonormal Ritz basis; drop directions the kept modes already span
        Mt = T.T @ self.M @ T
        lam, V = np.linalg.eigh(Mt)
        ok = lam > 1e-12 * lam.max()
        T = T @ (V[:, ok] / np.sqrt(lam[ok]))
        red = Structure(T.T @ self.M @ T, T.T @ self.C @ T, T.T @ self.K @ T, (), f"{self.name} (reduced)")
        return red, T
