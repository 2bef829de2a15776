"""Every relative link of the README and docs/ points to a file of the repository, and every #anchor to a heading of
that file (GitHub's slugs), so that a section that moves or disappears breaks a test, not a reader's click."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.conftest import REPO

_LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
_PAGES = sorted([REPO / "README.md", *(REPO / "docs").glob("*.md")])


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped (but - and _), spaces to hyphens.

    >>> slug("Density of the measured pixels (issue 11): what removes them, and why no filter closes the bar")
    'density-of-the-measured-pixels-issue-11-what-removes-them-and-why-no-filter-closes-the-bar'
    >>> slug("`guide`: obstacles")
    'guide-obstacles'
    """
    text = heading.strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    out: set[str] = set()
    in_code = False
    for line in page.read_text(encoding="utf-8").splitlines():
        if line.startswith("```"):
            in_code = not in_code
        elif not in_code and line.startswith("#"):
            base = slug(line.lstrip("#"))
            name, n = base, 1
            while name in out:  # repeated headings get -1, -2, ...
                name, n = f"{base}-{n}", n + 1
            out.add(name)
    return out


def test_the_pages_exist():
    assert len(_PAGES) >= 5 and all(p.is_file() for p in _PAGES)


@pytest.mark.parametrize("page", _PAGES, ids=lambda p: p.relative_to(REPO).as_posix())
def test_relative_links_and_anchors_resolve(page):
    broken = []
    for target in _LINK.findall(page.read_text(encoding="utf-8")):
        if re.match(r"^[a-z]+:", target):  # http(s), mailto: not checked here
            continue
        path, _, anchor = target.partition("#")
        dest = (page.parent / path).resolve() if path else page
        if not dest.exists():
            broken.append(f"{target}: no file {dest}")
        elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
            broken.append(f"{target}: no heading with the anchor #{anchor} in {dest.name}")
    assert not broken, "\n".join(broken)
