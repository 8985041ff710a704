"""Every registered env id through ``place`` and ``demo``: the positioner and the plane are
placed with their default shipped policies and with the model-based methods defined there, a
target outside the env's range or a negative seed is refused in one line, and the
model-based methods run on a user's own preset, where a policy of another scene is refused."""
import json
from pathlib import Path

import pytest

from microconveyor_env.cli import main

pytest.importorskip("stable_baselines3")

ROOT = Path(__file__).resolve().parents[2]


def run(capsys, *args):
    capsys.readouterr()
    status = main(list(args))
    out, err = capsys.readouterr()
    return status, out, err


def place_json(capsys, *args):
    status, out, err = run(capsys, "place", *args, "--json")
    assert status == 0, err or out
    return json.loads(out)


def test_place_on_the_positioner_with_its_policy_its_controller_and_de(capsys):
    base = ("--env", "MicroPositioner-v0", "--target", "7.5e-3")
    pol = place_json(capsys, *base, "--method", "policy")
    assert pol["env_id"] == "MicroPositioner-v0"
    assert pol["policy"].endswith("MicroPositioner-v0/dagger")
    assert pol["outcome"] == "rest" and pol["success"] and abs(pol["error_m"]) <= 50e-6
    assert pol["final_position_m"] == pytest.approx(7.5e-3 + pol["error_m"], abs=1e-12)
    for f in pol["firings"]:   # any actuator fires; each firing ends at rest
        assert f["actuator"] >= 1 and f["actuator_position_m"] == pytest.approx(
            (f["actuator"] - 1) * 0.25e-3)
        assert 200 <= f["frequency_hz"] <= 2000 + 1e-9 and 100e-6 <= f["stroke_m"] <= 200e-6 + 1e-12
    assert pol["firings"][-1]["position_after_m"] == pol["final_position_m"]
    mpc = place_json(capsys, *base, "--method", "mpc")
    assert mpc["policy"] is None and mpc["mpc_model"] == "identified"
    assert mpc["success"] and mpc["episodes"] > len(mpc["firings"])
    de = place_json(capsys, *base, "--method", "de", "--budget", "30")
    assert de["budget"] == 30 and de["plan_firings"] == 5 and 1 < de["episodes"] <= 31
    assert len(de["firings"]) <= 5
    # for people: mm, µm, Hz; where each actuator is and where the part rests after it
    status, text, _ = run(capsys, "place", *base)
    assert status == 0 and "at [mm]" in text and "rest after [mm]" in text
    assert f"error {pol['error_m'] * 1e6:+.1f} µm" in text


def test_place_on_the_plane_with_its_policy_and_its_controller_only(capsys):
    r = place_json(capsys, "--env", "MicroConveyor2D-v1", "--target", "1.5e-3,0.5e-3")
    assert r["policy"].endswith("MicroConveyor2D-v1/ppo") and r["target_m"] == [1.5e-3, 0.5e-3]
    assert r["outcome"] == "rest" and r["success"] and 0 <= r["error_m"] <= 50e-6
    x, y = r["final_position_m"]
    assert r["error_m"] == pytest.approx(((x - 1.5e-3) ** 2 + (y - 0.5e-3) ** 2) ** 0.5)
    assert all(len(f["actuator_position_m"]) == 2 for f in r["firings"])
    # the plane's one-step controller, asked for ±10 µm: the env's tolerance is the request
    mpc = place_json(capsys, "--env", "MicroConveyor2D-v1", "--target", "1.5e-3,0.5e-3",
                     "--method", "mpc", "--tolerance", "1e-5")
    assert mpc["policy"] is None and mpc["tolerance_m"] == 1e-5
    assert mpc["outcome"] == "rest" and mpc["success"] and mpc["error_m"] <= 10e-6
    assert mpc["placement_time_s"] == mpc["sim_time_s"] > 0 and mpc["episodes"] > 1
    status, _, err = run(capsys, "place", "--env", "MicroConveyor2D-v1", "--target",
                         "1.5e-3,0.5e-3", "--method", "de")
    assert status == 2 and len(err.strip().splitlines()) == 1, err
    assert "its methods are policy, mpc" in err, err


@pytest.mark.parametrize("args, msg", [
    (["--target", "0.1e-3"], "outside MicroConveyor-v1's target range, 0.5 to 10 mm"),
    (["--target", "0.1"], "outside MicroConveyor-v1's target range, 0.5 to 10 mm"),
    (["--target", "3e-3", "--env-kwargs", "target_range:(0.5e-3, 3e-3)", "--target", "5e-3"],
     "0.5 to 3 mm"),
    (["--target", "11e-3", "--env", "MicroPositioner-v0"], "MicroPositioner-v0's target range"),
    (["--target", "3e-3,3e-3", "--env", "MicroConveyor2D-v0"], "the actuator grid's box"),
    (["--target", "3e-3", "--seed", "-1"], "--seed"),
    (["--target", "3e-3", "--env", "MicroPositioner-v0", "--method", "mpc", "--policy", "x"],
     "--policy"),
    (["--target", "3e-3", "--env", "MicroPositioner-v0", "--method", "mpc", "--mpc-budgets",
      "30,10"], "--mpc-budgets"),
])
def test_place_refuses_in_one_line(capsys, args, msg):
    status, out, err = run(capsys, "place", *args)
    assert status == 2 and len(err.strip().splitlines()) == 1 and msg in err, err
    assert "internal error" not in err


def test_model_based_methods_run_on_a_users_own_preset(capsys, tmp_path):
    mine = tmp_path / "my.yaml"
    text = (ROOT / "configs" / "conveyor.yaml").read_text()
    mine.write_text(text.replace("name: conveyor", "name: mine", 1))
    base = ("--target", "3e-3", "--preset", str(mine))
    mpc = place_json(capsys, *base, "--method", "mpc", "--mpc-budgets", "30,10")
    assert mpc["env_kwargs"] == {"preset": str(mine)} and mpc["outcome"] in ("rest", "detached")
    assert "another scene" in mpc["actor"] and mpc["mpc_seeded"]
    de = place_json(capsys, *base, "--method", "de", "--budget", "30")
    assert de["env_kwargs"] == {"preset": str(mine)} and de["policy"] is None
    pos = place_json(capsys, "--env", "MicroPositioner-v0", "--target", "5e-3", "--preset",
                     str(mine), "--method", "mpc")
    assert pos["success"]
    status, _, err = run(capsys, "place", *base)   # the policy acts: its own scene only
    assert status == 2 and len(err.strip().splitlines()) == 1
    assert "Evaluating a policy on another scene is refused" in err


def test_demo_on_the_positioner_and_the_plane_with_their_default_policies(capsys, tmp_path):
    pytest.importorskip("imageio")
    status, out, err = run(capsys, "demo", "--env", "MicroPositioner-v0", "--out",
                           str(tmp_path / "p"), "--targets", "7.5e-3", "--gif-target", "0",
                           "--json")
    assert status == 0, err
    res = json.loads(out)
    assert res["episode"]["env_id"] == "MicroPositioner-v0"
    demo = res["policy_demo"]
    assert demo["policy"].endswith("MicroPositioner-v0/dagger") and demo["gif"] is None
    assert [r["target_m"] for r in demo["rows"]] == [7.5e-3] and demo["rows"][0]["success"]
    assert "rest position [mm]" in err and "1 of 1 targets within ±50 µm" in err
    for name in ("policy.png", "policy_errors.png", "episode.png"):
        assert (tmp_path / "p" / name).stat().st_size > 1000
    status, out, err = run(capsys, "demo", "--env", "MicroConveyor2D-v1", "--out",
                           str(tmp_path / "q"), "--targets", "1.5e-3,0.5e-3", "--json")
    assert status == 0, err
    demo = json.loads(out)["policy_demo"]
    assert demo["policy"].endswith("MicroConveyor2D-v1/ppo")
    assert demo["rows"][0]["target_m"] == [1.5e-3, 0.5e-3] and demo["rows"][0]["success"]
    gif = demo["gif"]   # one frame per firing, to the default point of the grid
    assert gif["target_m"] == pytest.approx([5 / 3 * 1e-3, 1 / 3 * 1e-3])
    assert (tmp_path / "q" / "carry.gif").read_bytes()[:4] == b"GIF8"
    assert gif["frames"] == gif["firings"] + 1
    assert "distance [µm]" in err and "(1.500, 0.500)" in err


def test_demo_refuses_targets_outside_the_envs_range_in_one_line(capsys, tmp_path):
    for args, msg in ((["--env", "MicroConveyor2D-v0", "--targets", "1e-3"], "x,y pairs"),
                      (["--env", "MicroPositioner-v0", "--targets", "20e-3"], "--targets"),
                      (["--gif-target", "20e-3"], "--gif-target")):
        status, _, err = run(capsys, "demo", "--out", str(tmp_path), *args)
        assert status == 2 and len(err.strip().splitlines()) == 1 and msg in err, err
    assert not any(tmp_path.iterdir())
