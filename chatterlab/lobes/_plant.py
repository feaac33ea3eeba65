"""What the boundary needs of the structure (:class:`Plant`: its FRF between
the coupling-element coordinates, poles, CE matrices and pole-residue form)
and the inner solve at given frequencies: every width beta with an eigenvalue
|nu(beta)| = 1 of N(beta) (see :mod:`chatterlab.lobes._diagram`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..frequency._bounds import Band, PoleResidue
from ..process._loop import ClosedLoop
from ._boundary import Ops, delayed_factors, make_ops, near_root, nu, widths_rank1

__all__ = ["Plant"]


class Plant:
    """What the boundary needs of the structure: the FRF H(jw) between the
    coupling-element coordinates (forces on point a in CE axes -> relative
    displacements dw, m/N), its poles (to place the frequency grid), the CE
    matrices at width b = 1 m (so that beta is the width in m), and, when
    known, its pole-residue form (which proves the searched band complete).

    Built from a closed loop (:meth:`from_loop`), from a
    python-control LTI system (:func:`chatterlab.lobes._control.lti_plant`)
    or from a measured FRF (:func:`chatterlab.lobes._measured.measured_plant`).

    A measured plant has no poles and no pole-residue form; instead
    ``measured_band`` (rad/s) is the band its FRF covers -- the band searched,
    never certified, so that chatter outside it is "unknown" -- and
    ``grid`` the measured frequencies, which the boundary's frequency grid
    keeps.
    """

    def __init__(
        self,
        H: Any,
        poles: np.ndarray,
        Dl_P: np.ndarray,
        Dl_V: np.ndarray,
        Dl_O: np.ndarray,
        residues: PoleResidue | None = None,
        *,
        measured_band: Band | None = None,
        grid: np.ndarray | None = None,
    ) -> None:
        self.H = H
        self.poles = np.asarray(poles, dtype=complex)
        self.Dl_P, self.Dl_V, self.Dl_O = (np.asarray(x, dtype=float) for x in (Dl_P, Dl_V, Dl_O))
        self.residues = residues
        self.measured_band = measured_band
        self.grid = None if grid is None else np.asarray(grid, dtype=float)
        self._factors: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def factors(self) -> tuple[np.ndarray, np.ndarray]:
        """D_O = U V^T (:func:`chatterlab.lobes._boundary.delayed_factors`), once per plant."""
        if self._factors is None:
            self._factors = delayed_factors(self.Dl_O)
        return self._factors

    @classmethod
    def from_loop(cls, loop: ClosedLoop) -> Plant:
        """The plant of a closed loop: its structure's FRF between the CE
        coordinates in pole-residue form, and its CE matrices (at the loop's
        width: a loop at b = 1 m makes beta the width in m)."""
        cm = loop.structure.complex_modes
        J = loop.J
        Jphi = J @ cm.phi
        m = J.shape[0]
        # the complex-mode superposition J phi diag(1/(s - lam)) phi^T J^T (all
        # modes, no residual), evaluated as one matrix product over the modes
        pr = PoleResidue(cm.lam, Jphi, Jphi.T, np.zeros((m, m)))

        def H(omega: np.ndarray) -> np.ndarray:
            return pr(1j * np.asarray(omega, float))

        return cls(H, cm.lam, loop.Dl_P, loop.Dl_V, loop.Dl_O, pr)

    def with_terms_o(self) -> Plant:
        """The same structure with only the delayed term of the process."""
        return Plant(
            self.H,
            self.poles,
            0 * self.Dl_P,
            0 * self.Dl_V,
            self.Dl_O,
            self.residues,
            measured_band=self.measured_band,
            grid=self.grid,
        )


def _ops(plant: Plant, omega: np.ndarray) -> Ops:
    return make_ops(plant.H, plant.Dl_P, plant.Dl_V, plant.Dl_O, omega, plant.factors)


_nu = nu


def _solve_beta(
    ops: Ops, lo: np.ndarray, hi: np.ndarray, idx: np.ndarray | None = None, n_grid: int = 48
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All beta in [lo, hi] (per frequency) with some |nu_j(beta)| = 1, by
    bracketing on a log grid (used to re-solve near a known branch).

    Returns (freq index, beta, z) of every solution, z = -1/nu.
    """
    N = ops.omega.size if idx is None else idx.size
    fidx = np.arange(N)
    t = np.linspace(0.0, 1.0, n_grid)
    lb = np.log(lo)[:, None] + (np.log(hi) - np.log(lo))[:, None] * t[None, :]
    with np.errstate(divide="ignore"):  # a rank-deficient N's zero eigenvalue: -inf, no sign change
        mag = np.log(np.abs(_nu(ops, np.exp(lb), idx)))  # (N, K, r)
    sgn = np.sign(mag)
    ch = np.nonzero(sgn[:, :-1, :] * sgn[:, 1:, :] < 0)
    fi, ki, ri = ch
    if fi.size == 0:
        return np.zeros(0, int), np.zeros(0), np.zeros(0, complex)
    a = lb[fi, ki]
    b = lb[fi, ki + 1]
    fa = mag[fi, ki, ri]
    fb_ = mag[fi, ki + 1, ri]
    sel = fidx[fi] if idx is None else idx[fi]
    # Illinois regula falsi on log|nu| against log beta (superlinear; keeps the bracket)
    last = np.zeros(a.size)
    for _ in range(40):
        c = np.where(fb_ != fa, b - fb_ * (b - a) / (fb_ - fa), 0.5 * (a + b))
        with np.errstate(divide="ignore"):
            fc = np.log(np.abs(_nu_pick(ops, np.exp(c), sel, ri)))
        left = np.sign(fc) == np.sign(fa)
        fb_ = np.where(left, np.where(last == 1, 0.5 * fb_, fb_), fc)
        fa = np.where(left, fc, np.where(last == -1, 0.5 * fa, fa))
        b = np.where(left, b, c)
        a = np.where(left, c, a)
        last = np.where(left, 1, -1)
        if np.all((np.abs(b - a) < 1e-15 * np.maximum(1.0, np.abs(a))) | (fc == 0)):
            break
    c = np.where(fb_ != fa, b - fb_ * (b - a) / (fb_ - fa), 0.5 * (a + b))
    beta = np.exp(c)
    nu_ = _nu_pick(ops, beta, sel, ri)
    return fi, beta, -1.0 / nu_


def _nu_pick(ops: Ops, beta: np.ndarray, freq: np.ndarray, branch: np.ndarray) -> np.ndarray:
    nu_ = _nu(ops, beta[:, None], freq)[:, 0, :]
    return nu_[np.arange(beta.size), branch]


def _widths_between(ops: Ops, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every boundary width in [lo, hi] at each frequency of ``ops``: exact
    (polynomial roots) for a rank-one delayed term, so two close widths near a
    fold are both found; bracketing for higher rank.  Returns (freq index,
    beta, z) like :func:`_solve_beta`."""
    if ops.Vt.shape[0] != 1:
        return _solve_beta(ops, lo, hi, n_grid=24)
    xs, _ = widths_rank1(ops, hi, screen=False)
    fi = np.repeat(np.arange(len(xs)), [x.size for x in xs])
    beta = np.concatenate(xs) * hi[fi] if fi.size else np.zeros(0)
    keep = beta >= lo[fi]
    fi, beta = fi[keep], beta[keep]
    return fi, beta, _z_at(ops, beta, fi)


def _nearest_width(
    ops: Ops, lo: np.ndarray, hi: np.ndarray, target: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """At each frequency of ``ops``, the boundary width in [lo, hi] nearest
    ``target`` (in log beta) and its z; NaN where there is none.

    What :func:`_widths_between` and a choice among its widths give, taken a
    shorter way for a rank-one term when the answer is proven: Newton on Q
    (the polynomial of :func:`chatterlab.lobes._boundary.widths_rank1`, in
    x = beta/hi, steps capped at 5 %) from the target to a root x*, and then
    Q / (x - x*) shown by the disc test of
    :func:`chatterlab.lobes._boundary.no_root_in_disc` to have no root
    within the disc about the target that holds every x as near in log as
    x* (radius at least 1e-6 of the target, so a near-double root -- two
    widths at a fold -- always takes the long way): x* is then the nearest
    root of Q, real or not, and the long way would choose it too.  Every
    other frequency (another root near, Newton not converged, x* outside
    [lo, hi]) takes the long way."""
    N = ops.omega.size
    best_b = np.full(N, np.nan)
    best_z = np.full(N, np.nan + 0j)
    long_way = np.ones(N, bool)
    if ops.Vt.shape[0] == 1 and ops.HA.shape[-1] <= 3 and N:
        x, sure = near_root(ops, hi, target / hi)
        beta = x * hi
        sure &= (beta >= lo) & (x <= 1.0 + 1e-9)
        rows = np.nonzero(sure)[0]
        best_b[rows] = beta[rows]
        best_z[rows] = _z_at(ops, beta[rows], rows)
        long_way = ~sure
    rows = np.nonzero(long_way)[0]
    if rows.size:
        sub = Ops(ops.omega[rows], ops.HA[rows], ops.HU[rows], ops.Vt)
        fi, bb, zz = _widths_between(sub, lo[rows], hi[rows])
        dist = np.abs(np.log(bb / target[rows][fi]))
        ordr = np.argsort(-dist)  # later writes (smaller distance) win
        best_b[rows[fi[ordr]]] = bb[ordr]
        best_z[rows[fi[ordr]]] = zz[ordr]
    return best_b, best_z


def _z_at(ops: Ops, beta: np.ndarray, freq: np.ndarray) -> np.ndarray:
    """z = -1/nu for the eigenvalue of N(beta) nearest the unit circle."""
    v = _nu(ops, beta[:, None], freq)[:, 0, :]
    with np.errstate(divide="ignore"):
        j = np.argmin(np.abs(np.log(np.abs(v))), axis=1)
    return -1.0 / v[np.arange(beta.size), j]
