"""The batched env every scene shares: N independent sub-envs stepped by one compiled call.

:class:`BatchedEnv` is Gymnasium's ``VectorEnv`` written once: argument checks, per-sub-env
generators seeded ``seed + i`` (as ``SyncVectorEnv`` seeds them, so a batched rollout is the
single envs' rollouts bit for bit), reset options checked whole before any sub-env changes,
``NEXT_STEP`` and ``SAME_STEP`` autoreset (``final_obs`` / ``final_info``), and the step's info
dict. A scene subclasses it with its config class and its part container (:mod:`.parts`), which
checks the reset options and says what the info rows hold.
"""
from __future__ import annotations

import numbers
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ...physics import dynamics_kernel as kernel
from .checks import check_render_mode, config_of, spec_id
from .parts import PartsBase

MAX_ENVS = 1_000_000  # parts in one batch (each costs ~1 kB of state)
OUTCOME_NAMES = np.array(kernel.OUTCOMES, dtype=object)  # the info's outcome of each code


class BatchedEnv(VectorEnv):
    """``num_envs`` independent copies of a scene's single env (its subclasses).

    A subclass sets :attr:`config_class`, :attr:`conveyor_class` (its part container, a
    :class:`~.parts.PartsBase`: the reset options, actions and saved states are checked
    there, and its ``errors`` and ``step_info`` say what the info rows hold) and
    :attr:`sb3_info` (the info keys :mod:`.sb3` passes on per sub-env); the config says how
    many steps an episode takes at most (``episode_limit``). ``get_state(i)``: sub-env ``i``'s saved
    part state; ``reset(options={"state": ...})`` starts sub-envs from saved states.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4,
                "autoreset_mode": AutoresetMode.NEXT_STEP}
    config_class: ClassVar[type]
    conveyor_class: ClassVar[type[PartsBase]]
    # the info keys of one sub-env (scalars or short rows) the SB3 adapter passes on, in order
    sb3_info: ClassVar[tuple[str, ...]] = ()
    conveyor: Any  # a conveyor_class

    def __init__(self, num_envs: int = 1, render_mode: str | None = None,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
                 config: Any = None, max_episode_steps: int | None = None,
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
        self.config = config_of(self.config_class, config, kwargs)
        # make_vec passes the spec's step limit; an episode ends by itself within
        # config.episode_limit steps, so a lower limit (which the single env's TimeLimit would
        # apply) is refused
        limit, what = self.config.episode_limit
        if max_episode_steps is not None and max_episode_steps < limit:
            raise ValueError(f"max_episode_steps={max_episode_steps} is below {what}: episodes "
                             f"would be cut short; pass max_episode_steps={limit}")
        self.num_envs = n = int(num_envs)
        self.render_mode = render_mode
        # the parts' state and compiled step, shared with the single env
        self.conveyor = self.conveyor_class(self.config, n, self.config.num_threads)
        c = self.conveyor
        self.single_action_space = spaces.Box(-1.0, 1.0, (c.action_input.shape[1],), np.float32)
        self.single_observation_space = spaces.Box(-c.obs_bound, c.obs_bound, (c.obs_dim,),
                                                   np.float32)
        self.action_space = batch_space(self.single_action_space, n)
        self.observation_space = batch_space(self.single_observation_space, n)
        self.done: np.ndarray = np.zeros(n, dtype=bool)
        self.rngs: list[np.random.Generator] = [seeding.np_random(None)[0] for _ in range(n)]
        self._started: bool = False

    # ------------------------------------------------------------------ info
    def _infos(self, outcome: np.ndarray, success: np.ndarray) -> dict:
        """The info rows every step and reset returns (with their ``_key`` masks): success, the
        parts' errors (the container's ``errors``), the outcome, the simulated time and, with
        randomisation on, this episode's factors."""
        c = self.conveyor
        infos = {"is_success": success.copy(), **c.errors(), "outcome": outcome,
                 "sim_time_s": c.parts.t.copy()}
        if c.randomised:
            infos["friction_factor"] = c.friction_factor.copy()
            infos["mass_factor"] = c.mass_factor.copy()
        return self._with_masks(infos, self.num_envs)

    # ------------------------------------------------------------------ resets
    def get_state(self, i: int) -> Any:
        """Sub-env ``i``'s part state now (the scene's saved state, naming the env id and the
        scene): ``reset(options={"state": ...})`` continues its episode from it."""
        return self.conveyor.get_state(int(i), spec_id(self))

    def _reset_one(self, i: int, *args: Any) -> None:
        self.conveyor.reset_part(i, self.rngs[i], *args)
        self.done[i] = False

    def _reset_many(self, rows: np.ndarray) -> None:
        """Reset the sub-envs ``rows`` (an index array, ascending) without options: the same
        draws as one ``_reset_one`` each, the parts' state written whole
        (:meth:`~.parts.PartsBase.reset_parts`)."""
        if not len(rows):
            return
        rngs = self.rngs
        self.conveyor.reset_parts(rows, [rngs[i] for i in rows.tolist()])
        self.done[rows] = False

    def reset(self, *, seed: int | list | None = None,
              options: dict | None = None) -> tuple[np.ndarray, dict]:
        # every option checked before anything changes
        resets = self.conveyor.check_reset(options, batched=True, env_id=spec_id(self))
        if seed is not None:
            seeds = ([int(seed) + i for i in range(self.num_envs)]
                     if isinstance(seed, (int, np.integer)) else [int(s) for s in seed])
            if len(seeds) != self.num_envs:
                raise ValueError(f"{len(seeds)} seeds for {self.num_envs} envs")
            self.rngs = [seeding.np_random(s)[0] for s in seeds]
        if resets.targets is None and resets.states is None:
            self._reset_many(np.arange(self.num_envs))
        else:
            for i in range(self.num_envs):
                self._reset_one(i, *resets.of(i))
        self._started = True
        return self._obs(), self._reset_infos()

    # ------------------------------------------------------------------ step
    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        if not self._started:
            raise RuntimeError("call reset() before step()")
        a = self.conveyor.check_actions(actions, self.num_envs)
        resetting = self.done.copy() if self.autoreset_mode == AutoresetMode.NEXT_STEP else \
            np.zeros(self.num_envs, dtype=bool)
        self._reset_many(np.flatnonzero(resetting))
        active = ~resetting
        out = self.conveyor.step(a, active)  # inactive parts report reward 0, MOVING, no firing
        codes = out.outcome.copy()
        terminated = active & ((codes == kernel.REST) | (codes == kernel.DETACHED))
        truncated = active & ((codes == kernel.MAX_TIME) | (codes == kernel.TOO_MANY_EVENTS))
        rew = np.where(active, out.reward, 0.0)
        self.done = terminated | truncated
        obs = self.conveyor.obs.copy()
        infos = self._infos(OUTCOME_NAMES[codes], active & out.success)
        for key, field, _ in self.conveyor.step_info:
            infos[key], infos["_" + key] = getattr(out, field).copy(), active.copy()
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
                shaped = mask.reshape((-1,) + (1,) * (val.ndim - 1))
                final_info[key] = np.where(shaped, val, blank)
                final_info["_" + key] = mask
        for i in idx.tolist():
            final_obs[i] = obs[i].copy()
        self._reset_many(idx)
        reset = self._reset_infos()
        infos = dict(infos)
        for key, val in reset.items():
            if not key.startswith("_"):
                infos[key] = infos[key].copy()
                infos[key][idx] = val[idx]
        for key, _, after_reset in self.conveyor.step_info:  # step-only: absent after a reset
            infos[key] = np.where(finished, after_reset, infos[key])
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

    @staticmethod
    def _with_masks(infos: dict, n: int) -> dict:
        """``infos`` with a ``_key`` mask (all True) beside each key."""
        ok = np.ones(n, dtype=bool)
        for key in list(infos):
            infos["_" + key] = ok.copy()
        return infos
