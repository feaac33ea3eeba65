"""Poles of a measured receptance by the poly-reference least-squares
complex frequency-domain estimator (pLSCF) for every model order, their
stabilisation diagram, and the choice of the poles the fit keeps (step 1 of
the modal fit; the method and references are in the docstring of
:mod:`chatterlab.structure._fit`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import InputError
from ..io import Result

__all__ = ["Stabilisation", "lscf_poles"]

#: the status codes of the stabilisation diagram
NEW, STABLE_FREQUENCY, STABLE = 0, 1, 2


# ============================================================================ pLSCF


@dataclass(frozen=True, eq=False)
class Stabilisation(Result):
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

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """Every physical pole of every order (``pole``), with its order,
        natural frequency, damping ratio and stability code; the measured
        curve (``omega``, ``magnitude``) on its own dimension."""
        order = np.concatenate([np.full(len(p), o) for o, p in zip(self.orders, self.poles, strict=True)])
        lam = (
            np.concatenate([np.asarray(p, complex) for p in self.poles])
            if self.poles
            else np.zeros(0, complex)
        )
        code = np.concatenate([np.asarray(s, int) for s in self.status]) if self.status else np.zeros(0, int)
        wn = np.abs(lam)
        return (
            {"pole": (np.arange(lam.size), "1", "pole")},
            {
                "order": (order, "1", "model order p"),
                "frequency": (wn / (2 * np.pi), "Hz", "natural frequency |lambda| / 2 pi"),
                "damping_ratio": (-lam.real / np.where(wn > 0, wn, 1.0), "1", "damping ratio"),
                "status": (code, "1", "0 new, 1 stable in frequency, 2 stable in frequency and damping"),
                "omega": (np.asarray(self.omega, float), "rad/s", "measured frequencies", ("frequency",)),
                "magnitude": (np.asarray(self.magnitude, float), "m/N", "sum of |H| over the entries",
                              ("frequency",)),
            },
            {"title": "chatterlab stabilisation diagram", "tol_frequency": self.tol_frequency,
             "tol_damping": self.tol_damping},
        )  # fmt: skip

    def to_csv(self, path: Any) -> Any:
        """The poles as CSV (``pole [1]``, ``order``, ``frequency``,
        ``damping_ratio``, ``status``); returns the path."""
        from ..io import write_csv

        coords, data, _ = self.dataset_parts()
        return write_csv(path, coords, {k: v for k, v in data.items() if len(v) == 3})

    def plot(self, ax: Any = None, **style: Any) -> Any:
        """The stabilisation diagram (order against frequency in Hz) over the
        measured magnitude (:func:`chatterlab.plot.plot_stabilisation`);
        returns the Axes.  Imports matplotlib."""
        from ..plot import plot_stabilisation

        return plot_stabilisation(self, ax=ax, codes=(NEW, STABLE_FREQUENCY, STABLE))


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
    """pLSCF poles for every order 1..max_order (see :mod:`chatterlab.structure._fit`)
    of the receptance ``H`` (n_freq, n_out, n_in), one matrix per frequency
    (``FRF.matrices``).

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
