"""The stable-baselines3 adapter of any scene's batched env.

SB3 cannot take a gymnasium ``VectorEnv``; :class:`MicroConveyorSB3VecEnv` wraps the batched env
of a registered id (the line's :class:`~..line.vector.MicroConveyorVectorEnv`, the plane's
:class:`~..plane.vector.MicroConveyor2DVectorEnv`; in ``SAME_STEP`` autoreset mode) so
``PPO("MlpPolicy", MicroConveyorSB3VecEnv(64, env_id="MicroConveyor2D-v0"))`` trains on the
compiled batch. Finished sub-envs are reset in the same step; their last observation is in
``infos[i]["terminal_observation"]`` and ``infos[i]["TimeLimit.truncated"]`` flags truncation, as
SB3 expects. Requires the ``train`` extra (stable-baselines3).
"""
from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env.base_vec_env import VecEnv

from .versions import scene_config, vector_class, vector_class_of
from .vector import BatchedEnv


class MicroConveyorSB3VecEnv(VecEnv):
    """``num_envs`` parts in one compiled batch, with SB3's VecEnv semantics.

    ``env_id``: any registered id (``"MicroConveyor-v1"``, ``"MicroConveyor2D-v0"``: its batched
    env with its defaults, as ``gym.make`` gives them; None: MicroConveyor-v0's); keyword
    arguments are fields of its config class overriding them. Or ``config=`` a config (an
    :class:`~..line.config.EnvConfig` or a :class:`~..plane.config.PlaneEnvConfig`: its class
    chooses the scene). The per-env info dicts hold the batched env's ``sb3_info`` keys.
    """

    def __init__(self, num_envs: int = 8, env_id: str | None = None, **kwargs: Any) -> None:
        cls = vector_class("MicroConveyor-v0")
        if env_id is not None:
            if "config" in kwargs:
                raise ValueError("give either env_id (with keyword overrides) or config=")
            cls = vector_class(env_id)
            kwargs = {"config": scene_config(env_id, **kwargs)}
        elif kwargs.get("config") is not None:
            cls = vector_class_of(kwargs["config"])
        self.venv: BatchedEnv = cls(num_envs, autoreset_mode=AutoresetMode.SAME_STEP, **kwargs)
        self._info_keys: tuple[str, ...] = self.venv.sb3_info
        self._actions: np.ndarray | None = None
        super().__init__(num_envs, self.venv.single_observation_space,
                         self.venv.single_action_space)

    def reset(self) -> np.ndarray:
        seeds = self._seeds
        seed = None if all(s is None for s in seeds) else [
            s if s is not None else int(np.random.SeedSequence().generate_state(1)[0])
            for s in seeds]
        obs, infos = self.venv.reset(seed=seed, options=self._merged_options())
        self.reset_infos = self._split(infos)
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
        obs, rew, term, trunc, infos = self.venv.step(self._actions)
        dones = term | trunc
        src = infos.get("final_info", infos) if dones.any() else infos
        out = self._split(infos)
        finished = np.flatnonzero(dones)
        if finished.size:
            final = self._split(src, finished)
            for j, i in enumerate(finished):
                self.reset_infos[i] = out[i]  # top-level rows of finished envs: the reset info
                out[i] = final[j]
                out[i]["terminal_observation"] = infos["final_obs"][i]
                out[i]["TimeLimit.truncated"] = bool(trunc[i] and not term[i])
        return obs, rew.astype(np.float32), dones, out

    def _merged_options(self) -> dict | None:
        """Per-env options ({"target": d} each, see ``set_options``) as one batched dict."""
        opts = self._options or []
        if not any(opts):
            return None
        unknown = {k for o in opts for k in o} - {"target"}
        if unknown:
            raise ValueError(f"unsupported reset options {sorted(unknown)}; only 'target'")
        if not all("target" in o for o in opts):
            raise ValueError("set a 'target' option for every sub-env (or for none)")
        return {"target": np.array([o["target"] for o in opts], dtype=float)}

    def _split(self, infos: dict, rows: np.ndarray | None = None) -> list[dict]:
        """Per-env info dicts (of ``rows``, default all) with the keys the batched env's masks
        (``_key``) mark present, as Python scalars (``tolist`` converts a column at once: the
        per-element conversion cost as much as the compiled step)."""
        sel = slice(None) if rows is None else rows
        cols = [(k, infos[k][sel].tolist(), infos["_" + k][sel].tolist())
                for k in self._info_keys if k in infos]
        n = self.num_envs if rows is None else len(rows)
        return [{k: vals[j] for k, vals, present in cols if present[j]} for j in range(n)]

    def set_targets(self, indices: Any, targets: Any) -> np.ndarray:
        """New targets [m] for sub-envs at the start of their episodes; every observation
        (the line's :meth:`~..line.vector.MicroConveyorVectorEnv.set_targets`)."""
        venv: Any = self.venv
        if not hasattr(venv, "set_targets"):
            raise AttributeError(f"{type(venv).__name__} has no set_targets: give targets as "
                                 "reset options (set_options)")
        obs = venv.set_targets(indices, targets)
        for i in np.atleast_1d(np.asarray(indices, dtype=np.int64)).tolist():
            if "position_error_m" in self.reset_infos[i]:
                self.reset_infos[i]["position_error_m"] = float(venv.x[i] - venv.target[i])
        return obs

    def close(self) -> None:
        self.venv.close()

    def _indices(self, indices: Any) -> Any:
        if indices is None:
            return range(self.num_envs)
        return [indices] if isinstance(indices, int) else indices

    def get_attr(self, attr_name: str, indices: Any = None) -> list:
        """The batched env's attribute, repeated per index (its sub-envs share one config)."""
        return [getattr(self.venv, attr_name) for _ in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        raise AttributeError("the batched env shares one configuration; create a new env instead")

    def env_method(self, method_name: str, *method_args: Any, indices: Any = None,
                   **method_kwargs: Any) -> list:
        raise AttributeError(f"{method_name}: per-sub-env methods are not available on the "
                             "compiled batch")

    def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
        return [False for _ in self._indices(indices)]

    def get_images(self) -> list:
        frames = self.venv.render()
        return list(frames) if frames is not None else [None] * self.num_envs

