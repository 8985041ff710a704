"""DAgger on MicroPositioner-v0: the expert's model is the env's own step (its predicted rest is
where the nominal env puts the part, bit for bit), its choice brings the part closer, and a
short DAgger run writes a policy folder that loads as data and acts."""
from __future__ import annotations

import numpy as np
import pytest

from microconveyor_env.envs.positioner.config import PositionerConfig
from microconveyor_env.envs.positioner.env import MicroPositionerEnv
from microconveyor_env.envs.positioner.part_state import PositionerState

pytest.importorskip("stable_baselines3")

from agents.imitation.dagger import DaggerSettings, dagger  # noqa: E402
from agents.mpc.positioner import BatchExpert  # noqa: E402


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
                                       ({"learning_rate": 2.0}, "learning_rate")])
def test_settings_refused(bad: dict, word: str) -> None:
    with pytest.raises(ValueError, match=word):
        DaggerSettings(**bad)


def test_dagger_refuses_a_conveyor() -> None:
    with pytest.raises(ValueError, match="not a positioner"):
        DaggerSettings(env_id="MicroConveyor-v1", env_kwargs={}).config()


def test_short_dagger_run_writes_a_policy_that_loads_as_data(tmp_path) -> None:
    from agents.rl.evaluation.evaluate import fixed_targets, load_policy, rollout

    s = DaggerSettings(rounds=2, episodes=4, epochs=2, frequencies=5, strokes=2)
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
    """Towards far targets the nearest-landing firings sit at the edge of detachment: without
    margins (no grid margin, no slack) they all detach a part 30 % heavier; checked on that
    heavier part, none does."""
    cfg = PositionerConfig.from_yaml(None)
    x = np.array([-0.15e-3, -0.1e-3, -0.05e-3, 2.1e-3, 4.45e-3, 0.7e-3])
    target = np.full(6, 9.9e-3)
    expert = BatchExpert(cfg, frequencies=21, strokes=3, margin=0, slack=0.0, heavier=heavier)
    acts, ok = expert.act(x, np.zeros(6), target)
    assert ok.all()
    heavy = MicroPositionerEnv(mass_factor_range=(1.3, 1.3))
    outcomes = []
    for i in range(6):
        heavy.reset(options={"state": PositionerState(float(x[i]), 0.0, 0, float(target[i]))})
        outcomes.append(heavy.step(acts[i])[4]["outcome"])
    assert outcomes.count("detached") == detached
