"""Modal fit of a measured receptance: poles by the (poly-reference)
least-squares complex frequency-domain estimator with a stabilisation
diagram, residues by least squares in the frequency domain with lower and
upper residual terms, and a maximum-likelihood refinement of the poles.

The model fitted to the receptance ``H[k, o, i]`` (m/N; ``FRF.matrices``,
one matrix per frequency: the layout of the fit's batched least squares)
at ``s = j w_k``::

    H(s) = sum_r [ R_r / (s - lam_r) + conj(R_r) / (s - conj(lam_r)) ] + LR / s^2 + UR

with lam_r = -zeta_r w_r + j w_r sqrt(1 - zeta_r^2), complex residue
matrices R_r (n_out, n_in) and real residual matrices LR (the modes below
the band, mass-like) and UR (the modes above, stiffness-like).

Three steps:

1. **Poles, stabilisation** (pLSCF, Guillaume et al. [1], Peeters et al. [2]):
   the right matrix-fraction model H_o(w) = B_o(W) A(W)^-1 in the z-domain
   basis W = exp(j w dt), dt = pi / w_max, with real matrix coefficients.
   Linearised, every output row o gives J_o = [X_o, Y_o] with
   X_o = w_o [W^0 .. W^p] and Y_o = -w_o [W^0 .. W^p] (x) H_o; the numerator
   is eliminated (reduced normal equations)::

       M = 2 sum_o (T_o - S_o^T R_o^-1 S_o),  R_o = Re X_o^H X_o,
       S_o = Re X_o^H Y_o,  T_o = Re Y_o^H Y_o,

   and with the highest coefficient A_p = I the others solve
   M[:pn, :pn] a = -M[:pn, pn:].  The poles are the eigenvalues z of the
   block companion matrix of A(z), lam = ln(z) / dt.  This is done for every
   order p = 1 .. max_order (the matrices of an order are the leading blocks
   of the largest), and a pole is *stable* when a pole of the previous order
   lies within ``tol_frequency`` (1 %) in natural frequency and
   ``tol_damping`` (5 %) in damping ratio.  The poles kept by the automatic
   choice are those of the highest order whose track stays stable down
   through at least ``min_stable`` consecutive lower orders in frequency
   (or the stable poles closest to frequencies the user names); two poles
   closer than their half-power half-width count as one, and after the
   refinement a pole whose term is not at least ``SIGNIFICANCE`` (5) times
   the noise where it acts is dropped (a noise pole that was stable by
   chance) and the rest refined again.
2. **Residues** (LSFD, [3] Ch. 4): for fixed poles the model is linear in
   Re R_r, Im R_r, LR, UR: one real weighted least-squares problem per
   entry (o, i).
3. **Refinement**: the poles are the only nonlinear parameters, so the
   weighted complex error with the residues eliminated (variable projection,
   Golub & Pereyra [4]) is minimised over (w_r, zeta_r) by
   ``scipy.optimize.least_squares``.  With the default weights 1/|H| the
   estimator is the maximum-likelihood one for relative complex noise
   (the usual model of a tap test's error, 1-3 % of |H|); the covariance of
   (w_r, zeta_r) follows from the projected Jacobian, s^2 (J^T J)^-1, and is
   reported as ``std_omega`` / ``std_damping``.  On noise-free data of a
   modal sum the refinement recovers the modes to round-off (the z-domain
   LSCF alone does not: a continuous-time mode is not a rational function
   of exp(j w dt), so its poles carry a small model bias that step 3
   removes).

Real modes.  For viscous proportional damping the modal constant
A_r = 2 j w_dr R_r (w_dr = Im lam_r) is real, H = sum A_r / (w_r^2 - w^2 +
2 j zeta_r w_r w); ``modal_constants`` holds A_r as fitted (complex), its
phase away from real is the mode complexity.  :meth:`ModalFit.to_model`
projects A_r on the real axis, takes mass-normalised shapes phi_r at the
measured coordinates (A_r = phi_r phi_r^T restricted to the driving points)
and builds M, K, C whose FRF at the measured coordinates is exactly the
real-mode sum (see there).

References
----------
.. [1] P. Guillaume, P. Verboven, S. Vanlanduit, H. Van der Auweraer,
   B. Peeters, "A poly-reference implementation of the least-squares complex
   frequency-domain estimator", Proc. IMAC XXI, 2003.
.. [2] B. Peeters, H. Van der Auweraer, P. Guillaume, J. Leuridan, "The
   PolyMAX frequency-domain method: a new standard for modal parameter
   estimation?", Shock and Vibration 11, 395-409, 2004.
.. [3] D. J. Ewins, *Modal Testing: Theory, Practice and Application*, 2nd
   ed., Research Studies Press, 2000 (modal constants, residual terms).
.. [4] G. H. Golub, V. Pereyra, "Separable nonlinear least squares: the
   variable projection method and its applications", Inverse Problems 19,
   R1-R26, 2003.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from ..errors import InputError
from ._fit_result import FitQuality, ModalFit
from ._frf import FRF
from ._lscf import NEW as NEW
from ._lscf import STABLE as STABLE
from ._lscf import STABLE_FREQUENCY as STABLE_FREQUENCY
from ._lscf import Stabilisation, _select, _stability, lscf_poles
from ._lsfd import _lsfd, _pole, lsfd

__all__ = ["ModalFit", "Stabilisation", "FitQuality", "fit_modes", "lscf_poles", "lsfd"]


# ============================================================================ input


def one_blas_thread() -> Any:
    """Single-threaded BLAS while the fit's many small dense solves run
    (:func:`chatterlab._threads.one_blas_thread`)."""
    from .._threads import one_blas_thread as limit

    return limit()


def _as_frf(frf: Any, band: tuple[float, float] | None) -> tuple[FRF, np.ndarray, np.ndarray]:
    """(the receptance restricted to ``band`` (rad/s), its omega, its
    matrices (n_freq, n_out, n_in)) from an FRF or a tuple (omega rad/s,
    data (n_out, n_in, n_freq) or (n_freq,))."""
    if isinstance(frf, tuple) and len(frf) == 2:
        shape = np.shape(frf[1])
        # coordinate k is output k and input k (a driving-point matrix)
        n_o, n_i = shape[:2] if len(shape) == 3 else (1, 1)
        frf = FRF.from_arrays(
            frf[0],
            frf[1],
            tuple(f"{k + 1}" for k in range(n_o)),
            tuple(f"{k + 1}" for k in range(n_i)),
            source="arrays",
        )
    elif not isinstance(frf, FRF):
        raise InputError(
            f"fit_modes: frf must be an FRF or a tuple (omega [rad/s], data), got {type(frf).__name__}"
        )
    frf = frf.as_kind("receptance")
    w = np.asarray(frf.omega, dtype=float)
    H = frf.matrices
    if not (np.all(np.isfinite(w)) and np.all(np.isfinite(H))):
        raise InputError("fit_modes: omega and the data must be finite; drop the bad points")
    if w.size > 1 and not np.all(np.diff(w) > 0):
        raise InputError("fit_modes: omega must increase strictly; sort the points and drop duplicates")
    if band is not None:
        lo, hi = (float(b) for b in band)
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 <= lo < hi):
            raise InputError(f"fit_modes: band must be (lo, hi) in rad/s with 0 <= lo < hi (got {band!r})")
        keep = (w >= lo) & (w <= hi)
        w, H = w[keep], H[keep]
        coh = None if frf.coherence is None else frf.coherence[..., keep]
        frf = replace(frf, omega=w, data=frf.data[..., keep], coherence=coh)
    if w.size < 8:
        raise InputError(f"fit_modes: {w.size} frequencies in the band; a fit needs at least 8")
    if np.any(w <= 0):
        raise InputError("fit_modes: the band must exclude 0 Hz (the lower residual is 1/s^2); raise band[0]")
    return frf, w, H


def _weights(H: np.ndarray, weighting: Any) -> np.ndarray:
    """Weights (n_freq, n_out, n_in) of the complex errors.  An entry that
    is zero at every frequency is taken as not measured (a file that writes
    0 for the cross FRFs it did not measure): weight 0, residue 0."""
    measured = np.any(H != 0, axis=0)[None, :, :]
    if isinstance(weighting, str):
        if weighting == "inverse":
            mag = np.abs(H)
            floor = 1e-12 * float(mag.max()) if mag.size else 0.0
            return measured / np.maximum(mag, max(floor, np.finfo(float).tiny))
        if weighting == "uniform":
            rms = max(float(np.sqrt(np.mean(np.abs(H[:, measured[0]]) ** 2))), np.finfo(float).tiny)
            return np.broadcast_to(measured / rms, H.shape).copy()
        raise InputError(
            f"fit_modes: weighting must be 'inverse' (relative noise), 'uniform' or an array (got {weighting!r})"
        )
    W = np.asarray(weighting, dtype=float)
    if W.shape != H.shape or not np.all(np.isfinite(W) & (W >= 0)):
        raise InputError(f"fit_modes: a weighting array must have the shape of H {H.shape}, finite and >= 0")
    return W


# ============================================================================ the fit


def _refine(
    w: np.ndarray,
    H: np.ndarray,
    Wt: np.ndarray,
    lam0: np.ndarray,
    lower: bool,
    upper: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """Variable-projection refinement of (w_r, zeta_r); returns (poles,
    std_omega, std_damping, message)."""
    from scipy.optimize import least_squares

    wn0 = np.abs(lam0)
    z0 = -lam0.real / wn0
    m = lam0.size

    def resid(x: np.ndarray) -> np.ndarray:
        lam = _pole(wn0 * (1 + x[:m]), z0 * np.exp(x[m:]))
        r = _lsfd(w, H, lam, Wt, lower, upper)[3]
        return np.concatenate([r.real.ravel(), r.imag.ravel()])

    sol = least_squares(resid, np.zeros(2 * m), method="lm", xtol=1e-13, ftol=1e-13, gtol=1e-13, x_scale=1.0)
    x = sol.x
    wn, ze = wn0 * (1 + x[:m]), z0 * np.exp(x[m:])
    used = np.any(Wt > 0, axis=0)  # the measured entries
    n_res = 2 * int(np.sum(Wt > 0))
    n_lin = int(used.sum()) * (2 * m + int(lower) + int(upper))
    dof = max(n_res - n_lin - 2 * m, 1)
    s2 = float(sol.fun @ sol.fun) / dof
    J = sol.jac
    try:
        cov = s2 * np.linalg.inv(J.T @ J)
        sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
        std_w, std_z = wn0 * sd[:m], ze * sd[m:]
    except np.linalg.LinAlgError:
        std_w = std_z = np.full(m, np.nan)
    return _pole(wn, ze), std_w, std_z, sol.message


#: a mode kept by the automatic choice stands this many noise levels above the noise
SIGNIFICANCE = 5.0


def _significance(
    w: np.ndarray, H: np.ndarray, Wt: np.ndarray, lam: np.ndarray, lower: bool, upper: bool
) -> np.ndarray:
    """Per pole, the weighted norm of its term over the weighted norm the
    noise has in the same place: ||W t_r|| / (s sqrt(n_r)), with s the rms
    weighted residual of the fit and n_r the number of measured samples in
    the pole's half-power band (at least 1) times the measured entries.  A
    mode that the data show stands far above 1 (hundreds for a tap-test
    mode); a pole fitted to the noise is about 1."""
    R, _, _, res, _ = _lsfd(w, H, lam, Wt, lower, upper)
    meas = Wt > 0
    s_hat = float(np.sqrt(np.mean(np.abs(res[meas]) ** 2))) if meas.any() else 0.0
    s = 1j * w
    n_entries = int(np.any(meas, axis=0).sum())
    out = np.zeros(lam.size)
    for r, l_ in enumerate(lam):
        term = R[r][None] / (s[:, None, None] - l_) + R[r].conj()[None] / (s[:, None, None] - np.conj(l_))
        norm = float(np.sqrt(np.sum(np.abs(Wt * term) ** 2)))
        n_r = max(int(np.sum(np.abs(w - abs(l_)) <= abs(l_.real))), 1) * max(n_entries, 1)
        out[r] = norm / (s_hat * np.sqrt(n_r)) if s_hat > 0 else np.inf
    return out


def _quality(
    fit_H: np.ndarray, H: np.ndarray, Wt: np.ndarray, w: np.ndarray, lam: np.ndarray, A: np.ndarray
) -> FitQuality:
    err = float(np.sqrt(np.sum(np.abs(H - fit_H) ** 2) / np.sum(np.abs(H) ** 2)))
    werr = float(np.sqrt(np.mean(np.abs(Wt * (H - fit_H))[Wt > 0] ** 2)))
    num = np.abs(np.sum(H.conj() * fit_H, axis=0)) ** 2
    den = np.sum(np.abs(H) ** 2, axis=0) * np.sum(np.abs(fit_H) ** 2, axis=0)
    frac = np.where(den > 0, num / np.where(den > 0, den, 1.0), np.nan)  # NaN: an entry not measured
    me, mf, cx = [], [], []
    for r, l_ in enumerate(lam):
        wn, z = abs(l_), -l_.real / abs(l_)
        sel = np.abs(w - wn) <= max(z, 2e-3) * wn
        if sel.sum() < 2:
            sel = np.argsort(np.abs(w - wn))[:3]
        Hs, Fs = H[sel], fit_H[sel]
        me.append(float(np.sqrt(np.sum(np.abs(Hs - Fs) ** 2) / np.sum(np.abs(Hs) ** 2))))
        mf.append(
            float(np.abs(np.sum(Hs.conj() * Fs)) ** 2 / (np.sum(np.abs(Hs) ** 2) * np.sum(np.abs(Fs) ** 2)))
        )
        a = A[r].ravel()
        k = int(np.argmax(np.abs(a)))
        cx.append(float(abs(a[k].imag) / abs(a[k])) if abs(a[k]) > 0 else np.nan)
    return FitQuality(err, werr, frac, np.array(me), np.array(mf), np.array(cx))


def fit_modes(
    frf: Any,
    *,
    modes: Any = "auto",
    max_order: int = 24,
    band: tuple[float, float] | None = None,
    weighting: Any = "inverse",
    lower: bool = True,
    upper: bool = True,
    refine: bool = True,
    tol_frequency: float = 0.01,
    tol_damping: float = 0.05,
    min_stable: int | None = None,
) -> ModalFit:
    """Fit a modal model to a measured receptance (single or matrix).

    Parameters
    ----------
    frf : FRF or tuple (omega, data)
        Receptance, m/N (an FRF of another kind is converted); omega in
        rad/s; data shaped (n_freq,) or (n_out, n_in, n_freq).
    modes : "auto", int or sequence of float
        Which poles: ``"auto"`` (stable tracks, see the module docstring),
        the n longest-stable poles, or the stable poles nearest the given
        frequencies (Hz) -- what one picks by hand in the diagram.
    max_order : int
        Highest pLSCF order (p n_in poles).
    band : (lo, hi), optional
        Fitted band, rad/s (default: all the data).
    weighting : "inverse", "uniform" or array like H
        Weights of the complex error: 1/|H| (relative noise: maximum
        likelihood for it), constant, or given (1/standard deviation).
    lower, upper : bool
        Fit the residual terms LR / s^2 and UR.
    refine : bool
        Refine the poles by variable projection (the maximum-likelihood step).
    tol_frequency, tol_damping : float
        Stability tolerances (relative) of the diagram.
    min_stable : int, optional
        Consecutive stable orders a pole needs to be kept by ``"auto"``
        (default max(4, max_order // 4)).

    Returns
    -------
    ModalFit
    """
    data, w, H = _as_frf(frf, band)
    if (
        isinstance(max_order, bool)
        or not isinstance(max_order, int | np.integer)
        or not 1 <= max_order <= 200
    ):
        raise InputError(f"fit_modes: max_order must be an integer in 1..200 (got {max_order!r})")
    for nm, v in (("tol_frequency", tol_frequency), ("tol_damping", tol_damping)):
        if not (isinstance(v, int | float) and 0 < v < 1):
            raise InputError(f"fit_modes: {nm} must be a fraction in (0, 1) (got {v!r})")
    with one_blas_thread():
        return _fit(
            data,
            w,
            H,
            modes,
            max_order,
            weighting,
            lower,
            upper,
            refine,
            tol_frequency,
            tol_damping,
            min_stable,
        )


def _fit(
    data: FRF,
    w: np.ndarray,
    H: np.ndarray,
    modes: Any,
    max_order: int,
    weighting: Any,
    lower: bool,
    upper: bool,
    refine: bool,
    tol_frequency: float,
    tol_damping: float,
    min_stable: int | None,
) -> ModalFit:
    Wt = _weights(H, weighting)
    table = lscf_poles(w, H, max_order=max_order, weights=Wt)
    ms = max(4, max_order // 4) if min_stable is None else int(min_stable)
    lam = _select(table, modes, tol_frequency, tol_damping, ms)
    status = _stability(table, tol_frequency, tol_damping)
    mag = np.sum(np.abs(H), axis=(1, 2))
    msg = "LSCF poles, LSFD residues"
    if lam.size == 0:
        raise InputError(
            "fit_modes: no pole is stable over enough orders; raise max_order, lower min_stable or name the"
            " frequencies (modes=[f1, f2, ...] in Hz)"
        )
    std_w = std_z = np.full(lam.size, np.nan)
    if refine:
        lam, std_w, std_z, m2 = _refine(w, H, Wt, lam, lower, upper)
        msg += f"; refined by variable projection ({m2})"
    if isinstance(modes, str) and lam.size > 1:
        # "auto": a pole that fits the noise (stable over orders by chance) has
        # a term no larger than the noise where it acts; drop it and refit
        sig = _significance(w, H, Wt, lam, lower, upper)
        weak = sig < SIGNIFICANCE
        if np.any(weak) and not np.all(weak):
            msg += (
                f"; dropped {int(weak.sum())} pole(s) not above the noise (significance < {SIGNIFICANCE:g})"
            )
            lam = lam[~weak]
            std_w, std_z = std_w[~weak], std_z[~weak]
            if refine:
                lam, std_w, std_z, _ = _refine(w, H, Wt, lam, lower, upper)
    order = np.argsort(np.abs(lam))
    lam, std_w, std_z = lam[order], std_w[order], std_z[order]
    R, LR, UR, _ = lsfd(w, H, lam, weights=Wt, lower=lower, upper=upper)
    stab = Stabilisation(
        tuple(p for p, _ in table),
        tuple(lp for _, lp in table),
        tuple(status),
        float(tol_frequency),
        float(tol_damping),
        w,
        mag,
        lam,
    )
    fit = ModalFit(
        omega_n=np.abs(lam),
        damping=-lam.real / np.abs(lam),
        poles=lam,
        residues=R,
        lower=LR,
        upper=UR,
        std_omega=std_w,
        std_damping=std_z,
        measured=data,
        outputs=data.outputs,
        inputs=data.inputs,
        quality=FitQuality(0.0, 0.0, np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0)),
        stabilisation=stab,
        source=data.source or "arrays",
        message=msg,
    )
    q = _quality(fit.synthesis(w), H, Wt, w, lam, fit.modal_constants)
    object.__setattr__(q, "significance", _significance(w, H, Wt, lam, lower, upper))
    object.__setattr__(fit, "quality", q)
    return fit
