"""docs/performance.md is generated from benchmarks/results/*.json by
benchmarks/report.py: regenerated here, it must equal the committed page, so
the page cannot drift from the measurements (rerun the benchmark, then the
report)."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _report():
    spec = importlib.util.spec_from_file_location("benchmarks_report", ROOT / "benchmarks" / "report.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # its dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def test_the_page_is_the_report_of_the_results(tmp_path):
    report = _report()
    out = tmp_path / "performance.md"
    out.write_text(report.render(ROOT / "benchmarks" / "results"))
    page = (ROOT / "docs" / "performance.md").read_text()
    assert page == out.read_text(), "docs/performance.md is stale: run python benchmarks/report.py"


def test_every_row_of_the_issue_has_a_table_and_missing_files_are_said(tmp_path):
    """With no results at all every row still has its table, saying so; a
    file in the generic format lands in its row with its numbers."""
    report = _report()
    empty = report.render(tmp_path)
    for row in report.ROWS:
        assert f"### {row.title}" in empty
    assert empty.count("No measurement in `benchmarks/results/` yet.") == len(report.ROWS)
    (tmp_path / "roots.json").write_text(
        json.dumps(
            {
                "issue26": [
                    {
                        "row": "roots",
                        "case": "306 DOF",
                        "chatterlab_s": [12.5, 13.0],
                        "ratio": [1.25, 1.3],
                        "load": 1.5,
                    }
                ]
            }
        )
    )
    page = report.render(tmp_path)
    assert "| – | 306 DOF | – | 12.5 / 13 s | 1.25 / 1.3x | – | 1.50 (LOADED) |" in page
    assert "**no**" in page  # 12.5 s against the 10 s goal


def test_a_goal_is_judged_in_the_rows_direction():
    report = _report()
    rows = {r.key: r for r in report.ROWS}
    fast = report.Entry("sweep", ratio=(1.9, 1.85))
    slow = report.Entry("sweep", ratio=(1.7, 1.75))
    assert report._met(rows["sweep"], fast) == "yes" and report._met(rows["sweep"], slow) == "**no**"
    cheap = report.Entry("main-job", ratio=(1.9, 2.1))
    dear = report.Entry("main-job", ratio=(2.1, 2.2))
    assert report._met(rows["main-job"], cheap) == "yes" and report._met(rows["main-job"], dear) == "**no**"
