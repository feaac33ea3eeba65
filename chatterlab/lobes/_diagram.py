"""Stability lobes by D-subdivision in the coupling-element coordinates.

On the stability boundary a characteristic root sits on the imaginary axis,
s = j w.  With the cutting process D(s) = -(b/b_ref) J^T Dl(s) J and the
structure's FRF between the CE coordinates H(jw) = J G(jw) J^T, Sylvester's
identity turns det Delta(jw) = 0 into

    det(I + beta H (A + z O)) = 0,   beta = b / b_ref,  A = D_P + jw D_V,  z = e^{-jwT}.

Factor the delayed matrix O = U V^T (rank r, 1 for the usual chip-thickness
regeneration).  The matrix determinant lemma gives, for each w,

    det(I + beta H A) det(I_r + z N(beta)),   N(beta) = beta V^T (I + beta H A)^-1 H U,

so the boundary is where an eigenvalue nu of N(beta) has |nu| = 1, and then
z = -1/nu fixes the delay: wT = -arg z + 2 pi k, k = 0, 1, 2, ... (one lobe
per k).  chatterlab finds every real positive beta with |nu(beta)| = 1 up to
the width range at every w of a grid (exactly: real roots of a polynomial,
:mod:`chatterlab.lobes._boundary`), follows the curve around its folds, and
so knows every lobe as a curve (T_k(w), b(w)); the grid's band is proven to
hold every boundary point by a gain bound (:mod:`chatterlab.frequency._bounds`).
The lower envelope at each requested speed is then refined to round-off by
regula falsi on the phase condition, re-solving beta exactly at each trial
frequency, and checked by the argument principle.

For the classical regenerative model (D_P = K_f b f n^T, D_O = -D_P, D_V = 0)
this reduces to Tlusty's b_lim = -1/(2 K_f Re[n^T G f]) with the phase
condition; for the paper's D_P + s D_V + D_O e^{-sT} (Eq. 2.23, 3.7-3.9) it is
the small eigenvalue problem above at each frequency.

References
----------
.. [1] J. Tlusty, M. Polacek, "The stability of machine tools against self
   excited vibrations in machining", Int. Res. Prod. Eng., ASME, 465-474, 1963.
.. [2] Y. Altintas, E. Budak, "Analytical prediction of stability lobes in
   milling", CIRP Annals 44(1), 357-362, 1995 (eigenvalue form of the boundary).
.. [3] T. Insperger, G. Stépán, *Semi-Discretization for Time-Delay Systems*,
   Springer, 2011, ch. 1-2 (D-subdivision).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np

from ..errors import InputError, check_speed, check_width
from ..frequency._bounds import Band, PoleResidue, certified_band
from ..frequency._frf import resonance_grid
from ..model._items import Process
from ..process._cutting import Feedback, feedback
from ..structure._assembly import FrozenSystem
from ..structure._complex import modal_response
from ._boundary import Ops, link, make_ops, nu, refine_folds, static_width, widths_rank1

__all__ = ["Lobe", "LobeDiagram", "Boundary", "Plant", "lobes", "boundary"]


@dataclass(frozen=True, eq=False)
class Lobe:
    """One lobe: the boundary for one integer k (and one solution branch)."""

    k: int
    branch: int
    delay: np.ndarray  #: s
    speed: np.ndarray  #: in the process unit (m/s or rpm)
    width: np.ndarray  #: b_lim, m
    frequency_hz: np.ndarray  #: chatter frequency, Hz


@dataclass(frozen=True, eq=False)
class LobeDiagram:
    """Result of :func:`lobes`: b_lim against speed.

    Attributes
    ----------
    speed : ndarray, shape (n,)
        The requested speeds, in ``speed_unit`` (shaping: m/s; turning: rpm;
        delay: s).
    delay : ndarray, shape (n,)
        The delay T (s) at each speed.
    b_lim : ndarray, shape (n,)
        Largest chatter-free width of cut (m) at each speed; ``inf`` where no
        boundary lies below ``width_max``.
    chatter_hz : ndarray, shape (n,)
        Chatter frequency (Hz) on the envelope.
    lobe : ndarray of int, shape (n,)
        The lobe number k forming the envelope (-1 where none).
    lobes : tuple of Lobe
        Every lobe in the speed range (curves sampled on the frequency grid).
    minimum : dict
        The smallest b_lim over the speed range: ``width`` (m), ``speed``,
        ``chatter_hz``.
    absolute_minimum : dict
        The smallest boundary width over all delays: ``width`` (m),
        ``chatter_hz`` (the asymptote the lobes approach at low speed).
    checks : tuple of dict
        Argument-principle counts of right-half-plane roots just below and
        above the envelope and at the width ceiling where the diagram says
        ``inf`` (see ``verify``); ``verified`` says whether all agree.
    band_hz : (float, float)
        The chatter-frequency band searched, Hz.
    band_certified : bool
        True when the loop-gain bound proves that no boundary point below
        ``width_max`` lies outside ``band_hz``; otherwise an ``inf`` only
        means "no chatter found in the band searched".
    band_note : str
        Why the band is (or is not) complete.
    folds : int
        Folds of the boundary curve located and followed.
    band_measured : bool
        The structure is a measured FRF and ``band_hz`` its measured band:
        outside it nothing is known, so an ``inf`` is "undetermined" and a
        finite b_lim is the boundary within the band only (claims 2 and 4).
    n_lobes : int
        Lobes crossing the speed range; when they are denser than 400 per
        branch, ``lobes`` keeps only those that form the envelope at the
        requested speeds.
    """

    speed: np.ndarray
    delay: np.ndarray
    b_lim: np.ndarray
    chatter_hz: np.ndarray
    lobe: np.ndarray
    lobes: tuple[Lobe, ...]
    minimum: dict[str, float]
    absolute_minimum: dict[str, float]
    speed_unit: str
    speed_name: str
    width_max: float
    terms: Literal["pdo", "o"]
    position: float | None
    model: str
    checks: tuple[dict[str, Any], ...] = ()
    elapsed: float = 0.0
    n_frequencies: int = 0
    meta: dict[str, Any] = field(default_factory=dict)
    band_hz: tuple[float, float] = (float("nan"), float("nan"))
    band_certified: bool = False
    band_note: str = ""
    folds: int = 0
    n_lobes: int = 0
    band_measured: bool = False

    @property
    def verified(self) -> bool | None:
        """True if every check agreed with the diagram, None if none ran."""
        if not self.checks:
            return None
        return all(c["agrees"] for c in self.checks)

    def summary(self) -> str:
        m, a = self.minimum, self.absolute_minimum
        lines = [
            f"stability lobes of {self.model} ({self.terms} feedback"
            + (f", position {self.position:g} m" if self.position is not None else "")
            + ")",
            f"  speeds {self.speed.min():g} .. {self.speed.max():g} {self.speed_unit} ({self.speed.size} points),"
            f" {self.n_lobes} lobes"
            + (
                f" ({len(self.lobes)} of them on the envelope kept as curves)"
                if self.n_lobes > len(self.lobes)
                else ""
            )
            + f", {self.n_frequencies} chatter frequencies, {self.elapsed:.2f} s",
        ]
        if np.isfinite(m["width"]):
            lines.append(
                f"  minimum b_lim in range: {m['width'] * 1e3:.4g} mm at {m['speed']:.5g} {self.speed_unit},"
                f" chatter {m['chatter_hz']:.2f} Hz"
                + (" (from the measured band; chatter outside it is unknown)" if self.band_measured else "")
            )
        elif self.band_certified:
            lines.append(f"  no chatter below {self.width_max * 1e3:g} mm in this speed range")
        else:
            lines.append(
                f"  no chatter found below {self.width_max * 1e3:g} mm in the band searched:"
                " stability outside it is undetermined"
            )
        lo, hi = self.band_hz
        lines.append(
            f"  chatter band searched {lo:.4g} .. {hi:.4g} Hz"
            + (
                " (complete: the loop gain is below 1 outside it)"
                if self.band_certified
                else f" ({self.band_note})"
            )
        )
        if np.isfinite(a["width"]):
            lines.append(
                f"  absolute minimum (all speeds): {a['width'] * 1e3:.4g} mm at {a['chatter_hz']:.2f} Hz"
            )
        if self.checks:
            ok = sum(c["agrees"] for c in self.checks)
            what = {
                "below": "just below the envelope",
                "above": "just above it",
                "ceiling": "inf at the ceiling",
            }
            kinds = ", ".join(
                what[k] for k in ("below", "above", "ceiling") if any(c["kind"] == k for c in self.checks)
            )
            lines.append(
                f"  verified by the argument principle: {ok}/{len(self.checks)} checks agree ({kinds})"
            )
            for c in self.checks:
                if not c["agrees"]:
                    lines.append(
                        f"  CHECK FAILED at {c['speed']:.6g} {self.speed_unit}, width {c['width'] * 1e3:.6g} mm:"
                        f" expected {c['expected']}, the argument principle says {c['verdict']}"
                        f" ({c['rhp_roots']} right-half-plane roots)"
                    )
        else:
            lines.append("  not verified (verify=0 or a plant without matrices)")
        return "\n".join(lines)

    #: meaning of :attr:`claim` codes
    CLAIMS = (
        "boundary",
        "stable below width_max (band proven)",
        "undetermined (band not proven)",
        "contradicted by a check",
        "boundary in the measured band (outside it unknown)",
    )

    @property
    def claim(self) -> np.ndarray:
        """What the diagram claims at each speed, as an index into
        :attr:`CLAIMS`: 0 a boundary at b_lim, 1 no boundary below
        ``width_max`` in a proven band, 2 no boundary found in a band that is
        not proven complete, 3 a check at this speed disagrees, 4 a boundary
        within a measured band (a lower one at a chatter frequency outside
        the band is not excluded)."""
        code = np.where(
            np.isfinite(self.b_lim), 4 if self.band_measured else 0, 1 if self.band_certified else 2
        )
        for c in self.checks:
            if not c["agrees"]:
                code[np.nonzero(self.speed == c["speed"])[0]] = 3
        return code

    def to_csv(self, path: Any) -> None:
        """Envelope: speed, delay (s), b_lim (m), chatter frequency (Hz), lobe
        number and the claim's status (see :attr:`claim`) -- SI like every
        chatterlab result file."""
        import csv

        from ..io._files import text_out

        with text_out(path) as fh:
            w = csv.writer(fh)
            w.writerow(
                [
                    f"speed [{self.speed_unit}]",
                    "delay [s]",
                    "b_lim [m]",
                    "chatter frequency [Hz]",
                    "lobe [-]",
                    "status",
                ]
            )
            claim = self.claim
            for k in range(self.speed.size):
                w.writerow(
                    [
                        f"{self.speed[k]:.9g}",
                        f"{self.delay[k]:.9g}",
                        f"{self.b_lim[k]:.9g}",
                        f"{self.chatter_hz[k]:.9g}",
                        int(self.lobe[k]),
                        self.CLAIMS[int(claim[k])],
                    ]
                )

    def to_xarray(self, attrs: dict[str, Any] | None = None) -> Any:
        """The diagram as an :class:`xarray.Dataset`: speed as coordinate;
        b_lim in m, chatter frequency in Hz, delay in s, lobe number and the
        claim code as data; summary numbers and checks as attributes."""
        from ..io import make_dataset

        a = {
            "title": "chatterlab stability lobe diagram",
            "model": self.model,
            "terms": self.terms,
            "position_m": float("nan") if self.position is None else self.position,
            "width_max_m": self.width_max,
            "min_b_lim_m": self.minimum["width"],
            "min_b_lim_speed": self.minimum["speed"],
            "min_b_lim_chatter_hz": self.minimum["chatter_hz"],
            "absolute_min_b_lim_m": self.absolute_minimum["width"],
            "verified": str(self.verified),
            "chatter_band_hz": list(self.band_hz),
            "chatter_band_certified": str(self.band_certified),
            "chatter_band_note": self.band_note,
            "chatter_band_measured": str(self.band_measured),
            "checks": json.dumps(list(self.checks)),
        }
        a.update(self.meta)
        a.update(attrs or {})
        return make_dataset(
            coords={"speed": (self.speed, self.speed_unit)},
            data={
                "b_lim": (self.b_lim, "m", "largest chatter-free width of cut"),
                "chatter_frequency": (self.chatter_hz, "Hz", "chatter frequency on the envelope"),
                "delay": (self.delay, "s", "delay between passes"),
                "lobe": (self.lobe.astype(float), "1", "lobe number k"),
                "claim": (
                    self.claim.astype(float),
                    "1",
                    "status: " + ", ".join(f"{i} {t}" for i, t in enumerate(self.CLAIMS)),
                ),
            },
            attrs=a,
        )

    def to_netcdf(self, path: str, attrs: dict[str, Any] | None = None) -> None:
        """Labelled netCDF-4 file of :meth:`to_xarray` (the model text as
        an attribute when the caller passes it), written atomically."""
        from ..io import write_dataset

        write_dataset(path, self.to_xarray(attrs))

    def plot(
        self, ax: Any = None, *, lobe_numbers: int = 8, title: str | None = None, axes: Any = None
    ) -> Any:
        """Lobe diagram (b_lim in mm against speed, unstable region shaded,
        lobe numbers) over the chatter frequency panel; returns the Axes
        (``axes=`` is a deprecated alias of ``ax=``)."""
        from ..plot import plot_lobes

        return plot_lobes(self, ax=ax, axes=axes, lobe_numbers=lobe_numbers, title=title)


# ============================================================================ inner solve


class Plant:
    """What the boundary needs of the structure: the FRF H(jw) between the
    coupling-element coordinates (forces on point a in CE axes -> relative
    displacements dw, m/N), its poles (to place the frequency grid), the CE
    matrices at width b = 1 m (so that beta is the width in m), and, when
    known, its pole-residue form (which proves the searched band complete).

    Built from a frozen RDFEM system (:meth:`from_frozen`), from a
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

    @classmethod
    def from_frozen(cls, frozen: FrozenSystem, fb_ref: Feedback) -> Plant:
        cm = frozen.complex_modes
        keep = np.arange(cm.lam.size)

        def H(omega: np.ndarray) -> np.ndarray:
            G = modal_response(cm, fb_ref.J, fb_ref.J.T, 1j * np.asarray(omega, float), keep, False)
            return np.transpose(G, (2, 0, 1))

        Jphi = fb_ref.J @ cm.phi
        m = fb_ref.J.shape[0]
        pr = PoleResidue(cm.lam, Jphi, Jphi.T, np.zeros((m, m)))
        return cls(H, cm.lam, fb_ref.Dl_P, fb_ref.Dl_V, fb_ref.Dl_O, pr)

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


_Ops = Ops


def _ops(plant: Plant, omega: np.ndarray) -> Ops:
    return make_ops(plant.H, plant.Dl_P, plant.Dl_V, plant.Dl_O, omega)


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
    xs, _ = widths_rank1(ops, hi)
    fi = np.concatenate([np.full(x.size, i) for i, x in enumerate(xs)]).astype(int)
    beta = np.concatenate(xs) * hi[fi] if fi.size else np.zeros(0)
    keep = beta >= lo[fi]
    fi, beta = fi[keep], beta[keep]
    return fi, beta, _z_at(ops, beta, fi)


def _z_at(ops: Ops, beta: np.ndarray, freq: np.ndarray) -> np.ndarray:
    """z = -1/nu for the eigenvalue of N(beta) nearest the unit circle."""
    v = _nu(ops, beta[:, None], freq)[:, 0, :]
    j = np.argmin(np.abs(np.log(np.abs(v))), axis=1)
    return -1.0 / v[np.arange(beta.size), j]


# ============================================================================ boundary curve


@dataclass(frozen=True)
class _Segment:
    branch: int
    omega: np.ndarray
    beta: np.ndarray
    z: np.ndarray
    idx: np.ndarray  # frequency indices into the grid


def boundary(plant: Plant, omega: np.ndarray, beta_max: float) -> tuple[Ops, list[_Segment], int]:
    """Every boundary solution (beta, z) on a frequency grid (refined at the
    folds of the curve), organised into continuous branches that follow the
    curve around its folds.  Returns the operators on the final grid, the
    branches and the number of folds located."""

    def make(w: np.ndarray) -> Ops:
        return _ops(plant, w)

    w, xs, folds = refine_folds(make, omega, beta_max)
    ops = make(w)
    segs: list[_Segment] = []
    chains = link(xs)
    for j, ch in enumerate(chains):
        if len(ch) < 2:
            continue
        fi = np.array([c[0] for c in ch])
        beta = np.array([xs[f][k] for f, k in ch]) * beta_max
        z = _z_at(ops, beta, fi)
        segs.append(_Segment(j, w[fi], beta, z, fi))
    return ops, segs, folds


def _refine_crossings(
    plant: Plant,
    T: np.ndarray,
    k: np.ndarray,
    w0: np.ndarray,
    w1: np.ndarray,
    h0: np.ndarray,
    h1: np.ndarray,
    b0: np.ndarray,
    b1: np.ndarray,
    psi0: np.ndarray,
    psi1: np.ndarray,
    iters: int = 60,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Solve h(w) = w T - psi(w) - 2 pi k = 0 in [w0, w1] by regula falsi
    (Illinois), with beta and psi = -arg z re-solved exactly near the branch
    at each trial frequency.  ``h0``, ``h1`` are the (exact) end values."""
    blo = np.minimum(b0, b1) / 1.5
    bhi = np.maximum(b0, b1) * 1.5
    wa, wb, ha, hb = w0.copy(), w1.copy(), h0.copy(), h1.copy()
    beta = np.where(h1 != h0, b0 + (b1 - b0) * h0 / (h0 - h1), 0.5 * (b0 + b1))
    w = np.where(h1 != h0, w0 - h0 * (w1 - w0) / (h1 - h0), 0.5 * (w0 + w1))
    ok = np.ones(T.size, bool)
    active = np.ones(T.size, bool)
    last = np.zeros(T.size)
    for _ in range(iters):
        idx = np.nonzero(active)[0]
        if idx.size == 0:
            break
        wa_, wb_, ha_, hb_ = wa[idx], wb[idx], ha[idx], hb[idx]
        wt = np.where(hb_ != ha_, wb_ - hb_ * (wb_ - wa_) / (hb_ - ha_), 0.5 * (wa_ + wb_))
        wt = np.clip(wt, np.minimum(wa_, wb_), np.maximum(wa_, wb_))
        ops = _ops(plant, wt)
        fi, bb, zz = _widths_between(ops, blo[idx], bhi[idx])
        frac = (wt - w0[idx]) / np.where(w1[idx] != w0[idx], w1[idx] - w0[idx], 1.0)
        target = b0[idx] + (b1[idx] - b0[idx]) * frac
        psi_guess = psi0[idx] + (psi1[idx] - psi0[idx]) * frac
        best_b = np.full(idx.size, np.nan)
        best_z = np.full(idx.size, np.nan + 0j)
        dist = np.abs(np.log(bb / target[fi]))
        ordr = np.argsort(-dist)  # later writes (smaller distance) win
        best_b[fi[ordr]] = bb[ordr]
        best_z[fi[ordr]] = zz[ordr]
        good = np.isfinite(best_b)
        ok[idx[~good]] = False
        active[idx[~good]] = False
        psi = -np.angle(best_z)
        psi = psi + 2 * np.pi * np.round((psi_guess - psi) / (2 * np.pi))
        ht = wt * T[idx] - psi - 2 * np.pi * k[idx]
        w[idx] = np.where(good, wt, w[idx])
        beta[idx] = np.where(good, best_b, beta[idx])
        same = np.sign(ht) == np.sign(ha_)
        lst = last[idx]
        new_wa = np.where(same, wt, wa_)
        new_ha = np.where(same, ht, np.where(lst == -1, 0.5 * ha_, ha_))
        new_wb = np.where(same, wb_, wt)
        new_hb = np.where(same, np.where(lst == 1, 0.5 * hb_, hb_), ht)
        last[idx] = np.where(same, 1, -1)
        wa[idx], ha[idx], wb[idx], hb[idx] = new_wa, new_ha, new_wb, new_hb
        done = (np.abs(wb[idx] - wa[idx]) <= 1e-14 * np.abs(wt)) | (ht == 0)
        active[idx[done & good]] = False
    return w, beta, ok


def _refine_rows(plant: Plant, T: np.ndarray, info: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_refine_crossings` on candidate rows (k, w0, w1, h0, h1, b0, b1, psi0, psi1)."""
    k, w0, w1, h0, h1, b0, b1, psi0, psi1 = info.T
    return _refine_crossings(plant, T, k, w0, w1, h0, h1, b0, b1, psi0, psi1)


def _grid(plant: Plant, lo: float, hi: float, n_base: int) -> np.ndarray:
    """Frequency grid on [lo, hi] (rad/s): logarithmic below a quarter of the
    first natural frequency, uniform above, plus clusters that resolve every
    resonance.  A measured plant: its measured frequencies in [lo, hi] and
    ``n_base`` uniform points between them (spline-interpolated FRF)."""
    if plant.grid is not None:
        w = np.unique(np.concatenate([plant.grid, np.linspace(lo, hi, n_base)]))
        return w[(w >= lo) & (w <= hi)]
    w1 = _first_mode(plant)
    parts = [resonance_grid(plant.poles, max(lo, min(0.25 * w1, hi)), hi, n_base)]
    if lo < 0.25 * w1:
        parts.append(np.geomspace(max(lo, 1e-4 * w1), min(0.25 * w1, hi), 80))
    if lo == 0.0:
        parts.append(np.zeros(1))  # w = 0 itself: the grid reaches the static case
    w = np.unique(np.concatenate(parts))
    return w[(w >= lo) & (w <= hi)]


def _first_mode(plant: Plant) -> float:
    wn = np.abs(plant.poles[plant.poles.imag > 0])
    return float(wn.min()) if wn.size else 1.0


def _band(plant: Plant, fmin: float | None, fmax: float | None, width_max: float) -> Band:
    """The chatter-frequency band searched (rad/s) and whether it is proven
    to hold every boundary point below ``width_max``.  A band given by the
    caller (either end) is searched as given and proves nothing outside it.
    A measured plant's band is the measured one (or the part of it between
    fmin and fmax), never certified."""
    if plant.measured_band is not None:
        return _measured_search_band(plant.measured_band, fmin, fmax)
    if fmin is None or fmax is None:
        auto = _auto_band(plant, width_max)
        if fmin is None and fmax is None:
            return auto
    lo = 2 * np.pi * fmin if fmin is not None else auto.lo
    hi = 2 * np.pi * fmax if fmax is not None else auto.hi
    if not hi > lo >= 0:
        raise InputError(
            f"the chatter frequency band is empty: fmin {lo / 2 / np.pi:g} Hz, fmax {hi / 2 / np.pi:g} Hz"
        )
    return Band(lo, hi, False, "band given by the caller (fmin/fmax): outside it nothing is claimed")


def _measured_search_band(mb: Band, fmin: float | None, fmax: float | None) -> Band:
    lo = mb.lo if fmin is None else 2 * np.pi * fmin
    hi = mb.hi if fmax is None else 2 * np.pi * fmax
    tol = 1e-12 * mb.hi
    if lo < mb.lo - tol or hi > mb.hi + tol:
        raise InputError(
            f"the chatter band {lo / 2 / np.pi:g} .. {hi / 2 / np.pi:g} Hz reaches outside the measured band"
            f" {mb.lo / 2 / np.pi:g} .. {mb.hi / 2 / np.pi:g} Hz; a measured FRF is not extrapolated: keep fmin/fmax inside it"
        )
    if not hi > lo:
        raise InputError(
            f"the chatter frequency band is empty: fmin {lo / 2 / np.pi:g} Hz, fmax {hi / 2 / np.pi:g} Hz"
        )
    return Band(max(lo, mb.lo), min(hi, mb.hi), False, mb.reason)


def _auto_band(plant: Plant, width_max: float) -> Band:
    """[0, hi] with hi from the gain bound when the structure has a pole-residue
    form and no pole at s = 0 (the grid then reaches w = 0 itself, where the
    loop gain bound of a stiff cut is usually above 1); otherwise a band from
    the modes, not proven."""
    w1 = _first_mode(plant)
    pmax = float(np.max(np.abs(plant.poles))) if plant.poles.size else 1.0
    rigid = plant.poles.size and float(np.min(np.abs(plant.poles))) <= 1e-9 * pmax
    if plant.residues is None or rigid:
        wn = np.sort(np.abs(plant.poles[plant.poles.imag > 0]))
        wk = float(wn[min(len(wn) - 1, 11)]) if wn.size else 10.0
        why = "a pole at s = 0 (rigid-body mode)" if rigid else "no pole-residue form of the structure"
        return Band(1e-3 * w1, 1.6 * wk, False, f"{why}: band from the modes, not proven")
    bd = certified_band(plant.residues, plant.Dl_P, plant.Dl_V, plant.Dl_O, width_max, 1e-3 * w1)
    return Band(0.0, max(bd.hi * 1.02, bd.lo), bd.certified, bd.reason)


@dataclass(frozen=True)
class _Candidates:
    """Integer crossings of F = (w T - psi) / 2 pi on each interval of a branch
    (rows: delays, columns: intervals)."""

    sg: _Segment
    psi: np.ndarray
    kc: np.ndarray
    Fa: np.ndarray
    Fb: np.ndarray
    has: np.ndarray
    bc: np.ndarray  # interpolated width of the lowest crossing (inf: none)
    lb: np.ndarray  # smaller end width: a lower bound of any crossing

    def info(self, ri: np.ndarray, ji: np.ndarray) -> np.ndarray:
        """Rows k, w0, w1, h0, h1, b0, b1, psi0, psi1 for :func:`_refine_crossings`."""
        sg, kk = self.sg, self.kc[ri, ji]
        return np.stack(
            [
                kk,
                sg.omega[ji],
                sg.omega[ji + 1],
                2 * np.pi * (self.Fa[ri, ji] - kk),
                2 * np.pi * (self.Fb[ri, ji] - kk),
                sg.beta[ji],
                sg.beta[ji + 1],
                self.psi[ji],
                self.psi[ji + 1],
            ],
            axis=1,
        )


def _interval_candidates(sg: _Segment, T: np.ndarray) -> _Candidates:
    psi = -np.unwrap(np.angle(sg.z))
    F = (sg.omega[None, :] * T[:, None] - psi[None, :]) / (2 * np.pi)  # (nT, L)
    Fa, Fb = F[:, :-1], F[:, 1:]
    ba, bb = sg.beta[:-1], sg.beta[1:]
    lo_end_is_a = (ba <= bb)[None, :]
    inc = Fb >= Fa
    Flo, Fhi = np.minimum(Fa, Fb), np.maximum(Fa, Fb)
    k_lo = np.floor(Flo) + 1.0  # smallest integer in (Flo, Fhi]
    k_hi = np.floor(Fhi)
    kc = np.where(lo_end_is_a, np.where(inc, k_lo, k_hi), np.where(inc, k_hi, k_lo))
    has = k_hi >= k_lo
    den = np.where(Fb != Fa, Fb - Fa, 1.0)
    t = np.clip((kc - Fa) / den, 0.0, 1.0)
    bc = np.where(has, ba[None, :] + t * (bb - ba)[None, :], np.inf)
    lb = np.broadcast_to(np.minimum(ba, bb)[None, :], bc.shape)
    return _Candidates(sg, psi, kc, Fa, Fb, has, bc, lb)


def _check_damped(plant: Plant, frozen: FrozenSystem | None) -> None:
    """A structural pole on (or right of) the imaginary axis: the structure
    alone is not asymptotically stable, its receptance is infinite on the
    axis, and no width is chatter-free with certainty -- refuse, naming the
    mode, instead of failing inside the boundary solver."""
    lam = plant.poles
    if lam.size == 0:
        return
    bad = lam.real >= -1e-12 * np.maximum(np.abs(lam), 1.0)
    if np.any(bad):
        k = int(np.argmax(bad))
        src = frozen.model.source if frozen is not None else "the plant"
        raise InputError(
            f"{src}: the structure has an undamped or unstable mode at {abs(lam[k].imag) / (2 * np.pi):.6g} Hz"
            f" (pole {lam[k]:.6g} 1/s): stability lobes need every mode damped; add damping (a spring's d,"
            " a beam's eta, a mode's damping_ratio > 0) or hold the free coordinate"
        )


def _check_terms(terms: str) -> None:
    if terms not in ("pdo", "o"):
        raise InputError("terms must be 'pdo' or 'o': lobes need the delayed (regenerative) term")


class Boundary:
    """The stability boundary of one frozen configuration, computed once on a
    frequency grid and evaluated at any delays (:meth:`envelope`).

    Used by :func:`lobes` and, cached per slide position, by the stability
    atlas sweep.

    Attributes
    ----------
    band : Band
        The chatter-frequency band searched (rad/s) and its certificate: with
        ``band.certified`` no boundary point with width <= ``width_max``
        exists outside it (gain bound, :mod:`chatterlab.frequency._bounds`).
    folds : int
        Folds of the boundary curve located (and followed) on the grid.
    static_width : float
        Smallest width (m) with a root at s = 0, for every delay (inf: none).
    """

    def __init__(
        self,
        frozen: FrozenSystem | None,
        *,
        width_max: float,
        terms: Literal["pdo", "o"] = "pdo",
        fmin: float | None = None,
        fmax: float | None = None,
        n_base: int | None = None,
        couplings: list[str] | None = None,
        plant: Plant | None = None,
    ) -> None:
        _check_terms(terms)
        self.frozen = frozen
        self.width_max = check_width(width_max, "width_max")
        if plant is None:
            if frozen is None:
                raise InputError("give a frozen system or a plant")
            # feedback at b = 1 m: beta is the width in m
            fb_ref = feedback(frozen, width=1.0, delay=1.0, terms=terms, couplings=couplings)
            plant = Plant.from_frozen(frozen, fb_ref)
        elif terms == "o":
            plant = plant.with_terms_o()
        self.plant = plant
        if not np.any(plant.Dl_O):
            raise InputError("the coupling elements have no delayed term (DO = 0): there are no lobes")
        _check_damped(plant, frozen)
        self.band = _band(plant, fmin, fmax, self.width_max)
        if self.band.hi > self.band.lo:
            self.omega = _grid(plant, self.band.lo, self.band.hi, n_base or 2000)
            self.ops, self.segments, self.folds = boundary(plant, self.omega, self.width_max)
        else:  # the gain bound excludes every frequency
            self.omega = np.zeros(0)
            self.ops, self.segments, self.folds = _ops(plant, self.omega), [], 0
        with np.errstate(all="ignore"):
            H0 = plant.H(np.array([0.0]))[0]
        self.static_width = static_width(H0, plant.Dl_P, plant.Dl_O, self.width_max)

    def envelope(self, T: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """b_lim (m), chatter frequency (Hz) and lobe number at delays T (s).

        On each grid interval of each branch, F(w) = (w T - psi(w)) / 2 pi
        crosses the integers k between its end values; with beta monotone on
        the interval (folds are grid points) the lowest crossing is the integer
        nearest the lower-beta end, and its width is at least the smaller end
        value.  The best interpolated candidate is refined first; then every
        other interval whose smaller end lies below that refined width is
        refined too, so a crossing whose linear interpolation was poor cannot
        be lost."""
        plant = self.plant
        T = np.atleast_1d(np.asarray(T, dtype=float))
        nT = T.size
        cand = [_interval_candidates(sg, T) for sg in self.segments]
        best = np.full(nT, np.inf)
        info = np.zeros((nT, 9))  # k, w0, w1, h0, h1, b0, b1, psi0, psi1
        r = np.arange(nT)
        for c in cand:
            j = np.argmin(c.bc, axis=1)
            bmin = c.bc[r, j]
            upd = bmin < best
            if np.any(upd):
                best[upd] = bmin[upd]
                info[upd] = c.info(r[upd], j[upd])
        b_lim = np.full(nT, np.inf)
        chatter = np.full(nT, np.nan)
        h = np.nonzero(np.isfinite(best))[0]
        if h.size:
            w, beta, ok = _refine_rows(plant, T[h], info[h])
            b_lim[h] = np.where(ok, beta, best[h])
            chatter[h] = w / (2 * np.pi)
            # second pass: every interval that could hold a lower crossing
            rows, infos = [], []
            for c in cand:
                ri, ji = np.nonzero(c.has & (c.lb < b_lim[:, None] * (1 - 1e-12)))
                if ri.size:
                    rows.append(ri)
                    infos.append(c.info(ri, ji))
            if rows:
                ri = np.concatenate(rows)
                inf_ = np.concatenate(infos)
                w2, beta2, ok2 = _refine_rows(plant, T[ri], inf_)
                for i in np.nonzero(ok2)[0]:
                    if beta2[i] < b_lim[ri[i]]:
                        b_lim[ri[i]], chatter[ri[i]] = beta2[i], w2[i] / (2 * np.pi)
        lobe_k = np.where(
            np.isfinite(b_lim), np.floor(2 * np.pi * np.nan_to_num(chatter) * T / (2 * np.pi)), -1
        )
        lobe_k = lobe_k.astype(int)
        if np.isfinite(self.static_width):
            # a root through s = 0 bounds every delay at the same width
            st = self.static_width < b_lim
            b_lim[st], chatter[st], lobe_k[st] = self.static_width, 0.0, 0
        return b_lim, chatter, lobe_k

    def absolute_minimum(self) -> dict[str, float]:
        """Smallest boundary width over all delays: ``width`` (m), ``chatter_hz``."""
        return _absolute_minimum(self.plant, self.segments, 1.0)


def lobes(
    frozen: FrozenSystem | None,
    speeds: np.ndarray,
    *,
    width_max: float = 0.02,
    terms: Literal["pdo", "o"] = "pdo",
    process: Process | None = None,
    fmin: float | None = None,
    fmax: float | None = None,
    n_frequencies: int | None = None,
    verify: int = 16,
    couplings: list[str] | None = None,
    plant: Plant | None = None,
    name: str | None = None,
) -> LobeDiagram:
    """Stability lobe diagram b_lim(speed) at a frozen configuration.

    Parameters
    ----------
    frozen : FrozenSystem
        The structure with the slide held at a position (``system.at(s)``).
    speeds : array, shape (n,)
        Cutting speeds in the process's unit (shaping: work speed m/s;
        turning: rpm; ``process.kind == "delay"``: the delay in s).
    width_max : float
        Largest width of cut considered, m; b_lim = inf above it.
    terms : {"pdo", "o"}
        All feedback terms (the paper's case c) or the delayed term only.
    process : Process, optional
        Kinematics mapping speed to delay (default: the model's ``[process]``).
    fmin, fmax : float, optional
        Chatter frequency band searched, Hz (default: from the modes).
    n_frequencies : int, optional
        Size of the uniform part of the frequency grid (default 2000); every
        resonance in the band adds a cluster of points that resolves it.
    verify : int
        How many envelope claims are checked by the argument principle
        (0 to skip; not available with a ``plant``): the global minimum just
        below and above the envelope, the ``verify - 1`` highest cusps and
        ``verify // 2`` lobe bottoms just below it (relative offset
        ``VERIFY_OFFSET``), and every run of ``inf`` at the width ceiling.
    plant : Plant, optional
        A structure given by its FRF instead of a model (e.g. a python-control
        LTI system, :func:`chatterlab.lobes._control.lti_plant`); ``frozen`` is then
        None and ``process`` must be given.
    name : str, optional
        Label of the structure in the result (default: the model file).

    Returns
    -------
    LobeDiagram
    """
    t0 = time.perf_counter()
    proc = process if process is not None else (frozen.model.process if frozen is not None else None)
    if proc is None:
        src = frozen.model.source if frozen is not None else "the plant"
        raise InputError(
            f"{src} has no [process] table: add one (shaping, turning or delay), or pass process=, so that"
            " speeds map to delays"
        )
    speeds = np.asarray(speeds, dtype=float)
    if speeds.ndim != 1 or speeds.size == 0:
        raise InputError("speeds must be a non-empty 1-D array")
    for v in (
        (speeds.min(), speeds.max()) if np.all(np.isfinite(speeds)) else speeds[~np.isfinite(speeds)][:1]
    ):
        check_speed(v, "speeds", proc.speed_unit)
    width_max = check_width(width_max, "width_max")
    _check_terms(terms)
    bd = Boundary(
        frozen,
        width_max=width_max,
        terms=terms,
        fmin=fmin,
        fmax=fmax,
        n_base=n_frequencies,
        couplings=couplings,
        plant=plant,
    )
    segs, n, b_ref = bd.segments, bd.ops.omega.size, 1.0
    T = np.asarray(proc.delay(speeds), dtype=float) if proc.kind != "delay" else speeds.copy()
    b_lim, chatter, lobe_k = bd.envelope(T)

    # every lobe in the range of delays, as curves on the frequency grid
    lobe_list: list[Lobe] = []
    Tlo, Thi = float(T.min()), float(T.max())
    n_in_range = 0
    for sg in segs:
        phi = np.mod(-np.angle(sg.z), 2 * np.pi)  # w T = phi + 2 pi k, phi in [0, 2 pi)
        kmin = max(int(np.floor((sg.omega * Tlo - phi).min() / (2 * np.pi))), 0)
        kmax = int(np.ceil((sg.omega * Thi - phi).max() / (2 * np.pi)))
        n_in_range += _lobes_crossing(sg.omega, phi, Tlo, Thi)
        if kmax - kmin > 400:  # a dense diagram: keep the lobes that form the envelope
            ks = np.unique(lobe_k[lobe_k >= 0])
            krange = ks if ks.size else np.arange(kmin, kmin + 50)
        else:
            krange = np.arange(kmin, kmax + 1)
        for k in krange:
            with np.errstate(divide="ignore", invalid="ignore"):  # w = 0: T = inf, outside
                Tk = (phi + 2 * np.pi * k) / sg.omega
            inside = (Tk >= Tlo) & (Tk <= Thi) & (Tk > proc.min_delay)
            if np.count_nonzero(inside) < 2:
                continue
            Ts = Tk[inside]
            lobe_list.append(
                Lobe(
                    int(k),
                    sg.branch,
                    Ts,
                    np.asarray(proc.speed_for_delay(Ts)) if proc.kind != "delay" else Ts,
                    sg.beta[inside] * b_ref,
                    sg.omega[inside] / (2 * np.pi),
                )
            )

    # minima
    if np.any(np.isfinite(b_lim)):
        j = int(np.nanargmin(b_lim))
        minimum = {"width": float(b_lim[j]), "speed": float(speeds[j]), "chatter_hz": float(chatter[j])}
    else:
        minimum = {"width": float("inf"), "speed": float("nan"), "chatter_hz": float("nan")}
    absolute = bd.absolute_minimum()

    diagram = LobeDiagram(
        speed=speeds,
        delay=T,
        b_lim=b_lim,
        chatter_hz=chatter,
        lobe=lobe_k,
        lobes=tuple(lobe_list),
        minimum=minimum,
        absolute_minimum=absolute,
        speed_unit=proc.speed_unit,
        speed_name=proc.speed_name,
        width_max=width_max,
        terms=terms,
        position=frozen.position if frozen is not None else None,
        model=name or (frozen.model.source if frozen is not None else "plant"),
        elapsed=0.0,
        n_frequencies=n,
        band_hz=(bd.band.lo / (2 * np.pi), bd.band.hi / (2 * np.pi)),
        band_certified=bd.band.certified,
        band_note=bd.band.reason,
        folds=bd.folds,
        n_lobes=n_in_range,
        band_measured=bd.plant.measured_band is not None,
    )
    checks = _verify(frozen, diagram, verify, couplings) if verify and frozen is not None else ()
    return replace(diagram, checks=checks, elapsed=time.perf_counter() - t0)


def _lobes_crossing(omega: np.ndarray, phi: np.ndarray, Tlo: float, Thi: float) -> int:
    """Number of lobes k of one branch that cross [Tlo, Thi]: the union over
    the branch's samples of the integers k with T_k = (phi + 2 pi k) / w in it."""
    ok = omega > 0
    lo = np.ceil((omega[ok] * Tlo - phi[ok]) / (2 * np.pi)).astype(np.int64)
    hi = np.floor((omega[ok] * Thi - phi[ok]) / (2 * np.pi)).astype(np.int64)
    lo = np.maximum(lo, 0)
    keep = hi >= lo
    if not np.any(keep):
        return 0
    order = np.argsort(lo[keep])
    a, b = lo[keep][order], hi[keep][order]
    reach = np.maximum.accumulate(b)
    starts = np.r_[True, a[1:] > reach[:-1] + 1]
    # merge overlapping intervals: each run from a start to the next start
    idx = np.nonzero(starts)[0]
    ends = np.r_[idx[1:] - 1, a.size - 1]
    return int(np.sum(reach[ends] - a[idx] + 1))


def _absolute_minimum(plant: Plant, segs: list[_Segment], b_ref: float) -> dict[str, float]:
    if not segs:
        return {"width": float("inf"), "chatter_hz": float("nan")}
    cand = [(float(sg.beta.min()), sg, int(np.argmin(sg.beta))) for sg in segs]
    bmin, sg, j = min(cand, key=lambda c: c[0])
    # bounded Brent refinement of min over w of beta(w) between the neighbouring samples
    if 0 < j < sg.omega.size - 1:
        from scipy.optimize import minimize_scalar

        def f(w: float) -> float:
            ops = _ops(plant, np.array([w]))
            _, bb, _ = _solve_beta(ops, np.array([bmin / 2]), np.array([bmin * 2]), n_grid=8)
            return float(bb.min()) if bb.size else np.inf

        a, c = sorted((float(sg.omega[j - 1]), float(sg.omega[j + 1])))
        if not c > a:
            return {"width": bmin * b_ref, "chatter_hz": float(sg.omega[j] / (2 * np.pi))}
        res = minimize_scalar(f, bounds=(a, c), method="bounded", options={"xatol": 1e-10 * c})
        if np.isfinite(res.fun) and res.fun <= bmin:
            return {"width": float(res.fun) * b_ref, "chatter_hz": float(res.x) / (2 * np.pi)}
    return {"width": bmin * b_ref, "chatter_hz": float(sg.omega[j] / (2 * np.pi))}


#: relative offset of the verification widths from the envelope
VERIFY_OFFSET = 1e-3


def _check_speeds(d: LobeDiagram, count: int) -> list[tuple[int, str]]:
    """Indices of the speeds checked and what is checked there.

    The global minimum (below and above the envelope), the highest local
    maxima of the sampled envelope (a lobe missed by the boundary search
    shows as a claim that is too high: the risk sits at the cusps between
    lobes), spread local minima (each a lobe's bottom), and the ends of every
    run of ``inf`` (checked at the width ceiling)."""
    b = d.b_lim
    fin = np.isfinite(b)
    out: list[tuple[int, str]] = []
    if np.any(fin):
        jmin = int(np.nanargmin(np.where(fin, b, np.nan)))
        out += [(jmin, "below"), (jmin, "above")]
        bb = np.where(fin, b, -np.inf)
        inner = np.arange(1, b.size - 1)
        peak = inner[(bb[inner] >= bb[inner - 1]) & (bb[inner] >= bb[inner + 1]) & fin[inner]]
        for j in ([0] if fin[0] else []) + ([b.size - 1] if fin[-1] else []):
            peak = np.append(peak, j)
        peak = peak[np.argsort(-b[peak])]
        out += [(int(j), "below") for j in peak[: max(count - 1, 0)] if int(j) != jmin]
        low = inner[(bb[inner] <= bb[inner - 1]) & (bb[inner] <= bb[inner + 1]) & fin[inner]]
        low = low[low != jmin]
        if low.size and count > 2:
            pick = low[np.linspace(0, low.size - 1, min(count // 2, low.size)).astype(int)]
            out += [(int(j), "below") for j in pick]
    inf = ~fin
    if np.any(inf):
        edges = np.nonzero(np.diff(np.r_[False, inf, False].astype(int)))[0]
        for a, e in zip(edges[::2], edges[1::2] - 1, strict=True):
            for j in {int(a), int(e), int((a + e) // 2)}:
                out.append((j, "ceiling"))
    return list(dict.fromkeys(out))


def _verify(
    frozen: FrozenSystem, d: LobeDiagram, count: int, couplings: list[str] | None
) -> tuple[dict[str, Any], ...]:
    """Check the diagram's claims by the argument principle, a route
    independent of the boundary computation: the number of closed-loop roots
    in the right half plane (:func:`chatterlab.frequency._winding.rhp_count_system`) is
    0 just below the envelope (b = (1 - VERIFY_OFFSET) b_lim) and > 0 just
    above it; where the diagram says ``inf``, 0 at the width ceiling."""
    from ..frequency._roots import make_system
    from ..frequency._winding import rhp_count_system

    out = []
    for j, kind in _check_speeds(d, count):
        if kind == "ceiling":
            b, expect = d.width_max, "stable"
        else:
            b = float(d.b_lim[j]) * (1 - VERIFY_OFFSET if kind == "below" else 1 + VERIFY_OFFSET)
            expect = "stable" if kind == "below" else "unstable"
        fb = feedback(frozen, width=b, delay=float(d.delay[j]), terms=d.terms, couplings=couplings)
        sys_ = make_system(frozen.A, frozen.B, frozen.C, DP=fb.DP, DV=fb.DV, DO=(fb.U, fb.V), tau=fb.delay)
        w = rhp_count_system(sys_)
        if w.status != "converged":
            verdict = "undetermined"
        else:
            verdict = "stable" if w.count == 0 else "unstable"
        out.append(
            {
                "speed": float(d.speed[j]),
                "delay": float(d.delay[j]),
                "width": b,
                "kind": kind,
                "expected": expect,
                "verdict": verdict,
                "rhp_roots": int(w.count),
                "agrees": verdict == expect,
            }
        )
    return tuple(out)
