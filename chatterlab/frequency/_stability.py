"""A stability verdict for one operating point (b, T) at a frozen configuration.

Two independent routes:

* the characteristic roots of det(s^2 A* + s (B* - D_V) + C* - D_P - D_O e^{-sT})
  (:mod:`chatterlab.frequency._roots`: spectral collocation of the delay equation, each
  root refined by Newton and checked under refinement), whose rightmost real
  part is the stability margin;
* the argument principle (:mod:`chatterlab.frequency._winding`): the number of closed-loop
  roots in the right half plane from the winding of det(I - G D) along the
  imaginary axis.

The verdict is ``stable`` / ``unstable`` / ``marginal`` when the routes
agree; when they disagree the result says so (``verdict = "undetermined"``)
instead of guessing.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np

from ..io import Result
from ..process._loop import ClosedLoop, closed_loop
from ..structure._assembly import FrozenSystem

__all__ = ["Stability", "stability", "loop_band", "MARGINAL_TOL", "mesh_checked"]

#: |Re lambda| below this fraction of |lambda| (plus 1e-9 1/s) counts as on the axis.
MARGINAL_TOL = 1e-7


@dataclass(frozen=True, eq=False)
class Stability(Result):
    """Result of :func:`stability`.

    Attributes
    ----------
    verdict : str
        ``"stable"``, ``"unstable"``, ``"marginal"`` (a root on the imaginary
        axis to tolerance) or ``"undetermined"`` (the two routes disagree,
        the root search did not converge, or no root was found right of the
        axis but neither a certified band nor the argument principle proves
        that none is there).
    abscissa : float
        Rightmost real part of the characteristic roots, 1/s: the margin
        (negative = stable).
    roots : RootsResult
    winding : WindingResult or None
    agree : bool or None
        Whether roots and argument principle agree (None if winding not run).
    """

    verdict: str
    abscissa: float
    roots: Any
    winding: Any
    agree: bool | None
    message: str
    width: float
    delay: float | None
    terms: str
    position: float | None
    process: str = ""  #: the model's process kind (turning, shaping, delay, milling); "" without one
    #: a model with beams: the verdict on the mesh twice as fine and the margin's
    #: discretisation error (:func:`mesh_checked`); empty otherwise
    mesh: dict[str, Any] = field(default_factory=dict)

    @property
    def chatter_hz(self) -> float:
        """Frequency of the rightmost root, Hz."""
        return float(self.roots.frequency_hz[0]) if len(self.roots.roots) else float("nan")

    def to_dict(self) -> dict[str, Any]:
        from .._version import __version__

        r = self.roots
        return {
            "chatterlab": __version__,
            "kind": "roots",
            "process": self.process or None,
            "verdict": self.verdict,
            "abscissa_per_s": self.abscissa,
            "agree": self.agree,
            "message": self.message,
            "width_m": self.width,
            "delay_s": self.delay,
            "terms": self.terms,
            "position_m": self.position,
            "method": r.method,
            "status": r.status,
            "roots": [
                {
                    "real_per_s": float(z.real),
                    "imag_rad_s": float(z.imag),
                    "frequency_hz": float(f),
                    "damping_ratio": float(d),
                }
                for z, f, d in zip(r.roots, r.frequency_hz, r.damping_ratio, strict=True)
            ],
            **({"mesh": self.mesh} if self.mesh else {}),
            "winding": None
            if self.winding is None
            else {
                "rhp_count": self.winding.count,
                "open_loop_rhp_count": self.winding.open_loop_count,
                "status": self.winding.status,
                "samples": self.winding.n_samples,
            },
        }

    def table(self) -> str:
        lines = [
            f"verdict: {self.verdict}   margin (rightmost Re) = {self.abscissa:.6g} 1/s",
            f"  width {self.width * 1e3:.6g} mm"
            + (f", delay {self.delay:.6g} s" if self.delay is not None else "")
            + f", feedback {self.terms}"
            + (f", position {self.position:g} m" if self.position is not None else ""),
            f"  {self.message}",
            *([f"  {self.mesh['line']}"] if self.mesh else []),
            self.roots.table(),
        ]
        return "\n".join(lines)

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """The roots' arrays (:meth:`RootsResult.dataset_parts`) with the
        verdict, the cut and the argument-principle count as attributes."""
        coords, data, attrs = self.roots.dataset_parts()
        d = self.to_dict()
        attrs = {**attrs, "title": "chatterlab stability verdict", "verdict": self.verdict,
                 "agree": str(self.agree), "verdict_message": self.message, "width_m": self.width,
                 "delay_s": float("nan") if self.delay is None else self.delay, "terms": self.terms,
                 "position_m": float("nan") if self.position is None else self.position,
                 "winding": json.dumps(d["winding"])}  # fmt: skip
        attrs.update({f"mesh_{k}": v for k, v in self.mesh.items() if k != "line"})
        if self.mesh:
            attrs["mesh"] = self.mesh["line"]
        return coords, data, attrs

    def plot(self, ax: Any = None, *, title: str | None = None, **style: Any) -> Any:
        """The rightmost roots in the complex plane, titled with the verdict
        (:func:`chatterlab.plot.plot_roots`); returns the Axes."""
        from ..plot import plot_roots

        head = (
            title
            or f"{self.verdict}: rightmost Re = {self.abscissa:.4g} 1/s, width {self.width * 1e3:.4g} mm"
        )
        return plot_roots(self.roots, ax=ax, title=head, **style)


def stability(
    frozen: FrozenSystem,
    *,
    width: float,
    speed: float | None = None,
    delay: float | None = None,
    terms: Literal["pdo", "pd", "o", "none"] = "pdo",
    couplings: list[str] | None = None,
    count: int = 6,
    winding: bool = True,
) -> Stability:
    """Is the cut at width b and delay T (or speed) stable?

    Parameters
    ----------
    frozen : FrozenSystem
        The configuration.
    width : float
        Width of cut b, m.
    speed, delay : float, optional
        The cutting speed (process unit) or the delay T (s).
    terms : {"pdo", "pd", "o", "none"}
        Feedback terms (paper's cases c, b; delayed only; a).
    count : int
        Number of rightmost roots reported.
    winding : bool
        Also count right-half-plane roots by the argument principle and
        require agreement.

    Returns
    -------
    Stability
    """
    from ._delay_system import single_threaded_blas

    # one BLAS thread: the work is dense problems of the structure's size, and
    # a second thread on a shared machine costs more than it gains
    with single_threaded_blas():
        return _stability(frozen, width, speed, delay, terms, couplings, count, winding)


def _stability(
    frozen: FrozenSystem,
    width: float,
    speed: float | None,
    delay: float | None,
    terms: Literal["pdo", "pd", "o", "none"],
    couplings: list[str] | None,
    count: int,
    winding: bool,
) -> Stability:
    """:func:`stability` (under one BLAS thread)."""
    from ._delay_system import loop_system
    from ._roots import characteristic_roots

    fb = closed_loop(frozen, width=width, speed=speed, delay=delay, terms=terms, couplings=couplings)
    # one delay system for both routes: they share its partial fractions and bands
    sys_ = loop_system(fb)
    r = characteristic_roots(sys_, count=count)
    absc = float(r.abscissa)
    if not np.isfinite(absc) or not r.converged:
        verdict = "undetermined"
        msg = f"root search: {r.message}"
        found = _unstable_root(sys_)
        if found is not None:
            # one root right of the axis proves instability, complete search or not
            verdict, absc = "unstable", float(found.real)
            msg += (
                f"; a root at {found.real:.6g} {found.imag:+.6g}j 1/s, refined by Newton from an unstable"
                " delay-free pole, proves the cut unstable"
            )
    else:
        scale = float(abs(r.roots[0])) if len(r.roots) else 1.0
        if abs(absc) <= MARGINAL_TOL * scale + 1e-9:
            verdict = "marginal"
        else:
            verdict = "stable" if absc < 0 else "unstable"
        msg = f"roots by {r.method}"
    w = None
    agree = None
    if winding:
        from ._winding import rhp_count

        # in factored form the count proves its own band (the gain bound's
        # passive tail): the loop band, which needs the structure's complex
        # modes, only ends a sampled count
        w = rhp_count(sys_, omega_max=None if sys_.partial_fractions() is not None else loop_band(fb))
        if verdict in ("stable", "unstable") and w.status == "converged":
            agree = (w.count == 0) == (verdict == "stable")
            how = "every phase increment proven" if w.proven else "phase sampled, not proven"
            if not agree:
                msg += (
                    f"; DISAGREEMENT: the argument principle ({how}) counts {w.count} right-half-plane"
                    f" root(s) while the rightmost root found has Re = {absc:.4g} 1/s"
                )
                verdict = "undetermined"
            else:
                msg += f"; argument principle agrees ({w.count} right-half-plane roots)"
        elif verdict == "marginal":
            msg += f"; argument principle: {w.status}, {w.count} right-half-plane roots"
        else:
            msg += f"; argument principle: {w.status} ({w.message})"
    if verdict == "stable" and not agree and not (r.complete_above < 0):
        # neither route proves it: the roots' band is not certified by the gain
        # bound and the argument principle did not run or did not converge
        verdict = "undetermined"
        msg += "; no root found right of the axis, but the band searched is not proven complete"
    proc = frozen.model.process
    return Stability(
        verdict,
        absc,
        r,
        w,
        agree,
        msg,
        float(width),
        fb.delay,
        terms,
        frozen.position,
        proc.kind if proc else "",
    )


def mesh_checked(coarse: Stability, fine: Stability, model: Any) -> Stability:
    """The verdict of a model with beams: ``coarse`` (on its mesh) judged
    against ``fine`` (the same cut on :meth:`Model.with_finer_mesh`) by
    :func:`chatterlab.model._mesh.mesh_verdict` -- undetermined when the two
    verdicts differ or the margin is within its discretisation error
    (docs/lobes.md, Eq. M3).  The roots and the count stay those of
    ``coarse``; ``mesh`` says what the finer mesh gave."""
    from ..model._mesh import MeshEstimate, mesh_record, mesh_verdict

    verdict, line = mesh_verdict(model, coarse.verdict, coarse.abscissa, fine.verdict, fine.abscissa)
    mesh = {
        "line": line,
        **mesh_record(model, prefix=""),
        "coarse_verdict": coarse.verdict,
        "fine_verdict": fine.verdict,
        "fine_abscissa_per_s": fine.abscissa,
        "abscissa_error_bound_per_s": float(MeshEstimate(coarse.abscissa, fine.abscissa).bound),
    }
    return replace(coarse, verdict=verdict, mesh=mesh)


def loop_band(fb: ClosedLoop, tol: float = 1e-4) -> float:
    """Upper end (rad/s) of the band where the cutting loop matters: twice
    the highest frequency at which the loop gain ||H(jw) Dl(jw)|| (all terms,
    |e^{-jwT}| = 1) exceeds ``tol``.  Above it det(I - G D) stays within
    ~tol of 1 and cannot wind about the origin, so the argument principle
    needs no samples there."""
    from ..structure._complex import modal_response

    cm = fb.structure.complex_modes
    wn = np.abs(cm.lam)
    wmax = 3.0 * float(wn.max())
    w = np.geomspace(max(1e-3 * float(wn.min()), 1e-3), wmax, 400)
    H = np.transpose(modal_response(cm, fb.J, fb.J.T, 1j * w, np.arange(cm.lam.size), False), (2, 0, 1))
    Dabs = np.abs(fb.Dl_P)[None] + w[:, None, None] * np.abs(fb.Dl_V)[None] + np.abs(fb.Dl_O)[None]
    gain = np.linalg.norm(np.abs(H) @ Dabs, ord=2, axis=(1, 2))
    big = np.nonzero(gain > tol)[0]
    if big.size == 0:
        return float(2.0 * wn.min())
    return float(min(wmax, 2.0 * w[big[-1]]))


def _unstable_root(sys_: Any) -> complex | None:
    """A characteristic root with Re > 0 found by Newton from the delay-free
    closed loop's unstable poles (where e^{-lambda T} is small the delayed
    term barely moves them), or None."""
    from ._newton import newton

    p = sys_.delay_free_poles()
    starts = p[(p.real > 0) & (p.imag >= 0)]
    if starts.size == 0:
        return None
    lam, ok = newton(sys_, starts[np.argsort(-starts.real)][:8])
    good = lam[ok & (lam.real > 0)]
    return complex(good[np.argmax(good.real)]) if good.size else None
