"""The command-line examples of the README and docs/ run as written, and
print what the page shows.

Every ``$ chatterlab ...`` line of a ```console block (continuation lines
joined; ``$M`` and ``$B`` from an earlier ``M=...`` line of the page
substituted) is run in a scratch folder where ``studies/`` is the
repository's, and must end with the exit status the page shows: the number
printed by a following ``$ echo $?``, 2 when its output starts with
``chatterlab: error:``, 0 otherwise.

Every line the page shows as its output must be printed again (issue 20,
item 6: documented outputs had drifted): the same words, and every number to
the digits the page prints (the printed value rounds to the page's).  A number printed at full
precision (15 or more significant digits: a float's repr, as CSV and JSON write it) is compared to
``FULL_RTOL`` relative: its last digits are the round-off of the CPU and BLAS that ran it.  Not compared, because they depend
on the machine and not on chatterlab: run times (a number of seconds after
``in`` or a comma), rates (``steps/s``), progress lines (``sweep:  10% (...``),
numbers at round-off level (|x| < 1e-12: only that they are as small), a
line the page elides with ``...``, and an annotation after two spaces and
``#``.  A command that cannot run here is listed in ``NOT_RUN`` with the
reason; an entry that no longer matches exactly one command fails, so
nothing is left out silently.  Files the examples write (figures into
``docs/figures/``) land in the scratch folder.
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
SLOW = (
    "--positions 0.6 1.1 6",
    "--feedback all --passes 3",
    "--step 1.4e-3 --passes 3",
    "--duration 20",
    "recommend example:traverse_shaper",
    "active studies/traverse_shaper",
    "absorber studies/traverse_shaper",
    "sensitivity studies/traverse_shaper",
)


#: a number as the program prints it
NUMBER = re.compile(r"(?<![\w.])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![\w.])")
#: what depends on the machine, not on chatterlab: a run time after "in" or a comma, a rate
MACHINE = re.compile(r"(?:(?<=, )|(?<=\bin ))\d+(?:\.\d+)?\s?(?:s|ms|min)\b(?!/)|\d+(?:\.\d+)? steps/s")
#: a progress line ("sweep:  10% (300/1800 points, 1.8 s)"): how many appear depends on the speed
PROGRESS = re.compile(r"^\s*[\w ]+:\s+\d+% \(")
#: a page's annotation of an output line
NOTE = re.compile(r"\s{2,}#\s.*$")


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
                j, status, shown = i + 1, 0, []
                while j < len(lines) and not lines[j].startswith("$ "):
                    if lines[j].startswith("chatterlab: error:"):
                        status = 2
                    shown.append(lines[j])
                    j += 1
                if j < len(lines) and lines[j].strip() == "$ echo $?" and j + 1 < len(lines):
                    status = int(lines[j + 1].strip())
                out.append((rel, cmd, status, shown))
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
    ("page", "cmd", "status", "shown"),
    [pytest.param(*c, marks=[pytest.mark.timeout(600)] if any(s in c[1] for s in SLOW) else []) for c in RUN],
    ids=[f"{p}:{c[11:60]}" for p, c, _, _ in RUN],
)
def test_documented_command_runs(page, cmd, status, shown, tmp_path):
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
    printed = (r.stdout + r.stderr).splitlines()
    missing = [ln for ln in shown if _compared(ln) and not any(_same_line(ln, p) for p in printed)]
    assert not missing, (
        f"{page}: {cmd}\nthe page shows lines the program no longer prints:\n"
        + "\n".join(missing)
        + "\n--- it prints:\n"
        + "\n".join(printed[:60])
    )


def _compared(line: str) -> bool:
    """Is this output line of a page compared with what the program prints?"""
    text = NOTE.sub("", line)
    return bool(text.strip()) and "..." not in text and "…" not in text and not PROGRESS.match(text)


def _parts(line: str) -> tuple[list[str], list[str]]:
    """The words between the numbers (whitespace-normalised, times masked) and the numbers."""
    text = " ".join(MACHINE.sub("<time>", NOTE.sub("", line)).split())
    return NUMBER.split(text), NUMBER.findall(text)


def _unit(number: str) -> float:
    """One unit of the last digit printed."""
    m = re.fullmatch(r"[-+]?\d*\.?(\d*)(?:[eE]([-+]?\d+))?", number)
    assert m is not None, number
    return 10.0 ** (int(m.group(2) or 0) - len(m.group(1)))


#: relative tolerance of a number printed at full precision.  The worst-conditioned such column on
#: the pages is a damping ratio of a lightly damped mode, zeta = -Re(lambda)/|lambda|: eigenvalues
#: carry an absolute round-off ~ n eps |lambda| (n states), so zeta carries ~ n eps / zeta relative
#: -- 72 x 2.2e-16 / 2.05e-4 = 8e-11 for the shaper's least damped mode; 1e-9 is above that
FULL_RTOL = 1e-9


def _significant(number: str) -> int:
    """How many significant digits a number is printed with."""
    mantissa = re.sub(r"[eE].*$", "", number).lstrip("+-").replace(".", "").lstrip("0")
    return len(mantissa)


def _same_number(shown: str, printed: str) -> bool:
    """The printed value rounds to the page's digits: equal at equal digits, within half a unit
    of the page's last digit (plus the printed rounding) when printed with more; at full precision
    (15 or more digits) within ``FULL_RTOL``."""
    a, b = float(shown), float(printed)
    if abs(a) < 1e-12:  # round-off: its digits depend on the BLAS, its size does not
        return abs(b) < 1e-12
    if _significant(shown) >= 15:
        return abs(a - b) <= FULL_RTOL * abs(a)
    us, up = _unit(shown), _unit(printed)
    if up >= us:
        return abs(a - b) <= 1e-9 * max(abs(a), us)
    return abs(a - b) <= (0.5 * us + 0.5 * up) * (1 + 1e-9)


def _same_line(shown: str, printed: str) -> bool:
    words, numbers = _parts(shown)
    words2, numbers2 = _parts(printed)
    return words == words2 and all(_same_number(x, y) for x, y in zip(numbers, numbers2, strict=True))


def test_the_comparison_masks_times_and_rounds_to_the_page():
    """The rules of the module docstring, on lines of the pages."""
    # full precision: the CSV of `modes` on two CPUs (the page's, and an AMD EPYC's)
    assert _same_line(
        "2,83.3387196896594,523.632619073226,0.011999224414819985,0.0005065376931499945",
        "2,83.33871968965701,523.632619073211,0.011999224414820328,0.0005065376931508095",
    )
    assert not _same_line("2,83.3387196896594", "2,83.3387206896594")  # 1.2e-8: not round-off
    assert _same_line(
        "  106 fields, 169 model evaluations, 14.20 s", "  106 fields, 169 model evaluations, 3.1 s"
    )
    assert _same_line("in 0.322 s (22947 steps/s)", "in 2.33 s (3175 steps/s)")
    assert _same_line("min b_lim 0.1699 mm", "min b_lim 0.16994 mm")
    assert not _same_line("min b_lim 0.1699 mm", "min b_lim 0.1701 mm")
    assert not _same_line("envelope: decaying (-1.646 1/s)", "envelope: undetermined (-1.646 1/s)")
    assert not _same_line(
        "from t = 0 to 0.5 s in 1 s", "from t = 0 to 0.6 s in 1 s"
    )  # a duration is a result
    assert _same_line(
        "(spectral radius 0.928860, error 4.4e-15)", "(spectral radius 0.928860, error 1.7e-15)"
    )
    assert not _same_line("error 4.4e-15", "error 4.4e-05")
    assert _same_line("1.818e-03 m", "1.8181e-03 m") and not _same_line("1.818e-03 m", "1.820e-03 m")
    assert not _compared("sweep:  10% (300/1800 points, 1.8 s)") and not _compared("  ...")
    assert _same_line("chatterlab: error: --step must be > 0 s (got 0)          # exit status 2, one line",
                      "chatterlab: error: --step must be > 0 s (got 0)")  # fmt: skip
