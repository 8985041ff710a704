"""Training-only reward shaping for MicroConveyor (a VecEnv wrapper named in a recipe).

:class:`LogErrorShaping` adds a potential-based term to the env's reward while training
(Ng, Harada & Russell, ICML 1999): at every step ``Psi(e') - Psi(e)`` with

    Psi(e) = -weight * ln(1 + min(|e|, horizon) / scale)

of the part's position error ``e = x - target`` [m] (after the step ``e'``, before it ``e``);
a detached part takes ``Psi(horizon)``, as the env's own potential takes its horizon. Over an
episode the terms telescope to ``Psi(e_final) - Psi(e_start)``: the return gains
``-weight * ln(1 + |e_final| / scale)`` plus a constant of the start, so the shaping rewards
*relative* accuracy. The env's reward is linear in the error; its last 100 µm are worth as
much as any other 100 µm, which let PPO settle near targets (0.5-3.5 mm) for ~1 mm errors
while far ones dominated the returns (docs/agents.md, "PPO on MicroConveyor-v1"). The log
term pays as much for halving an error of 100 µm as one of 2 mm.

Only training sees it: the env, its reward, evaluations and shipped metadata are unchanged.
A recipe names it the way rl-zoo3 names a VecEnv wrapper (``vec_env_wrapper``, applied
before VecNormalize; :mod:`.wrappers` builds only the wrappers it lists).
"""
from __future__ import annotations

from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from microconveyor_env.envs.rail.step import LENGTH_SCALE

from .hyperparams import number_in


class LogErrorShaping(VecEnvWrapper):
    """Adds ``Psi(e') - Psi(e)``, ``Psi(e) = -weight ln(1 + min(|e|, horizon)/scale)``, to the
    reward (module docstring). ``weight`` [reward units per e-fold], ``scale_m`` [m] the error
    at which the log bends (below it the term is nearly linear), ``horizon_m`` [m] where it
    saturates (default: the env's ``progress_horizon``)."""

    def __init__(self, venv: VecEnv, weight: float = 10.0, scale_m: float = 50e-6,
                 horizon_m: float | None = None) -> None:
        super().__init__(venv)
        if horizon_m is None:
            try:  # the batched env's config (MicroConveyorSB3VecEnv.get_attr)
                horizon_m = venv.get_attr("config")[0].progress_horizon
            except (AttributeError, IndexError):
                horizon_m = None
        if horizon_m is None:
            raise ValueError("LogErrorShaping: the env has no progress_horizon: pass horizon_m")
        self.weight, self.scale, self.horizon = (
            number_in(f"LogErrorShaping: {name}", val, 0.0, what="a positive number")
            for name, val in (("weight", weight), ("scale_m", scale_m), ("horizon_m", horizon_m)))
        self._psi = np.zeros(self.num_envs)

    def potential(self, error_m: np.ndarray) -> np.ndarray:
        """``Psi`` of position errors [m] (any shape)."""
        e = np.minimum(np.abs(np.asarray(error_m, float)), self.horizon)
        return -self.weight * np.log1p(e / self.scale)

    def _start_potential(self, obs: Any) -> np.ndarray:
        # observation 0 is the position error / LENGTH_SCALE (the env's layout, envs/line/task.py)
        return self.potential(np.asarray(obs, float)[:, 0] * LENGTH_SCALE)

    def reset(self) -> Any:
        obs = self.venv.reset()
        self._psi = self._start_potential(obs)
        return obs

    def step_wait(self) -> Any:
        obs, rew, dones, infos = self.venv.step_wait()
        err = np.array([inf.get("position_error_m", np.nan) for inf in infos], float)
        if np.isnan(err).any():
            raise RuntimeError("LogErrorShaping needs info['position_error_m'] on every step")
        psi = self.potential(err)
        detached = np.array([inf.get("outcome") == "detached" for inf in infos])
        psi[detached] = self.potential(np.array(self.horizon))
        shaped = np.asarray(rew, np.float64) + psi - self._psi
        self._psi = np.where(dones, self._start_potential(obs), psi)
        return obs, shaped.astype(np.float32), dones, infos
