"""Spindle-speed variation on a structure with many modes: the quasi-static split
(Eq. (1q) of chatterlab.frequency._floquet_ssv) on the bundled traverse shaper
(36 DOF), and process damping under SSV (its gain follows the varying speed).

Oracles: at RVA = 0 the SSV limit is the constant-speed limit, which
chatterlab.lobes computes independently (D-subdivision of the full 36-DOF loop,
or with process damping, of the loop with the flank's term); the split and the
unsplit engine agree to the split's own error estimate (split_error); with
C_pd = 0 the result is today's to the bit.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import chatterlab as cl
from chatterlab.errors import InputError
from chatterlab.frequency import ssv_multipliers
from chatterlab.frequency._floquet_ssv import delayed_transfer, ssv_split
from chatterlab.frequency._floquet_ssv_limit import ssv_limit
from chatterlab.process import SpeedVariation, closed_loop, ssv_loop

ROOT = Path(__file__).resolve().parents[1]
SHAPER = ROOT / "studies" / "traverse_shaper" / "model.toml"
TURNING = ROOT / "studies" / "process_damping" / "turning.toml"
#: the search's relative tolerance (Brent) in these tests
RTOL = 1e-5


def _with_process(text: str, table: str) -> str:
    """The model text with its [process] table replaced by ``table``."""
    i = text.index("[process]")
    j = text.find("\n[", i + 1)
    return text[:i] + table + ("" if j < 0 else text[j:])


@pytest.fixture(scope="module")
def shaper_delay(tmp_path_factory: pytest.TempPathFactory) -> cl.Model:
    """The traverse shaper's structure and cut with the delay itself as the speed
    (kind = "delay"): delays shorter than its stroke cycle, where the unsplit
    engine is affordable and the lowest lobes lie."""
    p = tmp_path_factory.mktemp("shaper") / "shaper_delay.toml"
    p.write_text(_with_process(SHAPER.read_text(), '[process]\nkind = "delay"\ndelay = 0.005\n'))
    return cl.load_model(p)


def _sensitivity(loop, width: float, f: float) -> float:
    """kappa of :func:`split_error`'s bound at the boundary (width, f) of the full
    structure: ln G(omega, b) - i omega tau = 2 pi i k has the Jacobian
    [d_omega ln G - i tau, d_ln b ln G] (real and imaginary parts as rows), and a
    change d ln G of G moves ln b by the second row of its inverse applied to
    (Re, Im) d ln G, at most kappa |d ln G| with kappa that row's 2-norm.  The
    derivatives by central differences: 1e-6 Hz (1e-4 of the resonance's half-power
    width zeta f ~ 0.015 Hz) and 1e-6 relative in b."""
    sys = ssv_loop(loop, SpeedVariation(0.0, 0.5), None, quasi_static=ssv_split(loop, 300.0))

    def lnG(w: float, f_: float) -> complex:
        return complex(np.log(complex(delayed_transfer(sys, w, f_, split=False)[0, 0])))

    df, db = 1e-6, 1e-6
    a = (lnG(width, f + df) - lnG(width, f - df)) / (2 * 2 * np.pi * df) - 1j * float(loop.delay)
    c = (lnG(width * (1 + db), f) - lnG(width * (1 - db), f)) / (2 * db)
    jac = np.array([[a.real, c.real], [a.imag, c.imag]])
    return float(np.linalg.norm(np.linalg.inv(jac)[1]))


def test_split_rva0_is_the_constant_speed_limit(shaper_delay: cl.Model) -> None:
    """RVA = 0 with the modes above 300 Hz quasi-static: b_lim of the 36-DOF shaper's
    D-subdivision lobes at tau = 5 ms (first lobe of the 76 Hz mode), to the split's
    error estimate: the relative change eps of the delayed loop's transfer G at the
    chatter frequency moves ln b_lim by at most kappa eps / (1 - eps) to first order
    (split_error; kappa from the full G, :func:`_sensitivity`), plus the search's 2 rtol."""
    tau = 0.005
    ref = float(cl.lobes(shaper_delay, [tau]).b_lim[0])
    fz = cl.assemble(shaper_delay).at()
    loop = closed_loop(fz, width=1e-3, delay=tau)
    r = ssv_limit(loop, None, SpeedVariation(0.0, 0.5), width_max=1e-3, scan=5, rtol=RTOL, split=300.0)
    eps = r["split_error"]
    assert 0 < eps < 0.05  # the estimate is a number, and small where the chatter is (76 Hz)
    assert abs(r["chatter_frequency"] - 76.2) < 0.5
    kappa = _sensitivity(loop, r["b_lim"], r["chatter_frequency"])
    assert abs(math.log(r["b_lim"] / ref)) <= kappa * eps / (1 - eps) + 2 * RTOL


def test_split_agrees_with_the_unsplit_engine(shaper_delay: cl.Model) -> None:
    """Under SSV (RVA 0.1, RVF 0.5) at tau = 2 ms, where the unsplit 36-DOF engine is
    affordable (~4 s): the growth per period ln|mu| of the split (modes above 300 Hz
    quasi-static) and of the unsplit engine at b = 0.3 mm.  The split changes the
    delayed loop's transfer G by d ln G, |d ln G| <= eps / (1 - eps) (its error
    estimate): as a change of ln b by Re d ln G and of the delay's phase omega_c tau by
    Im d ln G would.  So |ln|mu_split| - ln|mu_full|| <= eps / (1 - eps)
    (b |d ln|mu| / db| + |d ln|mu| / d tau| / omega_c) to first order (the derivatives
    by central differences of the split engine, whose O(h^2) error is the next order),
    plus both engines' discretisation checks."""
    fz = cl.assemble(shaper_delay).at()
    tau, b = 0.002, 0.3e-3
    loop = closed_loop(fz, width=1e-3, delay=tau)
    v = SpeedVariation(0.1, 0.5)
    opts = {"degree": 12, "span": 6.0}
    full = ssv_multipliers(loop, None, b, v, **opts)
    split = ssv_multipliers(loop, None, b, v, split=300.0, **opts)

    def growth(width: float, delay: float) -> float:
        lp = closed_loop(fz, width=1e-3, delay=delay)
        return math.log(ssv_multipliers(lp, None, width, v, split=300.0, check=False, **opts).spectral_radius)

    hb, ht = 1e-6, 1e-6 * tau
    db = abs(growth(b + hb, tau) - growth(b - hb, tau)) / (2 * hb)
    dt = abs(growth(b, tau + ht) - growth(b, tau - ht)) / (2 * ht)
    eps = split.meta["split_error"]
    assert 0 < eps < 0.1
    w_c = 2 * np.pi * split.frequency_hz
    gap = abs(math.log(split.spectral_radius) - math.log(full.spectral_radius))
    assert gap <= eps / (1 - eps) * (b * db + dt / w_c) + full.error + split.error
    assert gap > 0  # the two are different discretisations of different models: not the same numbers


def test_split_reports_and_refuses(shaper_delay: cl.Model) -> None:
    """The split is stated in the result; where it is not modelled, one line."""
    fz = cl.assemble(shaper_delay).at()
    loop = closed_loop(fz, width=1e-3, delay=0.005)
    m = ssv_multipliers(loop, None, 2e-4, SpeedVariation(0.1, 0.5), split=300.0, check=False)
    assert m.meta["kept"] == 9 and m.meta["split_hz"] == 300.0
    assert "9 of 36 modes integrated, quasi-static above 300 Hz" in m.resolution
    assert m.table().splitlines()[0].endswith("at b = 0.2 mm (period 10 ms)")
    with pytest.raises(InputError, match="spectral elements only"):
        ssv_multipliers(loop, None, 2e-4, SpeedVariation(0.1, 0.5), split=300.0, method="sdm")
    with pytest.raises(InputError, match="split must be a frequency"):
        ssv_multipliers(loop, None, 2e-4, SpeedVariation(0.1, 0.5), split=-1.0)


def test_table_names_are_the_process_ones() -> None:
    """A shaper's multipliers print b and m/s (its width and speed unit), not a_p and rpm."""
    fz = cl.assemble(cl.load_model(TURNING)).at()
    loop = closed_loop(fz, width=1e-3, speed=6000.0)
    m = ssv_multipliers(loop, 6000.0, 1e-3, SpeedVariation(0.1, 0.5), check=False)
    assert "at b = 1 mm, 6000 rpm" in m.table()


# ---------------------------------------------------------------------------- process damping
def _turning(tmp_path: Path, C_pd: float | None) -> cl.Model:
    text = TURNING.read_text()  # its [machine] workpiece_diameter gives V = pi D n / 60
    if C_pd is not None:
        text += f"\n[process_damping]\nC_pd = {C_pd!r}\n"
    p = tmp_path / f"turning_{C_pd}.toml"
    p.write_text(text)
    return cl.load_model(p)


#: a flank damping that matters at 3000 rpm: b C_pd / V = 1e-3 * 1e6 / 7.85 = 127 N s/m
#: beside the holder's 400 N s/m
C_PD = 1.0e6


def test_process_damping_rva0_is_the_constant_speed_limit(tmp_path: Path) -> None:
    """RVA = 0 with process damping: the 1-DOF turning limit of chatterlab.lobes with the
    flank's term (exact D-subdivision), to the spectral engine's error (its check, ~1e-10
    here) plus the search's 2 rtol; and the term matters (the limit without it is lower
    by more than that)."""
    rpm = 3000.0
    model = _turning(tmp_path, C_PD)
    ref = float(cl.lobes(model, [rpm]).b_lim[0])
    fz = cl.assemble(model).at()
    loop = closed_loop(fz, width=1e-3, speed=rpm)
    r = ssv_limit(loop, rpm, SpeedVariation(0.0, 0.5), width_max=5e-3, scan=5, rtol=RTOL)
    assert abs(r["b_lim"] - ref) / ref <= 2 * RTOL + 1e-8
    bare = float(cl.lobes(_turning(tmp_path, None), [rpm]).b_lim[0])
    assert (ref - bare) / bare > 10 * RTOL


def test_process_damping_zero_is_todays_ssv(tmp_path: Path) -> None:
    """C_pd = 0 under SSV is the loop without the table, to the bit."""
    rpm, v = 3000.0, SpeedVariation(0.1, 0.5)
    out = []
    for C in (0.0, None):
        fz = cl.assemble(_turning(tmp_path, C)).at()
        loop = closed_loop(fz, width=1e-3, speed=rpm)
        out.append(ssv_multipliers(loop, rpm, 1.2e-3, v, check=False).mu)
    assert np.array_equal(out[0], out[1])


def test_process_damping_follows_the_speed(tmp_path: Path) -> None:
    """Under SSV the flank's gain is C_pd b / V(t): the spectral engine and
    semi-discretisation (its mean of 1/V over each step) converge to the same
    multiplier; SD's error falls as steps^-2 (its order), so the SD value at 2m steps
    is within a third of the m-step one's distance (2^-2 with a margin for the
    next term) -- and the two routes agree to SD's own error estimate."""
    rpm, v = 3000.0, SpeedVariation(0.2, 0.5)
    fz = cl.assemble(_turning(tmp_path, C_PD)).at()
    loop = closed_loop(fz, width=1e-3, speed=rpm)
    ref = ssv_multipliers(loop, rpm, 1.2e-3, v).spectral_radius
    e1 = abs(
        ssv_multipliers(loop, rpm, 1.2e-3, v, method="sdm", steps=200, check=False).spectral_radius - ref
    )
    e2 = abs(
        ssv_multipliers(loop, rpm, 1.2e-3, v, method="sdm", steps=400, check=False).spectral_radius - ref
    )
    assert e2 <= e1 / 3
    # the gain follows the speed: at constant gain (the mean speed's) the multiplier differs
    # by more than SD's error
    const = ssv_multipliers(loop, rpm, 1.2e-3, SpeedVariation(0.0, 0.5), check=False).spectral_radius
    assert abs(const - ref) > e1


def test_the_shaper_at_its_own_speed_says_what_to_do() -> None:
    """The 36-DOF shaper at its nominal 0.5 m/s (tau 1.5 s) without a split would carry a
    history of ~2e5 values: refused before any work, in one line naming the split."""
    fz = cl.assemble(cl.load_model(SHAPER)).at()
    loop = closed_loop(fz, width=1e-3, speed=0.5)
    with pytest.raises(InputError, match="split=F"):
        ssv_multipliers(loop, 0.5, 2e-4, SpeedVariation(0.1, 0.5))


def test_the_time_domain_refuses_what_it_does_not_integrate(tmp_path: Path, shaper_delay: cl.Model) -> None:
    """simulate_ssv integrates Eq. (1) with constant matrices: a split or a speed-following
    process damping is refused in one line, not integrated wrongly."""
    from chatterlab.time._ssv import simulate_ssv

    v = SpeedVariation(0.1, 0.5)
    loop = closed_loop(cl.assemble(shaper_delay).at(), width=1e-3, delay=0.005)
    with pytest.raises(InputError, match="not integrated in time"):
        simulate_ssv(ssv_loop(loop, v, None, quasi_static=ssv_split(loop, 300.0)), 2e-4, 2)
    damped = closed_loop(cl.assemble(_turning(tmp_path, C_PD)).at(), width=1e-3, speed=3000.0)
    with pytest.raises(InputError, match="not integrated in time"):
        simulate_ssv(ssv_loop(damped, v, 3000.0), 1e-3, 2)


def test_limits_over_a_grid_carry_the_split(shaper_delay: cl.Model) -> None:
    """ssv_limits with a split (the sweep engine's task): the limit at RVA 0 is ssv_limit's
    (the same search), and the files carry the split's frequency and its error per limit."""
    from chatterlab.frequency import ssv_limits

    fz = cl.assemble(shaper_delay).at()
    res = ssv_limits(fz, [0.005], [0.0], [0.5], width_max=1e-3, scan=5, rtol=RTOL, split=300.0)
    one = ssv_limit(
        closed_loop(fz, width=1e-3, delay=0.005), None, SpeedVariation(0.0, 0.5), width_max=1e-3, scan=5,
        rtol=RTOL, split=300.0,
    )  # fmt: skip
    assert res.b_lim[0, 0, 0] == pytest.approx(one["b_lim"], rel=1e-12)
    ds = res.to_xarray()
    assert ds.attrs["split_hz"] == 300.0
    # the task's loop is built at width_max and moved to the delay (loop.at): its coefficients
    # differ by round-off, and eps is read at the band of an eigenvector's dominant frequency,
    # which amplifies it (3e-9 measured): 1e-6 says "the same estimate", not a different band
    assert float(ds["split_error"].values[0, 0, 0]) == pytest.approx(one["split_error"], rel=1e-6)
    assert "modes above 300 Hz quasi-static" in res.table()
