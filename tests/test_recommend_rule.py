"""The shop floor's route: the chatter frequency of a recording (spindle
harmonics removed) and the chatter-frequency rule.

Oracles: a synthetic signal with a known chatter frequency among strong
spindle harmonics; chatterlab's own time domain chattering -- a turning cut
(the rightmost characteristic root's imaginary part) and a linear milling
run (the critical Floquet multiplier's frequencies (arg mu + 2 pi k) / tau)
-- each mapped through the Newmark (trapezoidal) rule's exact frequency
distortion of an oscillator, w_h = (2 / h) atan(w h / 2) (Hughes, *The
Finite Element Method*, 2000, sec. 9.3), and compared within the record's
resolution 1 / duration; the rule's speeds have the tooth period j / f_c to
round-off, and its verdicts are the lobes'.
"""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest
from conftest import turning_text

import chatterlab as cl
from chatterlab.errors import InputError
from chatterlab.selection import ChatterFrequency, SpeedRule, chatter_frequency, chatter_rule, read_recording
from chatterlab.selection._spectrum import MIN_REVOLUTIONS, NOTCH

FS, DURATION, RPM, TEETH = 20000.0, 0.5, 10000.0, 2
F_SP = RPM / 60.0
#: refined-peak accuracy, bins of 1/D: the log-parabola fit of a Blackman-Harris main lobe sampled
#: at 1/4 bin is biased by < 1e-4 bin, and the harmonics' side lobes (-92 dB, i.e. 2.5e-5, times
#: amplitude ratios up to 30) shift it by < 1e-3 bin
PEAK_BINS = 2e-3


def _signal(
    f_c: float, amp: float = 0.1, seed: int = 0, harmonics: int = 50
) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(int(DURATION * FS)) / FS
    x = sum(
        (3.0 / m) * np.sin(2 * np.pi * m * F_SP * t + rng.uniform(0, 2 * np.pi)) for m in range(1, harmonics)
    )
    return t, x + amp * np.sin(2 * np.pi * f_c * t + rng.uniform(0, 2 * np.pi))


# ------------------------------------------------------------------------------ harmonics removed
@pytest.mark.parametrize("f_c", [951.3, 1204.7, 2 * F_SP + (NOTCH + 1.5) / DURATION])
def test_known_chatter_frequency_among_strong_harmonics(f_c):
    """The chatter line is 30 times weaker than the spindle's first harmonic and weaker than
    every harmonic up to the 15th; the last case lies 1.5 bins outside a harmonic's notch."""
    cf = chatter_frequency(_signal(f_c), spindle_hz=F_SP, teeth=TEETH)
    assert cf.resolution_hz == pytest.approx(1 / DURATION)
    assert abs(cf.frequency_hz - f_c) <= PEAK_BINS / DURATION, cf.frequency_hz - f_c
    assert cf.amplitude == pytest.approx(0.1, rel=1e-3)
    # every harmonic that was found was removed, none of them is the answer
    m = np.rint(cf.removed_hz / F_SP)
    assert np.all(np.abs(cf.removed_hz - m * F_SP) <= NOTCH / DURATION)
    assert cf.tooth_hz == TEETH * F_SP


def test_harmonics_only_is_no_chatter():
    t, x = _signal(951.3, amp=0.0)
    cf = chatter_frequency((t, x), spindle_hz=F_SP, teeth=TEETH)
    assert not cf.found and math.isnan(cf.frequency_hz)
    assert "no chatter" in cf.summary()
    with pytest.raises(InputError, match="no chatter frequency found"):
        chatter_rule(cf, RPM, teeth=TEETH)


def test_wav_and_csv_recordings(tmp_path):
    from scipy.io import wavfile

    t, x = _signal(951.3)
    pcm = np.round(x / np.max(np.abs(x)) * 32000).astype(np.int16)
    stereo = np.column_stack([np.zeros_like(pcm), pcm])
    wavfile.write(tmp_path / "cut.wav", int(FS), stereo)
    cf = chatter_frequency(tmp_path / "cut.wav", spindle_hz=F_SP, teeth=TEETH, channel=1)
    # 16-bit rounding adds white noise 96 dB down: the peak moves far less than the bound above
    assert abs(cf.frequency_hz - 951.3) <= PEAK_BINS / DURATION
    with open(tmp_path / "cut.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["time [s]", "acceleration [m/s^2]"])
        w.writerows(zip(t.tolist(), x.tolist(), strict=True))
    t2, x2 = read_recording(tmp_path / "cut.csv")
    np.testing.assert_array_equal(x2, x)
    cf2 = chatter_frequency(str(tmp_path / "cut.csv"), spindle_hz=F_SP, teeth=TEETH)
    assert abs(cf2.frequency_hz - 951.3) <= PEAK_BINS / DURATION


@pytest.mark.parametrize(
    ("make", "words"),
    [
        (lambda p: p.write_text("not a wav"), ["not a readable WAV file"]),
        (lambda p: None, ["file not found"]),
    ],
)
def test_unreadable_wav(tmp_path, make, words):
    p = tmp_path / "bad.wav"
    make(p)
    with pytest.raises(InputError) as e:
        chatter_frequency(p, spindle_hz=F_SP)
    assert "\n" not in str(e.value) and all(w in str(e.value) for w in words)


def test_recording_refusals(tmp_path):
    t, x = _signal(951.3)
    n_short = int((MIN_REVOLUTIONS - 1) / F_SP * FS)
    with pytest.raises(InputError, match="record at least"):  # too short to resolve the harmonics
        chatter_frequency((t[:n_short], x[:n_short]), spindle_hz=F_SP, teeth=TEETH)
    with pytest.raises(InputError, match="Nyquist"):  # 16 teeth at 5 kHz: tooth passing 2.7 kHz > 2.5 kHz
        chatter_frequency((t[::4], x[::4]), spindle_hz=F_SP, teeth=TEETH * 8)
    with pytest.raises(InputError, match="constant"):
        read_recording(_csv(tmp_path / "flat.csv", t, np.ones_like(t)))
    with pytest.raises(InputError, match="equal steps"):
        read_recording(_csv(tmp_path / "uneven.csv", t**1.01, x))
    with pytest.raises(InputError, match="channel 3"):
        read_recording(_csv(tmp_path / "one.csv", t, x), channel=3)
    with pytest.raises(InputError, match="spindle_hz"):
        chatter_frequency((t, x), spindle_hz=-1.0)


def _csv(p, t, x):
    with open(p, "w", newline="") as fh:
        csv.writer(fh).writerows(zip(t.tolist(), x.tolist(), strict=True))
    return p


# ------------------------------------------------------------------------------ simulated chatter
def _newmark(f_hz: float, h: float) -> float:
    """The frequency (Hz) the trapezoidal rule gives an oscillator of f_hz at step h."""
    w = 2 * np.pi * f_hz
    return (2 / h) * math.atan(w * h / 2) / (2 * np.pi)


def test_turning_simulation_chatters_at_the_rightmost_root():
    """A continuous turning cut 1.2 x above b_lim, forced by a runout at seven spindle harmonics:
    the chatter frequency found is the rightmost root's, within the record's resolution."""
    from chatterlab.time import Excitation, Initial, Integration

    model = cl.loads_model(turning_text(mass=2.0, stiffness=2.0e7, damping=400.0, name="1-DOF turning"))
    sy = cl.assemble(model)
    n = 4000.0
    b = 1.2 * float(cl.lobes(model, np.array([n]), width_max=0.05).b_lim[0])
    root = cl.stability(sy.at(), width=b, speed=n).roots.roots[0]
    assert root.real > 0
    f_sp, h = n / 60.0, 1e-5

    def runout(t):
        return 50.0 * sum(np.cos(2 * np.pi * k * f_sp * np.asarray(t) + k) for k in range(1, 8))

    sim = cl.simulate(sy, width=b, speed=n, integration=Integration(duration=1.0, step=h),
                      initial=Initial(q0={"tool.x": 1e-7}), excitation=Excitation(loads={"tool.x": runout}))  # fmt: skip
    cf = chatter_frequency((sim.t, sim.history("tool.x")), spindle_hz=f_sp)
    assert cf.removed_hz.size >= 7  # the runout's harmonics were there, and removed
    expect = _newmark(root.imag / (2 * np.pi), h)
    assert abs(cf.frequency_hz - expect) <= cf.resolution_hz, (cf.frequency_hz, expect)
    # the rule from it: each speed's tooth period holds j chatter waves
    rule = chatter_rule(cf, n, source=model, depth=b, count=3)
    np.testing.assert_allclose(60.0 / rule.speed, rule.waves / cf.frequency_hz, rtol=1e-13)
    assert rule.verdict.size == 3
    # the lobes at the running speed say the cut chatters (the model chatters as simulated)
    assert rule.current_limit < b


def test_milling_simulation_chatters_at_the_critical_multiplier():
    """A linear milling run 1.1 x above a_lim (Hopf): the chatter frequency found is one of the
    critical multiplier's frequencies (arg mu + 2 pi k) / tau, within the resolution."""
    from chatterlab.frequency import multipliers
    from chatterlab.lobes import milling_loop_of
    from chatterlab.process import Milling
    from chatterlab.time import Integration, simulate_milling

    model = cl.load_model("studies/milling/benchmark_1dof.toml")
    loop = milling_loop_of(cl.assemble(model).at())
    rpm = 11000.0
    a = 1.1 * float(cl.lobes(model, np.array([rpm])).b_lim[0])
    mu = multipliers(loop, rpm, a).critical
    assert abs(mu) > 1
    tau, steps = 60.0 / (2 * rpm), 100
    mode = model.modes[0]
    M, K = mode.mass, mode.mass * mode.omega**2
    C = 2 * mode.damping_ratio * mode.mass * mode.omega
    sim = simulate_milling(([[M]], [[C]], [[K]]), Milling.from_cut(model.process.milling), rpm, a, nonlinear=False,
                           integration=Integration(periods=200, steps_per_period=steps))  # fmt: skip
    cf = chatter_frequency((sim.t, sim.x), spindle_hz=rpm / 60.0, teeth=2)
    frac = np.angle(mu) / (2 * np.pi)
    family = np.r_[(frac + np.arange(-3, 8)) / tau, (-frac + np.arange(-3, 8)) / tau]
    family = family[family > 0]
    got = [_newmark(f, tau / steps) for f in family]
    assert min(abs(cf.frequency_hz - g) for g in got) <= cf.resolution_hz, (cf.frequency_hz, got)


# ------------------------------------------------------------------------------ the rule
def test_rule_without_a_model_is_undetermined():
    r = chatter_rule(951.3, RPM, teeth=TEETH, count=4)
    np.testing.assert_allclose(60.0 / (TEETH * r.speed), r.waves / 951.3, rtol=1e-13)
    j0 = 951.3 * 60.0 / (TEETH * RPM)
    assert list(np.abs(r.waves - j0)) == sorted(np.abs(r.waves - j0))  # nearest first
    assert set(r.verdict) == {"undetermined"} and np.all(np.isnan(r.limit))
    # the speed's +- from the resolution: n = 60 f_c / (N j) is linear in f_c, so dn = n df / f_c
    r2 = chatter_rule(951.3, RPM, teeth=TEETH, count=2, resolution_hz=2.0)
    np.testing.assert_allclose(r2.speed_error, r2.speed * 2.0 / 951.3, rtol=1e-12)


def test_rule_verdicts_are_the_lobes():
    model = cl.loads_model(turning_text(mass=2.0, stiffness=2.0e7, damping=400.0, name="1-DOF turning"))
    r = chatter_rule(520.0, 4000.0, source=model, depth=1e-3, margin=0.2, count=4, width_max=0.05)
    for s, lim, v in zip(r.speed, r.limit, r.verdict, strict=True):
        ref = float(cl.lobes(model, np.array([s]), width_max=0.05).b_lim[0])
        assert lim == pytest.approx(ref, rel=1e-12)
        expect = "stable" if 1e-3 <= 0.8 * ref else ("within margin" if 1e-3 < ref else "unstable")
        assert v == expect


def test_rule_on_the_shaper_uses_the_stroke_kinematics():
    model = cl.load_model("studies/traverse_shaper/model.toml")
    r = chatter_rule(83.0, 0.5, source=model, count=3, width_max=1e-3)
    np.testing.assert_allclose(model.process.delay(r.speed), r.waves / 83.0, rtol=1e-12)


def test_rule_refusals():
    with pytest.raises(InputError, match="margin"):
        chatter_rule(951.3, RPM, margin=1.2)
    with pytest.raises(InputError, match="running speed"):
        chatter_rule(951.3, -5.0)
    with pytest.raises(InputError, match="chatter frequency"):
        chatter_rule(float("nan"), RPM)
    model = cl.load_model("studies/milling/benchmark_1dof.toml")
    with pytest.raises(InputError, match="teeth"):
        chatter_rule(951.3, RPM, source=model, teeth=4)


def test_result_protocol(tmp_path):
    import json

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import xarray as xr

    cf = chatter_frequency(_signal(951.3), spindle_hz=F_SP, teeth=TEETH)
    model = cl.load_model("studies/milling/benchmark_1dof.toml")
    rule = chatter_rule(cf, RPM, source=model, depth=1e-3, count=3)
    for r in (cf, rule):
        assert isinstance(r, ChatterFrequency | SpeedRule)
        ds = r.to_xarray()
        assert all("units" in v.attrs for v in ds.variables.values())
        p = r.to_netcdf(tmp_path / "r.nc")
        with xr.open_dataset(p, engine="h5netcdf") as back:
            for k, v in ds.data_vars.items():
                np.testing.assert_array_equal(back[k].values, v.values)
        r.to_csv(tmp_path / "r.csv")
        text = r.to_json()
        assert "NaN" not in text and "Infinity" not in text
        json.loads(text)
        drawn = r.plot()
        again = r.plot(ax=drawn)
        assert list(np.ravel(np.asarray(again, dtype=object))) == list(
            np.ravel(np.asarray(drawn, dtype=object))
        )
        plt.close("all")
    with open(tmp_path / "r.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["verdict"] for r in rows] == list(rule.verdict)
