"""The result of the modal fit: :class:`ModalFit` (modes, residues,
residual terms, synthesis, the real-mode model ``to_model``) and its
:class:`FitQuality` (the model and the method are in the docstring of
:mod:`chatterlab.structure._fit`)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import InputError
from ..io import Result
from ._frf import FRF
from ._lscf import Stabilisation

__all__ = ["ModalFit", "FitQuality", "point_tables"]


def point_tables(coords: list[str]) -> list[dict[str, Any]]:
    """The ``[[point]]`` tables that name a fitted model's coordinates as
    points: ``holder.x`` and ``holder.y`` are the x and y of point
    ``holder``; a name without a direction is a point's x."""
    points: dict[str, dict[str, str]] = {}
    for c in coords:
        pt, _, d = c.rpartition(".")
        if pt and d in ("x", "y", "rz"):
            points.setdefault(pt, {})[d] = c
        else:
            points.setdefault(c, {})["x"] = c
    return [{"id": p, "coords": cs} for p, cs in points.items()]


# ============================================================================ result


@dataclass(frozen=True, eq=False)
class FitQuality:
    """How well the fitted model reproduces the data.

    ``error``: the normalised error sqrt(sum|H - H_fit|^2 / sum|H|^2) over
    every entry and frequency of the band; ``weighted_error``: the rms of
    the weighted complex error (with the default 1/|H| weights: the rms
    relative error, to be compared with the noise level); ``frac``
    (n_out, n_in): the FRF assurance criterion |H^H H_fit|^2 /
    (|H|^2 |H_fit|^2) per entry; per mode, over the half-power band
    w_r (1 +- zeta_r): ``mode_error`` (normalised error) and ``mode_frac``,
    and ``complexity``: |Im A_r| / |A_r| of the driving-point or largest
    modal constant (0 for a real mode); ``significance``: each mode's
    weighted term over the noise where it acts (below 5 the automatic
    choice drops a pole).
    """

    error: float
    weighted_error: float
    frac: np.ndarray
    mode_error: np.ndarray
    mode_frac: np.ndarray
    complexity: np.ndarray
    significance: np.ndarray = field(default_factory=lambda: np.zeros(0))


@dataclass(frozen=True, eq=False)
class ModalFit(Result):
    """A fitted modal model of a measured receptance (see :mod:`chatterlab.structure._fit`).

    Attributes
    ----------
    omega_n : ndarray (m,)
        Natural frequencies |lam_r|, rad/s (``frequency_hz`` in Hz).
    damping : ndarray (m,)
        Viscous damping ratios zeta_r = -Re lam_r / |lam_r|.
    poles : ndarray (m,), complex
        lam_r (upper half plane).
    residues : ndarray (m, n_out, n_in), complex
        R_r, m/(N s).
    lower, upper : ndarray (n_out, n_in)
        Residual terms LR (of LR / s^2, N^-1 s^-2 m... i.e. 1/kg) and UR (m/N).
    std_omega, std_damping : ndarray (m,)
        Standard deviations of omega_n and damping from the refinement's
        Jacobian (NaN without refinement).
    measured : FRF
        The fitted data: the receptance over the fitted band.
    outputs, inputs : coordinate names.
    quality : FitQuality
    stabilisation : Stabilisation
    """

    omega_n: np.ndarray
    damping: np.ndarray
    poles: np.ndarray
    residues: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    std_omega: np.ndarray
    std_damping: np.ndarray
    measured: FRF
    outputs: tuple[str, ...]
    inputs: tuple[str, ...]
    quality: FitQuality
    stabilisation: Stabilisation
    source: str = "arrays"
    message: str = ""

    # ------------------------------------------------------------ modal data
    @property
    def frequency_hz(self) -> np.ndarray:
        return self.omega_n / (2 * np.pi)

    @property
    def n_modes(self) -> int:
        return int(self.poles.size)

    @property
    def omega(self) -> np.ndarray:
        """The fitted frequencies, rad/s."""
        return self.measured.omega

    @property
    def band(self) -> tuple[float, float]:
        """The fitted band (rad/s)."""
        return float(self.omega[0]), float(self.omega[-1])

    @property
    def modal_constants(self) -> np.ndarray:
        """A_r = 2 j Im(lam_r) R_r (m, n_out, n_in), 1/kg: real for a real mode."""
        return 2j * self.poles.imag[:, None, None] * self.residues

    def _driving(self) -> list[tuple[int, int, str]]:
        """(output index, input index, name) of every driving point."""
        return [(self.outputs.index(c), i, c) for i, c in enumerate(self.inputs) if c in self.outputs]

    @property
    def shapes(self) -> np.ndarray:
        """Mass-normalised real mode shapes at the output coordinates
        (m, n_out), from the real part of the modal constants scaled by the
        first driving point: phi_o = A_oi / sqrt(A_ii).  InputError when no
        input is also an output (the scale of a shape needs a driving point)."""
        drv = self._driving()
        if not drv:
            raise InputError(
                "ModalFit: no input coordinate is also an output, so the shapes have no scale: measure a"
                " driving point (an input named like one of the outputs)"
            )
        A = self.modal_constants.real
        out = np.zeros((self.n_modes, len(self.outputs)))
        for r in range(self.n_modes):
            # the driving point with the largest modal constant sets the scale and sign
            o, i, _ = max(drv, key=lambda t: abs(A[r, t[0], t[1]]))
            aii = A[r, o, i]
            if aii <= 0:
                continue  # a mode with a non-positive driving-point constant: not a physical real mode
            out[r] = A[r, :, i] / np.sqrt(aii)
        return out

    @property
    def modal_stiffness(self) -> np.ndarray:
        """k_r = omega_r^2 / A_r at each driving point (m, n_drive), N/m
        (inf where the constant is not positive); columns follow the inputs
        that are also outputs (:attr:`driving_points`)."""
        A = self.modal_constants.real
        drv = self._driving()
        k = np.full((self.n_modes, len(drv)), np.inf)
        for j, (o, i, _) in enumerate(drv):
            pos = A[:, o, i] > 0
            k[pos, j] = self.omega_n[pos] ** 2 / A[pos, o, i]
        return k

    @property
    def modal_mass(self) -> np.ndarray:
        """m_r = 1 / A_r at each driving point (m, n_drive), kg."""
        return self.modal_stiffness / self.omega_n[:, None] ** 2

    @property
    def driving_points(self) -> tuple[str, ...]:
        return tuple(c for _, _, c in self._driving())

    # ------------------------------------------------------------ synthesis
    def synthesis(self, omega: Any, *, real_modes: bool = False, residuals: bool = True) -> np.ndarray:
        """The fitted receptance at ``omega`` (rad/s) as one matrix per
        frequency, (n_freq, n_out, n_in) (the layout of the fit; :meth:`frf`
        gives the FRF)."""
        w = np.atleast_1d(np.asarray(omega, dtype=float))
        s = 1j * w
        if real_modes:
            A = self.modal_constants.real
            den = self.omega_n[None, :] ** 2 + s[:, None] ** 2 + 2 * self.damping * self.omega_n * s[:, None]
            out = np.einsum("rab,kr->kab", A, 1.0 / den)
        else:
            a = 1.0 / (s[:, None] - self.poles[None, :])
            b = 1.0 / (s[:, None] - self.poles.conj()[None, :])
            out = np.einsum("rab,kr->kab", self.residues, a) + np.einsum(
                "rab,kr->kab", self.residues.conj(), b
            )
        if residuals:
            with np.errstate(divide="ignore", invalid="ignore"):
                out = out + self.lower[None] / s[:, None, None] ** 2 + self.upper[None]
        return out

    def frf(self, omega: Any = None, *, real_modes: bool = False, residuals: bool = True) -> FRF:
        """The fitted receptance at ``omega`` (rad/s; default the fitted
        frequencies) as an :class:`~chatterlab.structure.FRF`.

        ``real_modes``: the real-mode sum sum Re(A_r) / (w_r^2 - w^2 + 2 j
        zeta_r w_r w) (what :meth:`to_model` reproduces) instead of the
        complex-residue sum; ``residuals``: add LR / s^2 + UR."""
        w = np.atleast_1d(np.asarray(self.omega if omega is None else omega, dtype=float))
        H = self.synthesis(w, real_modes=real_modes, residuals=residuals)
        return FRF(
            omega=w,
            data=np.ascontiguousarray(np.moveaxis(H, 0, -1)),
            outputs=self.outputs,
            inputs=self.inputs,
            method="modal fit",
            source=f"modal fit of {self.source}",
        )

    # ------------------------------------------------------------ model
    def real_modes(
        self,
        *,
        residuals: str = "upper",
        factor: float = 10.0,
        residual_damping: float = 0.05,
        rank_tol: float = 1e-3,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(omega (n,), zeta (n,), Phi (n_c, n)) of the real-mode model on the
        n_c driving-point coordinates.

        Each fitted mode's real modal-constant matrix on those coordinates,
        symmetrised, S_r = sym Re A_r = sum_j e_j v_j v_j^T, gives one real
        mode (w_r, zeta_r, sqrt(e_j) v_j) per eigenpart with e_j > rank_tol
        max |e|: one for a mode seen at several coordinates (rank one), two
        for a pole that stands for two modes too close to separate (a tool's
        x and y modes), none for a negative part (not realisable with a
        positive mass; dropped).  A residual's part is kept when its
        receptance in the band (UR, LR / w_lo^2) exceeds rank_tol of the
        measured peak.

        ``residuals`` (``"upper"``, ``"both"`` or ``"none"``): pseudo-modes
        for the residual terms.  The upper residual UR = sum_j u_j u_j^T
        (positive eigenparts) becomes modes at w_hi = ``factor`` x the top
        of the band with shapes u_j w_hi and damping ``residual_damping``:
        exact as w -> 0, inside the band UR / (1 - x^2 + 2 j zeta x) with
        x = w / w_hi, i.e. errors ~ x^2 and 2 zeta x (1 % each at the band's
        top for the defaults).  The lower residual LR likewise at w_lo = the
        bottom of the band / ``factor`` with shapes sqrt(LR's parts) -- off
        by default: a lightly damped mode below the band adds a chatter
        frequency the measurement never saw (a spurious low lobe), and an
        undamped one a pole on the imaginary axis.  Undamped pseudo-modes
        (``residual_damping=0``) reproduce the residual terms exactly as
        w -> inf / 0 with relative errors x^2 and (w_lo / w)^2."""
        if residuals not in ("upper", "both", "none"):
            raise InputError(f"ModalFit: residuals must be 'upper', 'both' or 'none' (got {residuals!r})")
        if not (0 <= residual_damping < 1) or not (factor > 1):
            raise InputError("ModalFit: residual_damping must be in [0, 1) and factor > 1")
        drv = self._driving()
        if not drv:
            self.shapes  # noqa: B018 -- raises the InputError naming the fix
        rows = [o for o, _, _ in drv]
        cols = [i for _, i, _ in drv]
        A = self.modal_constants.real
        om: list[float] = []
        ze: list[float] = []
        shp: list[np.ndarray] = []

        def parts(S: np.ndarray, floor: float = 0.0) -> list[tuple[float, np.ndarray]]:
            ev, V = np.linalg.eigh(0.5 * (S + S.T))
            top = max(float(np.abs(ev).max()) if ev.size else 0.0, floor)
            return [(float(e), v) for e, v in zip(ev, V.T, strict=True) if top > 0 and e > rank_tol * top]

        for r in range(self.n_modes):
            for e, v in parts(A[r][np.ix_(rows, cols)]):
                om.append(float(self.omega_n[r]))
                ze.append(float(self.damping[r]))
                shp.append(np.sqrt(e) * v * (1.0 if v[np.argmax(np.abs(v))] > 0 else -1.0))
        lo, hi = self.band
        # a residual part counts when its receptance in the band (UR, LR / lo^2)
        # exceeds rank_tol of the measured peak; below, it is round-off or noise
        # and would only make Psi ill-conditioned
        peak = float(np.abs(self.measured.data).max())
        pseudo = []
        if residuals in ("upper", "both"):
            pseudo.append((self.upper, hi * factor, hi * factor, peak))
        if residuals == "both":
            pseudo.append((self.lower, lo / factor, 1.0, peak * lo**2))
        for Rm, w_p, gain, floor in pseudo:
            for e, v in parts(Rm[np.ix_(rows, cols)], floor):
                om.append(w_p)
                ze.append(float(residual_damping))
                shp.append(np.sqrt(e) * gain * v)
        Phi = np.array(shp).T.reshape(len(rows), len(om))
        return np.array(om), np.array(ze), Phi

    def to_model(
        self,
        *,
        name: str = "modal fit",
        residuals: str = "upper",
        factor: float = 10.0,
        residual_damping: float = 0.05,
        rank_tol: float = 1e-3,
        tables: dict[str, Any] | None = None,
    ) -> Any:
        """A matrix-level chatterlab :class:`~chatterlab.model.Model` whose
        receptance at the driving-point coordinates is the real-mode sum.

        With n_c driving-point coordinates and n real modes (fitted +
        residual pseudo-modes, :meth:`real_modes`), Phi (n_c, n) is extended
        to a square, invertible Psi = [Phi; N] by rows N spanning the
        complement of Phi's row space (n - n_c internal coordinates
        ``fit.q1`` ...) and

            M = Psi^-T Psi^-1,  K = Psi^-T diag(w_r^2) Psi^-1,
            L = Psi^-T diag(2 zeta_r w_r) Psi^-1,

        so Psi^T M Psi = I etc.: the receptance of (M, L, K) is Psi diag(1 /
        (w_r^2 - w^2 + 2 j zeta_r w_r w)) Psi^T, whose top-left n_c block is
        exactly sum_r phi_r phi_r^T / (...) (proportional damping, real
        modes).  What is approximate: the complex residues are projected to
        real modal constants (their complexity is in
        ``quality.complexity``), each constant matrix keeps its positive
        eigenparts only (above ``rank_tol``; a negative part cannot be
        realised with a positive mass), and the residual terms are
        pseudo-modes (see :meth:`real_modes`).  So the model equals
        :meth:`frf` ``(real_modes=True)`` on the driving-point coordinates
        exactly when every sym Re A_r there is positive semi-definite of the
        rank kept (true for real modes).  Needs n >= n_c (else there is too
        little modal information for a positive-definite M: ask for
        residuals).

        Coordinates named ``POINT.DIR`` (DIR in x, y, rz) become points with
        ``coords``; any other name a point of that name moving in x.
        ``tables`` adds model-file tables (e.g. ``{"coupling": [...],
        "process": {...}}``) to the built model.
        """
        from ..model._reader import build_model

        om, ze, Phi = self.real_modes(
            residuals=residuals, factor=factor, residual_damping=residual_damping, rank_tol=rank_tol
        )
        n_c, n = Phi.shape
        if n < n_c:
            raise InputError(
                f"ModalFit.to_model: {n} modes for {n_c} coordinates cannot give a positive-definite mass matrix;"
                " fit more modes or keep residuals='upper'"
            )
        if n > n_c:
            # complement of the row space of Phi: the last right singular vectors
            _, _, Vt = np.linalg.svd(Phi)
            Psi = np.vstack([Phi, Vt[n_c:]])
        else:
            Psi = Phi
        if np.linalg.cond(Psi) > 1e12:
            raise InputError(
                "ModalFit.to_model: the mode shapes at the measured coordinates are (nearly) dependent; drop a"
                " mode or measure more coordinates"
            )
        Pinv = np.linalg.inv(Psi)
        M = Pinv.T @ Pinv
        K = Pinv.T @ np.diag(om**2) @ Pinv
        L = Pinv.T @ np.diag(2 * ze * om) @ Pinv
        sym = [0.5 * (X + X.T) for X in (M, L, K)]
        coords = [c for _, _, c in self._driving()] + [f"fit.q{k + 1}" for k in range(n - n_c)]
        raw: dict[str, Any] = {
            "model": {"name": name, "description": f"real-mode model of the modal fit of {self.source}"},
            "matrices": {
                "coordinates": coords,
                "M": sym[0].tolist(),
                "L": sym[1].tolist(),
                "K": sym[2].tolist(),
            },
            "point": point_tables(coords[:n_c]),
        }
        for key, val in (tables or {}).items():
            if key in ("matrices",):
                raise InputError("ModalFit.to_model: tables may not replace [matrices]")
            if key == "point":
                raw["point"] = raw["point"] + list(val)
            else:
                raw[key] = val
        return build_model(raw, source=f"modal fit of {self.source}")

    # ------------------------------------------------------------ files
    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """The fitted modes (``mode`` 1..m) with their natural frequency,
        damping ratio and standard deviations, the residues per (output,
        input) entry (real and imaginary parts), the residual terms; the fit's
        quality and the coordinate names as attributes."""
        m = self.n_modes
        R = np.asarray(self.residues, dtype=complex)
        entry = ("mode", "output", "input")
        q = self.quality
        return (
            {
                "mode": (np.arange(1, m + 1), "1", "mode number"),
                "output": (np.arange(len(self.outputs)), "1", "output (index into the attribute outputs)"),
                "input": (np.arange(len(self.inputs)), "1", "input (index into the attribute inputs)"),
            },
            {
                "frequency": (self.frequency_hz, "Hz", "natural frequency |lambda| / 2 pi", ("mode",)),
                "damping_ratio": (self.damping, "1", "viscous damping ratio", ("mode",)),
                "std_frequency": (self.std_omega / (2 * np.pi), "Hz", "standard deviation of the frequency",
                                  ("mode",)),
                "std_damping_ratio": (self.std_damping, "1", "standard deviation of the damping ratio", ("mode",)),
                "residue_real": (R.real, "m/(N s)", "Re of the residue R_r", entry),
                "residue_imag": (R.imag, "m/(N s)", "Im of the residue R_r", entry),
                "lower_residual": (np.asarray(self.lower, float), "1/kg", "lower residual LR (of LR / s^2)",
                                   ("output", "input")),
                "upper_residual": (np.asarray(self.upper, float), "m/N", "upper residual UR", ("output", "input")),
            },
            {
                "title": "chatterlab modal fit",
                "source": self.source,
                "outputs": json.dumps(list(self.outputs)),
                "inputs": json.dumps(list(self.inputs)),
                "error": float(q.error),
                "weighted_error": float(q.weighted_error),
                "band_hz": [self.band[0] / (2 * np.pi), self.band[1] / (2 * np.pi)],
                "message": self.message,
            },
        )  # fmt: skip

    def to_csv(self, path: Any) -> Any:
        """The modes as CSV (``mode [1]``, ``frequency [Hz]``,
        ``damping_ratio [1]`` and their standard deviations), exact floats;
        returns the path (the residues are in :meth:`to_netcdf`)."""
        from ..io import write_csv

        coords, data, _ = self.dataset_parts()
        cols = {k: v[:3] for k, v in data.items() if v[3] == ("mode",)}
        return write_csv(path, {"mode": coords["mode"]}, cols)

    # ------------------------------------------------------------ plots
    def plot(self, output: int | str = 0, input: int | str = 0, ax: Any = None, **style: Any) -> Any:
        """Measured and fitted magnitude and phase of one entry against
        frequency (Hz), with the fitted natural frequencies marked
        (:func:`chatterlab.plot.plot_modal_fit`), on ``ax`` (a pair of Axes:
        magnitude, phase; default new); returns the pair.  Imports
        matplotlib."""
        from ..plot import plot_modal_fit

        return plot_modal_fit(self, output=output, input=input, ax=ax)

    def plot_stabilisation(self, ax: Any = None) -> Any:
        """The stabilisation diagram with the chosen poles marked."""
        return self.stabilisation.plot(ax)

    def table(self) -> str:
        """The modes as a text table (Hz, %, N/m)."""
        lines = [
            "mode  f [Hz]     +-        zeta [%]  +-      "
            + "  ".join(f"k {c} [N/m]" for c in self.driving_points)
        ]
        k = self.modal_stiffness if self.driving_points else np.zeros((self.n_modes, 0))
        for r in range(self.n_modes):
            lines.append(
                f"{r + 1:4d}  {self.frequency_hz[r]:9.3f}  {self.std_omega[r] / (2 * np.pi):8.3g}  "
                f"{100 * self.damping[r]:8.4f}  {100 * self.std_damping[r]:7.2g}  "
                + "  ".join(f"{x:12.5g}" for x in k[r])
            )
        return "\n".join(lines)
