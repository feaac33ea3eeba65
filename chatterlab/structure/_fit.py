"""Modal fit of a measured receptance: poles by the (poly-reference)
least-squares complex frequency-domain estimator with a stabilisation
diagram, residues by least squares in the frequency domain with lower and
upper residual terms, and a maximum-likelihood refinement of the poles.

The model fitted to ``H[k, o, i]`` (receptance, m/N) at ``s = j w_k``::

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

import contextlib
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import InputError

__all__ = ["ModalFit", "Stabilisation", "FitQuality", "fit_modes", "lscf_poles", "lsfd"]

#: the status codes of the stabilisation diagram
NEW, STABLE_FREQUENCY, STABLE = 0, 1, 2


# ============================================================================ input


def one_blas_thread() -> Any:
    """Single-threaded BLAS while the fit's many small dense solves run
    (threaded OpenBLAS is ~10x slower on them when the cores are shared);
    threadpoolctl when installed, else nothing.  (The frequency layer has
    the same guard for its solves; the structure layer cannot import it.)"""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


def _as_arrays(
    frf: Any, band: tuple[float, float] | None
) -> tuple[np.ndarray, np.ndarray, tuple, tuple, str]:
    """(omega, H (n_freq, n_out, n_in), outputs, inputs, source) from a
    MeasuredFRF (duck-typed: frequency, H, outputs, inputs) or a tuple
    (omega rad/s, H), restricted to ``band`` (rad/s)."""
    if isinstance(frf, tuple) and len(frf) == 2:
        w = np.asarray(frf[0], dtype=float)
        H = np.asarray(frf[1], dtype=complex)
        if H.ndim == 1:
            H = H[:, None, None]
        # the MeasuredFRF default: coordinate k is output k and input k (a driving-point matrix)
        outs = tuple(f"{k + 1}" for k in range(H.shape[1])) if H.ndim == 3 else ()
        ins = tuple(f"{k + 1}" for k in range(H.shape[2])) if H.ndim == 3 else ()
        src = "arrays"
    elif all(hasattr(frf, a) for a in ("frequency", "H", "outputs", "inputs")):
        w = np.asarray(frf.frequency, dtype=float)
        H = np.asarray(frf.H, dtype=complex)
        outs, ins = tuple(frf.outputs), tuple(frf.inputs)
        src = str(getattr(frf, "source", "measured FRF"))
    else:
        raise InputError(
            f"fit_modes: frf must be a MeasuredFRF or a tuple (omega [rad/s], H), got {type(frf).__name__}"
        )
    if w.ndim != 1 or H.ndim != 3 or H.shape[0] != w.size:
        raise InputError(
            f"fit_modes: H must have shape (n_freq, n_out, n_in) with n_freq = {w.size} (got {H.shape})"
        )
    if not (np.all(np.isfinite(w)) and np.all(np.isfinite(H))):
        raise InputError("fit_modes: omega and H must be finite; drop the bad points")
    if w.size > 1 and not np.all(np.diff(w) > 0):
        raise InputError("fit_modes: omega must increase strictly; sort the points and drop duplicates")
    if band is not None:
        lo, hi = (float(b) for b in band)
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 <= lo < hi):
            raise InputError(f"fit_modes: band must be (lo, hi) in rad/s with 0 <= lo < hi (got {band!r})")
        keep = (w >= lo) & (w <= hi)
        w, H = w[keep], H[keep]
    if w.size < 8:
        raise InputError(f"fit_modes: {w.size} frequencies in the band; a fit needs at least 8")
    if np.any(w <= 0):
        raise InputError("fit_modes: the band must exclude 0 Hz (the lower residual is 1/s^2); raise band[0]")
    return w, H, outs, ins, src


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


# ============================================================================ pLSCF


@dataclass(frozen=True, eq=False)
class Stabilisation:
    """The poles of every model order and their stability.

    ``orders[j]`` is the order p (the matrix polynomial degree; p n_in
    poles), ``poles[j]`` its physical poles (Im > 0, Re < 0, natural
    frequency in the band), ``status[j]`` per pole one of 0 (new),
    1 (stable in frequency), 2 (stable in frequency and damping) against
    the previous order.  ``omega`` and ``magnitude`` (the sum of |H| over
    the entries) are the measured curve the diagram is drawn over.
    """

    orders: tuple[int, ...]
    poles: tuple[np.ndarray, ...]
    status: tuple[np.ndarray, ...]
    tol_frequency: float
    tol_damping: float
    omega: np.ndarray
    magnitude: np.ndarray
    selected: np.ndarray = field(default_factory=lambda: np.zeros(0, complex))

    def plot(self, ax: Any = None) -> Any:
        """The stabilisation diagram (order against frequency in Hz) over the
        measured magnitude; returns the Axes.  Imports matplotlib."""
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(8, 5))
        styles = {
            NEW: dict(marker="o", mfc="none", color="0.6", ms=4, label="new"),
            STABLE_FREQUENCY: dict(marker="d", mfc="none", color="tab:blue", ms=4, label="stable frequency"),
            STABLE: dict(marker="+", color="tab:red", ms=7, label="stable frequency and damping"),
        }
        for code, st in styles.items():
            f, o = [], []
            for p, lam, s in zip(self.orders, self.poles, self.status, strict=True):
                sel = s == code
                f.extend(np.abs(lam[sel]) / (2 * np.pi))
                o.extend([p] * int(sel.sum()))
            ax.plot(f, o, ls="none", **st)
        for lam in self.selected:
            ax.axvline(abs(lam) / (2 * np.pi), color="k", lw=0.8, ls=":")
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel("model order p")
        ax2 = ax.twinx()
        ax2.semilogy(self.omega / (2 * np.pi), self.magnitude, color="k", lw=0.8)
        ax2.set_ylabel("sum |H|  [m/N]")
        ax.set_xlim(self.omega[0] / (2 * np.pi), self.omega[-1] / (2 * np.pi))
        ax.legend(loc="upper left", fontsize=8)
        ax.set_title(
            f"stabilisation: frequency {100 * self.tol_frequency:g} %, damping {100 * self.tol_damping:g} %"
        )
        return ax


def _lscf_blocks(w: np.ndarray, H: np.ndarray, Wt: np.ndarray, p: int, dt: float) -> Any:
    """R_o, S_o, T_o of every output row for the largest order p."""
    n_f, n_o, n_i = H.shape
    Om = np.exp(1j * np.outer(w * dt, np.arange(p + 1)))  # (n_f, p+1)
    blocks = []
    for o in range(n_o):
        # one scalar weight per row and frequency: the entries' weights averaged
        wo = np.sqrt(np.mean(Wt[:, o, :] ** 2, axis=1))
        X = wo[:, None] * Om
        Y = -(X[:, :, None] * H[:, o, None, :]).reshape(n_f, (p + 1) * n_i)
        blocks.append(((X.conj().T @ X).real, (X.conj().T @ Y).real, (Y.conj().T @ Y).real))
    return blocks


def _poles_of_order(blocks: Any, p: int, n_i: int, dt: float) -> np.ndarray:
    m = (p + 1) * n_i
    M = np.zeros((m, m))
    for R, S, T in blocks:
        Rp, Sp, Tp = R[: p + 1, : p + 1], S[: p + 1, :m], T[:m, :m]
        M += 2.0 * (Tp - Sp.T @ np.linalg.lstsq(Rp, Sp, rcond=None)[0])
    pn = p * n_i
    a = -np.linalg.lstsq(M[:pn, :pn], M[:pn, pn:], rcond=None)[0]  # (p n_i, n_i): A_0..A_{p-1} stacked
    comp = np.zeros((pn, pn))
    comp[: pn - n_i, n_i:] = np.eye(pn - n_i)
    # A(z) v = 0 with A_p = I: z^p v = -sum_r A_r z^r v, state [v; z v; ...; z^(p-1) v]
    comp[pn - n_i :, :] = -np.hstack([a[r * n_i : (r + 1) * n_i, :] for r in range(p)])
    z = np.linalg.eigvals(comp)
    z = z[np.abs(z) > 0]
    return np.log(z.astype(complex)) / dt


def lscf_poles(
    omega: np.ndarray,
    H: np.ndarray,
    *,
    max_order: int,
    weights: np.ndarray | None = None,
    band: tuple[float, float] | None = None,
    max_damping: float = 0.5,
) -> list[tuple[int, np.ndarray]]:
    """pLSCF poles for every order 1..max_order (see the module docstring).

    Returns a list of (order, physical poles): Im > 0, Re < 0, damping ratio
    below ``max_damping`` and natural frequency inside ``band`` (rad/s,
    default the data's)."""
    n_i = H.shape[2]
    Wt = np.ones(H.shape) if weights is None else weights
    dt = np.pi / float(omega[-1])
    blocks = _lscf_blocks(omega, H, Wt, max_order, dt)
    lo, hi = band if band is not None else (float(omega[0]), float(omega[-1]))
    out = []
    for p in range(1, max_order + 1):
        lam = _poles_of_order(blocks, p, n_i, dt)
        wn = np.abs(lam)
        with np.errstate(invalid="ignore", divide="ignore"):
            zeta = -lam.real / wn
        keep = (lam.imag > 0) & (zeta > 0) & (zeta < max_damping) & (wn >= lo) & (wn <= hi)
        lam = lam[keep]
        out.append((p, lam[np.argsort(np.abs(lam))]))
    return out


def _stability(table: list[tuple[int, np.ndarray]], tol_f: float, tol_z: float) -> list[np.ndarray]:
    status = []
    prev = np.zeros(0, complex)
    for _, lam in table:
        s = np.zeros(lam.size, dtype=int)
        if prev.size:
            for j, l_ in enumerate(lam):
                wn, z = abs(l_), -l_.real / abs(l_)
                wp, zp = np.abs(prev), -prev.real / np.abs(prev)
                k = int(np.argmin(np.abs(wp - wn)))
                if abs(wp[k] - wn) <= tol_f * wn:
                    s[j] = STABLE if abs(zp[k] - z) <= tol_z * z else STABLE_FREQUENCY
        status.append(s)
        prev = lam
    return status


def _track_length(
    table: list[tuple[int, np.ndarray]], j_top: int, lam: complex, tol_f: float, tol_z: float
) -> int:
    """How many consecutive orders below j_top hold a pole within tol_f in
    frequency of the one found at the order above (the pole's track in the
    stabilisation diagram).  Damping is not required to be stable along the
    track (the diagram marks it): under noise it wanders more than 5 %
    between orders while the frequency stays, and the refinement settles
    it."""
    n = 0
    cur = lam
    for j in range(j_top - 1, -1, -1):
        cand = table[j][1]
        if cand.size == 0:
            break
        wn = abs(cur)
        wc = np.abs(cand)
        k = int(np.argmin(np.abs(wc - wn)))
        if abs(wc[k] - wn) <= tol_f * wn:
            n += 1
            cur = cand[k]
        else:
            break
    return n


def _select(
    table: list[tuple[int, np.ndarray]],
    modes: Any,
    tol_f: float,
    tol_z: float,
    min_stable: int,
) -> np.ndarray:
    """The poles the fit keeps: automatic (long stable tracks at the top
    order), or the stable pole nearest each frequency asked for (Hz)."""
    if (
        isinstance(modes, str)
        and modes == "auto"
        or isinstance(modes, int | np.integer)
        and not isinstance(modes, bool)
    ):
        jt = len(table) - 1
        cands = []
        for j_top in range(jt, max(jt - 3, -1), -1):  # the top order, or the next ones if it is empty
            for lam in table[j_top][1]:
                n = _track_length(table, j_top, complex(lam), tol_f, tol_z)
                cands.append((n, complex(lam)))
            if cands:
                break
        cands.sort(key=lambda t: -t[0])
        chosen: list[complex] = []
        for n, lam in cands:
            if isinstance(modes, str) and n < min_stable:
                continue
            # two poles closer than their half-power half-width (|Re lam|) are
            # one pole to the LSFD (their columns are nearly collinear and the
            # refinement ill-posed): keep the first; its residue matrix then
            # has rank > 1 and real_modes splits it (a tool's x and y modes)
            if any(abs(lam - c) < 0.5 * (abs(lam.real) + abs(c.real)) for c in chosen):
                continue
            chosen.append(lam)
            if not isinstance(modes, str) and len(chosen) == int(modes):
                break
        if not isinstance(modes, str) and len(chosen) < int(modes):
            raise InputError(
                f"fit_modes: modes={int(modes)} but only {len(chosen)} distinct poles were found at the top order;"
                " raise max_order or ask for fewer modes"
            )
        return np.array(sorted(chosen, key=abs), dtype=complex)
    try:
        freqs = [float(f) for f in modes]
    except (TypeError, ValueError):
        raise InputError(
            f"fit_modes: modes must be 'auto', a number of modes or a list of frequencies in Hz (got {modes!r})"
        ) from None
    status = _stability(table, tol_f, tol_z)
    out = []
    for f in freqs:
        best, bestd = None, np.inf
        for (_p, lam), s in zip(table[::-1], status[::-1], strict=True):
            sel = lam[s == STABLE] if np.any(s == STABLE) else lam
            if sel.size:
                k = int(np.argmin(np.abs(np.abs(sel) - 2 * np.pi * f)))
                d = abs(abs(sel[k]) - 2 * np.pi * f)
                if d < bestd - 1e-12 * f:
                    best, bestd = complex(sel[k]), d
                if best is not None and d <= 0.05 * 2 * np.pi * f:
                    break
        if best is None or bestd > 0.1 * 2 * np.pi * f:
            raise InputError(f"fit_modes: no pole within 10 % of {f:g} Hz at any order; check the frequency")
        out.append(best)
    return np.array(sorted(out, key=abs), dtype=complex)


# ============================================================================ LSFD


def _pole(wn: np.ndarray, zeta: np.ndarray) -> np.ndarray:
    return -zeta * wn + 1j * wn * np.sqrt(np.maximum(1.0 - zeta**2, 0.0))


def _basis(s: np.ndarray, lam: np.ndarray, lower: bool, upper: bool) -> np.ndarray:
    """Complex basis columns (n_freq, 2m + residuals) of the real unknowns
    Re R_r, Im R_r, LR, UR."""
    a = 1.0 / (s[:, None] - lam[None, :])
    b = 1.0 / (s[:, None] - lam.conj()[None, :])
    cols = [a + b, 1j * (a - b)]
    if lower:
        cols.append((1.0 / s**2)[:, None])
    if upper:
        cols.append(np.ones((s.size, 1), complex))
    return np.hstack(cols)


def lsfd(
    omega: np.ndarray,
    H: np.ndarray,
    lam: np.ndarray,
    *,
    weights: np.ndarray | None = None,
    lower: bool = True,
    upper: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Residues and residual terms for fixed poles (one real weighted least
    squares per entry).

    Returns (R (m, n_out, n_in) complex, LR (n_out, n_in), UR (n_out, n_in),
    weighted residual (n_freq, n_out, n_in) complex)."""
    R, LR, UR, res, _ = _lsfd(omega, H, lam, weights, lower, upper)
    return R, LR, UR, res


def _solve_r(Rq: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with Rq x = b (upper triangular); a zero pivot (a column that is
    all zero, or two identical poles) gives the minimum-norm least-squares
    answer instead."""
    d = np.abs(np.diag(Rq))
    if d.size and d.min() > 1e-13 * d.max():
        from scipy.linalg import solve_triangular

        return np.asarray(solve_triangular(Rq, b))
    return np.linalg.lstsq(Rq, b, rcond=None)[0]


def _lsfd(
    w: np.ndarray, H: np.ndarray, lam: np.ndarray, Wt: np.ndarray | None, lower: bool, upper: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    s = 1j * w
    P = _basis(s, lam, lower, upper)
    n_f, n_o, n_i = H.shape
    m = lam.size
    R = np.zeros((m, n_o, n_i), complex)
    LR = np.zeros((n_o, n_i))
    UR = np.zeros((n_o, n_i))
    res = np.zeros(H.shape, complex)
    Wt = np.ones(H.shape) if Wt is None else Wt
    for o in range(n_o):
        for i in range(n_i):
            wt = Wt[:, o, i]
            if not np.any(wt > 0):
                continue  # not measured: residue 0, residual 0
            A = wt[:, None] * P
            Ar = np.vstack([A.real, A.imag])
            y = wt * H[:, o, i]
            # column scaling for the conditioning of the residual columns, then
            # Householder QR (backward stable; cheaper than the SVD of lstsq)
            sc = np.linalg.norm(Ar, axis=0)
            sc[sc == 0] = 1.0
            Q, Rq = np.linalg.qr(Ar / sc)
            x = _solve_r(Rq, Q.T @ np.concatenate([y.real, y.imag])) / sc
            R[:, o, i] = x[:m] + 1j * x[m : 2 * m]
            k = 2 * m
            if lower:
                LR[o, i] = x[k]
                k += 1
            if upper:
                UR[o, i] = x[k]
            res[:, o, i] = y - A @ x
    return R, LR, UR, res, P.shape[1]


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
class ModalFit:
    """A fitted modal model of a measured receptance (see the module docstring).

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
    omega, H : the fitted data (rad/s; (n_freq, n_out, n_in) m/N).
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
    omega: np.ndarray
    H: np.ndarray
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
    def frf(self, omega: Any, *, real_modes: bool = False, residuals: bool = True) -> np.ndarray:
        """The fitted receptance at ``omega`` (rad/s), (n_freq, n_out, n_in).

        ``real_modes``: the real-mode sum sum Re(A_r) / (w_r^2 - w^2 + 2 j
        zeta_r w_r w) (what :meth:`to_model` reproduces) instead of the
        complex-residue sum; ``residuals``: add LR / s^2 + UR."""
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

    def to_measured(self, omega: Any = None) -> Any:
        """The fitted FRF as a MeasuredFRF at ``omega`` (default: the fitted
        frequencies)."""
        from ._measured import MeasuredFRF

        w = self.omega if omega is None else np.asarray(omega, dtype=float)
        return MeasuredFRF.from_arrays(
            w, self.frf(w), self.outputs, self.inputs, source=f"modal fit of {self.source}"
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
        peak = float(np.abs(self.H).max())
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
        points: dict[str, dict[str, str]] = {}
        for c in coords[:n_c]:
            pt, _, d = c.rpartition(".")
            if pt and d in ("x", "y", "rz"):
                points.setdefault(pt, {})[d] = c
            else:
                points.setdefault(c, {})["x"] = c
        raw: dict[str, Any] = {
            "model": {"name": name, "description": f"real-mode model of the modal fit of {self.source}"},
            "matrices": {
                "coordinates": coords,
                "M": sym[0].tolist(),
                "L": sym[1].tolist(),
                "K": sym[2].tolist(),
            },
            "point": [{"id": p, "coords": cs} for p, cs in points.items()],
        }
        for key, val in (tables or {}).items():
            if key in ("matrices",):
                raise InputError("ModalFit.to_model: tables may not replace [matrices]")
            if key == "point":
                raw["point"] = raw["point"] + list(val)
            else:
                raw[key] = val
        return build_model(raw, source=f"modal fit of {self.source}")

    # ------------------------------------------------------------ plots
    def plot(self, output: int | str = 0, input: int | str = 0, ax: Any = None) -> Any:
        """Measured and fitted magnitude and phase of one entry against
        frequency (Hz), with the fitted natural frequencies marked, on ``ax``
        (a pair of Axes: magnitude, phase; default new); returns the pair.
        Imports matplotlib."""
        import matplotlib.pyplot as plt

        o = self.outputs.index(output) if isinstance(output, str) else int(output)
        i = self.inputs.index(input) if isinstance(input, str) else int(input)
        if ax is None:
            _, ax = plt.subplots(2, 1, sharex=True, figsize=(8, 6), gridspec_kw={"height_ratios": [2, 1]})
        ax_m, ax_p = ax
        f = self.omega / (2 * np.pi)
        Hf = self.frf(self.omega)[:, o, i]
        Hm = self.H[:, o, i]
        ax_m.semilogy(f, np.abs(Hm), ".", ms=2, color="0.5", label="measured")
        ax_m.semilogy(f, np.abs(Hf), "-", color="tab:red", lw=1.2, label=f"fit ({self.n_modes} modes)")
        ax_p.plot(f, np.degrees(np.angle(Hm)), ".", ms=2, color="0.5")
        ax_p.plot(f, np.degrees(np.angle(Hf)), "-", color="tab:red", lw=1.2)
        for fr in self.frequency_hz:
            ax_m.axvline(fr, color="k", lw=0.6, ls=":")
        ax_m.set_ylabel(f"|{self.outputs[o]} / {self.inputs[i]}|  [m/N]")
        ax_p.set_ylabel("phase [deg]")
        ax_p.set_xlabel("frequency [Hz]")
        ax_m.legend(fontsize=8)
        ax_m.set_title(
            f"modal fit: error {100 * self.quality.error:.2g} %, FRAC {self.quality.frac[o, i]:.5f}"
        )
        return ax

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
    frf : MeasuredFRF or tuple (omega, H)
        Receptance, m/N; omega in rad/s; H shaped (n_freq,) or
        (n_freq, n_out, n_in).
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
    w, H, outs, ins, src = _as_arrays(frf, band)
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
            w,
            H,
            outs,
            ins,
            src,
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
    w: np.ndarray,
    H: np.ndarray,
    outs: tuple,
    ins: tuple,
    src: str,
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
        omega=w,
        H=H,
        outputs=outs,
        inputs=ins,
        quality=FitQuality(0.0, 0.0, np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0)),
        stabilisation=stab,
        source=src,
        message=msg,
    )
    q = _quality(fit.frf(w), H, Wt, w, lam, fit.modal_constants)
    object.__setattr__(q, "significance", _significance(w, H, Wt, lam, lower, upper))
    object.__setattr__(fit, "quality", q)
    return fit
