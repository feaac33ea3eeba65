"""The traverse shaper's natural frequencies against the paper's Table 4.

Builds the shipped model (``model.toml``: Table 2 with the reconstructed
geometry of the lost Fig. 2b, corrected values) and its "printed" variant
(Table 2 exactly as printed), computes the seven lowest natural frequencies
at the central slide position, and compares them with Table 4 of
Wittbrodt & Kaliński and with the reconstruction values of
``shared/traverse_shaper/geometry.md``.

Run: ``python studies/traverse_shaper/modes.py`` (prints the table and writes
``docs/figures/shaper_modes.png``).  ``tests/test_studies.py`` checks the numbers.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import chatterlab as cl

HERE = Path(__file__).resolve().parent
MODEL = HERE / "model.toml"
#: Table 4 of the seed paper (Hz), slide at the central position
TABLE4 = np.array([76.20, 84.70, 115.56, 140.52, 176.96, 217.41, 237.30])
#: values a correct implementation of the reconstruction reproduces (geometry.md, section 4)
RECONSTRUCTION = np.array([76.28, 83.34, 115.35, 137.58, 176.61, 211.26, 234.39])
RECONSTRUCTION_PRINTED = np.array([75.76, 80.56, 114.58, 127.15, 164.47, 189.95, 225.97])


def run(position: float | None = None) -> dict[str, np.ndarray]:
    """Frequencies (Hz) of the default and printed variants, 7 modes each."""
    out = {}
    for variant in (None, "printed"):
        model = cl.load_model(MODEL, variant=variant)
        out[variant or "corrected"] = cl.modes(cl.assemble(model), count=7, position=position).frequency_hz
    return out


def table(res: dict[str, np.ndarray]) -> str:
    f, p = res["corrected"], res["printed"]
    lines = [
        f"{'mode':>4} {'Table 4':>9} {'chatterlab':>11} {'vs Table 4':>11} {'vs reconstr.':>13} {'printed':>9} {'vs Table 4':>11}",
    ]
    for k in range(7):
        lines.append(
            f"{k + 1:>4} {TABLE4[k]:>9.2f} {f[k]:>11.2f} {100 * (f[k] / TABLE4[k] - 1):>+10.2f}%"
            f" {100 * (f[k] / RECONSTRUCTION[k] - 1):>+12.3f}% {p[k]:>9.2f} {100 * (p[k] / TABLE4[k] - 1):>+10.2f}%"
        )
    return "\n".join(lines)


def plot(res: dict[str, np.ndarray], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    k = np.arange(1, 8)
    fig, ax = plt.subplots(figsize=(7.5, 4))
    w = 0.27
    ax.bar(k - w, TABLE4, w, label="paper, Table 4", color="0.5")
    ax.bar(k, res["corrected"], w, label="chatterlab (corrected Table 2)", color="tab:blue")
    ax.bar(k + w, res["printed"], w, label="chatterlab (Table 2 as printed)", color="tab:orange")
    for j in range(7):
        ax.annotate(
            f"{100 * (res['corrected'][j] / TABLE4[j] - 1):+.1f}%",
            (k[j], res["corrected"][j]),
            textcoords="offset points",
            xytext=(0, 3),
            ha="center",
            fontsize=7,
        )
    ax.set_xlabel("mode")
    ax.set_ylabel("natural frequency [Hz]")
    ax.set_title("traverse shaper: natural frequencies at the central slide position")
    ax.legend(fontsize=8, loc="upper left")
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


if __name__ == "__main__":
    sys.path.insert(0, str(HERE.parent))
    from _figures import figures_dir

    folder = figures_dir(__doc__.splitlines()[0])
    res = run()
    print(table(res))
    if folder is not None:
        plot(res, folder / "shaper_modes.png")
        print(f"wrote {folder / 'shaper_modes.png'}")
