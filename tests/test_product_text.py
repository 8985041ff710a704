"""Product text says what the thing is and does, not how it came to be: no issue numbers, no
"the bar", no sessions, no engineers, and no dates outside docs/results.md (whose provenance
column dates each measurement).

Checked: README.md, every page under docs/, every command's ``--help``, the module docstrings
under microconveyor_env/ and agents/, and the ``note`` of every shipped policy's metadata.
``tests/product_text_allowlist.txt`` names sources still to be rewritten (one per line, as the
failure names them); an entry whose source is clean fails too, so the list only shrinks.
"""
from __future__ import annotations

import argparse
import ast
import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ALLOWLIST = Path(__file__).with_name("product_text_allowlist.txt")
HISTORY = {
    "issue number": re.compile(r"\bissues?\s+#?\d+", re.I),
    "#number": re.compile(r"(?<![\w/&(\[])#\d+\b"),
    "the bar": re.compile(r"\bthe bar\b", re.I),
    "session": re.compile(r"\bsessions?\b", re.I),
    "engineer": re.compile(r"\bengineers?\b", re.I),
}
DATE = re.compile(r"\b(19|20)\d\d-[01]\d-[0-3]\d\b")
DATED_PAGE = "docs/results.md"   # its provenance column holds dates


def _pages() -> dict[str, str]:
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    return {f"page {p.relative_to(ROOT)}": p.read_text() for p in pages}


def _cli_help() -> dict[str, str]:
    from microconveyor_env.cli import build_parser

    parser = build_parser()
    out = {"help microconveyor": parser.format_help()}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out[f"help {name}"] = sub.format_help()
    return out


def _docstrings() -> dict[str, str]:
    out = {}
    for pkg in ("microconveyor_env", "agents"):
        for path in sorted((ROOT / pkg).rglob("*.py")):
            doc = ast.get_docstring(ast.parse(path.read_text()), clean=False)
            if doc:
                out[f"docstring {path.relative_to(ROOT)}"] = doc
    return out


def _notes() -> dict[str, str]:
    out = {}
    for meta in sorted((ROOT / "agents" / "policies").glob("*/*/metadata.json")):
        note = json.loads(meta.read_text()).get("note")
        if note:
            out[f"note {meta.parent.relative_to(ROOT)}"] = note
    return out


def findings(sources: dict[str, str]) -> dict[str, list[str]]:
    """Source name -> the history it holds (each hit as ``what: text``)."""
    found: dict[str, list[str]] = {}
    for name, text in sources.items():
        hits = [f"{what}: {m.group(0)!r}" for what, rx in HISTORY.items() for m in rx.finditer(text)]
        if name != f"page {DATED_PAGE}":
            hits += [f"date: {m.group(0)!r}" for m in DATE.finditer(text)]
        if hits:
            found[name] = hits
    return found


def _allowed() -> set[str]:
    if not ALLOWLIST.is_file():
        return set()
    return {ln.strip() for ln in ALLOWLIST.read_text().splitlines()
            if ln.strip() and not ln.startswith("#")}


def test_the_patterns_catch_history():
    text = ("met the bar of issue 20 in the evening session of another engineer on 2026-11-24, "
            "see #21; a link [x](agents.md#1-the-problem) and &#8212; are not history")
    hits = findings({"page x.md": text})["page x.md"]
    assert len(hits) == 6, hits   # issue 20, #21, the bar, session, engineer, the date


@pytest.mark.parametrize("kind", ["pages", "notes", "cli help", "docstrings"])
def test_no_history_in_product_text(kind):
    sources = {"pages": _pages, "notes": _notes, "cli help": _cli_help,
               "docstrings": _docstrings}[kind]()
    allowed = _allowed()
    found = findings(sources)
    bad = {k: v for k, v in found.items() if k not in allowed}
    assert not bad, "history in product text:\n" + "\n".join(
        f"{k}: {'; '.join(v[:6])}" for k, v in sorted(bad.items()))
    clean = sorted(k for k in allowed if k in sources and k not in found)
    assert not clean, f"remove from {ALLOWLIST.name} (now clean): {clean}"


def test_allowlist_names_only_sources_that_exist():
    names = {*_pages(), *_notes(), *_cli_help(), *_docstrings()}
    assert not sorted(_allowed() - names), "allowlist entries that name no source"
