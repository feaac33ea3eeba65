"""The result of :func:`chatterlab.lobes.lobes`: one :class:`Lobe` per
integer k and branch, and the :class:`LobeDiagram` (the envelope b_lim against
speed, its minima, checks and band), with its summary, claims, files and plot.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

__all__ = ["Lobe", "LobeDiagram", "count_failed"]


def count_failed(check: dict[str, Any]) -> bool:
    """True when a check's argument-principle count failed (its phase did not
    close: verdict ``undetermined``, or no count at all, ``rhp_roots < 0``):
    the check neither confirms nor contradicts the diagram."""
    return check["verdict"] == "undetermined" or int(check["rhp_roots"]) < 0


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
                f" ({len(self.lobes)} kept as curves: on each branch, the lobe numbers k of the envelope)"
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
            n_failed = sum(count_failed(c) for c in self.checks)
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
                + (f"; {n_failed} could not count the roots" if n_failed else "")
            )
            for c in self.checks:
                where = f"at {c['speed']:.6g} {self.speed_unit}, width {c['width'] * 1e3:.6g} mm"
                if count_failed(c):
                    why = c.get("reason") or c.get("message")
                    lines.append(
                        f"  CHECK NOT COUNTED {where} (expected {c['expected']}): the argument-principle count"
                        f" failed (its phase did not close{f': {why}' if why else ''}); nothing is verified there"
                    )
                elif not c["agrees"]:
                    lines.append(
                        f"  CHECK FAILED {where}: expected {c['expected']}, the argument principle says"
                        f" {c['verdict']} ({c['rhp_roots']} right-half-plane roots)"
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
        the band is not excluded).  A check whose count failed
        (:func:`count_failed`) contradicts nothing: its speed keeps the
        diagram's claim, unverified, like a speed that was not checked."""
        code = np.where(
            np.isfinite(self.b_lim), 4 if self.band_measured else 0, 1 if self.band_certified else 2
        )
        for c in self.checks:
            if not c["agrees"] and not count_failed(c):
                code[np.nonzero(self.speed == c["speed"])[0]] = 3
        return code

    def to_csv(self, path: Any) -> None:
        """Envelope: speed, delay (s), b_lim (m), chatter frequency (Hz), lobe
        number and the claim's status (see :attr:`claim`), and what was
        searched (the width ceiling, m, and the chatter band, Hz: an ``inf``
        means no boundary there, nothing more) -- SI like every chatterlab
        result file."""
        import csv

        from ..io._files import text_out

        with text_out(path) as fh:
            w = csv.writer(fh, lineterminator="\n")
            w.writerow(
                [
                    f"speed [{self.speed_unit}]",
                    "delay [s]",
                    "b_lim [m]",
                    "chatter frequency [Hz]",
                    "lobe [-]",
                    "status",
                    "searched below [m]",
                    "band low [Hz]",
                    "band high [Hz]",
                ]
            )
            claim = self.claim
            lo, hi = self.band_hz
            for k in range(self.speed.size):
                w.writerow(
                    [
                        f"{self.speed[k]:.9g}",
                        f"{self.delay[k]:.9g}",
                        f"{self.b_lim[k]:.9g}",
                        f"{self.chatter_hz[k]:.9g}",
                        int(self.lobe[k]),
                        self.CLAIMS[int(claim[k])],
                        f"{self.width_max:.9g}",
                        f"{lo:.9g}",
                        f"{hi:.9g}",
                    ]
                )

    def to_xarray(self, attrs: dict[str, Any] | None = None) -> Any:
        """The diagram as an :class:`xarray.Dataset`: speed as coordinate;
        b_lim in m, chatter frequency in Hz, delay in s, lobe number and the
        claim code as data; summary numbers and checks as attributes."""
        from ..io import make_dataset

        return make_dataset(*self.dataset_parts(attrs))

    def dataset_parts(
        self, attrs: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """``(coords, data, attrs)`` of :meth:`to_xarray` and :meth:`to_netcdf`
        (the specifications :func:`chatterlab.io.make_dataset` takes)."""
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
            "absolute_min_chatter_hz": self.absolute_minimum["chatter_hz"],
            "verified": str(self.verified),
            "chatter_band_hz": list(self.band_hz),
            "chatter_band_certified": str(self.band_certified),
            "chatter_band_note": self.band_note,
            "chatter_band_measured": str(self.band_measured),
            "checks": json.dumps(list(self.checks)),
        }
        a.update(self.meta)
        a.update(attrs or {})
        return (
            {"speed": (self.speed, self.speed_unit)},
            {
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
            a,
        )

    def to_netcdf(self, path: str, attrs: dict[str, Any] | None = None) -> None:
        """Labelled netCDF-4 file of :meth:`to_xarray` (the model text as
        an attribute when the caller passes it), written atomically by
        :func:`chatterlab.io.write_netcdf` (the same file, without importing
        xarray)."""
        from ..io import write_netcdf

        write_netcdf(path, *self.dataset_parts(attrs))

    def plot(
        self, ax: Any = None, *, lobe_numbers: int = 8, title: str | None = None, axes: Any = None
    ) -> Any:
        """Lobe diagram (b_lim in mm against speed, unstable region shaded,
        lobe numbers) over the chatter frequency panel; returns the Axes
        (``axes=`` is a deprecated alias of ``ax=``)."""
        from ..plot import plot_lobes

        return plot_lobes(self, ax=ax, axes=axes, lobe_numbers=lobe_numbers, title=title)
