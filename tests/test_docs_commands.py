"""The command-line examples of the README and docs/ run as written.

Every ``$ chatterlab ...`` line of a ```console block (continuation lines
joined; ``$M`` and ``$B`` from an earlier ``M=...`` line of the page
substituted) is run in a scratch folder where ``studies/`` is the
repository's, and must end with the exit status the page shows: the number
printed by a following ``$ echo $?``, 2 when its output starts with
``chatterlab: error:``, 0 otherwise; and every result the page quotes in
that output (a number with two or more decimals and a unit: mm, Hz, rpm,
m/s, um) must be printed again.  A command that cannot run here is
listed in ``NOT_RUN`` with the reason; an entry that no longer matches
exactly one command fails, so nothing is left out silently.  Files the
examples write (figures into ``docs/figures/``) land in the scratch folder.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

#: commands not run, by page and a phrase of the command, with the reason
NOT_RUN = {
    ("docs/cli.md", "--out atlas2.nc --quiet"): "interrupted with Ctrl-C after 4 s (the page shows exit 130)",
    ("docs/cli.md", "--out atlas2.nc --resume"): "resumes the interrupted run above",
    ("docs/model-format.md", "check model.toml"): "a user's own model.toml",
    ("docs/model-format.md", "modes model.toml"): "a user's own model.toml",
    ("docs/time-domain.md", "simulate turning.toml"): "a user's own turning.toml",
}
#: commands that take long enough (10-60 s) to be worth a mark of their own
SLOW = ("--positions 0.6 1.1 6", "--feedback all --passes 3", "--step 1.4e-3 --passes 3", "--duration 20")


#: a number the pages quote with a unit of a result (not a time: timings vary with the machine)
QUOTED = re.compile(r"(?<![\w.])(\d+\.\d{2,})\s?(mm|Hz|rpm|m/s|um|µm)\b")


def _commands() -> list[tuple[str, str, int, list[str]]]:
    out = []
    for page in PAGES:
        text = page.read_text()
        rel = str(page.relative_to(ROOT))
        env: dict[str, str] = {}
        for m in re.finditer(r"^```(console|bash|sh)\n(.*?)^```", text, flags=re.M | re.S):
            lines = m.group(2).split("\n")
            if m.group(1) != "console":  # a script: its commands have no prompt and show no output
                lines = ["$ " + ln if ln.startswith("chatterlab ") else ln for ln in lines]
            i = 0
            while i < len(lines):
                ln = lines[i]
                assign = re.match(r"^(?:\$ )?([A-Z])=(\S+)\s*$", ln)
                if assign:
                    env[assign.group(1)] = assign.group(2)
                if not ln.startswith("$ chatterlab"):
                    i += 1
                    continue
                cmd = ln[2:]
                while cmd.rstrip().endswith("\\") and i + 1 < len(lines):
                    i += 1
                    cmd = cmd.rstrip()[:-1] + " " + lines[i].strip()
                cmd = cmd.split("  #")[0].split(" # ")[0].strip()
                for k, v in env.items():
                    cmd = cmd.replace(f"${k}", v)
                # the expected status: an '$ echo $?' after the output, or an error line
                j, status, quoted = i + 1, 0, []
                while j < len(lines) and not lines[j].startswith("$ "):
                    if lines[j].startswith("chatterlab: error:"):
                        status = 2
                    quoted += [f"{num} {unit}" for num, unit in QUOTED.findall(lines[j])]
                    j += 1
                if j < len(lines) and lines[j].strip() == "$ echo $?" and j + 1 < len(lines):
                    status = int(lines[j + 1].strip())
                out.append((rel, cmd, status, quoted))
                i += 1
    return out


def _excluded(page: str, cmd: str) -> bool:
    return any(pg == page and phrase in cmd for pg, phrase in NOT_RUN)


ALL = _commands()
RUN = [c for c in ALL if not _excluded(c[0], c[1])]


def test_commands_are_found():
    assert len(ALL) >= 40 and {p for p, _, _, _ in ALL} >= {"docs/cli.md", "docs/frequency-domain.md"}


def test_each_exclusion_names_exactly_one_command():
    for (pg, phrase), why in NOT_RUN.items():
        hits = [c for p, c, _, _ in ALL if p == pg and phrase in c]
        assert len(hits) == 1, f"NOT_RUN entry {pg} {phrase!r} ({why}) matches {hits}"


@pytest.mark.slow
@pytest.mark.parametrize(
    ("page", "cmd", "status", "quoted"),
    [pytest.param(*c, marks=[pytest.mark.timeout(600)] if any(s in c[1] for s in SLOW) else []) for c in RUN],
    ids=[f"{p}:{c[11:60]}" for p, c, _, _ in RUN],
)
def test_documented_command_runs(page, cmd, status, quoted, tmp_path):
    (tmp_path / "studies").symlink_to(ROOT / "studies")
    (tmp_path / "docs" / "figures").mkdir(parents=True)
    env = dict(os.environ, MPLBACKEND="Agg")
    argv = shlex.split(cmd)
    assert argv[0] == "chatterlab"
    r = subprocess.run(
        [sys.executable, "-m", "chatterlab.cli", *argv[1:]],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
    )
    assert r.returncode == status, (
        f"{page}: {cmd}\nexit {r.returncode}\n{r.stdout[-1500:]}\n{r.stderr[-1500:]}"
    )
