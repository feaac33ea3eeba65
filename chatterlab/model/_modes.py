"""Reader of ``[[mode]]``: a modal model, as tap-test users type it.

Each mode k is a single-degree-of-freedom oscillator in its modal coordinate
eta_k, with natural frequency w_k, damping ratio zeta_k and modal stiffness
k_k (or modal mass m_k = k_k / w_k^2), seen at the named physical coordinates
through its shape entries phi_ik:

    u_i = sum_k phi_ik eta_k,
    m_k eta_k'' + 2 zeta_k sqrt(k_k m_k) eta_k' + k_k eta_k = sum_i phi_ik F_i,

so the receptance between physical coordinates i and j is the familiar modal
sum (Ewins, *Modal Testing*, 2nd ed., 2000, eq. 2.58 for real modes):

    H_ij(jw) = sum_k phi_ik phi_jk / (k_k - w^2 m_k + j w 2 zeta_k sqrt(k_k m_k)).

The model becomes a matrix-level model whose coordinates are the modes
(diagonal M, L, K), and every ``[[point]]`` that names physical coordinates
is mapped to the modes through the shape entries (a weighted row of the point
map). Everything that works on a matrix-level model -- modes, FRFs, roots,
lobes, the time domain -- then works on the modal model.

``k_k`` belongs to the shape as written: with ``shape = { "tool.x" = 1.0 }``
the mode's static compliance at ``tool.x`` is 1/k_k (CutPro's and MetalMAX's
"modal stiffness in direction x").
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import ModelError
from ._fields import _id_of, _Item
from ._items import MatrixBlock, Mode

__all__ = ["read_modal_model", "modal_matrices"]

#: natural frequencies accepted, Hz (a mode of 1e-300 Hz has an infinite mass;
#: the plausible range :data:`MODE_HZ_PLAUSIBLE` is warned about by the CLI)
FREQUENCY_RANGE = (1e-3, 1e7)
#: modal stiffness accepted, N/m: the range of every stiffness of a model file
STIFFNESS_RANGE = (1e-3, 1e16)
#: the largest shape entry accepted (in size): an entry scales the mode's
#: compliance by its square, so 1e300 overflows every matrix built from it
SHAPE_MAX = 1e6

_FIELDS = ("id", "frequency_hz", "damping_ratio", "stiffness", "mass", "shape", "direction", "description")


def modal_matrices(modes: tuple[Mode, ...]) -> MatrixBlock:
    """Diagonal M, L, K (one coordinate per mode, named by the mode id)."""
    w = np.array([m.omega for m in modes])
    k = np.array([m.stiffness for m in modes])
    mass = k / w**2
    c = 2.0 * np.array([m.damping_ratio for m in modes]) * np.sqrt(k * mass)
    M, L, K = np.diag(mass), np.diag(c), np.diag(k)
    for a in (M, L, K):
        a.setflags(write=False)
    return MatrixBlock(tuple(m.id for m in modes), M, L, K, ())


def read_modal_model(src: str, raw: dict[str, Any]) -> tuple[tuple[Mode, ...], MatrixBlock] | None:
    """The ``[[mode]]`` tables of a file (None when it has none)."""
    if "mode" not in raw:
        return None
    tables = raw["mode"]
    if not isinstance(tables, list) or not tables:
        raise ModelError(
            "must be an array of tables: write each mode as [[mode]] with id, frequency_hz, damping_ratio,"
            " stiffness (or mass) and shape",
            source=src,
            item="[[mode]]",
        )
    clash = [
        k
        for k in ("matrices", "body", "node", "beam", "attachment", "contact", "constraint", "movable")
        if k in raw
    ]
    if clash:
        raise ModelError(
            f"a modal model ([[mode]]) cannot be combined with {', '.join(clash)}: keep the [[mode]] tables"
            " (with [[point]] coords naming their shape coordinates, [[coupling]] and [process]) or the others",
            source=src,
            item="[[mode]]",
        )
    modes: list[Mode] = []
    seen: set[str] = set()
    for i, t in enumerate(tables):
        iid = _id_of(src, "mode", i, t)
        if iid in seen:
            raise ModelError(f"duplicate mode id '{iid}'", source=src, item=f"mode.{iid}", field="id")
        seen.add(iid)
        modes.append(_read_mode(src, iid, t))
    names = {m.id for m in modes}
    for m in modes:
        for c, _ in m.shape:
            if c in names:
                raise ModelError(
                    f"shape: '{c}' names a mode; shape entries name physical coordinates (e.g. \"tool.x\")",
                    source=src,
                    item=f"mode.{m.id}",
                    field="shape",
                )
    return tuple(modes), modal_matrices(tuple(modes))


def _read_mode(src: str, iid: str, t: Any) -> Mode:
    it = _Item(src, f"mode.{iid}", t, _FIELDS)
    f_hz = it.num("frequency_hz", unit="Hz", positive=True)
    if not FREQUENCY_RANGE[0] <= f_hz <= FREQUENCY_RANGE[1]:
        raise it.err(
            "frequency_hz",
            f"must be within {FREQUENCY_RANGE[0]:g}..{FREQUENCY_RANGE[1]:g} Hz (got {f_hz:g} Hz);"
            f" tap-tested modes lie in {MODE_HZ_PLAUSIBLE[0]:g}..{MODE_HZ_PLAUSIBLE[1]:g} Hz",
        )
    zeta = it.num("damping_ratio", nonneg=True)
    if zeta >= 1.0:
        raise it.err("damping_ratio", f"must be < 1 (an underdamped mode; got {zeta:g})")
    omega = 2.0 * math.pi * f_hz
    if it.has("stiffness") == it.has("mass"):
        raise it.err(
            "stiffness",
            "give exactly one of stiffness (modal stiffness, N/m) or mass (modal mass, kg) for the shape as written",
        )
    if it.has("stiffness"):
        k = it.num("stiffness", unit="N/m")
        if k <= 0:
            raise it.err(
                "stiffness", f"must be > 0 N/m (a mode with k <= 0 has no restoring force; got {k:g})"
            )
    else:
        m = it.num("mass", unit="kg")
        if m <= 0:
            raise it.err("mass", f"must be > 0 kg (got {m:g})")
        k = m * omega**2
        if not STIFFNESS_RANGE[0] <= k <= STIFFNESS_RANGE[1]:
            raise it.err(
                "mass",
                f"mass {m:g} kg at {f_hz:g} Hz is a modal stiffness m (2 pi f)^2 = {k:g} N/m, outside"
                f" {STIFFNESS_RANGE[0]:g}..{STIFFNESS_RANGE[1]:g} N/m; machine-tool modes have"
                f" {MODE_STIFFNESS_PLAUSIBLE[0]:g}..{MODE_STIFFNESS_PLAUSIBLE[1]:g} N/m",
            )
    if it.has("shape") == it.has("direction"):
        raise it.err(
            "shape",
            'give exactly one of shape = { "tool.x" = 1.0, ... } or direction = "tool.x" (shape 1 there)',
        )
    if it.has("direction"):
        shape: tuple[tuple[str, float], ...] = ((it.str("direction"), 1.0),)
    else:
        s = it.raw("shape")
        if not isinstance(s, dict) or not s:
            raise it.err(
                "shape", f'must be an inline table like {{ "tool.x" = 1.0, "tool.y" = 0.4 }}, got {s!r}'
            )
        entries = []
        for c, v in s.items():
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise it.err("shape", f"'{c}' must be a finite number, got {v!r}")
            if abs(v) > SHAPE_MAX:
                raise it.err(
                    "shape",
                    f"'{c}' = {v:g} is above {SHAPE_MAX:g} in size: shape entries are the mode's"
                    " displacements for the stiffness as written, about 1 (scale the stiffness instead)",
                )
            entries.append((str(c), float(v)))
        if all(v == 0.0 for _, v in entries):
            raise it.err("shape", "all entries are zero: the mode would be seen nowhere")
        shape = tuple(entries)
    return Mode(iid, omega, zeta, k, shape)


def shape_coordinates(modes: tuple[Mode, ...]) -> dict[str, tuple[tuple[str, float], ...]]:
    """Physical coordinate -> ((mode id, shape entry), ...)."""
    out: dict[str, list[tuple[str, float]]] = {}
    for m in modes:
        for c, v in m.shape:
            out.setdefault(c, []).append((m.id, v))
    return {c: tuple(v) for c, v in out.items()}


#: the natural frequencies of a tap-tested mode, Hz: a table below it was most
#: likely typed in kHz (0.922 for 922 Hz); above it, in rad/s or cpm
MODE_HZ_PLAUSIBLE = (10.0, 5e4)
#: the modal stiffnesses of machine-tool modes, N/m: below, most likely typed
#: in N/um (1.3 for 1.3e6 N/m) or N/mm
MODE_STIFFNESS_PLAUSIBLE = (1e3, 1e11)


def modal_slips(modes: tuple[Mode, ...]) -> list[str]:
    """Unit-slip warnings for a ``[[mode]]`` table, at most one line per
    kind: natural frequencies below :data:`MODE_HZ_PLAUSIBLE` (kHz typed as
    Hz) or above it (rad/s typed as Hz), and, for modes of plausible
    frequency, modal stiffnesses below :data:`MODE_STIFFNESS_PLAUSIBLE`
    (N/um typed as N/m)."""
    lo, hi = MODE_HZ_PLAUSIBLE
    klo = MODE_STIFFNESS_PLAUSIBLE[0]
    f = {m.id: m.omega / (2.0 * math.pi) for m in modes}
    low = [i for i, v in f.items() if v < lo]
    high = [i for i, v in f.items() if v > hi]
    soft = [m.id for m in modes if lo <= f[m.id] <= hi and m.stiffness < klo]

    def listed(ids: list[str], fmt: Any) -> str:
        shown = ", ".join(f"{i} ({fmt(i)})" for i in ids[:3])
        return shown + (f" and {len(ids) - 3} more" if len(ids) > 3 else "")

    out = []
    if low:
        out.append(
            f"[[mode]] frequency_hz below {lo:g} Hz: {listed(low, lambda i: f'{f[i]:g} Hz')}: typed in kHz?"
            " frequency_hz is in Hz"
        )
    if high:
        out.append(
            f"[[mode]] frequency_hz above {hi:g} Hz: {listed(high, lambda i: f'{f[i]:g} Hz')}: typed in rad/s?"
            " frequency_hz is in Hz"
        )
    if soft:
        k = {m.id: m.stiffness for m in modes}
        out.append(
            f"[[mode]] modal stiffness below {klo:g} N/m: {listed(soft, lambda i: f'{k[i]:g} N/m')}:"
            " typed in N/um? stiffness is in N/m"
        )
    return out
