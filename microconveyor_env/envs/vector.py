"""Batched MicroConveyor-v0: N parts stepped together by one compiled call (numba prange)."""
from __future__ import annotations

import numbers
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ..physics import dynamics_kernel as kernel
from . import actions as act, task
from .common import OwnsConveyor, check_render_mode, check_target, conveyor_field, spec_id
from .config import EnvConfig
from .part_state import PartState
from .state import Conveyor

MAX_ENVS = 1_000_000  # parts in one batch (each costs ~1 kB of state)


class MicroConveyorVectorEnv(OwnsConveyor, VectorEnv):
    """``num_envs`` independent copies of :class:`~microconveyor_env.envs.MicroConveyorEnv`.

    Same spaces, rewards and info keys as the single env (batched). Sub-env ``i`` reset with
    ``seed`` uses ``seed + i``, as ``SyncVectorEnv`` does, so both give identical rollouts.
    ``autoreset_mode``: ``NEXT_STEP`` (default, the gymnasium default: the step after a finished
    episode resets that sub-env, ignoring its action, with reward 0) or ``SAME_STEP`` (reset at
    once; the last observation and info are in ``info["final_obs"]`` / ``info["final_info"]``).
    Threads: ``num_threads`` (an EnvConfig field, also a ``make_vec`` keyword): 1 runs a serial
    loop, k > 1 numba's parallel loop with k threads, ``None`` (default) picks between the two by
    measuring them as it runs (:mod:`.threads`). Results are bit-identical in every case.
    ``max_episode_steps`` (``make_vec`` passes the spec's): checked to be >= ``n_actuators``.
    ``reset(options={"state": s})``: every sub-env starts from the part state ``s`` (a list:
    one per sub-env); see the single env and :mod:`.part_state`.
    Per-episode randomisation (``action_noise``, ``friction_factor_range``, ``mass_factor_range``;
    :mod:`.randomisation`): each part has its own row of constants and draws from streams derived
    from its own generator, so sub-env ``i`` seeded ``seed + i`` draws what the single env seeded
    ``seed + i`` draws; ``friction_factor`` / ``mass_factor`` (arrays) hold this episode's factors.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4,
                "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, render_mode: str | None = None,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
                 config: EnvConfig | None = None, max_episode_steps: int | None = None,
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
        if config is not None and not isinstance(config, EnvConfig):
            raise ValueError(f"config must be an EnvConfig, got {type(config).__name__}")
        self.config: EnvConfig = config or EnvConfig.from_yaml(**kwargs)
        # make_vec passes the spec's step limit; episodes end by themselves after n_actuators
        # firings, so a lower limit (which the single env's TimeLimit would apply) is refused
        if max_episode_steps is not None and max_episode_steps < self.config.n_actuators:
            raise ValueError(f"max_episode_steps={max_episode_steps} is below the "
                             f"{self.config.n_actuators} actuators: episodes would be cut "
                             f"short; pass max_episode_steps={self.config.n_actuators}")
        self.num_envs = n = int(num_envs)
        self.render_mode = render_mode
        # the parts' state, randomisation and compiled step (state.py), shared with the single env
        self.conveyor: Conveyor = Conveyor(self.config, n, self.config.num_threads)
        self.single_action_space = spaces.Box(-1.0, 1.0, (act.ACTION_DIM,), np.float32)
        self.single_observation_space = spaces.Box(-task.OBS_BOUND, task.OBS_BOUND,
                                                   (self.conveyor.obs_dim,), np.float32)
        self.action_space = batch_space(self.single_action_space, n)
        self.observation_space = batch_space(self.single_observation_space, n)
        self.done: np.ndarray = np.zeros(n, dtype=bool)
        self.rngs: list[np.random.Generator] = [seeding.np_random(None)[0] for _ in range(n)]
        self._started: bool = False

    # the parts' state (arrays, one element per sub-env; written in place) and configuration
    x = conveyor_field("parts.x", "Positions [m].")
    v = conveyor_field("parts.v", "Velocities [m/s].")
    t = conveyor_field("parts.t", "Simulated times [s].")
    target = conveyor_field("parts.target", "Targets [m].")
    fired = conveyor_field("parts.fired", "Actuators fired so far (int64).")
    friction_factor = conveyor_field("friction_factor",
                                     "This episode's factor on the friction [-], per sub-env.")
    mass_factor = conveyor_field("mass_factor", "This episode's factor on the mass [-], per sub-env.")
    threads = conveyor_field("threads", "Serial or parallel, per step (:mod:`.threads`).")

    # ------------------------------------------------------------------ resets
    def _reset_one(self, i: int, target: float | None = None,
                   state: PartState | None = None) -> None:
        self.conveyor.reset_part(i, self.rngs[i], target, state)
        self.done[i] = False

    def set_targets(self, indices: Any, targets: Any) -> np.ndarray:
        """Give the parts of sub-envs ``indices`` new targets [m] (checked as reset's ``target``
        option) in place of the ones their reset drew; each must be at the start of its
        episode (no actuator fired). Returns every sub-env's observation (a copy). The rest of
        the episode is the one the reset drew; a training-time target distribution uses it
        (agents/rl/targets.py)."""
        idx = np.atleast_1d(np.asarray(indices, dtype=np.int64))
        tv = np.broadcast_to(np.asarray(targets, dtype=float), idx.shape)
        checked = []  # every target checked before any is set
        for i, t in zip(idx.tolist(), tv.tolist(), strict=True):
            if not 0 <= i < self.num_envs:
                raise IndexError(f"sub-env {i} of {self.num_envs}")
            if self.fired[i] or self.t[i]:
                raise ValueError(f"sub-env {i} is in its episode ({self.fired[i]} actuator(s) "
                                 "fired): a target can be set only at an episode's start")
            checked.append(check_target(t))
        for i, t in zip(idx.tolist(), checked, strict=True):
            self.conveyor.parts.target[i] = t
        return self._obs()

    def get_state(self, i: int) -> PartState:
        """Sub-env ``i``'s part state now (:class:`~.part_state.PartState`, naming the env id
        and the scene)."""
        return self.conveyor.get_state(int(i), spec_id(self))

    def reset(self, *, seed: int | list | None = None,
              options: dict | None = None) -> tuple[np.ndarray, dict]:
        resets = self.conveyor.check_reset(options, batched=True)  # before anything changes
        if seed is not None:
            seeds = ([int(seed) + i for i in range(self.num_envs)]
                     if isinstance(seed, (int, np.integer)) else [int(s) for s in seed])
            if len(seeds) != self.num_envs:
                raise ValueError(f"{len(seeds)} seeds for {self.num_envs} envs")
            self.rngs = [seeding.np_random(s)[0] for s in seeds]
        for i in range(self.num_envs):
            self._reset_one(i, *resets.of(i))
        self._started = True
        return self._obs(), self._reset_infos()

    # ------------------------------------------------------------------ step
    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        if not self._started:
            raise RuntimeError("call reset() before step()")
        a = act.check_actions(actions, self.num_envs, out=self.conveyor.action_input)
        resetting = self.done.copy() if self.autoreset_mode == AutoresetMode.NEXT_STEP else \
            np.zeros(self.num_envs, dtype=bool)
        for i in np.flatnonzero(resetting):
            self._reset_one(int(i))
        active = ~resetting
        out = self.conveyor.step(a, active)  # inactive parts report reward 0, MOVING, no firing
        codes = out.outcome.copy()
        terminated = active & ((codes == kernel.REST) | (codes == kernel.DETACHED))
        truncated = active & ((codes == kernel.MAX_TIME) | (codes == kernel.TOO_MANY_EVENTS))
        rew = np.where(active, out.reward, 0.0)
        self.done = terminated | truncated
        obs = self.conveyor.obs.copy()  # out.obs itself without observation history
        infos = self._infos(np.array(kernel.OUTCOMES, dtype=object)[codes], active & out.success)
        for key, col in (("frequency_hz", out.frequency), ("stroke_m", out.stroke),
                         ("delay_s", out.delay)):
            infos[key], infos["_" + key] = col.copy(), active.copy()
        if self.autoreset_mode == AutoresetMode.SAME_STEP and self.done.any():
            infos = self._same_step_reset(obs, infos)
            obs = self._obs()
        return obs, rew, terminated, truncated, infos

    def _same_step_reset(self, obs: np.ndarray, infos: dict) -> dict:
        """Reset finished sub-envs now; as SyncVectorEnv does, their last observation and info go
        to ``final_obs`` / ``final_info`` and the top-level info rows become the reset info."""
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
                final_info[key] = np.where(mask, val, blank)
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
        for key in ("frequency_hz", "stroke_m", "delay_s"):  # step-only keys: absent after reset
            infos[key] = np.where(finished, 0.0, infos[key])
            infos["_" + key] = infos["_" + key] & ~finished
        infos["final_obs"], infos["_final_obs"] = final_obs, finished
        infos["final_info"], infos["_final_info"] = final_info, finished.copy()
        return infos

    # ------------------------------------------------------------------ helpers
    def _obs(self) -> np.ndarray:
        return self.conveyor.observe().copy()

    def _reset_infos(self) -> dict:
        return self._infos(np.full(self.num_envs, "moving", dtype=object),
                           np.zeros(self.num_envs, dtype=bool))

    def _infos(self, outcome: np.ndarray, success: np.ndarray) -> dict:
        ok = np.ones(self.num_envs, dtype=bool)
        infos = {"is_success": success.copy(), "position_error_m": self.x - self.target,
                 "outcome": outcome, "sim_time_s": self.t.copy()}
        if self.conveyor.randomised:
            infos["friction_factor"] = self.friction_factor.copy()
            infos["mass_factor"] = self.mass_factor.copy()
        for key in list(infos):
            infos["_" + key] = ok.copy()
        return infos

    def render(self) -> tuple | None:
        if self.render_mode != "rgb_array":
            return None
        from .render import render_frame

        return tuple(render_frame(self.config, self.x[i], self.target[i], int(self.fired[i]),
                                  None, self.t[i]) for i in range(self.num_envs))
