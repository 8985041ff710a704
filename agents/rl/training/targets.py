"""A training-time target distribution for MicroConveyor (a VecEnv wrapper named in a recipe).

:class:`TargetMixture` redraws, with probability ``p``, each new episode's target uniformly
from a sub-range ``range_m`` of the env's target range; the other episodes keep the target the
env drew (uniform over its whole range). With ``p = 0.35`` and v1's 0.5-3 mm, 52 % of the
episodes go to the near targets where PPO's misses were (26 % under the env's own
distribution): the piecewise choice of which actuator sets the part down is learnt there
(docs/agents.md, "PPO on MicroConveyor-v1").

Only training sees it: the env, its reward, its target range, evaluations and shipped metadata
are unchanged (a policy trained with it is evaluated on the env's uniform targets).
"""
from __future__ import annotations

from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper, VecMonitor

from .hyperparams import number_in


class TargetMixture(VecEnvWrapper):
    """With probability ``p`` [-] a new episode's target [m] is drawn uniformly from
    ``range_m`` = [lo, hi] [m], which must lie within the env's ``target_range``; otherwise the
    env's own draw stays. The draws come from a generator seeded by :meth:`seed` (the
    training seed), apart from the env's own streams."""

    def __init__(self, venv: VecEnv, p: float = 0.35, range_m: Any = (0.5e-3, 3e-3)) -> None:
        inner = venv.venv if isinstance(venv, VecMonitor) else venv
        if isinstance(inner, VecEnvWrapper):
            raise ValueError(f"TargetMixture must be the innermost wrapper (first in "
                             f"vec_env_wrapper): {type(inner).__name__} inside it would see "
                             "each episode start before its target is redrawn")
        super().__init__(venv)
        p = number_in("TargetMixture: p", p, 0.0, 1.0, what="a probability", closed_hi=True)
        try:
            lo, hi = (float(v) for v in range_m)
        except (TypeError, ValueError):
            raise ValueError(f"TargetMixture: range_m must be [lo, hi] in m, got "
                             f"{range_m!r}") from None
        env_lo, env_hi = venv.get_attr("config")[0].target_range
        if not env_lo <= lo < hi <= env_hi:
            raise ValueError(f"TargetMixture: range_m [{lo:g}, {hi:g}] m must be an interval "
                             f"within the env's target range [{env_lo:g}, {env_hi:g}] m")
        if not hasattr(venv.unwrapped, "set_targets"):
            raise ValueError("TargetMixture needs the batched conveyor env (set_targets)")
        self.p, self.lo, self.hi = float(p), lo, hi
        self.rng = np.random.default_rng()

    def seed(self, seed: int | None = None) -> Any:
        # apart from the env's streams (seeded seed + i by the same SeedSequence algorithm)
        self.rng = np.random.default_rng(None if seed is None else [int(seed), 0x7A46])
        return self.venv.seed(seed)

    def _redraw(self, obs: Any, new: np.ndarray) -> Any:
        pick = new[self.rng.random(new.size) < self.p]
        if not pick.size:
            return obs
        base: Any = self.venv.unwrapped  # MicroConveyorSB3VecEnv (checked in __init__)
        fresh = base.set_targets(pick, self.rng.uniform(self.lo, self.hi, pick.size))
        obs = np.array(obs, copy=True)
        obs[pick] = fresh[pick]
        return obs

    def reset(self) -> Any:
        return self._redraw(self.venv.reset(), np.arange(self.num_envs))

    def step_wait(self) -> Any:
        obs, rew, dones, infos = self.venv.step_wait()
        if np.any(dones):
            obs = self._redraw(obs, np.flatnonzero(dones))
        return obs, rew, dones, infos
