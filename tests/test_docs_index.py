"""docs/index.md and docs/architecture.md stay true to the package.

"The docs are the program": a newcomer finds the Newmark solver, the lobe
engine or the milling process by the folder and file names that
docs/index.md's "Module map" gives, and the pages by its "Documentation"
list.  Both went stale once (files renamed and split, subpackages and pages
added without a row); these tests make that a failure:

* every ``x.py`` named in a row of the map exists in the row's subpackage
  (or at the ``sub/x.py`` path it spells out);
* every module of chatterlab/ (but ``__init__.py`` and ``__main__.py``) is
  named in the module column of its own subpackage's rows, exactly once;
* every page of the site's navigation (mkdocs.yml ``nav``; the API pages
  through ``api/index.md``) is linked from the "Documentation" list, and the
  list links nothing that is not in the navigation;
* the "Speed" section types no measured number: it points to
  docs/performance.md, generated from benchmarks/results/*.json;
* every ``*.py`` path docs/architecture.md names exists.

Text is parsed, nothing imported or built (mkdocs --strict, which checks
links and anchors, is tests/test_docs_site.py).
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "chatterlab"
INDEX = ROOT / "docs" / "index.md"
ARCHITECTURE = ROOT / "docs" / "architecture.md"

#: files a package needs that are not modules of a capability
NOT_MAPPED = {"__init__.py", "__main__.py"}

#: a file name in backticks: `_loop.py`, `errors.py`, `time/_core.py`
PY_NAME = re.compile(r"`([\w./]+\.py)`")


def _section(text: str, heading: str) -> str:
    """The body of the ``## heading`` section of a page, up to the next ``## ``."""
    match = re.search(rf"^## {re.escape(heading)}[ \t]*$", text, flags=re.M)
    assert match, f"docs/index.md has no '## {heading}' section"
    rest = text[match.end() :]
    end = re.search(r"^## ", rest, flags=re.M)
    return rest[: end.start()] if end else rest


def _map_rows() -> list[tuple[str, list[str], list[str]]]:
    """(subpackage folder relative to chatterlab/, names in the module column, names in the row)."""
    rows: list[tuple[str, list[str], list[str]]] = []
    lines = [ln for ln in _section(INDEX.read_text(), "Module map").splitlines() if ln.startswith("|")]
    assert len(lines) > 2, "the module map has no table"
    header = [c.strip() for c in lines[0].strip().strip("|").split("|")]
    assert header == ["subpackage", "module", "holds"], header
    sub = None
    for line in lines[2:]:  # past the header and its --- line
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        # a "|" inside a cell would shift the columns and hide a file name from the checks
        assert len(cells) == 3, (
            f"module map row with {len(cells)} cells, not 3 (a '|' inside a cell?): {line}"
        )
        if cells[0]:
            folder = re.fullmatch(r"`([\w/]+)/`", cells[0])
            assert folder, f"module map: the subpackage cell {cells[0]!r} is not a `folder/`"
            sub = "" if folder.group(1) == "chatterlab" else folder.group(1)
        assert sub is not None, f"module map: the first row names no subpackage: {line}"
        modules = PY_NAME.findall(cells[1])
        assert modules, f"module map: a row of {sub or 'chatterlab'}/ names no module: {line}"
        rows.append((sub, modules, PY_NAME.findall(line)))
    return rows


def _resolve(sub: str, name: str) -> Path:
    """A name of the map: ``sub/x.py`` from chatterlab/, a bare ``x.py`` in the row's subpackage."""
    return PKG / name if "/" in name else PKG / sub / name


def test_every_file_the_map_names_exists_where_it_says():
    missing = sorted(
        {
            f"chatterlab/{_resolve(sub, name).relative_to(PKG)}"
            for sub, _, names in _map_rows()
            for name in names
            if not _resolve(sub, name).is_file()
        }
    )
    assert not missing, f"docs/index.md's module map names files that do not exist: {missing}"


def test_every_module_is_in_the_map_once():
    listed: dict[Path, int] = {}
    for sub, modules, _ in _map_rows():
        for name in modules:
            path = _resolve(sub, name)
            listed[path] = listed.get(path, 0) + 1
    modules = {p for p in PKG.rglob("*.py") if p.name not in NOT_MAPPED}
    assert modules, "no module found under chatterlab/"
    absent = sorted(str(p.relative_to(ROOT)) for p in modules - set(listed))
    assert not absent, (
        f"docs/index.md's module map does not name: {absent} (add a row or a name to its subpackage's rows)"
    )
    twice = sorted(str(p.relative_to(ROOT)) for p, n in listed.items() if n > 1)
    assert not twice, f"docs/index.md's module map names these in more than one module cell: {twice}"


def _nav_pages() -> list[str]:
    """The pages of mkdocs.yml's ``nav``, read as text (the config holds a !!python tag)."""
    lines = (ROOT / "mkdocs.yml").read_text().splitlines()
    start = lines.index("nav:")
    pages: list[str] = []
    for line in lines[start + 1 :]:
        if line and not line[0].isspace():
            break  # the next top-level key
        page = re.search(r"([\w./-]+\.md)\s*$", line)
        if page:
            pages.append(page.group(1))
    assert "index.md" in pages and len(pages) > 5, pages
    return pages


def _documentation_links() -> set[str]:
    body = _section(INDEX.read_text(), "Documentation")
    return {m.group(1) for m in re.finditer(r"\]\(([^)#\s]+\.md)(?:#[^)\s]*)?\)", body)}


def test_every_page_of_the_navigation_is_in_the_documentation_list():
    # the API pages are reached through api/index.md, which the list links
    wanted = {
        p for p in _nav_pages() if p != "index.md" and not (p.startswith("api/") and p != "api/index.md")
    }
    links = _documentation_links()
    assert not wanted - links, f"docs/index.md's Documentation list does not link: {sorted(wanted - links)}"
    assert not links - set(_nav_pages()), (
        f"docs/index.md's Documentation list links pages outside mkdocs.yml's nav: {sorted(links - set(_nav_pages()))}"
    )


def test_speed_section_points_to_the_generated_page_and_types_no_number():
    body = _section(INDEX.read_text(), "Speed")
    assert "(performance.md)" in body, "the Speed section must link performance.md"
    assert "benchmarks/" in body, "the Speed section must name benchmarks/"
    # numbers copied by hand went stale (issue 26): the page is generated from benchmarks/results/*.json
    numbers = re.findall(r"\d+(?:\.\d+)?", body)
    assert not numbers, (
        f"the Speed section of docs/index.md types numbers {numbers}: they belong to docs/performance.md"
    )


def test_every_file_architecture_names_exists():
    text = ARCHITECTURE.read_text()
    package_names = {p.name for p in PKG.rglob("*.py")}
    missing = []
    for name in sorted(set(PY_NAME.findall(text))):
        if name.split("/")[0] in {"tests", "benchmarks", "studies"}:
            found = (ROOT / name).is_file()
        elif "/" in name:
            found = (PKG / name).is_file()
        else:  # a bare name in a sentence about its folder: at least a module of that name exists
            found = name in package_names
        if not found:
            missing.append(name)
    assert not missing, f"docs/architecture.md names files that do not exist: {missing}"


def test_the_checks_see_a_stale_map():
    """The parser is not vacuous: the old map's names are caught."""
    assert not _resolve("time", "_milling_setup.py").is_file()
    assert not _resolve("cli", "errors.py").is_file()
    assert _resolve("", "errors.py").is_file() and _resolve("lobes", "time/_core.py").is_file()
    rows = _map_rows()
    assert {sub for sub, _, _ in rows} >= {
        "",
        "time",
        "lobes",
        "frequency",
        "design",
        "uncertainty",
        "selection",
    }
