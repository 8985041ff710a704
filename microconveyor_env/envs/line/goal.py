"""MicroConveyorGoal-v1: the conveyor with a goal-conditioned (Dict) interface.

The same env as :class:`~.env.MicroConveyorEnv` (same physics, actions and episode end, bit
for bit), with the observation split as goal-conditioned suites (Gymnasium-Robotics, panda-gym)
split it, so that SB3's ``HerReplayBuffer`` can relabel goals:

| key | shape | content (clipped to ±10) |
|---|---|---|
| ``observation`` | (5,) | position x / 10 mm, velocity / 0.5 m/s, distance to the next actuator / spacing (0 once all fired), elapsed time / max_time, fraction of actuators fired |
| ``achieved_goal`` | (1,) | position x / 10 mm |
| ``desired_goal`` | (1,) | target / 10 mm |

Nothing in ``observation`` depends on the goal, so a relabelled transition is a valid one.
:meth:`MicroConveyorGoalEnv.compute_reward` evaluates the env's own reward
(:func:`.task.reward`) for any goal from the transition's ``info`` (``x_before_m``,
``t_before_s``, ``sim_time_s``, ``outcome``) and the observed goals, and ``step`` returns exactly
``compute_reward(obs["achieved_goal"], obs["desired_goal"], info)`` (what SB3's checker and HER
require). It equals the base env's reward up to the float32 rounding of the observed positions
(6e-8 relative: < 2e-5 in reward at 10 mm with the default 50 µm progress scale). A relabelled
goal changes the reward of a transition, not when the episode ended (``stop_at_target`` ended it
for the original target). The reward depends on the transition (progress from the previous
position), so SB3's ``HerReplayBuffer`` needs ``copy_info_dict=True``; without it
``compute_reward`` gets empty infos and says so.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces

from ...physics import dynamics_kernel as kernel
from ..rail.step import LENGTH_SCALE, OBS_BOUND
from . import task
from .env import MicroConveyorEnv

OBS_DIM = 5
INFO_KEYS = ("outcome", "x_before_m", "t_before_s", "sim_time_s")  # what compute_reward reads
_CODES = {name: i for i, name in enumerate(kernel.OUTCOMES)}


class MicroConveyorGoalEnv(MicroConveyorEnv):
    """:class:`MicroConveyorEnv` with a Dict observation (``observation``, ``achieved_goal``,
    ``desired_goal``; module docstring) and a vectorised ``compute_reward``. Arguments and
    everything else as the base env; ``info`` also holds ``x_before_m`` [m] and
    ``t_before_s`` [s], the part's position and time before the step.

    SB3's env checker calls ``compute_reward`` on the env it is given, and the wrappers
    ``gym.make`` puts around this env (``TimeLimit``, ``OrderEnforcing``, the passive checker) do
    not pass attribute look-ups through in Gymnasium 1.x: ``check_env(gym.make(
    "MicroConveyorGoal-v1"))`` fails with "'TimeLimit' object has no attribute
    'compute_reward'". Check the env inside the wrappers::

        import gymnasium as gym
        import microconveyor_env  # registers MicroConveyorGoal-v1
        from stable_baselines3.common.env_checker import check_env

        check_env(gym.make("MicroConveyorGoal-v1").unwrapped)

    Training needs nothing of the kind: SB3's ``HerReplayBuffer`` reaches ``compute_reward``
    through the vectorised env, which looks inside the wrappers.
    """

    def __init__(self, render_mode: str | None = None, config: Any = None, **kwargs: Any) -> None:
        super().__init__(render_mode=render_mode, config=config, **kwargs)
        if self.config.observe_history:
            raise ValueError(f"MicroConveyorGoal-v1 does not take observe_history (got "
                             f"{self.config.observe_history}): its remembered rows hold the "
                             "target, so a relabelled goal would not be a valid observation; "
                             "use MicroConveyor-v1")
        b = OBS_BOUND
        goal = spaces.Box(-b, b, (1,), np.float32)
        self.observation_space = spaces.Dict({
            "observation": spaces.Box(-b, b, (OBS_DIM,), np.float32),
            "achieved_goal": goal, "desired_goal": goal})
        self._tc = task.constants(self.config)

    def reset(self, *, seed: int | None = None,  # type: ignore[override]  # Dict observation
              options: dict[str, Any] | None = None) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        obs, info = super().reset(seed=seed, options=options)
        return self._goal_obs(obs), info

    def step(self, action: Any  # type: ignore[override]  # Dict observation
             ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        x0, t0 = self.x, self.t
        flat, _, terminated, truncated, info = super().step(action)
        info["x_before_m"], info["t_before_s"] = x0, t0
        obs = self._goal_obs(flat)
        reward = self.compute_reward(obs["achieved_goal"], obs["desired_goal"], info)
        return obs, reward, terminated, truncated, info

    def compute_reward(self, achieved_goal: Any, desired_goal: Any,
                       info: Mapping[str, Any] | Sequence[Mapping[str, Any]]) -> Any:
        """The env's reward of the transition(s) described by ``info`` had the target been
        ``desired_goal`` (in units of 10 mm, as observed); ``achieved_goal`` is the position
        after the step (it is also in ``info``'s transition; used for the new position). One
        transition (``info`` a dict): a float; a batch (``info`` a sequence of dicts, goals of
        shape (B, 1)): an array (B,)."""
        single = isinstance(info, Mapping)
        infos: list[Mapping[str, Any]] = [info] if isinstance(info, Mapping) else list(info)
        if any(k not in inf for inf in infos for k in INFO_KEYS):
            raise ValueError("MicroConveyorGoal-v1's reward depends on the transition (progress "
                             f"from the previous position): compute_reward needs info with "
                             f"{', '.join(INFO_KEYS)}. With SB3's HerReplayBuffer pass "
                             "replay_buffer_kwargs=dict(copy_info_dict=True)")
        ach = np.asarray(achieved_goal, dtype=float).reshape(len(infos), -1)[:, 0]
        des = np.asarray(desired_goal, dtype=float).reshape(len(infos), -1)[:, 0]
        out = np.empty(len(infos))
        for i, inf in enumerate(infos):
            out[i] = task.reward(_CODES[inf["outcome"]], float(inf["x_before_m"]),
                                 float(ach[i]) * LENGTH_SCALE, float(inf["t_before_s"]),
                                 float(inf["sim_time_s"]), float(des[i]) * LENGTH_SCALE,
                                 self._tc)
        return float(out[0]) if single else out

    def _goal_obs(self, flat: np.ndarray) -> dict[str, np.ndarray]:
        """The Dict observation from the base env's compiled one (``flat``: error, velocity,
        next actuator, time, fraction fired, target): the goal-free entries 1-4 are reused, the
        position and target are taken exactly (not error + target, which would round)."""
        b = OBS_BOUND
        x = np.float32(min(max(self.x / LENGTH_SCALE, -b), b))
        target = np.float32(min(max(self.target / LENGTH_SCALE, -b), b))
        return {"observation": np.concatenate(([x], flat[1:5])).astype(np.float32),
                "achieved_goal": np.array([x], np.float32),
                "desired_goal": np.array([target], np.float32)}


def goal_observations(flat: np.ndarray) -> dict[str, np.ndarray]:
    """The Dict observations of a batch of base-env observations ``flat`` (N, 6) (what a policy
    trained on the goal env needs when it acts in the batched Box env): the position is error
    + target, exact up to float32 rounding (< 1e-6 of 10 mm) while neither is clipped."""
    flat = np.asarray(flat, dtype=np.float32).reshape(-1, task.OBS_DIM)
    b = OBS_BOUND
    x = np.clip(flat[:, :1] + flat[:, 5:6], -b, b)
    return {"observation": np.concatenate((x, flat[:, 1:5]), axis=1),
            "achieved_goal": x, "desired_goal": flat[:, 5:6].copy()}
