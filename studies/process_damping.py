"""Process damping in turning: the low-speed stability that the flank gives.

A 1-DOF turning tool (m x'' + c x' + k x = F) cuts a workpiece of diameter D
with a worn tool whose flank rubs on the surface it has just cut: the force
on the tool is

    F = -K_f b [x(t) - x(t - T)] - C_pd (b / V) x',   T = 60 / n,  V = pi D n / 60

(Altintas, Eynian & Onozuka 2008; Budak & Tunc 2010).  The study computes the
lobes with and without the flank's damping (``chatterlab.lobes``; the width
and the delay are coupled through V, docs/process-damping.md) and checks the
closed form of the lobe bottoms: at a fixed speed the process damping is an
extra viscous damping b C_pd / V, so Tlusty's minimum 2 k zeta (1 + zeta) / K_f
holds with zeta = (c + b C_pd / V) / (2 sqrt(k m)), a quadratic equation in b
(docs/process-damping.md, Eq. 8) whose root rises like 1/V at low speed:
b - b_0 = b_0 (1 + 2 zeta_0) w_n C_pd / (K_f V) + O(1/V^2).

Run: ``python studies/process_damping.py`` (prints the numbers and writes the
model without the table and the cutting tests of docs/process-damping.md into
``studies/process_damping/``; ``--figures DIR`` draws ``process_damping_lobes.png``).  ``tests/test_process_damping.py``
checks them.

References: Y. Altintas, M. Eynian, H. Onozuka, CIRP Annals 57 (2008)
371-374; E. Budak, L. T. Tunc, CIRP Annals 59 (2010) 403-408; J. Tlusty, M.
Polacek (1963).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import chatterlab as cl

MASS, STIFF, DAMP, KF = 2.0, 2.0e7, 400.0, 2.0e9  # kg, N/m, N s/m, N/m^2
DIAMETER = 0.05  #: m, the workpiece
C_PD = 2.0e5  #: N/m, the flank's linear coefficient
#: the indentation model whose small-vibration equivalent is C_PD: K_sp w^2 / 4
K_SP, WEAR_LAND, CLEARANCE_DEG = 8.0e13, 1.0e-4, 7.0


def model_text(C_pd: float | None = C_PD, indentation: bool = False) -> str:
    """The model file: the tool on its holder, the regenerative cut, the
    workpiece diameter and (unless ``C_pd`` is None) the flank's damping."""
    text = f"""
[model]
name = "1-DOF turning with process damping"

[[body]]
id = "tool"
mass = {MASS}
inertia = 1.0
centre = [0.0, 0.0]

[[support]]
body = "tool"
fix = ["y", "rz"]

[[spring]]
id = "holder"
a = "tool"
b = "ground"
c1 = {STIFF}
d1 = {DAMP}

[[coupling]]
id = "cut"
a = "tool"
b = "ground"
model = "regenerative"
Kf = {KF}
width_ref = 0.001

[process]
kind = "turning"
rpm = 300

[machine]
workpiece_diameter = {DIAMETER}
"""
    if indentation:
        text += (
            f"\n[process_damping]\nK_sp = {K_SP}\nwear_land = {WEAR_LAND}\nclearance_deg = {CLEARANCE_DEG}\n"
        )
    elif C_pd is not None:
        text += f"\n[process_damping]\nC_pd = {C_pd}\n"
    return text


#: the folder of the study's files (the model and the cutting tests the docs use)
FILES = Path(__file__).resolve().parent / "process_damping"
#: speeds (rpm) of the synthetic chatter onsets, and of a stable and a chattering cut
ONSETS_RPM = (190.0, 230.0, 300.0, 400.0)
CUT_RPM = 260.0


def cuts_text() -> str:
    """The cutting tests of docs/process-damping.md: the chatter onsets of
    the model with C_PD at ONSETS_RPM, rounded to 1 um (the measurement),
    and a cut 5 % below and one 5 % above the limit at CUT_RPM."""
    n = np.array([*ONSETS_RPM, CUT_RPM])
    d = cl.lobes(cl.loads_model(model_text(), source="process_damping.py"), n, width_max=0.02, verify=0)
    b = np.round(d.b_lim * 1e3, 3)
    rows = [f"{v:g},{w:.3f},onset,0.01" for v, w in zip(ONSETS_RPM, b[:-1], strict=True)]
    rows += [f"{CUT_RPM:g},{0.95 * b[-1]:.3f},stable,", f"{CUT_RPM:g},{1.05 * b[-1]:.3f},chatter,"]
    head = (
        "# cutting tests of a 1-DOF turning tool (studies/process_damping.py: the onsets of C_pd = 2e5 N/m)\n"
    )
    return head + "speed,width_mm,result,sigma_mm\n" + "\n".join(rows) + "\n"


def bottom(V: np.ndarray | float, C_pd: float = C_PD) -> np.ndarray:
    """The lowest lobe bottom at the cutting speed V (m/s), m: the root of
    K_f b = w_n (c + b g)(1 + (c + b g) / a), g = C_pd / V, a = 2 sqrt(k m)
    (Tlusty's 2 k zeta (1 + zeta) / K_f with the damping c + b g)."""
    g = C_pd / np.asarray(V, dtype=float)
    wn = np.sqrt(STIFF / MASS)
    a = 2 * np.sqrt(STIFF * MASS)
    # (wn/a) g^2 b^2 + (wn g (1 + 2c/a) - Kf) b + wn c (1 + c/a) = 0: the smaller positive root
    A = wn * g * g / a
    B = wn * g * (1 + 2 * DAMP / a) - KF
    Cc = wn * DAMP * (1 + DAMP / a)
    with np.errstate(invalid="ignore", divide="ignore"):
        disc = B * B - 4 * A * Cc
        root = np.where(A > 0, (-B - np.sqrt(disc)) / (2 * A), -Cc / B)
    return np.where((disc >= 0) & (B < 0), root, np.inf)


def run(rpm: np.ndarray | None = None) -> dict:
    """The lobes with and without process damping, and the lobe bottoms
    against the closed form."""
    n = np.geomspace(60.0, 3000.0, 400) if rpm is None else np.asarray(rpm, float)
    damped = cl.lobes(cl.loads_model(model_text(), source="process_damping.py"), n, width_max=0.02)
    plain = cl.lobes(cl.loads_model(model_text(None), source="process_damping.py"), n, width_max=0.02)
    V = np.pi * DIAMETER * n / 60.0
    zeta = DAMP / (2 * np.sqrt(STIFF * MASS))
    b0 = 2 * STIFF * zeta * (1 + zeta) / KF
    wn = np.sqrt(STIFF / MASS)
    return {
        "damped": damped,
        "plain": plain,
        "speed": n,
        "cutting_speed": V,
        "bottom": bottom(V),
        "b0": b0,
        #: the first-order trend b - b0 = b0 (1 + 2 zeta) w_n C_pd / (K_f V): its speed scale V*, m/s
        "V_star": float((1 + 2 * zeta) * wn * C_PD / KF),
        "stable_below_rpm": float(n[np.isinf(damped.b_lim)].max()) if np.any(np.isinf(damped.b_lim)) else 0.0,
    }


if __name__ == "__main__":
    from _figures import figures_dir

    folder = figures_dir(__doc__.splitlines()[0])
    FILES.mkdir(exist_ok=True)
    (FILES / "turning.toml").write_text(model_text(None))
    (FILES / "cuts.csv").write_text(cuts_text())
    r = run()
    d = r["damped"]
    print(d.summary())
    fin = np.isfinite(d.b_lim)
    print(
        f"without process damping the envelope's minimum is {np.min(r['plain'].b_lim) * 1e3:.4f} mm"
        f" (closed form {r['b0'] * 1e3:.4f} mm); with C_pd = {C_PD:g} N/m the cut is stable at every"
        f" width up to 20 mm below {r['stable_below_rpm']:.0f} rpm, and the lobe bottoms rise like 1/V"
        f" with V* = {r['V_star']:.4f} m/s"
    )
    ratio = d.b_lim[fin] / r["bottom"][fin]
    print(f"envelope / closed-form lowest bottom: min {ratio.min():.6f} (>= 1: the bottom bounds it)")
    if folder is None:
        raise SystemExit(0)
    import matplotlib

    matplotlib.use("Agg")
    from chatterlab.plot import plot_lobes, savefig

    axes = plot_lobes(
        d,
        title="1-DOF turning with process damping (C_pd = 2e5 N/m, D = 50 mm)",
        references={
            "without process damping": (r["speed"], r["plain"].b_lim),
            "lobe bottoms, closed form (Eq. 8)": (r["speed"], r["bottom"]),
        },
    )
    out = folder / "process_damping_lobes.png"
    savefig(axes, str(out))
    print(f"wrote {out}")
