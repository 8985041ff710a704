"""``microconveyor demo`` on the default env: MicroConveyor-v1's surface and its default shipped
policy carrying a part, a table per target, charts and a GIF of a long carry."""
import json

import pytest
from support.cli import run_cli


def run(*args):
    """``microconveyor demo`` in this process (what it prints and its status; tests/support/cli.py)."""
    return run_cli("demo", *args)


def test_demo_on_two_targets_shows_v1_and_its_default_policy(tmp_path):
    pytest.importorskip("stable_baselines3")
    pytest.importorskip("imageio")
    r = run("--out", str(tmp_path), "--targets", "2e-3,9e-3", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["episode"]["env_id"] == "MicroConveyor-v1" and out["preset"] == "conveyor"
    demo = out["policy_demo"]
    assert demo["policy"].endswith("MicroConveyor-v1/ppo_refined")
    rows = demo["rows"]
    assert [r_["target_m"] for r_ in rows] == [2e-3, 9e-3]
    for row in rows:   # the best shipped v1 policy places both within the tolerance, at rest
        assert row["outcome"] == "rest" and row["success"], row
        assert abs(row["final_position_m"] - row["target_m"] - row["error_m"]) < 1e-12
        assert abs(row["error_m"]) <= demo["tolerance_m"] == 50e-6
        assert 1 <= row["firings"] <= 5
    gif = demo["gif"]   # the long carry: 9 mm by default on v1, a small GIF in --out
    assert gif["path"] == str(tmp_path / "carry.gif") and gif["target_m"] == pytest.approx(9e-3)
    data = (tmp_path / "carry.gif").read_bytes()
    assert data[:4] == b"GIF8" and len(data) == gif["bytes"] < 2_000_000
    assert gif["outcome"] == "rest" and abs(gif["position_error_m"]) <= 50e-6
    for name in ("policy.png", "policy_errors.png", "episode.png", "summary.json"):
        assert (tmp_path / name).stat().st_size > 1000, name
    assert json.loads((tmp_path / "summary.json").read_text())["policy_demo"]["rows"] == rows
    # the table for people goes to stderr under --json: target, rest position, error, firings
    assert "rest position [mm]" in r.stderr and "firings" in r.stderr
    assert "2 of 2 targets within ±50 µm" in r.stderr


def test_demo_refuses_a_plane_target_that_is_not_a_point_in_one_line(tmp_path):
    r = run("--env", "MicroConveyor2D-v0", "--targets", "1e-3", "--out", str(tmp_path))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "x,y pairs" in r.stderr and "MicroConveyor2D-v0" in r.stderr
    assert not any(tmp_path.iterdir())


def test_demo_targets_and_gif_target_are_checked(tmp_path):
    for bad, msg in ((["--targets", "0.2"], "--targets"), (["--gif-target", "-1e-3"],
                                                          "--gif-target")):
        r = run("--out", str(tmp_path), *bad, "--json")
        assert r.returncode == 2 and msg in json.loads(r.stdout)["error"], r.stdout
