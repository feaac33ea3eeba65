"""Bad input to the probabilistic lobes (issue 24, "Done means"): every
refusal is one line and status 2, naming the entry or option and the fix --
a negative standard deviation, a distribution on a non-numeric field, a
covariance that is not positive semi-definite, a sample count of 0 or
10^12, and the rest of what the [uncertainty] table and `chatterlab risk`
take; refused before any lobe diagram is computed."""

from __future__ import annotations

import pytest
from conftest import assert_clean_error

from chatterlab.cli._main import main

BASE = """
[[mode]]
id = "x1"
frequency_hz = 500.0
damping_ratio = 0.03
stiffness = 1.0e7
direction = "tool.x"

[[point]]
id = "tip"
coords = { x = "tool.x" }

[[coupling]]
id = "cut"
a = "tip"
b = "ground"
model = "regenerative"
width_ref = 0.001
Kf = 2.0e9

[process]
kind = "turning"
rpm = 3000.0
"""
GOOD = '[uncertainty]\n"coupling.cut.Kf" = { distribution = "lognormal", cv = 0.1 }\n'
RISK = ["--speed", "2000", "12000", "--points", "5", "--width-max", "2", "--backend", "serial", "--quiet"]


def run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def write(tmp_path, table: str) -> str:
    p = tmp_path / "m.toml"
    p.write_text(BASE + table)
    return str(p)


TABLES = {
    "negative std": (
        '[uncertainty]\n"mode.x1.stiffness" = { distribution = "normal", std = -1e5 }\n',
        ['"mode.x1.stiffness"', "std: must be >= 0"],
    ),
    "negative cv": (
        '[uncertainty]\n"coupling.cut.Kf" = { distribution = "lognormal", cv = -0.1 }\n',
        ["cv: must be >= 0"],
    ),
    "non-numeric field": (
        '[uncertainty]\n"coupling.cut.model" = { distribution = "normal", std = 1.0 }\n',
        ["a distribution is for a numeric field", "'regenerative'"],
    ),
    "list field": (
        '[uncertainty]\n"point.tip.coords" = { distribution = "normal", std = 1.0 }\n',
        ["is a list or table, not a number"],
    ),
    "covariance not PSD": (
        '[uncertainty]\n[[uncertainty.group]]\nparameters = ["mode.x1.stiffness", "mode.x1.damping_ratio"]\n'
        "covariance = [[1e10, 2e3], [2e3, 1e-6]]\n",
        ["group #1", "covariance: is not positive semi-definite", "smallest eigenvalue"],
    ),
    "covariance not symmetric": (
        '[uncertainty]\n[[uncertainty.group]]\nparameters = ["mode.x1.stiffness", "mode.x1.damping_ratio"]\n'
        "covariance = [[1e10, 1e4], [0.0, 1e-6]]\n",
        ["covariance: must be symmetric"],
    ),
    "correlation diagonal": (
        '[uncertainty]\n"mode.x1.stiffness" = { distribution = "normal", cv = 0.1 }\n'
        '"mode.x1.damping_ratio" = { distribution = "normal", cv = 0.1 }\n'
        '[[uncertainty.group]]\nparameters = ["mode.x1.stiffness", "mode.x1.damping_ratio"]\n'
        "correlation = [[1.0, 0.5], [0.5, 2.0]]\n",
        ["the diagonal must be 1"],
    ),
    "covariance member with its own distribution": (
        '[uncertainty]\n"mode.x1.stiffness" = { distribution = "normal", cv = 0.1 }\n'
        '[[uncertainty.group]]\nparameters = ["mode.x1.stiffness", "mode.x1.damping_ratio"]\n'
        "covariance = [[1e10, 0.0], [0.0, 1e-6]]\n",
        ["has its own distribution and is in a covariance group"],
    ),
    "unknown distribution": (
        '[uncertainty]\n"coupling.cut.Kf" = { distribution = "gamma", std = 1e8 }\n',
        ["distribution: must be one of normal, lognormal, uniform"],
    ),
    "misspelt field": (
        '[uncertainty]\n"coupling.cut.Kf" = { distribution = "normal", stdev = 1e8 }\n',
        ["unknown field 'stdev'", "did you mean 'std'?"],
    ),
    "both std and cv": (
        '[uncertainty]\n"coupling.cut.Kf" = { distribution = "normal", std = 1e8, cv = 0.1 }\n',
        ["exactly one of std"],
    ),
    "uniform reversed": (
        '[uncertainty]\n"coupling.cut.Kf" = { distribution = "uniform", low = 2.2e9, high = 1.8e9 }\n',
        ["must not exceed high"],
    ),
    "mean outside the truncation": (
        '[uncertainty]\n"mode.x1.damping_ratio" = { distribution = "normal", std = 0.01, lower = 0.05 }\n',
        ["outside the truncation"],
    ),
    "lognormal of a negative mean": (
        '[uncertainty]\n"coupling.cut.Kf" = { distribution = "lognormal", mean = -1.0, std = 1.0 }\n',
        ["its mean must be > 0"],
    ),
    "no such item": (
        '[uncertainty]\n"coupling.cutt.Kf" = { distribution = "normal", cv = 0.1 }\n',
        ["addresses nothing", "no [[coupling]] with id 'cutt'", "known: cut"],
    ),
    "not a path": (
        '[uncertainty]\n"Kf" = { distribution = "normal", cv = 0.1 }\n',
        ["is not a parameter path"],
    ),
    "a field left at its default": (
        '[uncertainty]\n"coupling.cut.Kv" = { distribution = "normal", std = 10.0 }\n',
        ["does not write this field: give the distribution's mean"],
    ),
    "empty table": ("[uncertainty]\n", ["is empty"]),
    "in two groups": (
        '[uncertainty]\n"mode.x1.stiffness" = { distribution = "normal", cv = 0.1 }\n'
        '"mode.x1.damping_ratio" = { distribution = "normal", cv = 0.1 }\n'
        '"coupling.cut.Kf" = { distribution = "normal", cv = 0.1 }\n'
        '[[uncertainty.group]]\nparameters = ["mode.x1.stiffness", "mode.x1.damping_ratio"]\n'
        "correlation = [[1.0, 0.5], [0.5, 1.0]]\n"
        '[[uncertainty.group]]\nparameters = ["mode.x1.stiffness", "coupling.cut.Kf"]\n'
        "correlation = [[1.0, 0.5], [0.5, 1.0]]\n",
        ["in two groups"],
    ),
}


@pytest.mark.parametrize("case", sorted(TABLES))
def test_a_bad_uncertainty_table_is_one_line_naming_the_entry(case, tmp_path, capsys):
    """Refused where the model is read, so by every command (check, risk)."""
    table, words = TABLES[case]
    path = write(tmp_path, table)
    for argv in (["check", path], ["risk", path, *RISK]):
        code, _, err = run(capsys, *argv)
        assert_clean_error(code, err, "[uncertainty]", *words)


OPTIONS = {
    "--samples 0": (["--samples", "0"], ["samples must be at least 16"]),
    "--samples 1e12": (["--samples", "1e12"], ["samples 1e+12 is more than the largest accepted, 1e+06"]),
    "--samples 2.5": (["--samples", "2.5"], ["samples must be a whole number"]),
    "--replicates 1": (["--replicates", "1"], ["replicates must be a whole number >= 2"]),
    "--seed -1": (["--seed", "-1"], ["seed must be a whole number >= 0"]),
    "--quantiles 100": (["--quantiles", "5", "100"], ["--quantiles is a probability in %"]),
    "--risk 150": (["--risk", "150"], ["--risk is a probability in %"]),
    "--tol 0": (["--tol", "0"], ["--tol is a probability in %"]),
    "--level 100": (["--level", "100"], ["--level is a probability in %"]),
    "point above the ceiling": (
        ["--point", "5000", "3"],
        ["operating point width 3 mm is above width_max 2 mm"],
    ),
    "point at speed 0": (["--point", "0", "0.3"], ["operating point #1 speed must be > 0"]),
    "--plot-sobol alone": (["--plot-sobol", "s.png"], ["add --sensitivity"]),
    "--factor without =": (["--sensitivity", "--factor", "cut"], ["--factor 'cut': write NAME=PATTERN"]),
    "--factor naming nothing": (["--sensitivity", "--factor", "tap=mode.*"], ["names no uncertain field"]),
    "--widths 1": (["--widths", "1"], ["--widths must be >= 2"]),
}


@pytest.mark.parametrize("case", sorted(OPTIONS))
def test_a_bad_option_is_one_line(case, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    extra, words = OPTIONS[case]
    code, out, err = run(capsys, "risk", write(tmp_path, GOOD), *RISK, *extra)
    assert_clean_error(code, err, *words)
    assert not list(tmp_path.glob("*.png"))


def test_a_model_without_a_table_and_a_distribution_the_model_refuses(tmp_path, capsys):
    """No [uncertainty]: say how to add one.  A damping ratio normal with a
    standard deviation as large as itself reaches negative values: refused
    at its 1e-6 quantile before any sample, with the fix (truncate)."""
    code, _, err = run(capsys, "risk", write(tmp_path, ""), *RISK)
    assert_clean_error(code, err, "has no [uncertainty] table", "docs/uncertainty.md")
    table = '[uncertainty]\n"mode.x1.damping_ratio" = { distribution = "normal", std = 0.03 }\n'
    code, _, err = run(capsys, "risk", write(tmp_path, table), *RISK)
    assert_clean_error(code, err, "at its 1e-06 quantile", "mode.x1.damping_ratio = -0.", "truncate it")
