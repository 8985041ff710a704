"""Every file of ``scripts/`` and ``benchmarks/`` imports (a script whose package import broke
fails here, not when someone reproduces a figure), and the README's reproduce command for its
answer table runs on a tiny budget."""
import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FILES = sorted([*(ROOT / "scripts").glob("*.py"), *(ROOT / "benchmarks").glob("*.py")])


@pytest.mark.parametrize("path", FILES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_every_script_imports(path):
    pytest.importorskip("stable_baselines3")
    spec = importlib.util.spec_from_file_location(f"_script_{path.stem}", path)
    assert spec is not None and spec.loader is not None
    spec.loader.exec_module(importlib.util.module_from_spec(spec))


def test_the_answer_tables_reproduce_command_runs(tmp_path):
    pytest.importorskip("stable_baselines3")
    readme = (ROOT / "README.md").read_text()
    assert "python scripts/answer_table.py" in readme
    out = tmp_path / "answer.json"
    r = subprocess.run([sys.executable, str(ROOT / "scripts/answer_table.py"), "--per-distance",
                        "1", "--noise-seeds", "1", "--out", str(out)],
                       capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    data = json.loads(out.read_text())
    assert data["env_id"] == "MicroConveyor-v1" and len(data["targets_m"]) == 5
    assert set(data["methods"]) == {"ppo_refined", "de", "mpc_ppo_refined"}
