"""Links in README.md and docs/ work in the repository, not only in the built site: every
relative link names a file that exists, and every ``#anchor`` a heading of that file (slugged as
MkDocs' ``toc`` extension slugs it)."""
from __future__ import annotations

import re
import unicodedata
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
LINK = re.compile(r"\]\(([^)\s]+)\)")
FENCE = re.compile(r"```.*?```", re.S)


def slug(heading: str) -> str:
    """Python-Markdown's ``toc.slugify``: ASCII, lower case, punctuation dropped, spaces to -."""
    text = unicodedata.normalize("NFKD", heading).encode("ascii", "ignore").decode()
    text = re.sub(r"[^\w\s-]", "", text).strip().lower()
    return re.sub(r"[-\s]+", "-", text)


def anchors(page: Path) -> set[str]:
    text = FENCE.sub("", page.read_text())
    return {slug(re.sub(r"[`*]", "", h)) for h in re.findall(r"^#{1,6}\s+(.+?)\s*$", text, re.M)}


def test_slug_matches_mkdocs():
    assert slug("1. The dissertation's problem (its Table 4.3)") == (
        "1-the-dissertations-problem-its-table-43")
    assert slug("Placing a part at 1–9 mm") == "placing-a-part-at-19-mm"


@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(ROOT)) for p in PAGES])
def test_relative_links_resolve(page):
    bad = []
    for target in LINK.findall(FENCE.sub("", page.read_text())):
        if re.match(r"[a-z]+:", target):          # http:, https:, mailto:
            continue
        path, _, anchor = target.partition("#")
        dest = (page.parent / path).resolve() if path else page
        if not dest.exists():
            bad.append(f"{target}: no file {dest.relative_to(ROOT) if ROOT in dest.parents else dest}")
        elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
            bad.append(f"{target}: no heading #{anchor} in {dest.name}")
    assert not bad, "\n".join(bad)
