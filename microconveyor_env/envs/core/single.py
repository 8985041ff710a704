"""The single env every scene shares: one part (the scene's container with N = 1, always the
serial loop), reset through the container's checked options, and its saved part state.

A scene's single env subclasses :class:`SingleEnv` with its spaces, its step and its info dict;
:meth:`SingleEnv._after_reset` adds what the scene keeps beside the part (the line's renderer,
the plane's path).
"""
from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from .checks import spec_id
from .part_state import SavedState


class SingleEnv(gym.Env):
    """One part of a scene: ``reset`` (seed, ``options={"target": ...}`` or ``{"state": ...}``,
    checked before anything changes) and ``get_state``."""

    conveyor: Any  # the scene's PartsBase, N = 1
    _done: bool
    _last_firing: Any

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

    def _checked_action(self, action: Any) -> np.ndarray:
        """The start of a step: the episode is running and ``action`` checked into the part's
        input buffer (a RuntimeError after the episode's end, a ValueError for a bad action)."""
        if self._done:
            raise RuntimeError("step() called on a finished episode: call reset() first")
        return self.conveyor.check_actions(action, None)

    def _after_reset(self) -> None:
        """What the scene does after a reset, beside the part."""

    def _info(self, outcome: str, success: bool) -> dict[str, Any]:
        raise NotImplementedError

    def get_state(self) -> SavedState:
        """The part's state now (SI units): ``reset(options={"state": s})`` continues the
        episode from it exactly. It names the env id and the scene: an env of another scene
        refuses it."""
        return self.conveyor.get_state(0, spec_id(self))
