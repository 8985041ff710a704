"""The ``human`` render mode's window: pygame, from the ``render`` extra
(``pip install "microconveyor-env[render]"``), imported only when the mode is asked for.

Without pygame an env's own ``metadata["render_modes"]`` leaves ``human`` out
(:func:`installed_modes`): the modes it lists are those this install renders, so Gymnasium's
``check_env``, which renders in each listed mode, passes. The class's modes still name
``human``, so ``gym.make(id, render_mode="human")`` reaches the env, which refuses it at once,
naming the extra (:func:`require_pygame`).
"""
from __future__ import annotations

import importlib.util
import os
from collections.abc import Sequence
from typing import Any

import numpy as np

EXTRA = 'pip install "microconveyor-env[render]"'


def require_pygame() -> Any:
    """The pygame module, or gymnasium's ``DependencyNotInstalled`` naming the extra."""
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    try:
        import pygame
    except ImportError as exc:
        from gymnasium.error import DependencyNotInstalled

        raise DependencyNotInstalled(f'render_mode="human" needs pygame, which is not installed: '
                                     f"{EXTRA} (the render extra)") from exc
    return pygame


def installed_modes(modes: Sequence[str]) -> list[str]:
    """``modes`` less ``human`` when pygame is not installed (found without importing it)."""
    return [m for m in modes if m != "human" or importlib.util.find_spec("pygame") is not None]


class Window:
    """A pygame window showing rgb frames at a given rate (opened at the first frame)."""

    def __init__(self, title: str = "MicroConveyor") -> None:
        self.pygame = require_pygame()
        self.title = title
        self.screen: Any = None
        self.clock: Any = None

    def show(self, frames: Sequence[np.ndarray], fps: float) -> None:
        """Show ``frames`` (uint8 (H, W, 3)) one after the other, ``fps`` per second."""
        pg = self.pygame
        for frame in frames:
            if self.screen is None:
                pg.init()
                pg.display.init()
                pg.display.set_caption(self.title)
                self.screen = pg.display.set_mode((frame.shape[1], frame.shape[0]))
                self.clock = pg.time.Clock()
            surface = pg.surfarray.make_surface(np.ascontiguousarray(frame.transpose(1, 0, 2)))
            self.screen.blit(surface, (0, 0))
            pg.event.pump()
            pg.display.flip()
            self.clock.tick(fps)

    def close(self) -> None:
        if self.screen is not None:
            self.pygame.display.quit()
            self.pygame.quit()
            self.screen = None
