"""A milling run in the time domain (:class:`chatterlab.time.MillingSimulation`):
:func:`plot_milling_run` -- the tool's vibration, the cutting force and the
Poincare samples, the panels a verdict of chatter is read from."""

from __future__ import annotations

from typing import Any

import numpy as np


def plot_milling_run(run: Any, *, ax: Any = None, **style: Any) -> Any:
    """The vibration x, y (um) and the cutting force Fx, Fy (N) against time
    and the Poincare samples of the coordinate that moves more (x or y
    against its velocity at t = k T: the first half of the run grey, the
    last half red), the title giving the speed, depth and the verdict.

    ``ax``: three Axes (vibration, force, samples), default a new figure,
    or one Axes for the vibration alone; ``style`` goes to the time
    histories' ``Axes.plot`` (default ``lw=0.6``).  Returns the Axes drawn
    on (the three, or the one given)."""
    import matplotlib.pyplot as plt

    line = {"lw": 0.6, **style}
    if ax is not None and not isinstance(ax, list | tuple | np.ndarray):
        _vibration(ax, run, line)
        ax.set_xlabel("t [s]")
        return ax
    if ax is None:
        fig = plt.figure(figsize=(10, 7), layout="constrained")
        gs = fig.add_gridspec(2, 2)
        ax = [fig.add_subplot(gs[0, 0]), fig.add_subplot(gs[1, 0]), fig.add_subplot(gs[:, 1])]
    a0, a1, a2 = ax
    _vibration(a0, run, line)
    a1.plot(run.t, run.Fx, label="Fx", **line)
    a1.plot(run.t, run.Fy, label="Fy", **line)
    a1.set_xlabel("t [s]")
    a1.set_ylabel("cutting force [N]")
    a1.legend(fontsize=8)
    p = run.poincare
    half = p.shape[0] // 2
    c = 0 if np.ptp(p[:, 0]) >= np.ptp(p[:, 1]) else 1  # the coordinate that moves more
    a2.plot(1e6 * p[:half, c], 1e3 * p[:half, 2 + c], ".", ms=3, color="0.7", label="first half")
    a2.plot(1e6 * p[half:, c], 1e3 * p[half:, 2 + c], ".", ms=4, color="C3", label="last half")
    a2.set_xlabel(f"{'xy'[c]} at t = k T [µm]")
    a2.set_ylabel(f"{'xy'[c]}' at t = k T [mm/s]")
    a2.set_title("Poincaré samples", fontsize=9)
    a2.legend(fontsize=8)
    return ax


def _vibration(ax: Any, run: Any, line: dict[str, Any]) -> None:
    """x and y of the tool (um) against time, the verdict in the title."""
    ax.plot(run.t, 1e6 * run.x, label="x", **line)
    ax.plot(run.t, 1e6 * run.y, label="y", **line)
    ax.set_ylabel("tool vibration [µm]")
    ax.set_title(
        f"{run.rpm:.0f} rpm, a_p = {1e3 * run.depth:.3g} mm: {run.verdict} "
        f"(ln|mu| = {run.growth_per_period:.3g} per period)",
        fontsize=9,
    )
    ax.legend(fontsize=8)
