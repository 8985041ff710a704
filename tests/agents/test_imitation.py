"""DAgger: on MicroPositioner-v0 the expert's model is the env's own step (its predicted rest is
where the nominal env puts the part, bit for bit) and its choice brings the part closer; on
MicroConveyor-v1 the seeded expert keeps the seed policy's firings and re-aims its last one so
that the env puts the part on the target; a short run on either writes a policy folder that
loads as data and acts; each env id's recipe comes from configs/dagger.yml."""
from __future__ import annotations

import numpy as np
import pytest

from microconveyor_env.envs.positioner.config import PositionerConfig
from microconveyor_env.envs.positioner.env import MicroPositionerEnv
from microconveyor_env.envs.positioner.part_state import PositionerState

pytest.importorskip("stable_baselines3")

from agents.imitation.dagger import DaggerSettings, dagger, recipe  # noqa: E402
from agents.mpc.experts import BatchExpert, SeededExpert  # noqa: E402


def test_expert_predicts_the_nominal_env_exactly_and_gets_closer() -> None:
    cfg = PositionerConfig.from_yaml(None)
    expert = BatchExpert(cfg, frequencies=9, strokes=3)
    x = np.array([-0.15e-3, 2.1e-3, 7.43e-3])
    target = np.array([3.0e-3, 1.2e-3, 7.5e-3])
    acts, ok = expert.act(x, np.zeros(3), target)
    assert ok.all() and acts.shape == (3, 3) and acts.dtype == np.float32
    env = MicroPositionerEnv()
    for i in range(3):
        env.reset(options={"state": PositionerState(float(x[i]), 0.0, 0, float(target[i]))})
        env.step(acts[i])
        assert abs(env.x - target[i]) < abs(x[i] - target[i])
    # the prediction behind the choice is the env's own step on the nominal model
    c = expert._container(len(x))
    c.parts.x[:], c.parts.t[:], c.parts.target[:], c.parts.fired[:] = x, 0.0, target, 0
    c.step(acts.astype(np.float64))
    env.reset(options={"state": PositionerState(float(x[1]), 0.0, 0, float(target[1]))})
    env.step(acts[1])
    assert env.x == c.parts.x[1]


def test_expert_refuses_when_nothing_gets_closer() -> None:
    cfg = PositionerConfig.from_yaml(None)
    acts, ok = BatchExpert(cfg, frequencies=5, strokes=2).act(
        np.array([5.0e-3]), np.zeros(1), np.array([5.0e-3]))
    assert not ok[0]


@pytest.mark.parametrize("bad, word", [({"rounds": 0}, "rounds"), ({"episodes": 1.5}, "episodes"),
                                       ({"net_arch": ()}, "net_arch"),
                                       ({"learning_rate": 2.0}, "learning_rate"),
                                       ({"fit": "sgd"}, "fit"), ({"fit_iterations": 0},
                                                                 "fit_iterations"),
                                       ({"newton_iterations": 0}, "newton_iterations"),
                                       ({"accept_m": -1e-6}, "accept_m"),
                                       ({"seed_policy": ""}, "seed_policy"),
                                       ({"keep": "first"}, "keep")])
def test_settings_refused(bad: dict, word: str) -> None:
    with pytest.raises(ValueError, match=word):
        DaggerSettings(**bad)


def test_dagger_refuses_what_it_has_no_expert_for() -> None:
    # the plane has an expert (tests/agents/test_plane_dagger.py), seeded by no policy
    with pytest.raises(ValueError, match="not seeded"):
        DaggerSettings(env_id="MicroConveyor2D-v1", env_kwargs={}, seed_policy="ppo").config()
    with pytest.raises(ValueError, match="not seeded"):
        DaggerSettings(seed_policy="ppo").config()   # the positioner's expert has no seed
    with pytest.raises(ValueError, match="another scene"):   # a seed of another scene
        from agents.imitation.dagger import make_expert
        s = recipe("MicroConveyor-v1", env_kwargs={"tolerance": 1e-5}, seed_policy="ppo_refined")
        make_expert(s, s.config())
    with pytest.raises(ValueError, match="Dict observations"):
        DaggerSettings(env_id="MicroConveyorGoal-v1", env_kwargs={})
    for env_id in ("MicroConveyor-v0", "MicroConveyor2D-v0"):
        with pytest.raises(ValueError, match="no recipe"):
            recipe(env_id)


def test_recipes_are_the_settings_of_configs_dagger_yml() -> None:
    assert recipe("MicroPositioner-v0") == DaggerSettings()   # the dataclass holds its recipe
    v1 = recipe("MicroConveyor-v1", seed=3)   # from the simulator alone: no seed policy
    assert (v1.env_kwargs, v1.seed_policy, v1.fit, v1.net_arch, v1.rounds, v1.seed) == (
        {}, None, "lbfgs", (64, 64, 64), 8, 3)
    seeded = recipe("MicroConveyor-v1", seed_policy="ppo_refined")   # the recipe's seeded entry
    assert (seeded.seed_policy, seeded.net_arch, seeded.rounds, seeded.fit_iterations) == (
        "ppo_refined", (64, 64), 5, 1000)
    with pytest.raises(ValueError, match="fit"):
        recipe("MicroConveyor-v1", fit="sgd")


def test_short_dagger_run_writes_a_policy_that_loads_as_data(tmp_path) -> None:
    from agents.rl.evaluation.evaluate import fixed_targets, load_policy, rollout

    s = DaggerSettings(rounds=2, episodes=4, epochs=2, frequencies=5, strokes=2, margin=2)
    meta = dagger(tmp_path / "p", s, progress=lambda line: None)
    assert meta["trained_by"] == "dagger" and len(meta["rounds"]) == 2
    assert meta["rounds"][0]["acting"] == "expert" and meta["steps"] > 0
    pol = load_policy(tmp_path / "p")
    assert pol.env_id == "MicroPositioner-v0"
    cfg = pol.config
    res = rollout(pol, fixed_targets(cfg, 3, 0), cfg)
    assert len(res["error_m"]) == 3


@pytest.mark.parametrize("heavier, detached", [(0.0, 6), (0.3, 0)])
def test_expert_keeps_away_from_what_detaches_a_heavier_part(heavier: float,
                                                            detached: int) -> None:
    """Towards far targets the nearest-landing firings sit at the edge of detachment: searched
    on the full model without margins (no grid margin, no slack) they all detach a part 30 %
    heavier; checked on that heavier part, none does."""
    cfg = PositionerConfig.from_yaml(None)
    x = np.array([-0.15e-3, -0.1e-3, -0.05e-3, 2.1e-3, 4.45e-3, 0.7e-3])
    target = np.full(6, 9.9e-3)
    expert = BatchExpert(cfg, frequencies=21, strokes=3, margin=0, slack=0.0, heavier=heavier,
                         search="model")   # the map's trust keeps its own distance
    acts, ok = expert.act(x, np.zeros(6), target)
    assert ok.all()
    heavy = MicroPositionerEnv(mass_factor_range=(1.3, 1.3))
    outcomes = []
    for i in range(6):
        heavy.reset(options={"state": PositionerState(float(x[i]), 0.0, 0, float(target[i]))})
        outcomes.append(heavy.step(acts[i])[4]["outcome"])
    assert outcomes.count("detached") == detached


def _v1_states(n_targets: int = 6) -> tuple:
    """The states the shipped v1 policy visits towards a few targets, before each firing: the
    observations and the states as arrays (x, v, t, fired, target)."""
    from microconveyor_env.envs import MicroConveyorVectorEnv, env_config
    from agents.rl.artefacts.shipped import shipped_path
    from agents.rl.evaluation.evaluate import load_policy

    cfg = env_config("MicroConveyor-v1")
    pol = load_policy(shipped_path("ppo_refined", "MicroConveyor-v1"))
    venv = MicroConveyorVectorEnv(n_targets, config=cfg)   # a finished sub-env is masked
    obs, _ = venv.reset(seed=0, options={"target": np.linspace(0.7e-3, 9.6e-3, n_targets)})
    O, S = [], []
    done = np.zeros(n_targets, bool)
    while not done.all():
        p = venv.conveyor.parts
        O.append(obs[~done].copy())
        S.append(np.stack([np.array(getattr(p, k), float)[~done]
                           for k in ("x", "v", "t", "fired", "target")], 1))
        obs, _, term, trunc, _ = venv.step(pol.act(obs))
        done |= term | trunc
    return cfg, pol, np.concatenate(O), np.concatenate(S)


def test_seeded_expert_lands_the_last_firing_and_keeps_the_others() -> None:
    """Where the seed's firing is its last, the re-aimed one puts the part, in the env itself,
    within accept_m of the target (and at most as far as the seed's own); elsewhere the expert
    fires what the seed fires."""
    from types import SimpleNamespace

    from microconveyor_env.envs import MicroConveyorEnv, PartState

    cfg, pol, obs, S = _v1_states()
    expert = SeededExpert(cfg, pol.act, accept_m=2e-6)
    parts = SimpleNamespace(x=S[:, 0], v=S[:, 1], t=S[:, 2], fired=S[:, 3].astype(np.int64),
                            target=S[:, 4])
    acts, fixed = expert.act(obs, parts)
    seed = np.clip(pol.act(obs), -1, 1)
    assert fixed.sum() >= 3 and (~fixed).sum() >= 3
    assert np.array_equal(acts[~fixed], seed[~fixed].astype(np.float32))
    env = MicroConveyorEnv(**{"preset": "conveyor", "target_range": (0.5e-3, 10e-3)})
    for i in np.flatnonzero(fixed):
        x, v, t, k, target = S[i]
        state = PartState(float(x), float(v), float(t), int(k), float(target))
        errors = []
        for a in (acts[i], seed[i]):
            env.reset(options={"state": state})
            _, _, term, _, info = env.step(a)
            assert term and info["outcome"] == "rest"
            errors.append(abs(info["position_error_m"]))
        assert errors[0] <= 2e-6 and errors[0] <= errors[1]


def test_seeded_expert_predicts_the_env_bit_for_bit() -> None:
    """The model's rest is the env's: the same firing then the no-ops, from the same state."""
    from microconveyor_env.envs import MicroConveyorEnv, PartState
    from microconveyor_env.physics import dynamics_kernel as kernel
    from agents.rl.refinement.corrections import NOOP

    cfg, pol, obs, S = _v1_states(3)
    expert = SeededExpert(cfg, pol.act)
    a = np.clip(pol.act(obs), -1, 1).astype(np.float64)
    x_end, code, _ = expert.rest_after(tuple(S[:, j] if j != 3 else S[:, 3].astype(np.int64)
                                             for j in range(5)), a)
    env = MicroConveyorEnv(**{"preset": "conveyor", "target_range": (0.5e-3, 10e-3)})
    assert (code == kernel.REST).sum() >= 5
    for i in np.flatnonzero(code == kernel.REST):
        x, v, t, k, target = S[i]
        env.reset(options={"state": PartState(float(x), float(v), float(t), int(k),
                                              float(target))})
        _, _, term, trunc, info = env.step(a[i])
        while not (term or trunc):
            _, _, term, trunc, info = env.step(NOOP)
        assert info["outcome"] == "rest" and env.conveyor.parts.x[0] == x_end[i]


def test_seeded_expert_leaves_finished_and_unasked_rows_alone() -> None:
    """Rows not asked for (``rows``), and parts that have fired every actuator, get the seed's
    action as it is: never fired on the model (a part past the last actuator has none)."""
    from types import SimpleNamespace

    cfg, pol, obs, S = _v1_states(3)
    expert = SeededExpert(cfg, pol.act)
    parts = SimpleNamespace(x=S[:, 0], v=S[:, 1], t=S[:, 2], fired=S[:, 3].astype(np.int64),
                            target=S[:, 4])
    every, fixed_all = expert.act(obs, parts)
    assert fixed_all.any()
    seed = np.clip(pol.act(obs), -1, 1).astype(np.float32)
    none, fixed_none = expert.act(obs, parts, rows=np.zeros(len(S), bool))
    assert not fixed_none.any() and np.array_equal(none, seed)
    done = SimpleNamespace(**{**vars(parts), "fired": np.full(len(S), cfg.n_actuators)})
    acts, fixed = expert.act(obs, done)
    assert not fixed.any() and np.array_equal(acts, seed)


def test_seeded_expert_refuses_another_scene() -> None:
    with pytest.raises(ValueError, match="conveyor"):
        SeededExpert(PositionerConfig.from_yaml(None), lambda obs: obs)


def test_short_v1_dagger_run_writes_a_policy_that_loads_as_data(tmp_path) -> None:
    from agents.rl.evaluation.evaluate import fixed_targets, load_policy, rollout

    s = recipe("MicroConveyor-v1", rounds=2, episodes=4, fit_iterations=3, seed=2,
               seed_policy="ppo_refined")
    meta = dagger(tmp_path / "p", s, progress=lambda line: None)
    assert meta["trained_by"] == "dagger" and meta["env_id"] == "MicroConveyor-v1"
    assert meta["expert"]["seed_policy"] == "ppo_refined" and meta["env_kwargs"] == {}
    assert meta["rounds"][0]["success_rate"] >= 0.75   # the seeded expert acting
    # the expert acting in round 0 re-aims the seed's last firings of its own episodes
    assert meta["rounds"][0]["labels_corrected"] > 0
    pol = load_policy(tmp_path / "p")
    res = rollout(pol, fixed_targets(pol.config, 3, 0), pol.config)
    assert len(res["error_m"]) == 3


@pytest.mark.parametrize("argv, words", [
    (["--env", "MicroPositioner-v0", "--seed-policy", "ppo"], "not seeded by a policy"),
    (["--seed-policy", "no-such-policy"], "no policy at"),
    (["--env-kwargs", "tolerance:1e-5", "--seed-policy", "ppo_refined"], "another scene"),
    (["--env", "MicroConveyor-v0"], "no recipe")])
def test_imitate_refuses_in_one_line(argv: list, words: str, tmp_path, capsys) -> None:
    from microconveyor_env.cli import main

    status = main(["imitate", "--out", str(tmp_path / "p"), "--rounds", "1", "--episodes", "2",
                   *argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and words in err[0] and "Traceback" not in err[0]
    assert not (tmp_path / "p").exists()


def test_keep_best_puts_the_fit_whose_episodes_went_best_into_the_policy() -> None:
    """keep="best": fit r is scored by round r + 1's episodes and the last fit by one more round;
    the best (share within the tolerance, then the median) is the one the student holds."""
    import dataclasses

    import torch

    from agents.imitation.dagger import _keep_best
    from agents.imitation.student import Student
    from microconveyor_env.envs.core.versions import vector_class

    s = recipe("MicroConveyor-v1", rounds=3, episodes=4, keep="best")
    cfg = s.config()
    venv = vector_class(s.env_id)(s.episodes, config=dataclasses.replace(cfg, num_threads=1))
    student = Student(s, cfg)
    student.set_stats(np.zeros((2, venv.conveyor.obs_dim), np.float32))
    fits = [[p.detach().clone() + k for p in student.params] for k in range(3)]

    def score(success: float, median: float) -> dict:
        return {"success_rate": success, "median_abs_error_m": median, "episodes": 4}

    # fit 0 scored perfect by round 1's episodes: nothing the last fit plays can beat it
    rounds = [score(1.0, 0.0), score(1.0, 0.0), score(0.5, 1e-4)]
    kept = _keep_best(s, venv, student, fits, rounds)
    assert kept["round"] == 0 and kept["success_rate"] == 1.0
    assert all(torch.equal(p, v) for p, v in zip(student.params, fits[0], strict=True))
    # fit 1 scored perfect, fit 0 less so: fit 1 is kept
    rounds = [score(1.0, 0.0), score(0.9, 1e-5), score(1.0, 0.0)]
    kept = _keep_best(s, venv, student, fits, rounds)
    assert kept["round"] == 1
    assert all(torch.equal(p, v) for p, v in zip(student.params, fits[1], strict=True))
