"""The documentation builds as a site (mkdocs.yml) with no warning.

``mkdocs build --strict`` fails on any warning: a relative link to a page or
file that is not part of the site, an ``#anchor`` that no heading of its
target has, an absolute link, a page of docs/ left out of the nav, or a
docstring that mkdocstrings cannot read.  External http(s) links are not
checked (CI has no network).  The built site is then read for what it must
hold: every page of the nav, every figure of docs/figures/ (made by the
scripts in studies/) shown by a page, the math marked for MathJax, and an
API page per public subpackage that documents each name of its ``__all__``.
"""

from __future__ import annotations

import html
import importlib
import importlib.util
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(
        importlib.util.find_spec("mkdocs") is None or importlib.util.find_spec("mkdocstrings") is None,
        reason='mkdocs and mkdocstrings are not installed (pip install -e ".[docs]")',
    ),
]

#: the subpackages with an API page: every subpackage of chatterlab but the command line, and errors
NOT_DOCUMENTED = {"cli"}


def _build(config: Path, site: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "mkdocs",
            "build",
            "--strict",
            "--config-file",
            str(config),
            "--site-dir",
            str(site),
        ],
        cwd=config.parent,
        capture_output=True,
        text=True,
        timeout=240,
    )


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("site")
    run = _build(ROOT / "mkdocs.yml", out)
    log = run.stdout + run.stderr
    assert run.returncode == 0, f"mkdocs build --strict failed:\n{log[-4000:]}"
    assert "WARNING" not in log, log[-4000:]
    return out


def _nav_pages() -> list[str]:
    from mkdocs.utils.yaml import yaml_load  # mkdocs' own loader (the config uses a !!python tag)

    with open(ROOT / "mkdocs.yml") as f:
        nav = yaml_load(f)["nav"]
    pages: list[str] = []

    def walk(item):
        if isinstance(item, str):
            pages.append(item)
        elif isinstance(item, dict):
            for v in item.values():
                walk(v)
        else:
            for v in item:
                walk(v)

    walk(nav)
    return pages


def _html(site: Path, page: str) -> str:
    stem = page.removesuffix(".md")
    if stem == "index":
        path = site / "index.html"
    elif stem.endswith("/index"):
        path = site / stem.removesuffix("/index") / "index.html"
    else:
        path = site / stem / "index.html"
    assert path.is_file(), f"{page} was not built ({path.relative_to(site)} missing)"
    return path.read_text()


def _h1(page: str) -> str:
    m = re.search(r"<h1[^>]*>(.*?)</h1>", page, flags=re.S)
    assert m, "no <h1>"
    text = html.unescape(re.sub(r"<[^>]+>", "", m.group(1)))
    return re.sub(r"\s+", " ", text.replace("\N{PILCROW SIGN}", "")).strip()


def _subpackages() -> list[str]:
    subs = sorted(p.parent.name for p in (ROOT / "chatterlab").glob("*/__init__.py"))
    return [s for s in subs if s not in NOT_DOCUMENTED] + ["errors"]


def test_every_page_of_docs_is_in_the_nav():
    pages = set(_nav_pages())
    on_disk = {str(p.relative_to(DOCS)) for p in DOCS.rglob("*.md")}
    assert on_disk == pages, (
        f"not in the nav: {sorted(on_disk - pages)}; in the nav, no file: {sorted(pages - on_disk)}"
    )
    assert {f"api/{s}.md" for s in _subpackages()} <= pages, "a public subpackage has no API page"


def test_every_nav_page_is_built_with_its_title(site):
    for page in _nav_pages():
        first = (DOCS / page).read_text().splitlines()[0]
        # a hand-written page: its '# title'; an API page ('::: chatterlab.x'): the object's name
        title = first.removeprefix("# ") if first.startswith("# ") else first.removeprefix(":::").strip()
        assert _h1(_html(site, page)) == title, f"{page}: heading is not {title!r}"


def test_figures_from_the_studies_are_shown(site):
    shown: set[str] = set()
    for page in _nav_pages():
        shown |= set(re.findall(r'<img[^>]*src="[^"]*figures/([\w.-]+\.png)"', _html(site, page)))
    figures = {p.name for p in (DOCS / "figures").glob("*.png")}
    assert figures, "docs/figures/ has no figure"
    assert figures <= shown, f"figures no page shows: {sorted(figures - shown)}"
    for name in figures:
        assert (site / "figures" / name).stat().st_size == (DOCS / "figures" / name).stat().st_size


def test_math_is_marked_for_mathjax(site):
    text = _html(site, "theory.md")
    assert len(re.findall(r'class="arithmatex"', text)) > 50
    assert "$$" not in re.sub(r"<code>.*?</code>", "", text, flags=re.S)


def test_api_pages_document_every_public_name(site):
    for sub in _subpackages():
        module = importlib.import_module(f"chatterlab.{sub}")
        text = _html(site, f"api/{sub}.md")
        ids = set(re.findall(r'id="(chatterlab\.[\w.]+)"', text))
        missing = [n for n in module.__all__ if f"chatterlab.{sub}.{n}" not in ids]
        assert not missing, f"chatterlab.{sub}: no entry for {missing}"
        private = sorted(i for i in ids if re.search(r"\._[a-z]", i))
        assert not private, f"chatterlab.{sub}: private names documented: {private[:5]}"


def test_api_pages_render_the_docstrings(site):
    lobes = _html(site, "api/lobes.md")
    assert 'id="chatterlab.lobes.lobes"' in lobes
    entry = lobes[lobes.index('id="chatterlab.lobes.lobes"') :]
    entry = entry[: entry.find('id="chatterlab.lobes.', 30)]
    assert "The stability lobe diagram of" in entry  # the summary line
    assert "width_max" in entry and "Largest width of cut" in entry  # a numpy Parameters entry
    freq = _html(site, "api/frequency.md")
    assert 'id="chatterlab.frequency.multipliers"' in freq
    assert "Floquet multipliers of milling" in freq


def test_a_broken_anchor_fails_the_build(tmp_path):
    """The link checking is on: the same site with one broken anchor does not build."""
    shutil.copytree(DOCS, tmp_path / "docs", ignore=shutil.ignore_patterns("figures"))
    shutil.copytree(
        DOCS / "figures", tmp_path / "docs" / "figures", copy_function=lambda s, d: Path(d).touch()
    )
    config = (ROOT / "mkdocs.yml").read_text()
    # the API pages need the package's source, which stays in the repository
    (tmp_path / "mkdocs.yml").write_text(config.replace("paths: [.]", f"paths: [{ROOT}]"))
    theory = tmp_path / "docs" / "theory.md"
    theory.write_text(theory.read_text() + "\nSee [the lobes](lobes.md#no-such-heading).\n")
    run = _build(tmp_path / "mkdocs.yml", tmp_path / "site")
    assert run.returncode != 0
    assert "no-such-heading" in run.stdout + run.stderr
