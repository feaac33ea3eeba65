"""Issue 20, item 5: the pictures say what they show.  Each test reads the
figure back (titles, labels, legends, panel counts, data ranges)."""

from __future__ import annotations

from types import SimpleNamespace

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from chatterlab import plot as P  # noqa: E402


@pytest.fixture(autouse=True)
def _close():
    yield
    plt.close("all")


def _sim(terms: str, amp: float):
    t = np.linspace(0.0, 1.0, 2001)
    x = amp * 1e-6 * np.sin(2 * np.pi * 80 * t)
    return SimpleNamespace(
        t=t,
        data={"rfe5.x": x, "rfe5.y": 0.5 * x},
        terms=terms,
        width=2e-3,
        delay=1.5,
        meta={},
        model="traverse shaper",
        in_cut=(t > 0.1) & (t < 0.9),
        spectrum=lambda n, window=None, x=x: (np.fft.rfftfreq(t.size, t[1]), np.abs(np.fft.rfft(x)) / t.size),
    )


def test_histories_of_several_cases_are_titled_with_every_case_and_in_micrometres():
    sims = [_sim("none", 30), _sim("pd", 20), _sim("pdo", 20)]
    axes = P.plot_histories(sims, ["rfe5.x", "rfe5.y"])
    title = axes[0].get_title()
    assert "none / pd / pdo" in title  # was "feedback none"
    assert axes[0].get_ylabel() == "rfe5.x [µm]"  # was "[um]"


def test_simulate_all_draws_one_column_per_case_none_hiding_another():
    sims = [_sim("none", 30), _sim("pd", 20), _sim("pdo", 20)]
    grid = P.plot_cases(sims, ["rfe5.x", "rfe5.y"])
    assert grid.shape == (3, 3)
    assert [grid[0, j].get_title() for j in range(3)] == ["feedback none", "feedback pd", "feedback pdo"]
    for j in range(3):  # one case per panel
        for i in range(3):
            assert len([ln for ln in grid[i, j].lines if ln.get_gid() in ("history", "spectrum")]) == 1
    assert "none / pd / pdo" in grid[0, 0].figure._suptitle.get_text()
    assert grid[0, 0].get_ylim() == grid[0, 2].get_ylim()  # one scale per row
    assert "µm" in grid[2, 0].get_ylabel()


def _drawing(k: int):
    xy = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    shape = np.random.default_rng(0).normal(size=(k, 3, 2))
    return {"members": [{"kind": "beam", "id": "b", "xy": xy, "shape": shape}],
            "frequency_hz": np.arange(1, k + 1) * 50.0, "model": "m"}  # fmt: skip


def test_mode_shapes_draw_every_mode_asked_for():
    ax = P.plot_mode_shapes(_drawing(7))
    assert len(ax) == 7  # --count 7 drew 6
    legends = [a.get_legend().get_texts()[0].get_text() for a in ax]
    assert legends[-1].startswith("mode 7: 350.00 Hz")


def test_frequencies_of_a_modal_model_have_no_stray_legend_and_say_their_values():
    ax = P.plot_frequencies(np.array([922.0, 922.0]), damping_ratio=np.array([0.011, 0.011]), title="m")
    assert ax.get_legend() is None  # was a legend "chatterlab"
    texts = [t.get_text() for t in ax.texts if t.get_gid() == "frequency-label"]
    assert texts == ["922 Hz\nζ = 0.011"] * 2
    ax = P.plot_frequencies(np.array([76.3, 83.3]), reference=np.array([76.2, 84.7]))
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["computed", "reference"]


def _frf(f, z, label, closed=False):
    return SimpleNamespace(frequency_hz=f, data=z[None, None, :], outputs=("p.x",), inputs=("p.x",),
                           label=label, unit="m/N", closed_loop=closed, width=None, delay=None,
                           position=None, peaks=lambda o, i, n: [])  # fmt: skip


def test_a_coarsely_sampled_delayed_loop_phase_is_not_unwrapped_into_whole_turns():
    f = np.linspace(1.0, 300.0, 2000)
    z = 1e-7 * np.exp(-2j * np.pi * f * 1.5)  # turns once per 0.67 Hz: 4.5 points a turn
    ax_m, ax_p = P.plot_frf([_frf(f, z, "closed loop", True)])
    ph = np.asarray(ax_p.lines[0].get_ydata())
    assert ph.min() >= -180 - 1e-9 and ph.max() <= 180 + 1e-9  # np.unwrap gave spurious turns
    assert "180" in ax_p.get_ylabel()


def test_frf_pairs_draws_every_output():
    f = np.linspace(1.0, 100.0, 400)
    z = 1.0 / (1.0 - (f / 50) ** 2 + 0.02j * f / 50)
    r = SimpleNamespace(frequency_hz=f, data=np.stack([z, 2 * z])[:, None, :], outputs=("a.x", "a.y"),
                        inputs=("a.x",), label="open loop", unit="m/N", closed_loop=False, position=None,
                        peaks=lambda o, i, n: [])  # fmt: skip
    axs = P._frf.plot_frf_pairs([r], title="m")
    titles = [a.get_title() for a in axs[::2]]
    assert titles == ["m: a.x / a.x", "m: a.y / a.x"]  # two --output plotted only the first
    np.testing.assert_allclose(axs[2].lines[0].get_ydata(), np.abs(2 * z))


def test_frf_with_a_plot_prints_no_table(tmp_path, capsys):
    from chatterlab.cli._main import main

    model = "studies/traverse_shaper/model.toml"
    code = main(["frf", model, "--input", "rfe5.x", "--output", "rfe5.x", "--points", "50",
                 "--plot", str(tmp_path / "f.png")])  # fmt: skip
    assert code == 0
    out = capsys.readouterr().out
    # the summary and "wrote" lines, and (a model with beams) the resonances' mesh line: no table
    rest = [ln for ln in out.splitlines() if not ln.startswith("mesh: ")]
    assert "frequency [Hz]" not in out and len(rest) <= 2 and "mesh: 6 beam elements" in out
