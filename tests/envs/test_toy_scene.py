"""A new scene needs only the core (docs/architecture.md, "A new scene"): a deliberately small
one, a point that each action pushes along a line, built from ``envs/core`` alone (a config, a
task, a compiled step, a part container, a saved state and a registration), registered under a
test-only id, passes Gymnasium's checker, seeds reproducibly, saves and restores its state, and
its batched env runs the single envs' rollouts bit for bit."""
import ast
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, NamedTuple

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from numba import njit, prange

from microconveyor_env import env_ids
from microconveyor_env.envs.core.config import SceneConfig
from microconveyor_env.envs.core.part_state import SavedState, check_fired, check_scene, within
from microconveyor_env.envs.core.parts import PartsBase
from microconveyor_env.envs.core.reward import is_success, reward, reward_constants
from microconveyor_env.envs.core.single import SingleEnv
from microconveyor_env.envs.core.vector import BatchedEnv
from microconveyor_env.envs.core.versions import scene_of
from microconveyor_env.physics import dynamics_kernel as kernel  # the outcome codes

TOY_ID = "ToyScene-v0"   # test-only


# ---------------------------------------------------------------- the scene (about a page)
@dataclass(frozen=True)
class ToyConfig(SceneConfig):
    """A point on a line; each firing pushes it by up to ``reach`` [m] and takes ``dt`` [s]."""

    reach: float = 1e-3
    dt: float = 0.01
    max_firings: int = 8
    target_range: tuple = (1e-3, 4e-3)
    tolerance: float = 1e-4
    progress_scale: float | None = None
    progress_horizon: float | None = None
    time_cost: float = 1.0
    success_bonus: float = 10.0
    detach_penalty: float = 10.0
    max_time: float = 1.0
    stop_at_target: bool = True
    num_threads: int | None = 1

    def __post_init__(self) -> None:
        self._check_ranges({"reach": (1e-6, 1.0, False, "m"), "tolerance": (1e-9, 1.0, False, "m")})
        self._check_horizon(self.target_range[1], "target_range[1] = ")

    episode_limit = property(lambda self: (self.max_firings, "max_firings"))
    randomised = property(lambda self: False)


class Task(NamedTuple):   # read by name in compiled code
    reach: float
    dt: float
    max_firings: int
    max_time: float
    progress_scale: float
    time_cost: float
    success_bonus: float
    detach_penalty: float
    tolerance: float
    progress_horizon: float
    stop_at_target: bool


class Parts(NamedTuple):
    x: np.ndarray
    t: np.ndarray
    fired: np.ndarray
    target: np.ndarray


class Outputs(NamedTuple):
    reward: np.ndarray
    outcome: np.ndarray
    success: np.ndarray
    push: np.ndarray
    obs: np.ndarray


@njit
def _observe(i, parts, TC, obs):
    obs[i, 0] = min(max((parts.x[i] - parts.target[i]) / TC.reach, -10.0), 10.0)
    obs[i, 1] = parts.fired[i] / TC.max_firings


@njit
def _advance(i, actions, active, parts, c, AC, TC, out):
    out.reward[i], out.outcome[i], out.success[i], out.push[i] = 0.0, kernel.MOVING, False, 0.0
    if active[i]:
        x0, t0, target = parts.x[i], parts.t[i], parts.target[i]
        x, t, k = x0 + min(max(actions[i, 0], -1.0), 1.0) * TC.reach, t0 + TC.dt, parts.fired[i] + 1
        code = kernel.REST if abs(x - target) <= TC.tolerance or k == TC.max_firings else kernel.MOVING
        out.reward[i] = reward(code, abs(x0 - target), abs(x - target), t0, t, TC)
        out.success[i] = is_success(code, abs(x - target), TC)
        out.outcome[i], out.push[i] = code, x - x0
        parts.x[i], parts.t[i], parts.fired[i] = x, t, k
    _observe(i, parts, TC, out.obs)
    return 0   # no part leaves a contact table


@njit
def step_serial(actions, active, parts, c, AC, TC, out):
    beyond = 0
    for i in range(len(parts.x)):
        beyond += _advance(i, actions, active, parts, c, AC, TC, out)
    return beyond


@njit(parallel=True)
def step_parallel(actions, active, parts, c, AC, TC, out):
    beyond = 0
    for i in prange(len(parts.x)):
        beyond += _advance(i, actions, active, parts, c, AC, TC, out)
    return beyond


@njit
def observe_all(parts, TC, obs):
    for i in range(len(parts.x)):
        _observe(i, parts, TC, obs)


@dataclass(frozen=True)
class ToyState(SavedState):
    REQUIRED: ClassVar[tuple[str, ...]] = ("position_m", "time_s", "fired", "target_m")
    position_m: float
    time_s: float
    fired: int
    target_m: float
    env_id: str | None = None
    scene: dict[str, Any] | None = field(default=None, hash=False, repr=False)


class ToyParts(PartsBase):
    components = ("push",)
    step_info = (("push_m", "push", 0.0),)

    def __init__(self, config: ToyConfig, n: int, num_threads: int | None = 1) -> None:
        self.config, self.n, z = config, n, np.zeros
        self.consts = self.action = z(0)
        self.task = Task(config.reach, config.dt, config.max_firings, **reward_constants(config))
        self.parts = Parts(z(n), z(n), z(n, np.int64), z(n))
        self.out = Outputs(z(n), z(n, np.int64), z(n, np.bool_), z(n), z((n, 2), np.float32))
        self.obs, self.obs_dim, self.obs_bound = self.out.obs, 2, 10.0
        self._start_randomisation(config, n)
        self._start(n, num_threads)

    def compiled(self) -> tuple:
        return step_serial, step_parallel, observe_all, (self.parts, self.task, self.out.obs)

    def check_targets(self, given: Any, batched: bool) -> list:
        return [within("target", t, 0.0, 0.1, "m", 1.0, "the rail") for t in
                np.broadcast_to(np.asarray(given, dtype=float), (self.n if batched else 1,))]

    def check_state(self, state: Any) -> ToyState:
        s = state if isinstance(state, ToyState) else ToyState.from_dict(state)
        if s.scene is not None:
            check_scene(s, self.config)
        check_fired(s.fired, self.config.max_firings)
        return s

    def reset_part(self, i: int, rng: np.random.Generator, target: Any = None,
                   state: ToyState | None = None) -> None:
        drawn = rng.uniform(*self.config.target_range)
        p = self.parts
        p.x[i], p.t[i], p.fired[i], p.target[i] = 0.0, 0.0, 0, drawn if target is None else target
        if state is not None:
            p.x[i], p.t[i], p.fired[i], p.target[i] = (state.position_m, state.time_s,
                                                       state.fired, state.target_m)

    def get_state(self, i: int, env_id: str | None = None) -> ToyState:
        p = self.parts
        return ToyState(float(p.x[i]), float(p.t[i]), int(p.fired[i]), float(p.target[i]),
                        env_id, scene_of(self.config))

    def errors(self) -> dict[str, np.ndarray]:
        return {"position_error_m": self.parts.x - self.parts.target}


class ToyEnv(SingleEnv):
    config_class, conveyor_class = ToyConfig, ToyParts


class ToyVectorEnv(BatchedEnv):
    config_class, conveyor_class = ToyConfig, ToyParts


REGISTRATION = env_ids.Registration(TOY_ID, "toy", f"{__name__}:ToyConfig", f"{__name__}:ToyEnv",
                                    f"{__name__}:ToyVectorEnv", TOY_ID, False, 8,
                                    env_ids.NOT_SCENE)


# ---------------------------------------------------------------- what it gets from the core
@pytest.fixture(scope="module")
def registered():
    env_ids.REGISTRY[TOY_ID] = REGISTRATION
    env_ids.register_all()
    yield TOY_ID
    del env_ids.REGISTRY[TOY_ID]
    gym.registry.pop(TOY_ID)


def _rollout(env, seed, actions):
    obs, info = env.reset(seed=seed)
    rows = [(obs.tolist(), info)]
    for a in actions:
        obs, rew, term, trunc, info = env.step(a)
        rows.append((obs.tolist(), rew, term, trunc, info))
        if term or trunc:
            break
    return rows


ACTIONS = np.array([[0.9], [0.7], [-0.2], [0.4], [0.1], [0.05], [0.3], [0.2]], np.float32)


def test_the_toy_scene_passes_gymnasiums_checker(registered):
    env = gym.make(registered)
    check_env(env.unwrapped, skip_render_check=True)
    assert env.spec.max_episode_steps == 8


def test_the_toy_scene_seeds_reproducibly(registered):
    a, b = gym.make(registered), gym.make(registered)
    assert _rollout(a, 3, ACTIONS) == _rollout(b, 3, ACTIONS)
    assert _rollout(a, 3, ACTIONS)[0][0] != _rollout(a, 4, ACTIONS)[0][0]


def test_the_toy_scene_saves_and_restores_its_state(registered):
    env = gym.make(registered)
    env.reset(seed=5)
    env.step(ACTIONS[0])
    saved = env.unwrapped.get_state()
    def rows(e):
        return [(o.tolist(), *more) for o, *more in (e.step(a) for a in ACTIONS[1:3])]

    rest = rows(env)
    again = gym.make(registered)
    again.reset(options={"state": ToyState.from_dict(saved.to_dict())})
    assert rows(again) == rest
    other = ToyEnv(config=ToyConfig(reach=2e-3))   # another scene refuses it
    with pytest.raises(ValueError, match="another scene"):
        other.reset(options={"state": saved})


def test_the_toy_scenes_batched_env_runs_the_single_envs_rollouts(registered):
    n, seed = 3, 11
    venv = gym.make_vec(registered, n, vectorization_mode="vector_entry_point")
    obs, _ = venv.reset(seed=seed)
    singles = [gym.make(registered) for _ in range(n)]
    single_obs = [e.reset(seed=seed + i)[0] for i, e in enumerate(singles)]
    np.testing.assert_array_equal(obs, np.stack(single_obs))
    for k in range(3):
        acts = np.roll(ACTIONS[:n], k, axis=0)
        obs, rew, term, trunc, infos = venv.step(acts)
        for i, e in enumerate(singles):
            o, r, t, u, info = e.step(acts[i])
            assert (obs[i].tolist(), rew[i], term[i], trunc[i]) == (o.tolist(), r, t, u)
            assert infos["push_m"][i] == info["push_m"]
            assert infos["position_error_m"][i] == info["position_error_m"]


def test_the_toy_scene_is_built_from_the_core_alone():
    tree = ast.parse(Path(__file__).read_text())
    modules = [n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module]
    scenes = [m for m in modules if m.startswith("microconveyor_env.envs.")
              and not m.startswith("microconveyor_env.envs.core")]
    assert not scenes
