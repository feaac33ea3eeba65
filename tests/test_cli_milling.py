"""The command line on milling models (issue 12, item 7): ``lobes`` prints and
writes what :func:`chatterlab.lobes.milling_lobes` computes, ``roots`` the
Floquet multipliers, ``simulate`` the time-domain verdict, with the same
units at the edge (a_p in mm, speeds in rpm) and bad input as one line."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_clean_error

import chatterlab as cl
from chatterlab.cli import main
from chatterlab.frequency import multipliers
from chatterlab.lobes import milling_lobes, milling_loop_of

ROOT = Path(__file__).resolve().parents[1]
ONE = ROOT / "studies" / "milling" / "benchmark_1dof.toml"


@pytest.fixture(scope="module")
def bench():
    m = cl.load_model(ONE)
    loop = milling_loop_of(cl.assemble(m).at())
    return m, loop, loop.milling


def test_lobes_csv_is_the_api_result(bench, tmp_path, capsys):
    m, S, mill = bench
    out = tmp_path / "l.csv"
    code = main(["lobes", str(ONE), "--speed", "8000", "20000", "--points", "7", "--width-max", "10",
                 "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    ref = milling_lobes(S, np.linspace(8000.0, 20000.0, 7), depth_max=0.01)
    with open(out) as fh:
        rows = list(csv.reader(fh))
    head, body = rows[0], rows[1:]
    # SI, name [unit], no comment line: what every chatterlab CSV is (pandas reads it as it is)
    # one column scheme for every lobe diagram (tests/test_lobes.py), the limit named a_lim
    assert head == ["speed [rpm]", "delay [s]", "a_lim [m]", "chatter_frequency [Hz]", "lobe [1]",
                    "certified [m]", "multiplier_abs [1]", "multiplier_arg [rad]", "error [m]",
                    "width_max [m]", "scan_step [m]", "band_low [Hz]", "band_high [Hz]", "kind", "claim",
                    "basis"]  # fmt: skip
    col = {h: i for i, h in enumerate(head)}
    assert {(float(r[col["width_max [m]"]]), float(r[col["scan_step [m]"]])) for r in body} == {
        (ref.width_max, ref.scan_step)
    }
    got = np.array([float(r[col["a_lim [m]"]]) for r in body])
    # the same computation through the CLI: the CSV holds repr() of the floats, so exactly equal
    np.testing.assert_array_equal(got, ref.a_lim)
    np.testing.assert_array_equal([float(r[0]) for r in body], ref.speed)
    np.testing.assert_array_equal([float(r[1]) for r in body], 60.0 / (mill.teeth * ref.speed))
    assert [r[head.index("kind")] for r in body] == [k or "none" for k in ref.kind]


def test_roots_json_is_the_floquet_result(bench, tmp_path, capsys):
    m, S, mill = bench
    out = tmp_path / "r.json"
    code = main(
        ["roots", str(ONE), "--width", "2", "--speed", "18000", "--format", "json", "--out", str(out)]
    )
    assert code == 0, capsys.readouterr().err
    d = json.loads(out.read_text())
    ref = multipliers(S, 18000.0, 2e-3)
    # the one roots contract (docs/cli.md): the roots are the Floquet exponents ln(mu)/T
    assert d["kind"] == "roots" and d["process"] == "milling" and d["verdict"] == "unstable"
    assert d["chatterlab"] == cl.__version__ and d["critical"]["type"] == ref.kind
    assert d["spectral_radius"] == ref.spectral_radius
    assert d["abscissa_per_s"] == pytest.approx(np.log(ref.spectral_radius) / ref.period, rel=1e-12)
    assert d["roots"][0]["real_per_s"] == pytest.approx(d["abscissa_per_s"], rel=1e-12)
    # every field of the contract is there ("mesh": only for a model with beams, not milling)
    turning = set(json.loads(_turning_roots_json(tmp_path, capsys))) - {"mesh"}
    assert turning <= set(d), turning - set(d)


def test_simulate_above_and_below_the_limit(bench, capsys):
    """At 18000 rpm the Floquet limit is a flip lobe near 1.3 mm (a_e/D = 0.05): the nonlinear run at
    2 mm saturates on a period-two orbit, the one at 1 mm settles on the forced periodic motion, and
    the linear run at 2 mm grows at ln|mu| per period."""
    m, S, mill = bench
    a_lim = milling_lobes(S, np.array([18000.0]), depth_max=0.01).a_lim[0]
    assert 1e-3 < a_lim < 2e-3
    main(["simulate", str(ONE), "--width", "2", "--speed", "18000", "--revolutions", "60"])
    assert "flip chatter" in capsys.readouterr().out.splitlines()[0]
    main(["simulate", str(ONE), "--width", "1", "--speed", "18000", "--revolutions", "60"])
    assert capsys.readouterr().out.splitlines()[0].endswith(": stable")
    main(["simulate", str(ONE), "--width", "2", "--speed", "18000", "--revolutions", "60", "--linear"])
    out = capsys.readouterr().out
    mu = multipliers(S, 18000.0, 2e-3).spectral_radius
    g = float(out.split("growth per period")[1].split()[0])
    # Newmark at 150 steps per period: phase error (w h)^2 / 12 ~ 2e-4 per period; the fit's own spread
    # over the last 60 periods is reported as growth_error ~1e-3 (docs/time-domain.md)
    assert g == pytest.approx(np.log(mu), abs=3e-3)


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (
            ["lobes", str(ONE), "--speed", "8000", "9000", "--positions", "0", "1", "3"],
            ["--positions", "milling"],
        ),
        (["roots", str(ONE), "--width", "1", "--delay", "0.003"], ["--speed"]),
        (["simulate", str(ONE), "--speed", "9000"], ["--width"]),
        (
            [
                "lobes",
                str(ROOT / "studies" / "traverse_shaper" / "model.toml"),
                "--speed",
                "0.1",
                "1",
                "--method",
                "sdm",
            ],
            ["--method sdm", "milling"],
        ),  # fmt: skip
    ],
)
def test_bad_milling_options_are_one_line(argv, words, capsys):
    assert_clean_error(main(argv), capsys.readouterr().err, *words)


def test_nonlinear_without_feed_is_refused(tmp_path, capsys):
    text = ONE.read_text().replace("feed_per_tooth = 1.0e-4", "feed_per_tooth = 0.0")
    (tmp_path / "m.toml").write_text(text)
    code = main(["simulate", str(tmp_path / "m.toml"), "--width", "1", "--speed", "9000"])
    assert_clean_error(code, capsys.readouterr().err, "feed_per_tooth", "--linear")


def test_a_multiplier_within_its_error_of_one_is_undetermined():
    """|mu| - 1 smaller than the convergence check: neither stable nor chatter is claimed."""
    from chatterlab.frequency import Multipliers

    def r(error: float) -> Multipliers:
        return Multipliers(mu=np.array([1j * (1.0 - 1e-12)]), critical=1j * (1.0 - 1e-12), kind="hopf",
                           spectral_radius=1.0 - 1e-12, stable=True, error=error, frequency_hz=1.0,
                           method="spectral", resolution="", period=1.0, rpm=1.0, depth=1e-3)  # fmt: skip

    assert r(1e-10).verdict == "undetermined" and r(1e-10).to_dict()["verdict"] == "undetermined"
    assert r(1e-14).verdict == "stable" and r(1e-14).verdict_line().startswith("stable")


def _turning_roots_json(tmp_path, capsys) -> str:
    out = tmp_path / "turning.json"
    shaper = ROOT / "studies" / "traverse_shaper" / "model.toml"
    assert (
        main(
            ["roots", str(shaper), "--width", "0.2", "--speed", "0.5", "--format", "json", "--out", str(out)]
        )
        == 0
    )
    capsys.readouterr()
    return out.read_text()
