"""What an ``inf`` b_lim in a sweep's summary means, in words (and what a
lobe diagram's failed argument-principle checks mean, :func:`check_verdict`).

A b_lim of ``inf`` at a point whose task succeeded says only that no
boundary point lies below the width ceiling (``--width-max``) in the
chatter band searched.  Whether that is a claim of stability depends on the
band: when the loop-gain bound proves that no boundary point below the
ceiling lies outside it (``Band.certified``), the point is stable up to the
ceiling; otherwise it is undetermined.  The sweep's outputs carry the value
and the per-point task status, not the band, so the summary asks the lobe
engine's ``Boundary`` for the band of each configuration holding an ``inf``
(one per position in an atlas; at most ``MAX_BAND_CHECKS`` in a sweep).
"""

from __future__ import annotations

from collections import Counter
from typing import Any

from ._common import m_to_mm

#: configurations whose band a sweep summary checks; beyond them an ``inf``
#: is reported as not checked (undetermined as far as this run shows)
MAX_BAND_CHECKS = 8


def ceiling_claim(band: Any, width_max: float) -> str:
    """The meaning of ``inf`` under the ceiling ``width_max`` (m) in ``band``
    (a ``Band``; None: its band was not checked)."""
    ceiling = f"the width ceiling {m_to_mm(width_max):g} mm"
    if band is None:
        return f"undetermined (no boundary found below {ceiling}; the band searched was not checked here)"
    if band.certified:
        return f"no boundary below {ceiling} in the certified band"
    return f"undetermined (no boundary found below {ceiling} in a band not proven complete: {band.reason})"


def check_verdict(checks: Any) -> str:
    """The last line of a lobe diagram whose argument-principle checks did not
    all agree: contradicted where a count disagrees, unverified where the
    count itself failed (its phase did not close) -- never a negative count."""
    from ..lobes._result import count_failed

    failed = sum(count_failed(c) for c in checks)
    contradicted = sum(not c["agrees"] and not count_failed(c) for c in checks)
    parts = []
    if contradicted:
        parts.append(
            "the argument principle contradicts the diagram at the checks marked CHECK FAILED:"
            " treat the diagram as undetermined there"
        )
    if failed:
        parts.append(
            f"the argument-principle count failed at {failed} check(s) (marked CHECK NOT COUNTED: its phase"
            " did not close): the diagram is unverified there, neither confirmed nor contradicted"
        )
    return "chatterlab: " + "; ".join(parts)


def inf_note(claims: list[str], total: int, what: str = "points") -> str:
    """``inf at K of N points: CLAIM`` (or a count per claim when they differ)."""
    counts = Counter(claims)
    head = f"inf at {len(claims)} of {total} {what}"
    if len(counts) == 1:
        return f"{head}: {claims[0]}"
    return f"{head}: " + ", ".join(f"{n} {c}" for c, n in counts.items())


def ok_infs(values: Any, task_status: Any) -> Any:
    """Mask of the ``inf`` values at points whose task succeeded (a failed
    task's outputs are NaN, never a claim)."""
    import numpy as np

    mask = np.isinf(np.asarray(values, dtype=float))
    if task_status is not None:
        mask &= np.asarray(task_status) == 0
    return mask


def sweep_band(task: Any, model: Any, point: dict[str, float]) -> Any:
    """The chatter band (``Band``) a ``QuantityTask``'s b_lim searched at a
    grid point: the same model parameters, position, ceiling and terms."""
    from ..lobes import Boundary
    from ..structure._assembly import assemble

    builtin = ("width", "speed", "delay", "position")
    params = {task.aliases.get(k, k): float(v) for k, v in point.items() if k not in builtin}
    position = point.get("position", task.fixed.get("position"))
    mdl = model.with_parameters(params) if params else model
    return Boundary(assemble(mdl).at(position), width_max=task.width_max, terms=task.terms).band


def sweep_inf_claims(res: Any, output: str, task: Any, model: Any) -> tuple[list[str], int]:
    """The claim of every ``inf`` of ``output`` at a succeeded point of the
    sweep result ``res``, and the number of points; the band is checked once
    per configuration (speed, delay and width do not change it)."""
    import numpy as np

    values = np.asarray(res.data[output], dtype=float)
    idx = np.argwhere(ok_infs(values, res.task_status))
    names = [a.name for a in res.grid.axes]
    cache: dict[tuple[Any, ...], Any] = {}
    claims = []
    for ix in idx:
        point = {n: float(res.grid.axes[d].values[i]) for d, (n, i) in enumerate(zip(names, ix, strict=True))}
        key = tuple(sorted((k, v) for k, v in point.items() if k not in ("width", "speed", "delay")))
        if key not in cache:
            cache[key] = sweep_band(task, model, point) if len(cache) < MAX_BAND_CHECKS else None
        claims.append(ceiling_claim(cache[key], task.width_max))
    return claims, values.size
