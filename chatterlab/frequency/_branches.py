"""The eigenvalue branches of the loop transfer, the predicted root locations, and the "branch" method.

With :math:`\\det\\Delta = \\det P\\,\\det(I_r - H(\\lambda) e^{-\\lambda\\tau})`,
:math:`H = V^T P^{-1} U`, the roots along each eigenvalue branch
:math:`\\mu_j` of :math:`H` satisfy
:math:`\\lambda\\tau = \\log\\mu_j(\\lambda) + 2\\pi i k`.  Tracking
:math:`\\mu_j(j\\omega)` continuously along the axis gives predicted root
locations (:func:`predict`: they steer where the spectral search looks); one
Newton start per prediction is the ``"branch"`` method (:func:`branch_roots`),
an independent check of the spectral route.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from numpy.typing import NDArray

from ._band import band_top
from ._delay_system import DelaySystem
from ._newton import EXP_LIMIT, newton_distinct
from ._roots_result import RootsResult, TooLarge, make_result

__all__ = ["predict", "branch_roots", "AXIS_GRID_MAX"]

ComplexArray = NDArray[np.complex128]
FloatArray = NDArray[np.float64]


#: most frequencies the root prediction samples on the axis (bounds memory to
#: about 100 MB: the grid, the tracked eigenvalues and one chunk of the transfer)
AXIS_GRID_MAX = 2_000_000


def _axis_grid(sys: DelaySystem, top: float) -> FloatArray:
    """Frequencies in [0, top] (rad/s): step pi/(4 tau) plus refinement at poles."""
    tau = sys.tau
    step = min(math.pi / (4.0 * tau), top / 200.0)
    n = top / step
    if n > AXIS_GRID_MAX:
        raise TooLarge(
            f"the delay {tau:.4g} s needs {n:.3g} axis samples up to {top / 2 / math.pi:.4g} Hz"
            f" (limit {AXIS_GRID_MAX:.0e}): the roots are too dense to enumerate; pass omega_max"
            " to narrow the band"
        )
    pts = [np.linspace(0.0, top, int(math.ceil(top / step)) + 1)]
    offs = np.array([-8, -4, -2, -1, -0.5, -0.25, 0, 0.25, 0.5, 1, 2, 4, 8])
    p = sys.delay_free_poles()
    for z in p[p.imag >= 0]:
        d = max(abs(z.real), 1e-9 * abs(z), 1e-12)
        loc = z.imag + d * offs
        pts.append(loc[(loc >= 0) & (loc <= top)])
    return np.unique(np.concatenate(pts))


def _track_branches(mu: ComplexArray) -> ComplexArray:
    """Reorder the columns of ``mu`` (shape (G, r)) into continuous branches."""
    G, r = mu.shape
    if r == 1 or G < 2:
        return mu
    perms = np.array(list(itertools.permutations(range(r)))) if r <= 4 else None
    out = np.empty_like(mu)
    order = np.arange(r)
    out[0] = mu[0]
    if perms is not None:
        # best raw-to-raw matching of consecutive samples, vectorised
        with np.errstate(invalid="ignore"):
            cost = np.abs(mu[1:, perms] - mu[:-1, None, :]).sum(axis=2)
        cost[~np.isfinite(cost)] = np.inf
        best = perms[np.argmin(cost, axis=1)]
        for i in range(1, G):
            order = best[i - 1][order]
            out[i] = mu[i, order]
        return out
    for i in range(1, G):  # pragma: no cover - r > 4 is unusual
        prev = out[i - 1]
        cur = list(range(r))
        for j in range(r):
            k = min(cur, key=lambda c: abs(mu[i, c] - prev[j]))
            order[j] = k
            cur.remove(k)
        out[i] = mu[i, order]
    return out


def predict(sys: DelaySystem, top: float) -> tuple[ComplexArray, FloatArray]:
    """Predicted root locations from the phase condition along each branch.

    With ``mu_j(j w)`` the eigenvalues of ``H(j w)`` tracked continuously along
    the axis and ``phi_j`` their unwrapped phase, roots near the axis lie
    where ``tau w - phi_j(w) = 2 pi k`` (the phase condition of
    ``lam tau = log mu_j(lam) + 2 pi i k``); one Newton step of that scalar
    equation from the crossing ``j w*`` gives
    ``lam ~ j w* + log|mu_j| / (tau - s)``, ``s = d log mu_j / d lam``.
    Added: sign changes and dips of ``det Delta(x)`` on the real axis and the
    delay-free poles.  Returns the estimates (upper half plane) and an
    uncertainty (rad/s; ``inf`` where ``|s| > tau / 2``, i.e. where the
    long-delay picture does not hold).
    """
    tau = sys.tau
    w = _axis_grid(sys, top)
    mu = _track_branches(sys.loop_eigenvalues(1j * w))
    ests = []
    uncs = []
    with np.errstate(all="ignore"):
        for j in range(mu.shape[1]):
            m = mu[:, j]
            ok = np.isfinite(m) & (m != 0)
            if np.sum(ok) < 2:
                continue
            ww = w[ok]
            la = np.log(np.abs(m[ok]))
            ph = np.unwrap(np.angle(m[ok]))
            psi = (tau * ww - ph) / (2.0 * np.pi)
            lev = np.floor(psi)
            cross = np.flatnonzero(lev[1:] != lev[:-1])
            if cross.size == 0:
                continue
            dla = np.gradient(la, ww)
            dph = np.gradient(ph, ww)
            idx_list = []
            kk_list = []
            for i in cross:
                lo_, hi_ = sorted((psi[i], psi[i + 1]))
                ks = np.arange(math.floor(lo_) + 1, math.floor(hi_) + 1)
                idx_list.append(np.full(ks.shape, i))
                kk_list.append(ks)
            ii = np.concatenate(idx_list)
            kk = np.concatenate(kk_list)
            t = (kk - psi[ii]) / (psi[ii + 1] - psi[ii])
            wstar = ww[ii] + t * (ww[ii + 1] - ww[ii])
            lam_abs = la[ii] + t * (la[ii + 1] - la[ii])
            # d log mu / d lam on the axis = -i d log mu / d w
            s = -1j * ((dla[ii] + t * (dla[ii + 1] - dla[ii])) + 1j * (dph[ii] + t * (dph[ii + 1] - dph[ii])))
            corr = lam_abs / (tau - s)
            est = 1j * wstar + corr
            ratio = np.abs(s) / tau
            unc = np.where(ratio < 0.5, 2.0 * ratio * np.abs(corr) + 1e-12, np.inf)
            good = np.isfinite(est) & (est.real * tau > -EXP_LIMIT)
            ests.append(est[good])
            uncs.append(unc[good])
    lam = np.concatenate(ests) if ests else np.zeros(0, complex)
    unc = np.concatenate(uncs) if uncs else np.zeros(0)
    # the real axis (two real roots may share a branch index)
    p = sys.delay_free_poles()
    with np.errstate(all="ignore"):
        a_hi = (
            max(float(np.max(lam.real)) if lam.size else 0.0, float(np.max(p.real)) if p.size else 0.0, 0.0)
            + 10.0 / tau
        )
    x = np.linspace(a_hi - 60.0 / tau, a_hi, 601)
    with np.errstate(all="ignore"):
        sg, ld = np.linalg.slogdet(sys.delta(x).real)
    flip = np.flatnonzero(sg[1:] * sg[:-1] < 0)
    dips = np.flatnonzero((ld[1:-1] < ld[:-2]) & (ld[1:-1] < ld[2:])) + 1
    xr = np.concatenate([0.5 * (x[flip] + x[flip + 1]), x[dips]])
    # the delay-free poles: starts for the structural roots when the delay
    # term is weak or the delay short (where the sweeps do not contract)
    pp = p[p.imag >= 0]
    lam = np.concatenate([lam, xr.astype(complex), pp])
    unc = np.concatenate([unc, np.full(xr.shape, x[1] - x[0]), np.zeros(pp.shape)])
    lam = np.where(lam.imag < 0, lam.conj(), lam)
    return lam, unc


def branch_roots(sys: DelaySystem, count: int, omega_max: float | None, t0: float) -> RootsResult:
    tau = sys.tau
    top = band_top(sys, count, omega_max)
    est, unc = predict(sys, top)
    # Newton from the predictions that may end up among the rightmost
    re = est.real + np.minimum(unc, 1e6)
    take = np.argsort(-re)
    nstart = min(est.size, 4 * count + 16)
    roots, rejected = newton_distinct(sys, est[take[:nstart]], np.zeros(0, complex))
    # widen until the count-th root is safely right of every unused prediction
    while nstart < est.size and roots.size:
        srt = np.sort(roots.real)[::-1]
        a_c = float(srt[min(count, srt.size) - 1])
        more = take[nstart:][re[take[nstart:]] >= a_c - 0.5 / tau - 0.1 * abs(a_c)]
        if more.size == 0 and roots.size >= count:
            break
        if more.size == 0:
            more = take[nstart : nstart + 4 * count + 16]
        roots, rej = newton_distinct(sys, est[more], roots)
        rejected += rej
        nstart += more.size
        take = np.concatenate(
            [
                take[: nstart - more.size],
                more,
                np.setdiff1d(take[nstart - more.size :], more, assume_unique=True),
            ]
        )
    roots = roots[np.lexsort((roots.imag, -roots.real))][:count]
    status = "converged" if roots.size >= count else "not_converged"
    msg = (
        f"{roots.size} roots by Newton from {nstart} of {est.size} branch predictions "
        f"up to {top:.6g} rad/s ({rejected} start(s) without convergence)"
    )
    return make_result(
        roots, method="branch", n_nodes=(0, 0), rejected=rejected, status=status, message=msg, t0=t0
    )
