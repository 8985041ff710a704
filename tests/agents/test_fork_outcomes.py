"""scripts/fork_outcomes.py: the per-seed bar counted from run metadata, forks traced to the
state they came from, runs off the chart kept in the JSON."""
import json

import pytest
from support.scripts import load_script


def _run(tmp_path, name, seed, success, median_m, forks=None):
    d = tmp_path / name
    d.mkdir()
    meta = {"seed": seed, "steps": 6_000_640,
            "evaluation": {"success_rate_50um": success, "median_abs_error_m": median_m}}
    if forks:
        meta["forks"] = forks
    (d / "metadata.json").write_text(json.dumps(meta))
    return d


def test_counts_the_bar_and_traces_forks(tmp_path):
    fork = [{"at_steps": 4_000_000, "from_seed": 2, "seed": 21}]
    runs = [_run(tmp_path, "a", 0, 0.92, 15e-6),            # at the bar
            _run(tmp_path, "b", 1, 0.90, 20e-6),            # on both edges: at the bar
            _run(tmp_path, "c", 21, 0.95, 20.5e-6, fork),   # median just over
            _run(tmp_path, "d", 3, 0.89, 5e-6),             # success just under
            _run(tmp_path, "e", 4, 0.13, 1.5e-3)]           # far off the chart
    out = tmp_path / "fig" / "forks"
    assert load_script("fork_outcomes").main(["recipe=" + ",".join(map(str, runs[:3])),
                           "other=" + ",".join(map(str, runs[3:])), "--out", str(out)]) == 0
    data = json.loads(out.with_suffix(".json").read_text())
    rec, other = data["variants"]
    assert (rec["at_bar"], rec["n"], other["at_bar"], other["n"]) == (2, 3, 0, 2)
    assert [r["at_bar"] for r in rec["runs"]] == [True, True, False]
    assert rec["runs"][2]["state_seed"] == 2 and rec["runs"][2]["seed"] == 21
    assert other["runs"][1]["median_abs_error_m"] == pytest.approx(1.5e-3)
    assert out.with_suffix(".png").stat().st_size > 10_000


def test_refuses_unfinished_runs_and_bad_specs(tmp_path):
    d = tmp_path / "unfinished"
    d.mkdir()
    (d / "metadata.json").write_text(json.dumps({"seed": 0}))
    script = load_script("fork_outcomes")
    with pytest.raises(SystemExit, match="no final evaluation"):
        script.main([f"x={d}", "--out", str(tmp_path / "o")])
    with pytest.raises(SystemExit, match="LABEL=FOLDER"):
        script.main([str(d), "--out", str(tmp_path / "o")])
