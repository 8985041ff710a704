"""``microconveyor place``: one part to one target with the default shipped policy, MPC seeded
by it, or DE; the plan, the rest position, the error, the outcome and the compute."""
import json

import pytest

from microconveyor_env.cli import main


def place(capsys, *args):
    status = main(["place", *args])
    out, err = capsys.readouterr()
    return status, out, err


def test_place_9mm_with_the_default_policy_lands_within_50um(capsys):
    pytest.importorskip("stable_baselines3")
    status, out, err = place(capsys, "--target", "9e-3", "--method", "policy", "--json")
    assert status == 0, err
    r = json.loads(out)
    assert r["env_id"] == "MicroConveyor-v1" and r["policy"].endswith("MicroConveyor-v1/ppo_refined")
    assert r["outcome"] == "rest" and r["success"] and abs(r["error_m"]) <= 50e-6
    assert r["final_position_m"] == pytest.approx(9e-3 + r["error_m"], abs=1e-12)
    assert r["episodes"] == 1 and r["wall_time_s"] > 0
    firings = r["firings"]   # the line fires its actuators in order, each within the env's ranges
    assert [f["actuator"] for f in firings] == list(range(1, len(firings) + 1))
    for f in firings:
        assert 200 <= f["frequency_hz"] <= 6000 and 0 < f["stroke_m"] <= 200e-6
        assert 0 <= f["delay_s"] < 0.1
    # the same placement for people: the plan in Hz, µm, µs, the error in µm
    status, text, _ = place(capsys, "--target", "9e-3")
    assert status == 0
    assert "frequency [Hz]" in text and "stroke [µm]" in text and "delay [µs]" in text
    assert f"error {r['error_m'] * 1e6:+.1f} µm" in text and "1 simulator episode" in text


def test_place_mpc_seeded_by_the_policy_and_de_report_their_compute(capsys):
    pytest.importorskip("stable_baselines3")
    status, out, err = place(capsys, "--target", "3e-3", "--method", "mpc", "--mpc-budgets",
                             "30,10", "--json")
    assert status == 0, err
    mpc = json.loads(out)
    assert mpc["method"] == "mpc" and "seeding the MPC" in mpc["actor"]
    assert mpc["mpc_first_budget"] == 30 and mpc["mpc_replan_budget"] == 10
    # the first plan spends at most 30 model episodes, each re-plan at most 10, plus the part's
    assert 1 < mpc["episodes"] <= 30 + 10 * (len(mpc["firings"]) - 1) + 1
    status, out, err = place(capsys, "--target", "1e-3", "--method", "de", "--budget", "30",
                             "--json")
    assert status == 0, err
    de = json.loads(out)
    assert de["policy"] is None and de["budget"] == 30 and 1 < de["episodes"] <= 31


def test_place_under_perturbation_plays_the_perturbed_episode(capsys):
    pytest.importorskip("stable_baselines3")
    runs = {}
    for noise in ("0", "0.01"):
        status, out, err = place(capsys, "--target", "5e-3", "--noise", noise, "--spread", "0.05",
                                 "--json")
        assert status == 0, err
        runs[noise] = json.loads(out)
    assert runs["0.01"]["noise"] == 0.01 and runs["0.01"]["spread"] == 0.05
    assert runs["0.01"]["error_m"] != runs["0"]["error_m"]   # the noise acted


@pytest.mark.parametrize("args, msg", [
    (["--target", "0.2"], "--target"),
    (["--target", "1e-3", "--budget", "30"], "--budget"),
    (["--target", "1e-3", "--method", "de", "--policy", "x"], "--policy"),
    (["--target", "1e-3", "--mpc-budgets", "30,10"], "--mpc-budgets"),
    (["--target", "1e-3", "--noise", "-1"], "--noise"),
    (["--target", "1e-3", "--env", "MicroConveyor2D-v0"], "X,Y"),   # a point of the plane
    (["--target", "1e-3", "--tolerance", "2e-3"], "--tolerance"),   # beyond 1 mm
    (["--target", "1e-3", "--tolerance", "0"], "--tolerance"),
    (["--target", "1e-3", "--method", "de", "--time-weight", "-1"], "--time-weight"),
    (["--target", "1e-3", "--time-weight", "1e3"], "--time-weight"),   # DE's cost only
])
def test_place_refuses_in_one_line(capsys, args, msg):
    status, out, err = place(capsys, *args)
    assert status == 2 and len(err.strip().splitlines()) == 1 and msg in err, err


@pytest.mark.parametrize("env_id", ["MicroConveyor-v1", "MicroPositioner-v0"])
def test_place_serves_the_precision_asked_for(capsys, env_id):
    # --tolerance is the env's tolerance (success within it) and DE's T_d, with the
    # dissertation's time weight by default on the line (the positioner's DE: precision only);
    # the placement time is reported in s and ms
    status, out, err = place(capsys, "--target", "2e-3", "--method", "de", "--budget", "20",
                             "--tolerance", "1e-5", "--env", env_id, "--json")
    assert status == 0, err
    r = json.loads(out)
    assert r["tolerance_m"] == 1e-5
    assert r["time_weight"] == (1e3 if env_id == "MicroConveyor-v1" else None)
    assert r["placement_time_s"] == r["sim_time_s"] > 0
    assert r["success"] == (r["outcome"] == "rest" and abs(r["error_m"]) <= 1e-5)
    status, text, _ = place(capsys, "--target", "2e-3", "--method", "de", "--budget", "20",
                            "--tolerance", "1e-5", "--time-weight", "0", "--env", env_id)
    assert status == 0 and "(±10 µm)" in text and " ms" in text.splitlines()[-2]
    assert "placement time" not in text.splitlines()[0]   # precision only: no time weight
