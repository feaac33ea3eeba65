"""Write docs/performance.md from the benchmark results (issue 26's table).

Run from the repository root::

    python benchmarks/report.py                 # writes docs/performance.md
    python benchmarks/report.py --out FILE.md   # elsewhere (the test compares)

The page is generated, never typed: every number on it is read from
``benchmarks/results/*.json`` by this script, and
``tests/test_performance_page.py`` regenerates it and fails when
``docs/performance.md`` differs.  Whatever files exist are used; a row whose
file is missing says so.  One table per row of issue 26, one line per
measured run (a file may keep several, by label: ``before``, ``after``):
the competitor and chatterlab (min / median seconds), their ratio
(min / median), the accuracy each reached, the 1-minute load, the peak RSS,
the date and the commit, and the row's goal.

A benchmark joins the page in one of two ways:

* one of the formats read below (``lobes.json``, ``milling.json``,
  ``startup.json``, ``bench_sweep.json``, ``time.json``), or
* any results file with a top-level list ``"issue26"`` of entries
  ``{"row": KEY, "label", "case", "competitor", "competitor_s": [min, median],
  "chatterlab_s": [min, median], "ratio": [min, median], "accuracy", "load",
  "peak_rss_mb", "date", "commit"}`` (KEY one of :data:`ROWS`; any field may
  be missing), which is how a new benchmark (the time domain, roots) reports
  without a reader here.
"""

from __future__ import annotations

import argparse
import json
import math
import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
PAGE = ROOT / "docs" / "performance.md"


@dataclass(frozen=True)
class Row:
    """One row of issue 26: what is measured against what, and the goal."""

    key: str
    title: str
    competitor: str
    ratio: str  #: what the ratio is (which way is better)
    goal: str
    better: str  #: "higher" or "lower": which ratios meet a goal of the form ratio >= / <= target
    target: float


ROWS: tuple[Row, ...] = (
    Row(
        "time-1dof",
        "Time domain, 1-DOF regenerative turning",
        "the fastest scipy solve_ivp method (method of steps) at equal error",
        "competitor / chatterlab CPU time",
        ">= 10x at 1 % and at 0.1 % error",
        "higher",
        10.0,
    ),
    Row(
        "time-shaper",
        "Time domain, the traverse shaper (36 DOF, T = 0.1 s, 0.3 s window)",
        "the fastest scipy solve_ivp method at equal error",
        "competitor / chatterlab CPU time",
        ">= 10x",
        "higher",
        10.0,
    ),
    Row(
        "lobes",
        "lobes() on the shaper (300 speeds, verify=0)",
        "the shaper's 3x3 FRF at the engine's frequencies by eigen + pole-residue",
        "chatterlab / competitor time",
        "<= 10x",
        "lower",
        10.0,
    ),
    Row(
        "verify",
        "The argument-principle verification (verify=16) on top of lobes()",
        "lobes() with verify=0",
        "verification's extra time / lobes() time",
        "<= 1x",
        "lower",
        1.0,
    ),
    Row(
        "milling",
        "Milling lobes, spectral vs a plain numpy first-order SDM (m = 40, 201 speeds)",
        "a plain numpy SDM, m = 40, same depth search",
        "competitor / chatterlab time",
        ">= 10x at a_e/D = 1 and 0.05, at 1e-6 accuracy",
        "higher",
        10.0,
    ),
    Row(
        "milling-fe",
        "Structural milling: a 300-DOF FE end mill",
        "the 10 s per speed budget (no hand reduction)",
        "slowest speed's CPU time / 10 s",
        "<= 10 s per speed at every rpm and immersion, no hand reduction",
        "lower",
        1.0,
    ),
    Row(
        "main-job",
        "README main job (chatterlab lobes on the shaper, PNG + netCDF)",
        'python -c "import numpy, scipy, matplotlib" plus an empty figure of the same size drawn and saved',
        "chatterlab / competitor",
        "<= 2x",
        "lower",
        2.0,
    ),
    Row(
        "roots",
        "roots / stability() on the shaper refined to 306 DOF",
        "the 10 s and 1 GB budget",
        "CPU time / 10 s",
        "<= 10 s and <= 1 GB",
        "lower",
        1.0,
    ),
    Row(
        "sweep",
        "A 72-point sweep, serial vs loky on 2 workers",
        "the serial backend",
        "serial / loky wall time (speed-up)",
        ">= 1.8x, bit-identical",
        "higher",
        1.8,
    ),
)


@dataclass
class Entry:
    """One measured run of one row."""

    row: str
    label: str = ""
    case: str = ""
    competitor_s: tuple[float, float] | None = None
    chatterlab_s: tuple[float, float] | None = None
    ratio: tuple[float, float] | None = None
    accuracy: str = ""
    load: float | None = None
    peak_rss_mb: float | None = None
    date: str = ""
    commit: str = ""
    source: str = ""
    extra: dict[str, Any] = field(default_factory=dict)


# --------------------------------------------------------------- readers
def _num(x: Any) -> float | None:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def _load1(x: Any) -> float | None:
    """The 1-minute load from a number, a list or a /proc/loadavg string."""
    if isinstance(x, (list, tuple)):
        return _num(x[0]) if x else None
    if isinstance(x, str):
        m = re.match(r"\s*([0-9.]+)", x)
        return float(m.group(1)) if m else None
    return _num(x)


def _pair(d: Any, lo: str = "min_s", hi: str = "median_s") -> tuple[float, float] | None:
    if not isinstance(d, dict):
        return None
    a, b = _num(d.get(lo)), _num(d.get(hi))
    return (a, b) if a is not None and b is not None else None


def _date(s: Any) -> str:
    return str(s or "")[:16].replace("T", " ")


def read_lobes(data: dict[str, Any], source: str) -> list[Entry]:
    """bench_lobes: ``runs`` by label with lobes_verify0, lobes_verify, frf, ratios."""
    out = []
    for label, run in data.get("runs", {}).items():
        common = dict(
            label=label,
            load=_load1(run.get("load_before")),
            peak_rss_mb=_num(run.get("peak_rss_mb")),
            date=_date(run.get("date_utc")),
            commit=str(run.get("commit", "")),
            source=source,
        )
        r = run.get("ratios", {})
        lobes0, lobes16, frf = (_pair(run.get(k)) for k in ("lobes_verify0", "lobes_verify", "frf"))
        acc = _num(run.get("frf_rel_diff_vs_engine"))
        out.append(
            Entry(
                "lobes",
                case=f"{run.get('grid_size', '?')} frequencies, {run.get('n_poles', '?')} poles",
                competitor_s=frf,
                chatterlab_s=lobes0,
                ratio=_ratio(r, "lobes_over_frf"),
                accuracy=f"same FRF to {acc:.1e}" if acc is not None else "",
                **common,
            )
        )
        extra = None
        if lobes0 and lobes16:
            extra = (lobes16[0] - lobes0[0], lobes16[1] - lobes0[1])
        out.append(
            Entry(
                "verify",
                case=f"verify={run.get('verify', '?')}",
                competitor_s=lobes0,
                chatterlab_s=extra,
                ratio=_ratio(r, "verify_extra_over_lobes"),
                accuracy=_checks(run.get("result_verify")),
                **common,
            )
        )
    return out


def _checks(result: Any) -> str:
    """ "n/m checks agree" from a diagram's list of argument-principle checks."""
    checks = result.get("checks") if isinstance(result, dict) else None
    if not isinstance(checks, list) or not checks:
        return ""
    agree = sum(1 for c in checks if isinstance(c, dict) and c.get("agrees"))
    return f"{agree}/{len(checks)} checks agree"


def _ratio(r: dict[str, Any], stem: str) -> tuple[float, float] | None:
    a, b = _num(r.get(stem + "_min")), _num(r.get(stem + "_median"))
    return (a, b) if a is not None and b is not None else None


def read_milling(data: dict[str, Any], source: str) -> list[Entry]:
    """bench_milling: ``runs`` by label; ``lobes`` per immersion (chatterlab vs
    sdm), ``fe`` cases per rpm and immersion."""
    out = []
    for label, run in data.get("runs", {}).items():
        common = dict(
            label=label,
            peak_rss_mb=_num(run.get("peak_rss_mb")),
            date=_date(run.get("date_utc")),
            commit=str(run.get("commit", "")),
            source=source,
        )
        for imm, case in (run.get("lobes") or {}).items():
            cl, sdm = case.get("chatterlab", {}), case.get("sdm", {})
            a, b = _pair(sdm), _pair(cl)
            ratio = (a[0] / b[0], a[1] / b[1]) if a and b else None
            acc = f"max rel. error {_err(cl.get('error_max_rel'))} vs SDM {_err(sdm.get('error_max_rel'))}"
            out.append(
                Entry(
                    "milling",
                    case=f"a_e/D = {imm}, {case.get('speeds', '?')} speeds",
                    competitor_s=a,
                    chatterlab_s=b,
                    ratio=ratio,
                    accuracy=acc,
                    load=_load1(case.get("load_before", case.get("load"))),
                    extra={"repeats": run.get("repeat")},
                    **{**common, "peak_rss_mb": _num(case.get("peak_rss_mb")) or common["peak_rss_mb"]},
                )
            )
        fe = run.get("fe")
        if isinstance(fe, dict) and fe.get("cases"):
            cases = fe["cases"]
            ok = [c for c in cases if c.get("status") == "ok"]
            cpu = [_num(c.get("cpu_s")) for c in ok]
            cpu_ok = [c for c in cpu if c is not None]
            worst = max(cpu_ok) if cpu_ok else None
            loads = [_load1(c.get("load")) for c in cases]
            rss = [_num(c.get("peak_rss_mb")) for c in cases]
            out.append(
                Entry(
                    "milling-fe",
                    case=f"{fe.get('elements', '?')} elements: {len(ok)} of {len(cases)} cases computed",
                    chatterlab_s=(worst, worst) if worst is not None else None,
                    ratio=(worst / 10.0, worst / 10.0) if worst is not None else None,
                    accuracy=_fe_accuracy(ok),
                    load=max((x for x in loads if x is not None), default=None),
                    **{
                        **common,
                        "peak_rss_mb": max((x for x in rss if x is not None), default=common["peak_rss_mb"]),
                    },
                )
            )
    return out


def _err(x: Any) -> str:
    """A relative error as printed: inf (a limit missed) stays inf."""
    try:
        v = float(x)
    except (TypeError, ValueError):
        return "?"
    return f"{v:.1e}" if math.isfinite(v) else str(v)


def _fe_accuracy(ok: list[dict[str, Any]]) -> str:
    rel = []
    for c in ok:
        err, a_lim = _num(c.get("error_m")), _num(c.get("a_lim_m"))
        if err is not None and a_lim:
            rel.append(err / a_lim)
    return f"own error estimate <= {max(rel):.1e} of a_lim" if rel else ""


def read_startup(data: dict[str, Any], source: str) -> list[Entry]:
    """bench_startup: the main job against its floor, wall and CPU."""
    out = []
    for label, run in (data.get("runs") or {"": data}).items():
        cases = run.get("cases", {})
        job, floor = cases.get("main job", {}), cases.get("floor", {})
        for kind in ("cpu", "wall"):
            a, b = (
                _pair(floor, f"{kind}_min_s", f"{kind}_median_s"),
                _pair(job, f"{kind}_min_s", f"{kind}_median_s"),
            )
            out.append(
                Entry(
                    "main-job",
                    label=label,
                    case=f"{kind.upper()} time",
                    competitor_s=a,
                    chatterlab_s=b,
                    ratio=(b[0] / a[0], b[1] / a[1]) if a and b else None,
                    accuracy=str(job.get("result", "")),
                    load=_load1(run.get("load_average_start")),
                    peak_rss_mb=_num(job.get("peak_rss_mb")),
                    date=_date(run.get("date_utc")),
                    commit=str(run.get("commit", "")),
                    source=source,
                )
            )
    return out


def read_sweep(data: dict[str, Any], source: str) -> list[Entry]:
    """bench_sweep: the speed-up of loky x2 over serial on the chatterlab sweep."""
    sp = (data.get("speedup") or {}).get("chatterlab")
    if not isinstance(sp, dict):
        return []
    r = _num(sp.get("speedup_min")), _num(sp.get("speedup_median"))
    return [
        Entry(
            "sweep",
            case=f"{sp.get('tasks', '?')} points: {sp.get('task', '')}",
            competitor_s=_pair(sp.get("serial")),
            chatterlab_s=_pair(sp.get("loky2_warm")),
            ratio=(r[0], r[1]) if r[0] is not None and r[1] is not None else None,
            accuracy="bit-identical" if sp.get("bit_identical") else "NOT bit-identical",
            load=_load1(data.get("load_average_start")),
            peak_rss_mb=_num(sp.get("peak_rss_mb")),
            date=_date(data.get("date_utc")),
            commit=str(data.get("commit", "")),
            source=source,
        )
    ]


#: bench_time's problems -> issue 26's rows
TIME_ROWS = {"turning_1dof": "time-1dof", "shaper_36dof": "time-shaper"}


def read_time(data: dict[str, Any], source: str) -> list[Entry]:
    """bench_time: per problem and error target, each chatterlab route against
    the fastest solve_ivp method at that target (CPU time)."""
    out = []
    for row in data.get("rows", []):
        key = TIME_ROWS.get(row.get("problem", ""))
        if key is None:
            continue
        for tgt in row.get("targets", []):
            contenders = tgt.get("contenders", {})
            ivp = {k: v for k, v in contenders.items() if k.startswith("solve_ivp") and isinstance(v, dict)}
            best = min(
                ivp, key=lambda k: _num(ivp[k].get("time", {}).get("cpu_min_s")) or math.inf, default=None
            )
            comp = _pair(ivp[best].get("time"), "cpu_min_s", "cpu_median_s") if best else None
            for name, c in contenders.items():
                if name.startswith("solve_ivp") or not isinstance(c, dict):
                    continue
                mine = _pair(c.get("time"), "cpu_min_s", "cpu_median_s")
                err = _err(c.get("error"))
                acc = f"error {err}" + (
                    f" vs {best.removeprefix('solve_ivp ')} {_err(ivp[best].get('error'))}" if best else ""
                )
                out.append(
                    Entry(
                        key,
                        case=f"error target {_num(tgt.get('target')) or 0:g}: {name}",
                        competitor_s=comp,
                        chatterlab_s=mine,
                        ratio=(comp[0] / mine[0], comp[1] / mine[1]) if comp and mine else None,
                        accuracy=acc,
                        load=_load1(row.get("load_1min_before", data.get("load_1min_start"))),
                        peak_rss_mb=_num(row.get("peak_rss_mb_after", data.get("peak_rss_mb"))),
                        date=_date(data.get("date_utc")),
                        commit=str(data.get("commit", "")),
                        source=source,
                    )
                )
    return out


def read_generic(data: dict[str, Any], source: str) -> list[Entry]:
    """The ``"issue26"`` list any benchmark may write."""
    out = []
    for e in data.get("issue26", []):
        if not isinstance(e, dict) or e.get("row") not in {r.key for r in ROWS}:
            continue
        out.append(
            Entry(
                str(e["row"]),
                label=str(e.get("label", "")),
                case=str(e.get("case", "")),
                competitor_s=_tuple(e.get("competitor_s")),
                chatterlab_s=_tuple(e.get("chatterlab_s")),
                ratio=_tuple(e.get("ratio")),
                accuracy=str(e.get("accuracy", "")),
                load=_load1(e.get("load")),
                peak_rss_mb=_num(e.get("peak_rss_mb")),
                date=_date(e.get("date")),
                commit=str(e.get("commit", "")),
                source=source,
            )
        )
    return out


def _tuple(x: Any) -> tuple[float, float] | None:
    if isinstance(x, (list, tuple)) and len(x) == 2:
        a, b = _num(x[0]), _num(x[1])
        if a is not None and b is not None:
            return (a, b)
    return None


#: file name -> its reader (any other file is read for its "issue26" list only)
READERS: dict[str, Callable[[dict[str, Any], str], list[Entry]]] = {
    "lobes.json": read_lobes,
    "milling.json": read_milling,
    "startup.json": read_startup,
    "bench_sweep.json": read_sweep,
    "time.json": read_time,
}


def collect(results: Path) -> tuple[list[Entry], list[str], list[str]]:
    """Every entry of every results file; the files used and those not."""
    entries: list[Entry] = []
    used: list[str] = []
    unused: list[str] = []
    for path in sorted(results.glob("*.json")):
        try:
            data = json.loads(path.read_text())
        except (OSError, ValueError):
            unused.append(f"{path.name} (not readable as JSON)")
            continue
        if not isinstance(data, dict):
            unused.append(path.name)
            continue
        got = read_generic(data, path.name)
        reader = READERS.get(path.name)
        if reader is not None:
            try:
                got += reader(data, path.name)
            except (AttributeError, KeyError, TypeError, ValueError, ZeroDivisionError) as exc:
                unused.append(f"{path.name} (its format changed: {type(exc).__name__})")
                continue
        (used if got else unused).append(path.name)
        entries += got
    return entries, used, unused


# --------------------------------------------------------------- the page
def _s(x: float) -> str:
    return f"{x:.3g}"


def _cell_pair(p: tuple[float, float] | None, unit: str = " s") -> str:
    return f"{_s(p[0])} / {_s(p[1])}{unit}" if p else "–"


def _met(row: Row, e: Entry) -> str:
    if e.ratio is None:
        return "–"
    r = e.ratio[0]
    ok = r >= row.target if row.better == "higher" else r <= row.target
    return "yes" if ok else "**no**"


def _load_cell(x: float | None) -> str:
    if x is None:
        return "–"
    return f"{x:.2f} (LOADED)" if x > 1.0 else f"{x:.2f}"


def table(row: Row, entries: Iterable[Entry]) -> list[str]:
    rows = sorted(entries, key=lambda e: (e.date, e.label, e.case))
    lines = [
        f"### {row.title}",
        "",
        f"Competitor: {row.competitor}. Ratio: {row.ratio}. Goal: **{row.goal}**.",
        "",
    ]
    if not rows:
        return [*lines, "No measurement in `benchmarks/results/` yet.", ""]
    lines += [
        "| run | case | competitor min / median | chatterlab min / median | ratio min / median"
        " | accuracy | load | peak RSS | date (UTC) | commit | goal met | file |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for e in rows:
        rss = f"{e.peak_rss_mb:.0f} MB" if e.peak_rss_mb is not None else "–"
        cells = [
            e.label or "–",
            e.case or "–",
            _cell_pair(e.competitor_s),
            _cell_pair(e.chatterlab_s),
            _cell_pair(e.ratio, "x"),
            e.accuracy or "–",
            _load_cell(e.load),
            rss,
            e.date or "–",
            f"`{e.commit}`" if e.commit else "–",
            _met(row, e),
            f"`{e.source}`",
        ]
        lines.append("| " + " | ".join(c.replace("|", "/") for c in cells) + " |")
    return [*lines, ""]


def render(results: Path = RESULTS) -> str:
    entries, used, unused = collect(results)
    out = [
        "# Performance",
        "",
        "<!-- generated by benchmarks/report.py from benchmarks/results/*.json: do not edit;"
        " tests/test_performance_page.py fails when this page and the results differ -->",
        "",
        "The rows of issue 26: each figure measured against its named competitor in the",
        "same run, repeated, min and median (seconds unless stated). A ratio's direction is",
        "given per row; *goal met* compares the min ratio with the goal. The 1-minute load",
        "average is the machine's (2 cores): above 1 the run is marked LOADED, and a",
        "speed-up or a ratio against a floor measured then is bounded by what the other",
        "processes left. Rerun a benchmark (`python benchmarks/bench_*.py`) and then",
        "`python benchmarks/report.py` to refresh this page.",
        "",
    ]
    for row in ROWS:
        out += table(row, [e for e in entries if e.row == row.key])
    out += ["## Files", ""]
    out.append("Read: " + (", ".join(f"`{u}`" for u in used) if used else "none") + ".")
    # the files not read are printed by main(), not written here: a new results
    # file of another benchmark does not change this page
    return "\n".join(out) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--results", default=str(RESULTS), help="folder of the results JSON files")
    ap.add_argument("--out", default=str(PAGE), help="the page to write")
    args = ap.parse_args()
    Path(args.out).write_text(render(Path(args.results)))
    print(f"wrote {args.out}")
    _, _, unused = collect(Path(args.results))
    if unused:
        print("not on the page (no reader for their format and no 'issue26' list): " + ", ".join(unused))


if __name__ == "__main__":
    main()
