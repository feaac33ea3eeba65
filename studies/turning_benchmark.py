"""A single-degree-of-freedom turning system whose lobes are known in closed form.

m x'' + c x' + k x = -K_f b [x(t) - x(t - T)],  T = 60/n.

Tlusty's boundary: along lobe k the chatter frequency w > w_n satisfies
w T = eps(w) + 2 pi k with eps = 3 pi + 2 arg G(jw), and
b_lim = -1 / (2 K_f Re G(jw)); its minimum is 2 k zeta (1 + zeta) / K_f.
This study builds the same system as a chatterlab model file, computes the
lobes by chatterlab's D-subdivision, and compares every envelope point with
the closed form (solved independently per speed and lobe with brentq).

Run: ``python studies/turning_benchmark.py`` (prints the errors and writes
``docs/figures/turning_lobes.png``).  ``tests/test_studies.py`` checks them.

References: J. Tlusty, M. Polacek (1963); Y. Altintas, *Manufacturing
Automation*, 2nd ed., Cambridge University Press, 2012, ch. 3.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

import chatterlab as cl
from chatterlab.lobes._diagram import lobes

MASS, STIFF, DAMP, KF = 2.0, 2.0e7, 400.0, 2.0e9  # kg, N/m, N s/m, N/m^2

MODEL = f"""
[model]
name = "1-DOF turning benchmark"
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
rpm = 3000
"""


def G(w: np.ndarray | float) -> np.ndarray:
    return 1.0 / (STIFF - MASS * np.asarray(w) ** 2 + 1j * DAMP * np.asarray(w))


def tlusty(rpm: np.ndarray, kmax: int = 80) -> np.ndarray:
    """The closed-form envelope b_lim(n) (m), solved per speed and lobe."""
    wn = np.sqrt(STIFF / MASS)
    out = np.full(rpm.size, np.inf)
    for i, n in enumerate(rpm):
        T = 60.0 / n
        for k in range(kmax):

            def f(w: float, T: float = T, k: int = k) -> float:
                return w * T - (3 * np.pi + 2 * np.angle(G(w))) - 2 * np.pi * k

            a, b = wn * (1 + 1e-9), wn * 5
            if f(a) * f(b) < 0:
                w = brentq(f, a, b, xtol=1e-14, rtol=1e-15)
                out[i] = min(out[i], -1.0 / (2 * KF * G(w).real))
    return out


def run(rpm: np.ndarray | None = None) -> dict:
    n = np.linspace(2000.0, 12000.0, 300) if rpm is None else rpm
    model = cl.loads_model(MODEL, source="turning_benchmark.py")
    d = lobes(cl.assemble(model).at(), n, width_max=0.05, verify=2)
    ref = tlusty(n)
    zeta = DAMP / (2 * np.sqrt(STIFF * MASS))
    return {
        "diagram": d,
        "reference": ref,
        "max_rel_error": float(np.max(np.abs(d.b_lim / ref - 1))),
        "minimum": d.absolute_minimum["width"],
        "minimum_closed_form": 2 * STIFF * zeta * (1 + zeta) / KF,
        "verified": d.verified,
    }


if __name__ == "__main__":
    from _figures import figures_dir

    folder = figures_dir(__doc__.splitlines()[0])
    r = run()
    print(r["diagram"].summary())
    print(f"max relative error of the envelope against the closed form: {r['max_rel_error']:.2e}")
    print(
        f"minimum b_lim {r['minimum'] * 1e3:.9g} mm, closed form 2 k zeta (1 + zeta) / K_f = {r['minimum_closed_form'] * 1e3:.9g} mm"
    )
    if folder is None:
        raise SystemExit(0)
    import matplotlib

    matplotlib.use("Agg")
    from chatterlab.plot import plot_lobes, savefig

    d = r["diagram"]
    axes = plot_lobes(
        d,
        title="1-DOF turning: chatterlab lobes and Tlusty's closed form",
        references={"closed form (Tlusty), at the requested speeds": (d.speed, r["reference"])},
    )
    out = folder / "turning_lobes.png"
    savefig(axes, str(out))
    print(f"wrote {out}")
