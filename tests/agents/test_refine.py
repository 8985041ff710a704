"""`refine`: Newton corrections of a policy's last firing, fitted back into the actor."""
import json
import zipfile

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from agents.rl.evaluation.evaluate import load_policy  # noqa: E402
from agents.rl.refinement.corrections import (  # noqa: E402
    NOOP,
    correct_first_firing,
    correct_last_firing,
    labelled_episodes,
    play,
)
from agents.rl.refinement.fit import MeanActor, fit  # noqa: E402
from agents.rl.refinement.refine import refine  # noqa: E402
from agents.rl.refinement.settings import RefineSettings  # noqa: E402
from agents.rl.refinement.writer import write_refined  # noqa: E402
from agents.rl.artefacts.shipped import shipped_path  # noqa: E402
from support.cli import run_cli  # noqa: E402


def _shipped():
    return load_policy(shipped_path("ppo", "MicroConveyor-v1"))


def test_newton_lands_the_last_firing_and_touches_nothing_else():
    pol = _shipped()
    # far targets, where the shipped policy ends 30-55 um past them (a smooth bias, measured)
    targets = np.linspace(6.0e-3, 9.0e-3, 16)
    ep = play(pol.config, targets, actor=MeanActor(pol))
    assert np.all(ep.rest) and np.nanmin(np.abs(ep.error_m)) > 10e-6
    plans, keep = correct_last_firing(pol.config, targets, ep, RefineSettings(newton_iterations=4))
    assert keep.mean() >= 0.9
    again = play(pol.config, targets, plans=plans)
    assert np.all(np.abs(again.error_m[keep]) <= 10e-6)
    last = ep.taken.sum(1) - 1
    changed = np.any(plans != ep.actions, axis=2)
    for i in range(len(targets)):   # only the last firing taken moved
        assert not changed[i, :last[i]].any() and not changed[i, last[i] + 1:].any()
    assert changed[keep, last[keep]].all()


def test_a_correction_that_changes_the_episode_length_is_not_kept(monkeypatch):
    """The states after a corrected firing are only valid labels if the episode still ends
    there: the final replay of episode 0 is given another length, and its correction is dropped."""
    import agents.rl.refinement.corrections as mod

    pol = _shipped()
    targets = np.linspace(6.0e-3, 9.0e-3, 4)
    ep = play(pol.config, targets, actor=MeanActor(pol))
    settings = RefineSettings(newton_iterations=3)
    calls, real_play = [], mod.play

    def longer_final(config, t, actor=None, plans=None):
        out = real_play(config, t, actor=actor, plans=plans)
        calls.append(1)
        if len(calls) == 3 * 4 + 1:   # 3 iterations x (base + 3 probes), then the final replay
            taken = out.taken.copy()
            taken[0, :] = True
            taken[0, -1] = not ep.taken[0, -1]
            out = out._replace(taken=taken)
        return out

    monkeypatch.setattr(mod, "play", longer_final)
    _, keep = correct_last_firing(pol.config, targets, ep, settings)
    assert len(calls) == 13 and not keep[0] and keep[1:].all()


def test_the_first_firing_alone_lands_near_targets_the_policy_overshoots():
    """Near targets (0.5-0.8 mm) the shipped policy's first firing carries the part past
    (measured: 150-540 um); Newton on the first firing alone, inside the box, stops it there."""
    pol = _shipped()
    cfg = pol.config
    targets = np.array([0.52e-3, 0.6e-3, 0.7e-3, 0.8e-3, 5.0e-3])
    ep = play(cfg, targets, actor=MeanActor(pol))
    failed = ~(ep.rest & (np.abs(ep.error_m) <= cfg.tolerance))
    assert failed[:4].all()
    plans, keep = correct_first_firing(cfg, targets, ep, RefineSettings())
    assert keep[:4].all() and not keep[4]   # 5 mm: not failed, and beyond one firing's reach
    again = play(cfg, targets[:4], plans=plans[:4])
    assert np.all(again.taken.sum(1) == 1) and np.all(np.abs(again.error_m) <= 10e-6)
    assert np.all(np.abs(plans[:, 0]) < 1.0) and np.all(plans[:, 1:] == NOOP)
    # an episode that already succeeded is left alone, however well one firing would do
    done = ep._replace(error_m=np.where(np.arange(5) == 0, 0.0, ep.error_m),
                       rest=np.where(np.arange(5) == 0, True, ep.rest))
    assert correct_first_firing(cfg, targets, done, RefineSettings())[1].tolist() == [
        False, True, True, True, False]


def test_a_first_firing_correction_replaces_a_last_firing_one(monkeypatch):
    import agents.rl.refinement.corrections as mod

    pol = _shipped()
    targets = np.array([0.6e-3, 7.5e-3])
    ep = play(pol.config, targets, actor=MeanActor(pol))
    real = mod.correct_last_firing
    monkeypatch.setattr(mod, "correct_last_firing",
                        lambda *a: (real(*a)[0], np.array([True, True])))   # both "kept"
    lab, last_kept, first_kept = labelled_episodes(pol.config, targets, ep, RefineSettings())
    assert first_kept.tolist() == [True, False] and last_kept.tolist() == [False, True]
    assert lab.taken[0].sum() == 1


def test_labels_sit_at_the_states_of_the_corrected_episodes():
    pol = _shipped()
    cfg = pol.config
    targets = np.array([0.6e-3, 7.5e-3, 8.5e-3])
    ep = play(cfg, targets, actor=MeanActor(pol))
    lab, last_kept, first_kept = labelled_episodes(cfg, targets, ep, RefineSettings())
    assert first_kept.tolist() == [True, False, False] and last_kept.tolist() == [False, True, True]
    assert lab.taken[0].sum() == 1 and np.abs(lab.error_m[0]) <= 10e-6   # one firing, landed
    for i in (1, 2):   # a corrected last firing: the same states, another last action
        n = ep.taken[i].sum()
        assert np.array_equal(lab.taken[i], ep.taken[i])
        assert np.array_equal(lab.obs[i, :n], ep.obs[i, :n])
        assert np.array_equal(lab.actions[i, :n - 1], ep.actions[i, :n - 1])
        assert not np.array_equal(lab.actions[i, n - 1], ep.actions[i, n - 1])


def test_the_fit_compares_actions_as_the_env_fires_them():
    """A mean beyond the box with a label beyond it costs nothing (the env clips both); the
    weights come back in float32."""
    import torch

    pol = _shipped()
    actor = MeanActor(pol)
    obs = play(pol.config, np.array([2e-3, 6e-3]), actor=actor).obs[:, 0]
    raw = actor.raw(obs)
    assert (np.abs(raw) > 1).any()
    labels = np.where(np.abs(raw) > 1, 3.0 * np.sign(raw), raw)   # same side of the box
    before, after = fit(actor, obs, labels, 5)
    assert before < 1e-12 and after <= before
    assert all(p.dtype == torch.float32 for p in actor.net.parameters())
    inside = np.where(np.abs(raw) > 1, 0.5 * np.sign(raw), raw)   # pulled inside: it costs
    assert fit(actor, obs, inside, 1)[0] > 0.1


def test_refine_keeps_its_best_round_and_writes_a_policy_folder(tmp_path):
    import shutil

    src = src_folder = tmp_path / "run"   # a train run's folder: shipped files, a curve
    shutil.copytree(shipped_path("ppo", "MicroConveyor-v1"), src)
    first = {**json.loads((src / "metadata.json").read_text())["evaluation"], "steps": 1}
    (src / "evaluations.jsonl").write_text(json.dumps(first) + "\n")
    pol = load_policy(src)
    state0 = pol.actor.sb3_state()
    lines = []
    rep = refine(pol, RefineSettings(targets=64, rounds=2, newton_iterations=3,
                                     fit_iterations=30), log=lines.append)
    scores = [r["training_score"] for r in rep["rounds"]]
    kept = scores[rep["kept_round"]]
    assert all((kept["success_rate"], -kept["median_abs_error_m"])
               >= (s["success_rate"], -s["median_abs_error_m"]) for s in scores)
    assert rep["rounds"][1]["corrected"] > 0 and len(lines) == 4
    # the weights left in the policy are the kept round's: scoring them again gives its score
    from agents.rl.refinement.refine import _score
    targets = np.random.default_rng([0, 0x5EF1]).uniform(*pol.config.target_range, 64)
    assert _score(pol.config, targets, MeanActor(pol)) == kept
    after = pol.actor.sb3_state()
    moved = any(not np.array_equal(v.numpy(), after[k].numpy()) for k, v in state0.items())
    assert moved == (rep["kept_round"] > 0)

    out = write_refined(pol, rep, tmp_path / "refined", evaluation={"success_rate": 1.0})
    loaded = load_policy(out)   # data-only loader, hashes verified
    obs = np.random.default_rng(1).uniform(-1, 1, (8, 6)).astype(np.float32)
    assert np.array_equal(loaded.act(obs), pol.act(obs))
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["refinement"]["kept_round"] == rep["kept_round"] and "note" not in meta
    assert meta["refined_from"]["evaluation"] == pol.metadata["evaluation"]
    src, new = (zipfile.ZipFile(p / "model.zip") for p in (src, out))
    assert src.namelist() == new.namelist()
    for name in src.namelist():
        if name != "policy.pth":
            assert src.read(name) == new.read(name)
    # the written policy.pth holds the fitted actor and, unchanged, everything else (value net,
    # log std)
    from agents.rl.artefacts.sb3_files import read_weights
    old_w, new_w = (read_weights(p / "model.zip") for p in (src_folder, out))
    assert list(old_w) == list(new_w)
    for k in old_w:
        want = after[k] if k in after else old_w[k]
        assert np.array_equal(new_w[k].numpy(), want.numpy()), k
    assert any("value" in k for k in old_w)
    with pytest.raises(ValueError, match="exists and is not empty"):
        write_refined(pol, rep, out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["refined", "run"]   # no staging left
    curve = [json.loads(line) for line in (out / "evaluations.jsonl").read_text().splitlines()]
    assert curve[0] == first and curve[1]["refined"] and curve[1]["success_rate"] == 1.0
    assert curve[1]["wall_time_s"] == pol.metadata["wall_time_s"] + rep["wall_time_s"]


def test_a_later_worse_round_is_dropped(monkeypatch):
    """Round 1 scores best, round 2 worse: the weights left are round 1's fit."""
    import agents.rl.refinement.fit as fitting
    import agents.rl.refinement.refine as mod

    pol = _shipped()
    scores = iter([(0.5, 30e-6), (0.9, 10e-6), (0.7, 5e-6)])
    def fake_score(*a):
        rate, median = next(scores)
        return {"success_rate": rate, "median_abs_error_m": median}

    monkeypatch.setattr(mod, "_score", fake_score)
    after_fit, real_fit = [], fitting.fit

    def recording_fit(actor, *a):
        out = real_fit(actor, *a)
        after_fit.append({k: v.clone() for k, v in actor.net.state_dict().items()})
        return out

    monkeypatch.setattr(fitting, "fit", recording_fit)
    rep = refine(pol, RefineSettings(targets=32, rounds=2, newton_iterations=2, fit_iterations=20))
    assert rep["kept_round"] == 1 and len(after_fit) == 2
    final = pol.actor.module.state_dict()
    assert all(np.array_equal(after_fit[0][k].numpy(), final[k].numpy()) for k in final)
    assert not all(np.array_equal(after_fit[1][k].numpy(), final[k].numpy()) for k in final)


@pytest.mark.parametrize("kw", [{"targets": 0}, {"rounds": 0}, {"fit_iterations": 1.5},
                                {"step": 0.0}, {"accept_m": float("nan")}])
def test_bad_settings_are_refused(kw):
    with pytest.raises(ValueError, match="refine: "):
        RefineSettings(**kw)


def test_a_randomised_policy_is_refused():
    pol = load_policy(shipped_path("ppo_randomised", "MicroConveyor-v1"))
    with pytest.raises(ValueError, match="per-episode randomisation"):
        refine(pol, RefineSettings(targets=8, rounds=1))


def _cli(*args):
    """A command in this process (tests/cli start the console script's processes)."""
    return run_cli(*args)


def test_refine_command_writes_an_evaluated_folder_and_refuses_an_occupied_one(tmp_path):
    out = tmp_path / "r"
    src = str(shipped_path("ppo", "MicroConveyor-v1"))
    res = _cli("refine", src, "--out", str(out), "--targets", "32", "--rounds", "1",
               "--fit-iterations", "10", "--eval-targets", "10", "--json")
    assert res.returncode == 0, res.stderr
    doc = json.loads(res.stdout)
    assert doc["evaluation"]["n_targets"] == 10 and doc["refinement"]["settings"]["targets"] == 32
    assert "refine round 1/1" in res.stderr
    ev = _cli("evaluate", "--policy", str(out), "--targets", "10", "--json")
    assert ev.returncode == 0, ev.stderr
    assert json.loads(ev.stdout)["env_id"] == "MicroConveyor-v1"
    again = _cli("refine", src, "--out", str(out))
    assert again.returncode != 0 and "exists and is not empty" in again.stderr


@pytest.mark.parametrize("extra, message", [
    (["--algo", "sac"], "refines a PPO policy"),
    (["--env", "MicroConveyorGoal-v1"], "refines a PPO policy"),
    (["--env-kwargs", "action_noise:0.01"], "randomisation"),
])
def test_train_refine_refuses_before_training(tmp_path, capsys, extra, message):
    from microconveyor_env.cli import main

    out = tmp_path / "run"
    assert main(["train", "--out", str(out), "--steps", "4096", "--refine", *extra]) != 0
    assert message in capsys.readouterr().err and not out.exists()   # nothing trained


def test_train_refine_refuses_an_occupied_refined_folder(tmp_path, capsys):
    from microconveyor_env.cli import main

    (tmp_path / "run" / "refined").mkdir(parents=True)
    (tmp_path / "run" / "refined" / "x").write_text("mine")
    assert main(["train", "--out", str(tmp_path / "run"), "--steps", "4096", "--refine"]) != 0
    assert "not empty" in capsys.readouterr().err
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == ["refined"]


def test_train_refine_writes_the_refined_policy_into_the_run(tmp_path, monkeypatch, capsys):
    """One command: train, then refine the final policy into OUT/refined (tiny settings here;
    the command uses refine's defaults)."""
    import functools

    import agents.rl.refinement.settings as mod
    from microconveyor_env.cli import main

    monkeypatch.setattr(mod, "RefineSettings", functools.partial(
        mod.RefineSettings, targets=16, rounds=1, newton_iterations=1, first_iterations=1,
        fit_iterations=5))
    out = tmp_path / "run"
    assert main(["train", "--out", str(out), "--steps", "4096", "--no-progress", "--eval-freq",
                 "0", "--eval-targets", "10", "--refine", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["refined"]["out"] == str(out / "refined")
    assert doc["refined"]["refinement"]["settings"]["targets"] == 16
    assert doc["refined"]["evaluation"]["n_targets"] == 10
    refined = load_policy(out / "refined")
    assert refined.metadata["refinement"]["settings"]["rounds"] == 1
    assert refined.metadata["refined_from"]["files"] == load_policy(out).metadata["files"]
