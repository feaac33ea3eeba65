"""Lobes with error bars for the tap-test machine (docs/uncertainty.md).

The tap test's modal fit (docs/tap-test.md) reports each mode's natural
frequency and damping ratio with its standard deviation; carried into a
modal model (``uncertain_modal_model``) with a cutting-force coefficient
known to 10 % (lognormal), the turning lobes of the machine become a
probabilistic diagram: the probability of chatter over speed and width,
the 5/50/95 % lobes, the probability of chatter at two operating points,
Sobol' indices that say whether the tap test or the cutting test is worth
repeating, and the widest cut at a 1 % risk.

Run ``python studies/tap_test/risk.py`` (figures to
docs/figures/uncertainty_*.png; about 5 minutes on 2 cores);
``run(None, quick=True)`` is a short version.  Returns its numbers.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
FIGURES = HERE.parents[1] / "docs" / "figures"
sys.path.insert(0, str(HERE))
from walkthrough import F_FIT, KF, turning_tables  # noqa: E402

sys.path.pop(0)

#: the cutting test: Kf known to 10 % (a lognormal, so it stays positive)
KF_CV = 0.10
#: operating points (rpm, m): below the top of the highest lobe (the fitted model's 0.893 mm at
#: 27 472 rpm) and at the bottom of a lobe (its 0.158 mm at 12 843 rpm)
POINTS = [(27500.0, 0.80e-3), (12850.0, 0.15e-3)]
RISK = 0.01


def uncertain_model() -> Any:
    """The fitted tool point as [[mode]] tables with the fit's uncertainty,
    the turning cut of the walkthrough, K_f lognormal with cv 10 %."""
    from chatterlab.structure import FRF, fit_modes
    from chatterlab.uncertainty import uncertain_modal_model

    frf = FRF.read(HERE / "tool_point.csv")
    fit = fit_modes(frf, band=(2 * np.pi * 100.0, 2 * np.pi * F_FIT))
    model = uncertain_modal_model(
        fit,
        name="tap-test machine, fit uncertainty",
        tables=turning_tables("tool"),
        uncertainty={"coupling.cut.Kf": {"distribution": "lognormal", "mean": KF, "cv": KF_CV}},
    )
    return fit, model


def toml_text(raw: dict[str, Any]) -> str:
    """A model file's text for the tables of ``raw`` (the few TOML forms a
    modal model with [uncertainty] needs: tables, arrays of tables, inline
    tables, numbers, strings, lists)."""
    import json

    def val(x: Any) -> str:
        if isinstance(x, dict):
            return "{ " + ", ".join(f"{json.dumps(k)} = {val(v)}" for k, v in x.items()) + " }"
        if isinstance(x, list):
            return "[" + ", ".join(val(v) for v in x) + "]"
        if isinstance(x, bool):
            return "true" if x else "false"
        return json.dumps(x) if isinstance(x, str) else repr(float(x))

    def table(name: str, t: dict[str, Any]) -> list[str]:
        return [f"[{name}]"] + [f"{json.dumps(k) if '.' in k else k} = {val(v)}" for k, v in t.items()]

    lines: list[str] = []
    for key, t in raw.items():
        if isinstance(t, list):
            for item in t:
                lines += [f"[[{key}]]"] + [f"{k} = {val(v)}" for k, v in item.items()] + [""]
        else:
            groups = t.pop("group", []) if key == "uncertainty" else []
            lines += table(key, t) + [""]
            for g in groups:
                lines += [f"[[{key}.group]]"] + [f"{k} = {val(v)}" for k, v in g.items()] + [""]
    return "\n".join(lines)


def write_model(path: Path = HERE / "fit_uncertain.toml") -> Path:
    """``fit_uncertain.toml``: :func:`uncertain_model` as a model file, for
    ``chatterlab risk`` (docs/uncertainty.md); ``--check``: the committed
    file is still what this makes."""
    import json

    _, model = uncertain_model()
    head = (
        "# The tap-test machine's fitted tool point (docs/tap-test.md) as a modal model with the fit's own\n"
        "# uncertainty and a cutting coefficient known to 10 %: written by studies/tap_test/risk.py\n"
        "# (write_model); docs/uncertainty.md\n\n"
    )
    raw = json.loads(model.raw)
    raw["model"]["description"] = (
        "modal model of the fit of studies/tap_test/tool_point.csv, with its uncertainty"
    )
    text = head + toml_text(raw)
    path.write_text(text)
    return path


def run(out: Path | None = FIGURES, *, quick: bool = False, jobs: int = 2) -> dict[str, Any]:
    from chatterlab.uncertainty import risk

    fit, model = uncertain_model()
    rpm = np.linspace(3000.0, 30000.0, 60 if quick else 300)
    res = risk(
        model,
        rpm,
        width_max=1.5e-3,
        samples=16 if quick else 512,
        replicates=2 if quick else 8,
        points=POINTS,
        sensitivity=True,
        factors={"tap test (fit)": ["mode.*"], "cutting test (Kf)": ["coupling.*"]},
        jobs=jobs,
        n_frequencies=500,
        progress=not quick,
    )
    s1, st = res.sobol["b_min"]
    out_numbers = {
        "summary": res.summary(),
        "n_samples": res.n_samples,
        "b_min_mean_mm": 1e3 * float(res.b_min.value),
        "b_min_quantiles_mm": (1e3 * np.asarray(res.b_min_quantiles.value)).tolist(),
        "nominal_min_mm": 1e3 * res.nominal.minimum["width"],
        "p_chatter": np.asarray(res.p_chatter.value).tolist(),
        "p_chatter_interval": [
            np.asarray(res.p_chatter.low).tolist(),
            np.asarray(res.p_chatter.high).tolist(),
        ],
        "sobol_first": dict(zip(res.factor_names, np.asarray(s1.value).tolist(), strict=True)),
        "sobol_total": dict(zip(res.factor_names, np.asarray(st.value).tolist(), strict=True)),
        "recommend": res.recommend(RISK),
        "fit_std_hz": (fit.std_omega / (2 * np.pi)).tolist(),
        "fit_std_damping": fit.std_damping.tolist(),
    }
    if out is not None:
        import matplotlib

        matplotlib.use("Agg")
        from chatterlab.plot import savefig

        savefig(res.plot(risk=RISK), str(out / "uncertainty_map.png"))
        savefig(res.plot_sensitivity(), str(out / "uncertainty_sobol.png"))
    return out_numbers


if __name__ == "__main__":
    import json

    if "--write-model" in sys.argv:
        print(f"wrote {write_model()}")
        raise SystemExit(0)
    r = run()
    print(r.pop("summary"))
    print(json.dumps(r, indent=1))
