"""Insperger & Stepan's 1-DOF milling benchmark: lobes by three methods, and
a variable-pitch cutter against the same cutter with uniform pitch.

The structure is one mode along the feed (x): m = 0.03993 kg,
f_n = 922 Hz, zeta = 0.011; the cutter has N = 2 teeth, Kt = 6e8 N/m^2,
Kn = 2e8 N/m^2, down-milling at a_e/D = 0.05 and 1, 5000-25000 rpm, depths
to 10 mm (Insperger & Stepan 2004).  The lobes are computed by

* spectral-element Floquet (the reference, converged to ~1e-9 relative),
* first-order semi-discretisation with 40 steps per period (the method
  peers use),
* the zeroth-order approximation (ZOA) through the D-subdivision engine,

and overlaid.  The second figure is the classic variable-pitch
demonstration (Altintas, Engin & Budak 1999): a 4-tooth cutter with
alternating 70/110 deg pitch at a_e/D = 0.25 against the uniform 90 deg
one.  The pitch difference Delta = 40 deg cancels the regeneration of
consecutive teeth where omega_c Delta / Omega ~ pi, i.e. near
Omega = omega_c Delta / pi: about 11000 rpm for a 920 Hz chatter.

Run: ``python studies/milling_benchmark.py`` (prints the numbers; with
``--figures docs/figures`` it also rewrites ``milling_lobes.png`` and
``milling_pitch.png`` there).
``tests/test_floquet.py`` runs :func:`compute` on a few speeds.

References: T. Insperger, G. Stepan, Int. J. Numer. Meth. Engng 61 (2004)
117-141; Y. Altintas, S. Engin, E. Budak, J. Manuf. Sci. Eng. 121 (1999)
173-178.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from chatterlab.lobes import LobeDiagram, milling_lobes
from chatterlab.process import Milling, milling_loop
from chatterlab.structure import Structure

MASS, FN, ZETA = 0.03993, 922.0, 0.011
KT, KN = 6e8, 2e8
DEPTH_MAX = 0.01


def tool() -> Structure:
    return Structure.single_dof(MASS, 2 * np.pi * FN, ZETA)


def cutter(immersion: float, teeth: int = 2, pitch: tuple[float, ...] = ()) -> Milling:
    return Milling.from_immersion(teeth, 0.02, KT, KN, immersion, "down", pitch=pitch)


def compute(n_speeds: int = 201, n_sdm: int | None = None, n_pitch: int | None = None) -> dict[str, Any]:
    """The lobes of both immersions by the three methods (SDM on ``n_sdm``
    speeds, default all) and the pitch comparison on ``n_pitch`` speeds
    6000-20000 rpm (default n_speeds // 2)."""
    rpm = np.linspace(5000.0, 25000.0, n_speeds)
    rpm_sdm = rpm if n_sdm is None else np.linspace(5000.0, 25000.0, n_sdm)
    out: dict[str, Any] = {"rpm": rpm}
    for imm in (0.05, 1.0):
        m = cutter(imm)
        out[imm] = {
            "spectral": milling_lobes(milling_loop(tool(), m), rpm, depth_max=DEPTH_MAX),
            "sdm": milling_lobes(
                milling_loop(tool(), m), rpm_sdm, method="sdm", steps=40, rtol=1e-4, depth_max=DEPTH_MAX
            ),
            "zoa": milling_lobes(milling_loop(tool(), m), rpm, method="zoa", depth_max=DEPTH_MAX),
        }
    rpm_p = np.linspace(6000.0, 20000.0, n_pitch or max(n_speeds // 2, 3))
    out["pitch_rpm"] = rpm_p
    out["uniform"] = milling_lobes(milling_loop(tool(), cutter(0.25, 4)), rpm_p, depth_max=DEPTH_MAX)
    var = cutter(0.25, 4, tuple(np.radians([70.0, 110.0, 70.0, 110.0])))
    out["variable"] = milling_lobes(milling_loop(tool(), var), rpm_p, depth_max=DEPTH_MAX)
    return out


def draw(res: dict[str, Any], folder: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = []
    fig, axes = plt.subplots(2, 1, figsize=(9, 8), sharex=True)
    for ax, imm in zip(axes, (0.05, 1.0), strict=True):
        sets: list[tuple[str, LobeDiagram, dict[str, Any]]] = [
            ("ZOA (Altintas & Budak)", res[imm]["zoa"], {"color": "0.55", "lw": 1.2}),
            ("SDM, 40 steps", res[imm]["sdm"], {"color": "tab:orange", "lw": 1.0, "ls": "--"}),
            ("spectral Floquet (reference)", res[imm]["spectral"], {"color": "tab:blue", "lw": 1.4}),
        ]
        for label, L, kw in sets:
            ax.plot(L.speed, np.where(np.isfinite(L.a_lim), L.a_lim * 1e3, np.nan), label=label, **kw)
        sp = res[imm]["spectral"]
        flip = sp.kind == "flip"
        ax.plot(
            sp.speed[flip], sp.a_lim[flip] * 1e3, "v", ms=3, color="tab:red", label="flip (period doubling)"
        )
        ax.set_ylim(0, DEPTH_MAX * 1e3)
        ax.set_ylabel("limit axial depth a_lim (mm)")
        ax.set_title(
            f"a_e/D = {imm:g}, down-milling, N = 2 (Insperger & Stepan 1-DOF benchmark)", fontsize=10
        )
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper left", fontsize=8, ncol=2)
    axes[1].set_xlabel("spindle speed (rpm)")
    fig.tight_layout()
    p = folder / "milling_lobes.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    paths.append(p)

    fig, ax = plt.subplots(figsize=(9, 4.2))
    for key, label, colour in (
        ("uniform", "uniform pitch, 4 x 90 deg", "0.4"),
        ("variable", "variable pitch, 70/110/70/110 deg", "tab:green"),
    ):
        L = res[key]
        ax.plot(
            L.speed, np.where(np.isfinite(L.a_lim), L.a_lim * 1e3, np.nan), label=label, color=colour, lw=1.3
        )
    ax.set_ylim(0, DEPTH_MAX * 1e3)
    ax.set_xlabel("spindle speed (rpm)")
    ax.set_ylabel("limit axial depth a_lim (mm)")
    ax.set_title(
        "N = 4, a_e/D = 0.25 down-milling, 1-DOF benchmark structure (spectral Floquet)", fontsize=10
    )
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    p = folder / "milling_pitch.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    paths.append(p)
    return paths


def main() -> None:
    from _figures import figures_dir

    folder = figures_dir(__doc__.splitlines()[0])
    res = compute(201, 101)
    for imm in (0.05, 1.0):
        sp = res[imm]["spectral"]
        print(sp.summary())
        zo = res[imm]["zoa"]
        flip = sp.kind == "flip"
        print(
            f"  ZOA: {np.count_nonzero(flip)} flip speeds, where ZOA is >30 % deeper or none:"
            f" {np.count_nonzero(~np.isfinite(zo.a_lim[flip]) | (zo.a_lim[flip] > 1.3 * sp.a_lim[flip]))}"
        )
    u, v = res["uniform"], res["variable"]
    j = int(np.argmax(v.a_lim / u.a_lim))
    print(
        f"variable pitch: largest gain x{v.a_lim[j] / u.a_lim[j]:.2f} at {v.speed[j]:.0f} rpm"
        f" ({u.a_lim[j] * 1e3:.3f} -> {v.a_lim[j] * 1e3:.3f} mm)"
    )
    if folder is not None:
        for p in draw(res, folder):
            print("wrote", p)


if __name__ == "__main__":
    main()
