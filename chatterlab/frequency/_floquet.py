"""Floquet multipliers of milling: a structure under the periodic,
regenerative cutting force of a :class:`~chatterlab.process.Milling` cutter.

The equation (tool point r = J q relative to the workpiece, Eq. 1 of
:mod:`chatterlab.process._milling`)

    M q'' + C q' + K q = -a_p J^T sum_j H_j(t) J [q(t) - q(t - tau_j)]      (1)

has coefficients periodic in T (:meth:`Milling.period`).  With the state
x = (q, q'), one period maps the history on [-T, 0] to the one on [0, T]; the
eigenvalues mu of this monodromy operator are the Floquet multipliers, and
(1) is asymptotically stable iff every |mu| < 1.  A multiplier leaving the
unit circle as a complex pair is a secondary Hopf (quasi-periodic chatter),
at mu = -1 a flip (period doubling), at mu = +1 a fold.

Two discretisations of the operator, each with an explicit accuracy knob:

``"spectral"`` (the reference).  Spectral-element collocation (Butcher et al.
2004; Lehotzky, Insperger & Stepan 2016): the period is cut at the
breakpoints where a tooth enters or leaves the cut, so the coefficients are
analytic on each piece; every piece where a tooth cuts is split into
``elements`` sub-elements carrying Chebyshev-Lobatto collocation of
``degree`` p, and where no tooth cuts the motion is free and solved exactly,
x(t) = e^{A t} x(0).  The delayed argument t - tau_j of a node in tooth j's
cut falls in tooth j-1's cut at the same angle: at a node of the same
sub-element for a uniform pitch, by spectral interpolation otherwise.
For a variable pitch the mesh also has the breakpoints shifted by each
delay (where the solution's fourth derivative jumps), so a delayed image
never straddles a jump of x''.  Unknowns and equations are scaled
(velocities in units of the highest pole frequency), which keeps U well
conditioned without changing the multipliers.  The error falls faster than
any power of p (geometrically); the result reports the change of the
critical multiplier when the degree is raised by ``CHECK_DEGREE`` as its
convergence check.

``"sdm"``.  First-order semi-discretisation (Insperger & Stepan 2004;
Insperger, Stepan & Turi 2008): ``steps`` steps per period, the
coefficients replaced by their exact mean over each step, the delayed
displacement interpolated linearly between the grid values, and each step
solved exactly.  Its multipliers converge as steps^-2.

The depth a_p enters the spectral matrices linearly, U(a) = U0 + a U1 and
V(a) = V0 + a V1 (without helix), so a search over a_p assembles once per
speed (:class:`SpectralMonodromy`).

References
----------
E. A. Butcher, H. Ma, E. Bueler, V. Averina, Z. Szabo, Stability of linear
time-periodic delay-differential equations via Chebyshev polynomials,
Int. J. Numer. Meth. Engng 59 (2004) 895-922.
D. Lehotzky, T. Insperger, G. Stepan, Extension of the spectral element
method for stability analysis of time-periodic delay-differential equations
with multiple and distributed delays, Commun. Nonlinear Sci. Numer. Simul.
35 (2016) 177-189.
T. Insperger, G. Stepan, Updated semi-discretization method for periodic
delay-differential equations with discrete delay, Int. J. Numer. Meth.
Engng 61 (2004) 117-141.
T. Insperger, G. Stepan, J. Turi, On the higher-order semi-discretizations
for periodic delayed systems, J. Sound Vib. 313 (2008) 334-341.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from ..errors import InputError, check_nonneg, check_positive
from ..io import Result
from ..process._damping import milling_rubbing
from ..process._loop import ClosedLoop
from ._floquet_sdm import check_method, finite_monodromy, matched_change, sdm_monodromy, sdm_multipliers
from ._floquet_spectral import (
    CHECK_DEGREE,
    DEGREE,
    ELEMENT_SPAN,
    QuasiStatic,
    SpectralMonodromy,
    auto_degree,
    needs_split,
    spectral_mesh,
    split_frequency,
    split_structure,
)

__all__ = [
    "Multipliers",
    "SpectralMonodromy",
    "multipliers",
    "sdm_monodromy",
    "classify",
    "CHECK_DEGREE",
    "DEGREE",
    "ELEMENT_SPAN",
    "chatter_frequency",
    "auto_degree",
    "spectral_mesh",
    "split_structure",
    "split_frequency",
    "needs_split",
    "QuasiStatic",
]

#: a multiplier within this angle of the real axis is a flip (pi) or fold (0)
REAL_ANGLE = 1e-6


# ============================================================================ results
def classify(mu: complex) -> str:
    """'flip' (mu on the negative real axis), 'fold' (positive real axis) or
    'hopf' (a complex pair: secondary Hopf)."""
    ang = abs(np.angle(mu))
    if ang > math.pi - REAL_ANGLE:
        return "flip"
    if ang < REAL_ANGLE:
        return "fold"
    return "hopf"


@dataclass(frozen=True, eq=False)
class Multipliers(Result):
    """Floquet multipliers of milling at one (rpm, a_p).

    Attributes
    ----------
    mu : ndarray of complex
        The multipliers found, largest modulus first (the discretisation's
        spurious zeros left out).
    critical : complex
        The multiplier of largest modulus.
    kind : str
        Its type: ``"hopf"`` (secondary Hopf, complex pair), ``"flip"``
        (period doubling, mu < 0) or ``"fold"`` (mu > 0).
    spectral_radius : float
        |critical|; stable iff < 1 (to the accuracy ``error``).
    stable : bool
        spectral_radius < 1.
    error : float
        Convergence check: |critical - critical at a higher resolution|
        (spectral: degree + CHECK_DEGREE; SDM: 2 x steps); nan if not run.
    frequency_hz : float
        Chatter frequency, Hz: of the frequencies |arg mu + 2 pi k| / T of the
        critical solution, the dominant harmonic of its eigenvector
        (spectral; :meth:`SpectralMonodromy.critical`), or the one nearest a
        structural pole (SDM).
    method, resolution : str
        ``"spectral"`` with "degree p x elements" or ``"sdm"`` with its steps.
    period : float
        T, s.
    width_symbol, speed_unit : str
        What the process calls its width and the unit of its speed (``"a_p"``
        and ``"rpm"`` for milling; ``"b"`` and ``"rpm"`` / ``"m/s"`` for turning
        and shaping under spindle-speed variation): the names the table prints,
        the process's own (:func:`process_names`).
    """

    mu: np.ndarray
    critical: complex
    kind: str
    spectral_radius: float
    stable: bool
    error: float
    frequency_hz: float
    method: str
    resolution: str
    period: float
    rpm: float
    depth: float
    elapsed: float = 0.0
    meta: dict[str, float] = field(default_factory=dict)
    width_symbol: str = "a_p"
    speed_unit: str = "rpm"

    @classmethod
    def ranked(cls, mu: np.ndarray, **fields: Any) -> Multipliers:
        """The result of multipliers ``mu`` ranked largest first: the critical
        one, its type, the spectral radius and the stability are read off
        ``mu[0]`` here (one place for every engine: constant speed, SSV, the
        forced orbit's check); ``fields`` are the others."""
        c = complex(mu[0])
        return cls(
            mu=mu, critical=c, kind=classify(c), spectral_radius=abs(c), stable=bool(abs(c) < 1.0), **fields
        )

    # ------------------------------------------------------------------ verdict
    @property
    def bound(self) -> float:
        """The bound on the error of ``spectral_radius`` the verdict uses:
        spectral elements converge geometrically, so the change to the raised
        degree (``error``) is the lower degree's error; first-order SD
        converges as steps^-p with p = 2, p = 1 before the asymptotic range
        (:func:`~chatterlab.frequency._floquet_sdm.sdm_multipliers`), and the
        change when the steps are doubled is (1 - 2^-p) of the error of the
        ``steps`` result: the bound is error / (1 - 2^-1) = 2 error."""
        return 2.0 * self.error if self.method == "sdm" else self.error

    @property
    def verdict(self) -> str:
        """``"stable"`` (every |mu| < 1 by more than :attr:`bound`),
        ``"unstable"`` or ``"undetermined"`` (|mu| within that bound of 1:
        neither claim is proven)."""
        if abs(self.spectral_radius - 1.0) <= self.bound:
            return "undetermined"
        return "stable" if self.spectral_radius < 1.0 else "unstable"

    @property
    def exponents(self) -> np.ndarray:
        """Floquet exponents ln(mu) / T (1/s, principal branch): the growth
        rates of the periodic loop, as the characteristic roots are those of
        a constant one."""
        mu = np.asarray(self.mu, dtype=complex)
        return np.log(mu) / self.period

    def table(self) -> str:
        """The multipliers and the verdict, as the command line prints them."""
        lines = [
            f"Floquet multipliers ({self.method}, {self.resolution}) at {self._where()}"
            f" (period {self.period * 1e3:.6g} ms)"
        ]
        lines.append("    |mu|        arg mu [deg]   type")
        for mu in self.mu:
            lines.append(f"  {abs(mu):10.6f}  {np.degrees(np.angle(mu)):12.4f}   {classify(complex(mu))}")
        lines.append(f"critical: {self.verdict_line()}; chatter frequency {self.frequency_hz:.2f} Hz")
        return "\n".join(lines)

    def _where(self) -> str:
        """ "a_p = 2 mm, 9000 rpm" in the process's names (no speed when it is unknown)."""
        head = f"{self.width_symbol} = {self.depth * 1e3:g} mm"
        return head if not np.isfinite(self.rpm) else f"{head}, {self.rpm:g} {self.speed_unit}".rstrip()

    def verdict_line(self) -> str:
        """The verdict in words, with the spectral radius and its error."""
        r, e = self.spectral_radius, self.error
        if self.verdict == "undetermined":
            return f"undetermined: |mu| = {r:.9f} is within its convergence error {e:.1e} of 1"
        if self.verdict == "stable":
            return f"stable: every |mu| < 1 (spectral radius {r:.6f}, error {e:.1e})"
        kind = {"hopf": "Hopf (quasi-periodic) chatter", "flip": "flip (period-doubling) chatter"}.get(
            self.kind, self.kind
        )
        return f"unstable: {kind}, |mu| = {r:.6f} (error {e:.1e})"

    def to_dict(self) -> dict[str, Any]:
        """The ``chatterlab roots --format json`` contract of every process
        (docs/cli.md): the roots are the Floquet exponents ln(mu)/T, their
        real parts the growth rates; milling adds the multipliers."""
        from .._version import __version__

        lam = self.exponents
        c = complex(self.critical)
        return {
            "chatterlab": __version__,
            "kind": "roots",
            "process": "milling",
            "verdict": self.verdict,
            "abscissa_per_s": float(np.log(self.spectral_radius) / self.period),
            "agree": None,
            "message": self.verdict_line(),
            "width_m": self.depth,
            "delay_s": self.period,
            "terms": "pdo",
            "position_m": self.meta.get("position_m"),
            "method": self.method,
            "status": "converged" if np.isfinite(self.spectral_radius) else "not_converged",
            "roots": [
                {
                    "real_per_s": float(z.real),
                    "imag_rad_s": float(z.imag),
                    "frequency_hz": float(abs(z.imag) / (2 * np.pi)),
                    "damping_ratio": float(-z.real / abs(z)) if z != 0 else float("nan"),
                }
                for z in lam
            ],  # fmt: skip
            "winding": None,
            "speed_rpm": self.rpm,
            "period_s": self.period,
            "resolution": self.resolution,
            "spectral_radius": float(self.spectral_radius),
            "error": float(self.error),
            "critical": {"re": c.real, "im": c.imag, "type": self.kind},
            "chatter_frequency_hz": float(self.frequency_hz),
            "multipliers": [{"re": float(m.real), "im": float(m.imag)} for m in self.mu],
        }

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """The multipliers (index ``multiplier``, largest first) with their
        modulus, angle and exponent; the verdict and the cut as attributes."""
        mu = np.asarray(self.mu, dtype=complex)
        lam = self.exponents
        return (
            {"multiplier": (np.arange(mu.size), "1", "multiplier, largest modulus first")},
            {
                "abs": (np.abs(mu), "1", "|mu|"),
                "arg": (np.angle(mu), "rad", "arg mu"),
                "exponent_real": (lam.real, "1/s", "Re ln(mu) / T (growth rate)"),
                "exponent_imag": (lam.imag, "rad/s", "Im ln(mu) / T (principal branch)"),
            },
            {
                "title": "chatterlab Floquet multipliers",
                "verdict": self.verdict,
                "kind": self.kind,
                "spectral_radius": float(self.spectral_radius),
                "error": float(self.error),
                "chatter_frequency_hz": float(self.frequency_hz),
                "method": self.method,
                "resolution": self.resolution,
                "period_s": self.period,
                "speed_rpm": self.rpm,
                "depth_m": self.depth,
                "speed_unit": self.speed_unit,
                "width_symbol": self.width_symbol,
            },
        )

    def plot(self, ax: Any = None, *, title: str | None = None, **style: Any) -> Any:
        """The multipliers and the unit circle (:func:`chatterlab.plot.plot_multipliers`);
        returns the Axes."""
        from ..plot import plot_multipliers

        head = title or f"{self.verdict}: {self._where()}"
        return plot_multipliers(self, ax=ax, title=head, **style)


def process_names(process: Any) -> dict[str, str]:
    """The ``width_symbol`` and ``speed_unit`` of :class:`Multipliers` from a process object
    (:class:`~chatterlab.model.Process`, :class:`~chatterlab.process.Milling`: their
    ``width_name`` ends with the symbol); milling's names when there is none."""
    if process is None:
        return {}
    return {"width_symbol": str(process.width_name).split()[-1], "speed_unit": str(process.speed_unit)}


def chatter_frequency(mu: complex, T: float, loop: ClosedLoop) -> float:
    """The member of the family (arg mu + 2 pi k)/T nearest a structural
    pole's frequency (rad/s -> Hz)."""
    base = abs(np.angle(mu)) / T
    poles = np.abs(np.linalg.eigvals(loop.state_matrix).imag)
    poles = poles[poles > 0]
    if poles.size == 0:
        return base / (2 * np.pi)
    k = np.arange(-50, 51)
    cand = np.abs(base + 2 * np.pi * k / T)
    d = np.min(np.abs(cand[:, None] - poles[None, :]), axis=1)
    return float(cand[int(np.argmin(d))] / (2 * np.pi))


# ============================================================================ entry point
def _split_of(loop: ClosedLoop, rpm: float, depth: float, split: Any) -> QuasiStatic | None:
    """The quasi-static split asked for (see :func:`multipliers`), None for none."""
    if split is None:
        return None
    if isinstance(split, str):
        if split != "auto":
            raise InputError(f"split must be 'auto', a frequency in Hz or None (got {split!r})")
        f = needs_split(loop, rpm, depth, 1e-10)
        if f is None:
            return None
    else:
        f = check_positive(split, "split", "Hz")
    qs = split_structure(loop, f)
    return qs if qs.kept < loop.n else None


def multipliers(
    loop: ClosedLoop,
    rpm: float,
    depth: float,
    *,
    method: Literal["spectral", "sdm"] = "spectral",
    degree: int = DEGREE,
    elements: int | None = None,
    steps: int = 40,
    check: bool = True,
    split: float | Literal["auto"] | None = "auto",
) -> Multipliers:
    """Floquet multipliers of milling at spindle speed ``rpm`` and depth ``depth`` (a_p, m).

    Parameters
    ----------
    loop : ClosedLoop
        The structure under the cutter (:func:`chatterlab.process.milling_loop`;
        ``loop.process`` is the :class:`~chatterlab.process.Milling`).
    rpm : float
        Spindle speed, rpm.
    depth : float
        Axial depth of cut a_p, m (>= 0).
    method : {"spectral", "sdm"}
        Spectral-element collocation (reference) or first-order
        semi-discretisation.
    degree, elements : int
        Spectral: polynomial degree and sub-elements per cutting piece.
    steps : int
        SDM: steps per period.
    check : bool
        Also compute at a higher resolution (spectral: degree +
        CHECK_DEGREE; SDM: 2 x steps) and report the change of the critical
        multiplier as ``error`` (with a quasi-static split, plus its change
        when the modes up to twice the split frequency are integrated).
    split : float, "auto" or None
        Spectral: the structure's modes above this frequency (Hz) respond
        quasi-statically (:func:`split_structure`); "auto": where the whole
        structure's discretisation would exceed 200 multipliers
        (:func:`needs_split`); None: never.

    Returns
    -------
    Multipliers

    References
    ----------
    See the module docstring.  Under a spindle-speed variation the cut has
    its own period and delays: :func:`chatterlab.frequency.ssv_multipliers`.
    """
    t0 = time.perf_counter()
    a = check_nonneg(depth, "depth of cut a_p", "m")
    milling = loop.milling
    if method == "spectral":
        qs = _split_of(loop, rpm, a, split)
        sm = SpectralMonodromy(loop, rpm, degree, elements, depth=a, depth_hint=a, quasi_static=qs)
        mu = np.linalg.eigvals(finite_monodromy(sm.monodromy(a), rpm, a))
        mu = mu[np.argsort(-np.abs(mu))]
        f_hz = sm.critical(a)[1]
        err = float("nan")
        if check:
            raised = sm.mesh.raised(CHECK_DEGREE)
            sm2 = SpectralMonodromy(loop, rpm, depth=a, depth_hint=a, mesh=raised, quasi_static=qs)
            err = matched_change(complex(mu[0]), sm2.at(a))
            if qs is not None:  # the split's own error: the modes up to twice its frequency in time
                fine = split_structure(loop, 2.0 * qs.f_split)
                if fine.kept > qs.kept:
                    sm3 = SpectralMonodromy(loop, rpm, None, depth=a, depth_hint=a, quasi_static=fine)
                    err += matched_change(complex(mu[0]), sm3.at(a))
        res = f"degree {sm.degree} x {sm.n_sub} elements" + (f"; {qs.note()}" if qs is not None else "")
        if qs is not None and milling_rubbing(loop, rpm) is not None:
            res += (
                "; process damping: the quasi-static modes' impulse where a tooth enters or leaves is not"
                " included (docs/process-damping.md)"
            )
        T = sm.period
    elif method == "sdm":
        mu, err = sdm_multipliers(loop, rpm, a, steps, check)
        res = f"{steps} steps"
        T = milling.period(rpm)
        f_hz = chatter_frequency(complex(mu[0]), T, loop)
    else:
        check_method(method)  # one line naming the methods
    mu = mu[np.abs(mu) > 1e-300]
    return Multipliers.ranked(
        mu,
        error=err,
        frequency_hz=f_hz,
        method=method,
        resolution=res,
        period=T,
        rpm=float(rpm),
        depth=a,
        elapsed=time.perf_counter() - t0,
    )
