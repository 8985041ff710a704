"""The tables of README.md and docs/ that repeat a stored result agree with it: each region
between ``<!-- results:NAME -->`` markers is what ``scripts/results_tables.py`` writes from the
stored JSON, and a percentage written next to a shipped policy's name elsewhere is one of the
figures its ``metadata.json`` records."""
from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from support.scripts import load_script

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


@pytest.fixture(scope="module")
def tables():
    return load_script("results_tables")


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_generated_regions_match_the_stored_results(tables, page):
    text = page.read_text()
    assert tables.render(text, tables.generators(), {}) == text, (
        f"{page.relative_to(ROOT)}: a generated table differs from the stored results; "
        "run python scripts/results_tables.py")


def test_the_readme_holds_the_answer_table_and_every_generator_is_used(tables):
    readme = tables.regions((ROOT / "README.md").read_text())
    assert {"answer", "noise"} <= set(readme)
    used = {name for page in PAGES for name in tables.regions(page.read_text())}
    assert used == set(tables.generators())


def test_markers_are_paired():
    for page in PAGES:
        text = page.read_text()
        opened = re.findall(r"<!-- results:([\w-]+) -->", text)
        closed = re.findall(r"<!-- /results:([\w-]+) -->", text)
        assert opened == closed, page.name


def test_a_changed_result_changes_the_table(tables):
    data = json.loads((ROOT / "docs" / "figures" / "answer_table.json").read_text())
    before = tables.answer_table(data)
    data["methods"]["de"]["nominal"][0]["error_m"] += 1e-3
    assert tables.answer_table(data) != before
    before = tables.answer_table(data)
    for e in data["methods"]["de"]["nominal"]:   # the placement times are tabled too
        e["time_s"] += 1e-3
    assert tables.answer_table(data) != before
    text = "<!-- results:answer -->\nstale\n<!-- /results:answer -->\n"
    out = tables.render(text, {"answer": lambda: "fresh"}, {})
    assert out == "<!-- results:answer -->\nfresh\n<!-- /results:answer -->\n"


def test_answer_table_holds_every_episode():
    data = json.loads((ROOT / "docs" / "figures" / "answer_table.json").read_text())
    n = len(data["distances_m"]) * data["targets_per_distance"]
    assert len(data["targets_m"]) == n
    for name, m in data["methods"].items():
        assert len(m["nominal"]) == n, name
        assert len(m["noise"]) == n * data["noise_seeds"], name
        assert {e["action_noise"] for e in m["noise"]} == {data["noise"]["sigma_action_units"]}
        assert {e["action_noise"] for e in m["nominal"]} == {0.0}
        for e in m["nominal"] + m["noise"]:   # every episode's placement time [s]
            assert 0 < e["time_s"] < 1, name


def _recorded_percentages() -> dict[str, set[str]]:
    """Policy name as the docs write it -> every success rate its metadata records, as
    percentages with 0 and 1 decimals."""
    out: dict[str, set[str]] = {}
    for meta_path in (ROOT / "agents" / "policies").glob("*/*/metadata.json"):
        meta = json.loads(meta_path.read_text())
        values: set[str] = set()
        for key, ev in meta.items():
            if key.startswith("evaluation") and isinstance(ev, dict):
                for k, v in ev.items():
                    if k.startswith("success_rate") and isinstance(v, (int, float)):
                        values |= {f"{100 * v:.0f}", f"{100 * v:.1f}"}
        env_id, name = meta_path.parent.parent.name, meta_path.parent.name
        names = [f"{env_id}/{name}"] + ([f"`{name}`"] if name != "ppo" else [])
        for n in names:
            out.setdefault(n, set()).update(values)
    return out


def _outside_regions(text: str) -> str:
    return re.sub(r"<!-- results:([\w-]+) -->.*?<!-- /results:\1 -->", "", text, flags=re.S)


def test_percentages_next_to_a_shipped_policy_are_its_recorded_figures():
    recorded = _recorded_percentages()
    bad = []
    for page in PAGES:
        for line in _outside_regions(page.read_text()).splitlines():
            named = [n for n in recorded if n in line]
            if not named:
                continue
            allowed = set().union(*(recorded[n] for n in named))
            for pct in re.findall(r"(?<![\w.±=])(\d+(?:\.\d+)?)\s?%", line):
                if pct not in allowed:
                    bad.append(f"{page.name}: {pct} % next to {named}: {line.strip()[:120]}")
    assert not bad, "\n".join(bad)
