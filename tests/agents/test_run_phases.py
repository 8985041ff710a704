"""PPO's run-phase recipe keys (agents/rl/training/phases.py): the exploration restart and shift, and
frozen observation statistics; when each fires in a run and across a resume."""
import pytest

from microconveyor_env.envs.core.sb3 import MicroConveyorSB3VecEnv


def _check_resume_cases(arm, hp, flag, cases, changed_log_std):
    """``arm`` (a phases function) on a fresh PPO (log std -3) for each case (saved flag (None:
    never saved), saved progress, progress now, expected flag, whether the change is made now)."""
    import torch

    from agents.rl.training.algos import algo_class

    for saved, progress, done_now, pending, made in cases:
        model = algo_class("ppo")("MlpPolicy", "Pendulum-v1", device="cpu",
                                  policy_kwargs={"log_std_init": -3.0})
        if saved is not None:
            setattr(model, flag, saved)
        model._current_progress_remaining = 1.0 - progress
        said: list[str] = []
        model.phase_log = said.append
        arm(model, hp, "ppo", done_now)
        assert getattr(model, flag) is pending, (saved, progress, done_now)
        assert bool(torch.all(model.policy.log_std == (changed_log_std if made else -3.0))), \
            (saved, progress, done_now)
        assert len(said) == int(made), (saved, progress, done_now, said)  # said when made


def test_exploration_restart_fires_once_and_restarts_the_schedule():
    """exploration_restart {at, log_std}: the first rollout past the fraction ``at`` explores
    with exactly that log std (set after the update before it), no other rollout does, and the
    learning rate decays towards 0 in each phase from its initial value."""
    import torch
    from stable_baselines3.common.callbacks import BaseCallback

    from agents.rl.training.algos import algo_class
    from agents.rl.training.hyperparams import linear_schedule
    from agents.rl.training.phases import exploration_restart

    seen = []

    class Record(BaseCallback):
        def _on_rollout_start(self) -> None:
            seen.append((self.model.num_timesteps, self.model.policy.log_std.detach().clone(),
                         self.model.lr_schedule(self.model._current_progress_remaining)))

        def _on_step(self) -> bool:
            return True

    env = MicroConveyorSB3VecEnv(8, env_id="MicroConveyor-v1", num_threads=1)
    model = algo_class("ppo")("MlpPolicy", env, n_steps=16, batch_size=64, n_epochs=2, seed=0,
                              learning_rate=linear_schedule(1e-3), device="cpu",
                              policy_kwargs={"net_arch": [16], "log_std_init": -3.0})
    exploration_restart(model, {"exploration_restart": {"at": 0.5, "log_std": -0.7}}, "ppo", 0.0)
    model.learn(1024, callback=Record())
    steps = [s for s, _, _ in seen]
    exact = [s for s, ls, _ in seen if torch.all(ls == -0.7)]
    assert exact == [min(s for s in steps if s >= 512)]  # once, at the first rollout past 50 %
    lrs = {s: lr for s, _, lr in seen}
    assert lrs[0] == pytest.approx(1e-3)
    assert lrs[384] == pytest.approx(1e-3 * (1 - 384 / 512))   # phase 1 decays towards 0
    assert lrs[512] == pytest.approx(1e-3)                      # and restarts at the fraction
    assert lrs[896] == pytest.approx(1e-3 * (1024 - 896) / 512)


def test_exploration_restart_on_resume_fires_once_by_what_the_checkpoint_saved():
    """A resume arms the restart from the run's progress under its budgets (``done_now``) and
    whether the checkpoint's model had fired it (saved with the model; for older checkpoints,
    the progress they saved): a fired restart is not repeated, one the checkpoint had not yet
    made is made at once (the checkpoint came from the rollout that crossed the point, or the
    wall budget ran ahead of the steps), and a larger budget that puts the run back before the
    point arms it again."""

    from agents.rl.training.algos import algo_class
    from agents.rl.training.phases import exploration_restart

    hp = {"exploration_restart": {"at": 0.5, "log_std": -2.0}}
    cases = [  # saved pending (None: never saved), saved progress, done now -> pending, filled
        (None, 0.0, 0.0, True, False),      # a new model
        (None, 0.499, 0.499, True, False),  # an older checkpoint before the point
        (None, 0.7, 0.7, False, False),     # an older checkpoint after it fired
        (True, 0.45, 0.55, False, True),    # crossed but not fired: fire now
        (True, 0.3, 0.7, False, True),      # wall budget ahead of the steps: fire now
        (False, 0.9, 0.9, False, False),    # fired: not again
        (False, 0.9, 0.3, True, False),     # a larger budget: before the point again
    ]
    _check_resume_cases(exploration_restart, hp, "restart_pending", cases, -2.0)
    excluded = algo_class("ppo")("MlpPolicy", "Pendulum-v1")._excluded_save_params()
    assert "restart_at" in excluded and "restart_pending" not in excluded


def test_exploration_shift_moves_the_log_std_once_and_leaves_the_schedule():
    """exploration_shift {at, by}: the first rollout past ``at`` explores with the log std the
    update before it left, shifted by ``by``; the learning-rate schedule is the recipe's
    (only the restart restarts it); with both keys the shift applies to the restarted noise."""
    import torch
    from stable_baselines3.common.callbacks import BaseCallback

    from agents.rl.training.algos import algo_class
    from agents.rl.training.hyperparams import linear_schedule
    from agents.rl.training.phases import exploration_restart, exploration_shift

    class Record(BaseCallback):
        def __init__(self):
            super().__init__()
            self.seen = []

        def _on_rollout_start(self) -> None:
            m = self.model
            self.seen.append((m.num_timesteps, m.policy.log_std.detach().clone(),
                              m.lr_schedule(m._current_progress_remaining)))

        def _on_step(self) -> bool:
            return True

    said: list[str] = []

    def run(hp):
        env = MicroConveyorSB3VecEnv(8, env_id="MicroConveyor-v1", num_threads=1)
        model = algo_class("ppo")("MlpPolicy", env, n_steps=16, batch_size=64, n_epochs=2,
                                  seed=0, learning_rate=linear_schedule(1e-3), device="cpu",
                                  policy_kwargs={"net_arch": [16], "log_std_init": -3.0})
        said.clear()
        model.phase_log = said.append
        exploration_restart(model, hp, "ppo", 0.0)
        exploration_shift(model, hp, "ppo", 0.0)
        rec = Record()
        model.learn(1024, callback=rec)
        return rec.seen

    plain, shifted = run({}), run({"exploration_shift": {"at": 0.5, "by": -1.5}})
    assert [s for s, _, _ in plain] == [s for s, _, _ in shifted]
    for (s, ls0, lr0), (_, ls1, lr1) in zip(plain, shifted, strict=True):
        assert lr1 == pytest.approx(lr0) and lr1 == pytest.approx(1e-3 * (1 - s / 1024))
        if s < 512:            # the same run before the point
            assert torch.equal(ls0, ls1), s
    first = min(s for s, _, _ in shifted if s >= 512)
    # at the first rollout past the point the log std is 1.5 lower than the update left it
    before = {s: ls for s, ls, _ in plain}[first]
    after = {s: ls for s, ls, _ in shifted}[first]
    torch.testing.assert_close(after, before - 1.5)
    # with the restart at the same point: the restarted value, shifted
    both = run({"exploration_restart": {"at": 0.5, "log_std": -0.7},
                "exploration_shift": {"at": 0.75, "by": -1.0}})
    at_shift = min(s for s, _, _ in both if s >= 768)
    ls = {s: v for s, v, _ in both}
    assert torch.all(ls[min(s for s in ls if s >= 512)] == -0.7)
    torch.testing.assert_close(ls[at_shift], ls[at_shift - 128] - 1.0, atol=0.05, rtol=0)
    # each change is reported once, at the step it was made, with its value
    restart_at = min(s for s in ls if s >= 512)
    assert said == [
        f"exploration restart at step {restart_at}: log std set to -0.7 in every action "
        "component; the learning rate decays again from its initial value",
        f"exploration shift at step {at_shift}: log std shifted by -1, now ["
        + ", ".join(f"{v:.2f}" for v in ls[at_shift].tolist()) + "]"]


def test_exploration_shift_on_resume_is_made_once():
    """The shift arms on resume as the restart does: made at once when the checkpoint crossed
    the point without making it, never twice, again after a larger budget."""

    from agents.rl.training.algos import algo_class
    from agents.rl.training.phases import exploration_shift

    hp = {"exploration_shift": {"at": 0.5, "by": -1.0}}
    _check_resume_cases(exploration_shift, hp, "shift_pending", [
        (None, 0.0, 0.0, True, False), (None, 0.7, 0.7, False, False),
        (True, 0.45, 0.55, False, True), (False, 0.9, 0.9, False, False),
        (False, 0.9, 0.3, True, False)], -4.0)
    excluded = algo_class("ppo")("MlpPolicy", "Pendulum-v1")._excluded_save_params()
    assert "shift_by" in excluded and "shift_pending" not in excluded


def test_whether_the_restart_fired_survives_a_checkpoint(tmp_path):
    from agents.rl.training.algos import algo_class
    from agents.rl.artefacts.sb3_files import safe_load

    for fired in (False, True):
        model = algo_class("ppo")("MlpPolicy", "Pendulum-v1", device="cpu")
        model.restart_pending = model.shift_pending = not fired
        model.save(tmp_path / "m.zip")
        back = safe_load(tmp_path / "m.zip", "ppo", model.observation_space, model.action_space,
                         cls=algo_class("ppo"))
        assert back.restart_pending is (not fired) and back.shift_pending is (not fired)


def test_obs_stats_freeze_at_the_fraction_and_stay_frozen_across_a_resume(tmp_path):
    """freeze_obs_stats_at: the observation statistics move until the first update past the
    fraction and never after, also in a run killed and resumed later (the resumed run freezes
    them at once); the reward statistics keep moving. Without the key they keep moving."""
    import json

    from agents.rl.training.settings import TrainSettings

    from agents.rl.training.train import train

    tiny = {"n_envs": 8, "n_steps": 16, "batch_size": 64, "n_epochs": 2,
            "policy_kwargs": {"net_arch": {"pi": [16], "vf": [16]}, "log_std_init": -1.0}}

    class Stop(Exception):
        pass

    def stop(res):
        raise Stop

    said: list[str] = []

    def run(out, **extra):
        said.clear()
        kw = dict(seed=0, env_id="MicroConveyor-v1", overrides={**tiny, **extra},
                  checkpoint_freq=128, eval_freq=512, eval_targets=2, progress_bar=False,
                  tensorboard=False)
        # killed at step 512 by its evaluation (before that step's checkpoint): the two
        # newest checkpoints, 256 and 384, stay
        with pytest.raises(Stop):
            train(out, TrainSettings(steps=2048, **kw), on_eval=stop, log=said.append)
        gens = sorted((out / "checkpoints").iterdir())
        assert [g.name for g in gens] == ["gen-000000000256", "gen-000000000384"]
        stats = [json.loads((g / "normalization.json").read_text()) for g in gens]
        kw.pop("eval_freq")
        train(out, TrainSettings(steps=2048, resume=True, eval_freq=0, **kw), log=said.append)
        return stats, json.loads((out / "normalization.json").read_text())

    (frozen_gens, frozen_end) = run(tmp_path / "f", freeze_obs_stats_at=0.1)
    # 0.1 of 2,048 steps: frozen after the 2nd rollout (256 steps, progress 0.125 >= 0.1)
    assert frozen_end["obs_rms"] == frozen_gens[0]["obs_rms"] == frozen_gens[1]["obs_rms"]
    assert frozen_end["ret_rms"] != frozen_gens[1]["ret_rms"]
    # said when: in the run, and at once in the resumed one (from the 384-step checkpoint)
    assert [m for m in said if "statistics frozen" in m] == [
        "observation statistics frozen at step 256", "observation statistics frozen at step 384"]
    (live_gens, live_end) = run(tmp_path / "l")
    assert not [m for m in said if "frozen" in m]
    assert live_end["obs_rms"]["mean"] != live_gens[1]["obs_rms"]["mean"]
    assert live_gens[0]["obs_rms"]["mean"] != live_gens[1]["obs_rms"]["mean"]


@pytest.mark.parametrize("key", [{"exploration_restart": {"at": 0.5, "log_std": -2.0}},
                                 {"exploration_shift": {"at": 0.5, "by": -1.0}}])
def test_exploration_restart_and_shift_are_ppo_settings(tmp_path, key):
    from agents.rl.training.settings import TrainSettings
    from agents.rl.training.train import train

    with pytest.raises(ValueError, match="PPO setting"):
        train(tmp_path, TrainSettings(steps=64, algo="sac", env_id="MicroConveyor-v1",
                                      overrides={**key, "n_envs": 2}, eval_freq=0,
                                      progress_bar=False, tensorboard=False))
