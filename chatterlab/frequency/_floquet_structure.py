"""The structure seen by the cutter of a milling model (:class:`ToolStructure`):
M q'' + C q' + K q = J^T F with r = J q the tool point, its first-order form,
the basis of the cut's coordinates, its FRF and its modal reduction.  Used by
the Floquet methods (:mod:`chatterlab.frequency._floquet`)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Literal

import numpy as np
import scipy.linalg as sla

from ..errors import InputError, check_nonneg, check_positive

__all__ = ["ToolStructure"]


@dataclass(frozen=True, eq=False)
class ToolStructure:
    """The structure seen by the cutter: M q'' + C q' + K q = J^T F, r = J q.

    Parameters
    ----------
    M, C, K : array, shape (n, n)
        Mass (kg), damping (N s/m) and stiffness (N/m) matrices.
    J : array, shape (2, n)
        Maps q to the tool's displacement r = (x, y) relative to the
        workpiece (feed along +x, see :mod:`chatterlab.process._milling`).
    name : str
        A label for results.
    """

    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    J: np.ndarray
    name: str = "structure"

    def __post_init__(self) -> None:
        M, C, K, J = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (self.M, self.C, self.K, self.J))
        n = M.shape[0]
        for nm, X in (("M", M), ("C", C), ("K", K)):
            if X.shape != (n, n) or not np.all(np.isfinite(X)):
                raise InputError(f"structure {nm} must be a finite {n} x {n} matrix (got shape {X.shape})")
        if J.shape != (2, n) or not np.all(np.isfinite(J)):
            raise InputError(
                f"structure J must be a finite 2 x {n} matrix mapping q to (x, y) (got {J.shape})"
            )
        for nm, X in (("M", M), ("C", C), ("K", K), ("J", J)):
            object.__setattr__(self, nm, X)

    @classmethod
    def single_dof(
        cls, mass: float, omega: float, zeta: float, direction: Literal["x", "y"] = "x"
    ) -> ToolStructure:
        """One mode along x (feed) or y: m x'' + 2 zeta m omega x' + m omega^2 x = F_x."""
        m = check_positive(mass, "mass", "kg")
        w = check_positive(omega, "natural frequency", "rad/s")
        z = check_nonneg(zeta, "damping ratio")
        if direction not in ("x", "y"):
            raise InputError(f"direction must be 'x' or 'y' (got {direction!r})")
        J = np.array([[1.0], [0.0]]) if direction == "x" else np.array([[0.0], [1.0]])
        return cls(
            np.array([[m]]), np.array([[2 * z * m * w]]), np.array([[m * w * w]]), J, f"1-DOF {direction}"
        )

    @classmethod
    def modal(
        cls,
        omega: np.ndarray,
        zeta: np.ndarray,
        stiffness: np.ndarray,
        shapes: np.ndarray,
        name: str = "modal",
    ) -> ToolStructure:
        """Modes in modal coordinates: omega (rad/s), damping ratios, modal
        stiffness k_k (N/m) and shapes (n_modes, 2), the (x, y) entries of
        each mode at the tool, so that r = shapes^T eta."""
        w = np.atleast_1d(np.asarray(omega, dtype=float))
        z = np.atleast_1d(np.asarray(zeta, dtype=float))
        k = np.atleast_1d(np.asarray(stiffness, dtype=float))
        S = np.atleast_2d(np.asarray(shapes, dtype=float))
        if not (w.shape == z.shape == k.shape and S.shape == (w.size, 2)):
            raise InputError(
                "modal: omega, zeta and stiffness need one value per mode and shapes (n_modes, 2)"
            )
        for i in range(w.size):
            check_positive(w[i], f"mode {i + 1} natural frequency", "rad/s")
            check_positive(k[i], f"mode {i + 1} stiffness", "N/m")
            check_nonneg(z[i], f"mode {i + 1} damping ratio")
        m = k / w**2
        return cls(np.diag(m), np.diag(2 * z * m * w), np.diag(k), S.T, name)

    @property
    def n(self) -> int:
        return self.M.shape[0]

    @cached_property
    def A(self) -> np.ndarray:
        """First-order matrix of x = (q, q'), (2n, 2n)."""
        n = self.n
        Mi = np.linalg.inv(self.M)
        return np.block([[np.zeros((n, n)), np.eye(n)], [-Mi @ self.K, -Mi @ self.C]])

    @cached_property
    def cut_basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Ub, Jr, W): r = Ub (Jr q) with Jr (rho, n) of full row rank, and
        W = M^-1 Jr^T (n, rho); the cutting term of (1) is W (Ub^T H Ub) Jr."""
        U, s, Vt = np.linalg.svd(self.J, full_matrices=False)
        rho = int(np.sum(s > 1e-12 * max(s[0], 1e-300)))
        Ub = U[:, :rho]
        Jr = s[:rho, None] * Vt[:rho]
        W = np.linalg.solve(self.M, Jr.T)
        return Ub, Jr, W

    @cached_property
    def omega_max(self) -> float:
        """Largest |Im| of the structure's poles, rad/s."""
        return float(np.max(np.abs(np.linalg.eigvals(self.A).imag), initial=0.0))

    def frf(self, omega: np.ndarray) -> np.ndarray:
        """H(j w) = J (K - w^2 M + j w C)^-1 J^T, m/N, shape (len(w), 2, 2)."""
        from ..structure import dynamic_receptance

        w = np.atleast_1d(np.asarray(omega, dtype=float))
        return dynamic_receptance(self.M, self.C, self.K, w, self.J)

    def stable(self) -> bool:
        return bool(np.all(np.linalg.eigvals(self.A).real < 0))

    def reduce(self, freq_max: float, check_hz: float | None = None) -> tuple[ToolStructure, float]:
        """The structure on its undamped modes below ``freq_max`` (Hz) plus the
        static residual at the tool, and the truncation error at the tool.

        The basis is the modes below ``freq_max`` and the part of the static
        deflections K^-1 J^T that those modes do not carry (residual
        flexibility), M-orthonormalised (a Ritz basis, so the reduced
        static compliance at the tool is exact).  The error returned is
        max |H(jw) - H_r(jw)| / max |H(jw)| over 400 frequencies up to
        ``check_hz`` (default freq_max / 2), H the FRF at the tool: all the
        Floquet problem sees of the structure is this response.
        """
        fmax = check_positive(freq_max, "freq_max", "Hz")
        fchk = check_positive(check_hz, "check_hz", "Hz") if check_hz is not None else fmax / 2
        w2, Phi = sla.eigh(self.K, self.M)
        keep = w2 < (2 * np.pi * fmax) ** 2
        P = Phi[:, keep]
        S = np.linalg.solve(self.K, self.J.T)  # static deflections under unit tool forces
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
        red = ToolStructure(
            T.T @ self.M @ T, T.T @ self.C @ T, T.T @ self.K @ T, self.J @ T, f"{self.name} (reduced)"
        )
        w = 2 * np.pi * np.linspace(0.0, fchk, 400)
        H, Hr = self.frf(w), red.frf(w)
        err = float(np.max(np.abs(H - Hr)) / np.max(np.abs(H)))
        return red, err
