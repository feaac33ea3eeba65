"""The speeds to choose on the traverse shaper and the milling benchmark,
and the chatter-frequency rule on a simulated chattering cut.

1. The traverse shaper (the bundled ``example:traverse_shaper``): the work
   speeds 0.6-1.0 m/s and widths that remove the most material with a 20 %
   margin below the lobes, at a feed of 0.2 mm per stroke.
2. Insperger & Stepan's 1-DOF milling benchmark (the structure and cutter
   of ``studies/milling_benchmark.py``: 2 teeth, a_e/D = 0.05,
   down-milling): 5000-25000 rpm by the spectral Floquet lobes, a spindle
   of 25000 rpm with constant torque to 6000 rpm and 1.5 kW above, a tool
   of 4 mm flute length, f_z = 0.1 mm.
3. The shop floor: the same cutter at 11000 rpm and 1.1 x its limit,
   simulated (the nonlinear cut: the tooth leaves the material, static chip
   f_z, so the signal carries the tooth-passing harmonics a microphone
   would hear), sampled at 20 kHz into ``studies/speed_selection/chatter.wav``;
   its chatter frequency with the harmonics removed, and the speeds the
   rule gives, checked against the lobes.

Run: ``python studies/speed_selection.py`` (prints the numbers; with
``--figures docs/figures`` it also draws ``speed_selection_shaper.png``,
``speed_selection_milling.png`` and ``speed_selection_rule.png``; with
``--wav`` it rewrites the recording).  docs/speed-selection.md shows them.

References: S. Smith, J. Tlusty, CIRP Annals 41 (1992) 433-436; T. L.
Schmitz, K. S. Smith, *Machining Dynamics*, 2nd ed., Springer, 2019, ch. 4;
T. Insperger, G. Stepan, Int. J. Numer. Meth. Engng 61 (2004) 117-141.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import milling_benchmark as mb  # noqa: E402  (the benchmark's structure and cutter)

import chatterlab as cl  # noqa: E402
from chatterlab.selection import Machine, chatter_frequency, chatter_rule, recommend  # noqa: E402

WAV = HERE / "speed_selection" / "chatter.wav"
RUNNING = 11000.0  #: rpm of the chattering cut
WAV_RATE = 20000  #: Hz


def shaper() -> Any:
    """The shaper's best cuts, 0.6-1.0 m/s."""
    from chatterlab._examples import resolve

    model = cl.load_model(resolve("example:traverse_shaper"))
    return recommend(model, np.linspace(0.6, 1.0, 200), margin=0.2, machine=Machine(feed=2e-4), count=4)


def milling_machine() -> Machine:
    power = ((1000.0, 250.0), (6000.0, 1500.0), (25000.0, 1500.0))  # W: constant torque, then constant power
    return Machine(max_speed=25000.0, power=power, max_depth=4e-3, feed=1e-4)


def milling() -> Any:
    """The benchmark's best cuts, 5000-25000 rpm (spectral Floquet lobes)."""
    loop = cl.milling_loop(mb.tool(), mb.cutter(0.05))
    return recommend(loop, np.linspace(5000.0, 25000.0, 201), margin=0.2, machine=milling_machine(), count=5)


def chatter_depth() -> float:
    """1.1 x the limit at the running speed, m."""
    loop = cl.milling_loop(mb.tool(), mb.cutter(0.05))
    return 1.1 * float(cl.lobes(loop, np.array([RUNNING]), width_max=mb.DEPTH_MAX).b_lim[0])


def simulate_chatter() -> tuple[np.ndarray, np.ndarray]:
    """The chattering cut at RUNNING rpm, 1.1 x a_lim, its tool vibration x(t)
    over the last second, resampled at WAV_RATE."""
    from chatterlab.time import Integration, simulate_milling

    a = chatter_depth()
    s = mb.tool()
    sim = simulate_milling((s.M, s.C, s.K), mb.cutter(0.05), RUNNING, a, feed=1e-4,
                           integration=Integration(periods=400, steps_per_period=100))  # fmt: skip
    t = np.arange(WAV_RATE) / WAV_RATE + (sim.t[-1] - 1.0)
    return t - t[0], np.interp(t, sim.t, sim.x)


def write_wav() -> Path:
    from scipy.io import wavfile

    _, x = simulate_chatter()
    WAV.parent.mkdir(exist_ok=True)
    wavfile.write(WAV, WAV_RATE, np.round(x / np.max(np.abs(x)) * 30000).astype(np.int16))
    return WAV


def rule() -> Any:
    """The chatter frequency of the recording and the rule's speeds, checked against the lobes."""
    cf = chatter_frequency(WAV, spindle_hz=RUNNING / 60.0, teeth=2)
    model = cl.load_model(HERE / "milling" / "benchmark_1dof.toml")
    return chatter_rule(cf, RUNNING, source=model, depth=chatter_depth(), count=4, width_max=mb.DEPTH_MAX)


def main() -> None:
    from _figures import figures_dir

    folder = figures_dir(__doc__.splitlines()[0])
    results = {"shaper": shaper(), "milling": milling(), "rule": rule()}
    for r in results.values():
        print(r.summary())
        print()
    if folder is None:
        return
    import matplotlib

    matplotlib.use("Agg")
    from chatterlab.plot import savefig

    for key, r in results.items():
        out = folder / f"speed_selection_{key}.png"
        savefig(r.plot(), str(out))
        print(f"wrote {out}")


if __name__ == "__main__":
    if "--wav" in sys.argv:
        sys.argv.remove("--wav")
        print(f"wrote {write_wav()}")
    main()
