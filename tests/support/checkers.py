"""Gymnasium's env checker as the tests run it: headless, and without the ``human`` render mode
when pygame (the ``render`` extra; the README's test command installs it, a core install does
not) is absent, since the checker makes the env once in every mode its metadata lists."""
from __future__ import annotations

import importlib.util
from typing import Any


def gymnasium_check_env(env: Any, monkeypatch: Any) -> None:
    """Run ``gymnasium.utils.env_checker.check_env`` on ``env`` (its unwrapped env)."""
    from gymnasium.utils.env_checker import check_env

    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")  # the human window, headless
    if importlib.util.find_spec("pygame") is None:
        modes = [m for m in env.metadata["render_modes"] if m != "human"]
        env.metadata = {**env.metadata, "render_modes": modes}
    check_env(env)
