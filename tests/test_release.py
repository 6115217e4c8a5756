"""One version, one citation, and the code that travels with the site.

- **One version.** ``closedloop.__version__`` is the only place the version is written: the wheel
  built from ``pyproject.toml`` carries it, the site's wheel and archive are named with it, the pages
  show it, ``closedloop --version`` prints it, and ``CITATION.cff`` and the newest released entry of
  ``CHANGELOG.md`` (Keep a Changelog) state it, with the same date.
- **One citation.** ``CITATION.cff`` names the title and the authors of ``_config.yml``, the two
  licences of the repository, and the paper by its own English title; the landing page shows it,
  every page carries it in its ``<meta>`` tags.
- **The references.** The bibliography's first section is the paper and the twelve works it cites,
  the second the rest; every DOI, ISBN or URL is well formed.
- **The downloads.** Every page's download menu offers the wheel and the archive, which exist; no
  entry of the menu leads to a file that is not there; the archive holds every notebook the site
  offers, the files they read, the library's source as in the repository, and the site's wheel.

The site is built once for the session (``built_site``, conftest.py); ``CLOSEDLOOP_SITE_BUILT=1``
reads the ``_build/html`` already there.
"""

import datetime
import html
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
import yaml

from ._toc import toc_pages

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "book" / "_ext"))
import companion  # noqa: E402

CITATION = yaml.safe_load((ROOT / "CITATION.cff").read_text(encoding="utf-8"))
#: A released entry of CHANGELOG.md: "## [0.1.0] - 2026-11-28".
RELEASE = re.compile(r"^## \[(\d+\.\d+\.\d+)\] - (\d{4}-\d{2}-\d{2})$", re.M)


def version():
    from closedloop import __version__

    return __version__


# --- one version --------------------------------------------------------------------------------
def test_the_version_is_written_once():
    written = re.findall(r"^__version__ = \"([^\"]+)\"$", (ROOT / "src" / "closedloop" / "__init__.py").read_text(),
                         re.M)
    assert written == [version()] and re.fullmatch(r"\d+\.\d+\.\d+", version())
    import tomllib

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" not in project["project"] and project["project"]["dynamic"] == ["version"]
    assert project["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "closedloop.__version__"}


def test_the_command_prints_the_version():
    done = subprocess.run([sys.executable, "-m", "closedloop.cli", "--version"], capture_output=True, text=True,
                          check=True)
    assert done.stdout.strip() == f"closedloop {version()}"


def test_the_changelog_and_the_citation_state_the_version_and_its_date():
    text = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    assert text.startswith("# Changelog\n") and "keepachangelog.com" in text
    assert "\n## [Unreleased]\n" in text and text.index("## [Unreleased]") < RELEASE.search(text).start()
    releases = RELEASE.findall(text)
    assert releases[0][0] == version(), "the newest entry of CHANGELOG.md is not this version"
    assert [tuple(map(int, v.split("."))) for v, _ in releases] == \
        sorted((tuple(map(int, v.split("."))) for v, _ in releases), reverse=True)
    assert str(CITATION["version"]) == version()
    assert CITATION["date-released"] == datetime.date.fromisoformat(releases[0][1])


def test_the_site_is_named_and_marked_with_the_version(built_site):
    for edition in (built_site, built_site / "vi"):
        downloads = sorted(path.name for path in (edition / "_downloads").iterdir())
        assert downloads == sorted(["CITATION.cff", f"closedloop-{version()}-py3-none-any.whl",
                                    f"closedloop-companion-{version()}.zip"])
        landing = (edition / "book" / "intro.html").read_text(encoding="utf-8")
        assert f'<meta name="closedloop:version" content="{version()}">' in landing
        assert f'<span class="companion-version">{version()}</span>' in landing
    with zipfile.ZipFile(built_site / "_downloads" / companion.wheel_name()) as wheel:
        metadata = wheel.read(f"closedloop-{version()}.dist-info/METADATA").decode()
    assert re.search(r"^Version: (.+)$", metadata, re.M).group(1) == version()
    assert 'Requires-Dist: bokeh>=3.4; extra == "plot"' in metadata     # a chapter's figures need no other extra


# --- one citation ------------------------------------------------------------------------------
def test_the_citation_names_the_book_its_authors_and_its_licences():
    config = yaml.safe_load((ROOT / "_config.yml").read_text(encoding="utf-8"))
    assert CITATION["cff-version"] == "1.2.0" and CITATION["type"] == "software"
    assert CITATION["title"] == config["title"]
    assert [person["name"] for person in CITATION["authors"]] == [config["author"]]
    assert config["author"] in (ROOT / "LICENSE").read_text() and config["author"] in \
        (ROOT / "LICENSE-TEXT").read_text()
    assert CITATION["license"] == ["MIT", "CC-BY-4.0"]
    assert "MIT License" in (ROOT / "LICENSE").read_text()
    assert "Creative Commons Attribution 4.0" in (ROOT / "LICENSE-TEXT").read_text()
    paper = CITATION["references"][0]
    assert paper["title"] == "Influence of initial conditions on movement behaviors of the slide-crank mechanism"
    assert [f"{p['family-names']} {p['given-names']}" for p in paper["authors"]] == \
        ["Nguyễn Văn Khang", "Nguyễn Văn Quyền", "Phạm Thị Mai Anh"] and paper["year"] == 2018


def test_the_landing_page_and_every_page_carry_the_citation(built_site):
    landing = re.sub(r"<[^>]+>", "", (built_site / "book" / "intro.html").read_text(encoding="utf-8"))
    landing = " ".join(html.unescape(landing).split())
    date = CITATION["date-released"].isoformat()
    assert f"{CITATION['authors'][0]['name']} ({date[:4]}), {CITATION['title']}, version {version()}, {date}." \
        in landing
    for page in toc_pages():
        text = (built_site / f"{page}.html").read_text(encoding="utf-8")
        assert f'<meta name="citation_title" content="{html.escape(CITATION["title"])}">' in text, page
        assert f'<meta name="citation_publication_date" content="{date.replace("-", "/")}">' in text, page


# --- the references ----------------------------------------------------------------------------
def bibliography():
    """``{key: {field: value}}`` of book/references.bib (a value's braces kept as written, its spaces single)."""
    text = (ROOT / "book" / "references.bib").read_text(encoding="utf-8")
    entries = {}
    for start in re.finditer(r"^@\w+\{([\w-]+),", text, re.M):
        fields, i = {}, start.end()
        while (field := re.compile(r"\s*(\w+)\s*=\s*\{").match(text, i)):
            depth, j = 1, field.end()
            while depth:
                depth += {"{": 1, "}": -1}.get(text[j], 0)
                j += 1
            fields[field.group(1).lower()] = " ".join(text[field.end():j - 1].split())
            i = j + 1 if text[j:j + 1] == "," else j
        entries[start.group(1)] = fields
    return entries


def test_the_bibliography_lists_the_paper_and_its_references_apart():
    entries = bibliography()
    cited = [key for key, entry in entries.items() if entry.get("keywords") == "paper"]
    assert len(cited) == 13 and "khang2018" in cited          # the paper and the 12 works of its list
    paper = entries["khang2018"]
    assert paper["title"] == CITATION["references"][0]["title"]
    assert "Ảnh hưởng của điều kiện đầu" in paper["note"] and paper["year"] == "2018"
    page = (ROOT / "book" / "bibliography.md").read_text(encoding="utf-8")
    assert page.count("```{bibliography}") == 2
    assert ':filter: keywords % "paper"' in page and ':filter: not keywords % "paper"' in page


def test_every_identifier_of_a_reference_is_well_formed():
    """A DOI, an ISBN-13 with its hyphens, or an https address; the page says each was checked."""
    entries = bibliography()
    assert len(entries) >= 23 and all("title" in entry and "year" in entry for entry in entries.values())
    identified = [key for key, entry in entries.items() if {"doi", "isbn", "url"} & set(entry)]
    assert identified
    for key in identified:
        fields = entries[key]
        assert re.fullmatch(r"10\.\d{4,}/\S+", fields.get("doi", "10.0000/x")), key
        assert re.fullmatch(r"97[89]-\d+-\d+-\d+-\d", fields.get("isbn", "978-0-0000-0000-0")), key
        assert re.fullmatch(r"https://\S+", fields.get("url", "https://x")), key


# --- the downloads ---------------------------------------------------------------------------------
@pytest.mark.parametrize("edition", ["", "vi/"], ids=["en", "vi"])
def test_every_page_offers_the_wheel_and_the_archive_and_no_missing_file(built_site, edition):
    site = built_site / edition
    for page in toc_pages():
        text = (site / f"{page}.html").read_text(encoding="utf-8")
        menu = text[text.index("dropdown-download-buttons"):]
        menu = menu[:menu.index("</ul>")]
        links = re.findall(r'<a href="([^"]+)"', menu)
        up = "../" * page.count("/")
        assert f"{up}_downloads/{companion.wheel_name()}" in links, page
        assert f"{up}_downloads/{companion.archive_name()}" in links, page
        missing = [link for link in links if not (site / Path(page).parent / link).is_file()]
        assert missing == [], f"{page}: the download menu leads to no file: {missing}"


def test_the_archive_holds_the_notebooks_their_files_and_the_library(built_site):
    from ipynb_download import DOWNLOAD_FILES

    with zipfile.ZipFile(built_site / "_downloads" / companion.archive_name()) as archive:
        names = archive.namelist()
        top = {name.split("/")[0] for name in names}
        assert top == {Path(companion.archive_name()).stem}
        inside = {name.split("/", 1)[1]: name for name in names}
        wheel = archive.read(inside[companion.wheel_name()])
        readme = archive.read(inside["README.md"]).decode()
    offered = {path.relative_to(built_site / "_sources").as_posix()
               for path in (built_site / "_sources").rglob("*.ipynb")}
    assert offered and offered <= set(inside)
    shipped = {path for paths in DOWNLOAD_FILES.values() for path in paths}
    for path in shipped:
        files = [p for p in (ROOT / path).rglob("*.py")] if (ROOT / path).is_dir() else [ROOT / path]
        assert {f.relative_to(ROOT).as_posix() for f in files} <= set(inside), path
    source = {p.relative_to(ROOT).as_posix() for p in (ROOT / "src").rglob("*")
              if p.is_file() and "__pycache__" not in p.parts and ".egg-info" not in p.as_posix()}
    assert source and source <= set(inside) and "pyproject.toml" in inside
    assert wheel == (built_site / "_downloads" / companion.wheel_name()).read_bytes()
    commands = companion.RUN_COMMANDS.format(wheel=companion.wheel_name()).splitlines()
    assert f'"{companion.wheel_name()}[plot]"' in commands[2] and all(line in readme for line in commands)
