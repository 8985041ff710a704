"""Recipe options beyond SB3's keyword arguments: the training-only log-error shaping
(agents/rl/training/shaping.py), the training-time target mixture (agents/rl/training/targets.py), bad recipe keys
refused by name, raw observations (norm_obs false); the run-phase keys' timing is in
test_run_phases.py."""
import numpy as np
import pytest
from stable_baselines3.common.vec_env import VecMonitor

from agents.rl.training import hyperparams, wrappers
from agents.rl.training.shaping import LogErrorShaping
from microconveyor_env.envs.core.sb3 import MicroConveyorSB3VecEnv

N = 16


def _plain_and_shaped(seed: int):
    plain = VecMonitor(MicroConveyorSB3VecEnv(N, env_id="MicroConveyor-v1", num_threads=1))
    shaped = LogErrorShaping(VecMonitor(MicroConveyorSB3VecEnv(N, env_id="MicroConveyor-v1",
                                                               num_threads=1)),
                             weight=3.0, scale_m=20e-6)
    plain.seed(seed)
    shaped.seed(seed)
    return plain, shaped


def test_shaping_telescopes_to_the_log_of_the_final_error():
    """Over every episode the added terms sum to Psi(final error) - Psi(start error), with a
    detached part at Psi(horizon); the env's own reward is unchanged underneath."""
    plain, shaped = _plain_and_shaped(3)
    obs_p, obs_s = plain.reset(), shaped.reset()
    np.testing.assert_array_equal(obs_p, obs_s)
    start = shaped.potential(obs_s[:, 0] * 10e-3)
    added = np.zeros(N)
    rng = np.random.default_rng(0)
    ended = 0
    outcomes = set()
    for _ in range(40):
        act = rng.uniform(-1, 1, (N, 3)).astype(np.float32)
        obs_p, r_p, d_p, inf_p = plain.step(act)
        obs_s, r_s, d_s, inf_s = shaped.step(act)
        np.testing.assert_array_equal(obs_p, obs_s)
        np.testing.assert_array_equal(d_p, d_s)
        added += r_s.astype(float) - r_p.astype(float)
        for i in np.flatnonzero(d_s):
            err = inf_s[i]["position_error_m"]
            outcomes.add(inf_s[i]["outcome"])
            final = (shaped.potential(shaped.horizon) if inf_s[i]["outcome"] == "detached"
                     else shaped.potential(err))
            # float32 rewards: a few ulps of the env's reward per step (a Python float: pytest
            # 9.2 refuses a NumPy float32 tolerance)
            tol = 1e-3 * max(1.0, abs(float(r_p[i])))
            assert added[i] == pytest.approx(final - start[i], abs=tol)
            added[i] = 0.0
            start[i] = shaped.potential(obs_s[i, 0] * 10e-3)
            ended += 1
    assert ended > N and {"rest", "detached"} <= outcomes


def test_potential_is_log_of_relative_error_and_saturates():
    env = LogErrorShaping(VecMonitor(MicroConveyorSB3VecEnv(2, env_id="MicroConveyor-v1",
                                                            num_threads=1)),
                          weight=2.0, scale_m=10e-6)
    assert env.horizon == pytest.approx(2 * (10e-3 + 0.15e-3))  # v1's progress_horizon
    e = np.array([0.0, 10e-6, 90e-6, 1.0])
    np.testing.assert_allclose(env.potential(e), [0.0, -2 * np.log(2), -2 * np.log(10),
                                                  -2 * np.log1p(env.horizon / 10e-6)])
    # halving 100 um pays as much as halving 2 mm (up to the bend at the scale)
    gain = lambda a, b: float(env.potential(b) - env.potential(a))  # noqa: E731
    assert gain(100e-6, 50e-6) == pytest.approx(gain(2e-3, 1e-3), rel=0.15)


@pytest.mark.parametrize("spec, message", [
    ("os.system", "is not one this package builds"),
    ({"agents.rl.training.shaping.LogErrorShaping": {"weight": -1}}, "weight must be a positive"),
    ({"agents.rl.training.shaping.LogErrorShaping": {"scale_m": float("inf")}}, "scale_m must be a pos"),
    ({"agents.rl.training.shaping.LogErrorShaping": {"weight": True}}, "weight must be a positive"),
    ({"agents.rl.training.shaping.LogErrorShaping": {"wieght": 1}}, "unexpected keyword"),
    ([1], "expected a name"),
])
def test_a_recipe_names_only_known_wrappers(spec, message):
    venv = VecMonitor(MicroConveyorSB3VecEnv(2, env_id="MicroConveyor-v1", num_threads=1))
    with pytest.raises(ValueError, match=message):
        wrappers.wrap(venv, spec)


def test_the_wrapper_key_is_the_trainers_not_ppos():
    hp = hyperparams.load(env_id="MicroConveyor-v1")
    hp["vec_env_wrapper"] = [{"agents.rl.training.shaping.LogErrorShaping": {"weight": 1.0}}]
    assert "vec_env_wrapper" not in hyperparams.algo_kwargs(hp)
    venv = VecMonitor(MicroConveyorSB3VecEnv(2, env_id="MicroConveyor-v1", num_threads=1))
    wrapped = wrappers.wrap(venv, hp["vec_env_wrapper"])
    assert isinstance(wrapped, LogErrorShaping) and wrapped.weight == 1.0
    assert wrappers.wrap(venv, None) is venv


def _targets_seen(env, resets=1, steps=60):
    """The targets [m] of every episode the env starts (observation 5 is target / 10 mm)."""
    seen = [env.reset()[:, 5] * 10e-3]
    rng = np.random.default_rng(1)
    for _ in range(steps):
        obs, _, dones, _ = env.step(rng.uniform(-1, 1, (env.num_envs, 3)).astype(np.float32))
        seen.append(obs[dones, 5] * 10e-3)
    return np.concatenate(seen)


def test_target_mixture_draws_the_share_it_is_given_and_leaves_the_rest_to_the_env():
    from agents.rl.training.targets import TargetMixture

    def mixed(p, seed=5):
        env = TargetMixture(VecMonitor(MicroConveyorSB3VecEnv(64, env_id="MicroConveyor-v1",
                                                              num_threads=1)),
                            p=p, range_m=[1e-3, 2e-3])
        env.seed(seed)
        return _targets_seen(env)

    every = mixed(1.0)
    assert every.size > 500 and every.min() >= 1e-3 and every.max() <= 2e-3
    some = mixed(0.5)
    inside = np.mean((some >= 1e-3) & (some <= 2e-3))
    expect = 0.5 + 0.5 * 1e-3 / 9.5e-3          # the env's own draw lands there too
    sd = np.sqrt(expect * (1 - expect) / some.size)
    assert abs(inside - expect) < 4 * sd, (inside, expect, some.size)
    assert some.min() >= 0.5e-3 and some.max() <= 10e-3 and np.mean(some > 2e-3) > 0.3
    np.testing.assert_array_equal(some, mixed(0.5))          # seeded: the same run twice
    assert not np.array_equal(some, mixed(0.5, seed=6))


@pytest.mark.parametrize("kwargs, message", [
    ({"p": 0.0}, "p must be a probability"),
    ({"p": 1.5}, "p must be a probability"),
    ({"p": float("nan")}, "p must be a probability"),
    ({"p": True}, "p must be a probability"),
    ({"range_m": [3e-3, 1e-3]}, "must be an interval within"),
    ({"range_m": [0.1e-3, 3e-3]}, "must be an interval within"),
    ({"range_m": "near"}, "range_m must be"),
])
def test_target_mixture_refuses_what_it_cannot_draw(kwargs, message):
    venv = VecMonitor(MicroConveyorSB3VecEnv(2, env_id="MicroConveyor-v1", num_threads=1))
    with pytest.raises(ValueError, match=message):
        wrappers.wrap(venv, {"agents.rl.training.targets.TargetMixture": kwargs})


def test_target_mixture_must_be_the_innermost_wrapper():
    """A wrapper inside it (the shaping) would see each episode's start before the redraw."""
    venv = VecMonitor(MicroConveyorSB3VecEnv(2, env_id="MicroConveyor-v1", num_threads=1))
    mix = {"agents.rl.training.targets.TargetMixture": {"p": 0.5}}
    shaped = "agents.rl.training.shaping.LogErrorShaping"
    with pytest.raises(ValueError, match="innermost"):
        wrappers.wrap(venv, [shaped, mix])
    both = wrappers.wrap(venv, [mix, shaped])
    assert type(both).__name__ == "LogErrorShaping"


def _tiny_ppo(out, steps, **overrides):
    from agents.rl.training.settings import TrainSettings
    from agents.rl.training.train import train

    tiny = {"n_envs": 8, "n_steps": 16, "batch_size": 64, "n_epochs": 2,
            "policy_kwargs": {"net_arch": {"pi": [16], "vf": [16]}, "log_std_init": -3.0},
            **overrides}
    return train(out, TrainSettings(steps=steps, seed=0, env_id="MicroConveyor-v1", overrides=tiny,
                                    checkpoint_freq=10**6, eval_freq=0, eval_targets=0,
                                    progress_bar=False, tensorboard=False))


def test_obs_stats_freeze_needs_normalised_observations(tmp_path):
    assert hyperparams.normalize_kwargs({"normalize": True}) == {}   # VecNormalize's defaults
    assert hyperparams.normalize_kwargs({"normalize": False}) is None
    _tiny_ppo(tmp_path / "t", 64, normalize=True, freeze_obs_stats_at=0.5)
    assert (tmp_path / "t" / "normalization.json").is_file()
    for raw in ({"normalize": None}, {"normalize": {"norm_obs": False, "norm_reward": True}}):
        with pytest.raises(ValueError, match="needs normalised observations"):
            _tiny_ppo(tmp_path / "r", 64, freeze_obs_stats_at=0.5, **raw)


@pytest.mark.parametrize("overrides, message", [
    ({"exploration_restart": {"at": 1.5, "log_std": -2.0}}, "at must be a number in"),
    ({"exploration_restart": {"at": 0.5}}, "must be {at: FRACTION"),
    ({"exploration_restart": {"at": 0.5, "log_std": "low"}}, "log_std must be a number"),
    ({"vec_env_wrapper": "builtins.eval"}, "is not one this package builds"),
    ({"freeze_obs_stats_at": 1.0}, "freeze_obs_stats_at must be a number in"),
    ({"freeze_obs_stats_at": "late"}, "freeze_obs_stats_at must be a number in"),
    ({"freeze_obs_stats_at": float("nan")}, "freeze_obs_stats_at must be a number in"),
    ({"exploration_restart": {"at": True, "log_std": -2.0}}, "at must be a number in"),
    ({"exploration_shift": {"at": 0.5}}, "must be {at: FRACTION, by: VALUE}"),
    ({"exploration_shift": {"at": 0.0, "by": -1.0}}, "exploration_shift: at must be"),
    ({"exploration_shift": {"at": 0.5, "by": float("inf")}}, "exploration_shift: by must be"),
    # gSDE's log std is per latent feature: the keys would set or shift another quantity
    ({"use_sde": True, "exploration_restart": None, "exploration_shift": {"at": 0.5, "by": -1.0}},
     "exploration_shift .*use_sde"),
    ({"use_sde": True, "exploration_restart": {"at": 0.5, "log_std": -2.0}},
     "exploration_restart .*use_sde"),
])
def test_bad_recipe_keys_are_refused_by_name(tmp_path, overrides, message):
    with pytest.raises(ValueError, match=message):
        _tiny_ppo(tmp_path, 64, **overrides)


def test_raw_observations_train_save_resume_and_load(tmp_path):
    """normalize with norm_obs false (rewards still normalised): SB3 keeps no observation
    statistics, the file records the identity, and the loaded policy reads raw observations."""
    import json

    from agents.rl.artefacts.policy_files import load_policy

    raw = {"normalize": {"norm_obs": False, "norm_reward": True}}
    _tiny_ppo(tmp_path, 256, **raw)
    stats = json.loads((tmp_path / "normalization.json").read_text())
    assert stats["norm_obs"] is False and stats["obs_rms"]["var"] == [1.0] * 6
    pol = load_policy(tmp_path)
    assert pol.normalizer is None
    from agents.rl.training.settings import TrainSettings
    from agents.rl.training.train import train

    meta = train(tmp_path, TrainSettings(steps=512, seed=0, env_id="MicroConveyor-v1", resume=True,
                                         overrides={"n_envs": 8, "n_steps": 16, "batch_size": 64,
                                         "n_epochs": 2,
                            "policy_kwargs": {"net_arch": {"pi": [16], "vf": [16]},
                                              "log_std_init": -3.0}, **raw}, checkpoint_freq=10**6, eval_freq=0, eval_targets=0, progress_bar=False, tensorboard=False))
    assert meta["steps"] == 512


def test_shaped_training_records_the_envs_own_returns(tmp_path):
    """The wrapper sits outside the monitor: a shaped run trains and its recorded metadata
    names the shaping (part of the config hash) while evaluations use v1's reward."""
    meta = _tiny_ppo(tmp_path, 256, vec_env_wrapper=[
        {"agents.rl.training.shaping.LogErrorShaping": {"weight": 5.0, "scale_m": 20e-6}}])
    assert meta["hyperparams"]["vec_env_wrapper"][0]["agents.rl.training.shaping.LogErrorShaping"] == {
        "weight": 5.0, "scale_m": 20e-6}


def test_train_quick_uses_the_quick_recipe_and_its_scene(tmp_path, capsys):
    """`train --quick` (PPO on v1): configs/ppo_quick.yml, v1's nearest targets (0.5-1.4 mm),
    evaluations printed as it goes; the policy is evaluated in that scene, and refused on v1's
    full range unless asked."""
    import json

    from agents.rl.evaluation.evaluate import load_policy
    from microconveyor_env.cli import main
    from microconveyor_env.envs import env_config

    quick = hyperparams.load(None, "MicroConveyor-v1", "ppo_quick")  # the packaged file
    assert quick["env_kwargs"]["target_range"] == [0.5e-3, 1.4e-3]
    assert quick["policy_kwargs"]["log_std_init"] == -2.0
    out = tmp_path / "q"
    assert main(["train", "--quick", "--steps", "8192", "--out", str(out), "--no-progress",
                 "--json"]) in (0, None)
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["env_kwargs"]["target_range"] == [0.5e-3, 1.4e-3]
    assert meta["hyperparams"]["policy_kwargs"]["log_std_init"] == -2.0
    assert meta["evaluation"]["n_targets"] == 50
    assert "eval: step" in capsys.readouterr().err
    pol = load_policy(out)
    assert pol.config.target_range == (0.5e-3, 1.4e-3)
    with pytest.raises(ValueError, match="target_range"):
        load_policy(out, env_config("MicroConveyor-v1"))
