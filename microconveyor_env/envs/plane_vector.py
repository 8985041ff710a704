"""Batched MicroConveyor2D-v0: N parts on the plane stepped together by one compiled call (numba
prange), bit-identical to N single envs."""
from __future__ import annotations

import numbers
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ..physics import dynamics_kernel as kernel
from . import plane_task
from .common import check_render_mode
from .plane_config import PlaneEnvConfig
from .plane_state import PlaneConveyor, check_plane_actions
from .plane_step import ACTION_DIM

MAX_ENVS = 1_000_000


class MicroConveyor2DVectorEnv(VectorEnv):
    """``num_envs`` independent copies of :class:`~.plane_env.MicroConveyor2DEnv`.

    Same spaces, rewards and info keys as the single env (batched; ``position_error_m`` is an
    ``(num_envs, 2)`` array). Sub-env ``i`` reset with ``seed`` uses ``seed + i``, as
    ``SyncVectorEnv`` does, so both give identical rollouts, bit for bit. ``autoreset_mode``:
    ``NEXT_STEP`` (default) or ``SAME_STEP`` (``final_obs`` / ``final_info``). ``num_threads`` (a
    config field): 1 a serial loop, k > 1 numba's parallel loop with k threads, None (default)
    chosen by measuring. ``reset(options={"target": (x, y)})``: one target [m] for every
    sub-env, or an ``(num_envs, 2)`` array.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4,
                "autoreset_mode": AutoresetMode.NEXT_STEP}
    conveyor: PlaneConveyor
    _started: bool

    def __init__(self, num_envs: int = 1, render_mode: str | None = None,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
                 config: PlaneEnvConfig | None = None, max_episode_steps: int | None = None,
                 **kwargs: Any) -> None:
        if (isinstance(num_envs, bool) or not isinstance(num_envs, numbers.Integral)
                or not 1 <= num_envs <= MAX_ENVS):
            raise ValueError(f"num_envs = {num_envs!r} is invalid: must be an integer in "
                             f"[1, {MAX_ENVS}]")
        check_render_mode(render_mode, self.metadata["render_modes"])
        self.autoreset_mode: AutoresetMode = AutoresetMode(autoreset_mode)
        if self.autoreset_mode == AutoresetMode.DISABLED:
            raise ValueError("autoreset_mode DISABLED is not supported; use NEXT_STEP or SAME_STEP")
        self.metadata = {**self.metadata, "autoreset_mode": self.autoreset_mode}
        if config is not None and kwargs:
            raise ValueError("give either config= or keyword overrides, not both")
        if config is not None and not isinstance(config, PlaneEnvConfig):
            raise ValueError(f"config must be a PlaneEnvConfig, got {type(config).__name__}")
        self.config: PlaneEnvConfig = config or PlaneEnvConfig.from_yaml(**kwargs)
        if max_episode_steps is not None and max_episode_steps < self.config.max_firings:
            raise ValueError(f"max_episode_steps={max_episode_steps} is below max_firings = "
                             f"{self.config.max_firings}: episodes would be cut short")
        self.num_envs = n = int(num_envs)
        self.render_mode = render_mode
        self.conveyor = PlaneConveyor(self.config, n, self.config.num_threads)
        self.single_action_space = spaces.Box(-1.0, 1.0, (ACTION_DIM,), np.float32)
        self.single_observation_space = spaces.Box(-plane_task.OBS_BOUND, plane_task.OBS_BOUND,
                                                   (plane_task.OBS_DIM,), np.float32)
        self.action_space = batch_space(self.single_action_space, n)
        self.observation_space = batch_space(self.single_observation_space, n)
        self.done: np.ndarray = np.zeros(n, dtype=bool)
        self.rngs: list[np.random.Generator] = [seeding.np_random(None)[0] for _ in range(n)]
        self._started = False

    # the parts' state (arrays, one element per sub-env; written in place)
    x = property(lambda self: self.conveyor.parts.x, doc="x [m] per sub-env")
    y = property(lambda self: self.conveyor.parts.y, doc="y [m] per sub-env")
    t = property(lambda self: self.conveyor.parts.t, doc="simulated times [s]")
    fired = property(lambda self: self.conveyor.parts.fired, doc="firings so far (int64)")
    target = property(lambda self: np.stack([self.conveyor.parts.tx, self.conveyor.parts.ty], 1),
                      doc="targets (num_envs, 2) [m] (a copy)")

    def _reset_one(self, i: int, target: tuple[float, float] | None = None) -> None:
        self.conveyor.reset_part(i, self.rngs[i], target)
        self.done[i] = False

    def reset(self, *, seed: int | list | None = None,
              options: dict | None = None) -> tuple[np.ndarray, dict]:
        targets = self.conveyor.check_targets(options, batched=True)  # before anything changes
        if seed is not None:
            seeds = ([int(seed) + i for i in range(self.num_envs)]
                     if isinstance(seed, (int, np.integer)) else [int(s) for s in seed])
            if len(seeds) != self.num_envs:
                raise ValueError(f"{len(seeds)} seeds for {self.num_envs} envs")
            self.rngs = [seeding.np_random(s)[0] for s in seeds]
        for i in range(self.num_envs):
            self._reset_one(i, None if targets is None else targets[i])
        self._started = True
        return self.conveyor.observe().copy(), self._reset_infos()

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        if not self._started:
            raise RuntimeError("call reset() before step()")
        a = check_plane_actions(actions, self.num_envs, self.conveyor.action_input)
        resetting = self.done.copy() if self.autoreset_mode == AutoresetMode.NEXT_STEP else \
            np.zeros(self.num_envs, dtype=bool)
        for i in np.flatnonzero(resetting):
            self._reset_one(int(i))
        active = ~resetting
        out = self.conveyor.step(a, active)
        codes = out.outcome.copy()
        terminated = active & ((codes == kernel.REST) | (codes == kernel.DETACHED))
        truncated = active & ((codes == kernel.MAX_TIME) | (codes == kernel.TOO_MANY_EVENTS))
        rew = np.where(active, out.reward, 0.0)
        self.done = terminated | truncated
        obs = out.obs.copy()
        infos = self._infos(np.array(kernel.OUTCOMES, dtype=object)[codes], active & out.success)
        for key, col in (("actuator", out.actuator), ("frequency_hz", out.frequency),
                         ("stroke_m", out.stroke), ("delay_s", out.delay)):
            infos[key], infos["_" + key] = col.copy(), active.copy()
        if self.autoreset_mode == AutoresetMode.SAME_STEP and self.done.any():
            infos = self._same_step_reset(obs, infos)
            obs = self.conveyor.observe().copy()
        return obs, rew, terminated, truncated, infos

    def _same_step_reset(self, obs: np.ndarray, infos: dict) -> dict:
        """Reset finished sub-envs now; their last observation and info go to ``final_obs`` /
        ``final_info`` (as SyncVectorEnv)."""
        finished = self.done.copy()
        idx = np.flatnonzero(finished)
        final_obs = np.full(self.num_envs, None, dtype=object)
        final_info: dict[str, Any] = {}
        for key, val in infos.items():
            if not key.startswith("_"):
                mask = np.zeros(self.num_envs, bool)
                mask[idx] = infos["_" + key][idx]
                blank = (np.full(self.num_envs, None, dtype=object) if val.dtype == object
                         else np.zeros_like(val))
                shaped = mask.reshape((-1,) + (1,) * (val.ndim - 1))
                final_info[key] = np.where(shaped, val, blank)
                final_info["_" + key] = mask
        for i in idx:
            final_obs[i] = obs[i].copy()
            self._reset_one(int(i))
        reset = self._reset_infos()
        infos = dict(infos)
        for key, val in reset.items():
            if not key.startswith("_"):
                infos[key] = infos[key].copy()
                infos[key][idx] = val[idx]
        for key in ("actuator", "frequency_hz", "stroke_m", "delay_s"):
            infos[key] = np.where(finished, -1 if key == "actuator" else 0.0, infos[key])
            infos["_" + key] = infos["_" + key] & ~finished
        infos["final_obs"], infos["_final_obs"] = final_obs, finished
        infos["final_info"], infos["_final_info"] = final_info, finished.copy()
        return infos

    def _reset_infos(self) -> dict:
        return self._infos(np.full(self.num_envs, "moving", dtype=object),
                           np.zeros(self.num_envs, dtype=bool))

    def _infos(self, outcome: np.ndarray, success: np.ndarray) -> dict:
        p = self.conveyor.parts
        err = np.stack([p.x - p.tx, p.y - p.ty], 1)
        infos = {"is_success": success.copy(), "position_error_m": err,
                 "distance_m": np.hypot(err[:, 0], err[:, 1]), "outcome": outcome,
                 "sim_time_s": p.t.copy()}
        ok = np.ones(self.num_envs, dtype=bool)
        for key in list(infos):
            infos["_" + key] = ok.copy()
        return infos

    def render(self) -> tuple | None:
        """``rgb_array``: one frame per sub-env (the part and target now, no path)."""
        if self.render_mode != "rgb_array":
            return None
        from .plane_render import render_plane_frame

        p = self.conveyor.parts
        return tuple(render_plane_frame(self.config, [(p.x[i], p.y[i])], (p.tx[i], p.ty[i]),
                                        int(p.fired[i]), None, p.t[i])
                     for i in range(self.num_envs))
