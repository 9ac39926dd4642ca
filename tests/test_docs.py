"""The README and the documentation pages describe the product as it is: the README stays short, no
development history gets in, the generated tables are those of the code, and every figure a page
shows and every page it links exists. (CI builds the site with `mkdocs build --strict`: `make docs`.)"""
import re
import subprocess
import sys

import pytest

from paths import ROOT

DOCS = ROOT / "docs"
# Pages the site publishes: docs/*.md but the material waiting to be merged (_*.md, excluded by mkdocs.yml)
PAGES = sorted(p for p in DOCS.rglob("*.md") if not p.name.startswith("_"))
HISTORY = re.compile(r"\bstop\s+[1-9][0-9]?\b|\bthe issue\b|\bsession|\bused to\b", re.IGNORECASE)


def test_the_readme_is_short():
    assert len((ROOT / "README.md").read_text(encoding="utf-8").splitlines()) <= 250


@pytest.mark.parametrize("path", [ROOT / "README.md", *PAGES], ids=lambda p: p.relative_to(ROOT).as_posix())
def test_no_development_history(path):
    found = [(k, m.group(0)) for k, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
             for m in HISTORY.finditer(line)]
    assert not found, f"{path.relative_to(ROOT)}: history wording at line(s) {found}"


def test_the_generated_tables_are_those_of_the_code():
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "docs_tables.py"), "--check"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


@pytest.mark.parametrize("path", [ROOT / "README.md", *PAGES], ids=lambda p: p.relative_to(ROOT).as_posix())
def test_every_link_and_figure_leads_to_a_file(path):
    for target in re.findall(r"\]\(([^)\s#]+)(?:#[^)\s]*)?\)", path.read_text(encoding="utf-8")):
        if not re.match(r"[a-z]+:", target):
            assert (path.parent / target).is_file(), f"{path.relative_to(ROOT)}: {target} does not exist"


def test_every_page_is_in_the_navigation():
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    listed = set(re.findall(r":\s*([\w/-]+\.md)\s*$", nav, re.MULTILINE))
    assert listed == {p.relative_to(DOCS).as_posix() for p in PAGES}
