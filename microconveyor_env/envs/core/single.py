"""The single env every scene shares: one part (the scene's container with N = 1, always the
serial loop), reset through the container's checked options, the step and its info dict, and
the part's saved state.

A scene's single env subclasses :class:`SingleEnv` with its config class and container
(:attr:`SingleEnv.config_class`, :attr:`SingleEnv.conveyor_class`): the spaces come from the
container, the info dict from its :meth:`~.parts.PartsBase.errors` and ``step_info`` (as the
batched env's rows, :mod:`.vector`). :meth:`SingleEnv._after_reset` and
:meth:`SingleEnv._after_step` add what the scene keeps beside the part (the line's renderer, the
plane's path, the last firing it draws).
"""
from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from ...physics import dynamics_kernel as kernel
from .checks import check_render_mode, config_of, spec_id
from .part_state import SavedState


class SingleEnv(gym.Env):
    """One part of a scene: ``reset`` (seed, ``options={"target": ...}`` or ``{"state": ...}``,
    checked before anything changes), ``step`` and ``get_state``.

    ``SingleEnv(render_mode=None, config=None, **kwargs)``: ``config`` a ``config_class`` or
    keyword overrides of its defaults file, not both."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}
    config_class: ClassVar[type]
    conveyor_class: ClassVar[type]
    conveyor: Any  # the scene's PartsBase, N = 1
    _done: bool
    _last_firing: Any

    def __init__(self, render_mode: str | None = None, config: Any = None,
                 **kwargs: Any) -> None:
        self.config = config_of(self.config_class, config, kwargs)
        check_render_mode(render_mode, self.metadata["render_modes"])
        self.render_mode = render_mode
        # the part's state, randomisation and compiled step, N = 1, always serial
        c = self.conveyor = self.conveyor_class(self.config, 1, num_threads=1)
        c.clear_targets()
        self.action_space = spaces.Box(-1.0, 1.0, (c.action_input.shape[1],), np.float32)
        self.observation_space = spaces.Box(-c.obs_bound, c.obs_bound, (c.obs_dim,), np.float32)
        self._done = True
        self._last_firing = None

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        # every option checked before anything changes
        resets = self.conveyor.check_reset(options, batched=False, env_id=spec_id(self))
        super().reset(seed=seed)
        self.conveyor.reset_part(0, self.np_random, *resets.of(0))
        self._done = False
        self._last_firing = None
        obs = self.conveyor.observe()[0].copy()
        self._after_reset()
        return obs, self._info("moving", False)

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Fire once (the episode must be running; ``action`` checked into the part's input
        buffer: a RuntimeError after the episode's end, a ValueError for a bad action)."""
        if self._done:
            raise RuntimeError("step() called on a finished episode: call reset() first")
        c = self.conveyor
        out = c.step(c.check_actions(action, None))
        outcome = kernel.OUTCOMES[int(out.outcome[0])]
        terminated = outcome in ("rest", "detached")
        truncated = outcome in ("max_time", "too_many_events")
        self._done = terminated or truncated
        info = self._info(outcome, bool(out.success[0]))
        for key, name, _ in c.step_info:
            info[key] = getattr(out, name)[0].item()
        self._after_step(info)
        return c.obs[0].copy(), float(out.reward[0]), terminated, truncated, info

    def _after_reset(self) -> None:
        """What the scene does after a reset, beside the part."""

    def _after_step(self, info: dict[str, Any]) -> None:
        """What the scene does after a step, beside the part (``info``: the step's)."""

    def _info(self, outcome: str, success: bool) -> dict[str, Any]:
        """The info every reset and step returns: success, the part's errors (the container's
        :meth:`~.parts.PartsBase.errors_of`), the outcome, the simulated time and, with
        randomisation on, this episode's factors."""
        c = self.conveyor
        info: dict[str, Any] = {"is_success": success, **c.errors_of(0), "outcome": outcome,
                                "sim_time_s": float(c.parts.t[0])}
        if c.randomised:
            info["friction_factor"] = float(c.friction_factor[0])
            info["mass_factor"] = float(c.mass_factor[0])
        return info

    def get_state(self) -> SavedState:
        """The part's state now (SI units): ``reset(options={"state": s})`` continues the
        episode from it exactly. It names the env id and the scene: an env of another scene
        refuses it."""
        return self.conveyor.get_state(0, spec_id(self))
